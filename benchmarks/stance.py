"""A light quadruped standing on sand on soft position servos, swept over stiffness, leg mass,
timestep and integrator: does the stance hold?

Run: python benchmarks/stance.py [--kp 1 3 10 30 100 300 1000] [--shin 0.005 0.015 0.025 0.1]
     [--timesteps 0.5 1 2] [--integrators euler implicitfast rk4] [--settle 1] [--hold 5]

The robot (``quadruped``): a 0.4 kg torso on four two-joint legs (hip and knee about y; thigh
30 g, shin capsule and sphere foot together ``--shin`` kg), position servos of stiffness kp
[N m/rad] holding the standing pose, joint damping 0.02 N m s/rad and armature 2e-4 kg m^2 (the
servos have no velocity gain: MuJoCo's Euler integrates an actuator's velocity gain explicitly,
which alone is unstable on legs this light), the shins and feet tagged, Li's generic medium at
zeta = 1e6 N/m^3, no floor. For each cell it settles for --settle s, then holds --hold s and
reports: the torso's drift [mm] over the hold, the median and largest step-to-step change of
the total RFT vertical force as a percentage of the weight, whether the torso sank into the
medium, the fraction of leg-passes the treatment held (stuck) or slipped, omega dt of the
stiffest joint mode (sqrt(kp / I) dt; plain MuJoCo's explicit servo is unstable above 2) and
the wall time per step. Writes results/stance.csv. The targets (docs/stability.md,
"Mechanisms"): drift <= 0.01 mm and force change <= 1 % of the weight.
"""

from __future__ import annotations

import argparse
import csv
import math
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import mjrft  # noqa: E402
from mjrft.app import metadata  # noqa: E402

OUT = Path(__file__).resolve().parent / "results"
INTEGRATORS = {"euler": "Euler", "implicitfast": "implicitfast", "rk4": "RK4"}
ARMATURE = 2e-4  # kg m^2 per joint
TORSO_MASS, THIGH_MASS = 0.4, 0.03  # kg


def quadruped(kp: float, shin: float, timestep: float, integrator: str) -> str:
    """MJCF of the light quadruped (see the module's docstring); shin: shin + foot mass [kg]."""
    legs = ""
    for name, x, y in (("FL", 0.1, 0.06), ("FR", 0.1, -0.06), ("HL", -0.1, 0.06),
                       ("HR", -0.1, -0.06)):  # fmt: skip
        legs += f"""
      <body name="{name}_thigh" pos="{x} {y} 0">
        <joint name="{name}_hip" axis="0 1 0" damping="0.02" armature="{ARMATURE}"/>
        <geom type="capsule" fromto="0 0 0 0.03 0 -0.05" size="0.008" mass="{THIGH_MASS}"
              contype="0" conaffinity="0"/>
        <body name="{name}_shin" pos="0.03 0 -0.05">
          <joint name="{name}_knee" axis="0 1 0" damping="0.02" armature="{ARMATURE}"/>
          <geom name="{name}_shin" type="capsule" fromto="0 0 0 -0.03 0 -0.05" size="0.006"
                mass="{0.7 * shin}" contype="0" conaffinity="0"/>
          <geom name="{name}_foot" pos="-0.03 0 -0.05" size="0.012" mass="{0.3 * shin}"
                contype="0" conaffinity="0"/>
        </body>
      </body>"""
    servos = "".join(f'<position joint="{leg}_{j}" kp="{kp}"/>'
                     for leg in ("FL", "FR", "HL", "HR") for j in ("hip", "knee"))  # fmt: skip
    return f"""
<mujoco model="light quadruped">
  <option timestep="{timestep}" integrator="{INTEGRATORS[integrator]}"/>
  <custom>
    <numeric name="mjrft:zeta" data="1e6"/>
    <numeric name="mjrft:triangles" data="200"/>
    <text name="mjrft:intruders_match" data="*_foot *_shin"/>
  </custom>
  <worldbody>
    <body name="torso" pos="0 0 0.108">
      <freejoint/>
      <geom type="box" size="0.12 0.05 0.02" mass="{TORSO_MASS}" contype="0" conaffinity="0"/>
      {legs}
    </body>
  </worldbody>
  <actuator>{servos}</actuator>
</mujoco>"""


