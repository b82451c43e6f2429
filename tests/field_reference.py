"""Slow, plain statements of the granular field's per-pass rules: what the compiled pass is
checked against (as MuJoCo's rollout_test.py keeps py_rollout).

The production implementation is the engine's pass (engine/forward.cc and its stages).
Here the same rules are written plainly in NumPy, one function per rule:

* the low-speed treatment of a free rigid body (:func:`treat` and its parts; any wrench law);
* the treatment of bodies in mechanisms (:func:`mechanism_wrenches`, from MuJoCo's own
  ``mj_fullM`` and ``mj_jacBodyCom``, dense NumPy solves, and MuJoCo's affine actuator rule
  written plainly, :func:`affine_actuator_force`);
* the RK4 stage rule (:func:`rk4_stage_held`, :class:`ReferenceField`);
* the ``xfrc_applied`` ownership protocol (:class:`ReferenceField`);
* the pure model on a tagged body from ``mjrft.element_forces`` (:func:`body_wrench_at`).

``ReferenceField(field).apply`` is a complete installed pass for MuJoCo's passive callback.
Frames: world; twists are (linear velocity of the CoM [m/s], angular velocity [rad/s]), wrenches
(force [N], torque about the CoM [N m]).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np
import quadrature_reference

import mjrft
from mjrft.core import surface
from mjrft.field.lowspeed import (
    DEFAULT_REACH,
    HOLD_REGULARISATION,
    IMPLICIT,
    JACOBIAN_STEP,
    PURE,
    RK4_HOLD_STEPS,
    ROUNDING,
    SLIP,
    STICK,
)

__all__ = ["IMPLICIT", "PURE", "SLIP", "STICK"]


# ---------------------------------------------------------------------- the low-speed treatment
def inertia_dot(a: np.ndarray, b: np.ndarray, mass: float, inertia: np.ndarray) -> float:
    """Kinetic-energy inner product m a_lin . b_lin + a_ang . I b_ang of two (6,) twists."""
    return float(mass * (a[:3] @ b[:3]) + a[3:] @ (inertia @ b[3:]))


def keeps_sense(
    pure: np.ndarray,
    twist: np.ndarray,
    mass: float,
    inertia: np.ndarray,
    other: np.ndarray,
    dt: float,
    steps: float,
) -> bool:
    """True if the twist keeps its sense under ``steps`` times the change predicted for a step.

    ``<xi + steps dt M^-1 (f + W(xi)), xi>_M > 0``; arguments as in :func:`treat` (world frame,
    twists [m/s, rad/s], wrenches [N, N m] about the CoM). With ``steps = reach`` this is the
    treatment's first test; with ``RK4_HOLD_STEPS`` it decides which bodies an RK4 step holds.
    """
    twist = np.asarray(twist, dtype=float)
    change = np.asarray(pure, dtype=float) + np.asarray(other, dtype=float)
    accel = np.concatenate([change[:3] / mass, np.linalg.solve(inertia, change[3:])])
    probe = twist + steps * dt * accel
    return inertia_dot(probe, twist, mass, inertia) > 0.0


def _mass_matrix(mass: float, inertia: np.ndarray) -> np.ndarray:
    """(6, 6) block diagonal of m I_3 and the (3, 3) inertia (world axes)."""
    mm = np.zeros((6, 6))
    mm[:3, :3] = mass * np.eye(3)
    mm[3:, 3:] = inertia
    return mm


def stiff(
    pure: np.ndarray,
    twist: np.ndarray,
    mass: float,
    inertia: np.ndarray,
    dt: float,
    steps: float,
) -> bool:
    """True if the medium alone could change the twist by its whole size within ``steps`` steps:
    ``steps dt |M^-1 W(xi)|_M >= |xi|_M``. Arguments as in :func:`treat` (world frame).

    Why: W is homogeneous of degree 0, so its Jacobian across the motion scales as |W| / |xi|;
    an explicit step of a transverse mode (a tilt, a sideways drift) overshoots once
    dt |M^-1 J| passes ~1 and grows at the step frequency once it passes 2 (docs/stability.md,
    "Rocking"). A body this test flags is moved with the linearly implicit force instead.
    """
    mm = _mass_matrix(mass, inertia)
    twist = np.asarray(twist, dtype=float)
    pure = np.asarray(pure, dtype=float)
    w_norm2 = float(pure @ np.linalg.solve(mm, pure))
    return (steps * dt) ** 2 * w_norm2 >= float(twist @ mm @ twist)


def transverse_basis(twist: np.ndarray, mass: float, inertia: np.ndarray) -> np.ndarray:
    """(5, 6) twists, orthonormal in <., .>_M and M-orthogonal to ``twist`` (world frame).

    Gram-Schmidt from the twist's direction over the coordinate axes scaled to unit M-norm,
    taking at each round the axis with the largest remainder (so none is nearly dependent).
    """
    mm = _mass_matrix(mass, inertia)
    basis = [np.asarray(twist, dtype=float) / math.sqrt(float(twist @ mm @ twist))]
    axes = [np.eye(6)[j] / math.sqrt(mm[j, j]) for j in range(6)]
    for _ in range(5):
        best, best_n = None, -1.0
        for a in axes:
            r = a - sum(float(u @ mm @ a) * u for u in basis)
            rn = math.sqrt(max(float(r @ mm @ r), 0.0))
            if rn > best_n:
                best, best_n = r, rn
        basis.append(best / best_n)
    return np.array(basis[1:])


def step_work(
    w: np.ndarray,
    twist: np.ndarray,
    end: np.ndarray,
    other: np.ndarray,
    mass: float,
    dt: float,
    semi_implicit: bool,
) -> float:
    """2 / dt times the mechanical energy a step gains with the medium's wrench w (a guard).

    The trapezoid ``w . (xi + xi_end)``: over a step with constant forces the kinetic energy
    changes by ``dt/2 (w + other) . (xi + xi_end)``, and RK4 moves the body along that mean
    twist, so the work of the other forces cancels with their potential. MuJoCo's Euler,
    implicit and implicitfast (``semi_implicit``) move it with the end twist instead (semi-
    implicit Euler), so a constant force F_c (gravity, the user's force) does ``dt F_c . v_end``
    of work while the kinetic energy counts ``dt/2 F_c . (v + v_end)``: the balance gains
    ``-dt^2/(2m) F_c . (F_c + f)``, f the medium's force. That is positive when the medium
    decelerates a sinking body (F_c down, F_c + f up) and is the gain the slow-lowering map
    flagged (docs/stability.md, "Energy balances"); the rotation has no potential and keeps the
    trapezoid. Arguments: (6,) wrench, start and end twists and the other wrenches, world frame,
    as in :func:`treat`; mass [kg]; dt [s].
    """
    p = float(np.asarray(w, dtype=float) @ (np.asarray(twist) + np.asarray(end)))
    if semi_implicit:
        fc = np.asarray(other, dtype=float)[:3]
        p -= dt * float(fc @ (fc + np.asarray(w, dtype=float)[:3])) / mass
    return p


def implicit_wrench(
    pure: np.ndarray,
    wrench_at: Callable[[np.ndarray], np.ndarray],
    twist: np.ndarray,
    mass: float,
    inertia: np.ndarray,
    other: np.ndarray,
    dt: float,
    semi_implicit: bool = False,
) -> np.ndarray | None:
    """The medium's wrench of a linearly implicit (one Newton step of backward Euler), or None.

    ``(M - dt J') d = M (xi_e - c xi)`` and the wrench ``W(xi) + J' d``: xi_e = xi + dt M^-1
    (f + W(xi)) is the explicit step's end, c = |xi_e|_M / |xi|_M, J' = J / c the Jacobian at
    c xi (with c = 1 this is ``(M - dt J) d = dt (f + W)``, Rosenbrock-Euler). J is the medium's
    Jacobian at xi from secants along the 5 transverse directions of :func:`transverse_basis`
    (J xi = 0 exactly: W is homogeneous of degree 0, Euler's theorem; so 5 evaluations, not 6).
    Along the motion this is the explicit step (stopping is the stick's job); across it, the
    step is backward Euler, which damps the stiff transverse modes instead of amplifying them.
    None (the treatment's step 3 decides) if the result is not finite, reverses the motion
    within the step, or gains energy over the step (:func:`step_work`). Arguments as in
    :func:`treat` (world frame; wrenches about the CoM).
    """
    twist = np.asarray(twist, dtype=float)
    pure = np.asarray(pure, dtype=float)
    other = np.asarray(other, dtype=float)
    mm = _mass_matrix(mass, inertia)
    n = math.sqrt(float(twist @ mm @ twist))
    h = JACOBIAN_STEP * n
    jac = np.zeros((6, 6))
    for u in transverse_basis(twist, mass, inertia):
        dw = (np.asarray(wrench_at(twist + h * u), dtype=float) - pure) / h
        jac += np.outer(dw, mm @ u)
    end_pure = twist + np.linalg.solve(mm, dt * (other + pure))
    # Linearise at c xi, c = |xi_end|_M / |xi|_M of the explicit step: the same direction (so
    # the same W) at the speed the step ends with, where the Jacobian is J / c (degree -1). A
    # body speeding up from rest (c >> 1) is otherwise linearised far outside J's validity.
    c = math.sqrt(max(float(end_pure @ mm @ end_pure), 0.0)) / n
    if not c > 0.0:
        return None
    jac /= c
    d_xi = np.linalg.solve(mm - dt * jac, mm @ (end_pure - c * twist))
    f = pure + jac @ d_xi
    if not np.all(np.isfinite(f)):
        return None
    end = twist + np.linalg.solve(mm, dt * (other + f))
    if float(end @ mm @ twist) <= 0.0:
        return None
    if step_work(f, twist, end, other, mass, dt, semi_implicit) > 0.0:
        return None
    return f


def treat(
    pure: np.ndarray,
    wrench_at: Callable[[np.ndarray], np.ndarray],
    twist: np.ndarray,
    mass: float,
    inertia: np.ndarray,
    other: np.ndarray,
    dt: float,
    reach: float = DEFAULT_REACH,
    implicit: bool = True,
    semi_implicit: bool = False,
) -> tuple[np.ndarray, int]:
    """The wrench the medium applies to one free rigid body over a step, and the decision.

    Args:
      pure: (6,) RFT wrench at the current twist (force [N], torque about the CoM [N m]), world.
      wrench_at: maps a (6,) twist (world, as ``twist``) to the RFT wrench at that twist.
      twist: (6,) linear velocity of the CoM [m/s] then angular velocity [rad/s], world.
      mass: [kg] (> 0). inertia: (3, 3) inertia about the CoM [kg m^2], world axes (SPD).
      other: (6,) every other wrench on the body over the step [N, N m], world, about the CoM.
      dt: step [s] (> 0). reach: see the module docstring.
      implicit: False keeps the pure model for slow moving bodies (step 2): the explicit
        step, which rocks a slowly sinking body (docs/stability.md, "Rocking"). The field
        always passes True; under RK4 its later stages keep the first stage's twist and
        implicit correction (engine/rk4.cc).
      semi_implicit: True where positions advance with the step's end velocity (MuJoCo's
        Euler, implicit, implicitfast), False for RK4: the energy balance the implicit and
        slip guards use (:func:`step_work`). The field passes the model's integrator.
    Returns:
      (wrench (6,), decision): decision is PURE, STICK, SLIP or IMPLICIT.
    """
    twist = np.asarray(twist, dtype=float)
    pure = np.asarray(pure, dtype=float)
    other = np.asarray(other, dtype=float)

    def m_inv(w: np.ndarray) -> np.ndarray:
        return np.concatenate([w[:3] / mass, np.linalg.solve(inertia, w[3:])])

    v_free = twist + dt * m_inv(other)
    # The explicit step with the pure model would add energy (a force turning the motion);
    # its balance's terms cancel near rest, so rounding counts as zero (ROUNDING).
    end = twist + dt * m_inv(other + pure)
    fc = other[:3] if semi_implicit else np.zeros(3)
    size = float(np.abs(pure) @ (np.abs(twist) + np.abs(end)))
    size += dt * float(np.abs(fc) @ (np.abs(fc) + np.abs(pure[:3]))) / mass
    gains = step_work(pure, twist, end, other, mass, dt, semi_implicit) > ROUNDING * size
    if keeps_sense(pure, twist, mass, inertia, other, dt, reach):
        if not (implicit and stiff(pure, twist, mass, inertia, dt, reach)) and not gains:
            return pure.copy(), PURE
        f = None
        if implicit:
            f = implicit_wrench(pure, wrench_at, twist, mass, inertia, other, dt, semi_implicit)
        if f is not None:
            return f, IMPLICIT
        # Implicitly the motion would reverse within the step (or gain work): step 3 decides.
    n2 = inertia_dot(v_free, v_free, mass, inertia)
    if n2 > 0.0:
        r = np.asarray(wrench_at(v_free), dtype=float)
        if dt * -float(r @ v_free) < n2:
            # Slip only where R adds no energy over the step (step_work: the trapezoid of the
            # power, plus semi-implicit Euler's term); else the pure model where it keeps the
            # motion's sense within this step, else stick.
            end = v_free + dt * m_inv(r)
            if step_work(r, twist, end, other, mass, dt, semi_implicit) <= 0.0:
                return r, SLIP
            if keeps_sense(pure, twist, mass, inertia, other, dt, 1.0) and not gains:
                return pure.copy(), PURE
    stick = np.concatenate([-mass * v_free[:3], -(inertia @ v_free[3:])]) / dt
    return stick * stick_fraction(stick, twist, other, mass, n2, dt, semi_implicit), STICK


def stick_fraction(
    stick: np.ndarray,
    twist: np.ndarray,
    other: np.ndarray,
    mass: float,
    n2: float,
    dt: float,
    semi_implicit: bool,
) -> float:
    """The largest fraction lam in [0, 1] of the stick wrench that adds no energy over the step.

    The full stick (lam = 1) ends the step at rest. Under RK4 the body still moves by dt xi / 2
    over the step, so a body rising slowly against gravity (|v| < g dt) gains more potential
    energy than the kinetic energy the stick takes (the RK4 flags of the slow lowering). The
    wrench lam S ends at (1 - lam) xi_free and its :func:`step_work` is the quadratic
    ``(n2/dt) lam^2 + B lam + C`` with C <= 0, so the largest root is the answer when lam = 1
    would gain; with RK4 it is ``1 - dt (S . xi) / n2``.
    Under Euler a passive body's stick never gains (its position does not move). Arguments:
    stick (6,) = -M xi_free / dt, twist (6,), other (6,), world frame as in :func:`treat`;
    n2 = |xi_free|^2_M [kg m^2/s^2] (twice a kinetic energy); mass [kg]; dt [s].
    """
    fc = np.asarray(other, dtype=float)[:3] if semi_implicit else np.zeros(3)
    # Rounding: Euler's balance of a passive stick is exactly -|xi|^2_M / dt <= 0, but its terms
    # cancel; at rest it rounds to +1e-22 and a fraction 1 - 1e-16 would leave the body creeping.
    size = float(
        np.abs(stick) @ np.abs(twist) + dt * np.abs(fc) @ (np.abs(fc) + np.abs(stick[:3])) / mass
    )
    if step_work(stick, twist, np.zeros(6), other, mass, dt, semi_implicit) <= ROUNDING * size:
        return 1.0
    a2 = n2 / dt
    b1 = float(stick @ twist) - a2 - dt * float(fc @ stick[:3]) / mass
    c0 = -dt * float(fc @ fc) / mass
    root = math.sqrt(b1 * b1 - 4.0 * a2 * c0)
    lam = -2.0 * c0 / (b1 + root) if b1 > 0.0 else (root - b1) / (2.0 * a2)
    return min(max(lam, 0.0), 1.0)


# ---------------------------------------------------------------------- the pure model
def surface_height(field: mjrft.GranularField, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Height [m] of the field's free surface at world (x, y) [m], written plainly: flat, a
    plane, or a grid linear over the two triangles of each cell split along (c, r)-(c+1, r+1),
    the nearest edge's height beyond it."""
    prm, grid = field.surface.prm, field.surface.grid
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    kind = int(prm[surface.KIND])
    if kind == surface.FLAT:
        return np.full(x.shape, prm[surface.Z0])
    if kind == surface.PLANE:
        return prm[surface.Z0] + prm[surface.GX] * x + prm[surface.GY] * y
    nrow, ncol = grid.shape
    u = np.clip((x - prm[surface.X0]) / prm[surface.DX], 0, ncol - 1)
    v = np.clip((y - prm[surface.Y0]) / prm[surface.DY], 0, nrow - 1)
    c, r = np.minimum(u.astype(int), ncol - 2), np.minimum(v.astype(int), nrow - 2)
    fu, fv = u - c, v - r
    lower = fu >= fv  # the triangle (c, r), (c+1, r), (c+1, r+1)
    corner = np.where(lower, grid[r, c + 1], grid[r + 1, c])
    a, b = np.where(lower, fu, fv), np.where(lower, fv, fu)
    return grid[r, c] + a * (corner - grid[r, c]) + b * (grid[r + 1, c + 1] - corner)


def geom_may_act(field: mjrft.GranularField, data: mujoco.MjData, g: int) -> bool:
    """False if geom g's bounding sphere is entirely above the surface or outside the region
    (a radius of 0, unknown to MuJoCo, never culls)."""
    c, r = data.geom_xpos[g], field.model.geom_rbound[g]
    if r <= 0.0:
        return True
    prm = field.surface.prm
    top = {
        surface.FLAT: prm[surface.Z0],
        surface.PLANE: surface_height(field, c[0], c[1])
        + r * np.hypot(*prm[surface.GX : surface.GY + 1]),
        surface.GRID: field.surface.grid.max(),
    }[int(prm[surface.KIND])]
    if c[2] - r >= top:
        return False
    region = field.region
    return region is None or not (np.any(c + r < region[0]) or np.any(c - r > region[1]))


def candidates(field, data, be) -> np.ndarray | None:
    """Body-local indices of the elements of be's geoms that may act; None if none may."""
    keep = [geom_may_act(field, data, int(g)) for g in be.geoms]
    if not any(keep):
        return None
    return np.concatenate(
        [np.arange(be.segments[i], be.segments[i + 1]) for i, k in enumerate(keep) if k]
    )


def body_wrench_at(field, data, be, idx, omega, v_ref, p_ref) -> np.ndarray:
    """(6,) RFT wrench on elements idx of body be at its current pose, moving with angular
    velocity omega (3,) and linear velocity v_ref (3,) at the world point p_ref (3,); torque
    about the body's CoM. Elements outside the region feel nothing. The quadrature of
    mjrft.core.quadrature, from its slow reference (tests/quadrature_reference.py)."""
    f, x = element_forces_at(field, data, be, idx, omega, v_ref, p_ref)
    b = be.body
    return np.concatenate([f.sum(axis=0), np.cross(x - data.xipos[b], f).sum(axis=0)])


def element_forces_at(field, data, be, idx, omega, v_ref, p_ref):
    """(forces (k, 3) [N], points (k, 3) [m]) of elements idx of body be, as body_wrench_at."""
    b = be.body
    reach, patch = be.quadrature

    def depth_of(p: np.ndarray) -> np.ndarray:  # vertical, below the local surface
        return surface_height(field, p[..., 0], p[..., 1]) - p[..., 2]

    return quadrature_reference.element_forces(
        be.centroids[idx], be.normals[idx], be.areas[idx], reach[idx], patch[idx],
        data.xmat[b].reshape(3, 3), data.xpos[b], omega, v_ref, p_ref, field.material,
        depth_of, field.region,
    )  # fmt: skip


def pure_wrench(field, data) -> np.ndarray:
    """(nbody, 6) RFT wrench of the pure model on every tagged body (cvel's linear part is at
    the subtree CoM of the body's root)."""
    out = np.zeros((field.model.nbody, 6))
    for be in field.bodies:
        idx = candidates(field, data, be)
        if idx is not None:
            b = be.body
            root = field.model.body_rootid[b]
            out[b] = body_wrench_at(
                field, data, be, idx, data.cvel[b, :3], data.cvel[b, 3:], data.subtree_com[root]
            )
    return out


def twist_wrench_at(field, data, be, idx, twist) -> np.ndarray:
    """(6,) RFT wrench on elements idx of body be moving with the (6,) twist (v at the CoM,
    omega)."""
    com = data.xipos[be.body]
    return body_wrench_at(field, data, be, idx, twist[3:], twist[:3], com)


# ---------------------------------------------------------------------- the field's rules
def free_body_terms(field, data, be) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """(twist (6,), mass, world inertia (3, 3), other wrenches (6,) but the user's) of a free
    body: gravity (with compensation) and the gyroscopic torque -w x I w."""
    m, b = field.model, be.body
    mass, inertia = float(m.body_mass[b]), np.array(m.body_inertia[b])
    x = data.ximat[b].reshape(3, 3)
    iw = (x * inertia) @ x.T
    om = np.array(data.cvel[b, :3])
    v = data.cvel[b, 3:] + np.cross(om, data.xipos[b] - data.subtree_com[m.body_rootid[b]])
    gravity = np.zeros(3)
    if not m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY):
        gravity = np.array(m.opt.gravity) * (1.0 - m.body_gravcomp[b])
    other = np.concatenate([mass * gravity, -np.cross(om, iw @ om)])
    return np.concatenate([v, om]), mass, iw, other


def treated_wrench(field, data, user) -> tuple[np.ndarray, list[int], dict[int, tuple]]:
    """The explicit path: (nbody, 6) wrench with the treatment, the decisions per tagged body,
    and per treated body its RK4 mode for later stages ('hold' or ('frozen', twist, J'd))."""
    m = field.model
    w = pure_wrench(field, data)
    dt = float(m.opt.timestep)
    semi = m.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4
    decisions, modes = [PURE] * len(field.bodies), {}
    for k, be in enumerate(field.bodies):
        b = be.body
        mass, inertia = float(m.body_mass[b]), np.array(m.body_inertia[b])
        if not (field.low_speed.on and field.stick_eligible[k] and dt > 0.0 and mass > 0.0):
            continue
        idx = candidates(field, data, be)
        if idx is None or not np.all(inertia > 0):
            continue
        twist, mass, iw, other = free_body_terms(field, data, be)
        other = other + user[b]
        pure = w[b].copy()
        w[b], decisions[k] = treat(
            pure, lambda tw, be=be, idx=idx: twist_wrench_at(field, data, be, idx, tw),
            twist, mass, iw, other, dt, field.low_speed.reach, semi_implicit=semi,
        )  # fmt: skip
        if decisions[k] == IMPLICIT:
            modes[k] = ("frozen", twist, w[b] - pure)
        elif decisions[k] != PURE or not keeps_sense(
            pure, twist, mass, iw, other, dt, RK4_HOLD_STEPS
        ):
            modes[k] = "hold"
    return w, decisions, modes


def affine_actuator_force(m: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """(nu,) force of each actuator at data's state by MuJoCo's rule for fixed or affine gains and
    no or affine biases (NaN for the others): gain(x, L, V) x + bias(L, V), x the activation (or
    the control, clamped to ctrlrange), clamped to forcerange."""
    out = np.full(m.nu, np.nan)
    flags = m.opt.disableflags
    for a in range(m.nu):
        gaintype, biastype = int(m.actuator_gaintype[a]), int(m.actuator_biastype[a])
        if gaintype not in (int(mujoco.mjtGain.mjGAIN_FIXED), int(mujoco.mjtGain.mjGAIN_AFFINE)):
            continue
        if biastype not in (int(mujoco.mjtBias.mjBIAS_NONE), int(mujoco.mjtBias.mjBIAS_AFFINE)):
            continue
        if m.actuator_actearly[a]:
            continue
        if flags & mujoco.mjtDisableBit.mjDSBL_ACTUATION:
            out[a] = 0.0
            continue
        if m.actuator_actadr[a] >= 0:
            x = data.act[m.actuator_actadr[a]]
        else:
            x = data.ctrl[a]
            if m.actuator_ctrllimited[a] and not flags & mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL:
                x = np.clip(x, *m.actuator_ctrlrange[a])
        length, velocity = data.actuator_length[a], data.actuator_velocity[a]
        g, b = m.actuator_gainprm[a], m.actuator_biasprm[a]
        affine_gain = gaintype == int(mujoco.mjtGain.mjGAIN_AFFINE)
        gain = g[0] + (g[1] * length + g[2] * velocity if affine_gain else 0.0)
        affine_bias = biastype == int(mujoco.mjtBias.mjBIAS_AFFINE)
        bias = b[0] + b[1] * length + b[2] * velocity if affine_bias else 0.0
        f = gain * x + bias
        out[a] = np.clip(f, *m.actuator_forcerange[a]) if m.actuator_forcelimited[a] else f
    return out


def actuator_update(m: mujoco.MjModel, data: mujoco.MjData, force_prev: np.ndarray) -> np.ndarray:
    """(nv,) change of the affine actuators' generalized force from force_prev (nu,) to this
    state's, through this state's moments (dense: actuator_moment expanded)."""
    change = np.nan_to_num(affine_actuator_force(m, data) - force_prev, nan=0.0)
    tau = np.zeros(m.nv)
    for a in range(m.nu):
        start = data.moment_rowadr[a]
        cols = data.moment_colind[start : start + data.moment_rownnz[a]]
        tau[cols] += data.actuator_moment[start : start + data.moment_rownnz[a]] * change[a]
    return tau


def body_metric(field, data, b: int) -> tuple[float, np.ndarray]:
    """(mass, world inertia (3, 3)) of body b: the metric of its twists."""
    x = data.ximat[b].reshape(3, 3)
    return float(field.model.body_mass[b]), (x * field.model.body_inertia[b]) @ x.T


def mechanism_wrenches(field, data, w: np.ndarray, decisions: list[int], st: dict) -> None:
    """The treatment of bodies in mechanisms (engine/mechanism.cc), in place on w (nbody, 6)
    and decisions; st: this MjData's record (time of the last pass, the generalized force the
    field applied then, the last holds)."""
    m, dt, nv = field.model, float(field.model.opt.timestep), field.model.nv
    t = float(data.time)
    t0 = st.get("mech_time")
    if t0 is not None and t == t0:  # a repeated pass reads what the first pass at t read
        valid, qacc, tau_prev, held_before, prev, force_prev = st["mech_in"]
    else:
        valid = t0 is not None and abs(t - (t0 + dt)) <= 1e-9 * dt + 1e-12 * abs(t)
        qacc = np.array(data.qacc)
        tau_prev = st.get("mech_tau", np.zeros(nv))
        held_before, prev = st.get("mech_held", {}), st.get("mech_prev", {})
        force_prev = np.array(data.actuator_force)
        st["mech_in"] = (valid, qacc, tau_prev, held_before, prev, force_prev)
    st["mech_time"] = t
    rows = [
        k for k, be in enumerate(field.bodies)
        if field.mechanism_eligible[k] and (idx := candidates(field, data, be)) is not None
        and np.any((p := be.centroids[idx] @ data.xmat[be.body].reshape(3, 3).T
                    + data.xpos[be.body])[:, 2] < surface_height(field, p[:, 0], p[:, 1]))
    ]  # fmt: skip
    st["mech_tau"], st["mech_held"], st["mech_prev"] = np.zeros(nv), {}, {}
    if not rows or nv == 0 or not dt > 0.0:
        return
    M = np.zeros((nv, nv))
    mujoco.mj_fullM(m, data, M)
    jac = []
    for k in rows:
        jp, jr = np.zeros((3, nv)), np.zeros((3, nv))
        mujoco.mj_jacBodyCom(m, data, jp, jr, field.bodies[k].body)
        jac.append(np.vstack([jp, jr]))
    J = np.vstack(jac)  # (6n, nv)
    tau_other = M @ qacc - tau_prev + actuator_update(m, data, force_prev)
    u = data.qvel + dt * np.linalg.solve(M, tau_other)
    A = J @ np.linalg.solve(M, J.T)
    bodies = [field.bodies[k].body for k in rows]
    n = len(rows)
    out = np.array([w[b] for b in bodies])
    held = np.zeros(n, dtype=bool)
    ref = np.array(
        [prev[k] if k in held_before else w[b] for k, b in zip(rows, bodies, strict=True)]
    )
    if valid:
        # A body held at the last pass is held again, and counts in the others' prediction
        # with the wrench it was held with (its pure model's direction is round-off at rest).
        g = np.linalg.solve(M, J.T @ ref.ravel())
        for a, b in enumerate(bodies):
            if rows[a] in held_before:
                held[a] = True
                continue
            ja = J[6 * a : 6 * a + 6]
            xi = ja @ data.qvel
            dxi = ja @ u - xi + dt * (ja @ g)
            pred = xi + field.low_speed.reach * dxi
            mass, iw = body_metric(field, data, b)
            keeps = inertia_dot(pred, xi, mass, iw) > 0.0
            fast = field.low_speed.reach**2 * inertia_dot(dxi, dxi, mass, iw) < inertia_dot(
                xi, xi, mass, iw
            )
            held[a] = not (keeps and fast)
    slipping = np.zeros(n, dtype=bool)
    for _ in range(n + 1):
        s_rows = [6 * a + r for a in range(n) if held[a] for r in range(6)]
        if s_rows:
            w_all = np.where(np.repeat(held, 6), ref.ravel(), out.ravel())
            rhs = -(J[s_rows] @ u) / dt - A[s_rows] @ w_all
            lhs = A[np.ix_(s_rows, s_rows)]
            lhs = lhs + np.diag(HOLD_REGULARISATION * np.diag(lhs) + 1e-300)
            delta = np.linalg.solve(lhs, rhs)
            out[held] = ref[held] + delta.reshape(-1, 6)
        worst, margin, slip = -1, 0.0, None
        for a in np.flatnonzero(held):
            xf = -dt * A[6 * a : 6 * a + 6, 6 * a : 6 * a + 6] @ out[a]
            hold = -float(out[a] @ xf)
            if not hold > 0.0:
                continue
            be = field.bodies[rows[a]]
            r_w = twist_wrench_at(field, data, be, candidates(field, data, be), xf)
            medium = -float(r_w @ xf)
            short = hold - medium - ROUNDING * (hold + abs(medium))
            if short > margin:
                worst, margin, slip = a, short, r_w
        if worst < 0:
            break
        xi = J[6 * worst : 6 * worst + 6] @ data.qvel
        held[worst], slipping[worst] = False, True
        out[worst] = slip if float(slip @ xi) <= 0.0 else w[bodies[worst]]
    for a, (k, b) in enumerate(zip(rows, bodies, strict=True)):
        w[b] = out[a]
        decisions[k] = STICK if held[a] else (SLIP if slipping[a] else PURE)
        if held[a]:
            st["mech_held"][k] = True
            st["mech_prev"][k] = out[a].copy()
    st["mech_tau"] = J.T @ out.ravel()


def rk4_stage_held(t: float, h: float, record: list[float]) -> bool:
    """True if a pass at time t [s] is stage 2, 3 or 4 of an RK4 step of length h [s] whose
    stage 1 was evaluated: MuJoCo's RK4 runs its stages at t0, t0 + h/2, t0 + h/2, t0 + h
    (computed as t0 + c h). record = [time of the last evaluated pass, passes since]."""
    t0, n = record
    if n in (1.0, 2.0) and t == t0 + 0.5 * h:
        record[1] = n + 1.0
        return True
    if n == 3.0 and t == t0 + 1.0 * h:
        record[1] = 4.0
        return True
    record[:] = [t, 1.0]
    return False


def rk4_step_gain(wrenches: list[np.ndarray], twist, mass, inertia, other, h) -> float:
    """Energy [J] an RK4 step of length h [s] adds with the medium's wrench of each of its four
    stages, beyond the step without it, for a free body of twist (6,), mass [kg], world inertia
    (3, 3) and other wrenches (6,) at stage 1, all held constant over the step.

    Written out from RK4's stages: the velocities v0, v0 + h/2 a1, v0 + h/2 a2, v0 + h a3 and
    accelerations a_j = (other + W_j) / M, combined with the weights (1, 2, 2, 1) / 6 into the
    end twist and the displacement; the energy counts the kinetic energy and the potential
    -other_lin . x of the constant force (the rotation has none)."""
    weights = np.array([1.0, 2.0, 2.0, 1.0]) / 6.0
    inv = np.linalg.inv(inertia)

    def step(ws):
        acc = [np.concatenate([(other[:3] + w[:3]) / mass, inv @ (other[3:] + w[3:])]) for w in ws]
        stage_twists = [twist, twist + h / 2 * acc[0], twist + h / 2 * acc[1], twist + h * acc[2]]
        end = twist + h * sum(c * a for c, a in zip(weights, acc, strict=True))
        moved = h * sum(c * v for c, v in zip(weights, stage_twists, strict=True))
        kinetic = 0.5 * (mass * end[:3] @ end[:3] + end[3:] @ inertia @ end[3:])
        return kinetic - other[:3] @ moved[:3]

    return step(wrenches) - step([np.zeros(6)] * 4)


def rk4_guard(guard: dict, w: np.ndarray, n: int, h: float) -> bool:
    """Whether stage n (2-4) of an RK4 step may apply w (6,) to a free body evaluated per stage:
    the step completed with w must not gain energy (:func:`rk4_step_gain`, within rounding). The
    guard record holds stage 1's twist, mass, inertia, other wrenches and the wrenches applied."""
    ws = guard["applied"] + [w] * (5 - n)
    gain = rk4_step_gain(ws, guard["twist"], guard["mass"], guard["inertia"], guard["other"], h)
    size = sum(np.abs(x).sum() for x in ws)
    speeds = (
        np.abs(guard["twist"]).sum() + h * (np.abs(guard["other"]).sum() + size) / guard["mass"]
    )
    return gain <= ROUNDING * h * size * speeds


class ReferenceField:
    """The installed pass written plainly: install ``apply`` as MuJoCo's passive callback.

    Per MjData: the user part of each tagged row and what was written (ownership: a component
    that differs from what was written was assigned by the user), the RK4 record and the modes
    stage 1 chose. ``decisions`` holds the decisions of the last evaluated stage 1.
    """

    def __init__(self, field: mjrft.GranularField) -> None:
        self.field = field
        self.state: dict[int, dict] = {}
        self.decisions: list[int] = []
        self.wrench = np.zeros((field.model.nbody, 6))
        #: Later RK4 stages in which the energy guard made a body hold stage 1's wrench.
        self.stage_holds = 0

    def apply(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        rows = self.field.body_ids
        st = self.state.setdefault(d._address, {
            "user": np.array(d.xfrc_applied[rows]), "written": np.array(d.xfrc_applied[rows]),
            "record": [0.0, 0.0], "modes": {},
        })  # fmt: skip
        held = m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4 and rk4_stage_held(
            d.time, m.opt.timestep, st["record"]
        )
        current = np.array(d.xfrc_applied[rows])
        assigned = current != st["written"]
        st["user"][assigned] = current[assigned]
        user = np.zeros((m.nbody, 6))
        user[rows] = st["user"]
        keep = np.zeros(len(rows), dtype=bool)
        if held:  # later stages: hold, freeze the twist, or the pure model of the stage
            w = pure_wrench(self.field, d)
            for k, mode in st["modes"].items():
                be = self.field.bodies[k]
                if mode == "hold":
                    keep[k] = True
                elif (idx := candidates(self.field, d, be)) is not None:
                    w[be.body] = twist_wrench_at(self.field, d, be, idx, mode[1]) + mode[2]
            self._guard_stages(st, w, int(st["record"][1]), float(m.opt.timestep))
        else:
            w, self.decisions, st["modes"] = treated_wrench(self.field, d, user)
            if self.field.low_speed.mechanisms:
                mechanism_wrenches(self.field, d, w, self.decisions, st)
                for k, dec in enumerate(self.decisions):
                    if dec != PURE and self.field.mechanism_eligible[k]:
                        st["modes"][k] = "hold"
            st["guards"] = self._guards(m, d, w, user, st["modes"])
        total = st["user"] + w[rows]
        total[keep] = current[keep]
        d.xfrc_applied[rows] = total
        st["written"] = total
        self.wrench[rows[~keep]] = w[rows[~keep]]

    def _guards(self, m, d, w, user, modes) -> dict[int, dict]:
        """Stage 1 of an RK4 step: the energy guard's record of each free body not held."""
        if m.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4 or not self.field.low_speed.on:
            return {}
        guards = {}
        for k, be in enumerate(self.field.bodies):
            b = be.body
            inertia = m.body_inertia[b]
            if modes.get(k) == "hold" or not self.field.stick_eligible[k]:
                continue
            if not (m.body_mass[b] > 0 and np.all(inertia > 0)):
                continue
            twist, mass, iw, other = free_body_terms(self.field, d, be)
            guards[k] = {"twist": twist, "mass": mass, "inertia": iw, "other": other + user[b],
                         "applied": [w[b].copy()]}  # fmt: skip
        return guards

    def _guard_stages(self, st: dict, w: np.ndarray, n: int, h: float) -> None:
        """Stages 2-4: a guarded body whose stage wrench would make the step gain energy holds
        stage 1's wrench from this stage on (engine/rk4.cc, GuardStage)."""
        for k, guard in st["guards"].items():
            if st["modes"].get(k) == "hold":
                continue
            b = self.field.bodies[k].body
            if not rk4_guard(guard, w[b], n, h):
                w[b] = guard["applied"][0]
                st["modes"][k] = "hold"
                self.stage_holds += 1
            guard["applied"].append(w[b].copy())
