"""Every plant's environment in JAX: the native driver's period (:mod:`mrd_env.stepping`, ``_driver_template.py``)
as pure functions of :class:`EnvParams` and :class:`EnvState` (the gymnax layout), jit- and vmap-able, float64.

The twin is made from the plant's own :class:`~mrd_env.envs.core.Assembly` (:func:`make_params`: an environment
id and its options, as ``gymnasium.make`` takes them), so every fact comes from the plant's folder once: the coupled
plant and its elimination matrices, the damper and its command lag and delay, the named signals' rows G
(h = G·[Y, F, w]), the online filters (the cars' Wk weighting), the reward's signals and per-episode scales, the
limits that end an episode and their penalty, the constraint costs, the sensors (with their noise, delay and
history). The records are a bank drawn once with the plant's own disturbance and the native environment's
seeding (the records ``reset(seed=s)`` meets), each turned into an episode by the plant's ``new_episode`` (the
passive car's or the uncontrolled building's reference scales, the initial state, the road ahead of a preview).

The step is the driver's: the command held over the period's ``n_sub`` physics steps through the delay queue,
:func:`mrd_env.jax.scheme.macro_step` (``exact`` or ``differentiable``), the row h, the filters, the reward's
integral over the period, the limits (``terminated``; an episode that diverges is ``terminated`` too, with the
penalty alone as its reward, as the native one), the time in violation of each cost term (``info["cost"]``, s),
the measurement with its noise (from the step's key), delay and history. Not here: the episode metrics' statistics
(the native environment's), Python-callable rewards and ``action_mode="force"`` (they raise ``ValueError``).
"""
from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..disturbances import Record
from ..resources import check as check_memory, format_bytes, record_bytes
from ..stepping.scheme import ATOL, MAX_SUBSTEPS, OK, RTOL, max_level_of
from . import scheme as sc
from .dampers import JACOBIANS, jax_damper

#: The two schemes (:mod:`mrd_env.jax.scheme`).
SCHEMES = ("exact", "differentiable")


@dataclasses.dataclass(frozen=True)
class EnvParams:
    """Everything an episode needs (arrays: pytree leaves) and the static choices (hashable fields: ``jit``
    recompiles when they change)."""
    # the plant and damper of each episode (leading axis E: 1, or one per episode of the bank when they are drawn)
    plant: sc.Plant         # (E, ...) the coupled plant's matrices (mrd_env.jax.scheme.Plant)
    G: jnp.ndarray          # (E, n_signals, n + nd + nw) the named signals' rows
    P: jnp.ndarray          # (E, nd, n_params) damper parameters
    lag: jnp.ndarray        # (E, nd, 3) η_rise, η_fall, delay
    noise: jnp.ndarray      # (E, n_measured) the sensors' noise standard deviations
    sensor_delay: jnp.ndarray  # (E,) the sensors' delay, control steps
    cost_limits: jnp.ndarray  # (E, n_cost_columns) the constraints' limits (a car's tyre load: its static load)
    sos: jnp.ndarray        # (n_sections, 6) every filter's second-order sections
    W: jnp.ndarray          # (n_records, rows, nw) the bank's inputs at every physics step, the last row held
    Y0: jnp.ndarray         # (n_records, n) each episode's initial state
    reward_scale: jnp.ndarray  # (n_records, n_reward_terms) the reward's weights × control_dt, per episode
    steps: jnp.ndarray      # (n_records,) control steps of each episode
    limits: jnp.ndarray     # (n_limit_columns,)
    v_min: float
    v_max: float
    dt: float
    penalty: float          # the termination penalty's constant part
    penalty_step: float     # and its part per control step of the episode's planned length
    atol: float
    rtol: float
    model: str = dataclasses.field(metadata={"static": True}, default="spencer_dyke")
    scheme: str = dataclasses.field(metadata={"static": True}, default="exact")
    n_sub: int = dataclasses.field(metadata={"static": True}, default=10)
    n_steps: int = dataclasses.field(metadata={"static": True}, default=1000)  # the bank's longest episode
    queue: int = dataclasses.field(metadata={"static": True}, default=2)
    max_level: int = dataclasses.field(metadata={"static": True}, default=3)
    substeps: int = dataclasses.field(metadata={"static": True}, default=1)
    newton_iterations: int = dataclasses.field(metadata={"static": True}, default=2)
    jacobian: str = dataclasses.field(metadata={"static": True}, default="kernel")  # the Newton matrix's damper part
    normalized: bool = dataclasses.field(metadata={"static": True}, default=True)
    width: int = dataclasses.field(metadata={"static": True}, default=0)  # columns of the row h
    reward_cols: tuple = dataclasses.field(metadata={"static": True}, default=())
    limit_cols: tuple = dataclasses.field(metadata={"static": True}, default=())
    cost_cols: tuple = dataclasses.field(metadata={"static": True}, default=())
    cost_sides: tuple = dataclasses.field(metadata={"static": True}, default=())
    cost_terms: tuple = dataclasses.field(metadata={"static": True}, default=(0,))  # each term's first column
    filters: tuple = dataclasses.field(metadata={"static": True}, default=())  # (in, out, first section, count)
    meas_cols: tuple = dataclasses.field(metadata={"static": True}, default=())
    max_delay: int = dataclasses.field(metadata={"static": True}, default=0)  # the FIFO's depth beyond history
    history: int = dataclasses.field(metadata={"static": True}, default=1)
    noisy: bool = dataclasses.field(metadata={"static": True}, default=False)
    param_names: tuple = dataclasses.field(metadata={"static": True}, default=())  # the columns of P
    cost_names: tuple = dataclasses.field(metadata={"static": True}, default=())
    kind: str = dataclasses.field(metadata={"static": True}, default="")  # the plant's name
    drawn: bool = dataclasses.field(metadata={"static": True}, default=False)  # a plant per episode (E = records)
    #: (ρ, margin): a clairvoyant's objective, not the environment's: each period's reward less ρ Σ relu(|s|/b −
    #: margin)² over its physics steps and the limits' signals s (bounds b), the CasADi path's exterior penalty
    #: (:data:`mrd_env.optimal.full_knowledge.LIMIT_PENALTY`), so that an optimum keeps off the limits the
    #: environment ends an episode at; () (the environment): none
    limit_penalty: tuple = dataclasses.field(metadata={"static": True}, default=())

    @property
    def nd(self) -> int:
        return self.P.shape[1]

    @property
    def control_dt(self) -> float:
        return self.dt * self.n_sub