def cell(kp: float, shin: float, timestep: float, integrator: str, settle: float, hold: float):
    """One cell of the sweep: a dict of what the module's docstring lists."""
    model = mjrft.load_model(quadruped(kp, shin, timestep, integrator))
    data = mujoco.MjData(model)
    fld = mjrft.GranularField(model)
    weight = float(model.body_subtreemass[1]) * float(-model.opt.gravity[2])
    legs = fld.body_ids
    for _ in range(round(settle / timestep)):
        mujoco.mj_step(model, data)
    start = data.xpos[1].copy()
    stats0 = fld.stats_of(data)
    changes, previous, finite = [], None, True
    t0 = time.perf_counter()
    n = round(hold / timestep)
    for _ in range(n):
        mujoco.mj_step(model, data)
        if not np.all(np.isfinite(data.qvel)) or np.abs(data.qvel).max() > 1e3:
            finite = False
            break
        fz = float(fld.wrench_of(data)[legs, 2].sum())
        if previous is not None:
            changes.append(abs(fz - previous) / weight)
        previous = fz
    per_step = (time.perf_counter() - t0) / n
    stats = fld.stats_of(data)
    passes = max(1, (stats["calls"] - stats0["calls"]) * len(legs))
    inertia = ARMATURE + THIGH_MASS * 0.058**2 / 3.0  # the hip's mode, thigh as a rod
    return {
        "integrator": integrator, "dt_ms": 1e3 * timestep, "kp": kp, "shin_g": 1e3 * shin,
        "omega_dt": math.sqrt(kp / inertia) * timestep, "stable": finite,
        "drift_mm": 1e3 * float(np.linalg.norm(data.xpos[1] - start)) if finite else math.nan,
        "force_change_median_pct": 100 * float(np.median(changes)) if changes else math.nan,
        "force_change_max_pct": 100 * float(np.max(changes)) if changes else math.nan,
        "sank": bool(finite and data.xpos[1][2] < 0.0),
        "stuck": (stats["stuck"] - stats0["stuck"]) / passes,
        "slipping": (stats["slipping"] - stats0["slipping"]) / passes,
        "us_per_step": 1e6 * per_step,
    }  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kp", type=float, nargs="+", default=[1, 3, 10, 30, 100, 300, 1000])
    p.add_argument("--shin", type=float, nargs="+", default=[0.005, 0.015, 0.025, 0.1])
    p.add_argument("--timesteps", type=float, nargs="+", default=[0.5, 1.0, 2.0], help="ms")
    p.add_argument("--integrators", nargs="+", default=list(INTEGRATORS), choices=INTEGRATORS)
    p.add_argument("--settle", type=float, default=1.0)
    p.add_argument("--hold", type=float, default=5.0)
    args = p.parse_args(argv)
    print(f"# {metadata.machine()['cpu'] or platform.machine()}, mjrft {mjrft.__version__}")
    rows = []
    for integrator in args.integrators:
        for dt in args.timesteps:
            for shin in args.shin:
                for kp in args.kp:
                    row = cell(kp, shin, dt * 1e-3, integrator, args.settle, args.hold)
                    rows.append(row)
                    print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                    for k, v in row.items()), flush=True)  # fmt: skip
    OUT.mkdir(exist_ok=True)
    with open(OUT / "stance.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    held = [r for r in rows if r["stable"] and r["drift_mm"] <= 0.01
            and r["force_change_median_pct"] <= 1.0 and not r["sank"]]  # fmt: skip
    print(f"# {len(held)} of {len(rows)} cells hold (drift <= 0.01 mm, force change <= 1 %)")


if __name__ == "__main__":
    main()
