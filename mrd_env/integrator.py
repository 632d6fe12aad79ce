"""The one fixed-step stepping routine used by the rig, the plants, the environments and identification.

It advances a batch of independent systems, each made of a linear plant coupled to ``nd`` dampers of one
model, on a fixed grid (dt = 1 ms by default)::

    q̇   = A q + B_F F + B_w w(t)                   linear plant (q may be empty: the virtual rig)
    x_j  = C_x q + D_x w,  ẋ_j = C_v q + D_v w,  ẍ_j = D_a w     kinematics across damper j
    ṡ_j  = rhs(p_j, s_j, x_j, ẋ_j, u_j)            damper internal states
    F_j  = force(p_j, s_j, x_j, ẋ_j, ẍ_j, u_j)
    u̇_j  = −η_j (u_j − v_j(t − τ_j))                command lag, v held over each step (zero-order hold)

The command dynamics (:mod:`mrd_env.command_lag`: η faster on a rise than on a fall if declared, a pure delay
τ) are integrated exactly (exponentials). The plant and damper states are advanced together
(no lagged coupling) by the two-stage, stiffly accurate, L-stable SDIRK method of Alexander (1977),
γ = 1 − 1/√2, order 2: the Bouc–Wen variable's Jacobian reaches |∂ż/∂z| ≈ 2(β+γ) z_s |ẋ−ẏ| (≈ 10⁴ s⁻¹
at 0.1 m/s for the prototype damper), which makes explicit schemes unstable at 1 ms.

Each stage equation Z = R + hγ f(Z) is solved with the structure of the system: the plant is linear, so
its part is eliminated exactly, q = (I − hγA)⁻¹(R_q + hγ B_w w) + M_q F with M_q = hγ(I − hγA)⁻¹B_F (matrices
computed once per sub-step length, :meth:`SystemMatrices.levels`); what is left is Newton's method on each
damper's internal states and force, nd·(ns + 1) unknowns (3 for a Spencer–Dyke damper), with the damper's
analytic derivatives (``DamperModel.partials``) or, for models without them, forward differences of the
damper's own functions (see ``_kernel_template.py``, where everything is inlined into one compiled function
per driver). After every step the model's ``project`` puts the states back in their invariant set
(z within ±z_s), which stage values may leave, and switches discrete modes. The exogenous input w is
interpolated linearly inside a step.

Accuracy control: each step of ``dt`` is split into 2^k equal sub-steps. Starting from half the previous
step's count, the count doubles (up to ``max_substeps``) until an a-posteriori estimate of the local error
— the SDIRK solution minus the embedded first-order one, filtered through the stage matrix as in Hairer &
Wanner, *Solving ODEs II*, IV.8 — is within ``rtol``·|state| + ``atol`` for every state (defaults :data:`RTOL` = 0.1 and :data:`ATOL` =
1e-5 in SI units with at most 8 sub-steps; the resulting force errors against Radau are in the README and in
``tests/test_integrator_accuracy.py``, ``tests/test_plants.py``). A Newton solve that does not
converge also halves the sub-step. The output grid stays fixed at ``dt`` whatever the splitting, and the
splitting depends only on the state, so runs are reproducible bit for bit.
"""
from __future__ import annotations

import hashlib
import importlib.util
import inspect
import math
import os
import re
import sys
import tempfile
from pathlib import Path

import numba as nb
import numpy as np

GAMMA = 1.0 - 1.0 / math.sqrt(2.0)

OK = 0
NONFINITE = 1
NO_CONVERGENCE = 2

#: Default local error tolerances (SI units): tighter ones buy accuracy that the models do not have at the price
#: of sub-steps (measured on the quarter car on a class-C road: rtol 1e-2 → 1.7 sub-steps per step, force
#: NRMSE 0.05 % against Radau; 1e-1 → 1.05 sub-steps, 0.12 %; no error control → 2.9 %).
RTOL = 1e-1
ATOL = 1e-5


@nb.njit(cache=True)
def _lu_factor(M, piv):
    """In-place LU with partial pivoting; returns False if M is singular."""
    n = M.shape[0]
    for k in range(n):
        p = k
        big = abs(M[k, k])
        for i in range(k + 1, n):
            if abs(M[i, k]) > big:
                big = abs(M[i, k])
                p = i
        if big == 0.0 or not math.isfinite(big):
            return False
        piv[k] = p
        if p != k:
            for c in range(n):
                tmp = M[k, c]
                M[k, c] = M[p, c]
                M[p, c] = tmp
        for i in range(k + 1, n):
            M[i, k] /= M[k, k]
            f = M[i, k]
            if f != 0.0:
                for c in range(k + 1, n):
                    M[i, c] -= f * M[k, c]
    return True


