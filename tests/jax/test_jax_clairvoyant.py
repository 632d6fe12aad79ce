"""The clairvoyant optimum by gradient (:mod:`mrd_env.jax.clairvoyant`, issue 41) on a short quarter-car and a short
building episode: re-simulated in the native environment, no law beats it — not the best constant command,
passive-off or a feedback law (an optimum over every command sequence is at least every causal law's return)."""
from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from mrd_env.jax.clairvoyant import clairvoyant  # noqa: E402
from mrd_env.optimal import episode_problem  # noqa: E402
from mrd_env.jax import env as je  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")


CASES = {
    "quarter_car": ("mrd_env/QuarterCarPhysical-v0", {"episode_seconds": 0.3, "road": "iso8608",
                                                      "road_params": {"road_class": "D", "speed": 20.0}},
                    ("passive_off", "skyhook_continuous")),
    "shear_building": ("mrd_env/ShearBuildingPhysical-v0", {"episode_seconds": 0.4, "ground_motion": "kanai_tajimi",
                                                            "damper_floors": [2]}, ("passive_off", "passive_on")),
}


@pytest.mark.parametrize("case", CASES)
def test_gradient_clairvoyant_beats_every_law_on_a_short_episode(case):
    from controllers import make_controller

    env_id, options, law_names = CASES[case]
    problem = episode_problem(env_id, seed=3, control_dt=1e-3, **options)
    grid = np.linspace(problem.v_min, problem.v_max, 9)
    constants = {f"constant {v:g}": np.full((problem.n_steps, 1), v) for v in grid}
    best_constant = max(problem.replay(V).ret for V in constants.values())
    laws = {name: problem.commands_of(lambda env, n=name: make_controller(n, env))
            for name in law_names}
    params = je.params_of_problem(problem, scheme="differentiable")
    _, s0 = je.reset(None, params, record=0)
    res = clairvoyant(je.episode_return, lambda V: problem.replay(V).ret, laws,
                      problem.v_min, problem.v_max, data=(params, s0), n_starts=1, max_iter=30)
    assert res.source == "optimiser"  # the optimiser improved on its warm start in the native environment
    assert res.ret == pytest.approx(problem.replay(res.commands).ret, abs=0.0)
    assert res.ret > best_constant
    for name in law_names:
        assert res.ret > res.warm_returns[name]
    assert np.all((res.commands >= problem.v_min) & (res.commands <= problem.v_max))


def test_bad_input_names_the_parameter():
    f = lambda V, data: V.sum()  # noqa: E731
    with pytest.raises(ValueError, match="n_starts"):
        clairvoyant(f, lambda V: 0.0, {"a": np.zeros((4, 1))}, 0.0, 1.0, n_starts=-1)
    with pytest.raises(ValueError, match=r"warm_starts\['b'\]"):
        clairvoyant(f, lambda V: 0.0, {"a": np.zeros((4, 1)), "b": np.zeros(4)}, 0.0, 1.0)
