"""The shipped quadruped models/go2_sand.xml: it loads with its legs tagged, stands on the medium
with the home ctrl held, and trots open-loop without tipping over."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from mjrft.envs import go2_sand

import mjrft

MODEL = Path(__file__).resolve().parents[1] / "models" / "go2_sand.xml"
G = 9.81
INTEGRATORS = ("EULER", "IMPLICITFAST", "RK4")


def load(integrator: str = "EULER", timestep: float | None = None) -> mujoco.MjModel:
    spec = go2_sand.build_spec()
    spec.option.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator}")
    if timestep is not None:
        spec.option.timestep = timestep
    return mjrft.load_model(spec)


def lower_legs(model: mujoco.MjModel) -> list[int]:
    return [model.body(f"{leg}_calf").id for leg in go2_sand.LEGS]


def test_loads_with_the_lower_legs_tagged_and_no_meshes():
    model = load()
    fld = mjrft.GranularField(model)
    tagged = sorted(i.name for i in fld.scene.intruders)
    parts = ("calf_upper", "calf_lower", "foot")
    assert tagged == sorted(f"{leg}_{p}" for leg in go2_sand.LEGS for p in parts)
    assert model.nmesh == 0 and model.nplugin == 1 + 12  # the engine, a sensor per tagged geom
    assert model.body_subtreemass[1] == pytest.approx(15.206408, abs=1e-6)  # Menagerie's Go2
    assert model.key(0).name == "home"
    np.testing.assert_array_equal(model.key_ctrl[0], go2_sand.HOME_CTRL)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    assert np.all(lo <= go2_sand.HOME_CTRL - go2_sand.ACTION_RANGE)
    assert np.all(go2_sand.HOME_CTRL + go2_sand.ACTION_RANGE <= hi)
    # The trot is an action of the environment: inside the action's range at every instant.
    trot = np.array([go2_sand.trot_offsets(t) for t in np.arange(0.0, 2.0, 0.001)])
    assert np.all(np.abs(trot) <= go2_sand.ACTION_RANGE)
    # The joints, in qpos order, are the actuators' (the action's) order.
    joints = [model.joint(model.actuator_trnid[a, 0]).name for a in range(model.nu)]
    assert joints == [f"{leg}_{j}_joint" for leg in go2_sand.LEGS for j in ("hip", "thigh", "calf")]
    assert [model.jnt_qposadr[model.joint(j).id] for j in joints] == list(range(7, 19))


def test_the_licence_notice_is_kept():
    """The numbers come from MuJoCo Menagerie's Go2 (BSD-3-Clause): the model file carries the
    notice and LICENSE.go2 beside it the licence."""
    text = MODEL.read_text()
    licence = (MODEL.parent / "LICENSE.go2").read_text()
    for line in ("Copyright (c) 2016-2022 HangZhou YuShu TECHNOLOGY CO.,LTD.",
                 "Redistribution and use in source and binary forms"):  # fmt: skip
        assert line in text and line in licence


#: Settling from the keyframe [m]: the keyframe is the rest state (benchmarks/quadruped.py
#: --keyframe); a new MjData there moves 0.004-0.018 mm (measured, every integrator, 1-2 ms) as
#: its first step feels no RFT yet.
SETTLE = 1e-4
#: Drift once settled [m] over the last 2 s of 3 s (measured: below 1e-12 m).
DRIFT = 1e-5


@pytest.mark.parametrize("timestep", [0.002, 0.001])
@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_stands_with_the_home_ctrl_held(integrator, timestep):
    model = load(integrator, timestep)
    fld = mjrft.GranularField(model)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    start = data.qpos[:3].copy()
    n = round(3.0 / timestep)
    path = np.empty((n, 3))
    for i in range(n):
        mujoco.mj_step(model, data)
        path[i] = data.qpos[:3]
    assert np.abs(path[-1] - start).max() < SETTLE
    assert np.ptp(path[n // 3 :], axis=0).max() < DRIFT
    weight = model.body_subtreemass[1] * G
    lift = fld.wrench_of(data)[lower_legs(model), 2].sum()
    assert lift == pytest.approx(weight, rel=1e-6)  # the medium alone carries it
    assert data.xmat[1][8] > math.cos(math.radians(5.0))  # level within 5 degrees (3.0 measured)
    _, sinkage = foot_state(model, fld, data)
    assert np.all((0.02 < sinkage) & (sinkage < 0.07))  # feet a few cm deep
    assert data.qpos[2] - 0.057 > 0.1  # the trunk's underside 10 cm above the surface


def foot_state(model, fld, data) -> tuple[np.ndarray, np.ndarray]:
    """Lower-leg RFT forces (4, 3) and the feet's depth below the flat surface (4,)."""
    feet = [model.geom(f"{leg}_foot").id for leg in go2_sand.LEGS]
    depth = fld.surface_z - (data.geom_xpos[feet, 2] - model.geom_size[feet, 0])
    return fld.wrench_of(data)[lower_legs(model), :3], depth


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_trots_forward_without_tipping_over(integrator):
    """The open-loop trot (trot_ctrl) for 4 s: the torso stays within 15 degrees of level and
    its underside above the surface, the feet sink at most 10 cm, and it walks forward
    (measured 0.4 m in 4 s under Euler)."""
    model = load(integrator)
    fld = mjrft.GranularField(model)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    lowest_up, lowest_trunk, deepest = 1.0, np.inf, 0.0
    for _ in range(round(4.0 / model.opt.timestep)):
        data.ctrl[:] = go2_sand.trot_ctrl(data.time)
        mujoco.mj_step(model, data)
        lowest_up = min(lowest_up, data.xmat[1][8])
        lowest_trunk = min(lowest_trunk, data.qpos[2] - 0.057)
        deepest = max(deepest, foot_state(model, fld, data)[1].max())
    assert lowest_up > math.cos(math.radians(15.0))
    assert lowest_trunk > 0.05
    assert deepest < 0.10
    assert data.qpos[0] > 0.2


def test_mjrft_run_trots_it_by_name(tmp_path):
    """`mjrft run go2_sand --ctrl mjrft.envs.go2_sand:trot_ctrl`: the shipped model by name,
    driven by the trot's ctrl(t, data)."""
    import json

    from mjrft.app import cli

    out = tmp_path / "trot"
    args = ["run", "go2_sand", "--duration", "0.3", "--out", str(out), "--no-plots"]
    assert cli.main([*args, "--ctrl", "mjrft.envs.go2_sand:trot_ctrl"]) == 0
    run = json.loads((out / "run.json").read_text())
    assert run["status"] == "completed" and run["options"]["ctrl"].endswith(":trot_ctrl")


def test_gymnasium_view_passes_the_checker():
    gymnasium = pytest.importorskip("gymnasium")
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make("mjrft/go2_sand-v0", time_limit=0.1)  # importing mjrft.envs registered it
    try:
        check_env(env.unwrapped, skip_render_check=True)
        obs, _ = env.reset(seed=0)
        sinkage = obs[env.unwrapped.observation_slices["foot_sinkage"]]
        assert sinkage.shape == (4,) and np.all(sinkage > 0.02)  # the feet rest in the medium
    finally:
        env.close()