@nb.njit(cache=True)
def _lu_solve(M, piv, b):
    n = M.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        for k in range(i):
            b[i] -= M[i, k] * b[k]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            b[i] -= M[i, k] * b[k]
        b[i] /= M[i, i]


_KERNELS: dict = {}


def _kernel_dir() -> Path:
    """Where generated kernels (and numba's cache of them) live: $MRD_ENV_CACHE_DIR, else the user cache."""
    env = os.environ.get("MRD_ENV_CACHE_DIR")
    base = Path(env) if env else Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "mrd-env"
    d = base / "kernels"
    try:
        d.mkdir(parents=True, exist_ok=True)
        probe = d / f".probe-{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError:  # read-only home: fall back to the temporary directory
        d = Path(tempfile.gettempdir()) / f"mrd-env-kernels-{os.getuid() if hasattr(os, 'getuid') else 0}"
        d.mkdir(parents=True, exist_ok=True)
    return d


def _kernel_source(model_cls) -> tuple[str, str]:
    fns = {"rhs": model_cls.rhs, "force": model_cls.force_law, "project": model_cls.project}
    analytic = getattr(model_cls, "partials", None)
    if analytic is not None:
        fns["partials"] = analytic
    # the model's functions are compiled again inline: one function per step, no calls in the Newton loop
    header = "".join(f"from {f.py_func.__module__} import {f.py_func.__name__} as _{name}_dispatcher\n"
                     f"{name} = nb.njit(inline='always')(_{name}_dispatcher.py_func)\n" for name, f in fns.items())
    header = "import numba as nb\n" + header
    header += f"ns = {len(model_cls.state_names)}\n"
    from .driver import layout_source

    here = Path(__file__).parent
    template = ((here / "_kernel_template.py").read_text() + "\n\n" + layout_source() + "\n\n"
                + (here / "_driver_template.py").read_text())
    footer = "" if analytic is not None else "\npartials = fd_partials  # the model has no analytic derivatives\n"
    # the key covers the template, this module (the LU helpers the kernel calls live here) and the model's own
    # modules, so an edited model never meets a stale kernel and editing one model recompiles only its kernel
    h = hashlib.sha256((header + template + footer).encode())
    for shared in (Path(__file__), here / "driver.py", here / "command_lag.py"):
        h.update(shared.read_bytes())
    for module in sorted(_model_modules(model_cls)):
        h.update(Path(module).read_bytes())
    return header + template + footer, h.hexdigest()[:16]


def _model_modules(model_cls) -> set[str]:
    """Source files of the model's class and of every function its kernel calls, followed through the imports of
    the damper package (e.g. the shared Bouc–Wen hysteresis)."""
    files = {inspect.getsourcefile(model_cls)}
    pkg = Path(__file__).with_name("dampers")
    todo = list(files)
    while todo:
        text = Path(todo.pop()).read_text(encoding="utf-8")
        for name in re.findall(r"^from \.(\w+) import", text, flags=re.M):
            f = str(pkg / f"{name}.py")
            if f not in files and Path(f).exists():
                files.add(f)
                todo.append(f)
    return files


def kernel_module(model_cls):
    """The compiled module of a damper model class (``advance``, ``macro_step``, ... of
    ``_kernel_template.py``).

    Built once per process from a generated module whose numba compilation is cached on disk, so a new
    process loads it instead of compiling again.
    """
    module = _KERNELS.get(model_cls)
    if module is None:
        module = _KERNELS[model_cls] = load_generated_module(f"mrd_env_kernel_{model_cls.name}",
                                                             *_kernel_source(model_cls))
    return module


