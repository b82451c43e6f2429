"""The C++ low-speed treatment and RK4 stage rules (engine/lowspeed.h, engine/rk4.h) against numba.

Two kinds of checks, every one bit for bit (``assert_array_equal``): the helpers (m_dot, solve6,
step_work, stick_fraction, transverse_basis, world_inertia, adds_no_energy, step_balance and the
record rules) on seeded random inputs, called in numba and in C++; and real scenes (free bodies
dropped, resting, thrown and lowered by a user force, under Euler, implicitfast and RK4), where a
passive callback runs the installed pass (mjrft.field.passive.forward, mode INSTALLED) step by
step from the numba functions and, at every rule of this port, runs the C++ function on a copy
of the same state (``engine_bridge.Bridge``) before the numba one, then compares what each
wrote. The callback's pass is checked to be the installed field's own: the trajectory it drives
equals, bit for bit, the one ``GranularField.installed()`` drives.
"""

from __future__ import annotations

import ctypes
import math

import engine_bridge as eb
import mujoco
import numpy as np
import pytest

import mjrft
from mjrft.field.numba_field import GranularField, load_plain
from mjrft import simulate
from mjrft.field import evaluate, lowspeed, mechanism, ownership, passive, rk4
from mjrft.field.tables import RK4_BODY, RK4_HEAD

MODELS = eb.ROOT / "models"
P = ctypes.c_void_p
D = ctypes.c_double
INTEGRATORS = {
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
}


@pytest.fixture(scope="module")
def lib():
    lib = eb.library()
    lib.mjrft_test_m_dot.restype = D
    lib.mjrft_test_m_dot.argtypes = [P, P, D, P]
    lib.mjrft_test_solve6.argtypes = [P, P, P]
    lib.mjrft_test_step_work.restype = D
    lib.mjrft_test_step_work.argtypes = [P, P, P, P, D, D, ctypes.c_int]
    lib.mjrft_test_stick_fraction.restype = D
    lib.mjrft_test_stick_fraction.argtypes = [P, P, P, D, D, D, ctypes.c_int]
    lib.mjrft_test_transverse_basis.argtypes = [P, D, P, P, D, P]
    lib.mjrft_test_world_inertia.argtypes = [P, P, P, P]
    lib.mjrft_test_adds_no_energy.argtypes = [P, P, P, D, P, P, D, ctypes.c_int]
    lib.mjrft_test_treat_all.argtypes = [P, P, P, P, P]
    lib.mjrft_test_treat_body.restype = ctypes.c_int64
    lib.mjrft_test_treat_body.argtypes = [P, P, P, P, ctypes.c_int, P, D, ctypes.c_int, P, P, P]
    lib.mjrft_test_stage_held.argtypes = [D, D, P]
    lib.mjrft_test_read_modes.argtypes = [P, P, P, P]
    lib.mjrft_test_write_modes.argtypes = [P, P, P, P, P]
    lib.mjrft_test_begin_step.argtypes = [P, P, P, P]
    lib.mjrft_test_step_balance.restype = D
    lib.mjrft_test_step_balance.argtypes = [P, P, ctypes.c_int, D, D, P]
    lib.mjrft_test_guard_stage.argtypes = [P, P, P, P]
    return lib


def ptr(a: np.ndarray) -> ctypes.c_void_p:
    assert a.flags.c_contiguous
    return P(a.ctypes.data)


def _spd(rng, n):
    a = rng.normal(size=(n, n))
    return a @ a.T + n * np.eye(n) * 10.0 ** rng.uniform(-3, 1)


def _rotation(rng):
    q = rng.normal(size=4)
    x = np.zeros(9)
    mujoco.mju_quat2Mat(x, q / np.linalg.norm(q))
    return x.reshape(3, 3)


