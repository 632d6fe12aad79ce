"""A small feed-forward policy in NumPy, the policy an evolution strategy trains (``mrd-env train --algo cmaes``).

Layers ``sizes = (n_obs, *hidden, n_act)``, tanh on every layer including the output, so that the action lies in
the normalised range [−1, 1]; a = tanh(W_L ... tanh(W_1ᵀ o + b_1) ... + b_L) for a normalised observation o. All
weights are one flat vector θ (what the strategy searches), layer by layer, each layer its (n_in, n_out) matrix
then its bias. :meth:`forward` evaluates a whole population of θ on a batch of observations at once.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np


class MLPPolicy:
    def __init__(self, sizes, theta=None):
        self.sizes = tuple(int(s) for s in sizes)
        if len(self.sizes) < 2 or min(self.sizes) < 1:
            raise ValueError(f"sizes must be (n_obs, *hidden, n_act) with every size >= 1, got {sizes!r}")
        self.n_params = sum(a * b + b for a, b in zip(self.sizes[:-1], self.sizes[1:]))
        self.theta = np.zeros(self.n_params) if theta is None else np.asarray(theta, dtype=np.float64)
        if self.theta.shape != (self.n_params,):
            raise ValueError(f"theta must have {self.n_params} parameters, got shape {self.theta.shape}")

    def layers(self, thetas: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """[(W (P, n_in, n_out), b (P, n_out)), ...] of a population ``thetas`` (P, n_params)."""
        thetas = np.atleast_2d(thetas)
        out, k = [], 0
        for a, b in zip(self.sizes[:-1], self.sizes[1:]):
            W = thetas[:, k:k + a * b].reshape(-1, a, b)
            k += a * b
            out.append((W, thetas[:, k:k + b]))
            k += b
        return out

    @staticmethod
    def forward(layers, obs: np.ndarray) -> np.ndarray:
        """Actions (P, E, n_act) of P policies for their batches of normalised observations (P, E, n_obs)."""
        h = obs
        for W, b in layers:
            h = np.tanh(np.einsum("pea,pab->peb", h, W) + b[:, None, :])
        return h

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface: the action of one normalised observation (n_obs,) or of a batch (N, n_obs)."""
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        a = self.forward(self.layers(self.theta), (obs[None] if single else obs)[None])[0]
        return (a[0] if single else a).astype(np.float32), state

    def to_bytes(self) -> bytes:
        """The ``.npz`` file's bytes (``theta``, ``sizes``: arrays only)."""
        buf = io.BytesIO()
        np.savez(buf, theta=self.theta, sizes=np.asarray(self.sizes))
        return buf.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> MLPPolicy:
        """The policy of an ``.npz`` file's bytes, read as arrays only (no pickle); ``ValueError`` otherwise."""
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                sizes, theta = z["sizes"], z["theta"]
        except (OSError, ValueError, KeyError, EOFError) as exc:
            raise ValueError(f"not a policy network file (arrays theta and sizes): {exc}") from None
        if sizes.ndim != 1 or sizes.dtype.kind not in "iu" or theta.dtype.kind != "f":
            raise ValueError("not a policy network file: sizes must be integers and theta numbers")
        return cls(tuple(int(s) for s in sizes), theta)

    def save(self, path: str | Path) -> None:
        Path(path).write_bytes(self.to_bytes())

    @classmethod
    def load(cls, path: str | Path) -> MLPPolicy:
        return cls.from_bytes(Path(path).read_bytes())
