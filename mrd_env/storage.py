"""Files that survive a kill and cannot be planted: every result, cache and agent file the project writes goes
through here.

- :func:`write_bytes` / :func:`write_text` / :func:`write_json`: the content goes to a uniquely named temporary
  file in the same folder (created with ``O_EXCL``, so no write ever follows a symlink planted at a predictable
  name), is flushed to disk, then renamed over the target (``os.replace``: atomic on POSIX and Windows). A kill at
  any moment leaves the previous file or the new one, never a mix.
- :func:`replace_folder`: a folder written in full beside its target (:func:`staging_folder`), then swapped in. On
  Linux the swap is one ``renameat2(RENAME_EXCHANGE)`` system call, so a reader sees the previous folder or the new
  one; elsewhere the previous folder is moved aside first and :func:`recover_folder` puts it back after a kill.
- :func:`inside`: a file named by a file (an agent's ``agent.json``, a preset) resolved inside its folder: no
  absolute path, no ``..``, no symlink leaving it.
- :func:`read_limited`: a file read only if it is a regular file (never a FIFO, a device such as ``/dev/zero``, a
  socket) and at most a given size, so that no shared file can hang or exhaust a reader.
- :func:`private_folder`: a per-user folder (mode 0700, owned by the user, not a symlink), checked before use as
  numba's own cache does.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import json
import os
import shutil
import signal
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path

#: Suffix of a folder moved aside during a non-atomic swap (recover_folder puts it back).
ASIDE = ".previous"


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (a temporary file in the same folder, fsync, rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        _umask_mode(fd)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        _unlink_quietly(tmp)
        raise
    return path


def writable_folder(path: str | Path, *, option: str = "--out") -> Path:
    """``path`` created if needed and probed with a write, before a long run that ends by writing there; an
    ``OSError`` naming ``option`` and the folder otherwise (an unwritable output must not cost the whole run)."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-probe.", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OSError(exc.errno, f"{option} {path} cannot be written ({exc.strerror or exc})") from None
    return path


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path: str | Path, obj, **dumps_kwargs) -> Path:
    """Write ``obj`` as JSON to ``path`` atomically (``dumps_kwargs`` as for :func:`json.dumps`)."""
    return write_text(path, json.dumps(obj, **dumps_kwargs))


def write_texts(files: dict) -> list[Path]:
    """Write several text files that belong together (a table's CSV and Markdown) so that a Ctrl-C or SIGTERM
    never leaves them from two different writes: every file is written to its temporary name first, then all are
    renamed with those signals held back (a few system calls)."""
    staged = []
    try:
        for path, text in files.items():
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
            staged.append((tmp, path))
            _umask_mode(fd)
            with os.fdopen(fd, "wb") as fh:
                fh.write(text.encode("utf-8"))
                fh.flush()
                os.fsync(fh.fileno())
        with _signals_held():
            for tmp, path in staged:
                os.replace(tmp, path)
    except BaseException:
        for tmp, _ in staged:
            _unlink_quietly(tmp)
        raise
    return [path for _, path in staged]


@contextmanager
def _signals_held():
    """SIGINT and SIGTERM held back for the block (delivered after it), where the platform allows it."""
    held = {signal.SIGINT, signal.SIGTERM}
    try:
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    except (AttributeError, ValueError, OSError):
        previous = None
    try:
        yield
    finally:
        if previous is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)


@contextmanager
def atomic_path(path: str | Path):
    """A temporary path in ``path``'s folder for a writer that takes a file name (``np.savez``, ``fig.savefig``,
    SB3's ``save``); renamed over ``path`` when the block ends without an error, removed otherwise."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    _umask_mode(fd)
    os.close(fd)
    try:
        yield Path(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        _unlink_quietly(tmp)
        raise


def current_umask() -> int:
    """The process's umask, read without changing it where the system says it (Linux's ``/proc/self/status``);
    elsewhere set and put back at once."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _umask_mode(fd: int) -> None:
    """Give a file made by ``mkstemp`` (mode 0600, for its unpredictable name's sake) the mode a plain ``open``
    would: 0666 less the umask, so that a result in a shared folder is readable as the user's other files are. The
    caches' files stay private through their folders (0700, :func:`private_folder`)."""
    if hasattr(os, "fchmod"):
        os.fchmod(fd, 0o666 & ~current_umask())


