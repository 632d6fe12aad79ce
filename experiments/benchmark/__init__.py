"""The benchmark's public API: suites, scoring, results and leaderboards, from one module.

A **suite** is a frozen list of test episodes with every episode's stored references (:mod:`mrd_env.suites`); a
controller's **score** on it is each episode's share of the achievable gain, (R − R_p) / (R_c − R_p), against those
references; a **result** is one controller's scores, a plain JSON file; a **leaderboard** merges the results of one
suite, checked against its references; the **benchmark** (:func:`run_benchmark`, ``mrd-env benchmark``) scores
every controller that fits each of a set of suites — the laws, MPC rows and agents the project ships, and yours — and
writes the result files and one leaderboard per suite. This module is what the docs and the README import; the modules behind it
(``experiments.benchmark.scoring``, ``experiments.benchmark.ranking``, ``mrd_env.suites``) are internal and may move.
It lives in ``experiments`` because scoring builds the registered laws and agents (``controllers``), which the
library (``mrd_env``) does not import.

>>> from experiments.benchmark import leaderboards, score, suite
>>> s = suite("car-comfort-v1")                                   # a shipped suite, or a suite file's path
>>> score(s, "skyhook_continuous").write("results/score/skyhook.json")   # a law, a shipped agent, an agent folder,
>>> score(s, MyController).write("results/score/mine.json")              # module:attribute or a class
>>> leaderboards(["results/score/skyhook.json", "results/score/mine.json"], out="results/leaderboard")
>>> run_benchmark(["car-comfort-v1"], {"mine": MyController}, out="results/benchmark")  # yours beside the shipped
"""
from __future__ import annotations

from mrd_env.suites import Reference, Suite, read_suite, suite, suites, write_suite

from experiments.benchmark.ranking import Leaderboard, leaderboard, leaderboards, read_result, write_leaderboards
from experiments.benchmark.run import Benchmark, run_benchmark, shipped_controllers
from experiments.benchmark.scoring import SuiteResult, result_filename, score, shipped_agent_names

__all__ = ["Suite", "Reference", "suite", "suites", "read_suite", "write_suite",
           "score", "SuiteResult", "result_filename", "shipped_agent_names",
           "read_result", "Leaderboard", "leaderboard", "leaderboards", "write_leaderboards",
           "run_benchmark", "Benchmark", "shipped_controllers"]
