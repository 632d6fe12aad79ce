"""The one fixed-step stepping routine used by the rig, the plants, the environments and identification.

It advances a batch of independent systems, each made of a linear plant coupled to ``nd`` dampers of one
model, on a fixed grid (dt = 1 ms by default)::

    q̇   = A q + B_F F + B_w w(t)                   linear plant (q may be empty: the virtual rig)
    x_j  = C_x q + D_x w,  ẋ_j = C_v q + D_v w,  ẍ_j = D_a w     kinematics across damper j
    ṡ_j  = rhs(p_j, s_j, x_j, ẋ_j, u_j)            damper internal states
    F_j  = force(p_j, s_j, x_j, ẋ_j, ẍ_j, u_j)
    u̇_j  = −η_j (u_j − v_j)                         command lag, v held over each step (zero-order hold)

The command lag is integrated exactly (an exponential). The plant and damper states are advanced together
(no lagged coupling) by the two-stage, stiffly accurate, L-stable SDIRK method of Alexander (1977),
γ = 1 − 1/√2, order 2: the Bouc–Wen variable's Jacobian reaches |∂ż/∂z| ≈ 2(β+γ) z_s |ẋ−ẏ| (≈ 10⁴ s⁻¹
at 0.1 m/s for the prototype damper), which makes explicit schemes unstable at 1 ms. Each stage is solved
by Newton's method with a finite-difference Jacobian; after every step the model's ``project`` puts the
states back in their invariant set (z within ±z_s), which stage values may leave. The exogenous input w
is interpolated linearly inside a step.

Accuracy control: each step of ``dt`` is split into 2^k equal sub-steps. Starting from half the previous
step's count, the count doubles (up to ``max_substeps``) until an a-posteriori estimate of the local error
— the SDIRK solution minus the embedded first-order one, filtered through the stage matrix as in Hairer &
Wanner, *Solving ODEs II*, IV.8 — is within ``rtol``·|state| + ``atol`` for every state (defaults 1e-2
and 1e-5 in SI units with at most 8 sub-steps: force errors below 0.03 % of a Radau reference for the
prototype damper up to 2.4 m/s, see ``tests/test_integrator_accuracy.py``). A Newton solve that does not
converge also halves the sub-step. The output grid stays fixed at ``dt`` whatever the splitting, and the
splitting depends only on the state, so runs are reproducible bit for bit.
"""
from __future__ import annotations

import hashlib
import importlib.util
import inspect
import math
import os
import sys
import tempfile
from pathlib import Path

import numba as nb
import numpy as np

GAMMA = 1.0 - 1.0 / math.sqrt(2.0)

OK = 0
NONFINITE = 1
NO_CONVERGENCE = 2


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
    header = "".join(f"from {f.py_func.__module__} import {f.py_func.__name__} as {name}\n" for name, f in fns.items())
    header += f"ns = {len(model_cls.state_names)}\n"
    template = Path(__file__).with_name("_kernel_template.py").read_text()
    # the key covers the template and every damper module, so an edited model never meets a stale kernel
    h = hashlib.sha256((header + template).encode())
    h.update(Path(__file__).read_bytes())  # the LU helpers the kernel calls live here
    for f in sorted(Path(__file__).with_name("dampers").glob("*.py")):
        h.update(f.read_bytes())
    for f in fns.values():
        h.update(Path(inspect.getsourcefile(f.py_func)).read_bytes())
    return header + template, h.hexdigest()[:16]


