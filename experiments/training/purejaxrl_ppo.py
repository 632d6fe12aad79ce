"""PPO as PureJaxRL writes it (``ppo_continuous_action.py``'s single-file layout), on a plant's twin held as a gymnax
environment (:func:`mrd_env.jax.make_gymnax`): the example of ``docs/jax.md`` ("As gymnax users write it"), which
``tests/jax/test_gymnax_api.py`` runs.

Nothing here knows the plant: the environment is reached only through gymnax's methods (``reset``, ``step``,
``action_space``, ``observation_space``, ``default_params``), vmapped over ``NUM_ENVS`` with ``in_axes=(0, None)``;
rollout, GAE and minibatch epochs are ``jax.lax.scan``s inside one ``jax.jit``; the update is optax's. Two things
differ from PureJaxRL's file, both to keep the project's dependencies as they are: the actor-critic is written in
plain JAX instead of flax (the same layers and initialisation), the Gaussian's log-density and entropy in closed form
instead of distrax. Episode returns are logged by a gymnax-style wrapper (PureJaxRL's ``LogWrapper``'s fields).
For the project's own trainer (observation statistics saved with the agent, truncations bootstrapped, the code-free
agent format) see :mod:`.ppo_jax`.

Run: ``python -m experiments.training.purejaxrl_ppo`` (a short run on ``QuarterCar-v1``; prints the mean episode
return of every tenth update).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from mrd_env.jax import make_gymnax

CONFIG = {"LR": 3e-4, "NUM_ENVS": 64, "NUM_STEPS": 64, "TOTAL_TIMESTEPS": 409_600, "UPDATE_EPOCHS": 4,
          "NUM_MINIBATCHES": 8, "GAMMA": 0.99, "GAE_LAMBDA": 0.95, "CLIP_EPS": 0.2, "ENT_COEF": 0.0, "VF_COEF": 0.5,
          "MAX_GRAD_NORM": 0.5, "ANNEAL_LR": True, "ENV_NAME": "mrd_env/QuarterCar-v1", "ENV_KWARGS": {}}


# ---------------------------------------------------------------- what PureJaxRL's wrappers.py holds
class LogEnvState(NamedTuple):
    env_state: object
    episode_returns: jnp.ndarray
    episode_lengths: jnp.ndarray
    returned_episode_returns: jnp.ndarray
    returned_episode_lengths: jnp.ndarray


class LogWrapper:
    """Keeps the running episode's return and length; ``info`` gets the last finished episode's (PureJaxRL's)."""

    def __init__(self, env):
        self._env = env

    def __getattr__(self, name):
        return getattr(self._env, name)

    def reset(self, key, params=None):
        obs, env_state = self._env.reset(key, params)
        zero = jnp.asarray(0.0)
        return obs, LogEnvState(env_state, zero, jnp.asarray(0), zero, jnp.asarray(0))

    def step(self, key, state, action, params=None):
        obs, env_state, reward, done, info = self._env.step(key, state.env_state, action, params)
        ret, length = state.episode_returns + reward, state.episode_lengths + 1
        state = LogEnvState(env_state, ret * (1 - done), length * (1 - done),
                            state.returned_episode_returns * (1 - done) + ret * done,
                            state.returned_episode_lengths * (1 - done) + length * done)
        info = {**info, "returned_episode_returns": state.returned_episode_returns,
                "returned_episode_lengths": state.returned_episode_lengths, "returned_episode": done}
        return obs, state, reward, done, info


# ---------------------------------------------------------------- the actor-critic (flax's Dense layers in plain JAX)
def dense(key, n_in, n_out, scale):
    return {"kernel": jax.nn.initializers.orthogonal(scale)(key, (n_in, n_out), jnp.float64),
            "bias": jnp.zeros(n_out, jnp.float64)}


def network_init(key, n_obs, n_act):
    k = jax.random.split(key, 6)
    return {"actor": [dense(k[0], n_obs, 256, math.sqrt(2)), dense(k[1], 256, 256, math.sqrt(2)),
                      dense(k[2], 256, n_act, 0.01)],
            "log_std": jnp.zeros(n_act, jnp.float64),
            "critic": [dense(k[3], n_obs, 256, math.sqrt(2)), dense(k[4], 256, 256, math.sqrt(2)),
                       dense(k[5], 256, 1, 1.0)]}


def network_apply(params, x):
    """(the Gaussian's mean and log-std, the value)."""
    def mlp(layers, h):
        for layer in layers[:-1]:
            h = jnp.tanh(h @ layer["kernel"] + layer["bias"])
        return h @ layers[-1]["kernel"] + layers[-1]["bias"]
    return (mlp(params["actor"], x), params["log_std"]), mlp(params["critic"], x)[..., 0]


def log_prob(pi, a):
    mean, log_std = pi
    z = (a - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * z * z - log_std - 0.5 * math.log(2 * math.pi), axis=-1)


def entropy(pi):
    return jnp.sum(pi[1] + 0.5 * math.log(2 * math.pi * math.e))


class Transition(NamedTuple):
    done: jnp.ndarray
    action: jnp.ndarray
    value: jnp.ndarray
    reward: jnp.ndarray
    log_prob: jnp.ndarray
    obs: jnp.ndarray
    info: dict


# ---------------------------------------------------------------- PureJaxRL's make_train
def make_train(config):
    config = dict(config)
    config["NUM_UPDATES"] = config["TOTAL_TIMESTEPS"] // config["NUM_STEPS"] // config["NUM_ENVS"]
    config["MINIBATCH_SIZE"] = config["NUM_ENVS"] * config["NUM_STEPS"] // config["NUM_MINIBATCHES"]
    env = make_gymnax(config["ENV_NAME"], **config["ENV_KWARGS"])
    env_params = env.default_params
    env = LogWrapper(env)

    def linear_schedule(count):
        frac = 1.0 - (count // (config["NUM_MINIBATCHES"] * config["UPDATE_EPOCHS"])) / config["NUM_UPDATES"]
        return config["LR"] * frac

    def train(rng):
        # INIT NETWORK
        rng, _rng = jax.random.split(rng)
        params = network_init(_rng, env.observation_space(env_params).shape[0], env.action_space(env_params).shape[0])
        tx = optax.chain(optax.clip_by_global_norm(config["MAX_GRAD_NORM"]),
                         optax.adam(linear_schedule if config["ANNEAL_LR"] else config["LR"], eps=1e-5))
        opt_state = tx.init(params)

        # INIT ENV
        rng, _rng = jax.random.split(rng)
        reset_rng = jax.random.split(_rng, config["NUM_ENVS"])
        obsv, env_state = jax.vmap(env.reset, in_axes=(0, None))(reset_rng, env_params)

        # TRAIN LOOP
        def _update_step(runner_state, unused):
            # COLLECT TRAJECTORIES
            def _env_step(runner_state, unused):
                params, opt_state, env_state, last_obs, rng = runner_state
                rng, _rng = jax.random.split(rng)
                pi, value = network_apply(params, last_obs)
                action = pi[0] + jnp.exp(pi[1]) * jax.random.normal(_rng, pi[0].shape)
                lp = log_prob(pi, action)
                rng, _rng = jax.random.split(rng)
                rng_step = jax.random.split(_rng, config["NUM_ENVS"])
                obsv, env_state, reward, done, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
                    rng_step, env_state, action, env_params)
                transition = Transition(done, action, value, reward, lp, last_obs, info)
                return (params, opt_state, env_state, obsv, rng), transition

            runner_state, traj_batch = jax.lax.scan(_env_step, runner_state, None, config["NUM_STEPS"])

            # CALCULATE ADVANTAGE
            params, opt_state, env_state, last_obs, rng = runner_state
            _, last_val = network_apply(params, last_obs)

            def _get_advantages(gae_and_next_value, transition):
                gae, next_value = gae_and_next_value
                done, value, reward = transition.done, transition.value, transition.reward
                delta = reward + config["GAMMA"] * next_value * (1 - done) - value
                gae = delta + config["GAMMA"] * config["GAE_LAMBDA"] * (1 - done) * gae
                return (gae, value), gae

            _, advantages = jax.lax.scan(_get_advantages, (jnp.zeros_like(last_val), last_val), traj_batch,
                                         reverse=True)
            targets = advantages + traj_batch.value

            # UPDATE NETWORK
            def _update_epoch(update_state, unused):
                def _update_minbatch(carry, batch_info):
                    params, opt_state = carry
                    traj_batch, advantages, targets = batch_info

                    def _loss_fn(params, traj_batch, gae, targets):
                        pi, value = network_apply(params, traj_batch.obs)
                        lp = log_prob(pi, traj_batch.action)
                        value_pred_clipped = traj_batch.value + (value - traj_batch.value).clip(
                            -config["CLIP_EPS"], config["CLIP_EPS"])
                        value_loss = 0.5 * jnp.maximum(jnp.square(value - targets),
                                                       jnp.square(value_pred_clipped - targets)).mean()
                        ratio = jnp.exp(lp - traj_batch.log_prob)
                        gae = (gae - gae.mean()) / (gae.std() + 1e-8)
                        loss_actor = -jnp.minimum(ratio * gae, jnp.clip(ratio, 1.0 - config["CLIP_EPS"],
                                                                        1.0 + config["CLIP_EPS"]) * gae).mean()
                        ent = entropy(pi)
                        total_loss = loss_actor + config["VF_COEF"] * value_loss - config["ENT_COEF"] * ent
                        return total_loss, (value_loss, loss_actor, ent)

                    total_loss, grads = jax.value_and_grad(_loss_fn, has_aux=True)(params, traj_batch, advantages,
                                                                                 targets)
                    updates, opt_state = tx.update(grads, opt_state, params)
                    return (optax.apply_updates(params, updates), opt_state), total_loss

                params, opt_state, traj_batch, advantages, targets, rng = update_state
                rng, _rng = jax.random.split(rng)
                batch_size = config["MINIBATCH_SIZE"] * config["NUM_MINIBATCHES"]
                permutation = jax.random.permutation(_rng, batch_size)
                batch = jax.tree_util.tree_map(lambda x: x.reshape((batch_size,) + x.shape[2:]),
                                               (traj_batch, advantages, targets))
                shuffled = jax.tree_util.tree_map(lambda x: jnp.take(x, permutation, axis=0), batch)
                minibatches = jax.tree_util.tree_map(
                    lambda x: jnp.reshape(x, [config["NUM_MINIBATCHES"], -1] + list(x.shape[1:])), shuffled)
                (params, opt_state), total_loss = jax.lax.scan(_update_minbatch, (params, opt_state), minibatches)
                return (params, opt_state, traj_batch, advantages, targets, rng), total_loss

            update_state = (params, opt_state, traj_batch, advantages, targets, rng)
            update_state, loss_info = jax.lax.scan(_update_epoch, update_state, None, config["UPDATE_EPOCHS"])
            params, opt_state, rng = update_state[0], update_state[1], update_state[-1]
            metric = {**traj_batch.info, "total_loss": loss_info[0], "value_loss": loss_info[1][0]}
            return (params, opt_state, env_state, last_obs, rng), metric

        rng, _rng = jax.random.split(rng)
        runner_state = (params, opt_state, env_state, obsv, _rng)
        runner_state, metric = jax.lax.scan(_update_step, runner_state, None, config["NUM_UPDATES"])
        return {"runner_state": runner_state, "metrics": metric}

    return train


def episode_returns(metrics) -> np.ndarray:
    """The mean return of the episodes that ended in each update's rollout (NaN where none did)."""
    done = np.asarray(metrics["returned_episode"]).reshape(len(metrics["returned_episode"]), -1)
    ret = np.asarray(metrics["returned_episode_returns"]).reshape(done.shape)
    with np.errstate(invalid="ignore"):
        return np.where(done.any(1), (ret * done).sum(1) / done.sum(1), np.nan)


if __name__ == "__main__":
    out = jax.jit(make_train(CONFIG))(jax.random.PRNGKey(0))
    for i, r in enumerate(episode_returns(out["metrics"])):
        if i % 10 == 0:
            print(f"update {i:4d}: mean episode return {r:.4f}")
