"""A deadline for a test whose failure would be a hang (a FIFO opened for reading, a blocked controller)."""
from __future__ import annotations

import signal
from contextlib import contextmanager


@contextmanager
def deadline(seconds: int = 20):
    """Raise ``TimeoutError`` in the block after ``seconds`` (SIGALRM: main thread, POSIX): a hang fails the test
    instead of blocking the run."""
    def expired(*_):
        raise TimeoutError(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
