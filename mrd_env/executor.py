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

Stopping: Ctrl-C, SIGTERM (as ``mrd-env`` routes it: a ``KeyboardInterrupt`` in the main process) or any other
exception while the pool runs kills its worker processes at once and waits for them to end — a task blocked in a
worker (a controller that never returns, say) cannot keep the sweep alive; ``ProcessPoolExecutor`` itself only
cancels the tasks not started and waits for the running ones. The workers ignore Ctrl-C (the parent stops them) and
are killed by the kernel if the parent dies without stopping them (Linux: ``PR_SET_PDEATHSIG``). A task that raises
``SystemExit`` or ``KeyboardInterrupt`` in a worker fails as any other task (:class:`TaskExited`): it does not exit
the caller's process.
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


def _call(task: Task):
    """Run a task; exceptions come back as values so that the caller decides on the retry."""
    try:
        return True, task()
    except Exception as exc:  # noqa: BLE001 — reported with the task's inputs by the caller
        return False, exc


def _call_in_worker(task: Task):
    """:func:`_call` in a pool's worker, where a ``SystemExit`` or ``KeyboardInterrupt`` can only be the task's
    (Ctrl-C is ignored there, SIGTERM ends the worker): a failure of the task, not a reason to exit the parent."""
    try:
        return _call(task)
    except (SystemExit, KeyboardInterrupt) as exc:
        what = f"SystemExit({exc.code!r})" if isinstance(exc, SystemExit) else type(exc).__name__
        return False, TaskExited(f"it raised {_short(what)} in a worker process")


def _worker_init() -> None:
    """A pool worker ignores Ctrl-C (the parent, which gets it too, stops the pool) and dies with its parent
    (Linux): a worker orphaned by a killed parent would otherwise run — or block — on its own."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            PR_SET_PDEATHSIG = 1
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
            if os.getppid() == 1:  # the parent died before the call: nobody to signal us
                os._exit(1)
        except (OSError, AttributeError):
            pass  # no libc prctl: the parent's stop still kills the workers


def default_jobs() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def resolve_backend(backend: str, n_tasks: int, jobs: int | None) -> str:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {list(BACKENDS)}, got {backend!r}")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    if backend == "auto":
        workers = jobs if jobs is not None else default_jobs()
        return "pool" if n_tasks > 1 and workers > 1 else "serial"
    return backend


def run_tasks(tasks: Sequence[Task], *, backend: str = "auto", jobs: int | None = None, address: str | None = None,
              progress: bool = True, desc: str = "sweep", retry: bool = True) -> list:
    """The results of ``tasks``, in their order (see the module docstring). ``retry=False``: a failed task is
    reported at once (for callers whose failures are the user's errors, not transient ones)."""
    tasks = list(tasks)
    backend = resolve_backend(backend, len(tasks), jobs)
    if not tasks:
        return []
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

    workers = min(jobs or default_jobs(), len(tasks))
    results: list = [None] * len(tasks)
    ex = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"), initializer=_worker_init)
    try:
        futures = {ex.submit(_call_in_worker, t): i for i, t in enumerate(tasks)}
        for fut in as_completed(futures):
            i = futures[fut]
            results[i] = _finish(tasks[i], fut.result(),
                                 (lambda i=i: ex.submit(_call_in_worker, tasks[i]).result()) if retry else None)
            bar.update()
    except BaseException:
        # Ctrl-C, SIGTERM, a failed task: the running tasks are not waited for (shutdown would wait for them all)
        _kill_workers(ex)
        raise
    ex.shutdown(wait=True)
    return results


def _kill_workers(ex, grace: float = 5.0) -> None:
    """Kill the pool's worker processes, drop its queued tasks and wait (at most ``grace`` s each) until they end."""
    procs = list((getattr(ex, "_processes", None) or {}).values())  # the pool's own record of its workers
    for p in procs:
        try:
            p.kill()
        except (OSError, ValueError, AttributeError):
            pass  # already ended, or closed
    ex.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        try:
            p.join(grace)
        except (OSError, ValueError, AssertionError):
            pass


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
