"""Cost of the deforming ground against the same scene on pristine ground, back to back.

Run: python benchmarks/deform_cost.py [--scenes hexapod go2 wheel] [--seconds 10]
         [--cells 0.005 0.002] [--every 1 10] [--frozen] [--repeats 3]
Scenes: ``hexapod`` (hexapod_sand, the 1 Hz alternating tripod), ``go2`` (models/go2_sand.xml
from its home keyframe, ``go2_sand.trot_ctrl``'s open-loop trot) and ``wheel``
(models/wheel_rig.xml at slip 0.3, one 15 cm pass, 1500 triangles), each on the pristine surface
and on deforming ground per cell [m] and per mjrft:deform_every; ``--frozen`` adds, per cell,
ground that follows the intruders only at its first update (deform_every 1e8: the force pass
looks the grid up at every step, nothing else changes). The cases of a scene run interleaved,
repeat by repeat, so a busy machine slows them alike; medians of the wall time, its ratio to
the pristine run, and the ground's counters: volume drift relative to the volume cut, the share
of updates whose relaxation met its work budget, pair visits per update. Writes
benchmarks/results/deform_cost.csv.
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np

OUT = Path(__file__).resolve().parent / "results" / "deform_cost.csv"
#: Default cells [m] per scene: the hexapod's documented 5 and 2 mm, the Go2's 5 and 2.5 mm,
#: the wheel's 5 mm (benchmarks/wheel_slip.py).
CELLS = {"hexapod": (0.005, 0.002), "go2": (0.005, 0.0025), "wheel": (0.005,)}
FROZEN = 10**8  # deform_every that never updates again after the first update
#: The Go2's medium [m] (xmin ymin zmin xmax ymax zmax): its feet rest 70-110 mm deep on
#: deforming ground, and its open-loop trot stays within 0.6 m of its start.
GO2_REGION = [-0.6, -0.6, -0.25, 0.6, 0.6, 0.05]
WHEEL_SLIP, WHEEL_LENGTH, WHEEL_TRIANGLES = 0.3, 0.15, 1500


def _counters(field, data) -> dict:
    """The ground's counters as benchmark columns."""
    soil = field.soil(data)
    c = soil.counters
    return {"volume_drift": abs(soil.volume()) / c["excavated"] if c["excavated"] else 0.0,
            "unrelaxed_share": c["unrelaxed"] / max(c["updates"], 1.0),
            "visits_per_update": c["visits"] / max(c["updates"], 1.0)}  # fmt: skip


def hexapod(cell: float | None, every: int, seconds: float) -> dict:
    """The hexapod's tripod walk for seconds [s] of simulated time."""
    from mjrft.envs import hexapod_sand

    env = hexapod_sand.make(seed=0, time_limit=math.inf, deform_cell=cell,
                            deform_every=every if cell else None)  # fmt: skip
    try:
        env.reset()
        action = np.array([1.0, math.pi])
        n = round(seconds / env.control_timestep())
        t0 = time.perf_counter()
        for _ in range(n):
            env.step(action)
        row = {"wall_s": time.perf_counter() - t0, "x_m": float(env.physics.data.qpos[0])}
        if cell:
            row.update(_counters(env.physics.field, env.physics.data.ptr))
        return row
    finally:
        env.close()


def go2(cell: float | None, every: int, seconds: float) -> dict:
    """The Go2's open-loop trot from its home keyframe for seconds [s] of simulated time."""
    from mjrft.envs import go2_sand

    import mjrft

    options = mjrft.SceneOptions(deform_cell=cell, deform_every=every if cell else None)
    spec = go2_sand.build_spec()
    spec.add_numeric(name="mjrft:region", data=GO2_REGION)  # both cases, the same scene
    model = mjrft.load_model(spec, options)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    substeps = round(0.02 / model.opt.timestep)
    t0 = time.perf_counter()
    for _ in range(round(seconds / 0.02)):
        data.ctrl[:] = go2_sand.trot_ctrl(data.time)
        mujoco.mj_step(model, data, substeps)
    row = {"wall_s": time.perf_counter() - t0, "x_m": float(data.qpos[0])}
    if cell:
        row.update(_counters(mjrft.GranularField(model), data))
    return row


def wheel(cell: float | None, every: int, seconds: float) -> dict:
    """One pass of the wheel rig (its length, not seconds, sets the duration)."""
    from mjrft.app import wheel as rig

    if every != 1:
        raise ValueError("the wheel rig updates its ground at every step (--every 1)")
    t0 = time.perf_counter()
    p = rig.run(WHEEL_SLIP, deform_cell=cell or 0.0, length=WHEEL_LENGTH,
                n_triangles=WHEEL_TRIANGLES)[0]  # fmt: skip
    return {"wall_s": time.perf_counter() - t0, "x_m": p.sinkage}


SCENES = {"hexapod": hexapod, "go2": go2, "wheel": wheel}


def cases(scene: str, cells: list[float] | None, everys: list[int], frozen: bool) -> list:
    """(cell or None for pristine, deform_every) of one scene."""
    out = [(None, 1)]
    for cell in cells or CELLS[scene]:
        out += [(cell, e) for e in (everys if scene != "wheel" else [1])]
        if frozen and scene != "wheel":
            out.append((cell, FROZEN))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", choices=sorted(SCENES), default=sorted(SCENES))
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated time per walk [s]")
    ap.add_argument("--cells", type=float, nargs="+", help="cells [m] (default: per scene)")
    ap.add_argument("--every", type=int, nargs="+", default=[1], help="mjrft:deform_every")
    ap.add_argument("--frozen", action="store_true", help="add never-updated ground per cell")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    rows = []
    for scene in args.scenes:
        todo = cases(scene, args.cells, args.every, args.frozen)
        runs = {c: [] for c in todo}
        for _ in range(args.repeats):
            for cell, every in todo:
                runs[(cell, every)].append(SCENES[scene](cell, every, args.seconds))
        base = statistics.median(r["wall_s"] for r in runs[todo[0]])
        for (cell, every), rs in runs.items():
            wall = statistics.median(r["wall_s"] for r in rs)
            row = {"scene": scene, "cell_m": cell or 0.0, "every": every, **rs[0],
                   "wall_s": wall, "vs_pristine": wall / base}  # fmt: skip
            rows.append(row)
            label = "pristine" if cell is None else f"{cell * 1e3:g} mm, every {every}"
            extra = (f", drift {row['volume_drift']:.1e}, budget met at "
                     f"{row['unrelaxed_share']:.1%} of updates, "
                     f"{row['visits_per_update']:.0f} visits/update" if "volume_drift" in row
                     else "")  # fmt: skip
            print(f"{scene} {label}: {wall:.3f} s ({row['vs_pristine']:.2f}x){extra}", flush=True)
    OUT.parent.mkdir(exist_ok=True)
    keys = ["scene", "cell_m", "every", "wall_s", "vs_pristine", "x_m", "volume_drift",
            "unrelaxed_share", "visits_per_update"]  # fmt: skip
    with OUT.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows({k: r.get(k, "") for k in keys} for r in rows)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
