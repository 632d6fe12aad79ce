"""No plant is named below its folder (issue 38): the code of ``mrd_env/`` outside ``mrd_env/plants/``, of
``controllers/`` and of ``experiments/`` reaches a plant through its spec or profile (resolved once per command
from ``--plant``), never by writing its name, and never branches on a plant's kind. The names come from the
registry (:func:`mrd_env.plants.plants`, former names included), so a new plant is covered as soon as it is
registered."""
from __future__ import annotations

import ast
from pathlib import Path

from mrd_env.plants import plants

ROOT = Path(__file__).resolve().parents[1]
#: The scanned folders, and the one inside them where the plants are declared.
SCANNED = ("mrd_env", "controllers", "experiments")
PLANT_FOLDERS = ROOT / "mrd_env" / "plants"
#: Names that hold a plant's kind: a comparison of one with a string literal is a branch on the plant.
KIND_NAMES = ("plant_kind",)
#: Objects whose ``.kind`` is the plant's kind (an environment's assembly).
KIND_OWNERS = ("assembly", "asm")


def plant_names() -> set[str]:
    """Every registered plant's name and former names."""
    return {n for spec in plants().values() for n in (spec.name, *spec.former_names)}


def sources() -> list[Path]:
    """The scanned ``.py`` files."""
    return [path for top in SCANNED for path in sorted((ROOT / top).rglob("*.py"))
            if PLANT_FOLDERS not in path.parents]


def _identifier(node: ast.AST) -> str:
    return node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else ""


def _is_kind(node: ast.AST) -> bool:
    """``plant_kind`` (a name or an attribute) or ``<assembly>.kind``."""
    if _identifier(node) in KIND_NAMES:
        return True
    return isinstance(node, ast.Attribute) and node.attr == "kind" and _identifier(node.value) in KIND_OWNERS


def _is_text(node: ast.AST) -> bool:
    """A string literal, or a tuple, list or set of them."""
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return bool(node.elts) and all(_is_text(e) for e in node.elts)
    return isinstance(node, ast.Constant) and isinstance(node.value, str)


def offences(path: Path, names: set[str]) -> list[str]:
    """``file:line: what`` for every plant name written in ``path`` and every branch on a plant's kind."""
    where = path.relative_to(ROOT) if ROOT in path.parents else path
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names:
            found.append((node.lineno, f"the plant name {node.value!r}"))
        elif isinstance(node, ast.Compare):
            operands = [node.left, *node.comparators]
            if any(_is_kind(o) for o in operands) and any(_is_text(o) for o in operands):
                found.append((node.lineno, f"a branch on a plant's kind ({ast.unparse(node)})"))
    return [f"{where}:{line}: {what}" for line, what in sorted(found)]


def test_no_plant_is_named_outside_the_plant_folders():
    names = plant_names()
    found = [line for path in sources() for line in offences(path, names)]
    assert not found, ("plants named outside mrd_env/plants/ (take the plant's profile or spec, resolved once by the "
                       "command, instead):\n" + "\n".join(found))


def test_the_scan_finds_a_plant_name_and_a_branch_on_a_kind(tmp_path):
    """The scan itself: a name in any spelling the registry knows, and a kind compared with a literal."""
    names = plant_names()
    former = next(n for spec in plants().values() for n in spec.former_names)
    sample = tmp_path / "sample.py"
    sample.write_text(f"a = {next(iter(plants()))!r}\n"
                      f"b = {{{former!r}: 1}}\n"
                      "if env.unwrapped.plant_kind == 'whatever':\n    pass\n"
                      "ok = base.assembly.kind in ('x', 'y') or fault.kind == 'spike'\n", encoding="utf-8")
    assert [line.split(":")[1] for line in offences(sample, names)] == ["1", "2", "3", "5"]
