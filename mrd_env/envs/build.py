"""The one rule that builds every part of an environment from what the user passes.

``None`` → the default kind; a name → that kind with its default options; an instance of the part's class →
itself; a dict → ``{"kind": name, **options}`` (the kind defaults to the default one). Anything else, an unknown
kind or an unknown option raises ``ValueError`` naming the argument and the valid choices.
"""
from __future__ import annotations

import inspect
from typing import Any, Callable, Mapping


def build(what: str, spec: Any, kinds: Mapping[str, Callable], default: str, base: type | tuple = (),
          **context) -> Any:
    """Build part ``what`` from ``spec`` (see the module docstring); ``context`` goes to every factory."""
    if base and isinstance(spec, base):
        return spec
    if spec is None:
        kind, options = default, {}
    elif isinstance(spec, str):
        kind, options = spec, {}
    elif isinstance(spec, Mapping):
        options = dict(spec)
        kind = options.pop("kind", default)
    else:
        names = [b.__name__ for b in (base if isinstance(base, tuple) else (base,))]
        raise ValueError(f"{what} must be None, a name among {sorted(kinds)}, a dict of options"
                         f"{' or a ' + ' / '.join(names) if names else ''}, got {type(spec).__name__}")
    if not isinstance(kind, str) or kind not in kinds:
        raise ValueError(f"{what}: unknown kind {kind!r}; valid: {sorted(kinds)}")
    factory = kinds[kind]
    check_options(f"{what} ({kind!r})", options, factory, exclude=tuple(context))
    return factory(**options, **context)


def check_options(what: str, options: Mapping, factory: Callable, exclude: tuple = (), also: tuple = ()) -> None:
    """``ValueError`` for an option ``factory`` does not take (its keyword parameters, minus ``exclude``; the
    message lists ``also``, names taken before the factory, among the valid ones)."""
    params = inspect.signature(factory).parameters
    if any(p.kind is p.VAR_KEYWORD for p in params.values()):
        return
    valid = [n for n, p in params.items() if n not in exclude and p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)]
    unknown = sorted(set(options) - set(valid), key=str)
    if unknown:
        raise ValueError(f"{what} has unknown option(s) {unknown}; valid: {sorted([*valid, *also])}")


def as_options(name: str, given) -> dict:
    """A dict of options (None → {}), else ``ValueError`` naming ``name``."""
    if given is None:
        return {}
    if not isinstance(given, Mapping):
        raise ValueError(f"{name} must be a dict, got {type(given).__name__}")
    return dict(given)


#: The option keys whose string value names a file the environment reads, at any depth of the options: a road's or a
#: ground motion's ``path`` (``"csv"``, ``"at2"``, ``"two_column"``), a neural inverse's ``network``; and the
#: top-level ``damper`` when it is a preset file (``"fitted.json"``).
FILE_KEYS = ("path", "network")
#: How deep :func:`confine_files` looks into nested options (deeper options are refused: no environment has them).
MAX_OPTION_DEPTH = 16


def map_files(options: Mapping, fn, where: str) -> dict:
    """``options`` with every file they name (:data:`FILE_KEYS` at any depth, a preset-file ``damper``) replaced by
    ``fn(value, label)`` (``label``: the option's place, for messages); options nested deeper than
    :data:`MAX_OPTION_DEPTH` are refused naming ``where``. The options are not changed."""
    from ..dampers import is_preset_file

    def walk(value, key: str, depth: int):
        if depth > MAX_OPTION_DEPTH:
            raise ValueError(f"{where}: options nested deeper than {MAX_OPTION_DEPTH} levels at {key}")
        if isinstance(value, Mapping):
            return {k: (fn(v, f"{key}[{k!r}]") if k in FILE_KEYS and isinstance(v, str)
                        else walk(v, f"{key}[{k!r}]", depth + 1)) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return type(value)(walk(v, f"{key}[{i}]", depth + 1) for i, v in enumerate(value))
        return value

    return {k: fn(str(v), str(k)) if k == "damper" and is_preset_file(v) else walk(v, str(k), 1)
            for k, v in options.items()}


def confine_files(options: Mapping, folder, where: str) -> dict:
    """``options`` with every file they name (:func:`map_files`) resolved inside ``folder`` by
    :func:`mrd_env.storage.inside` (a relative name only: no absolute path, no ``..``, no link leaving the folder),
    for options read from a file in that folder (an agent's ``env_kwargs``, a suite's options); ``ValueError``
    naming ``where``, the option and the name otherwise. The options are not changed."""
    from .. import storage

    return map_files(options, lambda v, label: str(storage.inside(folder, v, what=f"{where}: {label}")), where)
