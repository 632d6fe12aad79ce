"""The clairvoyant's penalty on the limits in the JAX twin (:attr:`mrd_env.jax.env.EnvParams.limit_penalty`,
procedure 5): the return it takes off is ρ Σ relu(|s|/b − margin)² over the physics rows, computed here from the
native environment's own states, and nothing is taken off without it."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from mrd_env.jax import env as je  # noqa: E402
from mrd_env.optimal import episode_problem  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")

ENV_ID = "mrd_env/QuarterCarPhysical-v0"


@pytest.fixture(scope="module")
def episode():
    p = episode_problem(ENV_ID, seed=3, control_dt=0.01, episode_seconds=0.3, road="iso8608",
                        road_params={"road_class": "D", "speed": 20.0})
    params = je.params_of_problem(p, scheme="exact")
    _, s0 = je.reset(None, params, record=0)
    return p, params, s0


def test_the_penalty_is_the_native_rows_excess_over_the_margin(episode):
    p, params, s0 = episode
    V = np.full((p.n_steps, p.nd), p.v_min)  # the softest damper: the largest strokes
    tr = p.replay(V, states=True)
    assert not tr.terminated and p.limits
    rho, margin = 1e3, 0.1  # a small margin, so that many rows are over it
    z = np.concatenate([tr.X, tr.F, p.W[:p.n_rows]], axis=1)[1:]  # the rows after each physics step
    expected = sum(rho * np.sum(np.maximum(np.abs(z @ np.atleast_2d(L.G).T).ravel() / L.bound - margin, 0.0) ** 2)
                   for L in p.limits)
    assert expected > 0
    plain = float(je.episode_return(V, (params, s0)))
    penalised = float(je.episode_return(V, (dataclasses.replace(params, limit_penalty=(rho, margin)), s0)))
    assert plain == pytest.approx(p.replay(V).ret, rel=1e-9)  # the exact scheme is the environment
    # the rows' replay steps at dt, so its error control differs from the 10 ms episode's: 2e-5 of the return
    assert plain - penalised == pytest.approx(expected, rel=1e-4)


def test_no_penalty_below_the_margin(episode):
    p, params, s0 = episode
    V = np.full((p.n_steps, p.nd), p.v_max)
    plain = float(je.episode_return(V, (params, s0)))
    assert float(je.episode_return(V, (dataclasses.replace(params, limit_penalty=(1e3, 0.98)), s0))) == plain
