"""The project's cache folders: where generated kernels (:mod:`mrd_env.stepping.codegen`), numba's compilation of
them, the clairvoyant solver's results and its compiled model (:mod:`mrd_env.optimal.cache`) and, only with
``MRD_ENV_JAX_CACHE=1``, JAX's compiled programs (:mod:`mrd_env.jax`: ``jax/``, checked at every read and write) live.

The root is ``$MRD_ENV_CACHE_DIR``, else ``$XDG_CACHE_HOME/mrd-env``, else ``~/.cache/mrd-env``. Generated Python
modules, numba's pickled compilations and shared libraries are loaded from there, so whoever can write the folder
can run code in this process: every folder is checked before use by :func:`mrd_env.storage.private_folder` (a
real folder, not a symlink, owned by this user, writable by nobody else; created with mode 0700). Where the root is
refused (with a warning saying why) or cannot be written (a read-only home), the cache falls back to
``$TMPDIR/mrd-env-<uid>``, checked the same way; where that one is refused too (another user created it first),
to a new folder of unpredictable name (:func:`tempfile.mkdtemp`), private to this process and its children.
"""
from __future__ import annotations

import os
import stat
import tempfile
import warnings
from pathlib import Path

from .storage import private_folder

#: Environment variable naming the cache root.
VARIABLE = "MRD_ENV_CACHE_DIR"

_LAST_RESORT: list[Path] = []  # this process's mkdtemp folder, once made


def cache_root() -> Path:
    """The configured cache root (not checked): ``$MRD_ENV_CACHE_DIR``, else the user's cache folder."""
    env = os.environ.get(VARIABLE)
    if env:
        return Path(env)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "mrd-env"


def _user_id() -> str:
    if hasattr(os, "getuid"):
        return str(os.getuid())
    import getpass

    return getpass.getuser()


def fallback_root() -> Path:
    """``$TMPDIR/mrd-env-<uid>`` if it is (or can be made) private, else a new ``mkdtemp`` folder."""
    shared = Path(tempfile.gettempdir()) / f"mrd-env-{_user_id()}"
    try:
        return private_folder(shared)
    except PermissionError as e:
        if _LAST_RESORT and _LAST_RESORT[0].is_dir():
            return _LAST_RESORT[0]
        made = Path(tempfile.mkdtemp(prefix="mrd-env-"))  # mode 0700, a name nobody can predict
        warnings.warn(f"{e}; using {made} for this process (its cache is not kept)", RuntimeWarning, stacklevel=3)
        _LAST_RESORT[:] = [made]
        return made


def _usable(folder: Path) -> bool:
    return os.access(folder, os.W_OK | os.X_OK)


def cache_folder(name: str) -> Path:
    """``<root>/<name>``, both checked private (created with mode 0700 if missing); the fallback root's ``name``
    where the root is refused or cannot be written (see the module docstring)."""
    root = cache_root()
    try:
        folder = private_folder(private_folder(root) / name)
        if _usable(folder):
            return folder
    except PermissionError as e:
        if e.errno is None:  # refused by the checks (not a plain "cannot create"): say so
            warnings.warn(f"{e}; using a private temporary folder instead", RuntimeWarning, stacklevel=2)
    except OSError:  # read-only or missing home: fall back quietly
        pass
    return private_folder(fallback_root() / name)


def read_regular(path: str | Path) -> bytes | None:
    """The bytes of ``path`` if it is a regular file (not through a symlink, not a FIFO or device), else None."""
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        with os.fdopen(fd, "rb") as fh:
            fd = None
            return fh.read()
    except OSError:
        return None
    finally:
        if fd is not None:
            os.close(fd)