# ------------------------------------------------------------------ helpers, random inputs
def test_helpers_equal_numba_bit_for_bit(lib):
    """m_dot, solve6, step_work, world_inertia, transverse_basis and adds_no_energy on seeded
    random inputs over many scales (numba called directly with the argument types its
    compiled pass uses)."""
    rng = np.random.default_rng(11)
    for i in range(300):
        scale = 10.0 ** rng.uniform(-8, 3, size=6)
        a, b = rng.normal(size=6) * scale, rng.normal(size=6) * scale[::-1]
        mass = 10.0 ** rng.uniform(-4, 3)
        x = _rotation(rng)
        inertia = 10.0 ** rng.uniform(-9, 0, size=3)
        iw, ii = lowspeed.world_inertia(x, inertia)
        iw_c, ii_c = np.empty((3, 3)), np.empty((3, 3))
        lib.mjrft_test_world_inertia(ptr(x), ptr(inertia), ptr(iw_c), ptr(ii_c))
        np.testing.assert_array_equal(iw_c, iw)
        np.testing.assert_array_equal(ii_c, ii)
        assert lib.mjrft_test_m_dot(ptr(a), ptr(b), mass, ptr(iw)) == lowspeed.m_dot(a, b, mass, iw)

        mat = _spd(rng, 6) if i % 3 else rng.normal(size=(6, 6))
        if i % 50 == 0:
            mat[:, 2] = 0.0  # singular: non-finite, the same non-finite
        rhs = rng.normal(size=6)
        a_c, rhs_c, x_c = mat.copy(), rhs.copy(), np.empty(6)
        lib.mjrft_test_solve6(ptr(a_c), ptr(rhs_c), ptr(x_c))
        a_n, rhs_n = mat.copy(), rhs.copy()
        np.testing.assert_array_equal(x_c, lowspeed.solve6(a_n, rhs_n))
        np.testing.assert_array_equal(a_c, a_n)
        np.testing.assert_array_equal(rhs_c, rhs_n)

        w, tw, end, other = (rng.normal(size=6) * 10.0 ** rng.uniform(-6, 2) for _ in range(4))
        dt = 10.0 ** rng.uniform(-5, -1)
        for semi in (False, True):
            assert lib.mjrft_test_step_work(
                ptr(w), ptr(tw), ptr(end), ptr(other), mass, dt, semi
            ) == lowspeed.step_work(w, tw, end, other, mass, dt, semi)
            got = lib.mjrft_test_adds_no_energy(
                ptr(w), ptr(tw), ptr(other), mass, ptr(iw), ptr(ii), dt, semi
            )
            assert bool(got) == lowspeed.adds_no_energy(w, (tw, other, mass, iw, ii), dt, semi)

        mm = np.zeros((6, 6))
        mm[:3, :3] = mass * np.eye(3)
        mm[3:, 3:] = iw
        n = math.sqrt(lowspeed.m_dot(a, a, mass, iw))
        basis = np.empty((6, 6))
        lib.mjrft_test_transverse_basis(ptr(a), mass, ptr(iw), ptr(mm), n, ptr(basis))
        np.testing.assert_array_equal(basis, lowspeed.transverse_basis(a, mass, iw, mm, n))


def test_stick_fraction_equals_numba_bit_for_bit(lib):
    """The stick fraction at random states, both integrators' balances: the full stick, the
    quadratic's root from either branch, and rounding at rest."""
    rng = np.random.default_rng(5)
    branches = set()
    for i in range(2000):
        mass = 10.0 ** rng.uniform(-3, 2)
        dt = 10.0 ** rng.uniform(-4, -2)
        iw = _spd(rng, 3) * 10.0 ** rng.uniform(-8, -3)
        tw = rng.normal(size=6) * 10.0 ** rng.uniform(-7, 0)
        other = np.zeros(6)
        other[:3] = rng.normal(size=3) * mass * 10.0
        other[3:] = rng.normal(size=3) * 1e-6
        free = tw + dt * np.concatenate([other[:3] / mass, np.linalg.solve(iw, other[3:])])
        if i % 7 == 0:
            free = rng.normal(size=6) * 10.0 ** rng.uniform(-7, 0)  # any other free twist
        stick = -np.concatenate([mass * free[:3], iw @ free[3:]]) / dt
        n2 = lowspeed.m_dot(free, free, mass, iw)
        for semi in (False, True):
            want = lowspeed.stick_fraction(stick, tw, other, mass, n2, dt, semi)
            got = lib.mjrft_test_stick_fraction(ptr(stick), ptr(tw), ptr(other), mass, n2, dt, semi)
            assert got == want or (math.isnan(got) and math.isnan(want))
            branches.add("full" if want == 1.0 else "part")
    assert branches == {"full", "part"}


