"""Stability map of passive bodies resting in the granular medium (the low-speed treatment's test).

What it does: for every combination of shape (sphere, mole-crab ellipsoid) x mass (1 g ... 100 kg,
size scaled at constant density) x timestep x integrator x low-speed treatment, it builds a free
body tagged for the granular field, releases it at rest with its lowest point on the free surface
(z = 0), simulates it on a model with the engine plugin (``mjrft.load_model``) and records how
it settles:

* ``d_qs``: the quasi-static equilibrium depth, the root (``scipy.optimize.brentq``) of
  F_z(d) = m g, with F_z the vertical RFT force on the body moving straight down at depth d
  (``mjrft.body.body_wrench`` on the field's own element set). RFT forces depend on the direction
  of motion only, so the speed of that probe motion (1 mm/s) does not matter.
* ``d_dyn``: the depth where a body released at rest at the surface must stop in continuous time,
  from the work balance m g d = integral_0^d F_z(x) dx (exact for a pure vertical translation,
  since the force does not depend on speed). Pure RFT has no restoring force at rest: every depth
  with F_z(d) >= m g is a rest state (a Filippov "stick" set, like Coulomb friction), so the body
  overshoots ``d_qs`` and stops at ``d_dyn``.
* ``d_2w``: the depth where F_z = 2 m g. A first-order integrator that steps a sign-switching
  force settles into a period-2 cycle (one step moving down with F_z acting, one moving up with
  no force), whose mean force is m g only where F_z = 2 m g: an artefact of the numerics.
* per run: peak and final depth, the final depth's relative error against ``d_qs`` and ``d_dyn``,
  drift over the hold phase, creep rate, post-settle speeds, step-frequency oscillation (reversals
  of the linear or angular velocity), swing of the vertical and size of the lateral RFT force
  over the last second, maximum tilt, energy gained over a step against the stability tolerance
  (net of the work the lowering force does over that step: the criterion is about the medium,
  and a user force is not passive), and failures (exceptions such as the engine's
  ``mujoco.FatalError`` on a non-finite state, NaN, MuJoCo resets).

Frames and units: SI throughout (m, s, kg, N, J). World z is up, the free surface is z = 0 and
the depth of the body is the depth of its lowest point, d = -(z_c - h(R)), with z_c the height
of the body-frame origin (= centre of mass; geoms sit at the body origin) and h(R) the support
height of the rotated shape, sqrt(sum_i (a_i R_zi)^2) for semi-axes a_i (the half-height when
upright; a tipped ellipsoid is measured at its actual lowest point). Linear velocities are
world-frame (``qvel[0:3]`` of the free joint), angular velocities body-frame (``qvel[3:6]``).
Energies: E = kinetic + m |g| z_com, datum z = 0.

Run ``python benchmarks/stability.py`` (full sweep: ~10 min on 2 cores) or ``--quick`` (a small
subset in < 1 min). Writes ``benchmarks/stability_results/stability.csv`` and
``stability_map.png`` (``stability_quick.*`` for ``--quick``) and prints the table.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import multiprocessing
import os
import platform
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from scipy.optimize import brentq

import mjrft
from mjrft import GranularField
from mjrft.app import metadata
from mjrft.body import body_wrench, quat_to_mat, trajectory_wrenches
from mjrft.core.elements import ElementSet

# --------------------------------------------------------------------------- sweep definition

#: Masses swept [kg]: 1 g to 100 kg.
MASSES_KG: tuple[float, ...] = (0.001, 0.01, 0.1, 1.0, 10.0, 100.0)
#: Timesteps swept [s].
TIMESTEPS_S: tuple[float, ...] = (0.0001, 0.0005, 0.001, 0.002, 0.005)
#: MuJoCo integrators swept (``model.opt.integrator``).
INTEGRATORS: dict[str, int] = {
    "Euler": int(mujoco.mjtIntegrator.mjINT_EULER),
    "implicitfast": int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST),
    "RK4": int(mujoco.mjtIntegrator.mjINT_RK4),
}
#: The low-speed treatment axis: name -> scene options (``mjrft.SceneOptions``) of the model
#: (``mjrft.lowspeed``); everything downstream (runs, CSV, map, table) iterates over this dict.
TREATMENTS: dict[str, dict[str, Any]] = {
    "off": {"low_speed": "off"},
    "stick": {"low_speed": "stick"},
}
#: How the body is let go. "drop": released at rest on the surface at t = 0; it must stop at
#: d_dyn (pure RFT has no rate dependence, so the body overshoots d_qs; see the module
#: docstring). "lower": held at the surface by an upward user force (``xfrc_applied``) equal to
#: its weight, lowered to zero as W (1 + cos(pi t / T)) / 2 over T = RAMP_TIMES sqrt(d_qs / g)
#: before the settle phase: a quasi-static release, which must end at d_qs. (Moving down, the
#: medium acts like a stiffness k = m g / d_qs, so sqrt(d_qs / g) is the body's own time scale;
#: a ramp 20 times slower leaves a residual overshoot far below the 5 % criterion.)
RELEASES: tuple[str, ...] = ("drop", "lower")
RAMP_TIMES = 20.0

#: Density of every body [kg/m^3]: glass-like, so a 1 g sphere has a 4.6 mm radius and a 100 kg
#: one 212 mm. Both shapes use it, so they are comparable at equal mass.
DENSITY = 2500.0
#: Mole-crab ellipsoid (36 mm tall x 19 mm wide): semi-axes [m] along body x, y, z (long axis
#: vertical), scaled isotropically to the swept mass.
ELLIPSOID_AXES_M = (0.0095, 0.0095, 0.018)
SHAPES: tuple[str, ...] = ("sphere", "ellipsoid")
#: Triangles per body (MJCF ``prm``).
N_TRIANGLES = 600
MATERIAL = "glass_beads"

#: Stability criteria (docs/stability.md), used for the pass/fail columns.
DEPTH_TOL = 0.05  # relative error of the settle depth against d_dyn (drop) or d_qs (lower)
DRIFT_TOL_M = 1e-4  # drift over a 10 s hold [m]
SPEED_TOL = 1e-5  # post-settle speed [m/s]
OSC_TOL = 0.05  # fraction of steps (last second) where the velocity or spin reverses
E_ABS_TOL_J = 1e-9  # energy gain per step: E_ABS_TOL_J + E_REL_TOL * |E|
E_REL_TOL = 1e-6

#: Speed above which a run counts as blown up [m/s] (a body falling 1 m reaches 4.4 m/s).
BLOWUP_SPEED = 100.0


@dataclass(frozen=True)
class Case:
    """One run of the sweep.

    Attributes:
      shape: "sphere" or "ellipsoid". mass: [kg]. dt: timestep [s]. integrator: INTEGRATORS key.
      treatment: TREATMENTS key. settle_s, hold_s: durations [s] of the settle and hold phases.
      release: RELEASES entry. ramp_times: the lowering ramp's length in units of sqrt(d_qs / g).
    """

    shape: str
    mass: float
    dt: float
    integrator: str
    treatment: str
    settle_s: float
    hold_s: float
    release: str = "drop"
    ramp_times: float = RAMP_TIMES


@dataclass
class Result:
    """Measurements of one run (SI; depths positive below the surface; NaN where undefined)."""

    treatment: str
    release: str
    shape: str
    mass_kg: float
    size_m: float  # sphere radius or ellipsoid vertical semi-axis
    n_tri: int
    integrator: str
    dt_s: float
    settle_s: float
    hold_s: float
    steps: int = 0
    status: str = "ok"  # "ok" or "fail"
    failure: str = ""  # failure message (exception, NaN, MuJoCo reset, blow-up)
    t_fail_s: float = math.nan
    d_qs_m: float = math.nan  # quasi-static depth, F_z(d) = m g
    d_dyn_m: float = math.nan  # continuous-time stop depth (work balance)
    d_2w_m: float = math.nan  # F_z(d) = 2 m g (period-2 cycle depth)
    d_peak_m: float = math.nan  # deepest point reached
    d_final_m: float = math.nan  # mean depth over the last second
    err_qs: float = math.nan  # (d_final - d_qs) / d_qs
    err_dyn: float = math.nan  # (d_final - d_dyn) / d_dyn
    err_ref: float = math.nan  # err_dyn for a drop, err_qs for a lowering: the criterion
    drift_m: float = math.nan  # max |z_c(t) - z_c(t_settle)| over the hold
    drift_xy_m: float = math.nan  # max horizontal displacement over the hold
    creep_m_s: float = math.nan  # slope of depth vs time over the hold (+ = sinking)
    v_post_m_s: float = math.nan  # max |v| (state, qvel) over the last second
    v_dx_m_s: float = math.nan  # max |dx/dt| from position increments over the last second
    w_post_rad_s: float = math.nan  # max |omega| over the last second
    osc: float = math.nan  # fraction of steps where v or omega reverses (last second)
    osc_vz: float = math.nan  # fraction of steps where v_z changes sign (last second)
    osc_dz: float = math.nan  # same for the position increments dz
    fz_range_W: float = math.nan  # (max - min) of the RFT F_z over the last second / m g
    flat_W: float = math.nan  # max horizontal RFT force over the last second / m g
    tilt_deg: float = math.nan  # max angle of the body z axis from vertical
    egain_J: float = math.nan  # max energy gain over one step, net of the user force's work
    egain_ratio: float = math.nan  # max of gain / (E_ABS_TOL_J + E_REL_TOL |E|)
    egain_steps: int = 0  # steps whose gain exceeds that tolerance
    e_hold_J: float = math.nan  # E(end) - E(t_settle): net energy change over the hold
    wall_s: float = math.nan
    fails: str = ""  # criteria not met: depth, drift, speed, osc, energy, run


# --------------------------------------------------------------------------- model and depths


def body_size(shape: str, mass: float, density: float = DENSITY) -> np.ndarray:
    """MuJoCo geom size [m] of a shape with the given mass [kg] at the given density [kg/m^3]."""
    volume = mass / density
    if shape == "sphere":
        return np.array([(3.0 * volume / (4.0 * math.pi)) ** (1.0 / 3.0)])
    if shape == "ellipsoid":
        ref = np.array(ELLIPSOID_AXES_M)
        scale = (volume / (4.0 / 3.0 * math.pi * float(np.prod(ref)))) ** (1.0 / 3.0)
        return ref * scale
    raise ValueError(f"unknown shape {shape!r}")


def scene_xml(shape: str, mass: float, n_tri: int, density: float = DENSITY) -> str:
    """MJCF of one free body resting with its lowest point on the surface z = 0.

    The geom's ``mass`` is set explicitly (its size follows from the density), so the weight
    used by the root-finds is exactly the compiled one. Contacts are disabled: the medium acts
    only through the mjrft field.
    """
    size = body_size(shape, mass, density)
    half_height = float(size[-1])
    size_s = " ".join(f"{s:.9g}" for s in size)
    return f"""<mujoco model="stability_{shape}">
  <option timestep="0.001" integrator="Euler"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="{MATERIAL}"/>
    <tuple name="mjrft:intruders">
      <element objtype="geom" objname="body" prm="{n_tri}"/>
    </tuple>
  </custom>
  <worldbody>
    <body name="body" pos="0 0 {half_height:.9g}">
      <freejoint/>
      <geom name="body" type="{shape}" size="{size_s}" mass="{mass:.9g}"
            contype="0" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>"""


@dataclass(frozen=True)
class Reference:
    """Depths [m] of one body from the core force model (see the module docstring)."""

    d_qs: float
    d_dyn: float
    d_2w: float


def reference_depths(
    elements: ElementSet, half_height: float, weight: float, field: GranularField
) -> Reference:
    """Quasi-static, continuous-time stop and period-2 depths of an upright body.

    Args:
      elements: the field's element set of the body, body frame [m].
      half_height: height of the body origin above its lowest point when upright [m].
      weight: m g [N].
      field: the GranularField (for its material and surface height).
    """
    material, surface = field.material, field.surface_z
    down = np.array([0.0, 0.0, -1e-3])  # any downward speed: RFT depends on direction only

    def fz(d: float) -> float:
        pos = np.array([0.0, 0.0, surface + half_height - d])
        w = body_wrench(elements, pos, np.eye(3), down, np.zeros(3), material, surface_z=surface)
        return float(w.force[2])

    hi = half_height
    while fz(hi) < 2.5 * weight:  # bracket: deep enough to carry 2.5 m g
        hi *= 2.0
        if hi > 1e3 * half_height:
            raise RuntimeError("the medium cannot carry this body")
    d_qs = brentq(lambda d: fz(d) - weight, 0.0, hi, xtol=1e-12 * hi, rtol=1e-12)
    d_2w = brentq(lambda d: fz(d) - 2.0 * weight, 0.0, hi, xtol=1e-12 * hi, rtol=1e-12)
    # Work balance on a fine grid (F_z is piecewise smooth: triangles enter the medium one by one).
    grid = np.linspace(0.0, hi, 4001)
    pos = np.zeros((len(grid), 3))
    pos[:, 2] = surface + half_height - grid
    rot = np.broadcast_to(np.eye(3), (len(grid), 3, 3))
    f = trajectory_wrenches(
        elements, pos, rot, np.tile(down, (len(grid), 1)), np.zeros((len(grid), 3)), material,
        surface_z=surface,
    ).force[:, 2]  # fmt: skip
    work = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(grid))])
    excess = work - weight * grid  # < 0 until the body has dissipated its potential energy
    after = np.flatnonzero((grid > d_qs) & (excess >= 0.0))
    if after.size == 0:
        d_dyn = math.nan
    else:
        i = int(after[0])
        d_dyn = float(np.interp(0.0, excess[i - 1 : i + 1], grid[i - 1 : i + 1]))
    return Reference(float(d_qs), d_dyn, float(d_2w))


# --------------------------------------------------------------------------- one run


def com_positions(model: mujoco.MjModel, body: int, qpos: np.ndarray) -> np.ndarray:
    """(T, 3) world positions [m] of one free body's centre of mass from its (T, 7) free-joint
    positions (origin, quaternion w x y z)."""
    return qpos[:, :3] + quat_to_mat(qpos[:, 3:7]) @ model.body_ipos[body]


def user_work(model: mujoco.MjModel, body: int, qpos: np.ndarray, user_f: np.ndarray) -> np.ndarray:
    """(T - 1,) work [J] of the user force on one body over each step.

    Args:
      qpos: (T, 7) free-joint positions after each step (row 0: initial).
      user_f: (T, 3) world force [N] applied at the CoM (``xfrc_applied``) during the step that
        ends at each row (row 0 unused).
    The force is constant over a step (MuJoCo holds ``xfrc_applied`` through all RK4 stages), so
    its work is exactly F . (x_com(end) - x_com(start)) on whatever path the integrator takes.
    """
    com = com_positions(model, body, qpos)
    return np.einsum("ti,ti->t", user_f[1:], np.diff(com, axis=0))


def mechanical_energy(
    model: mujoco.MjModel, body: int, qpos: np.ndarray, qvel: np.ndarray
) -> np.ndarray:
    """Kinetic + gravitational potential energy [J] of one free body along a trajectory.

    Args:
      qpos: (T, 7) free-joint positions (world position of the body origin, quaternion w x y z).
      qvel: (T, 6) free-joint velocities (world linear velocity of the origin, body-frame omega).
    Returns:
      (T,) E = 1/2 m |v_com|^2 + 1/2 omega.I omega + m |g| z_com, z datum at z = 0.
    """
    m = float(model.body_mass[body])
    g = -float(model.opt.gravity[2])
    rot = quat_to_mat(qpos[:, 3:7])  # body -> world
    ipos = model.body_ipos[body]
    com = com_positions(model, body, qpos)
    w_body = qvel[:, 3:6]
    v_com = qvel[:, :3] + np.einsum("tij,tj->ti", rot, np.cross(w_body, ipos))
    r_i = quat_to_mat(model.body_iquat[body])  # inertia frame -> body frame
    inertia = r_i @ np.diag(model.body_inertia[body]) @ r_i.T
    ke = 0.5 * m * np.einsum("ti,ti->t", v_com, v_com)
    ke += 0.5 * np.einsum("ti,ij,tj->t", w_body, inertia, w_body)
    return ke + m * g * com[:, 2]


def sign_change_fraction(x: np.ndarray, floor: float) -> float:
    """Fraction of consecutive pairs of x with opposite signs (|values| <= floor count as 0)."""
    s = np.sign(np.where(np.abs(x) > floor, x, 0.0))
    if len(s) < 2:
        return math.nan
    return float(np.mean(s[1:] * s[:-1] < 0.0))


def run_case(case: Case, n_tri: int, ref_cache: dict[tuple[str, float], Reference]) -> Result:
    """Simulate one case and measure it (never raises for a failing simulation)."""
    size = body_size(case.shape, case.mass)
    half_height = float(size[-1])
    res = Result(
        treatment=case.treatment, release=case.release, shape=case.shape, mass_kg=case.mass,
        size_m=half_height,
        n_tri=0, integrator=case.integrator, dt_s=case.dt, settle_s=case.settle_s,
        hold_s=case.hold_s,
    )  # fmt: skip
    model = mjrft.load_model(scene_xml(case.shape, case.mass, n_tri), **TREATMENTS[case.treatment])
    model.opt.timestep = case.dt
    model.opt.integrator = INTEGRATORS[case.integrator]
    body = model.body("body").id
    field = GranularField(model)
    res.n_tri = field.n_elements
    weight = float(model.body_mass[body]) * -float(model.opt.gravity[2])
    key = (case.shape, case.mass)
    if key not in ref_cache:
        ref_cache[key] = reference_depths(field.body_element_set(body), half_height, weight, field)
    ref = ref_cache[key]
    res.d_qs_m, res.d_dyn_m, res.d_2w_m = ref.d_qs, ref.d_dyn, ref.d_2w

    ramp_s = 0.0
    if case.release == "lower":
        ramp_s = case.ramp_times * math.sqrt(ref.d_qs / -float(model.opt.gravity[2]))
        case = dataclasses.replace(case, settle_s=ramp_s + case.settle_s)
        res.settle_s = case.settle_s
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    n = round((case.settle_s + case.hold_s) / case.dt)
    qpos = np.full((n + 1, 7), np.nan)
    qvel = np.full((n + 1, 6), np.nan)
    wrench = np.full((n + 1, 6), np.nan)  # RFT force, torque on the body (last forward pass)
    user_f = np.zeros((n + 1, 3))  # lowering force during the step that ends at each row
    qpos[0], qvel[0], wrench[0] = data.qpos, data.qvel, 0.0
    done = 0
    t0 = time.perf_counter()
    try:
        n_ramp = round(ramp_s / case.dt)
        rft = field.wrench_of(data)  # a view of data's last pass, updated by every step
        for i in range(1, n + 1):
            if n_ramp and i <= n_ramp + 1:  # assign the whole row (ownership protocol)
                data.xfrc_applied[body] = 0.0
                s = min(1.0, (i - 1) / n_ramp)
                data.xfrc_applied[body, 2] = weight * 0.5 * (1.0 + math.cos(math.pi * s))
                user_f[i, 2] = data.xfrc_applied[body, 2]
            mujoco.mj_step(model, data)
            qpos[i], qvel[i], wrench[i] = data.qpos, data.qvel, rft[body]
            if not np.all(np.isfinite(qvel[i])):
                raise FloatingPointError(f"non-finite state at t = {data.time:.6g} s")
            if abs(qvel[i, 2]) > BLOWUP_SPEED:
                raise FloatingPointError(f"|v_z| > {BLOWUP_SPEED} m/s at t = {data.time:.6g}")
            if data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number:
                raise FloatingPointError("MuJoCo reset the state (bad qacc)")
            done = i  # steps 0..done are valid
    except Exception as exc:  # record any failure: that is what the map is for
        res.status, res.failure = "fail", f"{type(exc).__name__}: {exc}".replace("\n", " ")
        res.t_fail_s = (done + 1) * case.dt
    res.wall_s = time.perf_counter() - t0
    res.steps = done
    n_ok = done + 1
    measure(res, model, body, size, qpos[:n_ok], qvel[:n_ok], wrench[:n_ok], case, user_f[:n_ok])
    return res


def measure(
    res: Result,
    model: mujoco.MjModel,
    body: int,
    size: np.ndarray,
    qpos: np.ndarray,
    qvel: np.ndarray,
    wrench: np.ndarray,
    case: Case,
    user_f: np.ndarray | None = None,
) -> None:
    """Fill the measurement fields of res from the recorded trajectory (steps 0..T).

    Args:
      size: geom size [m] (sphere radius, or ellipsoid semi-axes along body x, y, z).
      qpos, qvel: (T + 1, 7) and (T + 1, 6) free-joint state after each step (row 0: initial).
      wrench: (T + 1, 6) RFT force [N] and torque [N m] on the body, world frame, of the last
        forward pass of each step (``field.wrench_of(data)``; for RK4 its last stage).
      user_f: (T + 1, 3) user force [N] at the CoM during the step ending at each row (the
        lowering), or None; its work is taken off each step's energy gain.
    """
    dt = case.dt
    axes = np.broadcast_to(size, (3,))
    rot_z = quat_to_mat(qpos[:, 3:7])[:, 2, :]  # world z row of body -> world
    depth = np.sqrt(np.sum((axes * rot_z) ** 2, axis=1)) - qpos[:, 2]  # lowest point below z = 0
    res.d_peak_m = float(np.max(depth))
    energy = mechanical_energy(model, body, qpos, qvel)
    gain = np.diff(energy)
    if user_f is not None:
        gain -= user_work(model, body, qpos, user_f)
    if gain.size:
        tol = E_ABS_TOL_J + E_REL_TOL * np.abs(energy[:-1])
        res.egain_J = float(np.max(gain))
        res.egain_ratio = float(np.max(gain / tol))
        res.egain_steps = int(np.count_nonzero(gain > tol))
    res.tilt_deg = float(np.degrees(np.max(np.arccos(np.clip(rot_z[:, 2], -1.0, 1.0)))))
    if res.status == "fail":
        res.fails = "run"
        return
    i_settle = round(case.settle_s / dt)
    i_last = max(len(depth) - round(1.0 / dt), i_settle)
    hold = slice(i_settle, None)
    last = slice(i_last, None)
    res.d_final_m = float(np.mean(depth[last]))
    res.err_qs = (res.d_final_m - res.d_qs_m) / res.d_qs_m
    res.err_dyn = (res.d_final_m - res.d_dyn_m) / res.d_dyn_m
    res.err_ref = res.err_dyn if case.release == "drop" else res.err_qs
    res.drift_m = float(np.max(np.abs(qpos[hold, 2] - qpos[i_settle, 2])))
    res.drift_xy_m = float(np.max(np.linalg.norm(qpos[hold, :2] - qpos[i_settle, :2], axis=1)))
    t = np.arange(len(depth))[hold] * dt
    res.creep_m_s = float(np.polyfit(t, depth[hold], 1)[0]) if len(t) > 1 else math.nan
    res.v_post_m_s = float(np.max(np.linalg.norm(qvel[last, :3], axis=1)))
    dx = np.diff(qpos[i_last - 1 :, :3], axis=0) / dt
    res.v_dx_m_s = float(np.max(np.linalg.norm(dx, axis=1)))
    res.w_post_rad_s = float(np.max(np.linalg.norm(qvel[last, 3:], axis=1)))
    floor = 1e-12  # [m/s]: below this a velocity counts as zero
    v, w = qvel[last, :3], qvel[last, 3:]
    # Reversals between steps; velocities at round-off level (< floor) count as rest, not motion.
    v = np.where(np.linalg.norm(v, axis=1, keepdims=True) > floor, v, 0.0)
    w = np.where(np.linalg.norm(w, axis=1, keepdims=True) > floor, w, 0.0)
    reverse = (np.einsum("ti,ti->t", v[1:], v[:-1]) < 0.0) | (
        np.einsum("ti,ti->t", w[1:], w[:-1]) < 0.0
    )
    res.osc = float(np.mean(reverse)) if reverse.size else math.nan
    res.osc_vz = sign_change_fraction(qvel[last, 2], floor)
    weight = float(model.body_mass[body]) * -float(model.opt.gravity[2])
    res.fz_range_W = float(np.ptp(wrench[last, 2]) / weight)
    res.flat_W = float(np.max(np.linalg.norm(wrench[last, :2], axis=1)) / weight)
    res.osc_dz = sign_change_fraction(dx[:, 2], floor)
    res.e_hold_J = float(energy[-1] - energy[i_settle])
    fails = []
    if not abs(res.err_ref) <= DEPTH_TOL:
        fails.append("depth")
    if not res.drift_m <= DRIFT_TOL_M * case.hold_s / 10.0:  # 0.1 mm over 10 s
        fails.append("drift")
    if not res.v_post_m_s <= SPEED_TOL:
        fails.append("speed")
    if not res.osc <= OSC_TOL:
        fails.append("osc")
    if res.egain_steps:
        fails.append("energy")
    res.fails = " ".join(fails)


# --------------------------------------------------------------------------- outputs

FIELDS = [f.name for f in dataclasses.fields(Result)]


def write_csv(results: Sequence[Result], path: Path) -> None:
    """One row per run; column names and units as in ``Result`` (SI)."""
    tmp = path.with_suffix(".tmp")
    with tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(FIELDS)
        for r in results:
            row = []
            for name in FIELDS:
                v = getattr(r, name)
                row.append(f"{v:.6g}" if isinstance(v, float) else v)
            w.writerow(row)
    tmp.replace(path)


def read_csv(path: Path) -> list[Result]:
    """Results back from a CSV written by ``write_csv`` (for ``--plot-only``)."""
    types = {f.name: f.type for f in dataclasses.fields(Result)}
    out = []
    with path.open(newline="") as fh:
        for row in csv.DictReader(fh):
            kw: dict[str, Any] = {}
            for name, text in row.items():
                kind = types[name]
                kw[name] = float(text) if kind == "float" else int(text) if kind == "int" else text
            out.append(Result(**kw))
    return out


def _fmt(x: float, spec: str) -> str:
    return "-" if not np.isfinite(x) else format(x, spec)


def table(results: Sequence[Result]) -> str:
    """Compact fixed-width table of the results."""
    head = (
        f"{'treat':5} {'rel':5} {'shape':9} {'mass':>6} {'integ':12} {'dt_ms':>5} {'d_qs':>6}"
        f" {'d_dyn':>6}"
        f" {'d_2w':>6} {'d_fin':>6} {'err_qs':>7} {'err_dyn':>7} {'drift':>8} {'creep':>9}"
        f" {'v_post':>8} {'v_dx':>8}"
        f" {'osc':>4} {'tilt':>5} {'dFz/W':>5} {'Fxy/W':>5} {'egain/tol':>9} {'E_hold':>8}"
        f" {'fails'}"
    )
    units = (
        f"{'':5} {'':5} {'':9} {'kg':>6} {'':12} {'':>5} {'mm':>6} {'mm':>6} {'mm':>6} {'mm':>6}"
        f" {'%':>7}"
        f" {'%':>7} {'mm':>8} {'mm/s':>9} {'m/s':>8} {'m/s':>8} {'':>4} {'deg':>5} {'':>5}"
        f" {'':>5} {'':>9}"
        f" {'J':>8}"
    )
    lines = [head, units]
    for r in results:
        fails = r.fails if r.status == "ok" else f"FAIL {r.failure[:60]} @ {r.t_fail_s:.3g} s"
        lines.append(
            f"{r.treatment:5} {r.release:5} {r.shape:9} {r.mass_kg:6g} {r.integrator:12}"
            f" {r.dt_s * 1e3:5g}"
            f" {r.d_qs_m * 1e3:6.2f} {r.d_dyn_m * 1e3:6.2f} {r.d_2w_m * 1e3:6.2f}"
            f" {_fmt(r.d_final_m * 1e3, '6.2f')} {_fmt(r.err_qs * 100, '+7.1f')}"
            f" {_fmt(r.err_dyn * 100, '+7.1f')} {_fmt(r.drift_m * 1e3, '8.3g')}"
            f" {_fmt(r.creep_m_s * 1e3, '+9.2g')} {_fmt(r.v_post_m_s, '8.2g')}"
            f" {_fmt(r.v_dx_m_s, '8.2g')} {_fmt(r.osc, '4.2f')} {_fmt(r.tilt_deg, '5.2g')}"
            f" {_fmt(r.fz_range_W, '5.2f')} {_fmt(r.flat_W, '5.2f')}"
            f" {_fmt(r.egain_ratio, '9.2g')} {_fmt(r.e_hold_J, '+8.2g')} {fails}"
        )
    return "\n".join(lines)


#: Map rows: (Result field, title, log10 colour scale?, colour map, value scale for the cell text).
MAP_METRICS: tuple[tuple[str, str, bool, str, float], ...] = (
    ("err_ref", "depth error vs d_dyn (drop) / d_qs (lower) [%]", False, "RdBu_r", 100.0),
    ("drift_m", "drift over the hold [mm]", True, "viridis", 1e3),
    ("v_post_m_s", "post-settle max speed, last 1 s [mm/s]", True, "viridis", 1e3),
    ("egain_ratio", "max energy gain per step / tolerance", True, "plasma", 1.0),
)


def plot_map(results: Sequence[Result], path: Path, subtitle: str) -> None:
    """Heat maps mass x timestep: rows = metric (x treatment), columns = shape x integrator.

    Failed runs are drawn dark grey with "FAIL" and the failure time; the depth panels also show
    the fraction of steps with step-frequency oscillation (``osc``) and the maximum tilt.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap, LogNorm, Normalize
    from matplotlib.ticker import NullFormatter

    treatments = list(dict.fromkeys((r.treatment, r.release) for r in results))
    shapes = list(dict.fromkeys(r.shape for r in results))
    integrators = list(dict.fromkeys(r.integrator for r in results))
    masses = sorted({r.mass_kg for r in results})
    dts = sorted({r.dt_s for r in results})
    by_key = {
        ((r.treatment, r.release), r.shape, r.integrator, r.mass_kg, r.dt_s): r for r in results
    }
    cols = [(s, i) for s in shapes for i in integrators]
    rows = [(t, m) for t in treatments for m in MAP_METRICS]
    fig, axes = plt.subplots(
        len(rows), len(cols), figsize=(2.9 * len(cols) + 1.2, 2.5 * len(rows) + 0.8),
        squeeze=False, constrained_layout=True,
    )  # fmt: skip
    for ri, (treat, (name, title, log, cmap, scale)) in enumerate(rows):
        grid = np.full((len(masses), len(dts)), np.nan)
        failed = np.zeros_like(grid, dtype=bool)
        for ci, (shape, integ) in enumerate(cols):
            for mi, m in enumerate(masses):
                for di, dt in enumerate(dts):
                    r = by_key.get((treat, shape, integ, m, dt))
                    grid[mi, di] = np.nan if r is None else getattr(r, name) * scale
                    failed[mi, di] = r is not None and r.status == "fail"
            cells = [
                getattr(r, name) * scale
                for r in results
                if (r.treatment, r.release) == treat and r.status == "ok"
            ]
            finite = np.array([c for c in cells if np.isfinite(c)])
            if log:
                pos = finite[finite > 0]
                lo, hi = (pos.min(), pos.max()) if pos.size else (1e-12, 1.0)
                norm = LogNorm(vmin=lo, vmax=max(hi, lo * 10))
                shown = np.where(grid > 0, grid, lo)
            else:
                span = np.max(np.abs(finite)) if finite.size else 1.0
                norm = Normalize(-span, span)
                shown = grid
            ax = axes[ri, ci]
            masked = np.ma.masked_where(failed | ~np.isfinite(grid), shown)
            im = ax.imshow(masked, origin="lower", aspect="auto", cmap=cmap, norm=norm)
            ax.imshow(
                np.ma.masked_where(~failed, np.ones_like(grid)), origin="lower", aspect="auto",
                cmap=ListedColormap(["0.3"]), vmin=0, vmax=1,
            )  # fmt: skip
            for mi, m in enumerate(masses):
                for di, dt in enumerate(dts):
                    r = by_key.get((treat, shape, integ, m, dt))
                    if r is None:
                        continue
                    if r.status == "fail":
                        text, colour = f"FAIL\n{r.t_fail_s:.2g}s", "white"
                    else:
                        v = grid[mi, di]
                        text = f"{v:.2g}" if np.isfinite(v) else "-"
                        if name == "err_ref":
                            tilt = r.tilt_deg
                            text += f"\nosc {r.osc:.2f}"
                            text += f"\ntilt {tilt:.0f}°" if tilt >= 1 else f"\ntilt {tilt:.1f}°"
                        rgba = im.cmap(norm(shown[mi, di]))
                        lum = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2]
                        colour = "black" if lum > 0.5 else "white"
                    ax.text(di, mi, text, ha="center", va="center", fontsize=6.5, color=colour)
            ax.set_xticks(range(len(dts)), [f"{dt * 1e3:g}" for dt in dts], fontsize=7)
            ax.set_yticks(range(len(masses)), [f"{m:g}" for m in masses], fontsize=7)
            if ri == len(rows) - 1:
                ax.set_xlabel("timestep [ms]", fontsize=8)
            if ci == 0:
                ax.set_ylabel(f"{title}\n[{treat[0]}, {treat[1]}]  mass [kg]", fontsize=8)
            if ri == 0 or len(treatments) > 1:
                ax.set_title(f"{shape}, {integ}", fontsize=9)
        cbar = fig.colorbar(im, ax=axes[ri, :], shrink=0.9, pad=0.01)
        cbar.ax.tick_params(labelsize=7)
        cbar.ax.yaxis.set_minor_formatter(NullFormatter())
    fig.suptitle(
        "mjrft stability map: passive body released at rest on the surface of glass beads\n"
        + subtitle,
        fontsize=10,
    )
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)


