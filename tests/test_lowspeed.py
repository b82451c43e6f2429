"""The low-speed stick/slip treatment (mjrft.field.lowspeed) and stability at the extremes.

Reduced-size versions of the stability criteria (the full grid is ``benchmarks/stability.py``);
properties of the treatment's rules on arbitrary wrench laws, stated by the plain reference
(tests/field_reference.py); and the engine's treatment (the mjrft.granular plugin's pass)
checked against that reference.
"""

from __future__ import annotations

import itertools
import math

import field_reference as ref
import mujoco
import numpy as np
import pytest

import mjrft
from mjrft.body import trajectory_wrenches
from mjrft.field import GranularField, SceneError, lowspeed

DENSITY = 2500.0  # kg/m^3, as the stability map
# Relative agreement of the compiled treatment with the NumPy reference: both sum the same
# kernel forces; the reference solves the 3x3 inertia with LAPACK, the compiled one inverts it.
REF_RTOL = 1e-9
DEPTH_TOL = 0.05  # settle depth within 5 %
DRIFT_M = 1e-4  # drift below 0.1 mm (here over a shorter hold than the map's: stricter)
SPEED_M_S = 1e-5  # post-settle speed
TILT_DEG = 1.0  # an upright body that tips is far beyond this; a settled one stays below 0.5
E_ABS, E_REL = 1e-9, 1e-6  # energy gain per step <= E_ABS + E_REL |E|
G = 9.81  # m/s^2, gravity of the analytic laws
INTEGRATORS = {
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
}


def body_xml(shape: str, mass: float, n_tri: int = 400, custom: str = "", z: float | None = None):
    """One free body of the given mass at DENSITY, lowest point on the surface z = 0."""
    vol = mass / DENSITY
    if shape == "sphere":
        size = np.array([(3 * vol / (4 * math.pi)) ** (1 / 3)])
    else:  # mole-crab ellipsoid, long axis vertical
        ref = np.array([0.0095, 0.0095, 0.018])
        size = ref * (vol / (4 / 3 * math.pi * ref.prod())) ** (1 / 3)
    z = size[-1] if z is None else z
    return (
        f"""<mujoco><option><flag contact="disable"/></option><custom>
      <text name="mjrft:material" data="glass_beads"/>{custom}
      <tuple name="mjrft:intruders"><element objtype="geom" objname="g" prm="{n_tri}"/></tuple>
    </custom><worldbody><body name="b" pos="0 0 {z:.9g}"><freejoint/>
      <geom name="g" type="{shape}" size="{" ".join(f"{s:.9g}" for s in size)}"
            mass="{mass:.9g}"/>
    </body></worldbody></mujoco>""",
        size,
    )


def stop_depth(fld: GranularField, half_height: float, weight: float) -> float:
    """Depth where an upright body released at rest on the surface must stop in continuous time
    (work balance m g d = integral of F_z, the core model's force for straight-down motion):
    pure RFT is rate independent, so the body overshoots the quasi-static depth."""
    grid = np.linspace(0.0, 4 * half_height, 8001)
    pos = np.zeros((len(grid), 3))
    pos[:, 2] = half_height - grid
    n = len(grid)
    fz = trajectory_wrenches(
        fld.body_element_set(1), pos, np.broadcast_to(np.eye(3), (n, 3, 3)),
        np.tile([0.0, 0.0, -1.0], (n, 1)), np.zeros((n, 3)), fld.material,
    ).force[:, 2]  # fmt: skip
    excess = np.concatenate([[0.0], np.cumsum(0.5 * (fz[1:] + fz[:-1]) * np.diff(grid))])
    excess -= weight * grid
    i = int(np.flatnonzero((grid > grid[1]) & (excess >= 0))[0])
    return float(np.interp(0.0, excess[i - 1 : i + 1], grid[i - 1 : i + 1]))


def _quasi_static_depth(fld: GranularField, size: np.ndarray, weight: float) -> float:
    """Depth [m] where the core model's F_z for straight-down motion of body 1 (upright, lowest
    point at depth 0 when its origin is at size[-1]) equals the weight (brentq)."""
    from scipy.optimize import brentq

    es = fld.body_element_set(1)

    def fz(depth: float) -> float:
        pos = np.array([[0.0, 0.0, size[-1] - depth]])
        return float(
            trajectory_wrenches(
                es, pos, np.eye(3)[None], np.array([[0, 0, -1.0]]), np.zeros((1, 3)), fld.material
            ).force[0, 2]
        )

    return float(brentq(lambda x: fz(x) - weight, 1e-6, 2 * size[-1]))


