"""One executor for every sweep — benchmark grids, model comparisons, Monte-Carlo draws, training seeds: serially,
on a local process pool, or on Ray.

A sweep is a list of :class:`Task` (a picklable function, its arguments, a label). Tasks are independent, carry
their own seeds and return plain results, so the results — returned in the order of the tasks — are the same,
bit for bit, whatever the backend and the number of workers. A task that raises is retried once; if it fails
again :class:`TaskFailed` names it, its inputs and the error (never dropped silently). One progress bar over the
whole sweep.

Backends: ``"serial"`` (in this process); ``"pool"`` (``concurrent.futures.ProcessPoolExecutor`` with ``jobs``
workers, spawned processes so that numba's and torch's threads are never forked); ``"ray"`` (``ray.init`` on
``address``, a running cluster, or a local instance when ``address`` is None; the ``ray`` extra). ``"auto"``:
the pool when there is more than one task and more than one core, else serial.

The pool's workers are spawned: each imports the caller's main script again, so a script that starts a pool must do it
under ``if __name__ == "__main__":``; a pool asked for from a script's unguarded top level, or from a script read
from standard input (``python -``), is refused before any worker starts (:class:`UnguardedMain`, a ``ValueError``;
``"auto"`` is serial there).

Stopping: a task that fails for good drops the queued tasks; the running ones end first. On Ctrl-C or SIGTERM (as
``mrd-env`` routes it: a ``KeyboardInterrupt`` in the main process) the workers are stopped, not waited for
(``ProcessPoolExecutor`` only cancels the tasks not started and waits for the running ones: a task blocked in a
worker, a controller that never returns, kept the sweep alive). Each worker gets SIGTERM, raised in its task as
``KeyboardInterrupt`` so that a task that saves its work on Ctrl-C (a training run: the agent so far) does; a worker
still running :data:`STOP_GRACE` seconds later is killed. The workers ignore the terminal's Ctrl-C (the parent stops
them, once), take one SIGTERM (a second, from a job scheduler that signals every process as well, does not
interrupt a save) and die with their parent if it dies without stopping them (Linux: ``PR_SET_PDEATHSIG``). A task
that raises ``SystemExit`` or ``KeyboardInterrupt`` of its own in a worker fails as any other task
(:class:`TaskExited`): it does not exit the caller's process.
"""
from __future__ import annotations

import copy
import os
import reprlib
import signal
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

BACKENDS = ("auto", "serial", "pool", "ray")


@dataclass(frozen=True)
class Task:
    """``fn(*args, **kwargs)``; ``label`` names it in progress and error messages."""

    fn: Callable
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)
    label: str = ""

    def __call__(self):
        return self.fn(*self.args, **self.kwargs)

    def describe(self) -> str:
        inputs = ", ".join([*map(_short, self.args), *(f"{k}={_short(v)}" for k, v in self.kwargs.items())])
        return f"{self.label or getattr(self.fn, '__name__', 'task')}({inputs})"


class TaskFailed(RuntimeError):
    """A task failed on its first try and its one retry (or on its only try, without retries)."""

    def __init__(self, task: Task, error: BaseException, tries: int = 2):
        self.task, self.error = task, error
        times = "twice" if tries == 2 else "on its only try"
        super().__init__(f"task {task.describe()} failed {times}: {type(error).__name__}: {error}")


def _short(v: Any, n: int = 60) -> str:
    """``repr(v)`` in at most ``n`` characters, without building the whole of a huge value's repr first."""
    r = reprlib.Repr()
    r.maxstring = r.maxother = r.maxlong = n
    s = r.repr(v)
    return s if len(s) <= n else s[: n - 3] + "..."


class TaskExited(RuntimeError):
    """A task raised ``SystemExit`` or ``KeyboardInterrupt`` in a pool's worker: its own doing (the workers ignore
    Ctrl-C and the parent stops them), reported as the task's failure rather than exiting the caller."""


class UnguardedMain(ValueError):
    """The pool asked for from a script whose calls are not under ``if __name__ == "__main__":``: each spawned worker
    would run the script again (multiprocessing imports it), start its own pool, and die in its bootstrapping; or from
    a main script that is no file (``python -`` reads it from standard input), which no worker can import."""


