"""Golden trajectories: short runs of the rigs through every production path, pinned bit for bit.

Each scenario returns a dict of arrays (states sampled along a run). ``tests/golden/*.npz`` hold
the arrays the code produced when they were generated; ``tests/test_golden.py`` reruns the
scenarios and compares. They pin behaviour across refactors: they are not physics references.
Regenerate (only when a change of results is intended, and say why in the commit), all of them
or the scenarios named:

    python tests/golden_runs.py --write [NAME ...]
"""

from __future__ import annotations

import argparse
import copy
import platform
from pathlib import Path

import mujoco
import numpy as np
from mujoco.batch import Batch

import mjrft
from mjrft import simulate

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
GOLDEN = Path(__file__).resolve().parent / "golden"
#: Every this many steps a state is stored.
SAMPLE = 25


def _rig(name: str, duration: float, n_triangles: int | None, integrator: str | None = None):
    model = simulate.load_model(str(MODELS / f"{name}.xml"), n_triangles=n_triangles)
    simulate.configure(model, None, integrator)
    fld = mjrft.GranularField(model)
    states = []

    def observe(step, time, data):
        states.append(np.concatenate([[time], data.qpos, data.qvel, fld.wrench_of(data).ravel()]))

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
    model = mjrft.load_model(xml)
    fld = mjrft.GranularField(model)
    data = mujoco.MjData(model)
    data.qvel[:] = (0, 0, 0, 0.2, -0.1, 0) if lowered else (0.3, -0.1, -0.5, 4.0, -2.0, 6.0)
    weight = float(model.body_mass[1]) * 9.81
    states = []
    for i in range(steps):
        if lowered:  # the user holds it, then lets go over 1 s
            data.xfrc_applied[1] = (0, 0, weight * max(0.0, 1.0 - i / 1000), 0, 0, 0)
        mujoco.mj_step(model, data)
        if i % SAMPLE == 0:
            states.append(np.concatenate([data.qpos, data.qvel, data.xfrc_applied[1]]))
    return {"states": np.array(states), "stats": np.array(list(fld.stats_of(data).values()))}


def _explicit(steps: int = 800):
    """GranularField.wrench along a run: a sphere dropped with a user push in xfrc_applied (the
    treatment must balance it once the sphere rests); at every sampled state, the explicit
    evaluation (``wrench(..., user_xfrc=push)`` on a copy of the state before the step) beside
    the wrench the step's own pass computed there (``wrench_of``). Euler: the step's pass
    evaluates the state the step starts from."""
    model = simulate.load_model(str(MODELS / "sphere_drop.xml"), n_triangles=600)
    fld = mjrft.GranularField(model)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    data.qvel[:6] = (0.01, 0.0, -0.05, 0.0, 2.0, 0.0)
    user = np.zeros((model.nbody, 6))
    states, explicit, installed = [], [], []
    for i in range(steps):
        user[1, 0] = 0.02 * np.sin(0.01 * i)  # a user push [N] the treatment must balance
        data.xfrc_applied[1, 0] = user[1, 0]
        sampled = i % SAMPLE == 0
        if sampled:
            before = copy.copy(data)
        mujoco.mj_step(model, data)
        if sampled:
            mujoco.mj_forward(model, before)  # its kinematics (the copy's own pass runs too)
            explicit.append(fld.wrench(before, user_xfrc=user)[1])
            installed.append(fld.wrench_of(data)[1].copy())
            states.append(np.concatenate([data.qpos, data.qvel, data.xfrc_applied[1]]))
    return {
        "states": np.array(states),
        "explicit": np.array(explicit),
        "installed": np.array(installed),
    }


# Copies of the dropped sphere thrown differently, stepped on MuJoCo's threaded batch: the plugin
# runs inside each copy's mj_step, its state in the copy's plugin_state.
BATCH_QVEL = {2: (-0.02, -0.1, 0.0), 4: (0.0, 1.0, -3.0)}  # dof -> per copy [m/s, rad/s]


def _batch_model() -> mujoco.MjModel:
    return simulate.load_model(str(MODELS / "sphere_drop.xml"), n_triangles=600)


def _batch(steps: int = 600):
    """The copies on ``mujoco.batch.Batch``: qpos, qvel and the sphere's xfrc_applied row (the
    RFT the plugin wrote) of every copy, sampled."""
    model = _batch_model()
    batch = Batch(model, nsim=3, nthread=1)
    batch.reset(keyframe=0, stage=mujoco.mjtStage.mjSTAGE_NONE)  # as mj_resetDataKeyframe
    qpos, qvel, xfrc = batch.bind("qpos"), batch.bind("qvel"), batch.bind("xfrc_applied")
    for dof, values in BATCH_QVEL.items():
        qvel[:, dof] = values
    states = []
    for i in range(steps):
        batch.step()
        if i % SAMPLE == 0:
            states.append(np.concatenate([qpos, qvel, xfrc[:, 1]], axis=1))
    return {"states": np.array(states)}


def batch_singles(steps: int = 600) -> np.ndarray:
    """``_batch``'s states from one MjData per copy stepped by mj_step (what the batch must give
    bit for bit)."""
    model = _batch_model()
    datas = []
    for sim in range(3):
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        for dof, values in BATCH_QVEL.items():
            data.qvel[dof] = values[sim]
        datas.append(data)
    states = []
    for i in range(steps):
        for data in datas:
            mujoco.mj_step(model, data)
        if i % SAMPLE == 0:
            states.append([np.concatenate([d.qpos, d.qvel, d.xfrc_applied[1]]) for d in datas])
    return np.array(states)


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
    """The platform and versions a golden file was generated with; where they match, the test
    compares bit for bit.

    The CPU model is not part of it: the engine is C++ built with ``-ffp-contract=off`` and no
    fast-math, so it fuses a multiply-add only where the code says ``std::fma`` (exact on any
    CPU) and reorders nothing, whatever the compiler and ``-march``: its arithmetic is IEEE-754's,
    the same on every CPU of an architecture (the files reproduce bit for bit on AMD Zen 3 and
    on an Intel Xeon with AVX-512). What can still change the numbers: the architecture, the C
    library (its libm's ``hypot`` in the engine), MuJoCo's release (its own arithmetic) and
    NumPy's (the engine's tables and the tests' arrays are built with it)."""
    return "|".join(
        [
            platform.machine(),
            platform.system(),
            "-".join(platform.libc_ver()),
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
