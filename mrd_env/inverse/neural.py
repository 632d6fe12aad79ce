"""Neural inverse: a small multilayer perceptron over a short history of the measured motion and force.

At t_k the network maps the desired force f_d(t_{k+1}), the last H measured forces, strokes and velocities and
the effective command û_k to the change of the effective command over the step, u_{k+1} − û_k; the command sent
is the one that brings the first-order command lag u̇ = −η (u − v) from û_k to u_{k+1} in one step,
v = (u_{k+1} − û_k e^(−η dt))/(1 − e^(−η dt)), clipped to the range. û_k is the lag driven by the inverse's own
past commands (known exactly, so the network need not learn the lag, the part of the inverse that amplifies
errors by 1/(1 − e^(−η dt)), ≈ 5.8 at 1 ms for η = 190 s⁻¹). The inputs are levels and one-step differences,
each divided by its standard deviation in the training data (σ_F of the force, σ_ΔF of its one-step change,
σ_x, σ_v, σ_Δv, and σ_Δu of the effective command's change), so that the small changes the inverse turns on are
not buried under the levels (:func:`_features`)::

    input  = [(f_d − f_k)/σ_ΔF, (f_{k−i} − f_{k−i−1})/σ_ΔF (i < H−1), f_k/σ_F, x_k/σ_x, ẋ_k/σ_v,
              (x_{k−i} − x_{k−i−1})/(σ_v dt), (ẋ_{k−i} − ẋ_{k−i−1})/σ_Δv (i < H−1), (û_k − v_min)/(v_max − v_min)]
    output = (u_{k+1} − û_k)/σ_Δu                        layers: tanh, the last one linear

Networks are trained with torch (:func:`mrd_env.inverse.training.train_neural_inverse`) and stored as one
``.npz`` file of float64 weights with their metadata (JSON); inference runs in compiled numpy code
(:func:`_mlp`), not torch, so that a call costs microseconds (torch's per-call overhead is measured in
``experiments/measurements/speed/inverse.py``) and a reloaded network gives bit-identical commands. Networks for the
default presets ship in ``mrd_env/inverse/networks/`` (each file's metadata holds the command that reproduces
it): ``make_inverse("neural", damper)`` finds the one trained for the damper's model and preset.
"""
from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numba as nb
import numpy as np

from .. import storage
from ..resources import file_limit
from ..validation import shown
from .base import Inverse, lag_decay, writable_c

NETWORKS = Path(__file__).with_name("networks")
FORMAT = "mrd-env-neural-inverse"
#: The standard deviations that scale the network's inputs and output (see the module docstring).
SCALES = ("force", "force_change", "stroke", "velocity", "velocity_change", "command_change")


def n_inputs(history: int) -> int:
    """The network's input width for a history of H samples: 3 H + 2."""
    return 3 * history + 2


@nb.njit(cache=True)
def _features(hf, hx, hv, u_hat, fd, scales, lo, span, dt, inp):
    """The network's input (see the module docstring) into ``inp`` from the histories hf, hx, hv (newest
    first, H samples each), û and f_d. Shared by inference and training, so both see the same numbers."""
    H = hf.shape[0]
    sF, sdF, sx, sv, sdv = scales[0], scales[1], scales[2], scales[3], scales[4]
    inp[0] = (fd - hf[0]) / sdF
    j = 1
    for i in range(H - 1):
        inp[j] = (hf[i] - hf[i + 1]) / sdF
        j += 1
    inp[j] = hf[0] / sF
    inp[j + 1] = hx[0] / sx
    inp[j + 2] = hv[0] / sv
    j += 3
    for i in range(H - 1):
        inp[j] = (hx[i] - hx[i + 1]) / (sv * dt)
        inp[j + 1] = (hv[i] - hv[i + 1]) / sdv
        j += 2
    inp[j] = (u_hat - lo) / span


@dataclass(frozen=True)
class Network:
    """A trained inverse network: layer weights (out, in) and biases, the input history H, the scales and the
    damper and step it was trained for (``meta``: model, parameters, command channel, dt, training settings
    and the command that reproduces it)."""

    weights: tuple
    biases: tuple
    history: int
    scales: tuple  # (σ_F N, σ_ΔF N, σ_x m, σ_v m/s, σ_Δv m/s, σ_Δu V or A) of :data:`SCALES`
    meta: dict

    @property
    def n_inputs(self) -> int:
        return n_inputs(self.history)

    def to_torch(self):
        """The network as a float64 ``torch.nn.Sequential`` (Linear and Tanh layers) with these weights."""
        import torch

        layers = []
        for i, (W, b) in enumerate(zip(self.weights, self.biases)):
            lin = torch.nn.Linear(W.shape[1], W.shape[0]).double()
            with torch.no_grad():
                lin.weight.copy_(torch.from_numpy(W))
                lin.bias.copy_(torch.from_numpy(b))
            layers += [lin] + ([torch.nn.Tanh()] if i < len(self.weights) - 1 else [])
        return torch.nn.Sequential(*layers)

    def save(self, path: str | Path) -> Path:
        """Write the network as ``.npz`` (float64 weights, metadata as JSON); :func:`load_network` reads it back
        exactly."""
        path = Path(path)
        meta = {**self.meta, "format": FORMAT, "history": self.history, "scales": list(self.scales),
                "layers": len(self.weights)}
        arrays = {f"W{i}": np.asarray(w, dtype=np.float64) for i, w in enumerate(self.weights)}
        arrays.update({f"b{i}": np.asarray(b, dtype=np.float64) for i, b in enumerate(self.biases)})
        with storage.atomic_path(path) as tmp, tmp.open("wb") as fh:
            np.savez(fh, meta=np.array(json.dumps(meta, sort_keys=True)), **arrays)
        return path


