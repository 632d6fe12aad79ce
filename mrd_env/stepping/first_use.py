"""First use without waiting for the compiler: step a damper model's kernel as plain Python while a background
process compiles it into the disk cache, then switch to the compiled kernel.

numba needs 15–25 s to compile a damper model's kernel the first time (docs/speed.md). The generated kernel
source, executed by the interpreter (``nb.njit`` the identity, ``prange`` = ``range``), computes the same numbers
bit for bit, at about 0.5 ms per 1 ms step (tests/stepping/test_first_use.py). So with an empty cache,
:func:`~mrd_env.stepping.codegen.kernel_module` returns a :class:`SwitchingKernel`: its entry points run the
interpreted kernel, a background ``python -m mrd_env.warmup <model>`` compiles what a first use needs (the scalar
and vector steps and the rig) and leaves a *ready marker* beside the kernel, and the next call after the marker
appears runs the compiled kernel, loaded from the cache. The state lives in the caller's arrays, so the switch can
happen at any step of an episode without changing any result.

``MRD_ENV_FIRST_USE`` chooses: ``interpret`` (the default) or ``wait`` (compile in the calling process on first
use, as numba does; the test suite and the speed benchmarks use it). One background compilation runs per kernel
at a time, whatever the number of processes that need it (a lock file beside the marker).
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
import time
import types
import warnings
from pathlib import Path

import numpy as np

from .. import caches
from ..caches import read_regular
from ..storage import write_text

MODE_VARIABLE = "MRD_ENV_FIRST_USE"
MODES = ("interpret", "wait")
_STALE_LOCK_S = 600.0  # a compilation takes well under a minute; a lock older than this is a crashed process


def mode() -> str:
    """``interpret`` or ``wait`` (:data:`MODE_VARIABLE`, default ``interpret``)."""
    value = os.environ.get(MODE_VARIABLE, "interpret")
    if value not in MODES:
        raise ValueError(f"{MODE_VARIABLE} must be one of {MODES}, got {value!r}")
    return value


def set_mode(value: str) -> None:
    """Set :data:`MODE_VARIABLE` for this process and the processes it starts (e.g. ``wait`` before timing)."""
    if value not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {value!r}")
    os.environ[MODE_VARIABLE] = value


_PATCHED_GLOBALS: dict = {}


def python_function(fn):
    """``fn`` (a numba function, or a Python one) as plain Python: its ``py_func`` with every numba function it
    calls through its module's globals replaced likewise, so that calling it compiles nothing."""
    from numba.core.dispatcher import Dispatcher

    f = fn.py_func if isinstance(fn, Dispatcher) else fn
    g = f.__globals__
    patched = _PATCHED_GLOBALS.get(id(g))
    if patched is None:
        patched = _PATCHED_GLOBALS[id(g)] = dict(g)  # registered first: mutual calls end here
        for name, value in g.items():
            if isinstance(value, Dispatcher):
                patched[name] = python_function(value)
    out = types.FunctionType(f.__code__, patched, f.__name__, f.__defaults__, f.__closure__)
    out.__kwdefaults__ = f.__kwdefaults__
    return out


class _InterpretedNumba:
    """Stands in for ``numba`` in a generated kernel's source: the decorators give plain Python functions."""

    prange = range
    uint64 = np.uint64

    @staticmethod
    def njit(*args, **kwargs):
        if args and callable(args[0]) and not kwargs:
            return args[0]
        # the model's and the shared helpers' functions come from other modules: plain Python down to the leaves
        return lambda f: f if "__interpreted_nb__" in f.__globals__ else python_function(f)


def interpreted_module(name: str, source: str) -> types.ModuleType:
    """A generated kernel's ``source`` executed as plain Python (no compilation)."""
    module = types.ModuleType(f"{name}_interpreted")
    module.__dict__["__interpreted_nb__"] = _InterpretedNumba
    code = source.replace("import numba as nb\n", "nb = __interpreted_nb__\n")
    exec(compile(code, module.__name__, "exec"), module.__dict__)
    return module


#: Entry points compiled last (the threaded step, the longest to compile): the others switch at the ``serial``
#: marker, these at the final one.
LATE_ENTRIES = ("core_step_parallel",)


def ready_marker(kernel_path: Path, part: str = "") -> Path:
    """The file that says numba's cache holds ``kernel_path``'s compiled entry points (``part="serial"``: all but
    :data:`LATE_ENTRIES`). Its name carries numba's and Python's versions and numba's cache folder, so a marker
    never vouches for a cache that is not there."""
    import numba

    where = f"{numba.__version__} {sys.version} {os.environ.get('NUMBA_CACHE_DIR', '')}"
    tag = hashlib.sha256(where.encode()).hexdigest()[:8]
    return kernel_path.with_suffix(f".{tag}.{part}.ready" if part else f".{tag}.ready")


