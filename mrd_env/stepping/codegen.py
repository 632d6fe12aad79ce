"""The code generator: one compiled stepping module per damper model, written from the templates and cached on
disk (the source in the kernel folder, numba's compilation of it beside it), so that a new process loads it
instead of compiling again."""
from __future__ import annotations

import ast
import hashlib
import inspect
import sys
import types
from pathlib import Path

from ..caches import cache_folder, read_regular
from ..storage import write_text

from . import first_use
from .first_use import SwitchingKernel

HERE = Path(__file__).parent
KERNEL_TEMPLATES = (HERE / "_kernel_template.py", HERE / "_driver_template.py")
#: Lines of a template ending with this comment import what the generated module defines itself (see
#: :mod:`mrd_env.stepping.injected`); :func:`render` drops them.
INJECTED = "# injected"
# Files the kernel's code comes from besides the templates: the scheme's constants, the LU helpers, the layout's
# slot numbers and the command lag. The cache key covers them, so an edit never meets a stale kernel.
_SHARED = (HERE / "scheme.py", HERE / "matrices.py", HERE / "layout.py", HERE.parent / "command_lag.py")

_KERNELS: dict = {}


def kernel_dir() -> Path:
    """Where generated kernels (and numba's cache of them) live: ``kernels/`` in the project's cache folder
    (:func:`mrd_env.caches.cache_folder`: ``$MRD_ENV_CACHE_DIR``, else the user cache, else a private temporary
    folder), checked private (owned by this user, writable by nobody else) before every use."""
    return cache_folder("kernels")


def render(template: Path, header: str, footer: str = "") -> str:
    """``header`` + the template without its ``# injected`` lines + ``footer``."""
    lines = template.read_text(encoding="utf-8").splitlines(keepends=True)
    kept = [ln for ln in lines if not ln.rstrip().endswith(INJECTED)]
    if len(kept) == len(lines):
        raise ValueError(f"{template.name} has no '{INJECTED}' line: what does it take from the generator?")
    return header + "".join(kept) + footer


def kernel_source(model_cls) -> tuple[str, str]:
    """(source, cache key) of a damper model's stepping module: the model's functions, then the kernel and
    driver templates."""
    fns = {"rhs": model_cls.rhs, "force": model_cls.force_law, "project": model_cls.project}
    analytic = getattr(model_cls, "partials", None)
    if analytic is not None:
        fns["partials"] = analytic
    # the model's functions are compiled again inline: one function per step, no calls in the Newton loop
    header = "".join(f"from {f.py_func.__module__} import {f.py_func.__name__} as _{name}_dispatcher\n"
                     f"{name} = nb.njit(inline='always')(_{name}_dispatcher.py_func)\n" for name, f in fns.items())
    header = "import numba as nb\n" + header + f"ns = {len(model_cls.state_names)}\n"
    kernel, driver = KERNEL_TEMPLATES
    footer = "" if analytic is not None else "\npartials = fd_partials  # the model has no analytic derivatives\n"
    source = render(kernel, header) + "\n\n" + render(driver, "", footer)
    # the key covers the templates, the shared files and the model's own modules, so an edited model never
    # meets a stale kernel and editing one model recompiles only its kernel
    h = hashlib.sha256(source.encode())
    for shared in _SHARED:
        h.update(shared.read_bytes())
    for module in sorted(model_modules(model_cls)):
        h.update(Path(module).read_bytes())
    return source, h.hexdigest()[:16]


def model_modules(model_cls) -> set[str]:
    """Source files of the model's class and of every ``mrd_env`` module they import, followed through every import
    (relative or absolute, ``import`` or ``from ... import``; e.g. the shared Bouc–Wen hysteresis): whatever the
    kernel may call is in its key."""
    files = {str(Path(inspect.getsourcefile(model_cls)).resolve())}
    todo = list(files)
    while todo:
        for f in _imported_files(Path(todo.pop())):
            if f not in files:
                files.add(f)
                todo.append(f)
    return files


