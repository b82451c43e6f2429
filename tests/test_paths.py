"""One compiled pass, many callers: threads, the plain reference, the records it reads."""

from __future__ import annotations

import ctypes
import threading

import field_reference as ref
import mujoco
import numpy as np
import pytest

from mjrft.field import GranularField, layout, tables
from mjrft.field.state import DataState

SCENE = """
<mujoco>
  <option timestep="0.001" integrator="{integrator}"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <numeric name="mjrft:region" data="-0.2 -0.2 -0.3 0.2 0.2 0.1"/>
    <tuple name="mjrft:intruders">
      <element objtype="geom" objname="shell" prm="300"/>
      <element objtype="geom" objname="fin" prm="120"/>
      <element objtype="body" objname="ball" prm="200"/>
    </tuple>
  </custom>
  <worldbody>
    <body name="crab" pos="0 0 0.004">
      <freejoint/>
      <geom name="shell" type="ellipsoid" size="0.008 0.006 0.012" density="2500"/>
      <geom name="fin" type="box" size="0.006 0.001 0.004" pos="0.008 0 0.006" density="2500"/>
    </body>
    <body name="ball" pos="0.05 0 0.008">
      <joint type="slide" axis="0 0 1"/>
      <geom type="sphere" size="0.01" density="1500"/>
    </body>
  </worldbody>
</mujoco>"""
# Starts: a free body thrown in spinning (pure model, then implicit steps, slip and stick) and a
# body on a slide (never treated) sinking under its weight.
QVEL = {"thrown": (0.05, -0.02, -0.15, 3.0, -2.0, 1.5, -0.05), "resting": (0,) * 7}
# The reference sums NumPy-transformed element forces: the same physics in another order of
# floating-point operations (1e-16 per step), which the treatment's decisions may amplify.
PATH_RTOL = 1e-6


def model(integrator: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(SCENE.format(integrator=integrator))


def start(m: mujoco.MjModel, kind: str) -> mujoco.MjData:
    d = mujoco.MjData(m)
    d.qvel[:] = QVEL[kind]
    return d


def push(d: mujoco.MjData, i: int) -> None:
    """The user's part of xfrc_applied: assigned now and then, as a controller would."""
    if i % 40 == 0:
        d.xfrc_applied[1] = (0.01 * np.sin(i), 0.0, 0.05, 0.0, 1e-4, 0.0)
    if i == 120:
        d.xfrc_applied[:] = 0.0  # what the interactive viewer does before a perturbation


def run_compiled(m, kind, steps):
    fld = GranularField(m)
    d = start(m, kind)
    out = []
    with fld.installed():
        for i in range(steps):
            push(d, i)
            mujoco.mj_step(m, d)
            out.append((np.concatenate([d.qpos, d.qvel]), fld.last_decision[0]))
    return out, fld


def run_reference(m, kind, steps):
    reference = ref.ReferenceField(GranularField(m))
    d = start(m, kind)
    out = []
    mujoco.set_mjcb_passive(reference.apply)
    try:
        for i in range(steps):
            push(d, i)
            mujoco.mj_step(m, d)
            out.append((np.concatenate([d.qpos, d.qvel]), reference.decisions[0]))
    finally:
        mujoco.set_mjcb_passive(None)
    return out


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "RK4"])
@pytest.mark.parametrize("kind", ["thrown", "resting"])
def test_installed_pass_follows_the_plain_reference(integrator, kind):
    """The compiled installed pass (treatment, RK4 rule, ownership) against the same rules
    written plainly (field_reference.ReferenceField) as MuJoCo's passive callback."""
    m = model(integrator)
    steps = 240
    fast, fld = run_compiled(m, kind, steps)
    slow = run_reference(m, kind, steps)
    states = np.array([s for s, _ in fast])
    np.testing.assert_allclose(
        states, np.array([s for s, _ in slow]), rtol=PATH_RTOL, atol=PATH_RTOL * 1e-3
    )
    assert [int(k) for _, k in fast] == [k for _, k in slow]
    decided = {name for name in ("stuck", "slipping", "implicit") if fld.stats[name]}
    assert "stuck" in decided and (kind == "resting" or "implicit" in decided)
    assert np.ptp(states[:, 7]) > 1e-4  # the ball on its slide sank
    assert kind == "resting" or np.ptp(states[:, 2]) > 1e-3  # the thrown body moved


