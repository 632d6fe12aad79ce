"""A batch of coupled systems advanced over a record of steps: the rig's and identification's entry to the
stepping routine (environments drive :class:`~mrd_env.stepping.driver.Driver` directly)."""
from __future__ import annotations

import math

import numpy as np

from ..errors import SimulationDivergedError
from .driver import Driver, Processing
from .layout import DIVERGED, HIST_FULL, RUNNING
from .matrices import SystemMatrices
from .scheme import ATOL, MAX_SUBSTEPS, NONFINITE, RTOL


class Stepper:
    """A batch of N systems advanced ``n_steps`` steps of ``dt`` per call, each step with its own command (the
    rig and identification; environments use :class:`~mrd_env.stepping.driver.Driver` directly).

    ``Y`` (N, n) and ``U`` (N, nd) are the states and effective commands (assign to set them); :meth:`step`
    advances them and returns the per-step forces (N, n_steps, nd) and states (N, n_steps, n) as views of
    internal buffers (copy them to keep them past the next call).
    """

    def __init__(self, damper, system: SystemMatrices, N: int, n_steps: int, dt: float, *, P=None, lag=None,
                 max_substeps: int = MAX_SUBSTEPS, rtol: float = RTOL, atol: float = ATOL):
        self.damper = damper
        self.system = system
        nd, nw = system.nd, system.nw
        n = system.nq + nd * damper.n_states
        # the commands ride along as extra input channels that the plant ignores
        with_commands = SystemMatrices(nd, nw + nd, A=system.A if system.nq else None, BF=system.BF,
                                       Bw=np.hstack([system.Bw, np.zeros((system.nq, nd))]),
                                       Cx=system.Cx, Cv=system.Cv,
                                       **{k: np.hstack([getattr(system, k), np.zeros((nd, nd))])
                                          for k in ("Dx", "Dv", "Da")})
        G = np.zeros((nd + n, n + nd + nw + nd))
        G[:nd, n:n + nd] = np.eye(nd)  # rows: the forces, then the states
        G[nd:, :n] = np.eye(n)
        self.driver = Driver(damper, with_commands, N, Processing(G=G, history_mode=HIST_FULL, command_input=nw),
                             dt=dt, n_sub=n_steps, v_range=(-math.inf, math.inf), P=P, lag=lag,
                             max_substeps=max_substeps, rtol=rtol, atol=atol)
        self.dt = self.driver.dt
        self.max_substeps = self.driver.max_substeps
        self.N, self.n_steps, self.n, self.nd, self.nw = N, n_steps, n, nd, nw
        self.Y = np.zeros((N, n))
        self.Y[:, system.nq:] = np.tile(damper.initial_state(), nd)
        self.U = np.full((N, nd), damper.command.v_min)
        self.t = 0.0
        self._started = False

    @property
    def lag(self) -> np.ndarray:
        """The command dynamics (N, nd, 3): η_rise, η_fall (1/s) and delay (s) per system and damper (given at
        construction: the delay sizes the command queue)."""
        return self.driver.state("LAG").reshape(self.N, self.nd, 3)

    @property
    def P(self) -> np.ndarray:
        """The damper parameters (N, nd, n_params) of every system."""
        return self.driver.state("P").reshape(self.N, self.nd, -1)

    def step(self, V: np.ndarray, W: np.ndarray):
        """Advance by ``n_steps`` steps with commands V (N, n_steps, nd) and inputs W (N, n_steps+1, nw); raise
        :class:`~mrd_env.errors.SimulationDivergedError` if a system diverges."""
        F, Y, ok = self.advance(V, W)
        if not ok.all():
            b = int(np.flatnonzero(~ok)[0])
            reason, t_fail = self.driver.failure(b)
            raise diverged_error(self.damper.name, reason, self.t - self.n_steps * self.dt + t_fail, b,
                                 self.max_substeps)
        return F, Y

    def advance(self, V: np.ndarray, W: np.ndarray):
        """As :meth:`step`, without raising: (F, Y, ok) with ok[b] False for a system that diverged (its rows
        from the failure on are not meaningful)."""
        d = self.driver
        N, k, nd = self.N, self.n_steps, self.nd
        Wc = np.empty((N, k + 1, self.nw + nd))
        Wc[:, :, :self.nw] = W
        Wc[:, :k, self.nw:] = V
        Wc[:, k, self.nw:] = V[:, -1]
        d.set_inputs(Wc, 1, history_rows=k + 1)
        if not self._started or self._dirty():
            d.reset(Y0=self.Y, U0=self.U)
            self._started = True
        else:
            d.int_state("K")[:] = 0
            d.int_state("STATUS")[:] = RUNNING
            d.int_state("SUBSTEPS")[:] = 0
        d.step(np.zeros(0))
        ok = d.int_state("STATUS") != DIVERGED
        self.Y = d.state("Y")
        self.U = d.state("U")
        self._seen = (self.Y.copy(), self.U.copy())
        self.t += k * self.dt
        H = d.H
        return H[:, 1:, :nd], H[:, 1:, nd:], ok

    def substeps(self) -> np.ndarray:
        """Mean sub-steps per step of each system over the last call."""
        return self.driver.int_state("SUBSTEPS") / self.n_steps

    def _dirty(self) -> bool:
        """True if Y or U were assigned since the last step (the driver must start again from them)."""
        seen = getattr(self, "_seen", None)
        return seen is None or not (np.array_equal(seen[0], self.Y) and np.array_equal(seen[1], self.U))


