"""The certified clairvoyant (experiments/benchmark/certify.py): two solution paths that must agree, at the suite's own
control step; an episode they disagree on is never certified."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("casadi")

from experiments.benchmark import certify  # noqa: E402
from experiments.benchmark.references import best_constant  # noqa: E402
from mrd_env.optimal import episode_problem  # noqa: E402

ENV = "mrd_env/QuarterCarPhysical-v0"


# one worker runs the module (--dist loadgroup): its module fixture's certified episodes are computed once, not on each
pytestmark = pytest.mark.xdist_group("test_certify")


@pytest.fixture(scope="module")
def problem():
    """A short ISO class C road at the suite's 10 ms step: 40 commands."""
    return episode_problem(ENV, seed=1_000_000, control_dt=0.01, road="iso8608",
                           road_params={"road_class": "C", "speed": 20.0}, episode_seconds=0.4)


@pytest.fixture(scope="module")
def starts(problem):
    rp, vp = best_constant(problem)
    return rp, {"best constant": np.full((problem.n_steps, problem.nd), vp),
                "passive_off": np.full((problem.n_steps, problem.nd), problem.v_min)}


@pytest.fixture(scope="module")
def certificate(problem, starts):
    rp, st = starts
    return certify.certified_clairvoyant(problem, st, rp, n_starts=1, more_starts=2)


def test_both_paths_agree_and_certify_at_the_suites_control_step(problem, starts, certificate):
    rp, _ = starts
    c = certificate
    assert problem.n_steps == 40 and c.commands.shape == (40, 1)  # one command per 10 ms control step
    assert c.certified and c.rounds in (1, 2)
    a, b = (p.ret for p in c.paths.values())
    assert abs(a - b) <= certify.TOLERANCE * (c.ret - rp)
    assert c.ret > rp  # the clairvoyant beats the best constant command
    assert problem.replay(c.commands).ret == pytest.approx(c.ret, abs=1e-12)  # the environment pays it


def test_no_command_sequence_near_the_certified_optimum_does_better(problem, certificate):
    """A second method cannot improve it: random perturbations and the constant commands all score lower."""
    rng = np.random.default_rng(0)
    V = certificate.commands
    for _ in range(20):
        trial = np.clip(V + rng.normal(0, 0.05 * (problem.v_max - problem.v_min), V.shape), problem.v_min,
                        problem.v_max)
        assert problem.replay(trial).ret <= certificate.ret + 1e-9
    for v in np.linspace(problem.v_min, problem.v_max, 9):
        assert problem.replay(np.full_like(V, v)).ret <= certificate.ret


def test_paths_that_disagree_are_not_certified(problem, starts):
    """A path stuck at a poor point (a stand-in for a solver that failed) makes the episode uncertified, after the
    second round; the certificate still reports both paths."""
    rp, st = starts
    calls = []

    def poor(prob, s, n, fine_only=False):
        calls.append(n)
        V = np.full((prob.n_steps, prob.nd), prob.v_max)  # passive-on: far below the optimum
        r = float(prob.replay(V).ret)
        return certify.PathResult(r, V, r,
                                  [{"start": "x", "status": "converged", "success": True, "iterations": 1,
                                    "evaluations": 1, "return": r}])

    paths = {"casadi": (certify.casadi_path, certify.casadi_path), "poor": (poor, poor)}
    c = certify.certified_clairvoyant(problem, st, rp, n_starts=1, more_starts=2, paths=paths)
    assert not c.certified and c.rounds == 0
    assert calls == [1, 2, 1]  # solved again with more starts, and from the other path's optimum, before it was refused
    assert c.disagreement > certify.TOLERANCE
    assert c.to_json()["certified"] is False