def load_network(path: str | Path) -> Network:
    """A network saved by :meth:`Network.save`; ``ValueError`` for a missing or foreign file."""
    path = Path(path)
    foreign = f"{path}: not a neural-inverse network file (mrd-env inverse train writes them)"
    data = storage.read_limited(path, file_limit(), what="network file")  # regular files only: no FIFO, no device
    try:
        z = np.load(io.BytesIO(data), allow_pickle=False)
    except (OSError, ValueError):  # not an array file at all (numpy's own message speaks of pickles)
        raise ValueError(f"{foreign}: not an .npz archive") from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise ValueError(f"{foreign}: a single array, not an .npz archive")
    with z:
        try:
            meta = json.loads(str(z["meta"]))
            n = int(meta["layers"])
            weights = tuple(np.array(z[f"W{i}"], dtype=np.float64) for i in range(n))
            biases = tuple(np.array(z[f"b{i}"], dtype=np.float64) for i in range(n))
        except KeyError as exc:
            raise ValueError(f"{foreign}: no {exc.args[0]!r} in it") from None
        except (TypeError, ValueError) as exc:  # json.JSONDecodeError is a ValueError
            raise ValueError(f"{foreign}: unreadable metadata ({exc})") from None
    if meta.get("format") != FORMAT:
        raise ValueError(f"{foreign}: format {meta.get('format')!r}, expected {FORMAT!r}")
    return Network(weights, biases, int(meta["history"]), tuple(float(s) for s in meta["scales"]), meta)


def shipped_network(damper) -> Path:
    """The network shipped for ``damper``'s model and preset (parameters and command channel equal to a
    preset's), else ``ValueError`` saying how to train one."""
    cls = type(damper)
    for preset, spec in cls.presets.items():
        if spec.params == damper.params and spec.command == damper.command:
            path = NETWORKS / f"{damper.name}_{preset}.npz"
            if path.is_file():
                return path
    have = sorted(p.stem for p in NETWORKS.glob("*.npz"))
    raise ValueError(f"no neural inverse ships for this {damper.name!r} damper (networks ship for the presets "
                     f"{have}); train one with mrd_env.inverse.train_neural_inverse (mrd-env inverse train) and "
                     "pass network=<file>")


def _flat(net: Network) -> tuple[np.ndarray, np.ndarray]:
    """All weights and biases in one float64 vector, and the layer sizes (n_in, n_1, ..., n_out)."""
    parts, sizes = [], [net.weights[0].shape[1]]
    for W, b in zip(net.weights, net.biases):
        parts += [W.ravel(), b.ravel()]
        sizes.append(W.shape[0])
    return np.ascontiguousarray(np.concatenate(parts)), np.array(sizes, dtype=np.int64)


@nb.njit(cache=True)
def _mlp(inp, flat, sizes, work):
    """The network's output for one input vector: tanh layers, the last linear. ``work`` (2, max width)."""
    n_layers = sizes.shape[0] - 1
    src = 0
    for i in range(sizes[0]):
        work[0, i] = inp[i]
    o = 0
    for layer in range(n_layers):
        n_in, n_out = sizes[layer], sizes[layer + 1]
        dst = 1 - src
        bias = o + n_in * n_out
        for r in range(n_out):
            acc = flat[bias + r]
            row = o + r * n_in
            for k in range(n_in):
                acc += flat[row + k] * work[src, k]
            work[dst, r] = math.tanh(acc) if layer < n_layers - 1 else acc
        o = bias + n_out
        src = dst
    return work[src, 0]


@nb.njit(cache=True)
def _neural_commands(flat, sizes, scales, Hf, Hx, Hv, u_hat, fd, x, v, fm, lo, hi, dt, decay, out, work, inp):
    """One control step for N dampers: push the measurements into the histories Hf, Hx, Hv (N, H; newest
    first), evaluate the network, invert the lag from û (N,), clip, and advance û with the command sent."""
    H = Hf.shape[1]
    span = hi - lo
    for b in range(fd.shape[0]):
        for i in range(H - 1, 0, -1):
            Hf[b, i] = Hf[b, i - 1]
            Hx[b, i] = Hx[b, i - 1]
            Hv[b, i] = Hv[b, i - 1]
        Hf[b, 0] = fm[b]
        Hx[b, 0] = x[b]
        Hv[b, 0] = v[b]
        _features(Hf[b], Hx[b], Hv[b], u_hat[b], fd[b], scales, lo, span, dt, inp)
        u_next = u_hat[b] + scales[5] * _mlp(inp, flat, sizes, work)
        d = decay[0] if u_next > u_hat[b] else decay[1]  # the rate of a rising or a falling command
        c = min(max((u_next - u_hat[b] * d) / (1.0 - d), lo), hi)
        out[b] = c
        u_hat[b] = c + (u_hat[b] - c) * (decay[0] if c > u_hat[b] else decay[1])


