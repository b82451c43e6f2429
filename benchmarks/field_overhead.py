"""Field overhead: mj_step of a model with the engine plugin vs a plain mj_step of the same MJCF.

Run: python benchmarks/field_overhead.py [--triangles N]
1. models/ellipsoid_pitch.xml with the ellipsoid at N triangles (default 2000), at three states:
   lifted clear of the medium (every intruder above the surface), tip in (t = 1 s) and deep
   (t = 10 s); medians over 15 repeats of 2000 steps, plain (the MJCF compiled without the
   plugin) and field alternating; the ratio is the median of the back-to-back pairs' ratios.
2. Real-time factor of each rig at dt = 1 ms (simulated s per wall s, with the field, no
   recording).
3. Evaluated and acting fractions over each rig's run: triangles handed to the kernel (geoms not
   culled by their bounding sphere) and triangles that felt a force, per field evaluation,
   relative to all triangles.
Writes benchmarks/results/field_overhead.csv and field_fractions.csv.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import mujoco
import numpy as np

from mjrft import simulate
from mjrft.field import GranularField

OUT = Path(__file__).resolve().parent / "results"
MODELS = Path(__file__).resolve().parents[1] / "models"
RIG_DURATIONS = {
    "plate_rig": 3.0,
    "ellipsoid_pitch": 12.0,
    "root_circumnutation": 24.0,
    "sphere_drop": 2.0,
}


def state_at(model, t, lift=0.0) -> mujoco.MjData:
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, 0)
    while d.time < t:
        mujoco.mj_step(model, d)
    # The slider's integrated-velocity servo keeps its target position in act: lift both.
    d.qpos[model.joint("descent").qposadr[0]] += lift
    d.act[model.actuator("descent").actadr[0]] += lift
    mujoco.mj_forward(model, d)
    return d


def clone(model, d) -> mujoco.MjData:
    e = mujoco.MjData(model)
    e.qpos[:], e.qvel[:], e.act[:], e.ctrl[:] = d.qpos, d.qvel, d.act, d.ctrl
    e.time = d.time
    return e


def _run(model, d0, n) -> tuple[float, mujoco.MjData]:
    """Seconds per mj_step over n steps of model from state d0, and the MjData stepped."""
    d = clone(model, d0)
    mujoco.mj_step(model, d)  # one untimed step, as for a model that has just been made
    t0 = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(model, d)
    return (time.perf_counter() - t0) / n, d


def time_pairs(plain_model, model, fld, d0, n=2000, repeats=15):
    """Median s per mj_step of plain_model (no plugin) and of model (the plugin's), the median
    ratio of the pairs, and fld's work counters summed over the field runs (``stats_of``).

    Plain and field runs alternate, and each ratio is taken within a pair measured back to back,
    so that a slow spell of this shared machine lands on both sides of a ratio.
    """
    plain, field, ratio = [], [], []
    stats = dict.fromkeys(("calls", "evaluated", "acting"), 0)
    for _ in range(repeats):
        p, _ = _run(plain_model, d0, n)
        f, d = _run(model, d0, n)
        plain.append(p)
        field.append(f)
        ratio.append(f / p)
        for k, v in fld.stats_of(d).items():
            if k in stats:
                stats[k] += v
    return float(np.median(plain)), float(np.median(field)), float(np.median(ratio)), stats


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=2000)
    args = ap.parse_args()
    OUT.mkdir(exist_ok=True)
    model = simulate.load_model(MODELS / "ellipsoid_pitch.xml", n_triangles=args.triangles)
    plain_model = mujoco.MjModel.from_xml_path(str(MODELS / "ellipsoid_pitch.xml"))
    fld = GranularField(model)
    print(f"ellipsoid_pitch.xml, {fld.n_elements} triangles on the ellipsoid, dt = 1 ms, Euler")
    rows = []
    for label, t, lift in (("lifted clear", 0.0, 0.05), ("tip in (t=1 s)", 1.0, 0.0),
                           ("deep (t=10 s)", 10.0, 0.0)):  # fmt: skip
        d0 = state_at(model, t, lift)
        plain, with_field, ratio, s = time_pairs(plain_model, model, fld, d0)
        calls = max(1, s["calls"])
        rows.append(
            {
                "state": label,
                "plain_us": 1e6 * plain,
                "field_us": 1e6 * with_field,
                "ratio": ratio,
                "acting_fraction": s["acting"] / calls / fld.n_elements,
                "evaluated_fraction": s["evaluated"] / calls / fld.n_elements,
            }
        )
        r = rows[-1]
        print(
            f"  {label:16s} plain {r['plain_us']:6.1f} us  field {r['field_us']:7.1f} us  "
            f"ratio {r['ratio']:5.2f}  evaluated {r['evaluated_fraction']:.2f}  "
            f"acting {r['acting_fraction']:.2f}"
        )
    with open(OUT / "field_overhead.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)

    print("rig runs (with the field, default triangles, no recording):")
    frows = []
    for name, duration in RIG_DURATIONS.items():
        m = simulate.load_model(MODELS / f"{name}.xml")
        f = GranularField(m)
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        n = round(duration / m.opt.timestep)
        mujoco.mj_step(m, d)
        t0 = time.perf_counter()
        for _ in range(n):
            mujoco.mj_step(m, d)
        wall = time.perf_counter() - t0
        s = f.stats_of(d)
        frows.append(
            {
                "rig": name,
                "triangles": f.n_elements,
                "sim_s": duration,
                "wall_s": wall,
                "real_time_factor": duration / wall,
                "evaluated_fraction": s["evaluated"] / s["calls"] / f.n_elements,
                "acting_fraction": s["acting"] / s["calls"] / f.n_elements,
            }
        )
        r = frows[-1]
        print(
            f"  {name:20s} {r['triangles']:5d} triangles: {r['real_time_factor']:5.2f}x real time; "
            f"evaluated {r['evaluated_fraction']:.2f}, acting {r['acting_fraction']:.2f} of "
            "triangles per evaluation"
        )
    with open(OUT / "field_fractions.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(frows[0]))
        w.writeheader()
        w.writerows(frows)


if __name__ == "__main__":
    main()
