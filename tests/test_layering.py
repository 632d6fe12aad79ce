"""Package layering: the library (``mrd_env``) never imports the controllers or the experiments, no package has an
import circle (imports inside functions count: a lazy import only hides a circle), the stepping package imports nothing
above it, and no module switches matplotlib's backend (that would change the user's whole process)."""
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


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(package: str = "mrd_env") -> dict[str, set[str]]:
    """{module: the modules of ``package`` it imports anywhere in its file}; ``from .pkg import name`` points at
    the submodule pkg.name if there is one, else at pkg (its ``__init__``)."""
    files = {_module_name(p): p for p in (ROOT / package).rglob("*.py")}
    graph = {}
    for name, path in files.items():
        base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                mod = node.module or ""
                if node.level:
                    mod = ".".join(base[:len(base) - node.level + 1] + ([mod] if mod else []))
                # a package's own attributes (``from . import __path__``) are no dependency
                targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in files else mod for a in node.names
                           if not (a.name.startswith("__") and a.name.endswith("__"))]
            else:
                continue
            edges.update(t for t in targets if t in files and t != name)
        graph[name] = edges
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = set()
                    while True:
                        x = stack.pop()
                        on_stack.discard(x)
                        comp.add(x)
                        if x == v:
                            break
                    if len(comp) > 1:
                        out.append(comp)
            elif w not in index:
                index[w] = low[w] = len(index)
                stack.append(w)
                on_stack.add(w)
                work.append((w, iter(sorted(graph[w]))))
            elif w in on_stack:
                low[v] = min(low[v], index[w])
    return out


def test_import_cycles_are_found():
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]
    assert import_cycles({"a": {"b"}, "b": set()}) == []


@pytest.mark.parametrize("package", ["mrd_env", "controllers", "experiments"])
def test_no_import_circle(package):
    cycles = import_cycles(import_graph(package))
    assert not cycles, f"import circles in {package}: {[sorted(c) for c in cycles]}"


def test_stepping_imports_nothing_above_it():
    """The stepping routine sits under the plants, environments, rig and identification: it may use only the
    modules below it."""
    below = {"mrd_env.command_lag", "mrd_env.validation", "mrd_env.errors",
             "mrd_env.storage", "mrd_env.caches"}  # files and cache folders: they import nothing of the project's
    graph = import_graph()
    for name, edges in graph.items():
        if name.startswith("mrd_env.stepping"):
            bad = {e for e in edges if not e.startswith("mrd_env.stepping") and e not in below}
            assert not bad, f"{name} imports {sorted(bad)}"


def test_experiments_in_four_parts_import_downwards_only():
    """experiments/: ``common`` (what the commands, scripts and labs share) imports no command, script or lab; a
    command imports no other command, script or lab (each verb stands alone on the shared part)."""
    graph = import_graph("experiments")
    assert {"experiments.common.evaluation", "experiments.commands.benchmark"} <= set(graph)  # the parts are seen
    for name, edges in graph.items():
        part = name.split(".")[1] if name.count(".") else ""
        if part == "common":
            bad = {e for e in edges if e.split(".")[1:2] and e.split(".")[1] in ("commands", "scripts", "labs")}
        elif part == "commands":
            bad = {e for e in edges if e.startswith(("experiments.scripts", "experiments.labs"))
                   or (e.startswith("experiments.commands.") and e != name)}
        else:
            continue
        assert not bad, f"{name} imports {sorted(bad)}"


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


def test_the_generic_machinery_knows_no_plant():
    """The plants (``mrd_env/plants/<plant>/``, one folder each) sit above the generic machinery — the environment
    core, the mechanics, the dampers, the disturbances, the metrics, the optimal-control and inverse packages: none
    of those imports a plant, so a plant is added by its folder and one registry line, never by an edit below it.
    Only the package's face (``mrd_env/__init__``, which registers the plants) and the warm-up script, which
    steps a registered id, are above the plants (the suites' format is below them: the plants' suite definitions
    use it, and it finds the shipped files by path)."""
    above = {"mrd_env", "mrd_env.warmup"}
    graph = import_graph()
    assert "mrd_env.plants.quarter_car.env" in graph  # the plants are seen
    for name, edges in graph.items():
        if name.startswith("mrd_env.plants") or name in above:
            continue
        bad = {e for e in edges if e.startswith("mrd_env.plants")}
        assert not bad, f"{name} imports {sorted(bad)}: the generic machinery must not know a plant"