# --------------------------------------------------------------------------- main


def cpu_name() -> str:
    """CPU model name (as lscpu reports it) and core count."""
    return f"{metadata.machine()['cpu'] or platform.machine()}, {os.cpu_count()} cores"


def build_cases(args: argparse.Namespace) -> list[Case]:
    """The sweep (full, or the --quick subset)."""
    if args.quick:
        masses, dts, shapes = (0.01, 10.0), (0.001, 0.005), SHAPES
    else:
        masses, dts, shapes = MASSES_KG, TIMESTEPS_S, SHAPES
    # The baseline (treatment off) only for the drop: it never settles either way.
    return [
        Case(shape, m, dt, integ, treat, args.settle, args.hold, release, args.ramp_times)
        for treat in TREATMENTS
        for release in RELEASES
        if release in args.releases
        if treat != "off" or release == "drop"
        for shape in shapes
        for m in masses
        for integ in INTEGRATORS
        if integ in args.integrators
        for dt in dts
    ]


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="small subset (< 1 min), *_quick files")
    p.add_argument("--settle", type=float, default=None, help="settle phase [s] (2; quick 1)")
    p.add_argument("--hold", type=float, default=None, help="hold phase [s] (10; quick 1)")
    p.add_argument("--triangles", type=int, default=N_TRIANGLES, help="triangles per body")
    p.add_argument(
        "--ramp-times", type=float, default=RAMP_TIMES,
        help=f"lowering ramp in units of sqrt(d_qs / g) (default {RAMP_TIMES:g}; 200: 10x slower)",
    )  # fmt: skip
    p.add_argument(
        "--integrators", nargs="+", choices=list(INTEGRATORS), default=list(INTEGRATORS),
        help="integrators to sweep (default: all)",
    )  # fmt: skip
    p.add_argument(
        "--releases", nargs="+", choices=list(RELEASES), default=list(RELEASES),
        help="releases to sweep (default: all)",
    )  # fmt: skip
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes")
    p.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parent / "stability_results"
    )
    p.add_argument(
        "--plot-only", action="store_true", help="redraw the map and table from the CSV, no runs"
    )
    args = p.parse_args(argv)
    if args.settle is None:
        args.settle = 1.0 if args.quick else 2.0
    if args.hold is None:
        args.hold = 1.0 if args.quick else 10.0
    args.out.mkdir(parents=True, exist_ok=True)
    stem = "stability_quick" if args.quick else "stability"
    map_name = "stability_map_quick.png" if args.quick else "stability_map.png"
    subtitle = (
        f"settle {args.settle:g} s + hold {args.hold:g} s, {args.triangles} triangles, "
        f"density {DENSITY:g} kg/m^3; colours share one scale per row"
    )
    if args.plot_only:
        results = read_csv(args.out / f"{stem}.csv")
        plot_map(results, args.out / map_name, subtitle)
        print(table(results))
        return 0
    cases = build_cases(args)
    print(
        f"{len(cases)} runs: settle {args.settle:g} s + hold {args.hold:g} s each, "
        f"{args.triangles} triangles, density {DENSITY:g} kg/m^3, material {MATERIAL}",
        flush=True,
    )
    results: list[Result] = []
    t_start = time.perf_counter()
    with multiprocessing.get_context("spawn").Pool(args.jobs) as pool:
        runs = pool.imap(_run_one, [(c, args.triangles) for c in cases])
        for k, (case, r) in enumerate(zip(cases, runs, strict=True), 1):
            _report(k, len(cases), case, r, results, args, stem)
    wall = time.perf_counter() - t_start
    cpu = cpu_name()
    plot_map(results, args.out / map_name, subtitle)
    print()
    print(table(results))
    print(
        f"\n{len(results)} runs in {wall:.0f} s on {cpu}, {args.jobs} processes (python "
        f"{sys.version.split()[0]}); wrote {args.out / (stem + '.csv')} and {args.out / map_name}"
    )
    return 0


