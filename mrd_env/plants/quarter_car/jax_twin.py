"""The quarter car in JAX (needs the ``[jax]`` extra; importing it imports :mod:`mrd_env.jax`): ``make_params``, ``reset``, ``step`` and whole-episode ``rollout`` as pure functions of
:class:`EnvParams` and :class:`EnvState` (the gymnax layout), jit- and vmap-able, float64.

The physics and the reward are the native environment's (:mod:`mrd_env.plants.quarter_car`): the same plant
matrices and elimination matrices (built by :class:`~mrd_env.mechanics.CoupledPlant`), the same damper equations,
the command lag and its delay, the Wk-filtered sprung acceleration, the reward relative to the passive car on the
episode's road, the stroke limit and its penalty; the default sensors in the native order (float64 here), and
with ``preview`` the ``road_preview`` sensor after them as the native environment gives it.
Roads are a bank drawn once by :func:`make_params` with the project's generator (ISO 8608, ``method="fft"``), the
passive car's reference computed for each; :func:`reset` draws one from its key. :func:`native_roads` draws the
roads a native environment would meet at ``reset(seed=s)`` (the training mixture of classes and speeds).
"""
from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ...disturbances import iso8608_road
from ...envs import options as opt
from ...jax import scheme as sc
from ...jax.dampers import jax_damper
from ...mechanics import CoupledPlant
from ...metrics import weighting_sos
from ...stepping.scheme import ATOL, MAX_SUBSTEPS, OK, RTOL, max_level_of
from ...validation import check_scalar
from . import env as native
from .physics import quarter_car

#: The two schemes (:mod:`mrd_env.jax.scheme`).
SCHEMES = ("exact", "differentiable")
#: The default sensors, as the native environment's.
SENSORS = native.DEFAULT_SENSORS


@dataclasses.dataclass(frozen=True)
class EnvParams:
    """Everything an episode needs (arrays: pytree leaves) and the static choices (hashable fields: jit
    recompiles when they change)."""
    plant: sc.Plant
    A: jnp.ndarray          # (4, 4) state matrix of q' = [q, q̇]
    BF: jnp.ndarray         # (4, 1)
    Bw: jnp.ndarray         # (4, 3): z_r, ż_r and the static preload's channel
    P: jnp.ndarray          # (1, n_params) damper parameters
    lag: jnp.ndarray        # (1, 3) η_rise, η_fall, delay
    tyre: jnp.ndarray       # (2,) k_t, c_t
    sos: jnp.ndarray        # (n_sections, 6) the Wk weighting at 1/dt
    roads: jnp.ndarray      # (n_roads, rows [+ the longest preview], 2) z_r, ż_r at every physics step
    reward_scale: jnp.ndarray  # (n_roads, 3) the reward's weights × control_dt / the passive car's mean squares
    v_min: float
    v_max: float
    dt: float
    stroke_limit: float
    penalty: float          # the termination penalty: its rate × the planned episode length
    atol: float
    rtol: float
    model: str = dataclasses.field(metadata={"static": True}, default="spencer_dyke")
    scheme: str = dataclasses.field(metadata={"static": True}, default="exact")
    n_sub: int = dataclasses.field(metadata={"static": True}, default=10)
    n_steps: int = dataclasses.field(metadata={"static": True}, default=1000)
    queue: int = dataclasses.field(metadata={"static": True}, default=2)
    max_level: int = dataclasses.field(metadata={"static": True}, default=3)
    substeps: int = dataclasses.field(metadata={"static": True}, default=1)
    newton_iterations: int = dataclasses.field(metadata={"static": True}, default=2)
    normalized: bool = dataclasses.field(metadata={"static": True}, default=True)
    param_names: tuple = dataclasses.field(metadata={"static": True}, default=())  # the columns of P
    preview_steps: tuple = dataclasses.field(metadata={"static": True}, default=())  # road_preview's rows ahead


_STATIC = [f.name for f in dataclasses.fields(EnvParams) if f.metadata.get("static")]
jax.tree_util.register_dataclass(EnvParams, data_fields=[f.name for f in dataclasses.fields(EnvParams)
                                                         if f.name not in _STATIC], meta_fields=_STATIC)


class EnvState(NamedTuple):
    Y: jnp.ndarray        # (n,) plant [z_s, z_u, ż_s, ż_u] and damper states
    U: jnp.ndarray        # (1,) effective command
    F: jnp.ndarray        # (1,) damper force
    cmd: jnp.ndarray      # (1,) the command held over the last period
    queue: jnp.ndarray    # (queue, 1) past commands, newest first (the delay reads them)
    nsub: jnp.ndarray     # sub-steps to start the next step with (exact scheme)
    zi: jnp.ndarray       # (n_sections, 2) the Wk filter's state
    road: jnp.ndarray     # index of the episode's road in the bank
    k: jnp.ndarray        # control steps taken
    status: jnp.ndarray   # OK, or the stepping's failure code


