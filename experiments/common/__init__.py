"""What the commands, the benchmark, the trainers and the labs share: plant profiles, scenarios, the evaluation
loop, record files, fitting, the command-line options of the executor. It imports the library and itself only."""