def load_generated_module(prefix: str, source: str, key: str):
    """Write ``source`` as ``<prefix>_<key>.py`` in the kernel cache folder (if needed) and import it."""
    mod_name = f"{prefix}_{key}"
    if mod_name in sys.modules:
        return sys.modules[mod_name]
    path = _kernel_dir() / f"{mod_name}.py"
    if not path.exists() or path.read_text() != source:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)  # atomic: concurrent processes never see half a file
    spec = importlib.util.spec_from_file_location(mod_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module
    spec.loader.exec_module(module)
    return module


class SystemMatrices:
    """The linear part of a coupled system (see the module docstring); empty plant for the rig.

    Shapes: A (nq, nq), BF (nq, nd), Bw (nq, nw), Cx/Cv (nd, nq), Dx/Dv/Da (nd, nw).
    """

    def __init__(self, nd: int, nw: int, A=None, BF=None, Bw=None, Cx=None, Dx=None, Cv=None, Dv=None, Da=None):
        nq = 0 if A is None else np.asarray(A).shape[0]

        def mat(a, shape):
            out = np.zeros(shape) if a is None else np.ascontiguousarray(a, dtype=np.float64)
            if out.shape != shape:
                raise ValueError(f"system matrix has shape {out.shape}, expected {shape}")
            return out

        self.nq, self.nd, self.nw = nq, nd, nw
        self.A = mat(A, (nq, nq))
        self.BF = mat(BF, (nq, nd))
        self.Bw = mat(Bw, (nq, nw))
        self.Cx = mat(Cx, (nd, nq))
        self.Dx = mat(Dx, (nd, nw))
        self.Cv = mat(Cv, (nd, nq))
        self.Dv = mat(Dv, (nd, nw))
        self.Da = mat(Da, (nd, nw))
        self._levels: dict = {}

    @classmethod
    def displacement_driven(cls) -> "SystemMatrices":
        """The virtual rig: no plant, one damper whose x, ẋ, ẍ are the inputs w = (x, ẋ, ẍ)."""
        e = np.eye(3)
        return cls(nd=1, nw=3, Dx=e[0:1], Dv=e[1:2], Da=e[2:3])

    @property
    def C(self) -> np.ndarray:
        """[C_x, C_v] stacked (2, nd, nq), as the kernel takes them."""
        return np.ascontiguousarray(np.stack([self.Cx, self.Cv]))

    @property
    def D(self) -> np.ndarray:
        """[D_x, D_v, D_a] stacked (3, nd, nw)."""
        return np.ascontiguousarray(np.stack([self.Dx, self.Dv, self.Da]))

    def levels(self, dt: float, max_level: int) -> tuple[np.ndarray, ...]:
        """The plant's elimination matrices for the sub-step lengths h = dt/2^k, k = 0..max_level, stacked
        along the first axis: (I − hγA)⁻¹, hγ(I − hγA)⁻¹B_w, M_q = hγ(I − hγA)⁻¹B_F and [C_x M_q, C_v M_q]."""
        key = (float(dt), int(max_level))
        hit = self._levels.get(key)
        if hit is None:
            nq, nd, nw = self.nq, self.nd, self.nw
            L = max_level + 1
            Ainv, Bbar, Mq = np.zeros((L, nq, nq)), np.zeros((L, nq, nw)), np.zeros((L, nq, nd))
            PP = np.zeros((L, 2, nd, nd))
            for k in range(L):
                c = GAMMA * dt / 2 ** k
                inv = np.linalg.inv(np.eye(nq) - c * self.A) if nq else np.zeros((0, 0))
                Ainv[k] = inv
                Bbar[k] = c * inv @ self.Bw
                Mq[k] = c * inv @ self.BF
                PP[k, 0] = self.Cx @ Mq[k]
                PP[k, 1] = self.Cv @ Mq[k]
            hit = self._levels[key] = tuple(np.ascontiguousarray(a) for a in (Ainv, Bbar, Mq, PP))
        return hit


def max_level_of(max_substeps: int) -> int:
    """k such that 2^k is the first power of two >= ``max_substeps``."""
    return max(0, int(math.ceil(math.log2(max_substeps) - 1e-12)))


class Stepper:
    """A batch of N systems advanced ``n_steps`` steps of ``dt`` per call, each step with its own command (the
    rig and identification; environments use :class:`~mrd_env.driver.Driver` directly).

    ``Y`` (N, n) and ``U`` (N, nd) are the states and effective commands (assign to set them); :meth:`step`
    advances them and returns the per-step forces (N, n_steps, nd) and states (N, n_steps, n) as views of
    internal buffers (copy them to keep them past the next call).
    """

    def __init__(self, damper, system: SystemMatrices, N: int, n_steps: int, dt: float, *, P=None, lag=None,
                 max_substeps: int = 8, rtol: float = RTOL, atol: float = ATOL):
        from .driver import HIST_FULL, Driver, Processing

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
        from .driver import DIVERGED, RUNNING

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
    from .errors import SimulationDivergedError

    why = ("a non-finite state" if status == NONFINITE else
           f"no convergence of the implicit step even with {max_substeps} sub-steps")
    return SimulationDivergedError(
        f"damper model {name!r}: {why} at t = {t_fail:.6g} s (batch index {index}); "
        "check the parameters and the input amplitude", model=name, time=t_fail, index=index)


def run(damper, system: SystemMatrices, Y, U, V, W, dt: float, *, t0: float = 0.0, P=None,
        max_substeps: int = 8, rtol: float = RTOL, atol: float = ATOL):
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
