"""Thrown passive bodies never gain mechanical energy from the medium, in any step.

Run: python benchmarks/energy.py [--quick] [--workers N]
For every shape (sphere, capsule, cylinder, box, ellipsoid, mesh) x mass (0.05, 0.5, 5 kg, at
2500 kg/m^3) x timestep (1, 2 ms) x integrator (Euler, implicit, implicitfast, RK4) x throw (6
seeded random throws: a speed of 0.05-2 m/s into the medium, downward, at a random angle, and a
random spin of up to 30 rad/s), a free body is thrown into glass beads from just above the
surface and followed for 0.5 s (contacts off, gravity on). The energy the medium adds in a step
is the step's change of mechanical energy E = kinetic + m g z, less the change the same step from
the same state makes without the medium (a second model, stepped alone) where that is a gain:
MuJoCo's Euler by itself gains energy in the free rotation of an asymmetric body (a 5 kg capsule
spinning at 17 rad/s: 36x the tolerance per step, no medium involved), which is the integrator's,
not the medium's; where the free step loses energy (semi-implicit Euler under gravity loses
m g^2 dt^2 / 2), the step with the medium must not gain. It is compared with the tolerance
1e-9 J + 1e-6 |E| (the medium is dissipative, docs/design.md 2.9).
Prints the cells that gained and writes benchmarks/results/energy.csv (one row per throw: the
largest gain over the tolerance, the step and the treatment's decision in that step).
``--quick``: 2 throws per cell.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import math
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import mujoco
import numpy as np

import mjrft
from mjrft.field import GranularField

OUT = Path(__file__).resolve().parent / "results"
DENSITY = 2500.0  # kg/m^3
SHAPES = ("sphere", "capsule", "cylinder", "box", "ellipsoid", "mesh")
MASSES = (0.05, 0.5, 5.0)  # kg
TIMESTEPS = (0.001, 0.002)  # s
INTEGRATORS = ("Euler", "implicit", "implicitfast", "RK4")
THROWS = 6
DURATION = 0.5  # s
E_ABS, E_REL = 1e-9, 1e-6  # tolerance of a step's energy gain: E_ABS + E_REL |E|
# Shape proportions (unit volume), scaled to each mass at DENSITY: MuJoCo size parameters.
_UNIT = {
    "sphere": np.array([0.62]),
    "capsule": np.array([0.35, 0.9]),
    "cylinder": np.array([0.45, 0.6]),
    "box": np.array([0.7, 0.5, 0.35]),
    "ellipsoid": np.array([0.5, 0.5, 0.95]),
    "mesh": np.array([1.0]),
}
# A tetrahedron-capped prism: a convex mesh with sharp edges (unit scale).
_MESH_VERTICES = (
    "0.8 0 -0.5  -0.4 0.69 -0.5  -0.4 -0.69 -0.5  0.8 0 0.5  -0.4 0.69 0.5  -0.4 -0.69 0.5  0 0 1"
)


def scene(shape: str, mass: float, dt: float, integrator: str) -> str:
    """A free body of the given shape and mass, its lowest point 1 mm above the surface."""
    volume = mass / DENSITY
    if shape == "mesh":
        scale = (volume / 1.2) ** (1 / 3)
        scales = f"{scale} {scale} {scale}"
        asset = f'<asset><mesh name="m" vertex="{_MESH_VERTICES}" scale="{scales}"/></asset>'
        geom = f'<geom name="g" type="mesh" mesh="m" mass="{mass}"/>'
        height = 0.5 * scale
    else:
        size = _UNIT[shape] * volume ** (1 / 3)
        asset = ""
        sizes = " ".join(f"{x:.6g}" for x in size)
        geom = f'<geom name="g" type="{shape}" size="{sizes}" mass="{mass}"/>'
        lowest = {"sphere": 0, "capsule": None, "cylinder": 1, "box": 2, "ellipsoid": 2}[shape]
        height = float(size.sum() if lowest is None else size[lowest])
    prm = "0" if shape == "mesh" else "300"
    return f"""<mujoco><option timestep="{dt}" integrator="{integrator}">
      <flag contact="disable"/></option>{asset}
      <custom><text name="mjrft:material" data="glass_beads"/>
        <tuple name="mjrft:intruders"><element objtype="geom" objname="g" prm="{prm}"/></tuple>
      </custom>
      <worldbody><body name="b" pos="0 0 {height + 0.001:.6g}"><freejoint/>{geom}</body></worldbody>
    </mujoco>"""


def energy(m: mujoco.MjModel, d: mujoco.MjData) -> float:
    """Kinetic + gravitational potential energy [J] of the one free body."""
    mass = float(m.body_mass[1])
    x = d.ximat[1].reshape(3, 3)
    omega_body = d.qvel[3:6]  # free joint: angular velocity in the body frame
    omega = d.xmat[1].reshape(3, 3) @ omega_body
    inertia = (x * m.body_inertia[1]) @ x.T
    vel = np.zeros(6)
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, 1, vel, 0)
    kinetic = 0.5 * mass * vel[3:] @ vel[3:] + 0.5 * omega @ inertia @ omega
    return float(kinetic - mass * (m.opt.gravity @ d.xipos[1]))


def thrown(case: tuple) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The model of a throw (shape, mass [kg], dt [s], integrator, throw index), with the engine
    plugin (``mjrft.load_model``), and its data at the moment of the throw (seeded speed,
    direction and spin)."""
    shape, mass, dt, integrator, k = case
    m = mjrft.load_model(scene(shape, mass, dt, integrator))
    d = mujoco.MjData(m)
    rng = np.random.default_rng([k, SHAPES.index(shape), int(1e3 * mass), int(1e4 * dt)])
    speed = 10.0 ** rng.uniform(math.log10(0.05), math.log10(2.0))
    direction = rng.normal(size=3)
    direction[2] = -abs(direction[2]) - 0.3
    d.qvel[:3] = speed * direction / np.linalg.norm(direction)
    d.qvel[3:6] = rng.normal(size=3) * rng.uniform(0, 30) / math.sqrt(3)
    mujoco.mj_forward(m, d)
    return m, d