def _step_alone(m, kind, steps):
    fld = GranularField(m)
    d = start(m, kind)
    with fld.installed():
        for i in range(steps):
            push(d, i)
            mujoco.mj_step(m, d)
    return d


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_two_threads_step_two_mjdata_of_one_field_as_if_alone(integrator):
    """mj_step releases the GIL, so two threads run the field's pass at the same time; each
    MjData's state is its own, so each gets bit for bit what it gets stepped alone."""
    m = model(integrator)
    steps = 400
    alone = {kind: _step_alone(m, kind, steps) for kind in QVEL}
    fld = GranularField(m)
    datas = {kind: start(m, kind) for kind in QVEL}
    barrier = threading.Barrier(len(datas))

    def work(d):
        barrier.wait()
        for i in range(steps):
            push(d, i)
            mujoco.mj_step(m, d)

    with fld.installed():
        for d in datas.values():  # first sight registers each MjData (in Python, once)
            mujoco.mj_forward(m, d)
        threads = [threading.Thread(target=work, args=(d,)) for d in datas.values()]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    for kind, d in datas.items():
        np.testing.assert_array_equal(d.qpos, alone[kind].qpos, err_msg=kind)
        np.testing.assert_array_equal(d.qvel, alone[kind].qvel, err_msg=kind)
    assert fld.stats["calls"] >= 2 * steps


def test_records_round_trip_every_field():
    """What the compiled pass unpacks from the records is exactly the arrays packed into them."""
    import numba

    m = model("Euler")
    fld = GranularField(m)
    d = mujoco.MjData(m)
    st = DataState(fld._tables, (fld.last_wrench, fld.last_decision), d)

    @numba.njit
    def unpacked(model_address, entry_address):
        fm = tables.unpack_model(model_address)
        dd, s = tables.unpack_entry(fm, entry_address)
        return fm, dd, s

    fm, dd, s = unpacked(fld._tables.address, st.address)
    want_d = tables.MjDataArrays(
        d.xpos, d.xmat.reshape(-1, 3, 3), d.xipos, d.ximat.reshape(-1, 3, 3), d.cvel,
        d.subtree_com, d.geom_xpos, None, d.xfrc_applied, d.M, d.qvel, d.qacc, d.cdof, d.ctrl,
        d.act, d.actuator_length, d.actuator_velocity, d.actuator_force, d.actuator_moment,
        d.moment_rownnz, d.moment_rowadr, d.moment_colind, st.userdata,
    )  # fmt: skip
    for group, want in ((fm, fld._tables.arrays), (s, st.arrays), (dd, want_d)):
        assert group._fields == want._fields
        for name, got, value in zip(want._fields, group, want, strict=True):
            if value is None:  # d.time: checked through its address below
                continue
            if isinstance(value, np.ndarray):
                assert got.shape == value.shape and got.ctypes.data == value.ctypes.data, name
            else:
                assert got == value, name
    d.time = 0.125
    assert dd.time[0] == 0.125


def test_live_model_fields_and_data_time():
    """The pass reads opt.timestep and opt.integrator live (a user may change them between
    steps) and data.time at the address the layout computes."""
    m = model("Euler")
    fm = GranularField(m)._tables.arrays
    m.opt.timestep = 0.0025
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    assert fm.opt_timestep[0] == 0.0025 and fm.opt_integrator[0] == int(m.opt.integrator)
    d = mujoco.MjData(m)
    d.time = 3.5
    assert ctypes.c_double.from_address(layout.time_address(d)).value == 3.5


def test_a_wrong_struct_layout_is_refused_naming_the_mujoco_version(monkeypatch):
    m = model("Euler")
    real = layout.offset
    monkeypatch.setattr(layout, "offset", lambda s, f: real(s, f) + (8 if f == "timestep" else 0))
    with pytest.raises(layout.LayoutError, match=f"opt.timestep: MuJoCo {mujoco.__version__}"):
        layout.model_addresses(m)
