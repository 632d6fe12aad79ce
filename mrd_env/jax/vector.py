"""A Gymnasium ``VectorEnv`` over any plant's JAX environment (:mod:`mrd_env.jax.env`): N environments reset and
stepped by one jitted, vmapped call (needs the ``[jax]`` extra).

Spaces, observations (float32), rewards, flags, the ``NEXT_STEP`` autoreset and the infos mean what they mean in
the native vector environment of the same id and options (:mod:`mrd_env.envs.vector`; a test compares the two
through an autoreset): the step after an episode ends resets that environment and returns its first observation
with reward 0 and both flags false. ``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point",
backend="jax", **options)`` makes it for every plant (:mod:`mrd_env.plants.registry`).

Its default scheme is the differentiable one (:data:`DEFAULT_SCHEME`): a fixed amount of work per step, as fast as
the native vector environment or faster, within 0.5 % NRMSE of the exact scheme (``docs/jax.md``). The
exact scheme (``scheme="exact"``: the native environment's numbers to 1e-12) waits in every step for the batch's
slowest Newton solve, a tenth of the native speed on random commands: it is for cross-checks.
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..envs.base import action_space, as_action
from ..envs.core import PlantDeclarations
from ..envs.vector import reset_mask
from ..stepping.scheme import MAX_SUBSTEPS, OK
from ..stepping.stepper import diverged_error
from . import env as je

#: The scheme a JAX vector environment steps with unless given ``scheme=``: its users pick JAX for speed, and a
#: ``VectorEnv`` hands back NumPy arrays (no gradient goes through it), so the fast scheme, not the exact one.
DEFAULT_SCHEME = "differentiable"
#: Seeds are JAX keys' (``jax.random.PRNGKey``: a 64-bit signed integer): environment i's of ``reset(seed=s)`` is s + i.
SEED_LIMIT = 2 ** 63


def bands_of(params: je.EnvParams, randomise: dict | None) -> dict:
    """Every band :func:`~mrd_env.jax.env.draw_params` can draw, as arrays: those of ``randomise`` (the robustness
    twins' layout), the others (1, 1), a factor of exactly 1. One layout for every ``randomise``, so that nominal
    and randomised environments run one compiled program. Bands it cannot draw, or that are not
    0 < lo <= hi, raise ``ValueError`` naming them."""
    randomise = {} if randomise is None else randomise
    if not isinstance(randomise, dict):
        raise ValueError(f"randomise must be None or a dict of bands, got {type(randomise).__name__}")
    given = {**{f"damper_params.{n}": b for n, b in randomise.get("damper_params", {}).items()},
             **{f"command.{n}": b for n, b in randomise.get("command", {}).items() if n == "eta"}}
    for name, b in given.items():
        try:
            lo, hi = (float(x) for x in b)
        except (TypeError, ValueError):
            lo = hi = float("nan")
        if not 0 < lo <= hi < float("inf"):
            raise ValueError(f"randomise {name} must be a band (lo, hi) of factors with 0 < lo <= hi, got {b!r}")
    je.draw_params(jax.random.PRNGKey(0), params, randomise)  # refuses the bands it cannot draw, by name
    band = lambda key: tuple(jnp.asarray(float(x), jnp.float64) for x in given.get(key, (1.0, 1.0)))  # noqa: E731
    return {"damper_params": {n: band(f"damper_params.{n}") for n in params.param_names},
            "command": {"eta": band("command.eta")}}


def _host_bands(randomise) -> set:
    """The bands of ``randomise`` that change more than the damper's parameters and lag rate (masses, stiffnesses,
    the command delay, sensor noise and delay): drawn per episode of the bank, on the host
    (:func:`mrd_env.jax.env.drawn_episodes`), not in the step."""
    if not isinstance(randomise, dict):
        return set()
    return ({k for k in randomise if k not in ("seed", *je.DRAWN_BANDS)}
            | {f"command.{k}" for k in randomise.get("command", {}) if k != "eta"})


def _start(key, params, bands):
    """One environment's new episode: (observation, state, P, lag), its damper drawn from ``bands``."""
    k_draw, k_reset = jax.random.split(key)
    params = je.draw_params(k_draw, params, bands)
    obs, state = je.reset(k_reset, params)
    return obs, state, params.P, params.lag


