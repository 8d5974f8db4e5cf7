"""The ROS 2 wire and file formats, without ROS: CDR encoders and decoders (:mod:`.cdr`), the
recorded topics (:mod:`.topics`), MCAP recordings (:mod:`.recording`), the run metadata record
(:mod:`.metadata`) and library versions (:mod:`.versions`)."""