_STATIC = [f.name for f in dataclasses.fields(EnvParams) if f.metadata.get("static")]
jax.tree_util.register_dataclass(EnvParams, data_fields=[f.name for f in dataclasses.fields(EnvParams)
                                                         if f.name not in _STATIC], meta_fields=_STATIC)


class EnvState(NamedTuple):
    Y: jnp.ndarray        # (n,) plant [q, q̇] and damper states
    U: jnp.ndarray        # (nd,) effective commands
    F: jnp.ndarray        # (nd,) damper forces
    cmd: jnp.ndarray      # (nd,) the commands held over the last period
    queue: jnp.ndarray    # (queue, nd) past commands, newest first (the delay reads them)
    nsub: jnp.ndarray     # sub-steps to start the next step with (exact scheme)
    zi: jnp.ndarray       # (n_sections, 2) the filters' states
    fifo: jnp.ndarray     # (max_delay + history, n_measured) past measurements, newest first
    cost: jnp.ndarray     # (1 + n_terms,) the episode's time in violation (s): of any term, of each
    record: jnp.ndarray   # index of the episode's record in the bank
    k: jnp.ndarray        # control steps taken
    status: jnp.ndarray   # OK, or the stepping's failure code


def assembly_of(env_id: str, options: dict):
    """The native :class:`~mrd_env.envs.core.Assembly` of ``gymnasium.make(env_id, **options)`` (the id's
    registered options first) and the environment's class."""
    import gymnasium
    from gymnasium.envs.registration import load_env_creator

    from ..envs.core import assemble

    try:
        spec = gymnasium.spec(env_id)
    except gymnasium.error.Error as exc:
        raise ValueError(f"env_id: {exc}") from None
    cls = getattr(load_env_creator(spec.entry_point), "env_class", None) if isinstance(spec.entry_point, str) \
        else None
    if cls is None or not hasattr(cls, "build"):
        raise ValueError(f"env_id must be an id of an mrd_env environment, got {env_id!r}")
    return assemble(cls, {**spec.kwargs, **options}, own=()), cls


def native_records(asm, seeds) -> list:
    """The records a native environment of ``asm`` meets at ``reset(seed=s)`` for each of ``seeds`` (its
    disturbance drawn from the same Gymnasium seeding)."""
    from gymnasium.utils.seeding import np_random

    return [asm.disturbance.sample(np_random(int(s))[0], asm.dt) for s in seeds]


def _check_scheme(scheme, substeps, newton_iterations, jacobian) -> None:
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    if not isinstance(substeps, int) or substeps < 1 or substeps > MAX_SUBSTEPS or substeps & (substeps - 1):
        raise ValueError(f"substeps must be a power of two in [1, {MAX_SUBSTEPS}], got {substeps!r}")
    if not isinstance(newton_iterations, int) or not 1 <= newton_iterations <= 12:
        raise ValueError(f"newton_iterations must be an integer in [1, 12], got {newton_iterations!r}")
    if jacobian not in JACOBIANS or (jacobian == "exact" and scheme == "exact"):
        raise ValueError(f"jacobian must be one of {JACOBIANS} ('exact' with the differentiable scheme: the exact "
                         f"scheme iterates as the kernel does), got {jacobian!r} with scheme={scheme!r}")


def _structure(asm) -> dict:
    """What every episode of one twin must share (the compiled step's shapes and static choices)."""
    from ..envs.costs import Costs
    from ..envs.reward import CallableReward

    if isinstance(asm.reward, CallableReward):
        raise ValueError("reward: the JAX twin takes the plant's quadratic reward (reward_weights), not a Python "
                         "callable")
    if asm.action_mode not in ("normalized", "physical"):
        raise ValueError(f"action_mode must be 'normalized' or 'physical' in the JAX twin, got {asm.action_mode!r}")
    sig, d = asm.signals, asm.damper
    costs = asm.costs if asm.costs is not None else Costs()
    meas_cols = asm.sensors.bind(sig, asm.sensor_names)[0]
    rcols = asm.reward.bind(sig)[0]
    lcols, limits = asm.limits.bind(sig)
    return {"damper": d.name, "shapes": (asm.coupled.n, asm.coupled.system.nw, sig.G.shape, sig.width),
            "dt": (asm.dt, asm.n_sub), "command": (d.command.v_min, d.command.v_max),
            "sensors": (tuple(meas_cols), asm.sensors.history), "reward": tuple(rcols),
            "limits": (tuple(lcols), tuple(limits), asm.limits.penalty, asm.limits.penalty_rate),
            "costs": (costs.names, *(v for i, v in enumerate(costs.bind(sig)) if i != 1)), "action_mode": asm.action_mode,
            "filters": tuple((i, o, np.asarray(f).tobytes()) for i, o, f in asm.filters)}