def _advance(key, state, P, lag, action, restart, params, bands):
    """One environment's step: its episode's step, or (``restart``: its episode ended at the last step) a new
    episode with reward 0, both flags false and no cost, as the native NEXT_STEP autoreset."""
    key, k_step, k_start = jax.random.split(key, 3)
    obs, new, reward, terminated, truncated, info = je.step(k_step, state, action,
                                                            dataclasses.replace(params, P=P, lag=lag))
    obs0, state0, P0, lag0 = _start(k_start, params, bands)
    pick = lambda a, b: jnp.where(restart, a, b)  # noqa: E731
    new, P, lag = jax.tree_util.tree_map(pick, (state0, P0, lag0), (new, P, lag))
    out = (pick(obs0, obs), jnp.where(restart, 0.0, reward), terminated & ~restart, truncated & ~restart,
           jnp.where(restart, 0.0, info["cost"]), jnp.where(restart, 0.0, info["cost_terms"]))
    return key, new, P, lag, out


# module level: one compiled program per plant set-up and batch size, shared by every environment and its copies
@jax.jit
def _start_all(keys, params, bands):
    return jax.vmap(_start, in_axes=(0, None, None))(keys, params, bands)


@jax.jit
def _advance_all(keys, state, P, lag, actions, restart, params, bands):
    return jax.vmap(_advance, in_axes=(0, 0, 0, 0, 0, 0, None, None))(keys, state, P, lag, actions, restart, params,
                                                                      bands)