def loaded_at(
    xml: str, m: mujoco.MjModel, d: mujoco.MjData, **options
) -> tuple[GranularField, mujoco.MjData]:
    """xml loaded with other scene options (e.g. low_speed="off"; the options are the model's),
    m's timestep and integrator, and an MjData of it at d's state (qpos, qvel; mj_forward): the
    field and that MjData."""
    other = mjrft.load_model(xml, **options)
    other.opt.timestep, other.opt.integrator = m.opt.timestep, m.opt.integrator
    data = mujoco.MjData(other)
    data.qpos[:], data.qvel[:] = d.qpos, d.qvel
    mujoco.mj_forward(other, data)
    return GranularField(other), data


def energy(m: mujoco.MjModel, d: mujoco.MjData) -> float:
    """Kinetic + gravitational potential energy of the free body [J] (datum z = 0) of the state
    in qpos, qvel (after mj_step the derived positions are those of the step's start, so the
    kinematics are refreshed first; the engine's pass does not run in these stages)."""
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    mujoco.mj_energyPos(m, d)
    mujoco.mj_energyVel(m, d)
    return float(d.energy[0] + d.energy[1])


# ------------------------------------------------------------------ 1. settling
SETTLE_CASES = [
    (shape, mass, dt, integ)
    for shape in ("sphere", "ellipsoid")
    for mass in (0.001, 100.0)
    for dt in (0.001, 0.005)
    for integ in INTEGRATORS
]


@pytest.mark.parametrize(("shape", "mass", "dt", "integrator"), SETTLE_CASES)
def test_released_body_settles_and_stays(shape, mass, dt, integrator):
    xml, size = body_xml(shape, mass)
    m = mjrft.load_model(xml)
    m.opt.timestep, m.opt.integrator = dt, INTEGRATORS[integrator]
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    d = mujoco.MjData(m)
    fld = GranularField(m)
    assert fld.low_speed.on and fld.stick_eligible.all()  # the default
    weight = m.body_mass[1] * 9.81
    d_stop = stop_depth(fld, size[-1], weight)
    settle, hold = round(1.5 / dt), round(2.0 / dt)
    z, v, gain = [], [], []
    mujoco.mj_forward(m, d)
    e0 = energy(m, d)
    for _ in range(settle + hold):
        mujoco.mj_step(m, d)
        e1 = energy(m, d)
        gain.append((e1 - e0) / (E_ABS + E_REL * abs(e0)))
        e0 = e1
        z.append(d.qpos[2])
        v.append(np.linalg.norm(d.qvel))
    z, v = np.array(z), np.array(v)
    depth = size[-1] - z[-1]
    assert abs(depth - d_stop) <= DEPTH_TOL * d_stop, (depth, d_stop)
    assert np.ptp(z[settle:]) <= DRIFT_M
    assert v[settle:].max() <= SPEED_M_S
    assert max(gain) <= 1.0  # 2. energy: never gained beyond the tolerance in any step
    assert fld.stats_of(d)["stuck"] > 0


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
@pytest.mark.parametrize("shape", ["sphere"])
def test_slowly_lowered_body_rests_at_the_quasi_static_depth(shape, integrator):
    """Held by a user force that is lowered slowly: ends where F_z(d) = m g (brentq on the core
    model), within 5 %. Sphere only: the slender ellipsoid's lowered end depth depends on the
    small tilts its slip phases pick up (docs/stability.md, "Results")."""
    xml, size = body_xml(shape, 1.0)
    m = mjrft.load_model(xml)
    m.opt.timestep, m.opt.integrator = 0.002, INTEGRATORS[integrator]
    d = mujoco.MjData(m)
    fld = GranularField(m)
    weight = m.body_mass[1] * 9.81
    d_qs = _quasi_static_depth(fld, size, weight)
    ramp = round(20 * math.sqrt(d_qs / 9.81) / m.opt.timestep)
    _lower(m, d, fld, weight, ramp, round(1.0 / m.opt.timestep))
    depth = size[-1] - d.qpos[2]
    assert abs(depth - d_qs) <= DEPTH_TOL * d_qs, (depth, d_qs)
    assert np.linalg.norm(d.qvel) <= SPEED_M_S


