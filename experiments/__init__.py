"""The ``mrd-env`` command (:mod:`.cli`, ``mrd-env --help``) and the experiments, in four parts: :mod:`.commands`
(one module per verb), :mod:`.common` (what the commands, scripts and labs share), :mod:`.scripts` (``python -m
experiments.scripts.<name>``: benchmarks, probes, derivations, the agent export) and :mod:`.labs` (teaching labs)."""
