"""A JSON cache of solved episodes, keyed by everything the result depends on.

A file per key under ``$MRD_ENV_CACHE_DIR/optimal`` (else ``~/.cache/mrd-env/optimal``): its name is a hash of
the key and it stores the key itself, so that a result is only ever returned for the exact episode, plant, damper
and options it was solved for (a hash collision or an edited file is refused, not trusted).
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

#: Bumped when a solver changes what it returns for the same key.
VERSION = 1


def cache_dir() -> Path:
    env = os.environ.get("MRD_ENV_CACHE_DIR")
    base = Path(env) if env else Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "mrd-env"
    return base / "optimal"


def _path(kind: str, key: dict) -> tuple[Path, str]:
    text = json.dumps({"kind": kind, "version": VERSION, **key}, sort_keys=True, default=repr)
    return cache_dir() / f"{kind}-{hashlib.sha256(text.encode()).hexdigest()[:20]}.json", text


def load(kind: str, key: dict) -> dict | None:
    """The cached result of ``kind`` for ``key``, or None (nothing cached, or a file for another key)."""
    path, text = _path(kind, key)
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if json.dumps(stored.get("key"), sort_keys=True) != json.dumps(json.loads(text), sort_keys=True):
        return None
    return stored.get("result")


def store(kind: str, key: dict, result: dict) -> Path | None:
    """Cache ``result`` (JSON-ready) for ``key``; None where the cache cannot be written (read-only home)."""
    path, text = _path(kind, key)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps({"key": json.loads(text), "result": result}), encoding="utf-8")
        tmp.replace(path)  # atomic: parallel workers never read half a file
    except OSError:
        return None
    return path
