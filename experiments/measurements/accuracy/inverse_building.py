"""Clipped-optimal control of the three-storey building with each inverse model (a script, not a test).

    python -m experiments.measurements.accuracy.inverse_building [--out results/inverse/building] [--component NS EW] \\
        [--damper-floors 1]

For each inverse — the default on–off law (``inverse=None``, the benchmark's clipped-optimal row) and
``ClippedOptimal(env, inverse=name)`` with "heaviside", "sid", "model", "neural" — one El Centro episode of
``mrd_env/ShearBuildingPhysical-v0`` (the benchmark's scenario: the damper in storey 2, the record replayed at 0.2× time,
Spencer–Dyke prototype damper, the default sensors; ``--damper-floors 1`` puts the damper in storey 1, as the lab
building of Dyke et al. 1996 has it) gives the criteria J1–J6 (normalised by the uncontrolled building), the peak damper
force, how closely the damper force followed the LQR's desired force f_c (NRMSE and E_t of the achieved force
against f_c + F_static one control step later) and the mean wall time of ``predict`` per step.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import mrd_env  # noqa: F401  (registers the environments)
from controllers import ClippedOptimal
from mrd_env.identification.measures import error_time
from mrd_env.inverse import INVERSES, nrmse
from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode

from mrd_env.plants.shear_building.profile import PROFILE as BUILDING

SCENARIO = {"ground_motion": "el_centro", "ground_motion_params": {"time_scale": 0.2}}


def run_episode(inverse, component: str = "NS", seed: int = 0, damper_floors: tuple[int, ...] | None = None) -> dict:
    """One El Centro episode with clipped-optimal and ``inverse`` (the damper in ``damper_floors``, default the
    benchmark's); the row of the table."""
    params = {**SCENARIO["ground_motion_params"], "component": component}
    options = {**BUILDING.options, **({"damper_floors": tuple(damper_floors)} if damper_floors else {})}
    env = gym.make(BUILDING.env_id, **options, ground_motion="el_centro", ground_motion_params=params)
    ctrl = ClippedOptimal(env, inverse=inverse)
    base = env.unwrapped
    f_index = {n: sl for n, sl, *_ in base.sensor_layout}["damper_force"]
    obs, _ = env.reset(seed=seed)
    ctrl.reset()
    wanted, achieved = [], []
    spent = 0.0
    while True:
        t0 = time.perf_counter()
        action, _ = ctrl.predict(obs)
        spent += time.perf_counter() - t0
        obs, _, terminated, truncated, info = env.step(action)
        wanted.append(float(ctrl.last_desired[0, 0]) + base.F_static)  # f_c for the end of this step
        achieved.append(float(obs[f_index][0]))
        if terminated or truncated:
            break
    m = info["episode_metrics"]
    wanted, achieved = np.array(wanted), np.array(achieved)
    t = np.arange(wanted.size) * base.control_dt
    row = {"inverse": "on–off (default)" if inverse is None else inverse, "component": component,
           "damper floors": ",".join(str(f) for f in options["damper_floors"])}
    row.update({k: float(m[k]) for k in ("J1", "J2", "J3", "J4", "J5", "J6")})
    row.update({"damper_force_peak N": float(m["damper_force_peak"]), "f_c NRMSE %": 100 * nrmse(achieved, wanted),
                "f_c E_t %": 100 * error_time(wanted, achieved, t), "µs per predict": 1e6 * spent / wanted.size,
                "terminated": info.get("termination_reason", "") if terminated else ""})
    env.close()
    return row


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--component", nargs="+", default=["NS"], choices=("NS", "EW"))
    p.add_argument("--inverses", nargs="+", default=["default", *INVERSES])
    p.add_argument("--damper-floors", nargs="+", type=int, default=None, choices=(1, 2, 3),
                   help="storeys holding a damper (default: the benchmark's, storey 2)")
    p.add_argument("--out", type=Path, default=Path("results/inverse/building"))
    args = p.parse_args(argv)
    rows = []
    for comp in args.component:
        for name in args.inverses:
            rows.append(run_episode(None if name == "default" else name, comp, damper_floors=args.damper_floors))
            print(rows[-1], flush=True)
    md, _ = write_table(rows, args.out / "building_inverses", floatfmt=".4g",
                        title="three-storey building, El Centro (×0.2 time): clipped-optimal with each inverse")
    print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
