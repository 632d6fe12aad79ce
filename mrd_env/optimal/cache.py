"""A JSON cache of solved episodes, keyed by everything the result depends on.

A file per key under ``optimal/`` of the project's cache folder (:func:`mrd_env.caches.cache_folder`:
``$MRD_ENV_CACHE_DIR/optimal``, else ``~/.cache/mrd-env/optimal``; checked private before use). Its name is a hash
of the key; it stores the key itself, the result and a SHA-256 digest of both, so that a result is only ever
returned for the exact episode, plant, damper and options it was solved for: a file whose stored key is another
one (a hash collision, an edited key) or whose content does not match its digest (an edited result, a damaged
file) is refused, and the result is computed again; so are the files of version 1, which had no digest. Files are
written atomically (:func:`mrd_env.storage.write_json`): a kill never leaves half a file.

The digest detects an edited or damaged file; it is not a signature: nobody but you can write the folder (its
checks), and whoever can could also change the kernels loaded from beside it.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..caches import cache_folder, read_regular
from ..storage import write_json

#: Bumped when a solver changes what it returns for the same key, or the files' format changes (2: a digest).
VERSION = 2


def cache_dir() -> Path:
    """The folder of the cached results (checked private; see the module docstring)."""
    return cache_folder("optimal")


def _path(kind: str, key: dict) -> tuple[Path, str]:
    text = json.dumps({"kind": kind, "version": VERSION, **key}, sort_keys=True, default=repr)
    return cache_dir() / f"{kind}-{hashlib.sha256(text.encode()).hexdigest()[:20]}.json", text


def _digest(key, result) -> str:
    """SHA-256 of the stored key and result (canonical JSON: the same after a round trip through the file)."""
    text = json.dumps({"key": key, "result": result}, sort_keys=True, allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def load(kind: str, key: dict) -> dict | None:
    """The cached result of ``kind`` for ``key``, or None (nothing cached, a file for another key, or a file
    whose content does not match its digest: edited or damaged)."""
    try:
        path, text = _path(kind, key)
    except OSError:  # no usable cache folder
        return None
    data = read_regular(path)
    if data is None:
        return None
    try:
        stored = json.loads(data.decode("utf-8"))
    except ValueError:
        return None
    if not isinstance(stored, dict) or not {"key", "result", "digest"} <= stored.keys():
        return None
    if json.dumps(stored["key"], sort_keys=True) != json.dumps(json.loads(text), sort_keys=True):
        return None
    if stored["digest"] != _digest(stored["key"], stored["result"]):
        return None
    return stored["result"]


def store(kind: str, key: dict, result: dict) -> Path | None:
    """Cache ``result`` (JSON-ready) for ``key``; None where the cache cannot be written (read-only home)."""
    try:
        path, text = _path(kind, key)
        # the digest of what a reader will see: the key and result as they come back from the file
        record = json.loads(json.dumps({"key": json.loads(text), "result": result}))
        write_json(path, {**record, "digest": _digest(record["key"], record["result"])})
    except OSError:
        return None
    return path
