"""Steady drag of a blade on deforming ground: its mean, its fluctuation, and the relaxation.

Run: python benchmarks/deform_blade.py [--cells 0.005 0.0025 0.00125] [--length 0.1]
A blade (4 cm wide, 1.2 cm thick) held 15 mm deep in glass beads is dragged at 0.1 m/s along +x
for --length [m]; its RFT drag (x force) is sampled at every step over the second half of the
drag (the berm ahead has built up), on the pristine surface and on deforming ground per cell.
Prints the mean, the standard deviation and their ratio, the drag's spread over 1 cm windows
(how it drifts as the berm grows), and the ground's counters (updates whose relaxation met its
work budget, pair visits per update).
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np

import mjrft

BLADE = """<mujoco><option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<numeric name="mjrft:region" data="-0.05 -0.06 -0.1 {xmax} 0.06 0.05"/>
{cell}
<tuple name="mjrft:intruders"><element objtype="geom" objname="blade" prm="600"/></tuple></custom>
<worldbody><body name="blade" pos="0 0 0"><joint name="x" type="slide" axis="1 0 0"/>
<geom name="blade" type="box" size="0.006 0.02 0.02" pos="0 0 0.005" mass="1"/></body>
</worldbody><actuator><velocity joint="x" kv="2000"/></actuator></mujoco>"""
SPEED = 0.1  # [m/s]
WINDOW = 0.01  # [m] of travel per window of the drift measure


def drag(cell: float | None, length: float, travel: float = 0.0) -> dict:
    """Drag force samples [N] over the second half of the drag, and the ground's counters; the
    ground updated once the blade travelled `travel` cells (0: at every step)."""
    tag = f'<numeric name="mjrft:deform_cell" data="{cell}"/>' if cell else ""
    model = mjrft.load_model(BLADE.format(xmax=length + 0.08, cell=tag),
                             deform_travel=travel if cell else None)  # fmt: skip
    field = mjrft.GranularField(model)
    data = mujoco.MjData(model)
    data.ctrl[0] = SPEED
    xs, fs = [], []
    while data.qpos[0] < length:
        mujoco.mj_step(model, data)
        if data.qpos[0] > 0.5 * length:
            xs.append(data.qpos[0])
            fs.append(-field.wrench_of(data)[1, 0])  # resistance, against the motion
    out = {"x": np.array(xs), "f": np.array(fs)}
    if cell:
        c = field.soil(data).counters
        out["unrelaxed"] = c["unrelaxed"] / c["updates"]
        out["visits"] = c["visits"] / c["updates"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=float, nargs="+", default=[0.005, 0.0025, 0.00125])
    ap.add_argument("--length", type=float, default=0.1, help="drag length [m]")
    args = ap.parse_args()
    for cell in [None, *args.cells]:
        r = drag(cell, args.length)
        f, x = r["f"], r["x"]
        edges = np.arange(x.min(), x.max(), WINDOW)
        means = [f[(x >= a) & (x < a + WINDOW)].mean() for a in edges[:-1]]
        label = "pristine" if cell is None else f"{cell * 1e3:g} mm cell"
        extra = (f"; relaxation budget met at {r['unrelaxed']:.1%} of updates, "
                 f"{r['visits']:.0f} pair visits per update" if cell else "")  # fmt: skip
        spread = f"std/mean {f.std() / f.mean():.1%}"
        print(f"{label}: drag {f.mean():.3f} +- {f.std():.3f} N ({spread}), 1 cm windows "
              f"{min(means):.3f}-{max(means):.3f} N{extra}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