def make_params(*, plant_preset: str = "set_a", damper: str = "spencer_dyke", damper_preset: str | None = None,
                damper_params=None, dt: float = 1e-3, control_dt: float = 0.01, episode_seconds: float = 10.0,
                road_class: str = "C", speed: float = 20.0, n_roads: int = 16, seed: int = 0, roads=None,
                scheme: str = "exact", substeps: int = 1, newton_iterations: int = 2,
                action_mode: str = "normalized", stroke_limit: float = 0.1, reward_weights=None,
                preview=None) -> EnvParams:
    """The quarter car's parameters with the native environment's defaults (``QuarterCar-v1``: 10 ms control,
    normalised actions). ``roads``: records with channels (z_r, ż_r) at ``dt`` (default: ``n_roads`` ISO 8608
    roads of ``road_class`` at ``speed`` drawn from ``seed``). ``scheme``: "exact" or "differentiable" (with
    ``substeps``, a power of two up to 8, and ``newton_iterations``). ``preview``: the native option (the times
    ahead, s): the observation ends with the ``road_preview`` sensor, z_r(t + τ) for each τ, the record's last
    height held beyond its end. Bad values raise ``ValueError`` naming the option."""
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    if not isinstance(substeps, int) or substeps < 1 or substeps > MAX_SUBSTEPS or substeps & (substeps - 1):
        raise ValueError(f"substeps must be a power of two in [1, {MAX_SUBSTEPS}], got {substeps!r}")
    if not isinstance(newton_iterations, int) or not 1 <= newton_iterations <= 12:
        raise ValueError(f"newton_iterations must be an integer in [1, 12], got {newton_iterations!r}")
    if action_mode not in ("normalized", "physical"):
        raise ValueError(f"action_mode must be 'normalized' or 'physical', got {action_mode!r}")
    dt, control_dt, episode_seconds = opt.time_steps(dt, control_dt, episode_seconds)
    n_sub = int(round(control_dt / dt))
    n_steps = int(round(episode_seconds / control_dt))
    ahead = tuple(int(round(t / dt)) for t in opt.preview_times(preview, dt))
    p = quarter_car(plant_preset)
    d = opt.make_env_damper(damper, damper_preset, damper_params, "automotive")
    model = jax_damper(d.name)
    lp = p.plant()
    system = CoupledPlant(lp, d).system
    max_level = max_level_of(MAX_SUBSTEPS)
    Ainv, Bbar, Mq, PP = system.levels(dt, max_level)
    rows = n_steps * n_sub + 1
    if roads is None:
        n_roads = int(check_scalar("n_roads", n_roads, 1, 100_000))
        roads = [iso8608_road(road_class, speed, episode_seconds, dt, rng=seed + i, method="fft")
                 for i in range(n_roads)]
    data, scales = [], []
    w = opt.weights(reward_weights, native.DEFAULT_REWARD_WEIGHTS)
    for i, rec in enumerate(roads):
        arr = np.asarray(rec.data, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < rows or not np.all(np.isfinite(arr)):
            raise ValueError(f"roads[{i}] must hold (z_r, zdot_r) at {rows} or more steps of dt, got shape "
                             f"{arr.shape}")
        q0 = np.array([arr[0, 0], arr[0, 0], arr[0, 1], arr[0, 1]])
        ref = native.passive_reference(p, rec, q0, rows, dt)
        scales.append([w[k] * control_dt / max(ref[k], 1e-12) for k in native.REWARD_SIGNALS])
        # the preview reads rows ahead of the episode's, from the record while it lasts (as native with_preview)
        data.append(arr[np.minimum(np.arange(rows + max(ahead, default=0)), len(arr) - 1)])
    limit = check_scalar("stroke_limit", stroke_limit, 0.0, lo_open=True, unit="m")
    return EnvParams(
        plant=sc.Plant(*(jnp.asarray(a) for a in (system.C, system.D, Ainv, Bbar, Mq, PP))),
        A=jnp.asarray(system.A), BF=jnp.asarray(system.BF), Bw=jnp.asarray(system.Bw),
        P=jnp.asarray(d.params.as_array()[None]), lag=jnp.asarray(d.command.lag_vector()[None]),
        tyre=jnp.asarray([p.k_t, p.c_t]), sos=jnp.asarray(weighting_sos("Wk", dt)),
        roads=jnp.asarray(np.stack(data)), reward_scale=jnp.asarray(scales),
        v_min=float(d.command.v_min), v_max=float(d.command.v_max), dt=dt, stroke_limit=limit,
        penalty=float(w["termination"] * episode_seconds), atol=ATOL, rtol=RTOL, model=model.name, scheme=scheme,
        n_sub=n_sub, n_steps=n_steps, queue=int(math.floor(d.command.delay / dt * (1 + 1e-12))) + 2,
        max_level=max_level, substeps=substeps, newton_iterations=newton_iterations,
        normalized=action_mode == "normalized", param_names=tuple(f.name for f in dataclasses.fields(d.params)),
        preview_steps=ahead)


def native_roads(road, seeds, *, dt: float = 1e-3, episode_seconds: float = 10.0) -> list:
    """The road records a native quarter-car environment with the option ``road`` (its spelling: a kind's name or
    ``{"kind": ..., **options}``, e.g. the training mixture of classes and speeds) meets at ``reset(seed=s)``
    for each of ``seeds``: the same generator, drawn from the same Gymnasium seeding, so that :func:`make_params`
    (``roads=``) gives the twin the native episodes' roads."""
    from gymnasium.utils.seeding import np_random

    from ...envs.roads import road_source

    source = road_source(road, None, dt, episode_seconds)
    return [source.sample(np_random(int(s))[0], dt) for s in seeds]


def _inputs(params: EnvParams, road, row):
    z = params.roads[road, row]
    return [z[0], z[1], jnp.asarray(1.0)]


def _signals(params: EnvParams, Y, F, w, cmd):
    """The default sensors' values and the reward's raw terms (sprung acceleration, travel, tyre load)."""
    q = [Y[i] for i in range(4)]
    acc = [sum((params.A[i, k] * q[k] for k in range(4)), 0.0) + params.BF[i, 0] * F[0]
           + sum((params.Bw[i, k] * w[k] for k in range(3)), 0.0) for i in (2, 3)]
    travel = q[0] - q[1]
    tyre = -params.tyre[0] * q[1] - params.tyre[1] * q[3] + params.tyre[0] * w[0] + params.tyre[1] * w[1]
    sensors = jnp.stack([acc[0], acc[1], travel, q[2] - q[3], q[2], q[3], F[0], cmd[0]])
    return sensors, acc[0], travel, tyre


def _observe(params: EnvParams, road, row, sensors):
    """The observation: the default sensors, then the road ahead (``road_preview``) if the params have one."""
    if not params.preview_steps:
        return sensors
    return jnp.concatenate([sensors, params.roads[road, row + jnp.asarray(params.preview_steps), 0]])


def _filter(sos, zi, x):
    """One sample through the second-order sections (transposed direct form II, as ``scipy.signal.sosfilt``)."""
    rows = []
    for s in range(sos.shape[0]):
        y = sos[s, 0] * x + zi[s, 0]
        z0 = sos[s, 1] * x - sos[s, 4] * y + zi[s, 1]
        z1 = sos[s, 2] * x - sos[s, 5] * y
        rows.append(jnp.stack([z0, z1]))
        x = y
    return x, jnp.stack(rows)


def reset(key, params: EnvParams, road=None):
    """(observation, state) of a new episode: a road of the bank drawn from ``key`` (or the index ``road``), the
    car at rest in static equilibrium on its initial height, the effective command at its minimum."""
    if road is None:
        road = jax.random.randint(key, (), 0, params.roads.shape[0])
    model = jax_damper(params.model)
    zr0, zrd0 = params.roads[road, 0, 0], params.roads[road, 0, 1]
    Y = [zr0, zr0, zrd0, zrd0] + [jnp.asarray(0.0)] * model.ns
    U = [jnp.asarray(params.v_min, jnp.float64)]  # strongly typed, as step returns it: no second compile
    w = _inputs(params, road, 0)
    F, finite = sc.end_forces(model, params.plant.C, params.plant.D, params.P, Y, U, w)
    state = EnvState(Y=jnp.stack(Y), U=jnp.stack(U), F=jnp.stack(F), cmd=jnp.stack(U),
                     queue=jnp.full((params.queue, 1), params.v_min, jnp.float64), nsub=jnp.asarray(1, jnp.int32),
                     zi=jnp.zeros((params.sos.shape[0], 2)), road=jnp.asarray(road, jnp.int32),
                     k=jnp.asarray(0, jnp.int32), status=jnp.where(finite, OK, sc.NONFINITE).astype(jnp.int32))
    return _observe(params, road, 0, _signals(params, Y, F, w, U)[0]), state


def command(params: EnvParams, action):
    """The damper command (V or A) of an action: clipped to the Box and mapped onto [v_min, v_max] when
    normalised."""
    a = jnp.asarray(action, jnp.float64).reshape(1)
    if params.normalized:
        a = params.v_min + (jnp.clip(a, -1.0, 1.0) + 1.0) * 0.5 * (params.v_max - params.v_min)
    return jnp.clip(a, params.v_min, params.v_max)


def step(key, state: EnvState, action, params: EnvParams):
    """One control period: (observation, state, reward, terminated, truncated, info). The command is held over
    the period's ``n_sub`` physics steps; ``info``: the effective command, the sub-steps used and the status."""
    model = jax_damper(params.model)
    exact = params.scheme == "exact"
    cmd = command(params, action)
    scale = params.reward_scale[state.road]
    m, s = sc.delay_split(params.lag[0, 2], params.dt)
    nd = 1

    def physics(carry, k):
        Y, U, F, queue, nsub, zi, work, status, total, hit, used_total = carry
        row = state.k * params.n_sub + k
        queue = jnp.concatenate([cmd[None], queue[:-1]])
        cmds = ([queue[m + 1, 0]], [queue[m, 0]], [s])
        w0, w1 = _inputs(params, state.road, row), _inputs(params, state.road, row + 1)
        st, Yn, Un, Fn, used, nsub_n, work = sc.macro_step(
            model, params.plant, params.P, [[params.lag[0, 0], params.lag[0, 1]]], cmds, [Y[i] for i in range(
                Y.shape[0])], [U[0]], [F[0]], w0, w1, params.dt, params.atol, params.rtol, nsub, work, exact=exact,
            max_level=params.max_level, substeps=params.substeps, newton_iterations=params.newton_iterations)
        running = status == OK
        Yn, Un, Fn = jnp.stack(Yn), jnp.stack(Un), jnp.stack(Fn)
        _, acc, travel, tyre = _signals(params, Yn, Fn, w1, cmd)
        a_w, zin = _filter(params.sos, zi, acc)
        ok = running & (st == OK)
        keep = lambda new, old: jnp.where(ok, new, old)  # noqa: E731  (a failed system stays as it was)
        total = total + jnp.where(ok, scale[0] * a_w * a_w + scale[1] * travel * travel + scale[2] * tyre * tyre,
                                  0.0)
        hit = hit | (ok & (jnp.abs(travel) > params.stroke_limit))
        status = jnp.where(running, st, status).astype(jnp.int32)
        return (keep(Yn, Y), keep(Un, U), keep(Fn, F), queue, keep(nsub_n, nsub), keep(zin, zi), work, status,
                total, hit, used_total + jnp.where(ok, used, 0)), None

    work = sc.empty_work(nd, model.ns)
    init = (state.Y, state.U, state.F, state.queue, state.nsub, state.zi, work, state.status, jnp.asarray(0.0),
            jnp.asarray(False), jnp.asarray(0))
    (Y, U, F, queue, nsub, zi, _, status, total, hit, used), _ = lax.scan(physics, init, jnp.arange(params.n_sub))
    k = state.k + 1
    diverged = status != OK
    terminated = hit | diverged
    reward = -total / params.n_sub - jnp.where(terminated, params.penalty, 0.0)
    truncated = ~terminated & (k >= params.n_steps)
    new = EnvState(Y=Y, U=U, F=F, cmd=cmd, queue=queue, nsub=nsub, zi=zi, road=state.road, k=k, status=status)
    w = _inputs(params, state.road, k * params.n_sub)
    obs = _observe(params, state.road, k * params.n_sub, _signals(params, Y, F, w, cmd)[0])
    info = {"effective_command": U[0], "substeps": used / params.n_sub, "status": status}
    return obs, new, reward, terminated, truncated, info


def rollout(params: EnvParams, state: EnvState, actions):
    """A whole episode (or ``len(actions)`` steps) in one ``lax.scan``: (final state, observations, rewards,
    terminated, truncated), without autoreset (the steps after an episode's end repeat its last state)."""
    def body(carry, a):
        st, done = carry
        obs, new, r, term, trunc, _ = step(None, st, a, params)
        new = jax.tree_util.tree_map(lambda x, y: jnp.where(done, x, y), st, new)
        return (new, done | term | trunc), (obs, jnp.where(done, 0.0, r), term & ~done, trunc & ~done)

    (state, _), out = lax.scan(body, (state, jnp.asarray(False)), actions)
    return (state, *out)


def step_autoreset(key, state: EnvState, action, params: EnvParams):
    """:func:`step`, then a new episode (a road drawn from ``key``) in place of one that ended, in the same call
    (gymnax's convention): the returned observation and state are the new episode's; ``info["final_observation"]``
    holds the ended one's last observation."""
    obs, new, reward, terminated, truncated, info = step(key, state, action, params)
    done = terminated | truncated
    obs0, state0 = reset(key, params)
    new = jax.tree_util.tree_map(lambda a, b: jnp.where(done, a, b), state0, new)
    info = {**info, "final_observation": obs}
    return jnp.where(done, obs0, obs), new, reward, terminated, truncated, info


def params_of_problem(problem, **options) -> EnvParams:
    """The twin of an :class:`~mrd_env.optimal.EpisodeProblem` of the quarter car (physical commands at its
    control step, its road as the bank's only one; the plant, damper, stroke limit and reward weights from its
    options); ``options``: the scheme's (``scheme``, ``substeps``, ``newton_iterations``)."""
    keep = ("plant_preset", "damper", "damper_preset", "damper_params", "stroke_limit", "reward_weights")
    road = np.asarray(problem.W[:, :2], dtype=np.float64)
    return make_params(**{k: problem.options[k] for k in keep if k in problem.options}, dt=problem.dt,
                       control_dt=problem.control_dt, episode_seconds=problem.duration, action_mode="physical",
                       roads=[_Road(road)], **options)


def episode_return(actions, data):
    """The return of a whole episode under ``actions`` from ``data`` = (params, its first state): the function
    :func:`mrd_env.jax.clairvoyant.clairvoyant` maximises."""
    params, state = data
    return rollout(params, state, actions)[2].sum()


class _Road(NamedTuple):
    data: np.ndarray


#: The bands :func:`draw_params` draws (the robustness twin's, ``ROBUST_BANDS`` of the plant's suites).
DRAWN_BANDS = ("damper_params", "command")


def draw_params(key, params: EnvParams, bands: dict) -> EnvParams:
    """``params`` with an episode's draw of ``bands`` (the robustness twin's layout): ``damper_params``
    {name: (lo, hi)}, each parameter × U(lo, hi); ``command`` {"eta": (lo, hi)}, the lag rate (rise and fall) ×
    U(lo, hi). Only arrays change, so a batch of draws (``jax.vmap(lambda k: draw_params(k, params, bands))(keys)``,
    stepped with ``in_axes=0`` for the parameters) runs the same compiled step as the nominal one. Other bands (the
    delay, masses and stiffnesses: they change the queue's length or the eliminated plant matrices) raise
    ``ValueError`` naming them."""
    other = sorted(set(bands) - set(DRAWN_BANDS) - {"seed"}) + sorted(
        f"command.{k}" for k in bands.get("command", {}) if k != "eta")
    if other:
        raise ValueError(f"draw_params draws only damper_params and command.eta, got the bands {other}")
    unknown = sorted(set(bands.get("damper_params", {})) - set(params.param_names))
    if unknown:
        raise ValueError(f"damper_params bands must name parameters among {params.param_names}, got {unknown}")
    items = [(params.param_names.index(n), b) for n, b in bands.get("damper_params", {}).items()]
    eta = bands.get("command", {}).get("eta")
    lo = jnp.asarray([b[0] for _, b in items] + ([eta[0]] if eta else []), jnp.float64)
    hi = jnp.asarray([b[1] for _, b in items] + ([eta[1]] if eta else []), jnp.float64)
    f = jax.random.uniform(key, lo.shape, jnp.float64, lo, hi)
    P, lag = params.P, params.lag
    if items:
        P = P.at[0, jnp.asarray([i for i, _ in items])].multiply(f[:len(items)])
    if eta:
        lag = lag.at[0, :2].multiply(f[-1])
    return dataclasses.replace(params, P=P, lag=lag)


def drawn_options(params: EnvParams, nominal: EnvParams) -> dict:
    """The native environment's ``damper_params`` option of one draw of :func:`draw_params` (unbatched):
    the drawn values of every parameter that changed, and ``command`` {"eta"} if the lag rate did."""
    P, P0 = np.asarray(params.P[0]), np.asarray(nominal.P[0])
    out: dict = {n: float(P[i]) for i, n in enumerate(params.param_names) if P[i] != P0[i]}
    if float(params.lag[0, 0]) != float(nominal.lag[0, 0]):
        out["command"] = {"eta": float(params.lag[0, 0])}
    return {"damper_params": out}