def test_step_balance_and_record_rules_equal_numba(lib):
    """step_balance on random blocks for passes 2-4; stage_held on the stage-time sequences of
    RK4 steps and on other patterns; read_modes and write_modes on random records."""
    rng = np.random.default_rng(3)
    for _ in range(500):
        blk = rng.normal(size=RK4_BODY) * 10.0 ** rng.uniform(-6, 1)
        w = rng.normal(size=6) * 10.0 ** rng.uniform(-6, 1)
        mass, h = 10.0 ** rng.uniform(-3, 2), 10.0 ** rng.uniform(-4, -2)
        for n in (2, 3, 4):
            size = np.zeros(1)
            p = lib.mjrft_test_step_balance(ptr(blk), ptr(w), n, mass, h, ptr(size))
            assert (p, size[0]) == rk4.step_balance(blk, w, n, mass, h)
    # stage_held: four passes of each step (t0, t0 + h/2 twice, t0 + h), a repeated pass, a jump
    h = 0.0013
    rec_n, rec_c = np.zeros(2), np.zeros(2)
    t0, seen = 0.0, []
    for step in range(40):
        times = [t0, t0 + 0.5 * h, t0 + 0.5 * h, t0 + 1.0 * h]
        if step % 9 == 4:
            times.insert(2, t0 + 0.5 * h)  # a user's extra pass
        if step % 11 == 5:
            times = times[:2]  # a step cut short
        for t in times:
            got = lib.mjrft_test_stage_held(t, h, ptr(rec_c))
            want = rk4.stage_held(t, h, rec_n)
            assert bool(got) == want
            np.testing.assert_array_equal(rec_c, rec_n)
            seen.append(want)
        t0 = t0 + 1.0 * h  # mj_RungeKutta's t0 + h
    assert True in seen and False in seen
    # read_modes / write_modes
    bridge_t = eb.Tables()
    for ntb in (1, 3, 7):
        bridge_t.ntbody = ntb
        rec = rng.normal(size=RK4_HEAD + RK4_BODY * ntb)
        rec[RK4_HEAD::RK4_BODY] = rng.integers(0, 3, size=ntb).astype(float)
        keep_c, frz_c = np.zeros(ntb, np.int64), np.zeros(ntb, np.int64)
        keep_n, frz_n = keep_c.copy(), frz_c.copy()
        lib.mjrft_test_read_modes(ctypes.byref(bridge_t), ptr(rec), ptr(keep_c), ptr(frz_c))
        rk4.read_modes(rec, keep_n, frz_n)
        np.testing.assert_array_equal(keep_c, keep_n)
        np.testing.assert_array_equal(frz_c, frz_n)
        decision = rng.integers(0, 4, size=ntb).astype(np.int64)
        slow = rng.integers(0, 2, size=ntb).astype(np.int64)
        frozen = rng.normal(size=(ntb, 12))
        rec_c = rec.copy()
        lib.mjrft_test_write_modes(
            ctypes.byref(bridge_t), ptr(rec_c), ptr(decision), ptr(slow), ptr(frozen)
        )
        rk4.write_modes(rec, decision, slow, frozen, lowspeed.IMPLICIT)
        np.testing.assert_array_equal(rec_c, rec)


