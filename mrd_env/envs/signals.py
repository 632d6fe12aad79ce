"""Named signals of a coupled plant: linear functions of its state, the damper forces and the inputs.

A signal is a block of rows of G in h = G·[Y, F, W], Y = [q, q̇, damper states], W = [plant inputs, 1] (the
last input is the constant that balances the dampers' static preload). The compiled driver evaluates every
row at every physics step; after the rows come the applied commands and the outputs of the online filters.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics import CoupledPlant


@dataclass(frozen=True)
class Signal:
    """A named block of columns of the output row h, with its SI unit."""

    name: str
    columns: np.ndarray
    unit: str

    @property
    def width(self) -> int:
        return int(self.columns.size)


class SignalMap:
    """The rows of G for named signals of ``coupled`` (build with the helpers, then :meth:`add`).

    Helpers return rows over [Y, F, W]: :meth:`disp` (M·q), :meth:`vel` (M·q̇), :meth:`acc` (M·q̈ from the
    coupled equations of motion, damper inertance and static balance included), :meth:`force` (F),
    :meth:`inp` (M·w) and :meth:`damper_states`.
    """

    def __init__(self, coupled: CoupledPlant):
        s = coupled.system
        self.coupled = coupled
        self.n_dof = coupled.plant.n_dof
        self.nq = 2 * self.n_dof
        self.nY = coupled.n
        self.nd = s.nd
        self.nw = s.nw
        self.ncol = self.nY + self.nd + self.nw
        self._A, self._BF, self._Bw = s.A, s.BF, s.Bw
        self._rows: list[np.ndarray] = []
        self.signals: dict[str, Signal] = {}
        self._n = 0
        self.n_extra = 0

    # --- row helpers --------------------------------------------------------------------------------------------
    def _zeros(self, rows: int) -> np.ndarray:
        return np.zeros((rows, self.ncol))

    def disp(self, M) -> np.ndarray:
        """M @ q."""
        M = np.atleast_2d(np.asarray(M, dtype=float))
        G = self._zeros(M.shape[0])
        G[:, : self.n_dof] = M
        return G

    def vel(self, M) -> np.ndarray:
        """M @ q̇."""
        M = np.atleast_2d(np.asarray(M, dtype=float))
        G = self._zeros(M.shape[0])
        G[:, self.n_dof: self.nq] = M
        return G

    def acc(self, M) -> np.ndarray:
        """M @ q̈ with q̈ from the coupled equations of motion."""
        M = np.atleast_2d(np.asarray(M, dtype=float))
        G = self._zeros(M.shape[0])
        G[:, : self.nq] = M @ self._A[self.n_dof:]
        G[:, self.nY: self.nY + self.nd] = M @ self._BF[self.n_dof:]
        G[:, self.nY + self.nd:] = M @ self._Bw[self.n_dof:]
        return G

    def force(self) -> np.ndarray:
        G = self._zeros(self.nd)
        G[:, self.nY: self.nY + self.nd] = np.eye(self.nd)
        return G

    def inp(self, M) -> np.ndarray:
        """M @ w (plant inputs, without the constant channel)."""
        M = np.atleast_2d(np.asarray(M, dtype=float))
        G = self._zeros(M.shape[0])
        G[:, self.nY + self.nd: self.nY + self.nd + M.shape[1]] = M
        return G

    def damper_states(self) -> np.ndarray:
        k = self.nY - self.nq
        G = self._zeros(k)
        G[:, self.nq: self.nY] = np.eye(k)
        return G

    # --- the map ----------------------------------------------------------------------------------------------
    def add(self, name: str, rows: np.ndarray, unit: str) -> Signal:
        """A signal from rows of G (names starting with "_" are internal: not offered as sensors)."""
        rows = np.atleast_2d(rows)
        if rows.shape[1] != self.ncol:
            raise ValueError(f"signal {name!r}: rows need {self.ncol} columns, got {rows.shape}")
        if name in self.signals:
            raise ValueError(f"signal {name!r} is defined twice")
        if self.n_extra:
            raise RuntimeError("add every G-row signal before the commands and filter outputs")
        sig = Signal(name, np.arange(self._n, self._n + rows.shape[0]), unit)
        self._rows.append(rows)
        self._n += rows.shape[0]
        self.signals[name] = sig
        return sig

    def add_commands(self, unit: str) -> Signal:
        """The applied commands (the driver writes them after the G rows)."""
        sig = Signal("command", np.arange(self._n, self._n + self.nd), unit)
        self.signals["command"] = sig
        self.n_extra = -1  # G is closed
        return sig

    def add_output(self, name: str, unit: str) -> Signal:
        """A column written by the driver (a filter's output), after the commands."""
        n_g = self._n
        col = n_g + self.nd + max(self.n_extra, 0)
        sig = Signal(name, np.array([col]), unit)
        self.signals[name] = sig
        self.n_extra = max(self.n_extra, 0) + 1
        return sig

    @property
    def G(self) -> np.ndarray:
        return np.ascontiguousarray(np.vstack(self._rows)) if self._rows else np.zeros((0, self.ncol))

    @property
    def width(self) -> int:
        """Columns of the output row h."""
        return self._n + self.nd + max(self.n_extra, 0)

    def __getitem__(self, name: str) -> Signal:
        return self.signals[name]

    def __contains__(self, name: str) -> bool:
        return name in self.signals

    def output_rows(self, name: str) -> np.ndarray:
        """The rows of G of a signal (zeros for the commands and filter outputs, which are not linear outputs)."""
        sig = self.signals[name]
        G = self.G
        out = np.zeros((sig.width, self.ncol))
        mask = sig.columns < G.shape[0]
        out[mask] = G[sig.columns[mask]]
        return out
