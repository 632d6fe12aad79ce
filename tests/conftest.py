import os
import shutil
import tempfile

os.environ.setdefault("MPLBACKEND", "Agg")
# the suite compiles in its own processes (no background compilers, no interpreted steps where tests time or
# count); tests/stepping/test_first_use.py switches the interpreted first use on where it tests it
os.environ.setdefault("MRD_ENV_FIRST_USE", "wait")
# the test workers share JAX's compiled programs through the private, checked cache (mrd_env.jax: not persisted
# unless asked, since JAX does not authenticate its entries); tests/test_cache_security.py sets its own value
os.environ.setdefault("MRD_ENV_JAX_CACHE", "1")
# torch is imported by some test modules at collection: the once-per-process TorchThreadsWarning (for users calling
# SB3 themselves) would land in whichever test makes the worker's first environment; tests/envs/test_sb3_direct.py
# checks the warning in subprocesses without this
os.environ.setdefault("MRD_ENV_TORCH_THREADS_WARNING", "0")
# SB3 makes an empty SB3-<time> folder in the system's temporary folder for every learn() without a log folder (the
# docs' recipes and the speed scripts call it so): the suite's, its workers' and their subprocesses' go into one
# folder, removed at the end
_SB3_LOGDIR = None
if "SB3_LOGDIR" not in os.environ:
    _SB3_LOGDIR = os.environ["SB3_LOGDIR"] = tempfile.mkdtemp(prefix="mrd_env_tests_sb3_")


def pytest_unconfigure(config):
    if _SB3_LOGDIR is not None:
        shutil.rmtree(_SB3_LOGDIR, ignore_errors=True)


def pytest_collection_modifyitems(config, items):
    """With ``--dist loadgroup`` (pytest-xdist), the tests parametrised by a damper model other than the default
    run on one worker per model: a model's kernel is compiled by one process only, not by two at once."""
    import pytest

    from mrd_env.dampers import available_dampers

    models = set(available_dampers()) - {"spencer_dyke"}  # the default model: every worker compiles it anyway
    for item in items:
        params = getattr(getattr(item, "callspec", None), "params", {})
        model = next((v for v in params.values() if isinstance(v, str) and v in models), None)
        if model is not None:
            item.add_marker(pytest.mark.xdist_group(model))