def _lower(m, d, fld, weight, ramp_steps, after_steps):
    """Hold body 1 by an upward user force W (1 + cos(pi t / T)) / 2 lowered to 0 over
    ramp_steps, then let it rest after_steps; returns the largest tilt [deg] of its z axis."""
    tilt = 0.0
    for i in range(ramp_steps + after_steps):
        if i <= ramp_steps:
            d.xfrc_applied[1] = 0.0
            d.xfrc_applied[1, 2] = weight * 0.5 * (1 + math.cos(math.pi * i / ramp_steps))
        mujoco.mj_step(m, d)
        tilt = max(tilt, math.degrees(math.acos(min(1.0, d.xmat[1, 8]))))
    return tilt


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_very_slowly_lowered_ellipsoid_neither_rocks_nor_tips(integrator):
    """Lowered over 200 of its time scales sqrt(d_qs / g) (10x the map's ramp): the sinking is
    slow for long, where RFT is stiff across the motion. With the explicit pure model for the
    moving phases the ellipsoid rocked at the step frequency and tipped over (93 deg at 1 ms,
    1 g to 100 kg; docs/stability.md, "Rocking"); the linearly implicit step keeps it
    upright at d_qs. Under RK4 the pure model in every stage tipped it too; its later stages
    now keep the first stage's twist and implicit correction."""
    xml, size = body_xml("ellipsoid", 1.0)
    m = mjrft.load_model(xml)
    m.opt.timestep, m.opt.integrator = 0.001, INTEGRATORS[integrator]
    d = mujoco.MjData(m)
    fld = GranularField(m)
    weight = m.body_mass[1] * 9.81
    d_qs = _quasi_static_depth(fld, size, weight)
    ramp = round(200 * math.sqrt(d_qs / 9.81) / m.opt.timestep)
    tilt = _lower(m, d, fld, weight, ramp, round(0.5 / m.opt.timestep))
    depth = size[-1] - d.qpos[2]
    assert tilt < TILT_DEG, tilt
    assert abs(depth - d_qs) <= DEPTH_TOL * d_qs, (depth, d_qs)
    assert np.linalg.norm(d.qvel) <= SPEED_M_S
    assert fld.stats_of(d)["implicit"] > 0


def test_implicit_step_damps_rocking_that_the_explicit_step_amplifies():
    """One step of a slowly, steadily sinking ellipsoid (1 g, dt = 5 ms; a user force carries
    what the medium does not, as while it is lowered) with a small rocking spin: the pure
    model's torque reverses the spin and grows it (the step-frequency instability); the
    treatment's linearly implicit wrench damps it without reversing it."""
    xml, size = body_xml("ellipsoid", 0.001)
    m = mjrft.load_model(xml)
    m.opt.timestep = 0.005
    d = mujoco.MjData(m)
    d.qpos[2] = 0.7 * size[-1]  # 0.3 half-heights deep: the medium carries less than the weight
    d.qvel[:] = [0.0, 0.0, -1e-3, 1e-4, 0.0, 0.0]
    mujoco.mj_forward(m, d)
    x = d.ximat[1].reshape(3, 3)
    inertia = (x * m.body_inertia[1]) @ x.T
    om = d.qvel[3:]

    on = GranularField(m)
    off, d_off = loaded_at(xml, m, d, low_speed="off")
    user = np.zeros((m.nbody, 6))
    user[1, 2] = m.body_mass[1] * 9.81 - off.wrench(d_off)[1, 2]
    assert user[1, 2] > 0.0

    def spin_after(fld: GranularField, data: mujoco.MjData) -> np.ndarray:
        tau = fld.wrench(data, user_xfrc=user)[1, 3:] - np.cross(om, inertia @ om)
        return om + m.opt.timestep * np.linalg.solve(inertia, tau)

    explicit, implicit = spin_after(off, d_off), spin_after(on, d)
    assert on.decision_of(d)[0] == lowspeed.IMPLICIT
    assert explicit[0] < -om[0]  # reversed and amplified
    assert 0.0 <= implicit[0] < om[0]  # damped, same sense
    # Along the motion the implicit wrench is the pure one (J xi = 0: degree-0 homogeneity).
    np.testing.assert_allclose(
        on.wrench(d, user_xfrc=user)[1, 2], off.wrench(d_off)[1, 2], rtol=0.05
    )