# ------------------------------------------------------------------ the pass, mirrored
class Mirror:
    """The installed pass (passive.forward, INSTALLED) run from its numba parts in MuJoCo's
    passive callback, with this port's C++ rules run beside the numba ones on a copy of the
    state at each rule, and what they write compared.

    A mismatch is recorded, not raised (an exception inside the callback must not cross
    MuJoCo); ``check()`` raises the first one after the run. ``counts`` says how often each
    rule was compared and ``decisions`` which decisions were seen.
    """

    def __init__(self, lib, fld: GranularField, model, data) -> None:
        self.lib, self.fld, self.model, self.data = lib, fld, model, data
        self.st = fld._states.of(data)
        self.s = self.st.arrays
        self.bridge = eb.Bridge(fld, data)
        self.args = self.bridge.pointers(model, data)
        self.mr, self.er = fld._tables.address, self.st.address
        self.fm = fld._tables.arrays
        assert not self.fm.soil  # the deforming ground's update is not mirrored here
        self.errors: list[str] = []
        self.counts = {
            k: 0
            for k in (
                "stage_held",
                "read_modes",
                "guard_stage",
                "treat_body",
                "treat_all",
                "write_modes",
                "begin_step",
            )
        }
        self.decisions: set[int] = set()
        self.held = 0

    def sync(self) -> None:
        """The bridge's State arrays := the numba FieldData arrays (and soil block)."""
        for _, name in eb.state_arrays():
            if name in ("xfrc_last", "fresh"):  # the engine's own records: numba has none
                continue
            src = self.st.userdata if name == "soil" else getattr(self.s, name)
            np.copyto(self.bridge.arrays[name], src)

    def same(self, rule: str, names: tuple[str, ...], extra=()) -> None:
        self.counts[rule] += 1
        for name in names:
            got, want = self.bridge.arrays[name], getattr(self.s, name)
            if not np.array_equal(got, want, equal_nan=True):
                where = f"{rule} at t={self.data.time!r}"
                self.errors.append(f"{where}: s.{name} differs:\n C++ {got!r}\n numba {want!r}")
        for what, got, want in extra:
            if got != want:
                self.errors.append(f"{rule} at t={self.data.time!r}: {what} C++ {got} numba {want}")

    def __call__(self, model, data) -> None:
        if data._address != self.data._address:
            return
        try:
            self.forward()
        except Exception as e:  # reported after the run
            self.errors.append(f"exception in the pass: {e!r}")

    def forward(self) -> None:
        lib, s, mr, er, fm, bridge = self.lib, self.s, self.mr, self.er, self.fm, self.bridge
        model, data = self.model, self.data
        m, d, t, st = self.args
        bad = evaluate.first_bad_body(mr, er)
        s.status[0] = passive.OK if bad < 0 else -1 - bad
        if bad >= 0:
            return
        s.cull[:] = 0
        s.keep[:] = 0
        s.frz[:] = 0
        s.slow[:] = 0
        held = False
        if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
            self.sync()
            rec = bridge.arrays["rk4"]
            got = bool(lib.mjrft_test_stage_held(data.time, model.opt.timestep, ptr(rec)))
            held = rk4.stage_held(data.time, model.opt.timestep, s.rk4)
            self.same("stage_held", ("rk4",), [("held", got, held)])
            if held:
                self.sync()
                lib.mjrft_test_read_modes(
                    t,
                    ptr(bridge.arrays["rk4"]),
                    ptr(bridge.arrays["keep"]),
                    ptr(bridge.arrays["frz"]),
                )
                rk4.read_modes(s.rk4, s.keep, s.frz)
                self.same("read_modes", ("keep", "frz"))
        evaluated, acting = evaluate.pure_wrenches(mr, er)
        if held:
            ne, na = passive.frozen_wrenches(mr, er)
            evaluated += ne
            acting += na
            if fm.treat:
                self.sync()
                got = lib.mjrft_test_guard_stage(m, d, t, st)
                want = rk4.guard_stage(mr, er)
                self.held += want
                self.same("guard_stage", ("wrench", "rk4"), [("held", got, want)])
        if evaluated or not held:
            s.stats[0] += 1
        s.stats[1] += evaluated
        s.stats[2] += acting
        ownership.take_user_part(mr, er)
        if not held:
            s.decision[:] = lowspeed.PURE
            s.frozen[:] = 0.0
            if fm.treat:
                self.treat_bodies()
                self.sync()
                lib.mjrft_test_treat_all(m, d, t, st, ptr(bridge.arrays["user"]))
                lowspeed.treat_all(mr, er, s.user)
                self.same("treat_all", ("wrench", "decision", "frozen", "slow", "stats", "scratch"))
                self.decisions.update(int(x) for x in s.decision)
            if fm.mech:
                mechanism.treat_mechanisms(mr, er)
            self.sync()
            lib.mjrft_test_write_modes(
                t,
                ptr(bridge.arrays["rk4"]),
                ptr(bridge.arrays["decision"]),
                ptr(bridge.arrays["slow"]),
                ptr(bridge.arrays["frozen"]),
            )
            rk4.write_modes(s.rk4, s.decision, s.slow, s.frozen, lowspeed.IMPLICIT)
            self.same("write_modes", ("rk4",))
            if fm.treat and model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
                self.sync()
                lib.mjrft_test_begin_step(m, d, t, st)
                rk4.begin_step(mr, er)
                self.same("begin_step", ("rk4",))
        ownership.write_rows(mr, er)

    def treat_bodies(self) -> None:
        """treat_body of each body treat_all treats, alone: its wrench, decision, twist and the
        energy terms ab (which decide only through signs, so a difference in their rounding
        would rarely show in treat_all's outputs). s.scratch is restored after."""
        s, fm, model = self.s, self.fm, self.model
        dt = model.opt.timestep
        semi = model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4
        scratch = s.scratch.copy()
        m, d, t, st = self.args
        for k in range(len(fm.tbody_bodyid)):
            b = int(fm.tbody_bodyid[k])
            if not fm.tbody_treat[k] or not dt > 0.0 or not evaluate.in_play(self.mr, self.er, k):
                continue
            self.sync()
            out = [np.zeros(6), np.zeros(2), np.zeros(6)]
            want_w, want_ab, want_tw = s.wrench[b].copy(), out[1].copy(), out[2].copy()
            got_w = want_w.copy()
            got = self.lib.mjrft_test_treat_body(
                m,
                d,
                t,
                st,
                k,
                ptr(self.bridge.arrays["user"][b]),
                dt,
                semi,
                ptr(got_w),
                ptr(out[1]),
                ptr(out[2]),
            )
            want = lowspeed.treat_body(
                self.mr, self.er, k, s.user[b].copy(), dt, semi, want_w, want_ab, want_tw
            )
            self.counts["treat_body"] += 1
            for what, g, w in (
                ("decision", got, want),
                ("wrench", got_w, want_w),
                ("ab", out[1], want_ab),
                ("twist", out[2], want_tw),
            ):
                if not np.array_equal(g, w):
                    self.errors.append(
                        f"treat_body {k} at t={self.data.time!r}: {what} C++ {g!r} numba {w!r}"
                    )
        s.scratch[:] = scratch

    def check(self) -> None:
        if self.errors:
            raise AssertionError(f"{len(self.errors)} mismatches; first:\n" + self.errors[0])


