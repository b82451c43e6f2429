"""The deforming ground on MuJoCo Warp (mjrft.warp.soil) against the C++ engine's.

Each world's ground follows its intruders on Warp's CPU device; the engine follows the same
configurations (each world's float32 kinematics and time copied into an MjData, then
``GranularField.wrench``, whose pass moves the ground first), so the two grounds see the same
inputs and must agree to rounding. The first run compiles the ground's kernel (~1 min on one
core; cached in ~/.cache/warp after).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

pytest.importorskip("warp")
pytest.importorskip("mujoco_warp")

import mujoco_warp as mjw
import warp as wp
from soil_scenes import BLADE, PLATE
from warp_worlds import world_kinematics

import mjrft
import mjrft.warp as mw
from mjrft.core import surface as cs
from mjrft.core.soil import SOIL_STATS
from mjrft.field import GranularField

DEVICE = "cpu"
wp.config.quiet = True
#: The issue's bar: each world's ground [m] equals the engine's on the same configurations.
GROUND_ATOL = 1e-9
#: Every move takes from one vertex what it gives another (tests/test_soil.py's bound).
VOLUME_RTOL = 1e-9
#: The counters' volumes sum the same cuts in the same order as the engine's: rounding only.
COUNTER_RTOL = 1e-12

#: Ground wide enough for the cone deposit's box to fit in the work row (the scenes above, whose
#: intruders span a large part of the grid, fall back to the weighted rim at every update).
WIDE_PLATE = PLATE.replace(
    "-0.06 -0.06 -0.1 0.06 0.06 0.05", "-0.08 -0.08 -0.1 0.08 0.08 0.05"
).replace('size="0.025 0.025 0.005"', 'size="0.01 0.01 0.005"')
WIDE_BLADE = BLADE.replace("-0.05 -0.04 -0.1 0.15 0.04 0.05", "-0.05 -0.12 -0.1 0.15 0.12 0.05")
#: The blade with the ground following it once it has travelled half a cell (mjrft:deform_travel):
#: at 10 and 5 cm/s an update every 7 and 13 steps, each well past the half cell (0.15 and
#: 0.05 mm), so float32 speeds decide as the engine's do.
TRAVEL_BLADE = BLADE.replace(
    '<numeric name="mjrft:deform_cell" data="0.0025"/>',
    '<numeric name="mjrft:deform_cell" data="0.0025"/><numeric name="mjrft:deform_travel" '
    'data="0.5"/>',
)


def follow(xml: str, ctrl: np.ndarray, nstep: int):
    """Steps nworld = len(ctrl) worlds on Warp (ctrl (nworld, nu) held), the engine's ground
    following each world's configurations; returns (Warp blocks, engine blocks, excavated
    volumes [m^3]) after nstep steps, each (nworld, ...); no intruder went below the bottom, the
    last pass's wrenches are the engine's, and so are the ground's counters (the volumes to
    rounding)."""
    plain = mujoco.MjModel.from_xml_string(xml)
    field = mw.WarpField(plain, device=DEVICE, low_speed="off")
    assert field.deforms
    mjd = mujoco.MjData(plain)
    m = mjw.put_model(plain)
    d = mjw.put_data(plain, mjd, nworld=len(ctrl))
    d.ctrl.assign(ctrl.astype(np.float32))
    cpu_model = mjrft.load_model(xml, low_speed="off")
    cpu = GranularField(cpu_model)
    cpu_d = [mujoco.MjData(cpu_model) for _ in ctrl]
    cpu_wrench = np.zeros((len(ctrl), plain.nbody, 6))
    with field.installed(m, d):
        for _ in range(nstep):
            time = d.time.numpy().copy()  # the pass runs at the step's start time
            mjw.step(m, d)
            for w, cd in enumerate(cpu_d):  # the configuration the step's pass followed
                world_kinematics(cd, d, w)
                cd.time = float(time[w])
                cpu_wrench[w] = cpu.wrench(cd)
        wrench = field.wrenches(d)
    np.testing.assert_array_equal(field.wrenches(d), wrench)  # leaving `installed` keeps them
    want = np.array([cpu.state_array(cd, "soil") for cd in cpu_d])
    excavated = np.array([cpu.soil(cd).counters["excavated"] for cd in cpu_d])
    assert np.all(field.below_ground(d) == -1)
    # the forces under the deformed ground: the same quadrature on the same states
    scale = np.abs(cpu_wrench).max()
    assert scale > 0.0
    np.testing.assert_allclose(wrench, cpu_wrench, rtol=0, atol=1e-12 * scale)
    # the work done: every counter, the relaxation's pair visits included
    counters = field.soil_counters(d)
    for name in SOIL_STATS:
        engine = [cpu.soil(cd).counters[name] for cd in cpu_d]
        np.testing.assert_allclose(counters[name], engine, rtol=COUNTER_RTOL, atol=0, err_msg=name)
    assert np.all(counters["visits"] > 0)
    got = field.soil_blocks(d)
    print("ground gap", np.abs(got - want).max(), "excavated", excavated)
    return got, want, excavated


@pytest.mark.parametrize(
    ("xml", "ctrl", "nstep"),
    [
        (PLATE, [[-0.008], [-0.004]], 60),
        (BLADE, [[0.1], [0.05]], 120),
        (WIDE_PLATE, [[-0.008], [-0.004]], 60),
        (WIDE_BLADE, [[0.1], [0.05]], 120),
        (TRAVEL_BLADE, [[0.1], [0.05]], 120),
    ],
    ids=["plate-press", "blade-drag", "cone-plate-press", "cone-blade-drag", "travel-blade-drag"],
)
def test_each_worlds_ground_is_the_engines(xml, ctrl, nstep):
    """A plate pressed 8 and 4 mm into the ground (its position servo's target), and a blade
    1 cm deep dragged at 10 and 5 cm/s: every world's ground (surface, compacted level, memory
    and the block's head) equals the engine's on the same configurations, and its volume is
    conserved."""
    got, want, excavated = follow(xml, np.array(ctrl), nstep)
    assert np.all(excavated > 1e-6)  # each world cut its footprint: the test has teeth
    assert not np.allclose(got[0], got[1])  # the worlds differ
    np.testing.assert_allclose(got, want, rtol=0, atol=GROUND_ATOL)
    n = (got.shape[1] - cs.SOIL_HEAD) // cs.SOIL_LEVELS
    for w in range(len(got)):
        volume = got[w, cs.SOIL_HEAD : cs.SOIL_HEAD + n].sum() * 0.0025**2
        assert abs(volume) <= VOLUME_RTOL * excavated[w]


def test_reset_starts_the_ground_over_in_the_worlds_given():
    """After a press, world 0 is reset: its ground is the initial surface again (and is pressed
    anew by the next steps) and the mechanism treatment's records of its plate's carriage are
    cleared; world 1 keeps both."""
    plain = mujoco.MjModel.from_xml_string(PLATE)
    field = mw.WarpField(plain, device=DEVICE)
    m = mjw.put_model(plain)
    d = mjw.put_data(plain, mujoco.MjData(plain), nworld=2)
    d.ctrl.assign(np.array([[-0.008], [-0.008]], dtype=np.float32))
    with field.installed(m, d):
        for _ in range(30):
            mjw.step(m, d)
        pressed = field.soil_blocks(d)
        assert np.all(np.abs(pressed[:, cs.SOIL_HEAD :]).max(axis=1) > 1e-3)
        mech = field._worlds_of(d).mech  # the records of the last pass (white box)
        records = mech.time.numpy().copy(), mech.qin.numpy().copy()
        assert np.all(records[0][:, 1] == 1.0) and np.all(np.abs(records[1]).max(axis=1) > 0.0)
        field.reset(d, [True, False])
        after = field.soil_blocks(d)
        assert np.all(after[0] == 0.0)
        np.testing.assert_array_equal(after[1], pressed[1])
        for arr, before in zip((mech.time, mech.qin), records, strict=True):
            assert np.all(arr.numpy()[0] == 0.0)
            np.testing.assert_array_equal(arr.numpy()[1], before[1])
        mjw.step(m, d)  # the plate is still down there: world 0 is pressed again
    assert np.abs(field.soil_blocks(d)[0, cs.SOIL_HEAD :]).max() > 1e-3


def test_a_pass_neither_copies_to_the_host_nor_allocates(monkeypatch):
    """What a CUDA graph of mjw.step needs from the field (docs/gpu.md): once prepare(d) ran, a
    pass with the ground, the mechanism treatment and the free-body treatment only launches
    kernels. On the CPU device: the pass runs with Warp's host copies and allocations refused."""
    xml = PLATE.replace(  # the plate's carriage, plus a free ball resting in the ground
        '<element objtype="geom" objname="foot" prm="300"/>',
        '<element objtype="geom" objname="foot" prm="300"/>'
        '<element objtype="geom" objname="ball" prm="100"/>',
    ).replace(
        "</body></worldbody>",
        '</body><body name="ball" pos="0.04 0.04 0"><freejoint/>'
        '<geom name="ball" size="0.005" contype="0" conaffinity="0"/></body></worldbody>',
    )
    plain = mujoco.MjModel.from_xml_string(xml)
    field = mw.WarpField(plain, device=DEVICE)
    assert (
        field.deforms and field.setup.stick_eligible.any() and field.setup.mechanism_eligible.any()
    )
    m = mjw.put_model(plain)
    d = mjw.put_data(plain, mujoco.MjData(plain), nworld=2)
    d.qvel.assign(np.tile([-0.05, 0.0, 0.0, -0.01, 0.0, 0.0, 0.0], (2, 1)).astype(np.float32))
    field.prepare(d)
    mjw.forward(m, d)
    field.passive(m, d)  # loads the kernel modules
    mjw.step(m, d)

    def refused(*args, **kwargs):
        raise AssertionError("the pass copied to the host or allocated")

    monkeypatch.setattr(wp.array, "numpy", refused)  # the class: every array's host copy
    for name in ("zeros", "empty", "full", "clone", "array", "synchronize"):
        monkeypatch.setattr(wp, name, refused)
    field.passive(m, d)
    monkeypatch.undo()
    assert np.abs(field.wrenches(d)).max() > 0.0