def throw(case: tuple) -> dict:
    """One throw: the largest step gain over the tolerance, where, and the decision there."""
    shape, mass, dt, integrator, k = case
    m, d = thrown(case)
    # The same MJCF without the engine plugin: no medium.
    m_free = mujoco.MjModel.from_xml_string(scene(shape, mass, dt, integrator))
    decisions = GranularField(m).decision_of(d)  # a view of d's most recent pass
    free = mujoco.MjData(m_free)
    worst = {"ratio": 0.0, "step": -1, "decision": -1, "gain_J": 0.0, "energy_J": 0.0}
    e0 = energy(m, d)
    for i in range(round(DURATION / dt)):
        free.qpos[:], free.qvel[:], free.time = d.qpos, d.qvel, d.time
        mujoco.mj_step(m_free, free)  # the same step without the medium
        mujoco.mj_forward(m_free, free)
        mujoco.mj_step(m, d)
        decision = int(decisions[0])  # the step's (the forward pass below overwrites it)
        mujoco.mj_forward(m, d)
        e_free, e1 = energy(m_free, free), energy(m, d)
        gain = e1 - e0 - max(e_free - e0, 0.0)
        ratio = gain / (E_ABS + E_REL * abs(e0))
        if ratio > worst["ratio"]:
            worst = {"ratio": ratio, "step": i, "decision": decision,
                     "gain_J": gain, "energy_J": e0}  # fmt: skip
        e0 = e1
    return {"shape": shape, "mass_kg": mass, "dt_s": dt, "integrator": integrator, "throw": k,
            **worst}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 throws per cell")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    throws = 2 if args.quick else THROWS
    cases = list(itertools.product(SHAPES, MASSES, TIMESTEPS, INTEGRATORS, range(throws)))
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(throw, cases, chunksize=4))
    OUT.mkdir(exist_ok=True)
    name = "energy_quick.csv" if args.quick else "energy.csv"
    keys = sorted({k for r in rows for k in r}, key=list(rows[0]).index)
    with open(OUT / name, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    gained = [r for r in rows if r["ratio"] > 1.0]
    print(f"{len(rows)} throws in {time.perf_counter() - t0:.0f} s; {len(gained)} gained energy")
    for r in gained:
        print(
            f"  {r['shape']:9s} {r['mass_kg']:5g} kg dt {1e3 * r['dt_s']:g} ms "
            f"{r['integrator']:12s} throw {r['throw']}: +{r['gain_J']:.3g} J "
            f"({r['ratio']:.3g} x tolerance, "
            f"{100 * r['gain_J'] / max(abs(r['energy_J']), 1e-30):.2g} % of E) at step "
            f"{r['step']}, decision {r['decision']}"
        )


if __name__ == "__main__":
    main()
