"""Caches that cannot be planted and cached results that cannot be edited (issue 36, items 3 and 4):
:mod:`mrd_env.caches`, the kernel cache of :mod:`mrd_env.stepping.codegen`, the compile log and ready markers of
:mod:`mrd_env.stepping.first_use`, and the digest of :mod:`mrd_env.optimal.cache`.

Every test points ``MRD_ENV_CACHE_DIR`` (and the temporary folder) at its own ``tmp_path``: the user's cache is
never touched, and the tests are independent of each other (pytest-xdist)."""
import json
import os
import stat
import sys
import tempfile
import warnings
from pathlib import Path

import pytest

from mrd_env import caches
from mrd_env.dampers import damper_class
from mrd_env.optimal import cache
from mrd_env.stepping import codegen, first_use

pytestmark = pytest.mark.hostile  # every case here is a hostile file (a count: pytest -m hostile)

VICTIM = "a file that is not the project's: it must keep this content\n"


@pytest.fixture
def home(tmp_path, monkeypatch):
    """A cache root and a temporary folder of the test's own; the fallback of earlier tests forgotten."""
    root = tmp_path / "cache"
    monkeypatch.setenv("MRD_ENV_CACHE_DIR", str(root))
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    monkeypatch.setattr(caches, "_LAST_RESORT", [])
    return root


def _victim(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text(VICTIM)
    return victim


def _private(folder) -> bool:
    st = os.lstat(folder)
    return (stat.S_ISDIR(st.st_mode) and st.st_uid == os.getuid()
            and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH))


def test_the_kernel_folder_is_created_private_under_the_cache_root(home):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a good folder: no warning
        d = codegen.kernel_dir()
    assert d == home / "kernels" and _private(d) and _private(home)
    assert stat.S_IMODE(os.lstat(d).st_mode) == 0o700


def test_a_group_writable_cache_folder_is_refused(home, tmp_path):
    home.mkdir()
    home.chmod(0o770)
    with pytest.warns(RuntimeWarning, match="writable by others"):
        d = codegen.kernel_dir()
    assert home not in d.parents and _private(d) and _private(d.parent)
    assert d.parent == tmp_path / "tmp" / f"mrd-env-{os.getuid()}"  # the per-user fallback, checked
    assert not (home / "kernels").exists()


