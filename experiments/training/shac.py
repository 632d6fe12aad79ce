"""``mrd-env train --algo shac``: a policy trained through the physics — analytic policy gradients over short
horizons with a learned value at the horizon's end (SHAC: Xu et al., "Accelerated policy learning with parallel
differentiable simulation", ICLR 2022).

Why: the return of an episode is dominated by its disturbance (the road, the earthquake), which a critic cannot
predict, so a likelihood-ratio policy gradient (PPO) is mostly noise near a good law (see :mod:`.evolution`). Every
plant's JAX twin (:mod:`mrd_env.jax.env`, made from the plant's own assembly: :func:`~mrd_env.jax.env.make_params`
of the training environment's id and options, its differentiable scheme) gives the exact derivative of the rewards
with respect to the policy's weights along the disturbance actually met: no noise from it at all. Over a long
horizon those derivatives explode or vanish, so the episode is cut into windows of ``horizon`` control steps; the
loss of a window is −(Σ γᵗ rₜ + γᴴ V(o_H)) over ``n_envs`` episodes, V a critic fitted to TD(λ) targets of the same
rollouts (a target copy, Polyak-averaged, gives the bootstrap), and Adam (``optax.adam``, the gradient's global
norm clipped first by ``optax.clip_by_global_norm``) takes one step per window on the policy's weights. The critic
also sees the episode's remaining time (the return ends with it), as a fraction of the bank's longest episode.

The policy is the CMA-ES agents' network (:class:`~controllers.mlp_policy.MLPPolicy`: tanh layers, actions in
[−1, 1], deterministic) on the same normalised observations, so the agent saves and loads in the same code-free
format. It starts from a shipped agent (``warm_start``: a folder, or "cmaes" for the plant's shipped CMA-ES agent
with the same observation options), keeping that agent's observation statistics.

The training environment's options go to the twin as they are: whatever it refuses (a Python-callable reward,
``action_mode="force"``) SHAC refuses with its ``ValueError``. Noisy sensors (``sensor_noise``) draw their noise
from keys split off the run's key. Training episodes are the training environment's (its disturbance option: for
the quarter car ISO 8608 classes B–D at 10–30 m/s, for the building the mixture of Kanai–Tajimi and PEER
records), drawn as the native environment draws them at ``reset(seed=s)`` (:func:`~mrd_env.jax.env.native_records`)
for seeds below ``HELD_OUT_SEED``, as CMA-ES draws its training seeds: validation and the suites use seeds above.
Every round each of the ``n_envs`` episodes starts once and the round lasts the bank's longest episode (one that
ends earlier, at its record's end or a limit, restarts on another record of the round), then the round's records
are replaced; a round's bank is padded (its last input row held) to the longest bank met so far, so that records
of other lengths do not recompile. Validation (the native environment on unseen seeds), best-agent saving and the
agent folder are those of every ``mrd-env train`` run (:mod:`.trainers`).
"""
from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from experiments.common.plants import PlantProfile

#: The hyperparameters (``experiments/hyperparams/shac.yml``) and their defaults.
DEFAULTS = {"n_timesteps": 2.5e6, "n_envs": 32, "horizon": 100, "gamma": 0.995, "lam": 0.95, "actor_lr": 1e-3,
            "critic_lr": 1e-3, "critic_iterations": 16, "critic_minibatches": 4, "critic_hidden": [64, 64],
            "target_alpha": 0.2, "grad_clip": 1.0, "warm_start": "cmaes", "substeps": 1, "newton_iterations": 2,
            "critic_warmup": 30, "lr_decay": True}