def _unlink_quietly(path) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def staging_folder(target: str | Path) -> Path:
    """A new empty folder beside ``target`` to write a folder's next content into (then :func:`replace_folder`)."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    staged = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".staging", dir=target.parent))
    os.chmod(staged, 0o777 & ~current_umask())
    return staged


def _renameat2_exchange():
    """The Linux ``renameat2`` system call with RENAME_EXCHANGE, or None where it is not available."""
    if not hasattr(os, "uname") or os.uname().sysname != "Linux":
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    at_fdcwd, rename_exchange = -100, 2

    def exchange(a: Path, b: Path) -> bool:
        return fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0

    return exchange


_EXCHANGE = _renameat2_exchange()


def replace_folder(staged: str | Path, target: str | Path) -> Path:
    """Swap the fully written folder ``staged`` in as ``target`` (the previous ``target`` is deleted). A reader or a
    kill at any moment sees the previous folder or the new one (see the module docstring)."""
    staged, target = Path(staged), Path(target)
    _fsync_folder(staged)
    if not target.exists():
        os.replace(staged, target)
    elif _EXCHANGE is not None and _EXCHANGE(staged, target):
        shutil.rmtree(staged, ignore_errors=True)  # ``staged`` now holds the previous content
    else:
        aside = target.with_name(target.name + ASIDE)
        shutil.rmtree(aside, ignore_errors=True)
        os.replace(target, aside)
        os.replace(staged, target)
        shutil.rmtree(aside, ignore_errors=True)
    return target


def recover_folder(target: str | Path) -> Path:
    """``target``, put back from its moved-aside copy if a non-atomic swap was killed between its two renames."""
    target = Path(target)
    aside = target.with_name(target.name + ASIDE)
    if not target.exists() and aside.is_dir():
        os.replace(aside, target)
    return target


def _fsync_folder(folder: Path) -> None:
    for f in folder.iterdir():
        if f.is_file():
            with open(f, "rb") as fh:
                os.fsync(fh.fileno())


def inside(folder: str | Path, name, *, what: str = "file") -> Path:
    """``folder / name`` for a ``name`` read from a file in ``folder``, after a ``ValueError`` naming it if it is not
    a plain relative name inside the folder (absolute, ``..``, or a symlink that leaves it)."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"{what} {name!r} in {folder}: a file name (a string) is required")
    p = Path(name)
    if p.is_absolute() or ".." in p.parts or p.drive:
        raise ValueError(f"{what} {name!r} in {folder}: only a name inside the folder is allowed "
                         "(no absolute path, no '..')")
    root = Path(folder).resolve()
    resolved = (root / p).resolve()
    if resolved != root and root not in resolved.parents:
        raise ValueError(f"{what} {name!r} in {folder}: it is a link that leaves the folder (to {resolved})")
    return root / p


def read_limited(path: str | Path, limit: int, *, what: str = "file") -> bytes:
    """The bytes of ``path`` if it is a regular file (after following links) of at most ``limit`` bytes; a
    ``ValueError`` naming ``what``, the file and the limit otherwise. Opened without blocking, so a FIFO is refused
    rather than waited on; the size is checked before reading and again while reading (a file that grows)."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as exc:
        raise ValueError(f"{what} {path}: cannot be read ({exc.strerror or exc})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise ValueError(f"{what} {path}: not a regular file (a device, FIFO or socket): refused")
        if st.st_size > limit:
            raise ValueError(f"{what} {path}: {st.st_size} bytes, more than the {limit} bytes a {what} may hold: "
                             "refused")
        chunks, size = [], 0
        while True:
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
            if size > limit:
                raise ValueError(f"{what} {path}: more than the {limit} bytes a {what} may hold: refused")
        return b"".join(chunks)
    except OSError as exc:
        raise ValueError(f"{what} {path}: cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)


def private_folder(path: str | Path) -> Path:
    """``path`` created (mode 0700) or checked: a real folder, not a symlink, owned by this user and writable by
    nobody else; a ``PermissionError`` naming the folder and what is wrong otherwise (the numba cache's rule)."""
    path = Path(path)
    try:
        path.mkdir(mode=0o700, parents=True)
    except FileExistsError:
        pass
    st = os.lstat(path)
    if stat.S_ISLNK(st.st_mode) or not stat.S_ISDIR(st.st_mode):
        raise PermissionError(f"cache folder {path} is a link or not a folder: refused (remove it)")
    if hasattr(os, "getuid"):
        if st.st_uid != os.getuid():
            raise PermissionError(f"cache folder {path} belongs to user id {st.st_uid}, not to you "
                                  f"({os.getuid()}): refused (remove it or set MRD_ENV_CACHE_DIR)")
        if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
            raise PermissionError(f"cache folder {path} is writable by others (mode {stat.S_IMODE(st.st_mode):o}): "
                                  "refused (chmod 700 it or set MRD_ENV_CACHE_DIR)")
    return path
