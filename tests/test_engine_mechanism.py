"""The C++ treatment of bodies in mechanisms (engine/mechanism.cc) against the numba one
(mjrft.field.mechanism), bit for bit.

Scenes with bodies in mechanisms in the medium (the standing and walking hexapod, the rigs, the
passive chain of tests/test_mechanism.py) are stepped with the installed numba field, whose pass
the test runs itself, step by step in passive.forward's order (pure_wrenches,
ownership.take_user_part, lowspeed.treat_all, then mechanism.treat_mechanisms), so that at each
compared pass a Bridge copy of the field's state is taken just before treat_mechanisms; the C++
TreatMechanisms then runs on the copy and every array it writes must equal numba's.

The Cholesky factorisations and solves run in the numba code's order, so parity is exact
(assert_array_equal), not within a tolerance.
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path

import mujoco
import numpy as np
import pytest
from engine_bridge import Bridge, library

from mjrft.field import lowspeed, mechanism, ownership, passive, rk4
from mjrft.field.evaluate import first_bad_body, pure_wrenches
from mjrft.field.numba_field import GranularField, load_plain  # the numba reference

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
_P = ctypes.c_void_p
#: Arrays TreatMechanisms writes (or keeps as caches), compared whole. mech_vec is compared in
#: rows 0 (u) and 2 (the holds' right-hand side): row 1 is a work row whose use differs (numba:
#: the medium's generalized acceleration; C++: also the pass's wrenches, numba's temporary).
COMPARED = (
    "wrench", "decision", "slow", "stats", "scratch", "mech_tau", "mech_time", "mech_prev",
    "mech_held", "mech_in", "mech_in_prev", "mech_in_force", "mech_in_held", "mech_R",
    "mech_key", "mech_M", "mech_cfg", "mech_hkey", "mech_L", "mech_J", "mech_X", "mech_A",
    "mech_S",
)  # fmt: skip


@pytest.fixture(scope="module")
def lib():
    so = library(sanitize=os.environ.get("MJRFT_ASAN") == "1")
    so.mjrft_test_treat_mechanisms.argtypes = [_P, _P, _P, _P]
    so.mjrft_test_treat_mechanisms.restype = None
    so.mjrft_test_mech_cholesky.argtypes = [_P, ctypes.c_int, ctypes.c_int, ctypes.c_double]
    so.mjrft_test_mech_cholesky.restype = ctypes.c_int
    so.mjrft_test_mech_cho_solve.argtypes = [_P, ctypes.c_int, ctypes.c_int, _P]
    so.mjrft_test_mech_cho_solve.restype = None
    so.mjrft_test_actuator_forces.argtypes = [_P, _P, _P, _P]
    so.mjrft_test_actuator_forces.restype = None
    so.mjrft_test_full_inertia.argtypes = [_P, _P, _P]
    so.mjrft_test_full_inertia.restype = None
    return so


def _ptr(a: np.ndarray) -> ctypes.c_void_p:
    return ctypes.c_void_p(a.ctypes.data)


class Comparer:
    """Runs the installed pass of a numba field in Python (passive.forward, INSTALLED, without
    a deforming ground), comparing the C++ TreatMechanisms at every `every`-th pass."""

    def __init__(self, lib, model, data, fld, every: int = 1) -> None:
        self.lib, self.model, self.data, self.fld, self.every = lib, model, data, fld, every
        self.rk4 = model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
        self.dt = float(model.opt.timestep)
        self.passes = 0
        self.compared = 0
        self.mismatch: list[str] = []
        self.worst: dict[str, float] = {}
        assert not fld._tables.arrays.soil
        fld._native = False  # every pass through Python (the guard's trampoline), into _run
        fld._run = self._run

    def _run(self, st, data, mode) -> None:
        # No mujoco function is called here: inside MuJoCo's callback any binding call would
        # reset the binding's error escape (GranularField.apply_passive).
        assert mode == passive.INSTALLED
        fm = self.fld._tables.arrays
        m_rec, e_rec = self.fld._tables.address, st.address
        s = st.arrays
        bad = first_bad_body(m_rec, e_rec)
        s.status[0] = passive.OK if bad < 0 else -1 - bad
        if bad >= 0:
            self.mismatch.append(f"non-finite body {bad}")
            return
        s.cull[:] = 0
        s.keep[:] = 0
        s.frz[:] = 0
        s.slow[:] = 0
        held = False
        if self.rk4:
            held = rk4.stage_held(data.time, self.dt, s.rk4)
            if held:
                rk4.read_modes(s.rk4, s.keep, s.frz)
        evaluated, acting = pure_wrenches(m_rec, e_rec)
        if held:
            ne, na = passive.frozen_wrenches(m_rec, e_rec)
            evaluated += ne
            acting += na
            if fm.treat:
                rk4.guard_stage(m_rec, e_rec)
        if evaluated or not held:
            s.stats[0] += 1
        s.stats[1] += evaluated
        s.stats[2] += acting
        ownership.take_user_part(m_rec, e_rec)
        if not held:
            s.decision[:] = lowspeed.PURE
            s.frozen[:] = 0.0
            if fm.treat:
                lowspeed.treat_all(m_rec, e_rec, s.user)
            if fm.mech:
                self._treat(st, data)
            rk4.write_modes(s.rk4, s.decision, s.slow, s.frozen, lowspeed.IMPLICIT)
            if fm.treat and self.rk4:
                rk4.begin_step(m_rec, e_rec)
        ownership.write_rows(m_rec, e_rec)
        passive.report(s.decision, s.wrench, fm.tbody_bodyid, s.report_decision,
                       s.report_wrench, True)  # fmt: skip

    def _treat(self, st, data) -> None:
        compare = self.passes % self.every == 0
        self.passes += 1
        bridge = Bridge(self.fld, data) if compare else None
        mechanism.treat_mechanisms(self.fld._tables.address, st.address)
        if bridge is None:
            return
        self.lib.mjrft_test_treat_mechanisms(*bridge.pointers(self.model, data))
        self.compared += 1
        s = st.arrays
        for name in COMPARED:
            self._check(name, bridge.arrays[name], getattr(s, name), data.time)
        for row in (0, 2):
            self._check(f"mech_vec[{row}]", bridge.arrays["mech_vec"][row], s.mech_vec[row],
                        data.time)  # fmt: skip

    def _check(self, name, got, want, time) -> None:
        same = np.array_equal(got, want, equal_nan=True)
        if not same:
            diff = np.abs(np.asarray(got, float) - np.asarray(want, float))
            scale = np.abs(np.asarray(want, float)).max() or 1.0
            rel = float(np.nanmax(diff) / scale)
            self.worst[name] = max(self.worst.get(name, 0.0), rel)
            if len(self.mismatch) < 20:
                self.mismatch.append(f"t={time:.4f} {name}: max rel diff {rel:.3g}")

    def stats(self) -> np.ndarray:
        return self.fld._state(self.data).arrays.stats.copy()


def run_scene(lib, model, data, fld, steps: int, every: int = 1, each=None) -> Comparer:
    cmp = Comparer(lib, model, data, fld, every)
    with fld.installed():
        for i in range(steps):
            if each is not None:
                each(i, data)
            mujoco.mj_step(model, data)
    assert cmp.mismatch == [], cmp.mismatch
    assert cmp.compared > 0
    return cmp


def hexapod(integrator=mujoco.mjtIntegrator.mjINT_EULER, walking=False):
    model = mujoco.MjModel.from_xml_path(str(MODELS / "hexapod_sand.xml"))
    model.opt.integrator = integrator
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    if not walking:
        data.ctrl[:] = 0.0  # gait stopped: each hip servo holds its angle
        data.qvel[:] = 0.0
    return model, data, GranularField(model, low_speed="stick")


# --- building blocks on seeded random inputs ------------------------------------------------


def test_cholesky_and_its_solve_match_numba_bit_for_bit(lib):
    rng = np.random.default_rng(0)
    for n, lda in ((1, 1), (5, 5), (12, 18), (30, 30)):
        b = rng.normal(size=(n, n + 2))
        a = np.zeros((lda, lda))
        a[:n, :n] = b @ b.T
        eps = 1e-12 * a.diagonal().max()
        want, got = a.copy(), a.copy()
        ok = mechanism.cholesky(want, n, eps)
        assert lib.mjrft_test_mech_cholesky(_ptr(got), lda, n, eps) == int(ok) == 1
        np.testing.assert_array_equal(got, want)
        x = rng.normal(size=lda)
        xw, xg = x.copy(), x.copy()
        mechanism.cho_solve(want, n, xw)
        lib.mjrft_test_mech_cho_solve(_ptr(got), lda, n, _ptr(xg))
        np.testing.assert_array_equal(xg, xw)
    # not positive definite: both refuse at the same pivot
    a = np.diag([1.0, -1.0, 2.0])
    want, got = a.copy(), a.copy()
    assert not mechanism.cholesky(want, 3, 0.0)
    assert lib.mjrft_test_mech_cholesky(_ptr(got), 3, 3, 0.0) == 0
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("name", ["hexapod_sand", "plate_rig", "ellipsoid_pitch", "wheel_rig"])
def test_actuator_forces_and_full_inertia_match_numba(lib, name):
    model = mujoco.MjModel.from_xml_path(str(MODELS / f"{name}.xml"))
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    fld = GranularField(model)
    rng = np.random.default_rng(1)
    for _ in range(5):
        data.qpos[:] += 0.01 * rng.normal(size=model.nq)
        data.qvel[:] = rng.normal(size=model.nv)
        data.ctrl[:] += rng.normal(size=model.nu)
        data.act[:] += 0.1 * rng.normal(size=model.na)
        mujoco.mj_forward(model, data)
        st = fld._state(data)
        bridge = Bridge(fld, data)
        want = np.empty(model.nu)
        mechanism.actuator_forces(fld._tables.address, st.address, want)
        got = np.empty(model.nu)
        m_p, d_p, t_p, _ = bridge.pointers(model, data)
        lib.mjrft_test_actuator_forces(m_p, d_p, t_p, _ptr(got))
        np.testing.assert_array_equal(got, want)
        full = np.empty((model.nv, model.nv))
        lib.mjrft_test_full_inertia(m_p, d_p, _ptr(full))
        ref = np.empty((model.nv, model.nv))
        mujoco.mj_fullM(model, data, ref)
        np.testing.assert_array_equal(full, ref)


# --- whole passes on scenes -----------------------------------------------------------------


@pytest.mark.parametrize(
    "integrator",
    [mujoco.mjtIntegrator.mjINT_EULER, mujoco.mjtIntegrator.mjINT_IMPLICITFAST],
    ids=["Euler", "implicitfast"],
)
def test_a_standing_hexapod(lib, integrator):
    model, data, fld = hexapod(integrator)
    rng = np.random.default_rng(3)

    def nudge(i, data):  # the hip servos' set angles nudged now and then: holds re-made
        if i % 50 == 49:
            data.act[:] += 0.05 * rng.normal(size=model.na)
        if i % 7 == 3:  # a repeated pass at the same time reads what the first one read
            mujoco.mj_forward(model, data)

    cmp = run_scene(lib, model, data, fld, 400, each=nudge)
    stats = cmp.stats()
    assert stats[3] > 0  # bodies held
    assert cmp.compared == cmp.passes == 457  # 400 steps, 57 repeated passes


def test_a_walking_hexapod(lib):
    model, data, fld = hexapod(walking=True)
    cmp = run_scene(lib, model, data, fld, 600)
    stats = cmp.stats()
    assert stats[4] > 0  # holds the medium could not supply: feet slipping


@pytest.mark.parametrize("rig", ["plate_rig", "ellipsoid_pitch", "wheel_rig"])
def test_a_rig(lib, rig):
    model = mujoco.MjModel.from_xml_path(str(MODELS / f"{rig}.xml"))
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    fld = GranularField(model, n_triangles=400, low_speed="stick")
    stop = 300

    def stop_it(i, data):  # moving, then stopped mid-stroke (held)
        if i == stop:
            data.ctrl[:] = 0.0

    cmp = run_scene(lib, model, data, fld, 600, each=stop_it)
    assert cmp.stats()[3] > 0  # held once stopped


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_a_passive_chain(lib, integrator):
    from test_mechanism import CHAIN

    model = mujoco.MjModel.from_xml_string(CHAIN.format(dt=1e-3, integrator=integrator))
    data = mujoco.MjData(model)
    data.qvel[:6] = [0.02, 0.0, -0.2, 0.0, 1.0, 0.0]  # thrown in, tumbling
    fld = GranularField(model)
    cmp = run_scene(lib, model, data, fld, 800)
    assert cmp.stats()[3] > 0


def test_the_comparison_can_fail(lib):
    """One ulp more on the pure wrenches of the C++ copy's bodies is reported."""
    model, data, fld = hexapod()
    cmp = Comparer(lib, model, data, fld)
    bridge_init = Bridge.__init__

    def init(self, field, d, copy=True):
        bridge_init(self, field, d, copy)
        w = self.arrays["wrench"]
        w[:] = np.nextafter(w, np.inf)

    Bridge.__init__ = init
    try:
        with fld.installed():
            for _ in range(20):
                mujoco.mj_step(model, data)
    finally:
        Bridge.__init__ = bridge_init
    assert cmp.compared == 20 and any("wrench" in line for line in cmp.mismatch)