def mark_ready(kernel_path: Path, part: str = "") -> None:
    """Leave a ready marker of ``kernel_path`` (after those entry points were compiled into the cache)."""
    write_text(ready_marker(kernel_path, part), f"compiled by process {os.getpid()} at {time.ctime()}\n")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class SwitchingKernel:
    """A kernel module's stand-in until its compilation is in the cache: entry points (``run_systems``,
    ``core_reset``, ...) run the interpreted kernel, and the compiled one from the first call after their ready
    marker appears (the serial entries first, :data:`LATE_ENTRIES` at the final marker). ``compiled`` says
    whether the serial entries run compiled."""

    def __init__(self, model_cls, kernel_path: Path, source: str, load_compiled, *, model_name: str | None = None):
        self.__name__ = kernel_path.stem
        self._model_cls = model_cls
        self._model_name = model_name or model_cls.name  # what the background process compiles
        self._interpreted = interpreted_module(kernel_path.stem, source)
        # the model's own calls from Python (its static force) compile nothing either until the switch
        model_cls.python_functions = (python_function(model_cls.project), python_function(model_cls.force_law))
        self._load_compiled = load_compiled
        self._marker = ready_marker(kernel_path)
        self._serial_marker = ready_marker(kernel_path, "serial")
        self._lock = kernel_path.with_suffix(".compiling")
        self._log = kernel_path.with_suffix(".log")
        self._impl = self._interpreted
        self._proc = None
        self._next_check = 0.0
        self.compiled = False
        self._late_compiled = False
        self._start_compiler()

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        target = getattr(self._interpreted, name)
        if not callable(target):
            return target

        late = name in LATE_ENTRIES

        def entry(*args):
            if not (self._late_compiled if late else self.compiled):
                self._poll()
                if not (self._late_compiled if late else self.compiled):
                    with np.errstate(all="ignore"):  # the compiled kernel wraps uint64 and never warns
                        return getattr(self._interpreted, name)(*args)
            return getattr(self._impl, name)(*args)

        entry.__name__ = name
        self.__dict__[name] = entry
        return entry

    @property
    def settled(self):
        """The compiled module once every entry point is compiled (then new drivers take it directly), else
        None."""
        if not self._late_compiled and self._marker.exists():
            self._switch(late=True)
        return self._impl if self._late_compiled else None

    # --- the background compilation -----------------------------------------------------------------------
    def _start_compiler(self) -> None:
        """Start ``python -m mrd_env.warmup <model>`` unless another process holds the lock (is compiling)."""
        try:
            fd = os.open(self._lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            if not self._stale_lock():
                return
            self._lock.unlink(missing_ok=True)
            return self._start_compiler()
        # the child imports this very mrd_env, however this process found it (an install, a path, a checkout)
        root = str(Path(__file__).resolve().parents[2])
        path = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH", "")) if p)
        # ... and compiles into the very cache folder this process checked and uses (a fallback one included): the
        # kernel's own folder is <root>/kernels
        root_dir = str(self._lock.parent.parent)
        env = dict(os.environ, **{MODE_VARIABLE: "wait", "PYTHONPATH": path, caches.VARIABLE: root_dir})
        # the log: a new file (O_EXCL: never a symlink or a file planted at its name) renamed to its name
        log_fd, log_tmp = tempfile.mkstemp(prefix=f".{self._log.name}.", suffix=".tmp", dir=self._log.parent)
        try:
            os.replace(log_tmp, self._log)
            # its own session: the compilation finishes (for the next process) even if this one is interrupted
            self._proc = subprocess.Popen([sys.executable, "-m", "mrd_env.warmup", self._model_name,
                                           "--lock", str(self._lock)],
                                          stdin=subprocess.DEVNULL, stdout=log_fd, stderr=subprocess.STDOUT,
                                          env=env, start_new_session=True)
        except BaseException:
            os.close(fd)
            self._lock.unlink(missing_ok=True)
            raise
        finally:
            os.close(log_fd)
        with os.fdopen(fd, "w") as f:
            f.write(str(self._proc.pid))

    def _stale_lock(self) -> bool:
        try:
            pid = int(self._lock.read_text() or 0)
            age = time.time() - self._lock.stat().st_mtime
        except (OSError, ValueError):
            return False  # being written (or just removed): not stale
        return (pid > 0 and not _alive(pid)) or age > _STALE_LOCK_S

    def _poll(self) -> None:
        """Switch to the compiled kernel once the markers are there; compile here if the background process
        failed."""
        if self._marker.exists():
            return self._switch(late=True)
        if not self.compiled and self._serial_marker.exists():
            self._switch()
        now = time.monotonic()
        if now < self._next_check:
            return
        self._next_check = now + 0.5
        if self._proc is not None:
            if self._proc.poll() is not None and not self._marker.exists():
                err = (read_regular(self._log) or b"").decode(errors="replace").strip().splitlines()
                warnings.warn(f"the background compilation of the {self._model_name} kernel failed "
                              f"({err[-1] if err else f'exit code {self._proc.returncode}'}); compiling it here",
                              RuntimeWarning, stacklevel=3)
                self._switch(late=True)
        elif not self._lock.exists() or self._stale_lock():
            self._start_compiler()  # the process that was compiling it is gone without a marker

    def _switch(self, late: bool = False) -> None:
        """The serial entry points (and with ``late`` all) run compiled from now on."""
        if not self.compiled:
            self._impl = self._load_compiled()
            self.compiled = True
            self._model_cls.python_functions = None
        self._late_compiled = self._late_compiled or late
        for name in [n for n in self.__dict__ if not n.startswith("_") and callable(self.__dict__[n])]:
            if self._late_compiled or name not in LATE_ENTRIES:
                self.__dict__[name] = getattr(self._impl, name)  # later look-ups (an env's reset) skip the entry