def test_a_symlinked_cache_folder_is_refused(home, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir(mode=0o700)
    home.symlink_to(elsewhere, target_is_directory=True)
    with pytest.warns(RuntimeWarning, match="is a link"):
        d = codegen.kernel_dir()
    assert elsewhere not in d.parents and not (elsewhere / "kernels").exists()
    # a link at the kernel folder's own name is refused too
    home.unlink()
    home.mkdir(mode=0o700)
    (home / "kernels").symlink_to(elsewhere, target_is_directory=True)
    with pytest.warns(RuntimeWarning, match="is a link"):
        d = codegen.kernel_dir()
    assert d != home / "kernels" and not any(elsewhere.iterdir())


def _foreign(monkeypatch, *folders):
    """``os.lstat`` says ``folders`` belong to another user (what a folder another user created first looks like)."""
    real_lstat, other = os.lstat, os.getuid() + 4242
    foreign = {str(f) for f in folders}

    def lstat(path, *args, **kwargs):
        st = real_lstat(path, *args, **kwargs)
        if str(path) in foreign:
            st = os.stat_result((st.st_mode, st.st_ino, st.st_dev, st.st_nlink, other, st.st_gid, st.st_size,
                                 st.st_atime, st.st_mtime, st.st_ctime))
        return st

    monkeypatch.setattr(os, "lstat", lstat)


def test_a_foreign_owned_fallback_folder_is_refused(home, tmp_path, monkeypatch):
    """Another user created ``$TMPDIR/mrd-env-<uid>`` first, mode 0700 or not: it is not used; a new folder of
    unpredictable name, private, is. The cache root of another user is refused as well."""
    planted = tmp_path / "tmp" / f"mrd-env-{os.getuid()}"
    planted.mkdir(mode=0o700)
    home.mkdir(mode=0o700)
    _foreign(monkeypatch, planted, home)
    with pytest.warns(RuntimeWarning, match="belongs to user id") as record:
        d = codegen.kernel_dir()
    assert any(str(home) in str(w.message) for w in record) and any(str(planted) in str(w.message) for w in record)
    root = d.parent
    assert d.name == "kernels" and root.parent == tmp_path / "tmp" and root not in (planted, home)
    assert stat.S_IMODE(os.lstat(root).st_mode) == 0o700 and _private(d)
    assert not (home / "kernels").exists() and not (planted / "kernels").exists()
    assert caches.fallback_root() == root  # the same for the rest of the process (and its compiler)


def test_an_unwritable_cache_root_falls_back_quietly(home, tmp_path, monkeypatch):
    """A read-only home (simulated: no write access) is no attack: the per-user fallback, without a warning."""
    monkeypatch.setattr(caches, "_usable", lambda folder: tmp_path / "tmp" in folder.parents)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = codegen.kernel_dir()
    assert d == tmp_path / "tmp" / f"mrd-env-{os.getuid()}" / "kernels" and _private(d)


def test_a_planted_symlink_at_a_generated_modules_name_is_not_written_through(home, tmp_path):
    victim = _victim(tmp_path)
    cls = damper_class("spencer_dyke")
    source, key = codegen.kernel_source(cls)
    name = codegen.kernel_dir() / f"{codegen.kernel_prefix(cls)}_{key}.py"
    name.symlink_to(victim)
    path = codegen.write_generated_source(codegen.kernel_prefix(cls), source, key)
    assert path == name and not path.is_symlink() and path.read_text() == source
    assert victim.read_text() == VICTIM


def test_the_imported_module_is_the_checked_source_not_the_file_read_again(home, tmp_path, monkeypatch):
    """The race the issue names: the file is replaced between the content check and the import. What runs is the
    source the project generated, compiled from memory; the replacement runs nothing."""
    marker = tmp_path / "payload-ran"
    evil = f"import pathlib\npathlib.Path({str(marker)!r}).write_text('ran')\nX = 'evil'\n"
    real_write = codegen.write_generated_source

    def write_then_swap(prefix, source, key):
        path = real_write(prefix, source, key)
        path.write_text(evil)  # after the check, before the import
        return path

    monkeypatch.setattr(codegen, "write_generated_source", write_then_swap)
    prefix, key = "mrd_env_test_race", format(abs(hash(str(tmp_path))), "x")
    monkeypatch.delitem(sys.modules, f"{prefix}_{key}", raising=False)
    try:
        module = codegen.load_generated_module(prefix, "X = 'generated'\n", key)
        assert module.X == "generated" and not marker.exists()
        assert module.__file__ == str(codegen.kernel_dir() / f"{prefix}_{key}.py")  # numba's cache finds it
    finally:
        sys.modules.pop(f"{prefix}_{key}", None)


def _switching_kernel(monkeypatch, tmp_path):
    """A SwitchingKernel of the default model at its real path in the test's cache, its compiler process replaced
    by one that writes a line to the log it is given."""
    cls = damper_class("spencer_dyke")
    monkeypatch.setattr(cls, "python_functions", None)  # restored after the test
    source, key = codegen.kernel_source(cls)
    path = codegen.write_generated_source(codegen.kernel_prefix(cls), source, key)

    class FakeProcess:
        pid = 0
        returncode = 1

        def __init__(self, args, *, stdout, env, **kwargs):
            os.write(stdout, b"the compiler's output\n")
            self.env = env

        def poll(self):
            return 1

    monkeypatch.setattr(first_use.subprocess, "Popen", FakeProcess)
    return path, lambda: first_use.SwitchingKernel(cls, path, source, lambda: None)


def test_a_planted_symlink_at_the_compile_logs_name_is_not_written_through(home, tmp_path, monkeypatch):
    victim = _victim(tmp_path)
    path, make = _switching_kernel(monkeypatch, tmp_path)
    log = path.with_suffix(".log")
    log.symlink_to(victim)
    k = make()
    assert victim.read_text() == VICTIM
    assert not log.is_symlink() and log.read_text() == "the compiler's output\n"
    # the child compiles into the folder this process checked
    assert k._proc.env["MRD_ENV_CACHE_DIR"] == str(path.parent.parent)
    # a log replaced by a link later is not read through either (the failure warning names no other file)
    log.unlink()
    log.symlink_to(victim)
    k._next_check = 0.0
    k._switch = lambda late=False: None
    with pytest.warns(RuntimeWarning, match="exit code 1"):
        k._poll()


def test_a_planted_symlink_at_a_ready_markers_name_is_not_written_through(home, tmp_path):
    victim = _victim(tmp_path)
    cls = damper_class("spencer_dyke")
    path = codegen.kernel_path(cls)
    marker = first_use.ready_marker(path, "serial")
    marker.symlink_to(victim)
    first_use.mark_ready(path, "serial")
    assert victim.read_text() == VICTIM and not marker.is_symlink() and "compiled by process" in marker.read_text()


def test_the_optimal_cache_folder_is_private(home):
    assert cache.cache_dir() == home / "optimal" and _private(home / "optimal")


KEY = {"env_id": "mrd_env/QuarterCar-v1", "seed": 1, "damper_params": {"c0a": 1.0}}


def test_a_cached_result_round_trips_and_carries_its_digest(home):
    assert cache.load("clairvoyant", KEY) is None
    result = {"ret": -3.5, "commands": [0.0, 0.25, 1.0], "note": "α", "nan": float("nan")}
    path = cache.store("clairvoyant", KEY, result)
    loaded = cache.load("clairvoyant", KEY)
    assert loaded["ret"] == -3.5 and loaded["commands"] == [0.0, 0.25, 1.0] and loaded["note"] == "α"
    stored = json.loads(path.read_text())
    assert len(stored["digest"]) == 64 and stored["key"]["version"] == cache.VERSION
    assert [p.name for p in path.parent.iterdir()] == [path.name]  # no temporary file left behind


def test_a_cached_result_edited_in_its_file_is_refused_and_recomputed(home):
    """The defect the issue found: the result edited, the key kept, and the edited value was served."""
    path = cache.store("yardstick", KEY, {"clairvoyant": -3.5, "bound": -3.0})
    stored = json.loads(path.read_text())
    stored["result"]["clairvoyant"] = -0.1
    path.write_text(json.dumps(stored))
    assert cache.load("yardstick", KEY) is None
    # a file without a digest (as version 1 wrote them) is refused too
    del stored["digest"]
    path.write_text(json.dumps(stored))
    assert cache.load("yardstick", KEY) is None
    # the recomputed result is stored over it and served again
    cache.store("yardstick", KEY, {"clairvoyant": -3.5, "bound": -3.0})
    assert cache.load("yardstick", KEY) == {"clairvoyant": -3.5, "bound": -3.0}


def test_a_planted_symlink_at_a_cached_results_name_is_neither_read_nor_written_through(home, tmp_path):
    victim = _victim(tmp_path)
    path, _ = cache._path("clairvoyant", KEY)
    path.symlink_to(victim)
    assert cache.load("clairvoyant", KEY) is None
    assert cache.store("clairvoyant", KEY, {"ret": 1.0}) == path
    assert victim.read_text() == VICTIM and not path.is_symlink() and cache.load("clairvoyant", KEY) == {"ret": 1.0}


def test_the_kernel_cache_key_follows_every_import_of_the_models_code(tmp_path, monkeypatch):
    """Absolute, relative, ``import a.b`` and ``from pkg import module`` imports are all followed (transitively),
    so editing any module a damper model imports gives its kernel a new key (issue 38: only ``from .x import``
    lines were followed, and an absolute import left a stale kernel)."""
    from mrd_env.stepping import codegen

    pkg = tmp_path / "mrd_env"
    (pkg / "stepping").mkdir(parents=True)
    (pkg / "dampers").mkdir()
    files = {
        "dampers/model.py": "from mrd_env.dampers.absolute import f\nfrom .relative import g\n"
                            "import mrd_env.dampers.plain\nfrom .. import shared\nimport numpy as np\n",
        "dampers/absolute.py": "from .deeper import h\n", "dampers/deeper.py": "", "dampers/relative.py": "",
        "dampers/plain.py": "", "shared.py": "", "unrelated.py": "",
    }
    for name, text in files.items():
        (pkg / name).write_text(text)
    monkeypatch.setattr(codegen, "HERE", pkg / "stepping")
    monkeypatch.setattr(codegen.inspect, "getsourcefile", lambda cls: str(pkg / "dampers" / "model.py"))
    found = {str(p.relative_to(pkg)) for p in map(Path, codegen.model_modules(object))}
    assert found == set(files) - {"unrelated.py"}


# --- JAX's compilation cache (issue 48, item 11) ------------------------------------------------------------------
#: A process that compiles ``x + 1`` (and, with ``plant``, ``x * 100``) after importing mrd_env.jax, prints the
#: result of ``x + 1`` at 1.0 and, with ``plant``, the cache entries each compile wrote ({name: [new files]}).
#: ``swap``: the cache folder is replaced by a link to another folder after the import (what "checked only at
#: import" left open).
_JAX_PROCESS = r"""
import json, os, sys
from pathlib import Path
import mrd_env.jax, jax
from mrd_env import caches
folder = Path(os.environ["JAX_DIR"])
swap = os.environ.get("SWAP")
if swap:
    os.rename(folder, str(folder) + ".moved")
    os.symlink(swap, folder)
ls = lambda: set(os.listdir(folder)) if folder.is_dir() else set()
written = {}
before = ls()
plus = jax.jit(lambda x: x + 1.0)(1.0)
written["plus"] = sorted(ls() - before)
if os.environ.get("PLANT"):
    before = ls()
    jax.jit(lambda x: x * 100.0)(1.0)
    written["times"] = sorted(ls() - before)
print(json.dumps({"plus": float(plus), "written": written}))
"""


def _jax_run(env: dict) -> dict:
    import subprocess

    out = subprocess.run([sys.executable, "-c", _JAX_PROCESS], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "JAX_PLATFORMS": "cpu", **env})
    assert out.returncode == 0, out.stderr[-3000:]
    return {**json.loads(out.stdout.strip().splitlines()[-1]), "stderr": out.stderr}


