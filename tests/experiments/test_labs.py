"""The teaching labs (experiments/labs/): each runs end to end as a script, passes its instructor's checks (exit
code 0) and writes its figures, each a real plot; each is a jupytext percent notebook with the parts a lab needs."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
LABS = ROOT / "experiments" / "labs"

#: lab script → the figures it must write (relative to $MRD_LAB_OUT/<lab>/)
FIGURES = {
    "lab1_rig": ["loops_command.png", "figure5_parameters.png", "loops_frequency.png", "energy_per_cycle.png", "command_lag.png"],
    "lab2_identification": ["record.png", "model_comparison.png", "parameter_spread.png"],
    "lab3_quarter_car": ["tradeoff.png", "spectrum_wk.png"],
    "lab4_building": ["poles.png", "j_criteria.png"],
    "lab5_inverse": ["tracking.png", "mismatch.png"],
    "lab6_rl": ["agents/quarter_car_ppo_s0/learning_curve.png", "agent_vs_laws.png"],
    "lab7_benchmark": ["gain_captured.png", "leaderboard/leaderboard.png"],
}
#: lab script → checks its output must show passed (the ones that keep a lab honest)
REQUIRED_CHECKS = {
    "lab6_rl": ["[PASS] the lab's agent beats doing nothing: the agent started at skyhook scores above passive-off"],
    "lab7_benchmark": ["[PASS] no controller's mean share exceeds 1 (the clairvoyant knows the whole road)",
                       "[PASS] the leaderboard ranks the complete results in the order of their pooled shares, and shows "
                       "the smoke run apart, unranked"],
}
SECTIONS = ("Learning objectives", "Equations (recap", "## Task 1", "## Questions", "## Instructor's check")


def test_every_lab_file_is_listed():
    assert sorted(p.stem for p in LABS.glob("lab[0-9]*.py")) == sorted(FIGURES)


def assert_is_a_plot(path: Path) -> None:
    """A PNG of reasonable size that is not blank: enough non-white pixels and contrast to hold axes and data."""
    import matplotlib.image as mpimg

    assert path.exists(), f"missing figure {path}"
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] >= 250 and img.shape[1] >= 400, f"{path.name}: shape {img.shape}"
    gray = img[..., :3].mean(axis=2)
    ink = float(np.mean(gray < 0.9))
    assert 0.01 < ink < 0.9, f"{path.name}: {100 * ink:.1f} % non-white pixels"
    assert float(gray.std()) > 0.05, f"{path.name}: pixel std {gray.std():.3f}"
    colours = np.unique((img[..., :3].reshape(-1, 3) * 15).round(), axis=0)
    assert len(colours) >= 8, f"{path.name}: only {len(colours)} colours (a plot has lines in several colours)"


#: the labs whose end-to-end run is a long integration run (7-18 s each): the slow tier (docs/testing.md)
LONG_LABS = {"lab2_identification", "lab3_quarter_car", "lab5_inverse", "lab6_rl", "lab7_benchmark"}


@pytest.mark.parametrize("lab", [pytest.param(lab, marks=pytest.mark.slow) if lab in LONG_LABS else lab
                                 for lab in sorted(FIGURES)])
def test_lab_runs_end_to_end_and_writes_its_figures(lab, tmp_path):
    env = {**os.environ, "MRD_LAB_OUT": str(tmp_path), "MPLBACKEND": "Agg", "MRD_LAB_FULL": "",
           "MRD_LAB_RECORD": "", "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, str(LABS / f"{lab}.py")], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, f"{lab} failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}"
    assert "[FAIL]" not in proc.stdout
    assert re.search(r"(\d+)/\1 checks passed", proc.stdout), proc.stdout[-2000:]
    for check in REQUIRED_CHECKS.get(lab, []):
        assert check in proc.stdout, f"{lab}: no {check!r} in its output"
    for name in FIGURES[lab]:
        assert_is_a_plot(tmp_path / lab / name)


@pytest.mark.parametrize("lab", sorted(FIGURES))
def test_lab_is_a_percent_notebook_with_objectives_tasks_questions_and_checks(lab):
    text = (LABS / f"{lab}.py").read_text(encoding="utf-8")
    assert "format_name: percent" in text
    markdown = "\n".join(re.findall(r"# %% \[markdown\]\n((?:#.*\n)+)", text))
    for section in SECTIONS:
        assert section in markdown, f"{lab}: no {section!r} in its markdown cells"
    assert re.search(r"eqs?\. \(\d+", markdown), f"{lab}: the recap cites no equation of the review"
    assert text.count("lab.check(") >= 3 and text.rstrip().endswith("lab.finish()")


def test_lab_opens_as_a_notebook_through_jupytext():
    jupytext = pytest.importorskip("jupytext")
    for lab in FIGURES:
        nb = jupytext.read(LABS / f"{lab}.py")
        kinds = [c.cell_type for c in nb.cells]
        assert kinds.count("markdown") >= 5 and kinds.count("code") >= 4, (lab, kinds)
        assert nb.cells[0].cell_type == "markdown" and nb.cells[0].source.startswith("# Lab")


def test_a_failed_check_fails_the_lab(tmp_path):
    """A lab whose instructor's check fails exits non-zero, naming the check."""
    script = ("from experiments.labs.labkit import Lab\n"
              "lab = Lab('demo')\nlab.check('energy grows with command', False, '3 J then 2 J')\nlab.finish()\n")
    env = {**os.environ, "MRD_LAB_OUT": str(tmp_path),
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert "energy grows with command" in proc.stderr


def test_a_lab_executes_as_a_notebook(tmp_path, monkeypatch):
    """Lab 1 converted by jupytext and run cell by cell in a Jupyter kernel shows its figures under the cells
    (needs the labs extra and nbclient/ipykernel; skipped without them)."""
    jupytext = pytest.importorskip("jupytext")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    monkeypatch.setenv("MRD_LAB_OUT", str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    nb = jupytext.read(LABS / "lab1_rig.py")
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
                            ).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert sum("image/png" in o.get("data", {}) for o in outputs) == len(FIGURES["lab1_rig"])
    assert not [o for o in outputs if o.output_type == "error"]


def test_a_missing_record_ends_lab_2_with_one_line_and_figures_go_to_the_working_directory(tmp_path):
    """MRD_LAB_RECORD naming no file: one line on stderr, exit code 2, no traceback; and without MRD_LAB_OUT the
    lab's folder is made under the working directory's results/, never inside the installed package."""
    env = {k: v for k, v in os.environ.items() if k != "MRD_LAB_OUT"}
    env.update(MRD_LAB_RECORD="missing.csv", MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(LABS / "lab2_identification.py")], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == "lab2_identification: MRD_LAB_RECORD=missing.csv: no such readable file\n"
    assert (tmp_path / "results" / "labs" / "lab2_identification").is_dir()
