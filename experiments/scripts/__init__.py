"""Scripts run as ``python -m experiments.scripts.<name>``: benchmarks of speed and accuracy (``bench_*``), probes,
derivations and the agent export. They stand above the commands and the common modules and may import both."""