def _plant_times_100_as_plus_1(folder: Path, env: dict) -> None:
    """The attacker's part: compile ``x + 1`` and ``x * 100`` with the victim's settings, then put the second
    program's entry under the first one's name (JAX's keys hash the computation; the content is not checked)."""
    made = _jax_run({**env, "PLANT": "1", "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0"})
    assert made["plus"] == 2.0
    plus = [f for f in made["written"]["plus"] if f.endswith("-cache")]
    times = [f for f in made["written"]["times"] if f.endswith("-cache")]
    assert len(plus) == len(times) == 1, made["written"]
    (folder / plus[0]).write_bytes((folder / times[0]).read_bytes())


@pytest.mark.hostile
def test_a_planted_jax_program_is_never_run_by_default(home, tmp_path):
    """By default mrd_env.jax keeps compiled programs in memory only: an entry planted in ``<cache>/jax`` under the
    key of ``x + 1`` (the compiled ``x * 100``) is not read, and nothing is written there (before: 100.0)."""
    pytest.importorskip("jax")
    folder = home / "jax"
    folder.mkdir(parents=True, mode=0o700)
    home.chmod(0o700)
    # the planter uses the folder as the old default did (a cache directory JAX reads and writes)
    _plant_times_100_as_plus_1(folder, {"MRD_ENV_CACHE_DIR": str(home), "JAX_DIR": str(folder),
                                        "JAX_COMPILATION_CACHE_DIR": str(folder)})
    planted = sorted(os.listdir(folder))
    run = _jax_run({"MRD_ENV_CACHE_DIR": str(home), "JAX_DIR": str(folder), "MRD_ENV_JAX_CACHE": ""})
    assert run["plus"] == 2.0
    assert sorted(os.listdir(folder)) == planted  # nothing read (no access time written) nor written