@nb.njit(cache=True)
def feature_matrix(F, x, v, u, fd, u_next, H, scales, lo, hi, dt, X, y):
    """Training samples of one record (arrays (n,)): for k = H−1 .. n−2 the input at t_k with the desired force
    fd[k] into X[k − H + 1] and the scaled target (u_next[k] − u_k)/σ_Δu into y (naturally fd[k] = F[k + 1] and
    u_next[k] = u[k + 1])."""
    span = hi - lo
    for k in range(H - 1, F.shape[0] - 1):
        lo_k = k - H + 1
        _features(F[lo_k:k + 1][::-1], x[lo_k:k + 1][::-1], v[lo_k:k + 1][::-1], u[k], fd[k], scales, lo, span,
                  dt, X[lo_k])
        y[lo_k] = (u_next[k] - u[k]) / scales[5]


class NeuralInverse(Inverse):
    """Neural inverse (see the module docstring). ``network``: a :class:`Network`, a path to a saved one, or
    None for the network shipped for the damper's preset. The network's damper model, command channel and step
    must be the inverse's. ``u0``: the effective command at the first call (default v_min)."""

    name = "neural"
    needs_force = True

    def __init__(self, damper, *, dt: float = 1e-3, network=None, u0: float | None = None):
        super().__init__(damper, dt=dt)
        if network is None:
            network = shipped_network(self.damper)
        net = network if isinstance(network, Network) else load_network(network)
        meta = net.meta
        c = self.damper.command
        if meta.get("model") != self.damper.name:
            raise ValueError(f"network was trained for the {meta.get('model')!r} model, the damper is "
                             f"{self.damper.name!r}")
        trained = meta.get("command", {})
        if (trained.get("unit"), trained.get("v_min"), trained.get("v_max")) != (c.unit, c.v_min, c.v_max):
            raise ValueError(f"network was trained for commands {trained.get('v_min')}..{trained.get('v_max')} "
                             f"{trained.get('unit')}, the damper's are {c.v_min:g}..{c.v_max:g} {c.unit}")
        lag = (trained.get("eta"), trained.get("eta_fall"))
        if lag[1] is not None and not np.allclose(lag, (c.eta, c.eta_down), rtol=1e-9):
            raise ValueError(f"network was trained for a command lag eta = {lag[0]:g}, eta_fall = {lag[1]:g} 1/s, "
                             f"the damper's is {c.eta:g}, {c.eta_down:g} 1/s: it inverts the lag it was trained on")
        if abs(float(meta.get("dt", math.nan)) - self.dt) > 1e-9 * self.dt:
            raise ValueError(f"network was trained at dt = {meta.get('dt')} s, the inverse's dt = {self.dt:g} s: "
                             "its input history is sampled at the training step")
        self.network = net
        self._flat, self._sizes = _flat(net)
        self._scales = np.array(net.scales, dtype=np.float64)
        self._decay = lag_decay(c, self.dt)
        self.u0 = self.v_min if u0 is None else float(u0)
        if not self.v_min <= self.u0 <= self.v_max:
            raise ValueError(f"u0 = {shown(u0)} is invalid: must be within [{self.v_min:g}, {self.v_max:g}] {c.unit}")
        self._work = np.zeros((2, int(self._sizes.max())))
        self._inp = np.zeros(net.n_inputs)

    def _start(self, rows, x, v, f_measured):
        H = self.network.history
        if getattr(self, "_Hf", None) is None or self._Hf.shape[0] != self.N:
            self._Hf, self._Hx, self._Hv = (np.zeros((self.N, H)) for _ in range(3))
            self.u_hat = np.zeros(self.N)
        # the history starts full of the first measurement (as the environments' sensor history does)
        self._Hf[rows] = f_measured[rows, None]
        self._Hx[rows] = x[rows, None]
        self._Hv[rows] = v[rows, None]
        self.u_hat[rows] = self.u0

    def _command(self, f_desired, x, v, f_measured):
        out = np.empty(self.N)
        # writable C arrays whatever the caller's (read-only, strided): one compiled variant
        f_desired, x, v, f_measured = (writable_c(a) for a in (f_desired, x, v, f_measured))
        _neural_commands(self._flat, self._sizes, self._scales, self._Hf, self._Hx, self._Hv, self.u_hat,
                         f_desired, x, v, f_measured, self.v_min, self.v_max, self.dt, self._decay, out,
                         self._work, self._inp)
        return out