def _run(lib, make, steps: int, drive=None, installed_check: bool = True):
    """Run a scene through the mirrored pass; returns the Mirror. make() -> (model, data);
    drive(i, model, data) sets inputs before step i. With installed_check, the same run under
    GranularField.installed() must give the same trajectory, bit for bit."""
    model, data = make()
    fld = GranularField(model)
    mirror = Mirror(lib, fld, model, data)
    traj = []
    mujoco.set_mjcb_passive(mirror)
    try:
        for i in range(steps):
            if drive is not None:
                drive(i, model, data)
            mujoco.mj_step(model, data)
            traj.append(np.concatenate([data.qpos, data.qvel]))
    finally:
        mujoco.set_mjcb_passive(None)
    mirror.check()
    if installed_check:
        model2, data2 = make()
        fld2 = GranularField(model2)
        with fld2.installed():
            for i in range(steps):
                if drive is not None:
                    drive(i, model2, data2)
                mujoco.mj_step(model2, data2)
                np.testing.assert_array_equal(np.concatenate([data2.qpos, data2.qvel]), traj[i])
    return mirror


THROWN = """
<mujoco>
  <option timestep="{dt}" integrator="{integrator}"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <tuple name="mjrft:intruders"><element objtype="geom" objname="shell" prm="300"/></tuple>
  </custom>
  <worldbody>
    <body name="crab" pos="0 0 {z}">
      <freejoint/>
      <geom name="shell" type="ellipsoid" size="0.008 0.006 0.012" density="{density}"/>
    </body>
  </worldbody>
</mujoco>"""