@pytest.mark.hostile
def test_an_opted_in_jax_cache_is_checked_at_every_use_not_only_at_import(home, tmp_path):
    """``MRD_ENV_JAX_CACHE=1``: programs persist in the private ``<cache>/jax`` (a second process finds the first
    one's entry), and a folder swapped for a link to a folder holding a planted entry after the import is refused
    at the next compile, with a warning: the planted program does not run."""
    pytest.importorskip("jax")
    folder = home / "jax"
    env = {"MRD_ENV_CACHE_DIR": str(home), "JAX_DIR": str(folder), "MRD_ENV_JAX_CACHE": "1"}
    _plant_times_100_as_plus_1(folder, env)  # the cache works: each program wrote its entry
    assert _private(folder) and stat.S_IMODE(os.lstat(folder).st_mode) == 0o700
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir(mode=0o700)
    for f in os.listdir(folder):  # the attacker's copy of the planted folder
        (elsewhere / f).write_bytes((folder / f).read_bytes())
    run = _jax_run({**env, "SWAP": str(elsewhere)})
    assert run["plus"] == 2.0
    assert "is a link" in run["stderr"] and "neither read from nor written to" in run["stderr"]


@pytest.mark.hostile
def test_an_opted_in_jax_cache_reads_no_entry_through_a_symlink(home, tmp_path):
    """An entry that is a symlink (to a file outside the folder) is not read: JAX compiles again."""
    pytest.importorskip("jax")
    from mrd_env.jax import CheckedCache

    folder = home / "jax"
    folder.mkdir(parents=True, mode=0o700)
    home.chmod(0o700)
    outside = _victim(tmp_path)
    (folder / "jit_f-0123-cache").symlink_to(outside)
    cache_ = CheckedCache(folder, root=home)
    assert cache_.get("jit_f-0123") is None and cache_.get("../victim") is None
    cache_.put("jit_f-0123", b"program")
    assert outside.read_text() == VICTIM and cache_.get("jit_f-0123") == b"program"
    folder.chmod(0o777)
    with pytest.warns(RuntimeWarning, match="writable by others"):
        assert cache_.get("jit_f-0123") is None
