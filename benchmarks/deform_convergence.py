"""Convergence of the deforming ground with its cell: a plate resting under its weight and a
dragged blade, at successive halvings of the cell, with the observed order.

Run: python benchmarks/deform_convergence.py [--cells 0.01 0.005 0.0025 0.00125] [--quadruped]
         [--travel 0 0.25 1]
Plate: a 5 cm square plate of 0.84 kg on glass beads dropped from 1 mm above the surface and
left 0.6 s to settle; its rest depth [m] (and on the pristine surface, for reference). Blade: as in
benchmarks/deform_blade.py (4 cm wide, 15 mm deep, 10 cm at 0.1 m/s), its mean drag [N] over
the second half. For each: the value per cell, the change between successive cells, the observed
order p = log2(change / next change) of the last three cells and the Richardson estimate of the
cell-free value, with each cell's error against it. --quadruped: the Go2-class quadruped
(models/go2_sand.xml) set down with its feet on the surface and its home ctrl held, QUAD_S
seconds: its feet's mean depth at the end [m] (the same table), and when it settled: the first
time after which the torso's speed stays below SETTLED_SPEED (NaN if it did not within QUAD_S).
--travel: instead, the same measures per cell under each mjrft:deform_travel [cells] (0: the
ground updated at every step), with the change each makes against updating at every step.
"""

from __future__ import annotations

import argparse
import math

import mujoco
import numpy as np
from deform_blade import drag

import mjrft

PLATE = """<mujoco><option timestep="0.001" integrator="implicitfast"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<numeric name="mjrft:region" data="-0.06 -0.06 -0.1 0.06 0.06 0.05"/>
{cell}
<tuple name="mjrft:intruders"><element objtype="geom" objname="plate" prm="400"/></tuple></custom>
<worldbody><body name="plate" pos="0 0 0.006"><joint name="z" type="slide" axis="0 0 1"/>
<geom name="plate" type="box" size="0.025 0.025 0.005" mass="0.84"/></body></worldbody>
</mujoco>"""
SETTLE_S = 0.6
#: The quadruped's run [s] and the torso speed [m/s] below which it counts as settled (issue:
#: within 2 s on the finer cells).
QUAD_S, SETTLED_SPEED = 4.0, 1e-6
#: The quadruped's medium [m]: the ground around its stance (xmin ymin zmin xmax ymax zmax).
QUAD_REGION = [-0.45, -0.35, -0.5, 0.55, 0.35, 0.05]


def plate_depth(cell: float | None, travel: float = 0.0) -> float:
    """Rest depth [m] of the plate's bottom below the original surface after SETTLE_S, the
    ground updated once the plate travelled `travel` cells (0: at every step)."""
    tag = f'<numeric name="mjrft:deform_cell" data="{cell}"/>' if cell else ""
    model = mjrft.load_model(PLATE.format(cell=tag), deform_travel=travel if cell else None)
    data = mujoco.MjData(model)
    while data.time < SETTLE_S:
        mujoco.mj_step(model, data)
    return -(data.qpos[0] + 0.006 - 0.005)  # bottom: 5 mm below the body origin


def quadruped(cell: float | None, travel: float = 0.0) -> tuple[float, float]:
    """(mean feet depth [m] below the original surface after QUAD_S, settling time [s]); the
    ground updated once the feet travelled `travel` cells (0: at every step)."""
    import warnings

    from mjrft.envs import go2_sand

    spec = go2_sand.build_spec()
    spec.add_numeric(name="mjrft:region", data=QUAD_REGION)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the thighs' SinkingWarning on deep ground
        model = mjrft.load_model(spec, deform_cell=cell, deform_travel=travel if cell else None)
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    data.qpos[7:] = go2_sand.HOME_CTRL
    mujoco.mj_kinematics(model, data)
    feet = [model.geom(f"{leg}_foot").id for leg in go2_sand.LEGS]
    radius = model.geom_size[feet, 0]
    data.qpos[2] -= (data.geom_xpos[feet, 2] - radius).min()  # the lowest foot on the surface
    data.ctrl[:] = go2_sand.HOME_CTRL
    settled = math.nan
    while data.time < QUAD_S:
        mujoco.mj_step(model, data)
        if np.linalg.norm(data.qvel[:3]) >= SETTLED_SPEED:
            settled = math.nan
        elif math.isnan(settled):
            settled = data.time
    return float(np.mean(-(data.geom_xpos[feet, 2] - radius))), settled