# --- memory: estimated before anything is allocated (mrd_env.resources) ------------------------------------
#: Bytes a batched step takes per byte of one environment's arrays (:func:`env_floats`): the state it reads and
#: the one it returns, the new episode every step prepares for an autoreset, and the compiled step's temporaries;
#: and per element of the dampers' Newton blocks (one (k + 1) × (k + 1) block per damper, k its states: the batched
#: scheme eliminates the plant and solves each damper's block, never the whole m × m matrix of several dampers).
#: Fitted to XLA's ``memory_analysis`` of the vmapped step and the resident memory of large batches
#: (``experiments/measurements/memory/jax_bank.py``, docs/jax.md).
STEP_FACTOR = 3
NEWTON_FACTOR = 24


def env_floats(asm) -> int:
    """Floats of one environment of a batch: its state (plant, dampers, command queue, filters, sensor FIFO, costs,
    counters), its damper's draw and lag, its key, observation and action, and one row h with its inputs."""
    from ..envs.costs import Costs

    sig, s = asm.signals, asm.coupled.system
    nd, n = s.nd, asm.coupled.n
    n_meas = len(asm.sensors.bind(sig, asm.sensor_names)[0])
    sections = sum(len(np.atleast_2d(np.asarray(f))) for _, _, f in asm.filters)
    terms = len((asm.costs if asm.costs is not None else Costs()).names)
    queue = int(float(asm.damper.command.lag_vector()[2]) / asm.dt) + 2
    n_params = len(dataclasses.fields(asm.damper.params))
    return (n + nd * (3 + queue + n_params + 3 + 1) + 2 * sections
            + (asm.sensors.delay + 2 * asm.sensors.history) * n_meas + terms + 1 + 6 + sig.width + s.nw)


def plant_bytes(asm) -> int:
    """Bytes of one episode's plant in a bank that draws a plant per episode (``randomise`` beyond the damper):
    the elimination matrices of every sub-step level, the output matrices and the signals' rows."""
    s = asm.coupled.system
    levels = s.levels(asm.dt, max_level_of(MAX_SUBSTEPS))  # cached by the plant: computed once
    return int(sum(np.asarray(a).nbytes for a in (*levels, s.C, s.D, asm.signals.G)))


#: The most episodes a bank holds (``seeds``).
MAX_SEEDS = 100_000


def seed_list(seeds) -> list[int]:
    """``seeds`` as a list of ints, its length (1 to :data:`MAX_SEEDS`) checked before the list is made."""
    try:
        n = len(seeds)
    except (TypeError, OverflowError):
        n = None  # a generator: counted as it is listed, never past the bound
    if n is not None and not 1 <= n <= MAX_SEEDS:
        raise ValueError(f"seeds must name 1 to {MAX_SEEDS} episodes, got {n}")
    out = []
    for s in seeds:
        if len(out) == MAX_SEEDS:
            raise ValueError(f"seeds must name 1 to {MAX_SEEDS} episodes, got more")
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0:
            raise ValueError(f"seeds must be ints >= 0, got {s!r}")
        out.append(int(s))
    if not out:
        raise ValueError(f"seeds must name 1 to {MAX_SEEDS} episodes, got 0")
    return out


def record_samples(asm, seeds) -> int:
    """Samples of the longest record the bank of ``seeds`` holds: the disturbance's bound, else the first seed's
    record (a disturbance of unknown length: every record of a seeded bank is assumed that long)."""
    n = asm.disturbance.max_samples
    if n is None:
        n = native_records(asm, list(seeds)[:1])[0].n_samples
    if asm.episode_seconds is not None:
        n = min(n, int(round(asm.episode_seconds / asm.dt)) + 1)
    return int(n)


def bank_parts(asm, n_episodes: int, n_samples: int, *, drawn: bool = False, generated: bool = True) -> dict:
    """The estimate {what: bytes} of a bank of ``n_episodes`` on records of ``n_samples``: the records, the inputs W at every physics step, generating one record
    (``generated``), one episode's data from the plant's ``new_episode`` (dropped before the next) and, ``drawn``, every
    episode's own plant (its assembly's and the stacked copy)."""
    FLOAT = 8
    nw = asm.coupled.system.nw
    rows = asm.episode_steps(n_samples) * asm.n_sub + 1
    E = f"{n_episodes} episode{'s' if n_episodes != 1 else ''}"
    parts = {f"the records ({E} × {n_samples} samples × {nw - 1} channels)": n_episodes * n_samples * FLOAT * (nw - 1),
             f"the inputs W ({E} × {rows} rows × {nw} columns)": n_episodes * rows * nw * FLOAT,
             # one episode at a time: the bank keeps its inputs, not the plant's per-episode data
             "the episode's data computed at a reset": (asm.episode_floats + asm.reset_floats) * n_samples * FLOAT}
    if generated and asm.disturbance.random:
        parts["generating a record"] = record_bytes(n_samples, nw - 1, generated=True)
    if drawn:
        parts[f"the plant of each episode ({E})"] = 2 * n_episodes * plant_bytes(asm)
    return parts