def kernel_for(model_cls):
    """The compiled ``advance`` (see ``_kernel_template.py``) for a damper model class.

    Built once per process from a generated module whose numba compilation is cached on disk, so a new
    process loads it instead of compiling again (about 5 s per model).
    """
    k = _KERNELS.get(model_cls)
    if k is None:
        src, key = _kernel_source(model_cls)
        mod_name = f"mrd_env_kernel_{model_cls.name}_{key}"
        path = _kernel_dir() / f"{mod_name}.py"
        if not path.exists() or path.read_text() != src:
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(src)
            os.replace(tmp, path)  # atomic: concurrent processes never see half a file
        spec = importlib.util.spec_from_file_location(mod_name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[mod_name] = module
        spec.loader.exec_module(module)
        k = _KERNELS[model_cls] = module.advance
    return k


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

    @classmethod
    def displacement_driven(cls) -> "SystemMatrices":
        """The virtual rig: no plant, one damper whose x, ẋ, ẍ are the inputs w = (x, ẋ, ẍ)."""
        e = np.eye(3)
        return cls(nd=1, nw=3, Dx=e[0:1], Dv=e[1:2], Da=e[2:3])


class Stepper:
    """Preallocated stepping of a batch of N systems for ``n_steps`` steps per call (environments).

    Holds the states ``Y`` (N, n) and effective commands ``U`` (N, nd); :meth:`step` advances them and
    returns the per-step forces (N, n_steps, nd) and states (N, n_steps, n) as views of internal buffers
    (copy them to keep them past the next call).
    """

    def __init__(self, damper, system: SystemMatrices, N: int, n_steps: int, dt: float, *, P=None,
                 max_substeps: int = 8, rtol: float = 1e-2, atol: float = 1e-5):
        from .validation import check_scalar

        self.damper = damper
        self.system = system
        self.dt = check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
        self.max_substeps = int(check_scalar("max_substeps", max_substeps, 1, 4096))
        self.rtol = check_scalar("rtol", rtol, 0.0, lo_open=True)
        self.atol = check_scalar("atol", atol, 0.0, lo_open=True)
        nd = system.nd
        n = system.nq + nd * damper.n_states
        p = damper.params.as_array()
        # writable C-contiguous copies: numba compiles a separate kernel for read-only arrays
        self.P = np.array(np.broadcast_to(p, (N, nd, p.size)) if P is None else P, dtype=np.float64, order="C")
        self.eta = np.full((N, nd), damper.command.eta)
        self.Y = np.zeros((N, n))
        self.U = np.zeros((N, nd))
        self.F_out = np.zeros((N, n_steps, nd))
        self.Y_out = np.zeros((N, n_steps, n))
        self.nsub = np.zeros((N, n_steps), dtype=np.int64)
        self._kernel = kernel_for(type(damper))
        s = system
        self._mats = (s.A, s.BF, s.Bw, s.Cx, s.Dx, s.Cv, s.Dv, s.Da)
        self.t = 0.0

    def step(self, V: np.ndarray, W: np.ndarray):
        """Advance by ``V.shape[1]`` steps with commands V (N, n_steps, nd) and inputs W (N, n_steps+1, nw)."""
        status, b, k = self._kernel(*self._mats, self.P, self.eta, self.Y, self.U, V, W, self.dt,
                                    self.max_substeps, self.rtol, self.atol, self.F_out, self.Y_out, self.nsub)
        if status != OK:
            self._fail(status, b, k)
        self.t += V.shape[1] * self.dt
        return self.F_out, self.Y_out

    def _fail(self, status, b, k):
        from .errors import SimulationDivergedError

        t_fail = self.t + (k + 1) * self.dt
        name = self.damper.name
        why = ("a non-finite state" if status == NONFINITE else
               f"no convergence of the implicit step even with {self.max_substeps} sub-steps")
        raise SimulationDivergedError(
            f"damper model {name!r}: {why} at t = {t_fail:.6g} s (batch index {b}); "
            "check the parameters and the input amplitude", model=name, time=t_fail, index=b)


def run(damper, system: SystemMatrices, Y, U, V, W, dt: float, *, t0: float = 0.0, P=None,
        max_substeps: int = 8, rtol: float = 1e-2, atol: float = 1e-5):
    """Advance a batch once (see :class:`Stepper`), raising :class:`SimulationDivergedError` on failure.

    ``damper`` is a :class:`~mrd_env.dampers.DamperModel`; Y (N, n) and U (N, nd) are updated in place;
    V (N, n_steps, nd) commands, W (N, n_steps + 1, nw) inputs; ``P`` overrides the parameter vector per
    system and damper (N, nd, n_params). Returns (F (N, n_steps, nd), Y history (N, n_steps, n),
    sub-steps used (N, n_steps)).
    """
    V = np.array(V, dtype=np.float64, order="C")
    W = np.array(W, dtype=np.float64, order="C")
    N, n_steps, nd = V.shape
    if W.shape[:2] != (N, n_steps + 1):
        raise ValueError(f"W must have shape (N, n_steps + 1, nw) = ({N}, {n_steps + 1}, nw), got {W.shape}")
    st = Stepper(damper, system, N, n_steps, dt, P=P, max_substeps=max_substeps, rtol=rtol, atol=atol)
    if Y.shape != st.Y.shape or U.shape != st.U.shape:
        raise ValueError(f"Y and U must have shapes {st.Y.shape} and {st.U.shape}, got {Y.shape} and {U.shape}")
    st.Y, st.U, st.t = Y, U, t0
    st.step(V, W)
    return st.F_out, st.Y_out, st.nsub
