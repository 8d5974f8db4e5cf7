"""What a recording says: run metadata (:mod:`.run`), frames (:mod:`.frames`), metrics
(:mod:`.metrics`), plots (:mod:`.plots`), output files (:mod:`.report`), bit-for-bit replay
(:mod:`.replay`) and pathwise comparison of two runs (:mod:`.compare`)."""
