"""What a scene is: its schema and loading (:mod:`.scene`), walls and obstacles with the true
constraint values (:mod:`.geometry`), wished-velocity fields (:mod:`.fields`) and radius laws
(:mod:`.radii`). Imports nothing from the layers above."""