class JaxVectorEnv(PlantDeclarations, VectorEnv):
    """``num_envs`` environments of ``env_id`` (any mrd_env id) with its options (as ``gymnasium.make``), stepped
    in JAX.

    ``scheme``: ``"differentiable"`` by default (:data:`DEFAULT_SCHEME`: fixed work per step, about the native
    vector environment's speed or more, within 0.5 % NRMSE of the exact scheme), or ``"exact"`` (the native
    environment's numbers to 1e-12, for cross-checks: every step waits for the batch's slowest Newton solve, a
    tenth of the native speed at N = 256 on random commands).
    ``seeds``/``records``/``substeps``/``newton_iterations``/``jacobian``: the bank and the stepping, as
    :func:`mrd_env.jax.env.make_params` (default bank: one record for a fixed disturbance, else the records a
    native environment meets at ``reset(seed=s)`` for s in 0…15). Each (re)starting environment draws its record
    from the bank, and its sensor noise, from its own JAX key. Seeding as the native vector environment:
    ``reset(seed=s)`` seeds environment i with s + i (its key ``PRNGKey(s + i)``), a list of ``num_envs`` seeds
    seeds each (``None`` keeps that environment's key), ``reset()`` keeps the keys (the first one draws a seed
    per environment); ``np_random_seed`` is the tuple of those seeds, so a seeded reset replays bit for bit and
    environment i of ``reset(seed=s)`` is environment 0 of ``reset(seed=s + i)`` (the records are the bank's,
    not those the native environment draws from the same seed). ``randomise``: bands in the robustness twins' layout (``ROBUST_BANDS``). With
    ``damper_params`` and ``command.eta`` only, they are drawn for each environment at every reset and autoreset
    inside the step (its ``seed`` unused: the draws come from the environments' keys); with any other band (masses,
    stiffnesses, the command delay, sensor noise and delay) every band is drawn once per seed of the bank, on the
    host, by the plant's own code (:func:`mrd_env.jax.env.drawn_episodes`, the ``seed`` of the bands used), and
    each (re)start picks one of those episodes. Either way nothing new is compiled.
    ``max_episode_steps``: episodes end, truncated, after at most that many steps (as the native one).
    The bank and the batch are estimated before anything is drawn (:func:`mrd_env.jax.env.check_bank`): above
    ``MRD_ENV_MEMORY_LIMIT`` a ``ValueError`` names ``num_envs`` and ``seeds``/``records``, the estimate and the limit.
    ``autoreset_mode``: ``NEXT_STEP`` only.

    ``infos`` as the native vector environment's, each key with its ``_key`` mask: ``t`` (s), ``cost`` and
    ``cost_terms`` {term: (N,)} (s in violation over the last step, 0 for an environment that (re)started),
    ``disturbance`` (the record's name) for those that (re)start, ``termination_reason`` ("stroke_limit", or
    "diverged: ..." with the end of the failed control period as its time) for those whose episode ended; and
    ``effective_command`` (N, nd), the dampers' commands after their lag. Every array returned is a writable NumPy
    array of its own (Gymnasium's vector wrappers, ``ClipReward`` and ``NormalizeReward``, write in place). Not
    here: ``episode_metrics`` (the native environment's episode statistics are not computed in JAX), rendering,
    ``np_random`` (the draws come from JAX keys, not NumPy generators).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, env_id: str, num_envs: int = 1, *, seeds=None, records=None, scheme: str = DEFAULT_SCHEME,
                 substeps: int = 1, newton_iterations: int = 2, jacobian: str = "kernel", randomise: dict | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, max_episode_steps: int | None = None,
                 render_mode: str | None = None, **options):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
        if autoreset_mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.NEXT_STEP.value):
            raise ValueError(f"autoreset_mode must be NEXT_STEP (the JAX vector environment's only mode), got "
                             f"{autoreset_mode!r}")
        if render_mode is not None:
            raise ValueError(f"render_mode must be None (the JAX vector environment does not render; the native one "
                             f"does), got {render_mode!r}")
        if max_episode_steps is not None and (isinstance(max_episode_steps, bool) or not isinstance(
                max_episode_steps, (int, np.integer)) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be None or an int >= 1, got {max_episode_steps!r}")
        asm, _ = je.assembly_of(env_id, options)
        host = sorted(_host_bands(randomise))
        if records is None:
            seeds = (range(16) if asm.disturbance.random or host else (0,)) if seeds is None else seeds
            seeds = je.seed_list(seeds)
            # the bank and the batch estimated before anything is drawn or allocated (mrd_env.resources)
            je.check_bank(asm, seeds=seeds, num_envs=int(num_envs), drawn=bool(host))
            episodes = (je.drawn_episodes(env_id, options, randomise, seeds) if host
                        else [(asm, r) for r in je.native_records(asm, seeds)])
        elif seeds is not None:
            raise ValueError("seeds and records: give one of them (the bank's records, or the seeds that draw them)")
        elif host:
            raise ValueError(f"randomise {host} draws a plant per seed on the host: give seeds, not records")
        else:
            records = list(records)
            je.check_bank(asm, records=records, num_envs=int(num_envs))
            episodes = [(asm, r) for r in records]
        records = [r for _, r in episodes]
        params = je.params_of_episodes(episodes, scheme=scheme, substeps=substeps,
                                       newton_iterations=newton_iterations, jacobian=jacobian)
        if host:  # every band drawn per episode of the bank, on the host: nothing left to draw in the step
            randomise = None
        if max_episode_steps is not None:
            params = dataclasses.replace(params, steps=jnp.minimum(params.steps, int(max_episode_steps)))
        self.env_id = env_id
        self.assembly = asm
        self.params = params
        self.bands = bands_of(params, randomise)
        self.num_envs = N = int(num_envs)
        self.step_cap = None if max_episode_steps is None else int(max_episode_steps)
        self.record_names = np.array([r.name for r in records], dtype=object)
        # the native vector environment's observation Box (float32, unbounded), of the same width (a test checks)
        self.single_observation_space = spaces.Box(-np.inf, np.inf, (len(params.meas_cols) * params.history,),
                                                   np.float32)
        self.single_action_space = action_space(asm)
        self.observation_space = batch_space(self.single_observation_space, N)
        self.action_space = batch_space(self.single_action_space, N)
        self.nd = params.nd
        self.cost_names = params.cost_names
        self._ashape = (N, self.nd)
        self._seeds: list = [None] * N  # each environment's seed (its key's), as the native vector environment's
        self._keys = None  # (N, 2) each environment's JAX key
        self._state = None  # EnvState, batched
        self._obs = None
        self._P = self._lag = None  # each environment's damper parameters and lag (drawn with randomise)
        self._ended = np.zeros(N, dtype=bool)

    @property
    def max_episode_steps(self) -> int | None:
        """The bank's longest episode (control steps), within ``max_episode_steps``."""
        return int(np.max(np.asarray(self.params.steps)))

    @property
    def np_random_seed(self) -> tuple:
        """Each environment's seed (the last reset's, or the one drawn for it; ``None`` before a reset), as the
        native vector environment and ``SyncVectorEnv`` give them."""
        return tuple(self._seeds)

    def _seed_list(self, seed) -> list:
        """``reset``'s ``seed`` as one seed or ``None`` per environment (as the native vector environment's)."""
        N = self.num_envs
        is_int = lambda s: isinstance(s, (int, np.integer)) and not isinstance(s, bool)  # noqa: E731
        if seed is None:
            return [None] * N
        if is_int(seed):
            if not 0 <= seed <= SEED_LIMIT - N:
                raise ValueError(f"seed must be None, an int in [0, 2**63 - num_envs] or {N} seeds, got {seed!r}")
            return [int(seed) + i for i in range(N)]
        try:
            seeds = list(seed)
        except TypeError:
            raise ValueError(f"seed must be None, an int >= 0 or a sequence of {N} of them, got {seed!r}") from None
        if len(seeds) != N or not all(s is None or (is_int(s) and 0 <= s < SEED_LIMIT) for s in seeds):
            raise ValueError(f"seed must be None, an int or a sequence of {N} seeds (None or ints in [0, 2**63)), "
                             f"got {seed!r}")
        return [None if s is None else int(s) for s in seeds]

    # --- Gymnasium API -------------------------------------------------------------------------------------------
    def reset(self, *, seed=None, options=None):
        N = self.num_envs
        seeds = self._seed_list(seed)
        mask = reset_mask(options, self.num_envs, self._state is not None)
        # a given seed, or a first key (drawn as a scalar environment's), for the masked environments only
        new = mask & np.array([s is not None or self._keys is None for s in seeds])
        if new.any():
            seeds = [int(np.random.SeedSequence().entropy % SEED_LIMIT) if s is None else s for s in seeds]
            keys = jax.vmap(jax.random.PRNGKey)(jnp.asarray(seeds, jnp.int64))
            self._keys = keys if self._keys is None else jnp.where(jnp.asarray(new)[:, None], keys, self._keys)
            for b in np.flatnonzero(new):
                self._seeds[b] = seeds[b]
        nxt, use = jnp.split(jax.vmap(jax.random.split)(self._keys), 2, axis=1)
        obs, state, P, lag = _start_all(use[:, 0], self.params, self.bands)
        if self._state is None:
            self._state, self._P, self._lag = state, P, lag
        else:
            m = jnp.asarray(mask)
            pick = lambda a, b: jnp.where(m.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)  # noqa: E731
            obs = pick(obs, self._obs)
            self._state, self._P, self._lag = jax.tree_util.tree_map(pick, (state, P, lag),
                                                                     (self._state, self._P, self._lag))
        self._keys = jnp.where(jnp.asarray(mask)[:, None], nxt[:, 0], self._keys)
        self._obs = obs
        self._ended[mask] = False
        infos = {"t": np.zeros(N), "_t": mask.copy()}
        self._add_disturbance(infos, mask, np.asarray(self._state.record))
        self._add_costs(infos, np.zeros((N, 1 + len(self.cost_names))), mask)
        return np.array(obs, np.float32), infos

    def _add_costs(self, infos: dict, C: np.ndarray, mask: np.ndarray) -> None:
        """``cost`` (N,) and ``cost_terms`` {term: (N,)} from ``C`` (N, 1 + T), with the mask ``mask``."""
        infos["cost"], infos["_cost"] = C[:, 0], mask.copy()
        terms = {}
        for i, name in enumerate(self.cost_names, 1):
            terms[name], terms[f"_{name}"] = C[:, i], mask.copy()
        infos["cost_terms"], infos["_cost_terms"] = terms, mask.copy()

    def _add_disturbance(self, infos: dict, mask: np.ndarray, record: np.ndarray) -> None:
        names = np.full(self.num_envs, None, dtype=object)
        names[mask] = self.record_names[record[mask]]
        infos["disturbance"], infos["_disturbance"] = names, mask.copy()

    def step(self, actions):
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        N = self.num_envs
        if type(actions) is np.ndarray and actions.dtype == np.float64 and actions.shape == self._ashape:
            a = actions
        else:
            a = as_action(actions, self.nd, N).reshape(self._ashape)
        if not np.isfinite(a).all():  # the whole batch, before any environment steps
            raise ValueError("actions must be finite (no NaN or infinity)")
        restart = self._ended
        keys, state, P, lag, out = _advance_all(self._keys, self._state, self._P, self._lag, jnp.asarray(a),
                                            jnp.asarray(restart), self.params, self.bands)
        self._keys, self._state, self._P, self._lag, self._obs = keys, state, P, lag, out[0]
        obs, reward, terminated, truncated, cost, terms, k, status, U, record = jax.device_get(
            (*out, state.k, state.status, state.U, state.record))
        infos = {"t": k * self.control_dt, "_t": np.ones(N, dtype=bool)}
        self._add_costs(infos, np.concatenate([cost[:, None], terms], axis=1), np.ones(N, dtype=bool))
        # the arrays handed back are NumPy's own, writable (JAX's are read-only views of its buffers)
        infos["effective_command"], infos["_effective_command"] = np.array(U), np.ones(N, dtype=bool)
        if restart.any():
            self._add_disturbance(infos, restart, record)
        for b in np.flatnonzero(terminated):
            why = ("stroke_limit" if status[b] == OK else "diverged: " + str(diverged_error(
                self.damper.name, int(status[b]), float(infos["t"][b]), int(b), MAX_SUBSTEPS)))
            self._add_info(infos, {"termination_reason": why}, b)
        self._ended = terminated | truncated
        return np.array(obs, np.float32), np.array(reward), np.array(terminated), np.array(truncated), infos


__all__ = ["DEFAULT_SCHEME", "JaxVectorEnv"]