def test_without_treatment_the_same_body_does_not_settle():
    """The criterion can fail: the pure model chatters (guards against a vacuous settle test)."""
    xml, _ = body_xml("sphere", 0.1)
    m = mjrft.load_model(xml, low_speed="off")
    m.opt.timestep = 0.002
    d = mujoco.MjData(m)
    v = []
    for _ in range(1000):
        mujoco.mj_step(m, d)
        v.append(np.linalg.norm(d.qvel))
    assert max(v[-200:]) > 100 * SPEED_M_S


# ------------------------------------------------------------------ 2. energy
# Guards on the trapezoid of the power alone (not Euler's own energy balance, step_work) let
# implicitfast at reach 8 gain energy in the first throw (up to 2e3 x the tolerance), and these
# perturbed throws gain up to 900 x at reaches 4 and 8 (docs/stability.md, "Energy balances").
_THROW = (0.3, -0.1, -0.5, 4.0, -2.0, 6.0)
_THROWN = [
    (integ, reach, _THROW) for reach in (lowspeed.DEFAULT_REACH, 1.0, 8.0) for integ in INTEGRATORS
]
_THROWN += [
    ("implicitfast", lowspeed.DEFAULT_REACH, (0.4688, -0.0636, -0.5386, 3.6323, -1.3644, 4.1535)),
    ("Euler", 8.0, (0.2664, -0.0837, -0.6087, 4.5447, -1.8319, 4.8024)),
    ("Euler", 8.0, (0.236, -0.1195, -0.5155, 2.9154, -1.0293, 6.1992)),
]


@pytest.mark.parametrize(("integrator", "reach", "qvel"), _THROWN)
def test_thrown_spinning_body_never_gains_energy(integrator, reach, qvel):
    """A body thrown into the medium at an angle with spin, through rest, and held. Before slip
    was limited to forces doing no work over the step, reaches 4 and 8 gained energy here
    (up to 1e4 x the tolerance, every integrator)."""
    xml, _ = body_xml("ellipsoid", 0.05, z=0.0)
    m = mjrft.load_model(xml, stick_reach=reach)
    m.opt.timestep, m.opt.integrator = 0.001, INTEGRATORS[integrator]
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    d = mujoco.MjData(m)
    d.qvel[:] = qvel
    fld = GranularField(m)
    mujoco.mj_forward(m, d)
    e0 = energy(m, d)
    worst = -np.inf
    for _ in range(1500):
        mujoco.mj_step(m, d)
        e1 = energy(m, d)
        worst = max(worst, (e1 - e0) / (E_ABS + E_REL * abs(e0)))
        e0 = e1
    assert worst <= 1.0
    assert fld.stats_of(d)["stuck"] > 0 and np.linalg.norm(d.qvel) <= SPEED_M_S


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
@pytest.mark.parametrize("rise", [0.1, 0.25, 0.5, 0.9])
def test_body_rising_slowly_in_the_medium_gains_no_energy(integrator, rise):
    """A sphere resting at its quasi-static depth is given a slow upward speed rise * g dt
    (what an implicit step can leave behind). The medium stops it within the step. A full
    stick under RK4 still lifts it by dt v / 2, m g dt v / 2 of potential energy for m v^2 / 2
    of kinetic (a gain for v < g dt, up to m g^2 dt^2 / 8: 31x the tolerance in the slow
    lowering map); it now sticks only as far as that adds no energy. Euler's stick does not
    move the body."""
    xml, size = body_xml("sphere", 0.05)
    m = mjrft.load_model(xml)
    m.opt.timestep, m.opt.integrator = 0.005, INTEGRATORS[integrator]
    d = mujoco.MjData(m)
    fld = GranularField(m)
    d_qs = _quasi_static_depth(fld, size, m.body_mass[1] * G)
    d.qpos[2] = size[-1] - d_qs
    d.qvel[2] = rise * G * m.opt.timestep
    mujoco.mj_forward(m, d)
    e0 = energy(m, d)
    for _ in range(3):
        mujoco.mj_step(m, d)
        e1 = energy(m, d)
        assert e1 - e0 <= E_ABS + E_REL * abs(e0), (e1 - e0, fld.decision_of(d)[0])
        e0 = e1
    assert fld.stats_of(d)["stuck"] > 0


def _coulomb_like(c):
    """A rate-independent dissipative wrench law, like RFT's: -C xi / |xi|_C, C SPD (6, 6)."""

    def w(xi):
        n = math.sqrt(xi @ c @ xi)
        return -(c @ xi) / n if n > 0.0 else np.zeros(6)

    return w


