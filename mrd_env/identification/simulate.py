"""Models driven by prepared records: batched simulation of many parameter vectors on one record (one compiled
call per chunk of candidates), and :func:`predict` for one configured damper."""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..dampers import CommandSpec, DamperModel
from ..errors import SimulationDivergedError
from ..stepping import Stepper, SystemMatrices
from ..records import DamperRecord
from .prepare import PreparedRecord, as_record, prepare_record

_CHUNK = 32              # candidates per compiled call (bounds the memory of long records)


_RIG = SystemMatrices.displacement_driven()


def simulate_batch(cls, command: CommandSpec, prep: PreparedRecord, P: np.ndarray, lag: np.ndarray,
                   Y0: np.ndarray, integrator_options: Mapping) -> tuple[np.ndarray, np.ndarray]:
    """Forces (S, n) of S parameter vectors P (S, n_params) with command dynamics ``lag`` (S, 3: η_rise, η_fall,
    delay) on one record, and a mask of the runs that did not diverge (their rows are NaN). One compiled call per
    chunk of candidates; a diverging candidate stops alone, the others of its chunk run on."""
    S = P.shape[0]
    rec = prep.series
    n = rec.n
    F = np.full((S, n), np.nan)
    ok = np.ones(S, dtype=bool)
    if S == 0:
        return F, ok
    W1 = np.stack([rec.x, rec.v, prep.a], axis=1)
    V1 = rec.command[:-1, None]
    damper = _template(cls, command)
    for c0 in range(0, S, _CHUNK):
        sl = slice(c0, min(S, c0 + _CHUNK))
        m = sl.stop - c0
        st = Stepper(damper, _RIG, m, n - 1, prep.dt, P=P[sl, None, :], lag=lag[sl, None, :], **integrator_options)
        st.Y = np.array(Y0[sl], dtype=np.float64)
        st.U = np.full((m, 1), rec.command[0])
        Fc, _, good = st.advance(np.broadcast_to(V1, (m,) + V1.shape), np.broadcast_to(W1, (m,) + W1.shape))
        F[sl, 1:] = np.where(good[:, None], Fc[:, :, 0], np.nan)
        ok[sl] = good
    # force at t0 from the initial state switched to the initial motion (as the rig does), then the
    # end-of-step forces
    for i in range(S):
        if ok[i]:
            s0 = np.array(Y0[i], dtype=np.float64)
            cls.project(P[i], s0, rec.x[0], rec.v[0], rec.command[0])
            F[i, 0] = cls.force_law(P[i], s0, rec.x[0], rec.v[0], prep.a[0], rec.command[0])
    ok &= np.all(np.isfinite(F), axis=1)
    return F, ok


_TEMPLATES: dict = {}


def _template(cls, command: CommandSpec) -> DamperModel:
    """A damper instance of ``cls`` for the Stepper's bookkeeping (name, states, η); P overrides its params."""
    key = (cls, command)
    d = _TEMPLATES.get(key)
    if d is None:
        d = _TEMPLATES[key] = cls(None, command)
    return d


def predict(damper, record: DamperRecord | PreparedRecord, *, dt: float | None = None,
            command_range: str = "clip", faults: str = "exclude", offset: int = 0,
            **integrator_options) -> tuple[PreparedRecord, np.ndarray]:
    """(prepared record, model force in N) for ``damper`` driven by ``record`` on its uniform grid.

    ``damper``: a :class:`~mrd_env.dampers.DamperModel` or a fitted non-parametric model (anything with a
    ``predict_prepared(prep)`` method, e.g. :class:`~mrd_env.identification.neural.NeuralForwardModel`).
    ``faults`` and ``offset``: see :func:`~mrd_env.identification.prepare.prepare_record`. Raises
    :class:`~mrd_env.errors.SimulationDivergedError` if the simulation diverges.
    """
    prep = record if isinstance(record, PreparedRecord) else prepare_record(
        as_record(record, 0), damper.command, dt=dt, command_range=command_range, faults=faults, offset=offset)
    if not isinstance(damper, DamperModel):
        return prep, damper.predict_prepared(prep)
    cls = type(damper)
    P = damper.params.as_array()[None, :]
    F, ok = simulate_batch(cls, damper.command, prep, P, damper.command.lag_vector()[None, :],
                           damper.initial_state()[None, :], integrator_options)
    if not ok[0]:
        raise SimulationDivergedError(f"damper model {damper.name!r} diverged on record {prep.series.label!r}",
                                      model=damper.name)
    return prep, F[0]