def batch_parts(asm, num_envs: int, *, drawn: bool = False) -> dict:
    """The estimate {what: bytes} of ``num_envs`` environments stepped together (:data:`STEP_FACTOR` × their
    arrays and :data:`NEWTON_FACTOR` × their Newton blocks; ``drawn``: each step also gathers its episode's plant)."""
    s = asm.coupled.system
    m = s.nd + (asm.coupled.n - s.nq)  # the Newton unknowns: each damper's force and internal states
    blocks = s.nd * (m // s.nd) ** 2  # a block per damper
    each = 8 * (STEP_FACTOR * env_floats(asm) + NEWTON_FACTOR * blocks) + (plant_bytes(asm) if drawn else 0)
    who = f"{num_envs} environments'" if num_envs != 1 else "1 environment's"
    return {f"{who} state and step ({format_bytes(each)} each)": num_envs * each}


def check_bank(asm, *, seeds=None, records=None, num_envs: int = 0, drawn: bool = False) -> float:
    """``ValueError`` naming the options (``seeds`` or ``records``, ``num_envs``), the estimate and the limit
    (:func:`mrd_env.resources.check`) if the bank and a batch of ``num_envs`` exceed the memory limit; called before
    any record is drawn or array made. The estimate (bytes) otherwise."""
    if records is not None:
        n_ep, n = len(records), max((int(getattr(r, "n_samples", 0)) for r in records), default=1)
        cause = [f"records ({n_ep} records of up to {n} samples)"]
        parts = bank_parts(asm, n_ep, n, drawn=drawn, generated=False)
        parts.pop(next(k for k in parts if k.startswith("the records")))  # the caller's own arrays
    else:
        n_ep, n = len(seeds), record_samples(asm, seeds)
        cause = [f"seeds ({n_ep} episodes of {(n - 1) * asm.dt:g} s at dt={asm.dt:g} s)"]
        parts = bank_parts(asm, n_ep, n, drawn=drawn)
    if num_envs:
        parts.update(batch_parts(asm, num_envs, drawn=drawn))
        cause.insert(0, f"num_envs={num_envs}")
    return check_memory(parts, ", ".join(cause))


def params_of_episodes(episodes, *, scheme: str = "exact", substeps: int = 1, newton_iterations: int = 2,
                       jacobian: str = "kernel", name: str = "records") -> EnvParams:
    """The twin of a bank of episodes ``[(assembly, record), ...]``: each record (a
    :class:`~mrd_env.disturbances.Record` of the plant's disturbance channels at the assembly's dt) made an episode
    by its assembly's ``new_episode``. One assembly for every record gives one plant; one per record (the
    robustness twins' drawn plants, dampers, command lags, sensor noise and delays) gives each episode its own,
    all of one structure (the same damper model, signals, sensors, reward terms, limits and costs: ``ValueError``
    naming what differs). ``name``: the option's name in error messages; ``jacobian``: the damper's Jacobian in the
    Newton matrix, "kernel" (the numba kernel's: analytic or forward differences) or "exact" (``jax.jacfwd``,
    differentiable scheme only)."""
    from ..envs.costs import Costs

    _check_scheme(scheme, substeps, newton_iterations, jacobian)
    episodes = list(episodes)
    if not episodes:
        raise ValueError(f"{name}: the bank needs one record or more")
    asms = list({id(a): a for a, _ in episodes}.values())
    asm = asms[0]
    shared = _structure(asm)
    for other in asms[1:]:
        theirs = _structure(other)
        differ = sorted(k for k in shared if shared[k] != theirs[k])
        if differ:
            raise ValueError(f"{name}: every episode of a twin must have the same {differ} (the compiled step's "
                             f"structure)")
    drawn = len(asms) > 1
    sig, system = asm.signals, asm.coupled.system
    model = jax_damper(asm.damper.name)
    costs = asm.costs if asm.costs is not None else Costs()
    ccols, _, csides, cterms = costs.bind(sig)
    rcols = asm.reward.bind(sig)[0]
    lcols, limits = asm.limits.bind(sig)
    sos, filters = [], []
    for i, o, f in asm.filters:
        f = np.atleast_2d(np.asarray(f, dtype=np.float64))
        filters.append((int(sig[i].columns[0]), int(sig[o].columns[0]), sum(len(x) for x in sos), len(f)))
        sos.append(f)
    max_level = max_level_of(MAX_SUBSTEPS)
    n_sub, n2, n_in = asm.n_sub, 2 * asm.linear_plant.n_dof, system.nw - 1

    def plant_of(a) -> dict:
        s = a.coupled.system
        Ainv, Bbar, Mq, PP = s.levels(a.dt, max_level)
        d = a.damper
        return {"plant": (s.C, s.D, Ainv, Bbar, Mq, PP), "G": a.signals.G,
                "P": np.stack([d.params.as_array()] * s.nd), "lag": np.stack([d.command.lag_vector()] * s.nd),
                "noise": a.sensors.bind(a.signals, a.sensor_names)[1], "sensor_delay": a.sensors.delay,
                "cost_limits": np.asarray(((a.costs if a.costs is not None else Costs()).bind(a.signals))[1],
                                          np.float64)}

    plants = [plant_of(a) for a in (asms if not drawn else [a for a, _ in episodes])]
    stack = lambda key: np.stack([np.asarray(p[key]) for p in plants])  # noqa: E731
    steps, W_rows, Y0, scales = [], [], [], []
    for b, (a, rec) in enumerate(episodes):
        if not isinstance(rec, Record) or abs(rec.dt - a.dt) > 1e-9 * a.dt:
            raise ValueError(f"{name}[{b}] must be a Record at dt={a.dt:g} s, got {type(rec).__name__}"
                             + (f" at dt={rec.dt:g} s" if isinstance(rec, Record) else ""))
        n = a.episode_steps(rec.n_samples)
        if n < 1:
            raise ValueError(f"{name}[{b}] ({rec.duration:g} s) is shorter than one control period "
                             f"({a.control_dt:g} s)")
        ep = a.new_episode(rec)
        r = n * n_sub + 1
        data = np.asarray(ep.record.data, dtype=np.float64)
        if data.ndim != 2 or data.shape[1] != n_in or not np.all(np.isfinite(data[:r])):
            raise ValueError(f"{name}[{b}] must hold the {n_in} input channels {a.linear_plant.input_names}, "
                             f"finite, got shape {data.shape}")
        y0 = np.zeros(a.coupled.n)
        if ep.q0 is not None:
            y0[:n2] = ep.q0
        y0[n2:] = a.damper.rest_states(a.coupled.system.Cx @ y0[:n2])
        steps.append(n)
        W_rows.append(data[:r])
        Y0.append(y0)
        scales.append(a.reward.scales(ep, a.reward.bind(a.signals)[1] * a.control_dt))
    rows = max(steps) * n_sub + 1
    W = np.zeros((len(episodes), rows, system.nw))
    for b, data in enumerate(W_rows):
        r = len(data)
        W[b, :r, :n_in] = data
        W[b, :r, n_in] = 1.0  # the constant channel that balances the static preload
        W[b, r:] = W[b, r - 1]
    delays = stack("sensor_delay")
    lags = stack("lag")
    noise = stack("noise")
    return EnvParams(
        plant=sc.Plant(*(jnp.asarray(np.stack([p["plant"][k] for p in plants])) for k in range(6))),
        G=jnp.asarray(stack("G")), P=jnp.asarray(stack("P")), lag=jnp.asarray(lags), noise=jnp.asarray(noise),
        sensor_delay=jnp.asarray(delays, jnp.int32),
        sos=jnp.asarray(np.concatenate(sos) if sos else np.zeros((0, 6))), W=jnp.asarray(W),
        Y0=jnp.asarray(np.stack(Y0)), reward_scale=jnp.asarray(np.stack(scales)),
        steps=jnp.asarray(steps, jnp.int32), limits=jnp.asarray(limits, jnp.float64),
        cost_limits=jnp.asarray(stack("cost_limits")), v_min=float(asm.damper.command.v_min),
        v_max=float(asm.damper.command.v_max), dt=float(asm.dt), penalty=float(asm.limits.penalty),
        penalty_step=float(asm.limits.penalty_rate * asm.control_dt), atol=ATOL, rtol=RTOL, model=model.name,
        scheme=scheme, n_sub=n_sub, n_steps=max(steps),
        queue=int(math.floor(float(lags[..., 2].max()) / asm.dt * (1 + 1e-12))) + 2, max_level=max_level,
        substeps=substeps, newton_iterations=newton_iterations, jacobian=jacobian,
        normalized=asm.action_mode == "normalized", width=sig.width, reward_cols=tuple(int(c) for c in rcols),
        limit_cols=tuple(int(c) for c in lcols), cost_cols=tuple(ccols), cost_sides=tuple(csides),
        cost_terms=tuple(cterms), filters=tuple(filters),
        meas_cols=tuple(int(c) for c in asm.sensors.bind(sig, asm.sensor_names)[0]), max_delay=int(delays.max()),
        history=int(asm.sensors.history), noisy=bool(np.any(noise > 0)),
        param_names=tuple(f.name for f in dataclasses.fields(asm.damper.params)), cost_names=costs.names,
        kind=asm.kind, drawn=drawn)


def params_of_assembly(asm, records, **scheme) -> EnvParams:
    """The twin of one assembly on the bank ``records`` (:func:`params_of_episodes`)."""
    return params_of_episodes([(asm, r) for r in records], **scheme)


def make_params(env_id: str, *, seeds=range(16), records=None, randomise=None, scheme: str = "exact",
                substeps: int = 1, newton_iterations: int = 2, jacobian: str = "kernel", **options) -> EnvParams:
    """The twin of ``gymnasium.make(env_id, **options)`` (any mrd_env id and its options) on a bank of episodes:
    ``records`` (the plant's disturbance, e.g. road records), else those a native environment meets at
    ``reset(seed=s)`` for each of ``seeds``. ``randomise``: bands in the robustness twins' layout
    (:func:`mrd_env.suites.draw_episode`: damper parameters, command lag and delay, plant parameters, sensor noise
    and delay; its ``seed``), one draw per seed, each episode's environment built with its draw by the plant's own
    code (so the episodes are those of ``gymnasium.make(env_id, **options, **draw)``). ``scheme``: "exact" or
    "differentiable" (with ``substeps``, a power of two up to 8, ``newton_iterations`` and ``jacobian``:
    :func:`params_of_episodes`). Bad values raise ``ValueError`` naming the option; a bank above
    ``MRD_ENV_MEMORY_LIMIT`` too, before any record is drawn (:func:`check_bank`)."""
    scheme_options = {"scheme": scheme, "substeps": substeps, "newton_iterations": newton_iterations,
                      "jacobian": jacobian}
    _check_scheme(**scheme_options)
    asm, _ = assembly_of(env_id, options)
    if records is None:
        seeds = seed_list(seeds)
        check_bank(asm, seeds=seeds, drawn=randomise is not None)
    else:
        records = list(records)
        check_bank(asm, records=records)
    if randomise is None:
        return params_of_assembly(asm, native_records(asm, seeds) if records is None else records,
                                  **scheme_options)
    if records is not None:
        raise ValueError("randomise draws a plant per seed: give seeds, not records")
    return params_of_episodes(drawn_episodes(env_id, options, randomise, seeds), **scheme_options)


def drawn_episodes(env_id: str, options: dict, randomise: dict, seeds) -> list:
    """[(assembly, record)] of each seed's draw of the bands ``randomise`` (:func:`mrd_env.suites.draw_episode`,
    scenario 0): the native environment built with the draw and the record it meets at ``reset(seed=s)``."""
    from ..suites import draw_episode, nominal_values

    if not isinstance(randomise, dict) or "seed" not in randomise:
        raise ValueError(f"randomise must be bands {{'seed': int, band: ...}} (mrd_env.suites.draw_episode), got "
                         f"{randomise!r}")
    nominal = nominal_values(env_id, options)
    episodes = []
    for s in seeds:
        a, _ = assembly_of(env_id, {**options, **draw_episode(randomise, nominal, 0, s)})
        episodes.append((a, native_records(a, [s])[0]))
    return episodes


def params_of_problem(problem, **scheme) -> EnvParams:
    """The twin of an :class:`~mrd_env.optimal.EpisodeProblem` (any plant): its environment, options and control
    step with physical commands, its seeded episode as the bank's only record (checked: the same inputs as the
    problem's, row for row); ``scheme``: ``scheme``, ``substeps``, ``newton_iterations``."""
    asm, _ = assembly_of(problem.env_id, {**problem.options, "control_dt": problem.control_dt,
                                          "action_mode": "physical"})
    params = params_of_assembly(asm, native_records(asm, [problem.seed]), **scheme)
    rows = problem.n_rows
    if params.n_steps != problem.n_steps or not np.array_equal(np.asarray(params.W[0, :rows]), problem.W[:rows]):
        raise ValueError(f"the problem's episode ({problem.episode_name}) is not the one its environment draws at "
                         f"reset(seed={problem.seed})")
    return params


# --- the period ---------------------------------------------------------------------------------------------
class _Episode(NamedTuple):
    """An episode's plant and damper (its row of the per-episode arrays, or the shared one)."""
    plant: sc.Plant
    G: jnp.ndarray
    P: jnp.ndarray
    lag: jnp.ndarray
    noise: jnp.ndarray
    sensor_delay: jnp.ndarray
    cost_limits: jnp.ndarray


def _episode(params: EnvParams, record) -> _Episode:
    i = record if params.drawn else 0
    return _Episode(sc.Plant(*(a[i] for a in params.plant)), params.G[i], params.P[i], params.lag[i],
                    params.noise[i], params.sensor_delay[i], params.cost_limits[i])


def _stepped_columns(params: EnvParams) -> tuple:
    """The named signals the period reads at every physics step (the reward's, the limits', the costs' and the
    filters' inputs): the other rows of G are needed once, for the measurement at the period's end."""
    nsig = params.G.shape[1]
    cols = (*params.reward_cols, *params.limit_cols, *params.cost_cols, *(f[0] for f in params.filters))
    return tuple(sorted({int(c) for c in cols if c < nsig}))


def _sums(params: EnvParams) -> sc.Sums:
    """The scheme's sums (:mod:`mrd_env.jax.scheme`): the exact scheme forms the row as the native driver does."""
    return sc.KERNEL_SUMS if params.scheme == "exact" else sc.MATRIX_SUMS


def _step_row(params: EnvParams, G, Y, F, w, cmd, zi):
    """The columns of the row h = [G·[Y, F, w], the commands, the filters' outputs] that a physics step reads
    ({column: value}, :func:`_stepped_columns`), the filters' outputs (n_filters,) and their new states."""
    nsig, rows = G.shape[0], _stepped_columns(params)
    sig = _sums(params).mv(G[np.asarray(rows, np.int32)] if rows else G[:0], jnp.concatenate([Y, F, w]))
    h = {c: sig[i] for i, c in enumerate(rows)}
    h.update({nsig + j: cmd[j] for j in range(params.nd)})
    sections, out = [zi[s] for s in range(zi.shape[0])], []
    for fin, fout, s0, count in params.filters:
        x = h[fin]
        for s in range(s0, s0 + count):
            c = params.sos[s]
            y = c[0] * x + zi[s, 0]
            sections[s] = jnp.stack([c[1] * x - c[4] * y + zi[s, 1], c[2] * x - c[5] * y])
            x = y
        h[fout] = x
        out.append(x)
    return h, jnp.stack(out) if out else jnp.zeros(0), jnp.stack(sections) if sections else zi


def _row(params: EnvParams, G, Y, F, w, cmd, filtered):
    """The whole row h (width,): the named signals G·[Y, F, w], the commands, the filters' outputs ``filtered``.
    Assembled from its columns (no scatter: under ``vmap`` an indexed update of a batch is a serial loop)."""
    sig = _sums(params).mv(G, jnp.concatenate([Y, F, w]))
    cols = [sig[i] for i in range(G.shape[0])] + [cmd[j] for j in range(params.nd)]
    cols += [jnp.zeros_like(sig[0])] * (params.width - len(cols))
    for i, (_, fout, _, _) in enumerate(params.filters):
        cols[fout] = filtered[i]
    return jnp.stack(cols)


def _measure(params: EnvParams, noise, h, key):
    m = h[jnp.asarray(params.meas_cols, jnp.int32)]
    if params.noisy:
        if key is None:
            raise ValueError("the sensors are noisy: step and reset need a key")
        m = m + noise * jax.random.normal(key, m.shape, jnp.float64)
    return m


def _observe(params: EnvParams, delay, fifo):
    """The observation: measurements of steps k − delay − history + 1 … k − delay, oldest first."""
    return lax.dynamic_slice_in_dim(fifo, delay, params.history)[::-1].reshape(-1)


def _violations(params: EnvParams, limits, h):
    """[any term violated, each term violated] at the row h (0/1)."""
    out = []
    for t in range(len(params.cost_terms) - 1):
        v = jnp.asarray(False)
        for i in range(params.cost_terms[t], params.cost_terms[t + 1]):
            x = h[params.cost_cols[i]]
            x = jnp.abs(x) if params.cost_sides[i] == 0 else (-x if params.cost_sides[i] < 0 else x)
            v = v | (x > limits[i])
        out.append(v)
    anyv = jnp.asarray(False)
    for v in out:
        anyv = anyv | v
    return jnp.stack([anyv, *out]).astype(jnp.float64)


def reset(key, params: EnvParams, record=None):
    """(observation, state) of a new episode on a record of the bank drawn from ``key`` (or the index
    ``record``): the plant's initial state, the effective commands at their minimum, the sensors' FIFO full of
    the first measurement (noise drawn from ``key``)."""
    if record is None:
        key, sub = jax.random.split(key)
        record = jax.random.randint(sub, (), 0, params.W.shape[0])
    model = jax_damper(params.model, params.jacobian)
    ep = _episode(params, record)
    nd = params.nd
    Y = params.Y0[record]
    U = jnp.full(nd, params.v_min, jnp.float64)  # strongly typed, as step returns it: no second compile
    w = params.W[record, 0]
    F, finite = sc.end_forces(model, ep.plant.C, ep.plant.D, ep.P, Y, U, w, exact=params.scheme == "exact")
    zi = jnp.zeros((params.sos.shape[0], 2))
    m = _measure(params, ep.noise, _row(params, ep.G, Y, F, w, U, jnp.zeros(len(params.filters))), key)
    fifo = jnp.tile(m[None], (params.max_delay + params.history, 1))
    state = EnvState(Y=Y, U=U, F=F, cmd=U, queue=jnp.full((params.queue, nd), params.v_min, jnp.float64),
                     nsub=jnp.asarray(1, jnp.int32), zi=zi, fifo=fifo,
                     cost=jnp.zeros(len(params.cost_terms), jnp.float64), record=jnp.asarray(record, jnp.int32),
                     k=jnp.asarray(0, jnp.int32), status=jnp.where(finite, OK, sc.NONFINITE).astype(jnp.int32))
    return _observe(params, ep.sensor_delay, fifo), state


def command(params: EnvParams, action):
    """The dampers' commands (V or A) of an action: clipped to the Box and mapped onto [v_min, v_max] when
    normalised."""
    a = jnp.asarray(action, jnp.float64).reshape(params.nd)
    if params.normalized:
        a = params.v_min + (jnp.clip(a, -1.0, 1.0) + 1.0) * 0.5 * (params.v_max - params.v_min)
    return jnp.clip(a, params.v_min, params.v_max)


def step(key, state: EnvState, action, params: EnvParams):
    """One control period: (observation, state, reward, terminated, truncated, info). ``info``: the effective
    commands, the sub-steps used per physics step, the status, ``cost`` (s of the period in violation of any
    constraint) and ``cost_terms`` (s, per term, in ``params.cost_names``' order)."""
    model = jax_damper(params.model, params.jacobian)
    exact = params.scheme == "exact"
    nd = params.nd
    cmd = command(params, action)
    scale = params.reward_scale[state.record]
    ep = _episode(params, state.record)
    whole, ts = sc.delay_split(ep.lag[:, 2], params.dt)  # each damper's delay: whole steps and the rest
    lag = ep.lag[:, :2]
    P = sc.param_columns(ep.P)  # split once, outside the physics steps' loop

    def physics(carry, k):
        Y, U, F, queue, nsub, zi, w_ok, filtered, work, status, total, hit, cost, used_total = carry
        row = state.k * params.n_sub + k
        queue = jnp.concatenate([cmd[None], queue[:-1]])
        # the commands whole + 1 and whole steps back, per damper (selections: a gather per damper costs more)
        va, vb = queue[-1], queue[-1]
        for i in range(params.queue - 2, -1, -1):
            va = jnp.where(whole + 1 == i, queue[i], va)
            vb = jnp.where(whole == i, queue[i], vb)
        w0, w1 = params.W[state.record, row], params.W[state.record, row + 1]
        st, Yn, Un, Fn, used, nsub_n, work = sc.macro_step(
            model, ep.plant, P, lag, (va, vb, ts), Y, U, F, w0, w1, params.dt, params.atol, params.rtol, nsub,
            work, exact=exact, max_level=params.max_level, substeps=params.substeps,
            newton_iterations=params.newton_iterations)
        running = status == OK
        ok = running & (st == OK)
        hn, fn, zin = _step_row(params, ep.G, Yn, Fn, w1, cmd, zi)
        keep = lambda new, old: jnp.where(ok, new, old)  # noqa: E731  (a failed system stays as it was)
        term = jnp.asarray(0.0)
        for i, c in enumerate(params.reward_cols):
            term = term + scale[i] * hn[c] * hn[c]
        for i, c in enumerate(params.limit_cols):
            hit = hit | (ok & (jnp.abs(hn[c]) > params.limits[i]))
            if params.limit_penalty:  # n_sub ×: the period's reward is −total / n_sub
                rho, margin = params.limit_penalty
                over = jnp.maximum(jnp.abs(hn[c]) / params.limits[i] - margin, 0.0)
                term = term + params.n_sub * rho * over * over
        total = total + jnp.where(ok, term, 0.0)
        cost = cost + jnp.where(ok, _violations(params, ep.cost_limits, hn), 0.0)
        status = jnp.where(running, st, status).astype(jnp.int32)
        return (keep(Yn, Y), keep(Un, U), keep(Fn, F), queue, keep(nsub_n, nsub), keep(zin, zi), keep(w1, w_ok),
                keep(fn, filtered), work, status, total, hit, cost, used_total + jnp.where(ok, used, 0)), None

    work = sc.empty_work(nd, model.ns) if exact else None
    # the last accepted physics step's input and filter outputs: the measurement's row is made from them
    w_ok, filtered = params.W[state.record, 0], jnp.zeros(len(params.filters))
    init = (state.Y, state.U, state.F, state.queue, state.nsub, state.zi, w_ok, filtered, work, state.status,
            jnp.asarray(0.0), jnp.asarray(False), jnp.zeros(len(params.cost_terms)), jnp.asarray(0))
    (Y, U, F, queue, nsub, zi, w_ok, filtered, _, status, total, hit, cost, used), _ = lax.scan(
        physics, init, jnp.arange(params.n_sub))
    # the row of the period's last accepted physics step (zeros if none was: an episode that had already failed)
    h = jnp.where(used > 0, _row(params, ep.G, Y, F, w_ok, cmd, filtered), 0.0)
    k = state.k + 1
    diverged = status != OK
    terminated = hit | diverged
    planned = params.penalty + params.penalty_step * params.steps[state.record]
    reward = jnp.where(diverged, -planned, -total / params.n_sub - jnp.where(hit, planned, 0.0))
    truncated = ~terminated & (k >= params.steps[state.record])
    cost = cost * params.dt
    m = _measure(params, ep.noise, h, key)
    fifo = jnp.concatenate([m[None], state.fifo[:-1]])
    new = EnvState(Y=Y, U=U, F=F, cmd=cmd, queue=queue, nsub=nsub.astype(jnp.int32), zi=zi, fifo=fifo, cost=state.cost + cost,
                   record=state.record, k=k, status=status)
    info = {"effective_command": U, "substeps": used / params.n_sub, "status": status, "cost": cost[0],
            "cost_terms": cost[1:]}
    return _observe(params, ep.sensor_delay, fifo), new, reward, terminated, truncated, info


def rollout(params: EnvParams, state: EnvState, actions, key=None):
    """A whole episode (or ``len(actions)`` steps) in one ``lax.scan``: (final state, observations, rewards,
    terminated, truncated), without autoreset (the steps after an episode's end repeat its last state and
    reward 0). ``key``: the sensors' noise (needed only if they are noisy)."""
    keys = None if key is None else jax.random.split(key, actions.shape[0])

    def body(carry, x):
        st, done = carry
        a, kk = x
        obs, new, r, term, trunc, _ = step(kk, st, a, params)
        new = jax.tree_util.tree_map(lambda u, v: jnp.where(done, u, v), st, new)
        return (new, done | term | trunc), (obs, jnp.where(done, 0.0, r), term & ~done, trunc & ~done)

    (state, _), out = lax.scan(body, (state, jnp.asarray(False)), (actions, keys))
    return (state, *out)


def step_autoreset(key, state: EnvState, action, params: EnvParams):
    """:func:`step`, then a new episode (a record drawn from ``key``) in place of one that ended, in the same call
    (gymnax's convention): the returned observation and state are the new episode's; ``info["final_observation"]``
    holds the ended one's last observation."""
    k1, k2 = (None, None) if key is None else jax.random.split(key)
    obs, new, reward, terminated, truncated, info = step(k1, state, action, params)
    done = terminated | truncated
    obs0, state0 = reset(k2, params)
    new = jax.tree_util.tree_map(lambda a, b: jnp.where(done, a, b), state0, new)
    info = {**info, "final_observation": obs}
    return jnp.where(done, obs0, obs), new, reward, terminated, truncated, info


def episode_return(actions, data):
    """The return of a whole episode under ``actions`` from ``data`` = (params, its first state): the function
    :func:`mrd_env.jax.clairvoyant.clairvoyant` maximises."""
    params, state = data
    return rollout(params, state, actions)[2].sum()


#: The bands :func:`draw_params` draws (the robustness twins' layout, ``ROBUST_BANDS`` of the plants' suites).
DRAWN_BANDS = ("damper_params", "command")


def draw_params(key, params: EnvParams, bands: dict) -> EnvParams:
    """``params`` with an episode's draw of ``bands`` (the robustness twin's layout): ``damper_params``
    {name: (lo, hi)}, each parameter × U(lo, hi) (every damper the same); ``command`` {"eta": (lo, hi)}, the lag
    rate (rise and fall) × U(lo, hi). Only arrays change, so a batch of draws (``jax.vmap(lambda k:
    draw_params(k, params, bands))(keys)``, stepped with ``in_axes=0`` for the parameters) runs the same compiled
    step as the nominal one, drawn inside ``jit``. Other bands (the delay, masses and stiffnesses, sensor noise
    and delay) raise ``ValueError`` naming them: :func:`make_params` (``randomise=``) draws every band, on the
    host, an episode's plant built by the plant's own code."""
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
        P = P.at[:, :, jnp.asarray([i for i, _ in items])].multiply(f[:len(items)])
    if eta:
        lag = lag.at[:, :, :2].multiply(f[-1])
    return dataclasses.replace(params, P=P, lag=lag)


def drawn_options(params: EnvParams, nominal: EnvParams) -> dict:
    """The native environment's ``damper_params`` option of one draw of :func:`draw_params` (unbatched):
    the drawn values of every parameter that changed, and ``command`` {"eta"} if the lag rate did."""
    P, P0 = np.asarray(params.P[0, 0]), np.asarray(nominal.P[0, 0])
    out: dict = {n: float(P[i]) for i, n in enumerate(params.param_names) if P[i] != P0[i]}
    if float(params.lag[0, 0, 0]) != float(nominal.lag[0, 0, 0]):
        out["command"] = {"eta": float(params.lag[0, 0, 0])}
    return {"damper_params": out}


__all__ = ["EnvParams", "EnvState", "SCHEMES", "assembly_of", "native_records", "params_of_assembly", "make_params",
           "drawn_episodes", "params_of_problem", "reset", "step", "step_autoreset", "rollout", "command", "episode_return",
           "draw_params", "drawn_options"]