def _work_over_step(w, xi, other, mass, inertia, dt):
    """w . (xi + xi_end): twice the work of w over a step along the mean twist, over dt."""
    acc = np.concatenate([(other + w)[:3] / mass, np.linalg.solve(inertia, (other + w)[3:])])
    return float(w @ (2.0 * xi + dt * acc))


def _energy_gain(w, xi, other, mass, inertia, dt, semi_implicit):
    """Mechanical energy a step with the medium's wrench w adds, net of the other forces' work
    (the kinetic energy change minus that work), and the end twist. Semi-implicit Euler moves
    the body with the end velocity, so the (constant) other force works on it; else on the
    mean velocity. The other torque works on the mean angular velocity (no rotational
    potential)."""
    acc = np.concatenate([(other + w)[:3] / mass, np.linalg.solve(inertia, (other + w)[3:])])
    end = xi + dt * acc
    kinetic = 0.5 * (mass * end[:3] @ end[:3] + end[3:] @ inertia @ end[3:])
    kinetic -= 0.5 * (mass * xi[:3] @ xi[:3] + xi[3:] @ inertia @ xi[3:])
    v_move = end[:3] if semi_implicit else 0.5 * (xi[:3] + end[:3])
    work = dt * (other[:3] @ v_move + other[3:] @ (0.5 * (xi[3:] + end[3:])))
    return float(kinetic - work), end


@pytest.mark.parametrize("semi_implicit", [False, True])
def test_slip_and_implicit_never_do_positive_work_over_the_step(semi_implicit):
    """Slip applies R = W(xi_free), the medium's force in the direction the body ends the step
    in. R opposes xi_free but may push along the current motion xi when the other forces turn
    the motion (a spinning body thrown in): then the treatment keeps the pure model (if it does
    not reverse the motion within the step) or sticks. Random states and rate-independent
    dissipative laws; plus one constructed case where R would do positive work. The energy a
    slipping or implicit step adds is computed from the step's kinetic energy and the other
    forces' work, for RK4's mean-twist motion and for semi-implicit Euler's end-velocity one."""
    rng = np.random.default_rng(21)
    seen = set()
    for _ in range(3000):
        a = rng.normal(size=(6, 6))
        law = _coulomb_like(a @ a.T + 0.1 * np.eye(6))
        mass = 10.0 ** rng.uniform(-3, 2)
        b = rng.normal(size=(3, 3))
        inertia = mass * 1e-3 * (b @ b.T + 0.1 * np.eye(3))
        xi = rng.normal(size=6) * 10.0 ** rng.uniform(-4, 0)
        other = rng.normal(size=6) * mass * 10.0 ** rng.uniform(-1, 1.5)
        dt = 10.0 ** rng.uniform(-4, -2)
        pure = law(xi)
        w, dec = ref.treat(
            pure, law, xi, mass, inertia, other, dt, reach=8.0, semi_implicit=semi_implicit
        )
        seen.add(dec)
        speed = np.abs(xi).max() + dt * (np.abs(other).max() + np.abs(w).max()) / mass
        scale = (np.abs(w).max() + np.abs(other).max()) * speed
        gain, end = _energy_gain(w, xi, other, mass, inertia, dt, semi_implicit)
        # the guard's closed form is the step's energy balance (to the rounding of the kinetic
        # energy difference)
        guard = 0.5 * dt * ref.step_work(w, xi, end, other, mass, dt, semi_implicit)
        assert abs(gain - guard) <= 1e-9 * dt * scale
        if dec in (lowspeed.SLIP, lowspeed.IMPLICIT):
            assert gain <= 1e-9 * dt * scale
    assert seen == {lowspeed.PURE, lowspeed.STICK, lowspeed.SLIP, lowspeed.IMPLICIT}
    # Constructed: xi along x; the other force turns the free motion to (-0.5, 2, 0), and
    # R = W(xi_free) = -1.9 xi_free/|xi_free| (unit mass and inertia, dt = 1) dissipates the free
    # motion without reversing it, but its work over the step is positive (a rule that checked
    # only the dissipation would slip): under RK4 it sticks, only as far as the stick adds no
    # energy (lowspeed.stick_fraction).
    law = _coulomb_like(np.eye(6))
    xi = np.array([1.0, 0, 0, 0, 0, 0])
    other = np.array([-1.5, 2.0, 0, 0, 0, 0])

    def scaled(t):
        return 1.9 * law(t)

    r = scaled(xi + other)
    assert -r @ (xi + other) < (xi + other) @ (xi + other)  # slip would have been chosen
    assert _work_over_step(r, xi, other, 1.0, np.eye(3), 1.0) > 0.0
    w, dec = ref.treat(
        scaled(xi), scaled, xi, 1.0, np.eye(3), other, 1.0, reach=1.0, semi_implicit=semi_implicit
    )
    gain = _energy_gain(w, xi, other, 1.0, np.eye(3), 1.0, semi_implicit)[0]
    if semi_implicit:  # moving with the end velocity, R's step adds no energy: Euler slips
        assert dec == lowspeed.SLIP and gain <= 0.0
    else:  # along the mean twist the stick S = -M xi_free / dt works S . xi / 2 = 0.25 J; the
        # largest fraction that does none ends at (1 - lam) xi_free with
        # S . (xi + (1 - lam) xi_free) = 0: lam = 1 - (S . xi) / |xi_free|^2 = 1 - 0.5 / 4.25
        assert dec == lowspeed.STICK
        np.testing.assert_allclose(w, -15.0 / 17.0 * (xi + other))
        assert abs(gain) <= 1e-12