def unguarded_main() -> str | None:
    """``file:line`` of the call into this sweep from the main script's top level, outside an ``if __name__ ==
    "__main__":`` block (what a spawned worker re-runs when it imports the script); None when the call is guarded,
    or there is no script file to re-run (an interactive session, a notebook, ``python -c``)."""
    import ast
    import inspect

    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if not path or not os.path.isfile(path):
        return None
    frame = inspect.currentframe()
    while frame is not None and not (frame.f_code.co_name == "<module>" and frame.f_globals is vars(main)):
        frame = frame.f_back
    if frame is None:  # the main script's top level is not on the stack (a thread, a callback)
        return None
    line = frame.f_lineno
    try:
        with open(path, "rb") as f:
            tree = ast.parse(f.read(1 << 24))  # a script, read once and bounded (16 MiB)
    except (OSError, SyntaxError, ValueError):
        return None

    def is_guard(node) -> bool:
        t = node.test
        if not (isinstance(t, ast.Compare) and len(t.ops) == 1 and isinstance(t.ops[0], ast.Eq)):
            return False
        sides = [t.left, t.comparators[0]]
        return any(isinstance(a, ast.Name) and a.id == "__name__" for a in sides) and \
            any(isinstance(a, ast.Constant) and a.value == "__main__" for a in sides)

    for node in ast.walk(tree):
        if isinstance(node, ast.If) and is_guard(node) and node.body:
            if node.body[0].lineno <= line <= (node.body[-1].end_lineno or node.body[-1].lineno):
                return None
    return f"{path}:{line}"


def pool_refusal() -> str | None:
    """Why a process pool cannot start from this process's main script (one line), or None. Each spawned worker
    imports the main script first: one whose calls are unguarded (:func:`unguarded_main`) would run again in every
    worker; one that is no file (``python -`` names it ``<stdin>``) cannot be imported, and every worker died
    before its first task (the sweep ended in "its worker process ended" and a traceback per worker)."""
    path = getattr(sys.modules.get("__main__"), "__file__", None)
    if path and not os.path.isfile(path):
        return (f"backend 'pool' called from a main script that is no file ({path}): each worker process imports the "
                "main script first (multiprocessing's spawn) and cannot. Run the script from a file, or use "
                "backend=\"serial\"")
    where = unguarded_main()
    if where is not None:
        return (f"backend 'pool' called from the top level of the script {where}, outside an `if __name__ == "
                f"\"__main__\":` block: each worker process would run the script again (multiprocessing's spawn "
                "imports it). Put the script's calls under `if __name__ == \"__main__\":`, or use backend=\"serial\"")
    return None


def check_main_guard() -> None:
    """:class:`UnguardedMain` (one line) where :func:`pool_refusal` finds the pool cannot start: refused before any
    worker starts, rather than ending in a ``BrokenProcessPool`` after every worker re-ran the script or failed to
    import it."""
    why = pool_refusal()
    if why is not None:
        raise UnguardedMain(why)


class WorkerDied(RuntimeError):
    """A pool's worker process ended while running a task (``os._exit`` in the task's code, a crash, the kernel's
    out-of-memory killer): the pool is broken, so the sweep stops with the task named, never a bare
    ``BrokenProcessPool``."""


#: Seconds a stopped pool's workers have to end their tasks (a training run saves the agent so far) before they are
#: killed.
STOP_GRACE = 5.0


def _call(task: Task):
    """Run a task; exceptions come back as values so that the caller decides on the retry."""
    try:
        return True, task()
    except Exception as exc:  # noqa: BLE001 — reported with the task's inputs by the caller
        return False, exc


#: Set in a worker by the parent's stop (SIGTERM): the worker's later tasks do not start.
_stopping = False


def _call_in_worker(task: Task):
    """:func:`_call` in a pool's worker. A ``SystemExit`` or ``KeyboardInterrupt`` is the task's own (Ctrl-C is
    ignored there) or the parent's stop: either way the task's failure, never a reason to exit the parent."""
    if _stopping:
        return False, TaskExited("the sweep was stopped before it started")
    try:
        return _call(task)
    except (SystemExit, KeyboardInterrupt) as exc:
        what = f"SystemExit({_short(exc.code)})" if isinstance(exc, SystemExit) else type(exc).__name__
        return False, TaskExited("the sweep was stopped" if _stopping else f"it raised {what} in a worker process")


def _on_stop(signum, frame):
    """A worker's SIGTERM (the parent's stop): ``KeyboardInterrupt`` in the running task, once."""
    global _stopping
    if not _stopping:
        _stopping = True
        raise KeyboardInterrupt


