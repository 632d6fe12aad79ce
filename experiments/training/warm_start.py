"""Warm start: a policy network that begins as a classical law (behaviour cloning).

The law drives the training environments with Gaussian noise on its actions, so that the states visited are
those of a policy near the law, not only the law's own; the network is then fitted to the law's action in every
state (least squares on the normalised observations). Used by ``mrd-env train --algo cmaes --warm-start LAW``.
"""
from __future__ import annotations

import numpy as np


def collect(law, venv, *, steps: int, noise: float, rng: np.random.Generator):
    """Roll ``law`` out for ``steps`` vector steps on the SB3 VecEnv ``venv`` (its actions in [−1, 1] plus
    N(0, noise²), clipped; ``law`` None: zero actions plus the noise). Returns the observations, the law's actions,
    the rewards and the dones, each (steps, N, ...)."""
    obs = venv.reset()
    start = np.ones(venv.num_envs, bool)
    shape = (venv.num_envs, venv.action_space.shape[0])
    O, A, R, D = [], [], [], []
    for _ in range(int(steps)):
        a = np.zeros(shape, np.float32) if law is None else \
            np.asarray(law.predict(obs, episode_start=start)[0], dtype=np.float32).reshape(shape)
        executed = np.clip(a + noise * rng.standard_normal(shape), -1.0, 1.0).astype(np.float32)
        O.append(obs)
        A.append(a)
        obs, r, done, _ = venv.step(executed)
        R.append(r)
        D.append(done)
        start = done
    return np.asarray(O), np.asarray(A), np.asarray(R, dtype=np.float64), np.asarray(D)


def fit_policy(sizes, obs: np.ndarray, actions: np.ndarray, *, seed: int = 0, epochs: int = 30,
               batch_size: int = 512, learning_rate: float = 3e-3) -> np.ndarray:
    """The flat weights θ of an :class:`~controllers.mlp_policy.MLPPolicy` of ``sizes`` (tanh layers) fitted to
    map the normalised observations ``obs`` (n, n_obs) to ``actions`` (n, n_act) in [−1, 1]."""
    import torch

    torch.set_num_threads(1)  # one thread: the same weights on every machine and worker, bit for bit
    torch.manual_seed(seed)
    layers = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [torch.nn.Linear(a, b), torch.nn.Tanh()]
    net = torch.nn.Sequential(*layers)
    X = torch.as_tensor(obs, dtype=torch.float32)
    # a tanh output cannot reach ±1: aim just inside it
    Y = torch.as_tensor(np.clip(actions, -0.995, 0.995), dtype=torch.float32)
    opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
    rng = np.random.default_rng(seed)
    n = len(X)
    for _ in range(int(epochs)):
        for idx in np.array_split(rng.permutation(n), max(1, n // int(batch_size))):
            i = torch.as_tensor(idx)
            loss = torch.mean((net(X[i]) - Y[i]) ** 2)
            opt.zero_grad()
            loss.backward()
            opt.step()
    theta = []
    for m in net:
        if isinstance(m, torch.nn.Linear):
            theta += [m.weight.detach().numpy().T.ravel(), m.bias.detach().numpy()]  # (n_in, n_out), as MLPPolicy
    return np.concatenate(theta).astype(np.float64)