def _lifting(c, lift):
    """A rate-independent law with RFT's lift: -C xi / |xi|_C plus an upward force growing with
    the share of rotation in the motion (a spinning intruder is pushed up, Treers et al. 2021)."""

    def w(xi):
        n = math.sqrt(xi @ c @ xi)
        if n == 0.0:
            return np.zeros(6)
        out = -(c @ xi) / n
        out[2] += lift * np.linalg.norm(xi[3:]) / np.linalg.norm(xi)
        return out

    return w


def test_slip_and_implicit_add_no_energy_to_a_lifted_body_under_euler():
    """A slowly sinking, spinning body under gravity that the medium lifts harder than its
    weight. The trapezoid of the power misses what semi-implicit Euler adds: moving with the
    end velocity, gravity's work lags the kinetic energy by dt^2 g . (g + f/m) / 2 per unit
    mass, positive when f lifts (lowspeed.step_work). Over this grid the trapezoid rule slips
    and steps implicitly into energy gains (checked, so the test can fail); the Euler balance
    never does. (This law is active once the body rises, so the pure model, which fast bodies
    keep unguarded, gains here too; RFT's is dissipative.)"""
    mass, inertia = 1.0, 1e-3 * np.eye(3)
    other = np.array([0.0, 0.0, -mass * G, 0.0, 0.0, 0.0])
    gaining = {False: set(), True: set()}
    for k, lift, sink, spin, dt in itertools.product(
        (0.5, 1.0, 2.0, 5.0), (3.0, 5.0), (1e-4, 1e-3, 1e-2), (1.0, 3.0), (1e-3, 3e-3)
    ):
        c = G**2 * np.diag([k, k, k, 1e-3 * k, 1e-3 * k, 1e-3 * k])
        law = _lifting(c, lift * G)
        xi = np.array([0.0, 0.0, -sink, spin, 0.0, 0.0])
        for semi in (False, True):
            w, dec = ref.treat(law(xi), law, xi, mass, inertia, other, dt, semi_implicit=semi)
            gain, _ = _energy_gain(w, xi, other, mass, inertia, dt, semi_implicit=True)
            if gain > 1e-12:  # J; the trapezoid rule's gains here are 1e-7 to 1e-3 J
                gaining[semi].add(dec)
    treated = {lowspeed.SLIP, lowspeed.IMPLICIT}  # the guarded decisions
    assert gaining[False] >= treated
    assert not gaining[True] & treated


# ------------------------------------------------------------------ 3. fidelity and settings
def _fast_state(m, d, speed):
    rng = np.random.default_rng(3)
    d.qpos[2] = -0.005
    d.qvel[:3] = speed * np.array([0.3, -0.2, -1.0])
    d.qvel[3:] = rng.normal(size=3) * speed / 0.02
    mujoco.mj_forward(m, d)


