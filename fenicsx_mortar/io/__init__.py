"""What a scene run reads and writes besides the scene: mesh files as data
(:mod:`.mshfile`), the output directory and every write into it (:mod:`.output`),
checkpoints (:mod:`.checkpoint`), the interface CSV files and plots (:mod:`.interface`),
pictures (:mod:`.pictures`)."""
