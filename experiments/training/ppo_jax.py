"""PPO trained entirely inside one jitted function on the JAX quarter car (issue 41, item 3c), PureJaxRL's layout:
the whole training — N vmapped environments stepped with ``jax_twin.step_autoreset``, the running observation
statistics, GAE, the minibatch epochs and Adam — is one ``lax.scan`` over the updates inside one ``jax.jit``.

Run: ``python -m experiments.training.ppo_jax [--seed 0] [--num-envs 256] [--num-steps 64]
[--total-timesteps 4194304] [--scheme differentiable] [--out results/agents/ppo_jax_s0]`` (needs
``pip install mrd-env[jax]``; float64 throughout).

The policy is a Gaussian whose mean is a tanh network with tanh on every layer, the output included (so the mean
lies in the normalised action range [−1, 1], which ``QuarterCar-v1`` maps onto [v_min, v_max]), and whose log
standard deviation is one learned number per action, independent of the state; the environment clips a sample to
[−1, 1], the log-probability is the unclipped sample's (as SB3 does). The value is a separate tanh network with a
linear output. The loss is PPO's clipped objective (advantages normalised per minibatch) plus ``vf_coef`` × the
value's squared error minus ``ent_coef`` × the entropy, one Adam over both networks with the gradient's global
norm clipped (optax: :func:`optimizer`; SB3's defaults otherwise). Observations are normalised by running
statistics updated with every batch of observations inside the scan (SB3 ``VecNormalize``'s rule, clip ±10), so
the saved agent's ``normalization.npz`` is exactly what it was trained with.

GAE treats the two ends of an episode apart: a termination (the stroke limit, a failed step) has no future, a
truncation (the time limit) is bootstrapped from the value of the episode's last observation
(``info["final_observation"]`` of ``step_autoreset``, whose returned observation is the next episode's first).

Roads: a bank of ``--n-roads`` ISO 8608 roads, classes cycled over ``--road-classes`` at speeds drawn uniformly in
``--speeds`` (numpy, from the seed), each with its passive reference (``jax_twin.make_params``); each episode draws
one. At the end the deterministic policy (the Gaussian's mean network) is saved in the project's code-free agent
format (``controllers.mlp_policy.MLPPolicy``, ``controllers.agents.save_agent``: atomic) for ``QuarterCar-v1``'s
set-up (recorded as the physics-level id with ``control_dt`` 0.01 and normalised actions, as the suites need),
with the learning curve (``training.csv``: one row per update).
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

#: The native environment the twin stands for (its defaults: 10 ms control, actions in [−1, 1]). The agent is
#: saved for its physics-level id with those two options stated (what the suites run: ``mrd-env score``).
ENV_ID = "mrd_env/QuarterCar-v1"
CONTROL_DT = 0.01


@dataclasses.dataclass(frozen=True)
class Config:
    """PPO's settings (hashable: the jitted training is specialised on them). The defaults are the recipe that
    learned something on ``car-comfort-v1`` (share 0.165 of the achievable gain, 4.2·10⁶ steps; lr 3e-4, 4 epochs
    and 8 minibatches of 6.3·10⁶ steps gave −0.10: the best constant command's level)."""
    num_envs: int = 256
    num_steps: int = 64
    total_timesteps: int = 4_194_304
    update_epochs: int = 10
    num_minibatches: int = 32
    lr: float = 1e-3
    anneal_lr: bool = True
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_eps: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden: tuple = (64, 64)
    log_std_init: float = -0.5
    obs_clip: float = 10.0

    @property
    def num_updates(self) -> int:
        return self.total_timesteps // (self.num_envs * self.num_steps)

    @property
    def minibatch_size(self) -> int:
        return self.num_envs * self.num_steps // self.num_minibatches


#: The normaliser's ε (controllers.agents.ObservationNormalizer's default, what the saved agent applies).
OBS_EPS = 1e-8
#: Adam's constants (SB3's and PureJaxRL's ε).
ADAM_B1, ADAM_B2, ADAM_EPS = 0.9, 0.999, 1e-5


def check_config(cfg: Config) -> None:
    """``ValueError`` naming the first setting out of its range."""
    ints = {"num_envs": 1, "num_steps": 1, "update_epochs": 1, "num_minibatches": 1}
    for name, lo in ints.items():
        v = getattr(cfg, name)
        if not isinstance(v, int) or v < lo:
            raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
    if (cfg.num_envs * cfg.num_steps) % cfg.num_minibatches:
        raise ValueError(f"num_minibatches must divide num_envs × num_steps = {cfg.num_envs * cfg.num_steps}, got "
                         f"{cfg.num_minibatches}")
    if cfg.num_updates < 1:
        raise ValueError(f"total_timesteps must be at least num_envs × num_steps = {cfg.num_envs * cfg.num_steps}, "
                         f"got {cfg.total_timesteps}")
    for name, lo, hi in (("lr", 0.0, 1.0), ("gamma", 0.0, 1.0), ("gae_lambda", 0.0, 1.0), ("clip_eps", 0.0, 1.0),
                         ("max_grad_norm", 0.0, math.inf), ("obs_clip", 0.0, math.inf)):
        v = getattr(cfg, name)
        if not (lo < v <= hi):
            raise ValueError(f"{name} must be in ({lo:g}, {hi:g}], got {v!r}")
    for name in ("ent_coef", "vf_coef"):
        if not (0.0 <= getattr(cfg, name) < math.inf):
            raise ValueError(f"{name} must be finite and >= 0, got {getattr(cfg, name)!r}")
    if not (-20.0 <= cfg.log_std_init <= 2.0):
        raise ValueError(f"log_std_init must be in [-20, 2], got {cfg.log_std_init!r}")
    if not cfg.hidden or min(cfg.hidden) < 1:
        raise ValueError(f"hidden must be one or more layer sizes >= 1, got {cfg.hidden!r}")


# ---------------------------------------------------------------- networks, normaliser (pure jnp), optimiser

def mlp_init(key, sizes, out_scale: float):
    """[(W (n_in, n_out), b), ...]: orthogonal weights (gain √2, the last layer's ``out_scale``), zero biases
    (PureJaxRL's and SB3's initialisation)."""
    import jax
    import jax.numpy as jnp

    layers = []
    keys = jax.random.split(key, len(sizes) - 1)
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        gain = out_scale if i == len(sizes) - 2 else math.sqrt(2.0)
        W = jax.nn.initializers.orthogonal(gain)(keys[i], (a, b), jnp.float64)
        layers.append((W, jnp.zeros(b, jnp.float64)))
    return layers


def policy_mean(layers, obs):
    """The Gaussian's mean: tanh on every layer, the output included (``MLPPolicy``'s forward)."""
    import jax.numpy as jnp

    h = obs
    for W, b in layers:
        h = jnp.tanh(h @ W + b)
    return h


def value(layers, obs):
    """The value network: tanh hidden layers, a linear output; (…,) values."""
    import jax.numpy as jnp

    h = obs
    for W, b in layers[:-1]:
        h = jnp.tanh(h @ W + b)
    W, b = layers[-1]
    return (h @ W + b)[..., 0]


def log_prob(mean, log_std, a):
    import jax.numpy as jnp

    z = (a - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * z * z - log_std - 0.5 * math.log(2 * math.pi), axis=-1)


def entropy(log_std):
    import jax.numpy as jnp

    return jnp.sum(log_std + 0.5 * math.log(2 * math.pi * math.e))


class RunningStats(NamedTuple):
    """Running mean and variance of the observations (SB3's ``RunningMeanStd``: count starts at 1e-4)."""
    mean: object
    var: object
    count: object


def stats_init(n_obs: int) -> RunningStats:
    import jax.numpy as jnp

    return RunningStats(jnp.zeros(n_obs), jnp.ones(n_obs), jnp.asarray(1e-4))


def stats_update(s: RunningStats, x) -> RunningStats:
    """The statistics after a batch ``x`` (B, n_obs) (Chan et al.'s parallel update, as SB3)."""
    bm, bv, bc = x.mean(0), x.var(0), x.shape[0]
    delta = bm - s.mean
    tot = s.count + bc
    m2 = s.var * s.count + bv * bc + delta * delta * s.count * bc / tot
    return RunningStats(s.mean + delta * bc / tot, m2 / tot, tot)


def normalize(s: RunningStats, x, clip: float):
    """``ObservationNormalizer``'s rule: (x − mean)/√(var + ε), clipped to ±clip."""
    import jax.numpy as jnp

    return jnp.clip((x - s.mean) / jnp.sqrt(s.var + OBS_EPS), -clip, clip)


def optimizer(cfg: Config):
    """Adam (SB3's and PureJaxRL's ε) after the gradient's global norm is clipped to ``max_grad_norm``; with
    ``anneal_lr`` its learning rate falls linearly to 0 over the updates, constant within one update's epochs
    (PureJaxRL's schedule: optax counts minibatch steps)."""
    import optax

    per_update = cfg.update_epochs * cfg.num_minibatches
    lr = (lambda count: cfg.lr * (1.0 - (count // per_update) / cfg.num_updates)) if cfg.anneal_lr else cfg.lr
    return optax.chain(optax.clip_by_global_norm(cfg.max_grad_norm),
                       optax.adam(lr, b1=ADAM_B1, b2=ADAM_B2, eps=ADAM_EPS))


# ---------------------------------------------------------------- GAE

def gae(rewards, values, last_value, terminated, truncated, final_values, gamma: float, lam: float):
    """(advantages, value targets), each (T, N), of a rollout: ``values[t]`` = V(s_t), ``last_value`` = V(s_T)
    (the observation after the last step), ``final_values[t]`` = V of the observation that ended an episode at
    step t (read where ``truncated[t]``). After a termination nothing follows; after a truncation the episode
    would have gone on, so its value is bootstrapped from ``final_values``; after either, the next step's value
    belongs to a new episode and is not used."""
    import jax.numpy as jnp
    from jax import lax

    def body(carry, x):
        next_adv, next_value = carry
        r, v, term, trunc, vf = x
        done = term | trunc
        future = jnp.where(done, jnp.where(trunc, vf, 0.0), next_value)
        adv = r + gamma * future - v + gamma * lam * jnp.where(done, 0.0, next_adv)
        return (adv, v), adv

    _, adv = lax.scan(body, (jnp.zeros_like(last_value), last_value),
                      (rewards, values, terminated, truncated, final_values), reverse=True)
    return adv, adv + values


# ---------------------------------------------------------------- the training

#: The columns of the metrics ``train`` returns, one row per update.
METRICS = ("episode_return", "episodes", "policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction", "std")


class Runner(NamedTuple):
    params: dict          # {"actor": layers, "log_std": (n_act,), "critic": layers}
    opt: tuple
    env_state: object
    obs: object           # (N, n_obs) normalised observations the next actions are taken on
    stats: RunningStats
    key: object
    ep_return: object     # (N,) the running episodes' returns so far
    update: object        # updates done


def make_train(cfg: Config):
    """``train(key, env_params) -> (runner, metrics)``: the whole training as one function (jit it); ``metrics``
    holds one row per update (mean return of the episodes that ended in its rollout, their count, the losses,
    the approximate KL, the clipped fraction, the policy's std)."""
    import jax
    import jax.numpy as jnp
    import optax
    from jax import lax

    from mrd_env.plants.quarter_car import jax_twin as qc

    check_config(cfg)
    n, T = cfg.num_envs, cfg.num_steps
    batch = n * T
    v_reset = jax.vmap(qc.reset, in_axes=(0, None))
    v_step = jax.vmap(qc.step_autoreset, in_axes=(0, 0, 0, None))
    tx = optimizer(cfg)

    def init(key, env_params):
        k_env, k_actor, k_critic, key = jax.random.split(key, 4)
        obs, env_state = v_reset(jax.random.split(k_env, n), env_params)
        n_obs = obs.shape[-1]
        params = {"actor": mlp_init(k_actor, (n_obs, *cfg.hidden, 1), 0.01),
                  "log_std": jnp.full((1,), cfg.log_std_init, jnp.float64),
                  "critic": mlp_init(k_critic, (n_obs, *cfg.hidden, 1), 1.0)}
        stats = stats_update(stats_init(n_obs), obs)
        return Runner(params, tx.init(params), env_state, normalize(stats, obs, cfg.obs_clip), stats, key,
                      jnp.zeros(n), jnp.asarray(0, jnp.int32))

    def rollout_step(carry, _):
        r, env_params, ended_sum, ended_n = carry
        key, k_act, k_env = jax.random.split(r.key, 3)
        obs = r.obs
        mean = policy_mean(r.params["actor"], obs)
        a = mean + jnp.exp(r.params["log_std"]) * jax.random.normal(k_act, mean.shape)
        logp = log_prob(mean, r.params["log_std"], a)
        v = value(r.params["critic"], obs)
        raw, env_state, reward, term, trunc, info = v_step(jax.random.split(k_env, n), r.env_state, a, env_params)
        stats = stats_update(r.stats, raw)
        v_final = value(r.params["critic"], normalize(stats, info["final_observation"], cfg.obs_clip))
        done = term | trunc
        ep = r.ep_return + reward
        ended_sum, ended_n = ended_sum + jnp.sum(jnp.where(done, ep, 0.0)), ended_n + jnp.sum(done)
        r = r._replace(env_state=env_state, obs=normalize(stats, raw, cfg.obs_clip), stats=stats, key=key,
                       ep_return=jnp.where(done, 0.0, ep))
        return (r, env_params, ended_sum, ended_n), (obs, a, logp, v, reward, term, trunc, v_final)

    def loss_fn(params, mb):
        obs, a, logp_old, adv, target = mb
        mean = policy_mean(params["actor"], obs)
        logp = log_prob(mean, params["log_std"], a)
        ratio = jnp.exp(logp - logp_old)
        adv = (adv - adv.mean()) / (adv.std() + 1e-8)
        pg = -jnp.mean(jnp.minimum(ratio * adv, jnp.clip(ratio, 1 - cfg.clip_eps, 1 + cfg.clip_eps) * adv))
        v_loss = 0.5 * jnp.mean((value(params["critic"], obs) - target) ** 2)
        ent = entropy(params["log_std"])
        kl = jnp.mean((ratio - 1) - (logp - logp_old))  # the k3 estimator (SB3's approx_kl)
        clipped = jnp.mean((jnp.abs(ratio - 1) > cfg.clip_eps).astype(jnp.float64))
        return pg + cfg.vf_coef * v_loss - cfg.ent_coef * ent, (pg, v_loss, ent, kl, clipped)

    def update(carry, _):
        r, env_params = carry
        (r, _, ended_sum, ended_n), traj = lax.scan(
            rollout_step, (r, env_params, jnp.asarray(0.0, jnp.float64), jnp.asarray(0, jnp.int64)), None, T)
        obs, a, logp, v, rew, term, trunc, v_final = traj
        adv, target = gae(rew, v, value(r.params["critic"], r.obs), term, trunc, v_final, cfg.gamma,
                          cfg.gae_lambda)
        flat = [x.reshape(batch, *x.shape[2:]) for x in (obs, a, logp, adv, target)]

        def epoch(c, _):
            params, opt, key = c
            key, k = jax.random.split(key)
            perm = jax.random.permutation(k, batch)
            mbs = [x[perm].reshape(cfg.num_minibatches, cfg.minibatch_size, *x.shape[1:]) for x in flat]

            def minibatch(c2, mb):
                params, opt = c2
                (_, aux), grads = jax.value_and_grad(loss_fn, has_aux=True)(params, mb)
                step, opt = tx.update(grads, opt, params)
                params = optax.apply_updates(params, step)
                return (params, opt), jnp.stack(aux)

            (params, opt), aux = lax.scan(minibatch, (params, opt), mbs)
            return (params, opt, key), aux

        (params, opt, key), aux = lax.scan(epoch, (r.params, r.opt, r.key), None, cfg.update_epochs)
        aux = aux.reshape(-1, aux.shape[-1]).mean(0)
        row = jnp.concatenate([jnp.stack([jnp.where(ended_n > 0, ended_sum / jnp.maximum(ended_n, 1), jnp.nan),
                                          ended_n.astype(jnp.float64)]), aux,
                               jnp.exp(params["log_std"])[:1]])
        return (r._replace(params=params, opt=opt, key=key, update=r.update + 1), env_params), row

    def train(key, env_params):
        r = init(key, env_params)
        (r, _), rows = lax.scan(update, (r, env_params), None, cfg.num_updates)
        return r, rows

    return train



# ---------------------------------------------------------------- the environment, the agent, the command line

def env_params(*, seed: int = 0, n_roads: int = 32, road_classes=("B", "C", "D"), speeds=(10.0, 30.0),
               episode_seconds: float = 10.0, scheme: str = "differentiable", substeps: int = 1):
    """The twin's ``EnvParams`` at ``QuarterCar-v1``'s defaults (10 ms control, normalised actions) on a bank of
    ``n_roads`` ISO 8608 roads: class ``road_classes[i % k]``, speed uniform in ``speeds``, both drawn from
    ``seed``. ``ValueError`` naming a bad option."""
    from mrd_env.disturbances import iso8608_road
    from mrd_env.plants.quarter_car import jax_twin as qc
    from mrd_env.validation import check_scalar

    n_roads = int(check_scalar("n_roads", n_roads, 1, 4096))
    if len(speeds) != 2 or not 0 < speeds[0] <= speeds[1] < math.inf:
        raise ValueError(f"speeds must be two speeds 0 < lo <= hi (m/s), got {list(speeds)}")
    check_scalar("episode_seconds", episode_seconds, 0.0, 600.0, lo_open=True, unit="s")
    rng = np.random.default_rng([seed, 41])
    roads = [iso8608_road(road_classes[i % len(road_classes)], float(rng.uniform(*speeds)), episode_seconds, 1e-3,
                          rng=int(rng.integers(2 ** 31)), method="fft") for i in range(n_roads)]
    return qc.make_params(roads=roads, episode_seconds=episode_seconds, control_dt=CONTROL_DT, scheme=scheme,
                          substeps=substeps, action_mode="normalized")


def mean_policy(runner: Runner, cfg: Config):
    """The deterministic policy (the Gaussian's mean network) as an :class:`~controllers.mlp_policy.MLPPolicy`
    (weights layer by layer, each (n_in, n_out) matrix row-major then its bias) and its
    :class:`~controllers.agents.ObservationNormalizer`."""
    from controllers.agents import ObservationNormalizer
    from controllers.mlp_policy import MLPPolicy

    layers = runner.params["actor"]
    sizes = (layers[0][0].shape[0], *(W.shape[1] for W, _ in layers))
    theta = np.concatenate([np.concatenate([np.asarray(W).ravel(), np.asarray(b)]) for W, b in layers])
    stats = runner.stats
    return MLPPolicy(sizes, theta), ObservationNormalizer(np.asarray(stats.mean), np.asarray(stats.var),
                                                          cfg.obs_clip, OBS_EPS)


def curve_csv(rows) -> bytes:
    """The learning curve: one row per update (its number, then ``METRICS``)."""
    rows = np.asarray(rows)
    lines = [",".join(("update",) + METRICS)]
    lines += [",".join([str(i + 1)] + [f"{x:.10g}" for x in row]) for i, row in enumerate(rows)]
    return ("\n".join(lines) + "\n").encode()


def save(folder, runner: Runner, rows, cfg: Config, meta: dict) -> Path:
    """Save the mean policy in the code-free agent format (atomic: :func:`controllers.agents.save_agent`)."""
    from controllers.agents import save_agent
    from mrd_env.plants import plant_of_id

    policy, normalizer = mean_policy(runner, cfg)
    spec = plant_of_id(ENV_ID)
    meta = {"name": f"PPO-JAX {Path(folder).name}", "plant": spec.name, "env_id": spec.physics_id,
            "algo": "PPO-JAX", "recurrent": False, **meta,
            "hyperparameters": {**dataclasses.asdict(cfg), **meta.get("hyperparameters", {})}}
    return save_agent(folder, meta, policy=policy, normalizer=normalizer,
                      extra_files={"training.csv": curve_csv(rows)})


class UsageError(Exception):
    """A bad command line: one line on stderr, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # argparse prints the usage too and exits itself: one line instead
        raise UsageError(message)


def parser() -> argparse.ArgumentParser:
    d = Config()
    ap = _Parser(prog="python -m experiments.training.ppo_jax", description=__doc__.split("\n\n")[0],
                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--seed", type=int, default=0, help="seeds the networks, the actions, the resets and the "
                    "road bank")
    ap.add_argument("--num-envs", type=int, default=d.num_envs, help="N environments stepped together")
    ap.add_argument("--num-steps", type=int, default=d.num_steps, help="steps per environment per rollout")
    ap.add_argument("--total-timesteps", type=int, default=d.total_timesteps,
                    help="env-steps in all (rounded down to whole rollouts)")
    ap.add_argument("--update-epochs", type=int, default=d.update_epochs)
    ap.add_argument("--num-minibatches", type=int, default=d.num_minibatches)
    ap.add_argument("--lr", type=float, default=d.lr, help="Adam's learning rate")
    ap.add_argument("--no-anneal-lr", action="store_true", help="keep the learning rate constant (default: "
                    "linearly to 0)")
    ap.add_argument("--gamma", type=float, default=d.gamma)
    ap.add_argument("--gae-lambda", type=float, default=d.gae_lambda)
    ap.add_argument("--clip-eps", type=float, default=d.clip_eps)
    ap.add_argument("--ent-coef", type=float, default=d.ent_coef)
    ap.add_argument("--vf-coef", type=float, default=d.vf_coef)
    ap.add_argument("--max-grad-norm", type=float, default=d.max_grad_norm)
    ap.add_argument("--hidden", type=int, nargs="+", default=list(d.hidden), help="hidden layer sizes (tanh)")
    ap.add_argument("--log-std-init", type=float, default=d.log_std_init)
    ap.add_argument("--scheme", choices=("differentiable", "exact"), default="differentiable",
                    help="the twin's scheme (differentiable: fixed work per step; 2.8x the exact scheme's "
                    "training throughput at N = 64 on 2 CPU cores, bench_ppo_jax)")
    ap.add_argument("--substeps", type=int, default=1, help="the differentiable scheme's sub-steps (1, 2, 4, 8)")
    ap.add_argument("--n-roads", type=int, default=32, help="roads in the bank")
    ap.add_argument("--road-classes", nargs="+", default=["B", "C", "D"], help="ISO 8608 classes, cycled")
    ap.add_argument("--speeds", type=float, nargs=2, default=[10.0, 30.0], metavar=("LO", "HI"),
                    help="speed range (m/s), drawn per road")
    ap.add_argument("--episode-seconds", type=float, default=10.0)
    ap.add_argument("--out", type=Path, default=None, help="the agent's folder (default results/agents/"
                    "ppo_jax_s<seed>)")
    ap.add_argument("--print-every", type=int, default=10, help="print every k-th update's metrics")
    return ap


def config_of(args) -> Config:
    return Config(num_envs=args.num_envs, num_steps=args.num_steps, total_timesteps=args.total_timesteps,
                  update_epochs=args.update_epochs, num_minibatches=args.num_minibatches, lr=args.lr,
                  anneal_lr=not args.no_anneal_lr, gamma=args.gamma, gae_lambda=args.gae_lambda,
                  clip_eps=args.clip_eps, ent_coef=args.ent_coef, vf_coef=args.vf_coef,
                  max_grad_norm=args.max_grad_norm, hidden=tuple(args.hidden), log_std_init=args.log_std_init)


def prepare(argv=None):
    """(arguments, config, environment parameters) of a command line; ``UsageError`` or ``ValueError`` naming
    what is wrong."""
    args = parser().parse_args(argv)
    cfg = config_of(args)
    check_config(cfg)
    if args.print_every < 1:
        raise ValueError(f"--print-every must be >= 1, got {args.print_every}")
    options = {"seed": args.seed, "n_roads": args.n_roads, "road_classes": tuple(args.road_classes),
                  "speeds": tuple(args.speeds), "episode_seconds": args.episode_seconds, "scheme": args.scheme,
                  "substeps": args.substeps}
    return args, cfg, env_params(**options)


def run(args, cfg: Config, params, argv=None) -> int:
    """Train, print the learning curve and the speed, save the agent."""
    import jax

    train = jax.jit(make_train(cfg))
    key = jax.random.PRNGKey(args.seed)
    t0 = time.perf_counter()
    compiled = train.lower(key, params).compile()
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    runner, rows = jax.block_until_ready(compiled(key, params))
    wall = time.perf_counter() - t0
    steps = cfg.num_updates * cfg.num_envs * cfg.num_steps
    rows = np.asarray(rows)
    for i in range(0, len(rows), args.print_every):
        print(f"update {i + 1:5d} ({(i + 1) * cfg.num_envs * cfg.num_steps:>10d} steps): "
              + " ".join(f"{m} {x:.4g}" for m, x in zip(METRICS, rows[i])))
    print(f"{steps} env-steps in {wall:.1f} s ({steps / wall:.0f} env-steps/s; compile {compile_s:.1f} s)")
    if not np.all(np.isfinite(rows[:, 2:])):
        raise FloatingPointError("the training diverged: a loss is not finite (see the metrics above)")
    out = args.out or Path("results/agents") / f"ppo_jax_s{args.seed}"
    road = {"kind": "iso8608", "road_class": list(args.road_classes), "speed": tuple(args.speeds)}
    meta = {"seed": args.seed, "timesteps": steps, "command": " ".join(["python -m experiments.training.ppo_jax",
                                                                          *(argv if argv is not None
                                                                            else sys.argv[1:])]),
            "env_kwargs": {"road": road, "episode_seconds": args.episode_seconds, "action_mode": "normalized",
                           "control_dt": CONTROL_DT},
            "hyperparameters": {"scheme": args.scheme, "substeps": args.substeps, "n_roads": args.n_roads},
            "wall_time_s": wall, "compile_s": compile_s, "final_episode_return": float(rows[-1, 0])}
    save(out, runner, rows, cfg, meta)
    print("wrote", out)
    return 0


def main(argv=None) -> int:
    try:
        args, cfg, params = prepare(argv)
    except (UsageError, ValueError) as exc:
        print(f"ppo_jax: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    return run(args, cfg, params, argv)


if __name__ == "__main__":
    raise SystemExit(main())