def _thrown(integrator: str, lowered: bool = False, dt: float = 0.001):
    """tests/golden_runs.py's thrown and lowered ellipsoids: every decision on a free body."""
    xml = THROWN.format(
        integrator=integrator,
        dt=dt,
        density=2500 if lowered else 8000,
        z=0.0125 if lowered else 0.004,
    )

    def make():
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        data.qvel[:] = (0, 0, 0, 0.2, -0.1, 0) if lowered else (0.3, -0.1, -0.5, 4.0, -2.0, 6.0)
        return model, data

    def drive(i, model, data):  # the user holds it, then lets go over 0.5 s
        if lowered:
            weight = float(model.body_mass[1]) * 9.81
            data.xfrc_applied[1] = (0, 0, weight * max(0.0, 1.0 - i / 500), 0, 0, 0)

    return make, drive


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_thrown_ellipsoid_equals_numba(lib, integrator):
    """A dense ellipsoid thrown spinning into the medium, then settling: pure, implicit, slip
    and stick decisions, and (RK4) held, frozen and guarded stages."""
    make, drive = _thrown(integrator)
    mirror = _run(lib, make, 700, drive)
    assert mirror.counts["treat_all"] >= 700
    assert mirror.decisions == {lowspeed.PURE, lowspeed.STICK, lowspeed.SLIP, lowspeed.IMPLICIT}
    if integrator == "RK4":
        assert mirror.counts["guard_stage"] >= 3 * 600
        assert mirror.counts["begin_step"] >= 700


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_lowered_ellipsoid_equals_numba(lib, integrator):
    """A light ellipsoid lowered by a user force (the user part of xfrc_applied in the
    treatment's balance), then released to settle."""
    make, drive = _thrown(integrator, lowered=True)
    mirror = _run(lib, make, 800, drive)
    assert lowspeed.STICK in mirror.decisions and lowspeed.PURE in mirror.decisions


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_dropped_sphere_equals_numba(lib, integrator):
    """models/sphere_drop.xml (2000 triangles) released 1 mm above the surface: it falls in,
    is stopped and rests."""

    def make():
        model = load_plain(str(MODELS / "sphere_drop.xml"))
        model.opt.integrator = INTEGRATORS[integrator]
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        return model, data

    mirror = _run(lib, make, 400)
    assert lowspeed.STICK in mirror.decisions


RESTING = """<mujoco><option timestep="0.002" integrator="{integrator}">
  <flag contact="disable"/></option><custom>
  <text name="mjrft:material" data="glass_beads"/>
  <tuple name="mjrft:intruders"><element objtype="geom" objname="box" prm="400"/>
    <element objtype="geom" objname="ball" prm="300"/></tuple></custom>
  <worldbody>
    <body name="box" pos="0 0 0.004" euler="3 -2 10"><freejoint/>
      <geom name="box" type="box" size="0.02 0.015 0.008" density="2000"/></body>
    <body name="ball" pos="0.2 0 0.03"><freejoint/>
      <geom name="ball" type="sphere" size="0.01" density="4000"/></body>
  </worldbody></mujoco>"""


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_resting_box_and_falling_ball_equal_numba(lib, integrator):
    """Two tagged free bodies: a tilted box half sunk, settling and resting, and a ball out of
    the medium (culled: not in play) that falls in later, nudged by a user torque."""

    def make():
        model = mujoco.MjModel.from_xml_string(RESTING.format(integrator=integrator))
        return model, mujoco.MjData(model)

    def drive(i, model, data):
        data.xfrc_applied[1, 3:] = (0.0, 2e-4 * math.sin(0.05 * i), 0.0)

    mirror = _run(lib, make, 300, drive)
    assert lowspeed.STICK in mirror.decisions


