"""Package layering: the library (``mrd_env``) never imports the controllers or the experiments, and no module
switches matplotlib's backend (that would change the user's whole process)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _imports(path: Path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module


@pytest.mark.parametrize("path", sorted((ROOT / "mrd_env").rglob("*.py")), ids=lambda p: str(p.relative_to(ROOT)))
def test_library_does_not_import_controllers_or_experiments(path):
    bad = [m for m in _imports(path) if m.split(".")[0] in ("experiments", "controllers")]
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}"


@pytest.mark.parametrize("package", ["mrd_env", "controllers", "experiments"])
def test_no_module_switches_the_matplotlib_backend(package):
    for path in (ROOT / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "use" \
                    and isinstance(node.func.value, ast.Name) and node.func.value.id == "matplotlib":
                pytest.fail(f"{path.relative_to(ROOT)}:{node.lineno} calls matplotlib.use()")


def test_report_figures_leave_pyplot_alone(tmp_path):
    import matplotlib
    import matplotlib.pyplot as plt

    from mrd_env.rig import plot_loops, sinusoidal_test

    backend = matplotlib.get_backend()
    n_open = len(plt.get_fignums())
    path = plot_loops(sinusoidal_test("bingham", 0.01, 2.0, [0.0, 1.0], cycles=1), tmp_path / "loops.png")
    assert path.stat().st_size > 10_000
    assert matplotlib.get_backend() == backend and len(plt.get_fignums()) == n_open