def test_procedure_4_tries_the_cross_starts_before_more_starts(problem, starts, certificate):
    """Procedure 4: a path stuck at a poor point in round 1 that reaches the other's optimum when started there
    certifies in round 2 by the cross starts alone, and no more-starts solve runs; a path that cannot is still
    refused after the more starts."""
    rp, st = starts

    def stuck(prob, s, n, fine_only=False):  # passive-on, unless started at another path's optimum (kept there)
        V = s["casadi optimum"] if "casadi optimum" in s else np.full((prob.n_steps, prob.nd), prob.v_max)
        r = float(prob.replay(V).ret)
        return certify.PathResult(r, V, r, [{"start": next(iter(s)), "status": "converged", "success": True,
                                             "iterations": 1, "evaluations": 1, "return": r}])

    def optimum(prob, s, n, fine_only=False):  # a path that reaches the certified optimum from any start
        V = certificate.commands
        r = float(prob.replay(V).ret)
        return certify.PathResult(r, V, r, [{"start": next(iter(s)), "status": "converged", "success": True,
                                             "iterations": 1, "evaluations": 1, "return": r}])

    def never(*args, **kwargs):
        raise AssertionError("the more starts ran although the cross starts certified")

    paths = {"casadi": (optimum, never), "stuck": (stuck, never)}
    plain = certify.certified_clairvoyant(problem, st, rp, n_starts=1, more_starts=2,
                                          paths={"casadi": (optimum, optimum), "stuck": (stuck, stuck)})
    assert plain.certified and plain.rounds == 2  # procedure 3 gets there too, after the more starts
    c = certify.certified_clairvoyant(problem, st, rp, n_starts=1, more_starts=2, paths=paths, cross_first=True)
    assert c.certified and c.rounds == 2 and c.disagreement <= certify.TOLERANCE
    assert [r["start"] for r in c.paths["stuck"].runs] == ["best constant", "casadi optimum"]


def test_bad_arguments_are_refused(problem, starts):
    rp, st = starts
    with pytest.raises(ValueError, match="tolerance"):
        certify.certified_clairvoyant(problem, st, rp, tolerance=0)
    with pytest.raises(ValueError, match="n_starts"):
        certify.certified_clairvoyant(problem, st, rp, n_starts=5, more_starts=4)


def test_the_batched_round_1_is_the_gradient_paths_and_certifies(problem, starts, certificate):
    """Procedure 3: the gradient path's round 1 for two episodes together (the shorter padded) reaches the
    per-episode path's return within the tolerance of the range; certification handed it as ``first`` certifies
    without running that path's round 1 again."""
    rp, st = starts
    other = episode_problem(ENV, seed=1_000_001, control_dt=0.01, road="iso8608",
                            road_params={"road_class": "C", "speed": 20.0}, episode_seconds=0.3)
    rp2, vp2 = best_constant(other)
    st2 = {"best constant": np.full((other.n_steps, other.nd), vp2),
           "passive_off": np.full((other.n_steps, other.nd), other.v_min)}
    mine, theirs = certify.batched_gradient_paths([problem, other], [st, st2], 1)
    span = certificate.ret - rp
    assert mine.found and mine.commands.shape == (40, 1) and theirs.commands.shape == (30, 1)
    assert abs(mine.ret - certificate.paths["gradient"].ret) <= certify.TOLERANCE * span
    assert problem.replay(mine.commands).ret == pytest.approx(mine.commands_ret, abs=1e-12)  # the environment's
    assert theirs.ret > rp2 and len(mine.runs) == len(theirs.runs) == 1

    def not_again(*args):
        raise AssertionError("round 1 of the gradient path ran again")

    paths = {"casadi": certify.PATHS["casadi"], "gradient": (not_again, certify.PATHS["gradient"][1])}
    c = certify.certified_clairvoyant(problem, st, rp, n_starts=1, more_starts=2, paths=paths,
                                      first={"gradient": mine})
    assert c.certified and c.ret >= certificate.ret - certify.TOLERANCE * span


def test_procedure_3s_round_2_from_the_optimum_cannot_improve_it(problem, starts, certificate):
    """Procedure 3's round 2 (the batched solver for one episode, at the control step only, from the other path's
    optimum) leaves the certified optimum within the tolerance: a second method does not improve it."""
    rp, _ = starts
    assert certify.PATHS_3["gradient"][1] is certify.batched_gradient_path
    r = certify.batched_gradient_path(problem, {"optimum": certificate.commands}, 1, fine_only=True)
    assert len(r.runs) == 1 and r.runs[0]["start"] == "optimum"
    assert r.ret <= certificate.ret + certify.TOLERANCE * (certificate.ret - rp)
    assert r.ret >= certificate.ret - 1e-9 or not r.found  # a run that did not beat its start returns no commands


def test_the_batched_round_1_refuses_bad_input_by_name(problem, starts):
    rp, st = starts
    with pytest.raises(ValueError, match="n_starts must be an int >= 1"):
        certify.batched_gradient_paths([problem], [st], 0)
    with pytest.raises(ValueError, match="as long as each other"):
        certify.batched_gradient_paths([problem], [st, st], 1)
    with pytest.raises(ValueError, match="first must name paths of"):
        certify.certified_clairvoyant(problem, st, rp, n_starts=1, more_starts=2, first={"newton": None})
