"""The ``mrd-env`` command (:mod:`.cli`, ``mrd-env --help``) and the experiments, by purpose:

* :mod:`.commands`: one module per verb of ``mrd-env``;
* :mod:`.benchmark`: the benchmark's public API (suites, building them, scoring, results, leaderboards) and the
  modules behind it, the shipped suites' maintenance among them;
* :mod:`.training`: the training algorithms (Stable-Baselines3's bridge, CMA-ES, SHAC, PPO inside one jit) and
  what they share;
* :mod:`.common`: what the commands, the benchmark, the trainers and the labs share (plant profiles, scenarios,
  the evaluation loop, record files, the executor's options);
* :mod:`.measurements`: ``python -m experiments.measurements.<speed|memory|accuracy>.<name>``: how fast, how
  much memory, how accurate (scripts, not tests; each prints its figures with the machine's load);
* :mod:`.scripts`: maintenance tools (the fingerprint of a refactor, the agent export, a preset's derivation, probes);
* :mod:`.labs`: the teaching labs.
"""
