"""The device benchmark (``experiments.measurements.speed.device``, issue 52, item 4) in its smoke mode: it runs on
the machine's own backend at a tiny N, leaves out a size its memory estimate refuses (with the reason), and
writes the JSON and Markdown with the device, the host and each figure."""
from __future__ import annotations

import json

import pytest

jax = pytest.importorskip("jax")

pytestmark = pytest.mark.xdist_group("jax")


def test_quick_run_records_the_device_and_each_size(tmp_path, monkeypatch):
    from experiments.measurements.speed import device
    from mrd_env.jax import env as je

    env_id, options = device.PLANTS[device.QUICK["plants"]]
    asm = je.assembly_of(env_id, options)[0]
    small = je.check_bank(asm, seeds=range(device.BANK), num_envs=8)
    big = je.check_bank(asm, seeds=range(device.BANK), num_envs=1 << 20)
    monkeypatch.setenv("MRD_ENV_MEMORY_LIMIT", str(int((small + big) / 2)))  # N = 8 fits, N = 2^20 does not
    out = tmp_path / "device.json"
    assert device.main(["--quick", "--parts", "speed", "--n", f"8,{1 << 20}", "--out", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["device"]["backend"] == jax.default_backend()
    assert d["device"]["devices"] == [str(x) for x in jax.devices()]
    assert d["device"]["cpus"] >= 1 and isinstance(d["load_start"], float) and isinstance(d["load_end"], float)
    assert d["options"]["quick"] and d["clairvoyant"] is None
    ran, refused = d["speed"]
    assert (ran["plant"], ran["scheme"], ran["N"], ran["steps"]) == (device.QUICK["plants"], "differentiable", 8, 5)
    assert ran["env_steps_per_s"] > 0 and ran["compile_s"] > 0 and "skipped" not in ran
    assert refused["N"] == 1 << 20 and "MRD_ENV_MEMORY_LIMIT" in refused["skipped"]
    md = out.with_suffix(".md").read_text()
    assert "env-steps/s" in md and jax.devices()[0].device_kind in md and device.QUICK["plants"] in md


@pytest.mark.parametrize("args, names", [(["--plants", "nope"], "--plants"), (["--n", "0"], "--n"),
                                         (["--parts", "x"], "--parts"), (["--out", "a.txt"], "--out")])
def test_bad_option_is_one_line_and_exit_2(args, names, capsys):
    from experiments.measurements.speed import device

    with pytest.raises(SystemExit) as exc:
        device.main(args)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert names in err and len(err.splitlines()) == 1 and "Traceback" not in err