def test_random_states_every_decision(lib):
    """tests/test_lowspeed.py's random states around rest and at speed with user forces, one
    installed pass each (mj_forward), both integrator families: all four decisions."""
    xml = THROWN.format(integrator="Euler", dt=0.001, density=2500, z=0.0)
    for integrator in ("Euler", "RK4"):
        model = mujoco.MjModel.from_xml_string(xml)
        model.opt.integrator = INTEGRATORS[integrator]
        data = mujoco.MjData(model)
        fld = GranularField(model)
        mirror = Mirror(lib, fld, model, data)
        rng = np.random.default_rng(7)
        mujoco.set_mjcb_passive(mirror)
        try:
            for _ in range(150):
                data.qpos[:3] = [0, 0, 0.012 - rng.uniform(0, 0.024)]
                data.qpos[3:] = rng.normal(size=4)
                data.qpos[3:] /= np.linalg.norm(data.qpos[3:])
                data.qvel[:] = rng.normal(size=6) * 10.0 ** rng.uniform(-7, 0)
                data.xfrc_applied[1] = rng.normal(size=6) * [0.3, 0.3, 0.3, 1e-3, 1e-3, 1e-3]
                data.time += 1.0  # each pass a fresh stage 1
                mujoco.mj_forward(model, data)
        finally:
            mujoco.set_mjcb_passive(None)
        mirror.check()
        assert mirror.decisions == {lowspeed.PURE, lowspeed.STICK, lowspeed.SLIP, lowspeed.IMPLICIT}


def test_guard_stage_random_records(lib):
    """guard_stage and begin_step on random records and wrenches of the two-body scene (the
    scenes' guard rarely holds a body: here about half of the guarded bodies are held), passes
    2-4, held and per-stage modes, one body without inertia (never guarded)."""
    model = mujoco.MjModel.from_xml_string(RESTING.format(integrator="RK4"))
    data = mujoco.MjData(model)
    data.qvel[:] = np.random.default_rng(1).normal(size=model.nv) * 0.1
    mujoco.mj_forward(model, data)
    fld = GranularField(model)
    st = fld._states.of(data)
    s = st.arrays
    bridge = eb.Bridge(fld, data)
    m, d, t, sp = bridge.pointers(model, data)
    mr, er = fld._tables.address, st.address
    rng = np.random.default_rng(9)
    held = 0
    for i in range(400):
        s.rk4[:] = rng.normal(size=s.rk4.shape) * 10.0 ** rng.uniform(-6, 0)
        s.rk4[1] = float(2 + i % 3)
        s.rk4[RK4_HEAD::RK4_BODY] = rng.choice([rk4.RK4_PER_STAGE, rk4.RK4_HOLD, rk4.RK4_FROZEN], 2)
        s.wrench[:] = rng.normal(size=s.wrench.shape) * 10.0 ** rng.uniform(-6, 0)
        s.user[:] = rng.normal(size=s.user.shape) * 1e-3
        mass = model.body_mass[2]
        model.body_mass[2] = 0.0 if i % 5 == 0 else mass  # no inertia: not guarded
        for name in ("rk4", "wrench", "user"):
            np.copyto(bridge.arrays[name], getattr(s, name))
        got = lib.mjrft_test_guard_stage(m, d, t, sp)
        want = rk4.guard_stage(mr, er)
        held += want
        assert got == want
        np.testing.assert_array_equal(bridge.arrays["rk4"], s.rk4)
        np.testing.assert_array_equal(bridge.arrays["wrench"], s.wrench)
        lib.mjrft_test_begin_step(m, d, t, sp)
        rk4.begin_step(mr, er)
        np.testing.assert_array_equal(bridge.arrays["rk4"], s.rk4)
        model.body_mass[2] = mass
    assert 100 < held < 600