@pytest.mark.parametrize("speed", [0.2, 3.0, 100.0])
def test_moving_body_feels_exactly_the_pure_model(speed):
    xml, _ = body_xml("ellipsoid", 0.05)
    m = mjrft.load_model(xml)
    d = mujoco.MjData(m)
    _fast_state(m, d, speed)
    on = GranularField(m)
    off, d_off = loaded_at(xml, m, d, low_speed="off")
    w_on, w_off = on.wrench(d), off.wrench(d_off)
    assert on.decision_of(d)[0] == lowspeed.PURE
    np.testing.assert_array_equal(w_on, w_off)  # bit for bit, far inside the 0.1 % asked
    mujoco.mj_forward(m, d)  # the pass inside MuJoCo's forward too
    np.testing.assert_array_equal(on.wrench_of(d), w_off)


def test_slow_body_is_treated_and_off_switch_restores_the_pure_model():
    xml, _ = body_xml("sphere", 0.05)
    m = mjrft.load_model(xml)
    d = mujoco.MjData(m)
    d.qpos[2] -= 0.01  # submerged, at rest
    mujoco.mj_forward(m, d)
    on = GranularField(m)
    off, d_off = loaded_at(xml, m, d, low_speed="off")
    w_on = on.wrench(d)
    assert on.decision_of(d)[0] == lowspeed.STICK
    # Held at rest: exactly the weight, no torque (the pure model at zero velocity gives 0).
    np.testing.assert_allclose(w_on[1], [0, 0, m.body_mass[1] * 9.81, 0, 0, 0], atol=1e-12)
    np.testing.assert_array_equal(off.wrench(d_off)[1], 0.0)


def test_treatment_settings_from_mjcf_and_python():
    xml, _ = body_xml(
        "sphere",
        0.05,
        custom='<text name="mjrft:low_speed" data="off"/>'
        '<numeric name="mjrft:stick_reach" data="2.5"/>',
    )
    m = mjrft.load_model(xml)
    assert GranularField(m).low_speed == lowspeed.LowSpeed("off", 2.5)
    stick = mjrft.load_model(xml, low_speed="stick")
    assert GranularField(stick).low_speed == lowspeed.LowSpeed("stick", 2.5)
    assert GranularField(mjrft.load_model(xml, stick_reach=1.0)).low_speed.reach == 1.0
    # Options given to GranularField only check the model: those it was loaded with pass,
    # others are refused (the engine runs the model's own tables).
    assert GranularField(stick, low_speed="stick").low_speed.mode == "stick"
    with pytest.raises(SceneError, match="differ from those the options given"):
        GranularField(m, low_speed="stick")
    with pytest.raises(SceneError, match="low_speed = 'sticky'.*stick, free, off"):
        mjrft.load_model(xml, low_speed="sticky")
    with pytest.raises(SceneError, match="reach = -1.*\\(0, 1000\\]"):
        mjrft.load_model(xml, stick_reach=-1)
    bad, _ = body_xml("sphere", 0.05, custom='<text name="mjrft:low_speed" data="on"/>')
    with pytest.raises(SceneError, match="mjrft:low_speed'> = 'on'"):
        mjrft.load_model(bad)


def test_only_free_rigid_bodies_are_treated():
    xml = """<mujoco><custom><text name="mjrft:material" data="glass_beads"/>
      <tuple name="mjrft:intruders"><element objtype="geom" objname="a" prm="200"/>
        <element objtype="geom" objname="h" prm="200"/>
        <element objtype="geom" objname="c" prm="200"/>
      </tuple></custom><worldbody>
      <body name="free"><freejoint/><geom name="a" size="0.01"/></body>
      <body name="hinged"><joint type="hinge"/><geom name="h" size="0.01"/></body>
      <body name="parent" pos="1 0 0"><freejoint/><geom size="0.01"/>
        <body name="child"><joint type="hinge"/><geom name="c" size="0.01"/></body></body>
    </worldbody></mujoco>"""
    fld = GranularField(mjrft.load_model(xml))
    assert fld.stick_eligible.tolist() == [True, False, False]