def blade_drag(cell: float | None, travel: float = 0.0) -> float:
    """Mean drag [N] of the blade over the second half of its 10 cm (travel: as plate_depth)."""
    return float(drag(cell, 0.1, travel)["f"].mean())


def travel_table(cells: list[float], travels: list[float]) -> None:
    """The plate's rest depth, the blade's drag and the Go2's feet depth per cell and
    mjrft:deform_travel, with the change against updating at every step."""
    measures = (("plate rest depth", "mm", 1e3, plate_depth), ("blade drag", "N", 1.0, blade_drag),
                ("Go2 feet depth", "mm", 1e3, lambda c, t: quadruped(c, t)[0]))  # fmt: skip
    for name, unit, scale, fn in measures:
        for c in cells:
            base = fn(c, 0.0)
            row = [f"every step {base * scale:.4g} {unit}"]
            for t in travels:
                if t > 0:  # one run per setting (each is a simulation)
                    value = fn(c, t)
                    row.append(f"travel {t:g}: {value * scale:.4g} ({value / base - 1:+.1%})")
            print(f"{name}, cell {c * 1e3:g} mm: " + ", ".join(row), flush=True)


def table(name: str, unit: str, scale: float, cells: list[float], values: list[float],
          pristine: float) -> None:  # fmt: skip
    """Prints values per cell, the observed order and the errors against Richardson's value."""
    v = np.array(values)
    change = np.abs(np.diff(v))
    p = math.log2(change[-2] / change[-1]) if change[-1] > 0 else math.inf
    limit = v[-1] + (v[-1] - v[-2]) / (2.0**p - 1.0) if math.isfinite(p) else v[-1]
    print(f"{name} (pristine surface: {pristine * scale:.3f} {unit})")
    for c, x in zip(cells, v, strict=True):
        print(f"  cell {c * 1e3:g} mm: {x * scale:.4f} {unit}, error {abs(x - limit) * scale:.4f} "
              f"{unit} ({abs(x - limit) / abs(limit):.2%})")  # fmt: skip
    print(f"  observed order {p:.2f}; cell-free estimate {limit * scale:.4f} {unit}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=float, nargs="+", default=[0.01, 0.005, 0.0025, 0.00125])
    ap.add_argument("--quadruped", action="store_true", help="the Go2's stance instead")
    ap.add_argument("--travel", type=float, nargs="+", help="compare mjrft:deform_travel values")
    args = ap.parse_args()
    if args.travel:
        travel_table(sorted(args.cells, reverse=True), args.travel)
        return
    if len(args.cells) < 3:
        ap.error("--cells needs at least three sizes for an observed order")
    cells = sorted(args.cells, reverse=True)
    if args.quadruped:
        runs = [quadruped(c) for c in cells]
        table("Go2 feet depth", "mm", 1e3, cells, [r[0] for r in runs], quadruped(None)[0])
        for c, (_, t) in zip(cells, runs, strict=True):
            print(f"  cell {c * 1e3:g} mm: settled (|v| < {SETTLED_SPEED:g} m/s) at t = {t:.3f} s")
        return
    table("plate rest depth", "mm", 1e3, cells, [plate_depth(c) for c in cells], plate_depth(None))
    table("blade drag", "N", 1.0, cells, [blade_drag(c) for c in cells], blade_drag(None))


if __name__ == "__main__":
    main()