def diverged_error(name: str, status: int, t_fail: float, index: int, max_substeps: int):
    """The :class:`~mrd_env.errors.SimulationDivergedError` of a failed step (status NONFINITE/NO_CONVERGENCE)."""
    why = ("a non-finite state" if status == NONFINITE else
           f"no convergence of the implicit step even with {max_substeps} sub-steps")
    return SimulationDivergedError(
        f"damper model {name!r}: {why} at t = {t_fail:.6g} s (batch index {index}); "
        "check the parameters and the input amplitude", model=name, time=t_fail, index=index)


def run(damper, system: SystemMatrices, Y, U, V, W, dt: float, *, t0: float = 0.0, P=None,
        max_substeps: int = MAX_SUBSTEPS, rtol: float = RTOL, atol: float = ATOL):
    """Advance a batch once (see :class:`Stepper`), raising :class:`SimulationDivergedError` on failure.

    ``damper`` is a :class:`~mrd_env.dampers.DamperModel`; Y (N, n) and U (N, nd) are updated in place (the
    commands before t0 are taken as U, a settled driver);
    V (N, n_steps, nd) commands, W (N, n_steps + 1, nw) inputs; ``P`` overrides the parameter vector per
    system and damper (N, nd, n_params). Returns (F (N, n_steps, nd), Y history (N, n_steps, n), mean sub-steps
    per step (N,)).
    """
    V = np.array(V, dtype=np.float64, order="C")
    W = np.array(W, dtype=np.float64, order="C")
    N, n_steps, nd = V.shape
    if W.shape[:2] != (N, n_steps + 1):
        raise ValueError(f"W must have shape (N, n_steps + 1, nw) = ({N}, {n_steps + 1}, nw), got {W.shape}")
    st = Stepper(damper, system, N, n_steps, dt, P=P, max_substeps=max_substeps, rtol=rtol, atol=atol)
    if Y.shape != st.Y.shape or U.shape != st.U.shape:
        raise ValueError(f"Y and U must have shapes {st.Y.shape} and {st.U.shape}, got {Y.shape} and {U.shape}")
    st.Y, st.U, st.t = np.array(Y, dtype=np.float64), np.array(U, dtype=np.float64), t0
    F, Yh = st.step(V, W)
    Y[...] = st.Y
    U[...] = st.U
    return F, Yh, st.substeps()
