"""The C++ engine plugin against the numba pass it replaced, alternating in one process.

Run: python benchmarks/engine_vs_numba.py [--rounds 7]
For each scene (the rigs, the standing hexapod, the wheel, the deforming ground at 5 and 2 mm)
one round steps the same number of steps from the same keyframe three ways: a plain mj_step
without the field, the numba field installed (mjrft.field.numba_field), and the model carrying
the plugin; rounds alternate the three so that load on the machine hits them alike. Prints the
median microseconds per step of each, the ratio engine / numba and the trajectories' largest
difference (0: bit for bit). Writes benchmarks/results/engine_vs_numba.csv.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np

from mjrft.app.simulate import models_dir, reset_data
from mjrft.envs import hexapod_sand
from mjrft.field import plugin
from mjrft.field.numba_field import GranularField as NumbaField
from mjrft.field.numba_field import load_plain

OUT = Path(__file__).resolve().parent / "results" / "engine_vs_numba.csv"
#: name -> (model file, steps per round, scene options)
SCENES = {
    "ellipsoid_pitch": ("ellipsoid_pitch", 2000, {}),
    "plate_rig": ("plate_rig", 2000, {}),
    "root_circumnutation": ("root_circumnutation", 1000, {}),
    "sphere_drop": ("sphere_drop", 1000, {}),
    "hexapod_standing": ("hexapod_sand", 2000, {}),
    "wheel_rig": ("wheel_rig", 1000, {}),
    "hexapod_deforming_5mm": ("hexapod_sand", 1000, {"deform_cell": 0.005}),
    "hexapod_deforming_2mm": ("hexapod_sand", 500, {"deform_cell": 0.002}),
    "wheel_deforming_5mm": ("wheel_rig", 500, {"deform_cell": 0.005}),
}


def _run(model, steps, field=None) -> tuple[float, np.ndarray]:
    data = reset_data(model, 0)
    t0 = time.perf_counter()
    if field is None:
        for _ in range(steps):
            mujoco.mj_step(model, data)
    else:
        with field.installed():
            for _ in range(steps):
                mujoco.mj_step(model, data)
    wall = time.perf_counter() - t0
    return wall / steps * 1e6, np.concatenate([data.qpos, data.qvel])


def _spec(file: str, options: dict) -> mujoco.MjSpec:
    spec = mujoco.MjSpec.from_file(str(models_dir() / f"{file}.xml"))
    if options.get("deform_cell") and file == "hexapod_sand":  # the walking lane's region
        spec.add_numeric(name="mjrft:region", data=list(hexapod_sand.DEFORM_REGION))
    return spec


def scene(name: str, rounds: int) -> dict:
    file, steps, options = SCENES[name]
    plain = load_plain(_spec(file, {}))
    numba_model = load_plain(_spec(file, options), **options)
    numba_field = NumbaField(numba_model)
    engine_model = plugin.load_model(_spec(file, options), **options)
    times = {"plain": [], "numba": [], "engine": []}
    _run(numba_model, 10, numba_field)  # load the compiled code
    diff = 0.0
    for _ in range(rounds):
        times["plain"].append(_run(plain, steps)[0])
        t_numba, s_numba = _run(numba_model, steps, numba_field)
        t_engine, s_engine = _run(engine_model, steps)
        times["numba"].append(t_numba)
        times["engine"].append(t_engine)
        diff = max(diff, float(np.max(np.abs(s_numba - s_engine))))
    med = {k: statistics.median(v) for k, v in times.items()}
    return {
        "scene": name, "steps": steps, "plain_us": med["plain"], "numba_us": med["numba"],
        "engine_us": med["engine"], "engine_over_numba": med["engine"] / med["numba"],
        "max_state_diff": diff,
    }  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    args = ap.parse_args()
    rows = []
    print(f"{'scene':24s} {'plain us':>9s} {'numba us':>9s} {'engine us':>9s} "
          f"{'engine/numba':>12s} {'max diff':>9s}")  # fmt: skip
    for name in args.scenes:
        r = scene(name, args.rounds)
        rows.append(r)
        print(f"{name:24s} {r['plain_us']:9.1f} {r['numba_us']:9.1f} {r['engine_us']:9.1f} "
              f"{r['engine_over_numba']:12.2f} {r['max_state_diff']:9.1e}", flush=True)  # fmt: skip
    OUT.parent.mkdir(exist_ok=True)
    with OUT.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
