"""Cost of the deforming ground: the walking hexapod with it off and at two grid cells.

Run: python benchmarks/deform_cost.py [--repeats 3]
hexapod_sand (10 s of the 1 Hz alternating tripod, 500 control steps) on the pristine surface
and on deforming ground at 5 mm and 2 mm cells, updated every step and every 10 steps
(mjrft:deform_every); medians over repeats of the wall time, the ratio to the pristine run, the
distance walked, the volume drift relative to the volume cut and the share of updates whose
relaxation met its sweep budget. Writes benchmarks/results/deform_cost.csv.
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import time
from pathlib import Path

import numpy as np
from mjrft.envs import hexapod_sand

OUT = Path(__file__).resolve().parent / "results" / "deform_cost.csv"
#: (cell [m], steps between updates); cell None: the pristine surface.
CASES = ((None, 1), (0.005, 1), (0.005, 10), (0.002, 1), (0.002, 10))
WALK_S = 10.0


def walk(cell: float | None, every: int) -> dict:
    """One 10 s walk; wall time [s] and the ground's counters."""
    env = hexapod_sand.make(seed=0, time_limit=math.inf, deform_cell=cell,
                            deform_every=every if cell else None)  # fmt: skip
    try:
        env.reset()
        action = np.array([1.0, math.pi])
        n = round(WALK_S / env.control_timestep())
        t0 = time.perf_counter()
        for _ in range(n):
            env.step(action)
        wall = time.perf_counter() - t0
        physics = env.physics
        row = {"cell_m": cell or 0.0, "every": every, "wall_s": wall,
               "x_m": float(physics.data.qpos[0])}  # fmt: skip
        if cell:
            soil = physics.field.soil(physics.data.ptr)
            c = soil.counters
            row["volume_drift"] = abs(soil.volume()) / c["excavated"]
            row["unrelaxed_share"] = c["unrelaxed"] / c["updates"]
        return row
    finally:
        env.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    runs = {case: [walk(*case) for _ in range(args.repeats)] for case in CASES}
    base = statistics.median(r["wall_s"] for r in runs[CASES[0]])
    rows = []
    for (cell, every), rs in runs.items():
        wall = statistics.median(r["wall_s"] for r in rs)
        row = {**rs[0], "wall_s": wall, "vs_pristine": wall / base}
        rows.append(row)
        label = "pristine" if cell is None else f"{cell * 1e3:g} mm cell, every {every} steps"
        extra = (f", volume drift {row['volume_drift']:.1e}, budget met at "
                 f"{row['unrelaxed_share']:.1%} of updates" if cell else "")  # fmt: skip
        print(f"{label}: {wall:.2f} s for {WALK_S:g} s ({row['vs_pristine']:.1f}x), walked "
              f"{row['x_m']:.3f} m{extra}")  # fmt: skip
    OUT.parent.mkdir(exist_ok=True)
    keys = ["cell_m", "every", "wall_s", "vs_pristine", "x_m", "volume_drift", "unrelaxed_share"]
    with OUT.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows({k: r.get(k, "") for k in keys} for r in rows)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