# ------------------------------------------------------------------ compiled == reference
@pytest.mark.parametrize("integrator", ["Euler", "RK4"])  # Euler's and RK4's energy guards
@pytest.mark.parametrize("reach", [1.0, lowspeed.DEFAULT_REACH])
def test_compiled_treatment_equals_the_reference(reach, integrator):
    """Random states around rest and at speed, with user forces: the engine's pass (explicit,
    and inside mj_forward) against the plain statement of the treatment
    (field_reference.treated_wrench), decisions and the modes RK4's later stages follow
    included."""
    xml, size = body_xml("ellipsoid", 0.05, custom="")
    m = mjrft.load_model(xml, stick_reach=reach)
    m.opt.integrator = INTEGRATORS[integrator]
    d = mujoco.MjData(m)
    fld = GranularField(m)
    rng = np.random.default_rng(7)
    seen, holds = set(), set()
    for _ in range(60):
        d.qpos[:3] = [0, 0, size[-1] - rng.uniform(0, 2 * size[-1])]
        d.qpos[3:] = rng.normal(size=4)
        d.qpos[3:] /= np.linalg.norm(d.qpos[3:])
        d.qvel[:] = rng.normal(size=6) * 10.0 ** rng.uniform(-7, 0)
        user = np.zeros((m.nbody, 6))
        user[1] = rng.normal(size=6) * [0.3, 0.3, 0.3, 1e-3, 1e-3, 1e-3]
        mujoco.mj_forward(m, d)
        explicit = fld.wrench(d, user_xfrc=user)[1]
        dec = int(fld.decision_of(d)[0])
        # The pass inside MuJoCo's forward, with the user part taken from xfrc_applied.
        d.xfrc_applied[:] = user
        mujoco.mj_forward(m, d)
        np.testing.assert_array_equal(d.xfrc_applied[1], user[1] + explicit)
        w, decisions, modes = ref.treated_wrench(fld, d, user)
        assert decisions[0] == dec
        np.testing.assert_allclose(explicit, w[1], rtol=REF_RTOL, atol=REF_RTOL * np.abs(w).max())
        seen.add(dec)
        holds.add(modes.get(0) == "hold" and dec == lowspeed.PURE)
    assert seen == {lowspeed.PURE, lowspeed.STICK, lowspeed.SLIP, lowspeed.IMPLICIT}
    if reach < lowspeed.RK4_HOLD_STEPS:  # else pure-model bodies that RK4 holds are rare
        assert holds == {False, True}  # some pure-model bodies slow enough for RK4 to hold


# ------------------------------------------------------------------ 4. extremes
EXTREME = """<mujoco><option timestep="{dt}"><flag contact="disable"/></option><custom>
  <text name="mjrft:material" data="glass_beads"/>
  <tuple name="mjrft:intruders">
    <element objtype="geom" objname="tiny" prm="200"/>
    <element objtype="geom" objname="flat" prm="0"/>
    <element objtype="geom" objname="wall" prm="0"/>
    <element objtype="geom" objname="huge" prm="12"/>
  </tuple></custom><worldbody>
  <body name="tiny" pos="0 0 -1e-5"><freejoint/><geom name="tiny" size="1e-5" mass="0"/>
    <inertial pos="0 0 0" mass="1e-3" diaginertia="1e-11 1e-11 1e-11"/></body>
  <body name="flat" pos="1 0 0.001"><freejoint/><geom name="flat" type="box" size="0.05 0.05 0.001"
    mass="0.02"/></body>
  <body name="wall" pos="2 0 0"><freejoint/><geom name="wall" type="box" size="0.001 0.05 0.05"
    mass="0.02"/></body>
  <body name="huge" pos="5 0 -10"><freejoint/><geom name="huge" type="box" size="0.7 0.7 0.7"
    mass="3000"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("low_speed", ["stick", "off"])
@pytest.mark.parametrize("integrator", list(INTEGRATORS))
@pytest.mark.parametrize("speed", [0.0, 1e-9, 1e-3, 1.0, 100.0])
def test_extremes_stay_finite_and_raise_nothing(speed, integrator, low_speed):
    """Element areas 1e-12 (tiny sphere) to ~1 m^2 (huge box 10 m deep), a plate lying exactly on
    the surface, a vertical plate, exactly vertical velocities, and (at speed) bodies leaving
    and re-entering the medium."""
    m = mjrft.load_model(EXTREME.format(dt=0.002), low_speed=low_speed)
    m.opt.integrator = INTEGRATORS[integrator]
    d = mujoco.MjData(m)
    fld = GranularField(m)
    areas = np.concatenate([be.areas for be in fld.bodies])
    assert areas.min() < 1e-11 and areas.max() > 0.9
    for j in range(4):
        d.qvel[6 * j + 2] = -speed  # exactly vertical
    d.qvel[6 * 1 + 2] = speed  # the flat plate moves up and out
    for _ in range(100):
        mujoco.mj_step(m, d)
        assert np.all(np.isfinite(d.xfrc_applied)) and np.all(np.isfinite(d.qvel))