def check(hyper: dict) -> dict:
    """``hyper`` completed with the defaults, every value checked (``ValueError`` naming the key)."""
    unknown = sorted(set(hyper) - set(DEFAULTS) - {"policy", "normalize", "env_kwargs"})
    if unknown:
        raise ValueError(f"hyperparameters {unknown} are not SHAC options; valid: {sorted(DEFAULTS)}")
    h = {**DEFAULTS, **hyper}
    if not isinstance(h["lr_decay"], bool):
        raise ValueError(f"hyperparameter lr_decay must be true or false, got {h['lr_decay']!r}")
    if isinstance(h["critic_warmup"], bool) or not isinstance(h["critic_warmup"], int) or h["critic_warmup"] < 0:
        raise ValueError(f"hyperparameter critic_warmup must be an integer >= 0, got {h['critic_warmup']!r}")
    for key in ("n_timesteps", "n_envs", "horizon", "critic_iterations", "critic_minibatches", "newton_iterations"):
        v = h[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or v < 1 or float(v) != int(v):
            raise ValueError(f"hyperparameter {key} must be an integer >= 1, got {v!r}")
    for key, lo, hi in (("gamma", 0.0, 1.0), ("lam", 0.0, 1.0), ("target_alpha", 0.0, 1.0)):
        v = h[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
            raise ValueError(f"hyperparameter {key} must be in [{lo}, {hi}], got {v!r}")
    for key in ("actor_lr", "critic_lr", "grad_clip"):
        v = h[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
            raise ValueError(f"hyperparameter {key} must be > 0, got {v!r}")
    hidden = h["critic_hidden"]
    if not isinstance(hidden, (list, tuple)) or not all(isinstance(n, int) and n >= 1 for n in hidden):
        raise ValueError(f"hyperparameter critic_hidden must be a list of layer widths >= 1, got {hidden!r}")
    if h["substeps"] not in (1, 2, 4, 8):
        raise ValueError(f"hyperparameter substeps must be 1, 2, 4 or 8, got {h['substeps']!r}")
    if not isinstance(h["warm_start"], str):
        raise ValueError(f"hyperparameter warm_start must be 'cmaes' or an agent's folder, got {h['warm_start']!r}")
    return h


def check_entry(algo: str, hyper: dict) -> dict:
    """The trainer interface's check (:class:`~experiments.training.trainers.Trainer`)."""
    return check(hyper)


# --- the differentiable pieces (pure functions of arrays; jit- and grad-able) ----------------------------------------
def mlp(theta, sizes, x, linear_out: bool = False):
    """:class:`~controllers.mlp_policy.MLPPolicy`'s forward pass in JAX (the same flat layout of ``theta``: each
    layer's (n_in, n_out) matrix, then its bias); ``linear_out``: no tanh on the last layer (the critic)."""
    import jax.numpy as jnp

    k, h = 0, x
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        W = theta[k:k + a * b].reshape(a, b)
        k += a * b
        h = h @ W + theta[k:k + b]
        k += b
        if i < len(sizes) - 2 or not linear_out:
            h = jnp.tanh(h)
    return h


def n_weights(sizes) -> int:
    return sum(a * b + b for a, b in zip(sizes[:-1], sizes[1:]))


class Setup:
    """The jitted functions of one training set-up: the window's loss and its gradient, the critic's fit, the
    resets, on any plant's twin (:mod:`mrd_env.jax.env`: its parameters are an argument, so one set-up serves
    every bank). ``norm`` = (mean, scale, clip) of the observation normalisation; ``sizes`` the policy's,
    ``critic_sizes`` the critic's (its input: the normalised observation and the episode's remaining time).
    ``key`` (the loss, the actor's update, :meth:`start`): the sensors' noise, needed only if the twin's sensors
    are noisy (None otherwise)."""

    def __init__(self, sizes, critic_sizes, norm, h: dict):
        import jax
        import jax.numpy as jnp
        import optax

        from mrd_env.jax import env as je

        self.sizes, self.critic_sizes, self.h = tuple(sizes), tuple(critic_sizes), h
        # the actor: its gradient's global norm clipped (a rare stiff window must not jump), then Adam at the
        # learning rate of each window (its decay, 0 in the critic's warm-up: a hyperparameter set per call)
        self.actor_opt = optax.inject_hyperparams(lambda learning_rate: optax.chain(
            optax.clip_by_global_norm(float(h["grad_clip"])), optax.adam(learning_rate)))(
            learning_rate=float(h["actor_lr"]))
        self.critic_opt = optax.adam(float(h["critic_lr"]))
        mean, scale, clip = (jnp.asarray(norm[0]), jnp.asarray(norm[1]), float(norm[2]))
        H, gamma, lam = int(h["horizon"]), float(h["gamma"]), float(h["lam"])

        def normalize(o):
            return jnp.clip((o - mean) / scale, -clip, clip)

        def features(o, k, record, params):
            # the episode's remaining steps over the bank's longest, written so that an episode of the bank's
            # length gives 1 − k/n bit for bit (XLA divides by a constant n as a product by its reciprocal)
            rest = (1.0 - k / params.n_steps) - (params.n_steps - params.steps[record]) / params.n_steps
            return jnp.concatenate([normalize(o), rest[None]])

        def value(phi, o, k, record, params):
            return mlp(phi, self.critic_sizes, features(o, k, record, params), linear_out=True)[0]

        def window(theta, phi, state, obs, params, key):
            """One episode's window: (its loss, (observations, steps, rewards, ends, final observation and step,
            record) for the critic, final state and observation, done)."""
            def body(carry, k):
                st, o, done, ret, disc = carry
                a = mlp(theta, self.sizes, normalize(o))
                o2, st2, r, term, trunc, _ = je.step(k, st, a, params)
                ret = ret + disc * jnp.where(done, 0.0, r)
                ended = done | term | trunc
                st2 = jax.tree_util.tree_map(lambda x, y: jnp.where(done, x, y), st, st2)
                o2 = jnp.where(done, o, o2)
                out = (jax.lax.stop_gradient(o), st.k, jax.lax.stop_gradient(jnp.where(done, 0.0, r)), ended)
                return (st2, o2, ended, ret, disc * gamma), out

            init = (state, obs, jnp.asarray(False), jnp.asarray(0.0), jnp.asarray(1.0))
            keys = None if key is None else jax.random.split(key, H)
            (st, o, done, ret, disc), (O, K, R, D) = jax.lax.scan(body, init, keys, length=H)
            total = ret + disc * jnp.where(done, 0.0, value(phi, o, st.k, st.record, params))
            return -total, (O, K, R, D, jax.lax.stop_gradient(o), st.k, st.record), (st, o, done)

        def loss(theta, phi, states, obs, params, key=None):
            keys = None if key is None else jax.random.split(key, obs.shape[0])
            l, traj, end = jax.vmap(window, in_axes=(None, None, 0, 0, None, None if key is None else 0))(
                theta, phi, states, obs, params, keys)
            return jnp.mean(l) / H, (traj, end)

        grad = jax.value_and_grad(loss, has_aux=True)

        def targets(phi, traj, params):
            """TD(λ) targets of every visited observation (N, H), bootstrapped by the critic ``phi``."""
            O, K, R, D, o_end, k_end, rec = traj
            V = jax.vmap(jax.vmap(value, in_axes=(None, 0, 0, None, None)), in_axes=(None, 0, 0, 0, None))(
                phi, O, K, rec, params)
            v_end = jax.vmap(value, in_axes=(None, 0, 0, 0, None))(phi, o_end, k_end, rec, params)
            V_next = jnp.concatenate([V[:, 1:], v_end[:, None]], axis=1)

            def back(g_next, x):
                r, v_next, d = x
                g = r + gamma * jnp.where(d, 0.0, (1.0 - lam) * v_next + lam * g_next)
                return g, g

            _, G = jax.lax.scan(back, v_end, (R.T, V_next.T, D.T), reverse=True)
            return G.T

        def actor_update(theta, opt_state, lr, phi_target, states, obs, params, key=None):
            (l, (traj, end)), g = grad(theta, phi_target, states, obs, params, key)
            at_lr = opt_state._replace(hyperparams={**opt_state.hyperparams,
                                                    "learning_rate": jnp.asarray(lr, jnp.float64)})
            step, new_state = self.actor_opt.update(g, at_lr)
            new = (optax.apply_updates(theta, step), new_state)
            # the warm-up (lr 0) moves nothing: neither the weights nor Adam's moments and count
            theta, opt_state = jax.tree_util.tree_map(lambda a, b: jnp.where(lr > 0, a, b), new, (theta, opt_state))
            return theta, opt_state, l, jnp.linalg.norm(g), traj, end

        def critic_update(phi, phi_target, opt_state, traj, key, params):
            G = targets(phi_target, traj, params)
            O, K, rec = traj[0], traj[1], traj[6]
            X = jax.vmap(jax.vmap(features, in_axes=(0, 0, None, None)), in_axes=(0, 0, 0, None))(O, K, rec, params)
            X, G = X.reshape(-1, X.shape[-1]), G.reshape(-1)
            n_mb = int(h["critic_minibatches"])
            size = X.shape[0] // n_mb

            def mse(p, x, y):
                return jnp.mean((mlp(p, self.critic_sizes, x, linear_out=True)[:, 0] - y) ** 2)

            def epoch(carry, k):
                perm = jax.random.permutation(k, X.shape[0])

                def mb(carry, idx):
                    phi, opt_state = carry
                    l, g = jax.value_and_grad(mse)(phi, X[idx], G[idx])
                    step, opt_state = self.critic_opt.update(g, opt_state)
                    return (optax.apply_updates(phi, step), opt_state), l

                carry, ls = jax.lax.scan(mb, carry, perm[:n_mb * size].reshape(n_mb, size))
                return carry, ls.mean()

            keys = jax.random.split(key, int(h["critic_iterations"]))
            (phi, opt_state), ls = jax.lax.scan(epoch, (phi, opt_state), keys)
            a = h["target_alpha"]
            phi_target = a * phi_target + (1.0 - a) * phi
            return phi, phi_target, opt_state, ls[-1]

        def restart(key, states, obs, done, params):
            """Episodes that ended restart on a record of the bank drawn from ``key``."""
            keys = jax.random.split(key, done.shape[0])
            o0, s0 = jax.vmap(je.reset, in_axes=(0, None))(keys, params)
            states = jax.tree_util.tree_map(
                lambda a, b: jnp.where(done.reshape((-1,) + (1,) * (a.ndim - 1)), a, b), s0, states)
            return states, jnp.where(done[:, None], o0, obs)

        def start(params, key=None):
            """Every record of the bank's episode, in order."""
            n = params.W.shape[0]
            if key is None:
                return jax.vmap(lambda i: je.reset(None, params, record=i))(jnp.arange(n))
            return jax.vmap(lambda k, i: je.reset(k, params, record=i))(jax.random.split(key, n), jnp.arange(n))

        self.loss = jax.jit(loss)
        self.actor_update = jax.jit(actor_update)
        self.critic_update = jax.jit(critic_update)
        self.restart = jax.jit(restart)
        self.start = jax.jit(start)


_SETUPS: dict = {}


def setup_for(sizes, critic_sizes, norm, h: dict) -> Setup:
    """The :class:`Setup` of these choices, made once per process (its jitted functions compile once per shape of
    the twin's parameters: a second run of the same set-up, e.g. another seed, reuses them)."""
    key = (tuple(sizes), tuple(critic_sizes), *(np.asarray(a, np.float64).tobytes() for a in norm[:2]),
           float(norm[2]), tuple(sorted((k, str(v)) for k, v in h.items())))
    if key not in _SETUPS:
        _SETUPS[key] = Setup(sizes, critic_sizes, norm, h)
    return _SETUPS[key]


def twin_params(plant: PlantProfile, env_kwargs: dict, seeds, h: dict, n_steps: int = 0):
    """The twin (:func:`mrd_env.jax.env.make_params`, differentiable scheme) of ``plant``'s environment with the
    training options ``env_kwargs`` on the records its native environment meets at ``reset(seed=s)`` for each of
    ``seeds``; its inputs padded (the last row held) to ``n_steps`` control steps if the bank is shorter, so that
    banks of other lengths share one compilation. ``ValueError`` (the twin's) for an option it does not
    reproduce."""
    from mrd_env.jax import env as je

    params = je.make_params(plant.env_id, seeds=list(seeds), scheme="differentiable", substeps=int(h["substeps"]),
                            newton_iterations=int(h["newton_iterations"]), **env_kwargs)
    if params.n_steps >= n_steps:
        return params
    import jax.numpy as jnp

    W = params.W
    W = jnp.concatenate([W, jnp.repeat(W[:, -1:], n_steps * params.n_sub + 1 - W.shape[1], axis=1)], axis=1)
    return dataclasses.replace(params, W=W, n_steps=int(n_steps))


def warm_start_agent(spec: str, plant: PlantProfile, env_kwargs: dict):
    """The agent SHAC starts from: the folder ``spec``, or ("cmaes") the shipped CMA-ES agent of ``plant`` with the
    same observation options; ``ValueError`` if there is none or its observation differs."""
    from controllers import load_agent
    from controllers.agents import OBSERVATION_OPTIONS

    want = {k: v for k, v in env_kwargs.items() if k in OBSERVATION_OPTIONS}

    def same(agent) -> bool:
        have = {k: v for k, v in agent.env_kwargs.items() if k in OBSERVATION_OPTIONS}
        return {k: _plain(v) for k, v in have.items()} == {k: _plain(v) for k, v in want.items()}

    if spec == "cmaes":
        shipped = Path(__file__).parents[2] / "controllers" / "agents"
        for folder in sorted(shipped.glob("*_cmaes*")):  # the plant's former name too (building_cmaes)
            agent = load_agent(folder)
            if agent.meta.get("plant") == plant.name and same(agent):
                return folder, agent
        raise ValueError(f"no shipped CMA-ES agent of the {plant.name} observes {want}; give warm_start a folder")
    agent = load_agent(spec)
    if not same(agent):
        raise ValueError(f"warm_start {spec}: the agent observes other options than the training environment's")
    return Path(spec), agent


def _plain(v):
    return [_plain(x) for x in v] if isinstance(v, (list, tuple)) else v


def train_shac(plant: PlantProfile, algo: str, seed: int, *, out: Path, timesteps: int | None = None,
               hyper: dict | None = None, env_kwargs: dict | None = None, eval_freq: int = 20_000,
               eval_episodes: int = 8, progress: bool = False, command: str = "",
               warm_start: str | None = None) -> Path:
    """Train one SHAC agent on ``plant`` (any plant: see the module docstring); return its folder."""
    import jax
    import jax.numpy as jnp

    import mrd_env.jax  # noqa: F401  (float64, the compilation cache)
    from controllers.agents import save_agent
    from controllers.mlp_policy import MLPPolicy

    from experiments.training.evolution import NormalizedPolicy
    from experiments.common.scenarios import HELD_OUT_SEED
    from experiments.training.trainers import NetworkValidation, agent_name, env_options, plot_learning_curve, run_name, validation_split

    h = check(dict(hyper or {}))
    env_kwargs = dict(env_kwargs if env_kwargs is not None else env_options(plant))
    env_kwargs.update(h.get("env_kwargs") or {})
    spec = warm_start if warm_start is not None else h["warm_start"]
    start_folder, agent = warm_start_agent(spec, plant, env_kwargs)
    policy0, normalizer = agent.model, agent.normalizer
    timesteps = int(timesteps if timesteps is not None else float(h["n_timesteps"]))
    N, H = int(h["n_envs"]), int(h["horizon"])
    run_dir = Path(out) / f"{run_name(plant, 'shac', h, env_kwargs)}_s{seed}"
    run_dir.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()

    rng = np.random.default_rng(seed)
    params = twin_params(plant, env_kwargs, [int(s) for s in rng.integers(0, HELD_OUT_SEED, size=N)], h)
    sizes = policy0.sizes
    critic_sizes = (sizes[0] + 1, *h["critic_hidden"], 1)
    setup = setup_for(sizes, critic_sizes, (normalizer.mean, normalizer.scale, normalizer.clip), h)
    key = jax.random.PRNGKey(seed)
    key, k_phi = jax.random.split(key)
    theta = jnp.asarray(policy0.theta)
    phi = _init_critic(k_phi, critic_sizes)
    phi_target = phi
    actor_state, critic_state = setup.actor_opt.init(theta), setup.critic_opt.init(phi)
    val, obs_kwargs = validation_split(plant, env_kwargs, eval_episodes)

    def save(folder: Path, th, extra: dict, in_place: bool = False) -> None:
        meta = {"name": agent_name("SHAC", seed, h, env_kwargs), "plant": plant.name, "env_id": plant.env_id,
                "algo": "SHAC", "recurrent": False, "seed": seed, "timesteps": timesteps, "env_kwargs": env_kwargs,
                "hyperparameters": {**h, "warm_start": str(start_folder)}, "command": command,
                "wall_time_s": time.perf_counter() - t_start, **extra}
        save_agent(folder, meta, policy=MLPPolicy(sizes, np.asarray(th)), in_place=in_place, normalizer=normalizer)

    validation = NetworkValidation(run_dir, val, obs_kwargs, save, progress)

    def validate(th, steps: int) -> None:
        live = NormalizedPolicy(MLPPolicy(sizes, np.asarray(th)), normalizer.mean, normalizer.var, normalizer.clip,
                                normalizer.epsilon)
        validation(live, th, steps, wall_time_s=time.perf_counter() - t_start)

    from tqdm.auto import tqdm
    bar = tqdm(total=timesteps, desc=f"train {run_dir.name}", unit="step", disable=not progress)
    monitor = run_dir / "training.monitor.csv"
    monitor.write_text(f'#{{"t_start": {time.time()}, "env_id": "{plant.env_id}"}}\nr,l,t\n', encoding="utf-8")
    steps, next_eval, windows_done = 0, 0, 0
    noise = None  # the sensors' noise keys, split off only if they are noisy (else the run's keys are as without)
    try:
        while steps < timesteps:
            if steps > 0:  # a new round: new records (padded to the longest bank yet: nothing recompiles)
                params = twin_params(plant, env_kwargs, [int(s) for s in rng.integers(0, HELD_OUT_SEED, size=N)],
                                     h, n_steps=params.n_steps)
            if params.noisy:
                key, noise = jax.random.split(key)
            obs, states = setup.start(params, noise)
            returns = np.zeros(N)
            for _ in range(-(-params.n_steps // H)):
                if eval_freq and steps >= next_eval:
                    validate(theta, steps)
                    next_eval = steps + eval_freq
                # the critic learns first (a random one's gradient at the window's end would mislead the policy)
                learn = windows_done >= h["critic_warmup"]
                lr = float(h["actor_lr"]) * (1.0 - steps / timesteps if h["lr_decay"] else 1.0) * learn
                if params.noisy:
                    key, noise = jax.random.split(key)
                theta, actor_state, loss, gnorm, traj, (states, obs, done) = setup.actor_update(
                    theta, actor_state, lr, phi_target, states, obs, params, noise)
                windows_done += 1
                key, k1, k2 = jax.random.split(key, 3)
                phi, phi_target, critic_state, closs = setup.critic_update(phi, phi_target, critic_state, traj, k1,
                                                                           params)
                returns += np.asarray(traj[2]).sum(axis=1)
                states, obs = setup.restart(k2, states, obs, done, params)
                steps += N * H
                bar.update(N * H)
                if not np.isfinite(float(loss)):
                    raise FloatingPointError(f"SHAC's loss is not finite at {steps} steps (gradient norm "
                                             f"{float(gnorm):.3g}): lower actor_lr or horizon")
            with monitor.open("a", encoding="utf-8") as fh:
                fh.write(f"{returns.mean():.6g},{N * params.n_steps},{time.perf_counter() - t_start:.3f}\n")
    except KeyboardInterrupt:
        bar.close()
        save(run_dir, theta, {"timesteps_done": steps, "interrupted": True}, in_place=True)
        plot_learning_curve(run_dir)
        print(f"interrupted at {steps} steps: saved the agent so far in {run_dir}", file=sys.stderr)
        raise
    bar.close()
    if eval_freq:
        validate(theta, steps)
    save(run_dir, theta, {"timesteps_done": steps}, in_place=True)
    plot_learning_curve(run_dir)
    return run_dir


def _init_critic(key, sizes):
    """The critic's weights: Glorot-uniform matrices, zero biases (flat, :func:`mlp`'s layout)."""
    import jax
    import jax.numpy as jnp

    parts = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        key, k = jax.random.split(key)
        lim = np.sqrt(6.0 / (a + b))
        parts += [jax.random.uniform(k, (a * b,), jnp.float64, -lim, lim), jnp.zeros(b)]
    return jnp.concatenate(parts)
