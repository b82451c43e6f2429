"""Golden trajectories: short runs of the rigs through every production path, pinned bit for bit.

Each scenario returns a dict of arrays (states sampled along a run). ``tests/golden/*.npz`` hold
the arrays the code produced when they were generated; ``tests/test_golden.py`` reruns the
scenarios and compares. They pin behaviour across refactors: they are not physics references.
Regenerate (only when a change of results is intended, and say why in the commit):

    python tests/golden_runs.py --write
"""

from __future__ import annotations

import argparse
import platform
from pathlib import Path

import mujoco
import numpy as np

import mjrft
from mjrft import simulate
from mjrft.batch import BatchedField

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
GOLDEN = Path(__file__).resolve().parent / "golden"
#: Every this many steps a state is stored.
SAMPLE = 25


def _rig(name: str, duration: float, n_triangles: int | None, integrator: str | None = None):
    model = simulate.load_model(str(MODELS / f"{name}.xml"))
    simulate.configure(model, None, integrator)
    fld = mjrft.GranularField(model, n_triangles=n_triangles)
    states = []

    def observe(step, time, data):
        states.append(np.concatenate([[time], data.qpos, data.qvel, fld.last_wrench.ravel()]))

    data, _ = simulate.run(model, duration, fld=fld, observer=observe, observe_every=SAMPLE)
    return {"states": np.array(states), "final": np.concatenate([data.qpos, data.qvel])}


# A dense free ellipsoid thrown spinning into the medium, then left to settle, and a light one
# lowered slowly by a user force: the low-speed treatment's every decision (pure, implicit, slip,
# stick) on a free body, and the user part of xfrc_applied.
THROWN = """
<mujoco>
  <option timestep="0.001" integrator="{integrator}"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <tuple name="mjrft:intruders"><element objtype="geom" objname="shell" prm="300"/></tuple>
  </custom>
  <worldbody>
    <body name="crab" pos="0 0 0.004">
      <freejoint/>
      <geom name="shell" type="ellipsoid" size="0.008 0.006 0.012" density="{density}"/>
    </body>
  </worldbody>
</mujoco>"""


def _thrown(integrator: str, lowered: bool = False, steps: int = 1500):
    xml = THROWN.format(integrator=integrator, density=2500 if lowered else 8000)
    if lowered:
        xml = xml.replace('pos="0 0 0.004"', 'pos="0 0 0.0125"')
    model = mujoco.MjModel.from_xml_string(xml)
    fld = mjrft.GranularField(model)
    data = mujoco.MjData(model)
    data.qvel[:] = (0, 0, 0, 0.2, -0.1, 0) if lowered else (0.3, -0.1, -0.5, 4.0, -2.0, 6.0)
    weight = float(model.body_mass[1]) * 9.81
    states = []
    with fld.installed():
        for i in range(steps):
            if lowered:  # the user holds it, then lets go over 1 s
                data.xfrc_applied[1] = (0, 0, weight * max(0.0, 1.0 - i / 1000), 0, 0, 0)
            mujoco.mj_step(model, data)
            if i % SAMPLE == 0:
                states.append(np.concatenate([data.qpos, data.qvel, data.xfrc_applied[1]]))
    return {"states": np.array(states), "stats": np.array(list(fld.stats.values()))}


def _explicit(steps: int = 800):
    """The explicit path: xfrc_applied = user + field.wrench(data, user_xfrc=user) each step."""
    model = simulate.load_model(str(MODELS / "sphere_drop.xml"))
    fld = mjrft.GranularField(model, n_triangles=600)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    data.qvel[:6] = (0.01, 0.0, -0.05, 0.0, 2.0, 0.0)
    user = np.zeros((model.nbody, 6))
    states = []
    for i in range(steps):
        user[1, 0] = 0.02 * np.sin(0.01 * i)  # a user push [N] the treatment must balance
        mujoco.mj_forward(model, data)
        data.xfrc_applied[:] = user + fld.wrench(data, user_xfrc=user)
        mujoco.mj_step(model, data)
        if i % SAMPLE == 0:
            states.append(np.concatenate([data.qpos, data.qvel, data.xfrc_applied[1]]))
    return {"states": np.array(states)}


def _batch(steps: int = 600):
    model = simulate.load_model(str(MODELS / "sphere_drop.xml"))
    bf = BatchedField(mjrft.GranularField(model, n_triangles=600), nsim=3, nthread=1)
    bf.reset(keyframe=0)
    bf.batch.bind("qvel")[:, 2] = (-0.02, -0.1, 0.0)
    bf.batch.bind("qvel")[:, 4] = (0.0, 1.0, -3.0)
    bf.forward()
    states = []
    for i in range(steps):
        bf.step()
        if i % SAMPLE == 0:
            states.append(np.concatenate([bf.batch.bind("qpos"), bf.batch.bind("qvel")], axis=1))
    bf.close()
    return {"states": np.array(states)}


#: name -> scenario; each takes ~0.1-2 s on a 2-core machine.
SCENARIOS = {
    "ellipsoid_pitch_euler": lambda: _rig("ellipsoid_pitch", 4.2, 400),
    "ellipsoid_pitch_rk4": lambda: _rig("ellipsoid_pitch", 4.0, 400, "rk4"),
    "root_circumnutation": lambda: _rig("root_circumnutation", 3.0, 400),
    "plate_rig": lambda: _rig("plate_rig", 2.5, 400),
    "sphere_drop_euler": lambda: _rig("sphere_drop", 1.0, 600),
    "sphere_drop_rk4": lambda: _rig("sphere_drop", 1.0, 600, "rk4"),
    "sphere_drop_implicitfast": lambda: _rig("sphere_drop", 1.0, 600, "implicitfast"),
    "hexapod_sand": lambda: _rig("hexapod_sand", 1.5, None),
    "thrown_euler": lambda: _thrown("Euler"),
    "thrown_rk4": lambda: _thrown("RK4"),
    "thrown_implicitfast": lambda: _thrown("implicitfast"),
    "lowered_euler": lambda: _thrown("Euler", lowered=True),
    "lowered_rk4": lambda: _thrown("RK4", lowered=True),
    "explicit_sphere": _explicit,
    "batch_sphere": _batch,
}


def fingerprint() -> str:
    """The machine and versions a golden file was generated with (numba compiles for the host
    CPU; bit-identity is pinned on that combination)."""
    import llvmlite.binding as llvm

    return "|".join(
        [
            platform.machine(),
            llvm.get_host_cpu_name(),
            mujoco.__version__,
            np.__version__,
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write tests/golden/*.npz")
    parser.add_argument("names", nargs="*", help="scenarios (default: all)")
    args = parser.parse_args()
    GOLDEN.mkdir(exist_ok=True)
    for name in args.names or list(SCENARIOS):
        arrays = SCENARIOS[name]()
        if args.write:
            np.savez_compressed(GOLDEN / f"{name}.npz", fingerprint=fingerprint(), **arrays)
        print(name, {k: v.shape for k, v in arrays.items()})


if __name__ == "__main__":
    main()
