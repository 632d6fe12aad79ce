"""A JAX twin of the physics (optional: ``pip install mrd-env[jax]``; nothing else in the project needs it).

Importing it switches JAX to float64 (``jax_enable_x64``: the schemes need it; set before any array is made).
JAX's compiled programs are kept in memory, for this process only: a compiled program read from a file is code, and
JAX does not authenticate its cache's entries (an entry planted under a program's key runs in its place). With
``MRD_ENV_JAX_CACHE=1`` (:data:`CACHE_VARIABLE`) they are kept between processes in the project's cache folder
(:func:`mrd_env.caches.cache_folder` ``("jax")``), as private as the kernels' folder and checked at every read and
write, not only at import (:class:`CheckedCache`); a process that set ``jax_compilation_cache_dir`` itself keeps
its own choice (that folder is JAX's business). See ``docs/jax.md``: every plant's environment made from its own
assembly (:mod:`.env`) and its Gymnasium ``VectorEnv`` (:mod:`.vector`), the stepping scheme (:mod:`.scheme`), the
dampers (:mod:`.dampers`), any system over a record (:mod:`.simulate`), the clairvoyant by gradient
(:mod:`.clairvoyant`), the environment as a gymnax-style object (:func:`make_gymnax`, :mod:`.gymnax`).
"""
from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import jax

from ..caches import cache_folder, read_regular
from ..storage import private_folder, write_bytes

#: Environment variable: ``1`` keeps JAX's compiled programs between processes (in ``cache_folder("jax")``).
CACHE_VARIABLE = "MRD_ENV_JAX_CACHE"
_SUFFIX = "-cache"  # JAX's own name for an entry's file


def cache_wanted() -> bool:
    """Whether ``MRD_ENV_JAX_CACHE`` asks for the persistent cache (``1``, ``true``, ``yes``, ``on``)."""
    return os.environ.get(CACHE_VARIABLE, "").strip().lower() in ("1", "true", "yes", "on")


class CheckedCache:
    """JAX's persistent compilation cache in ``folder``, the folder and the cache root checked by
    :func:`mrd_env.storage.private_folder` before every read and every write (a folder made a link, handed to
    another owner or made writable by others after the import is refused from then on, with one warning).
    Entries are read only as regular files, never through a symlink (:func:`mrd_env.caches.read_regular`), and
    written atomically under a new name (:func:`mrd_env.storage.write_bytes`). Like the kernels' cache, the
    folder's privacy is what keeps others' programs out: JAX's entries carry no signature."""

    def __init__(self, folder: str | Path, root: str | Path | None = None):
        self._path = Path(folder)
        self._root = None if root is None else Path(root)
        self._warned = False

    def _checked(self) -> Path | None:
        try:
            if self._root is not None:
                private_folder(self._root)
            return private_folder(self._path)
        except OSError as e:
            if not self._warned:
                self._warned = True
                warnings.warn(f"{e}; JAX's compiled programs are neither read from nor written to it",
                              RuntimeWarning, stacklevel=4)
            return None

    def _file(self, folder: Path, key: str) -> Path | None:
        # JAX's keys are "<module name>-<hash>": anything else (a separator, a dot first) is not a name in the folder
        ok = isinstance(key, str) and re.fullmatch(r"[\w\-][\w.\-]*", key) is not None
        return folder / f"{key}{_SUFFIX}" if ok else None

    def get(self, key: str) -> bytes | None:
        folder = self._checked()
        path = None if folder is None else self._file(folder, key)
        return None if path is None else read_regular(path)

    def put(self, key: str, value: bytes) -> None:
        folder = self._checked()
        path = None if folder is None else self._file(folder, key)
        if path is not None:
            try:
                write_bytes(path, value)
            except OSError:
                pass  # a cache that cannot be written: the program is compiled again next time

    def clear(self) -> None:
        pass


def _persist() -> None:
    """Point JAX's persistent cache at ``cache_folder("jax")`` through :class:`CheckedCache`; where JAX's internals
    are not as expected (another JAX version), nothing is persisted (with a warning)."""
    try:
        from jax._src import compilation_cache as cc
    except ImportError:
        cc = None
    if cc is None or not hasattr(cc, "get_file_cache") or getattr(cc, "_cache", None) is not None:
        warnings.warn(f"{CACHE_VARIABLE}: this JAX's compilation cache cannot be checked; nothing is persisted",
                      RuntimeWarning, stacklevel=3)
        return
    folder = cache_folder("jax")
    original = cc.get_file_cache

    def get_file_cache(path):
        if Path(path) == folder:
            return CheckedCache(folder, root=folder.parent), path  # the root in use: configured, or the fallback
        return original(path)

    cc.get_file_cache = get_file_cache
    jax.config.update("jax_compilation_cache_dir", str(folder))
    if "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS" not in os.environ:  # the user's own choice kept
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    # XLA's own caches in that folder (GPU autotuning, kernels) are read by XLA, past the checks: not used
    jax.config.update("jax_persistent_cache_enable_xla_caches", "none")


jax.config.update("jax_enable_x64", True)
if cache_wanted() and not jax.config.jax_compilation_cache_dir:
    _persist()

from . import dampers, scheme, simulate  # noqa: E402
from .gymnax import make_gymnax  # noqa: E402

__all__ = ["CACHE_VARIABLE", "CheckedCache", "cache_wanted", "dampers", "scheme", "simulate", "make_gymnax"]