_REFS: dict[tuple[str, float], Reference] = {}  # per worker process


def _run_one(job: tuple[Case, int]) -> Result:
    case, n_tri = job
    return run_case(case, n_tri, _REFS)


def _report(k: int, n: int, case: Case, r: Result, results: list[Result], args, stem: str) -> None:
    """Print one finished run and checkpoint the CSV every 10 runs."""
    results.append(r)
    state = r.fails or "all criteria met"
    if r.status == "fail":
        state = f"FAIL at {r.t_fail_s:.3g} s: {r.failure[:70]}"
    print(
        f"[{k:3d}/{n}] {case.treatment} {case.release} {case.shape:9} m={case.mass:<6g} "
        f"{case.integrator:12} dt={case.dt * 1e3:g} ms: d={_fmt(r.d_final_m * 1e3, '.3f')} mm "
        f"(qs {r.d_qs_m * 1e3:.3f}, dyn {r.d_dyn_m * 1e3:.3f}, "
        f"err {_fmt(r.err_ref * 100, '+.1f')}%) "
        f"drift {_fmt(r.drift_m * 1e3, '.3g')} mm, v {_fmt(r.v_post_m_s, '.2g')} m/s, "
        f"osc {_fmt(r.osc, '.2f')}; {state} [{r.wall_s:.1f} s]",
        flush=True,
    )
    if k % 10 == 0 or k == n:
        write_csv(results, args.out / f"{stem}.csv")


if __name__ == "__main__":
    raise SystemExit(main())