def _worker_init() -> None:
    """A pool worker ignores the terminal's Ctrl-C (the parent, which gets it too, stops the pool), takes SIGTERM as
    the stop, and dies with its parent (Linux): a worker orphaned by a killed parent would otherwise run — or block —
    on its own."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _on_stop)
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            PR_SET_PDEATHSIG = 1
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
            if os.getppid() == 1:  # the parent died before the call: nobody to signal us
                os._exit(1)
        except (OSError, AttributeError):
            pass  # no libc prctl: the parent's stop still ends the workers


def default_jobs() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def resolve_backend(backend: str, n_tasks: int, jobs: int | None) -> str:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {list(BACKENDS)}, got {backend!r}")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    if backend == "auto":
        workers = jobs if jobs is not None else default_jobs()
        # where the pool cannot start (check_main_guard: an unguarded script, a script read from standard input)
        # auto is serial
        return "pool" if n_tasks > 1 and workers > 1 and pool_refusal() is None else "serial"
    return backend


def run_tasks(tasks: Sequence[Task], *, backend: str = "auto", jobs: int | None = None, address: str | None = None,
              progress: bool = True, desc: str = "sweep", retry: bool = True) -> list:
    """The results of ``tasks``, in their order (see the module docstring). ``retry=False``: a failed task is
    reported at once (for callers whose failures are the user's errors, not transient ones)."""
    tasks = list(tasks)
    backend = resolve_backend(backend, len(tasks), jobs)
    if not tasks:
        return []
    if backend == "pool":
        check_main_guard()
    from tqdm.auto import tqdm

    bar = tqdm(total=len(tasks), desc=desc, disable=not progress or len(tasks) < 2)  # one task: its own bar
    try:
        run = {"serial": _serial, "pool": _pool, "ray": _ray}[backend]
        return run(tasks, jobs, address, bar, retry)
    finally:
        bar.close()


def _finish(task: Task, outcome, retry: Callable[[], tuple] | None):
    ok, value = outcome
    if ok:
        return value
    if retry is None:
        raise TaskFailed(task, value, tries=1) from value
    ok, value2 = retry()
    if ok:
        return value2
    raise TaskFailed(task, value2) from value2


def _serial(tasks, jobs, address, bar, retry):
    out = []
    for t in tasks:
        # the first try runs on a copy, so that a retry starts from the task's own inputs (a generator it
        # draws from, say), as it does on a pool or Ray, which send the task again
        out.append(_finish(t, _call(copy.deepcopy(t)), (lambda t=t: _call(t)) if retry else None))
        bar.update()
    return out


def _pool(tasks, jobs, address, bar, retry):
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    workers = min(jobs or default_jobs(), len(tasks))
    results: list = [None] * len(tasks)
    ex = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"), initializer=_worker_init)
    submitted: list = []  # every future, retries' too: a stop waits for the running ones to return

    def submit(task):
        submitted.append(ex.submit(_call_in_worker, task))
        return submitted[-1]

    try:
        futures = {submit(t): i for i, t in enumerate(tasks)}
        for fut in as_completed(futures):
            i = futures[fut]
            try:
                outcome = fut.result()
            except BrokenProcessPool as exc:  # no retry: the pool is gone with its worker
                raise TaskFailed(tasks[i], WorkerDied(f"its worker process ended while running it ({exc})"),
                                 tries=1) from None
            results[i] = _finish(tasks[i], outcome, (lambda i=i: submit(tasks[i]).result()) if retry else None)
            bar.update()
    except Exception:
        # a failed task: the queued tasks are dropped, the running ones end (a training seed saves its agent) — unless
        # a Ctrl-C or SIGTERM comes meanwhile
        try:
            ex.shutdown(wait=True, cancel_futures=True)
        except BaseException:
            _stop_workers(ex, submitted)
            raise
        raise
    except BaseException:  # Ctrl-C, SIGTERM: the running tasks are stopped (shutdown would wait for them all)
        _stop_workers(ex, submitted)
        raise
    ex.shutdown(wait=True)
    return results


def _stop_workers(ex, futures, grace: float | None = None) -> None:
    """Stop the pool's workers: its queued tasks dropped, SIGTERM to each worker (its task's ``KeyboardInterrupt``,
    for it to save what it has), then, once the running tasks have returned or after ``grace`` s
    (:data:`STOP_GRACE`), SIGKILL to every worker (idle, or still running a task that will not stop: nothing of
    theirs is left to wait for); waits until they end. A second interrupt while waiting kills them at once."""
    from concurrent.futures import wait

    grace = STOP_GRACE if grace is None else grace
    procs = list((getattr(ex, "_processes", None) or {}).values())  # the pool's own record of its workers
    ex.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        _signal(p, signal.SIGTERM)
    try:
        wait([f for f in futures if not f.done()], timeout=grace)
    finally:
        for p in procs:
            _signal(p, signal.SIGKILL)
        for p in procs:
            p.join(1.0)


def _signal(p, sig) -> None:
    try:
        if p.pid is not None and p.exitcode is None:
            os.kill(p.pid, sig)
    except (OSError, ValueError):
        pass  # ended meanwhile


def _ray(tasks, jobs, address, bar, retry):
    try:
        import ray
    except ImportError:
        raise ImportError("--backend ray needs Ray (pip install 'mrd-env[ray]')") from None
    started = False
    if not ray.is_initialized():
        kw = {"address": address} if address else {"num_cpus": jobs or default_jobs()}
        ray.init(ignore_reinit_error=True, include_dashboard=False, log_to_driver=False, **kw)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(_call)
        refs = {remote.remote(t): i for i, t in enumerate(tasks)}
        results: list = [None] * len(tasks)
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            i = refs[done[0]]
            results[i] = _finish(tasks[i], ray.get(done[0]),
                                 (lambda i=i: ray.get(remote.remote(tasks[i]))) if retry else None)
            bar.update()
        return results
    finally:
        if started:
            ray.shutdown()


def timed(fn: Callable, *args, **kwargs) -> tuple[Any, float]:
    """(result, wall seconds) of a call — for the scaling tables."""
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t0
