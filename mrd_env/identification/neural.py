"""A non-parametric forward model (the review's Table 4 "neural network" class): a small network over a short
history of stroke, velocity and command that predicts the force.

    F_k = MLP( x_{k−l}, ẋ_{k−l}, v_{k−l} for l in LAGS ),   LAGS = 0, 1, 2, 3, 4, 6, 8, ..., 64 samples

Each input is standardised by the training records' mean and standard deviation, the force likewise; the network
has two hidden layers with tanh. The window covers 64 samples (21 ms at 3 kHz): the command's driver/coil lag
(3–8 ms) and the pre-yield hysteresis of the force lie inside it, so the network learns them from the data.

It is trained with Adam (torch, one thread, seeded: bit-reproducible) through :func:`~.fit.fit_model`
(``fit_model("neural", records)``), prepared and scored as the parametric models are (faults excluded, the
force optionally aligned), and returned in the same :class:`~.result.FitResult`; ``predict(fit.damper, record)``
runs it in numpy (float64 arithmetic on the float32 weights: no torch needed to use a trained model), and
:func:`~.presets.save_preset` / :func:`~.presets.load_preset` store and reload it exactly (weights written
as the float32 values they are).
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from ..dampers import CommandSpec
from ..validation import shown
from .prepare import PreparedRecord, prepare_record
from .result import FitResult, record_measures, pooled_measures, record_info

__all__ = ["NeuralOptions", "NeuralForwardModel", "fit_neural", "LAGS"]

LAGS = (0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64)
NAME = "neural"
# records whose sampling rates agree this closely are on one grid: files of one rate round their time stamps
# differently (a few 1e-6 of the mean interval), a real change of rate is far larger
RATE_RTOL = 1e-4


def same_rate(dt_a: float, dt_b: float) -> bool:
    """Whether two sampling intervals (s) are the same rate within :data:`RATE_RTOL`."""
    return abs(dt_a - dt_b) <= RATE_RTOL * max(dt_a, dt_b)


def _rate(dt: float) -> str:
    return f"{1.0 / dt:.6g} Hz (dt = {dt:.6g} s)"


@dataclass(frozen=True)
class NeuralOptions:
    """The network: ``hidden`` units in each of two tanh layers, ``lags`` (samples back in time, 0 = now),
    ``batch`` samples per Adam step, learning rate ``lr`` (decayed by cosine to 1/20 over the epochs, which are
    ``SearchOptions.maxiter``), ``weight_decay`` (AdamW)."""

    hidden: int = 48
    lags: tuple[int, ...] = LAGS
    batch: int = 256
    lr: float = 3e-3
    weight_decay: float = 1e-5

    def __post_init__(self) -> None:
        if not (isinstance(self.hidden, int) and 1 <= self.hidden <= 4096):
            raise ValueError(f"hidden = {shown(self.hidden)} is invalid: must be an int in [1, 4096]")
        lags = tuple(self.lags)
        bad = any((not isinstance(k, (int, np.integer))) or k < 0 for k in lags)
        if not lags or bad or len(set(lags)) != len(lags):
            raise ValueError(f"lags = {shown(self.lags)} is invalid: must be distinct ints >= 0")
        object.__setattr__(self, "lags", tuple(int(k) for k in lags))
        if not (isinstance(self.batch, int) and self.batch >= 1):
            raise ValueError(f"batch = {shown(self.batch)} is invalid: must be an int >= 1")
        if not (0 < self.lr < 1):
            raise ValueError(f"lr = {shown(self.lr)} is invalid: must be in (0, 1)")
        if not (0 <= self.weight_decay < 1):
            raise ValueError(f"weight_decay = {shown(self.weight_decay)} is invalid: must be in [0, 1)")


def _windows(prep: PreparedRecord, lags: tuple[int, ...]) -> np.ndarray:
    """(n, 3·len(lags)) inputs: x, ẋ, command at each lag (before the record: its first sample)."""
    rec = prep.series
    idx = np.clip(np.arange(rec.n)[:, None] - np.asarray(lags)[None, :], 0, rec.n - 1)
    return np.concatenate([rec.x[idx], rec.v[idx], rec.command[idx]], axis=1)


class NeuralForwardModel:
    """A trained forward model: force (N) from the history of stroke, velocity and command."""

    name = NAME

    def __init__(self, weights: list[np.ndarray], lags, x_mean, x_std, f_mean: float, f_std: float,
                 command: CommandSpec, dt: float):
        self.weights = [np.asarray(w, dtype=np.float32) for w in weights]
        self.lags = tuple(int(k) for k in lags)
        self.x_mean = np.asarray(x_mean, dtype=np.float64)
        self.x_std = np.asarray(x_std, dtype=np.float64)
        self.f_mean, self.f_std = float(f_mean), float(f_std)
        self.command = command
        self.dt = float(dt)

    @property
    def n_weights(self) -> int:
        return int(sum(w.size for w in self.weights))

    def predict_prepared(self, prep: PreparedRecord) -> np.ndarray:
        """The model force (N) at every sample of a prepared record (its grid step must be the training one)."""
        if not same_rate(prep.dt, self.dt):
            raise ValueError(f"the neural model was trained at {_rate(self.dt)}; record {prep.series.label!r} is "
                             f"sampled at {_rate(prep.dt)}: resample it to the model's step (dt = {self.dt:.6g} s)")
        h = (_windows(prep, self.lags) - self.x_mean) / self.x_std
        W1, b1, W2, b2, W3, b3 = (w.astype(np.float64) for w in self.weights)
        h = np.tanh(h @ W1.T + b1)
        h = np.tanh(h @ W2.T + b2)
        return (h @ W3.T + b3)[:, 0] * self.f_std + self.f_mean

    def to_dict(self) -> dict:
        """A JSON-able description that :meth:`from_dict` turns back into an identical model."""
        c = self.command
        return {"lags": list(self.lags), "dt": self.dt, "x_mean": self.x_mean.tolist(), "x_std": self.x_std.tolist(),
                "f_mean": self.f_mean, "f_std": self.f_std,
                "command": {"unit": c.unit, "v_min": c.v_min, "v_max": c.v_max},
                "weights": [{"shape": list(w.shape), "values": w.ravel().astype(np.float64).tolist()}
                            for w in self.weights]}

    @classmethod
    def from_dict(cls, d: dict) -> "NeuralForwardModel":
        try:
            weights = [np.array(w["values"], dtype=np.float32).reshape(w["shape"]) for w in d["weights"]]
            c = d["command"]
            return cls(weights, d["lags"], d["x_mean"], d["x_std"], d["f_mean"], d["f_std"],
                       CommandSpec(c["unit"], float(c["v_min"]), float(c["v_max"])), d["dt"])
        except (KeyError, TypeError) as exc:
            raise ValueError(f"not a neural forward model description (missing or bad {exc})") from None

    def __repr__(self) -> str:
        return f"NeuralForwardModel({self.n_weights} weights, lags {self.lags}, dt {self.dt:g} s)"


def fit_neural(records, net: NeuralOptions, search, data):
    """Train the network on ``records`` (see the module docstring); returns a :class:`~.result.FitResult`."""
    import torch

    if search.method != "adam":
        raise ValueError(f"the neural model is trained by 'adam', not {search.method!r}")
    t_start = time.perf_counter()
    units = {r.command_unit for r in records}
    if len(units) != 1:
        raise ValueError(f"the records mix command units {sorted(units)}")
    lo = min(float(r.command.min()) for r in records)
    hi = max(float(r.command.max()) for r in records)
    command = CommandSpec(units.pop(), lo, hi if hi > lo else lo + 1.0)
    kw = data.prepare_kwargs()
    preps = [prepare_record(r, command, **kw) for r in records]
    if data.align and data.offset is None:
        raise ValueError("the neural model cannot find the force offset itself (a more recent motion always fits "
                         "better): give it the one a parametric fit finds, "
                         "data={'offset': reference_offset(records)[0]} (on the command line: --force-offset auto)")
    if data.offset:
        preps = [prepare_record(r, command, offset=data.offset, **kw) for r in records]
    other = next((p for p in preps if not same_rate(p.dt, preps[0].dt)), None)
    if other is not None:
        raise ValueError(f"the neural model needs records of one sampling rate: {preps[0].series.label!r} is "
                         f"sampled at {_rate(preps[0].dt)}, {other.series.label!r} at {_rate(other.dt)}; give dt "
                         "(--dt) to resample them to one step")
    X = np.concatenate([_windows(p, net.lags)[p.mask] for p in preps])
    y = np.concatenate([p.series.force[p.mask] for p in preps])
    x_mean, x_std = X.mean(axis=0), X.std(axis=0)
    x_std[x_std == 0] = 1.0
    f_mean, f_std = float(y.mean()), float(y.std()) or 1.0
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        weights, history = _train(torch, (X - x_mean) / x_std, (y - f_mean) / f_std, net, search)
    finally:
        torch.set_num_threads(threads)
    model = NeuralForwardModel(weights, net.lags, x_mean, x_std, f_mean, f_std, command, preps[0].dt)
    per = [record_measures(p, model.predict_prepared(p)) for p in preps]
    settings = {**dataclasses.asdict(search), **dataclasses.asdict(data), **dataclasses.asdict(net),
                "maxiter": search.iterations, "n_weights": model.n_weights,
                "offsets": [p.offset for p in preps]}
    return FitResult(NAME, model, {}, {}, (), {}, {}, "adam", int(search.seed), history[-1], history[0], per,
                     pooled_measures(per), time.perf_counter() - t_start, search.iterations * len(y),
                     search.iterations, True, f"{search.iterations} epochs of Adam", tuple(history), 0, 0,
                     record_info(preps), settings)


def _train(torch, X: np.ndarray, y: np.ndarray, net: NeuralOptions, search):
    """Adam on the mean squared standardised error; returns the float32 weights and the loss per epoch."""
    gen = torch.Generator().manual_seed(int(search.seed))
    torch.manual_seed(int(search.seed))
    d = X.shape[1]
    mlp = torch.nn.Sequential(torch.nn.Linear(d, net.hidden), torch.nn.Tanh(),
                              torch.nn.Linear(net.hidden, net.hidden), torch.nn.Tanh(),
                              torch.nn.Linear(net.hidden, 1))
    Xt = torch.as_tensor(X, dtype=torch.float32)
    yt = torch.as_tensor(y, dtype=torch.float32)[:, None]
    epochs = search.iterations
    opt = torch.optim.AdamW(mlp.parameters(), lr=net.lr, weight_decay=net.weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=epochs, eta_min=net.lr / 20)
    history = []
    from tqdm import tqdm

    for _ in tqdm(range(epochs), desc="fit neural (adam)", unit="epoch", disable=not search.progress, leave=False):
        perm = torch.randperm(len(yt), generator=gen)
        total = 0.0
        for i in range(0, len(yt), net.batch):
            b = perm[i:i + net.batch]
            opt.zero_grad()
            loss = torch.mean((mlp(Xt[b]) - yt[b]) ** 2)
            loss.backward()
            opt.step()
            total += loss.item() * len(b)
        sched.step()
        history.append(total / len(yt))
    weights = [p.detach().numpy().copy() for p in mlp.parameters()]
    return weights, history