def _imported_files(path: Path) -> set[str]:
    """The files of the ``mrd_env`` modules (and packages' ``__init__``) that the module at ``path`` imports."""
    root = HERE.parent  # the mrd_env package folder
    package = path.resolve().parent.relative_to(root.parent).parts  # e.g. ("mrd_env", "dampers")

    def source(parts: tuple) -> Path | None:
        if not parts or parts[0] != root.name:
            return None
        target = root.parent.joinpath(*parts)
        return next((f for f in (target.with_suffix(".py"), target / "__init__.py") if f.is_file()), None)

    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found = [source(tuple(a.name.split("."))) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = tuple(node.module.split(".")) if node.module else ()
            if node.level:
                base = package[:len(package) - node.level + 1] + base
            # ``from pkg import x``: x's own module where x is one, else the module that defines x
            found = [source(base + (a.name,)) or source(base) for a in node.names]
        else:
            continue
        out |= {str(f.resolve()) for f in found if f is not None}
    return out


def kernel_module(model_cls, *, compiled: bool = False):
    """The compiled module of a damper model class (``macro_step``, ``run_systems``, ... of the templates).

    Built once per process from a generated module whose numba compilation is cached on disk, so a new
    process loads it instead of compiling again. While the cache does not hold it yet (no ready marker), a
    :class:`~mrd_env.stepping.first_use.SwitchingKernel` stands in (interpreted until a background process has
    compiled it), unless ``MRD_ENV_FIRST_USE=wait`` or ``compiled`` (a caller that needs the module itself).
    """
    module = _KERNELS.get(model_cls)
    if isinstance(module, SwitchingKernel) and module.settled is not None:  # compiled since: drop the stand-in
        module = _KERNELS[model_cls] = module.settled
    if module is not None and not (compiled and isinstance(module, SwitchingKernel)):
        return module
    prefix = kernel_prefix(model_cls)
    source, key = kernel_source(model_cls)
    path = write_generated_source(prefix, source, key)
    if compiled or first_use.mode() == "wait" or first_use.ready_marker(path).exists():
        module = load_generated_module(prefix, source, key)
    else:
        module = SwitchingKernel(model_cls, path, source, lambda: load_generated_module(prefix, source, key))
    _KERNELS[model_cls] = module
    return module


def kernel_prefix(model_cls) -> str:
    """The name of a damper model's generated kernel module, before its key."""
    return f"mrd_env_kernel_{model_cls.name}"


def kernel_path(model_cls) -> Path:
    """The generated kernel source of a damper model class (written if it is not there yet)."""
    source, key = kernel_source(model_cls)
    return write_generated_source(kernel_prefix(model_cls), source, key)


def write_generated_source(prefix: str, source: str, key: str) -> Path:
    """Write ``source`` as ``<prefix>_<key>.py`` in the kernel cache folder (if it is not there yet); its path.
    The write is atomic and never follows a symlink (:func:`mrd_env.storage.write_text`)."""
    path = kernel_dir() / f"{prefix}_{key}.py"
    if read_regular(path) != source.encode("utf-8"):
        write_text(path, source)  # a new file renamed over the name: concurrent processes never see half a file
    return path


def load_generated_module(prefix: str, source: str, key: str):
    """Write ``source`` as ``<prefix>_<key>.py`` in the kernel cache folder (if needed) and import it.

    What runs is ``source`` itself, compiled from memory under the file's name (numba's ``cache=True`` finds its
    compilation beside that file, and checks it against the file's content), never the file read back after a
    check: nothing written to the folder between the check and the import can run."""
    mod_name = f"{prefix}_{key}"
    if mod_name in sys.modules:
        return sys.modules[mod_name]
    path = write_generated_source(prefix, source, key)
    module = types.ModuleType(mod_name)
    module.__file__ = str(path)
    code = compile(source, str(path), "exec", dont_inherit=True)
    sys.modules[mod_name] = module
    try:
        exec(code, module.__dict__)
    except BaseException:
        sys.modules.pop(mod_name, None)
        raise
    return module
