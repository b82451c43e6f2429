"""Speed vs accuracy: force error and cost as functions of triangle count, error vs timestep.

Run: python benchmarks/pareto.py [--quick]

1. Force error vs triangle count, prescribed trajectories (no MuJoCo): the sphere (1 cm radius;
   lowest point starting at the surface, descending 1 cm/s for 3 s with 0.3 cm/s lateral velocity
   along x and a 1 rad/s spin about the horizontal axis (1, 1, 0)/sqrt 2), the mole-crab
   ellipsoid and the root-tip paraboloid under their rigs' motions (exactly the trajectories of
   ``mjrft.demos.ellipsoid_pitch`` and ``root_circumnutation``, at the demos' sample spacing), and
   the pure translations of the same shapes: the sphere straight down (what sphere_drop.xml does)
   and the ellipsoid demo without pitch. Reference: the same shape at ~REF_TRIANGLES (400,000)
   triangles, the mesh near that count with the most mid-planes on lattice lines. Metrics:
     force error  = RMS_t |F(t) - F_ref(t)| / max_t |F_ref(t)|,
     moment error = RMS_t |M(t) - M_ref(t)| / (max_t |F_ref(t)| * L),
   M about the body origin (sphere/ellipsoid centre, the paraboloid's pivot), L = the largest
   distance of a surface point from that origin (the moment of a symmetric body about its centre
   can be near zero, so it is scaled by peak force times size, not by its own peak). Cost: wall
   time of one evaluation per trajectory sample (compiled kernel ``mjrft.core.kernel``, the
   field's own hot path; identical to ``mjrft.body.trajectory_wrenches`` to 1e-15, checked here).
2. Fit error(n) = C n^-p per case (log-log least squares over 400 <= n <= REF/8); rule A (the
   three rig motions only: p = min p, C = MARGIN x the envelope of the measured points) and the
   proposed rule n(tol) = max(RULE_FLOOR, ceil((RULE_C / tol)^(1 / RULE_P))) covering all five
   cases. Both validated on shapes not used in the fit (capsule, cylinder, box, elongated
   ellipsoid 5 x 10 x 30 mm semi-axes, a pancake ellipsoid 30 x 20 x 6 mm, a long capsule
   of radius 3 mm and half-length 25 mm; and, blind to the choice of the rule's margin, a disc
   cylinder of radius 15 mm and half-length 2 mm) under the
   sphere's generic motion from a 17 deg tilted start, and under pure translations with the
   mesh lattice aligned to the surface. Then the lattice-parity effect: straight-down error
   with and without mesh vertices on z = 0 (since the curved shapes keep lattice lines on their
   mid-planes, every mesh has them).
3. Cost per mj_step vs triangle count (MuJoCo, field installed, Euler, dt = 1 ms):
   models/sphere_drop.xml (sphere resting in the medium, t = 0.3 s) and
   models/ellipsoid_pitch.xml (deep, t = 10 s); medians over repeats. The root rig is a fixed
   2976-triangle mesh, so the paraboloid's cost is the per-sample time of part 1.
4. Trajectory error vs timestep (Euler, 2000 triangles): ellipsoid_pitch.xml (driven rig, 4 s;
   RFT force error as in 1) and sphere_drop.xml (free, 1 s; CoM position error) at dt = 0.25,
   0.5, 1, 2 ms against dt = 0.125 ms, on a common 2 ms time grid.

Full run about 5 min on 2 cores, --quick about 30 s. Writes benchmarks/results/pareto_*.csv
and pareto.png (pareto_quick_* with --quick).
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from mjrft import geometry, simulate
from mjrft.app import demos
from mjrft.body import trajectory_wrenches
from mjrft.core import kernel as _kernel
from mjrft.core import surface
from mjrft.core.elements import ElementSet
from mjrft.core.material import Material
from mjrft.core.units import MM
from mjrft.field import GranularField

OUT = Path(__file__).resolve().parent / "results"
MODELS = Path(__file__).resolve().parents[1] / "models"

MATERIAL = Material.preset("glass_beads")
REF_TRIANGLES = 400_000
COUNTS = (100, 200, 400, 1000, 2000, 4000, 10_000, 20_000, 50_000, 100_000, 200_000)
FIT_MIN = 400  # fit over FIT_MIN <= n <= REF/8 (closer to the reference, its own error shows)
TOLERANCES = (0.10, 0.03, 0.01, 0.003)

# The rule proposed for the knob, n(tol) = max(RULE_FLOOR, ceil((RULE_C / tol)^(1 / RULE_P))):
# p = 0.8, below every fitted order (0.92-1.03); C = 5.2, 2.1x the envelope of all five fitted
# cases at that p (2.46, set by the root tip; the held-out shapes reach 2.67, the slender
# ellipsoid). The curved shapes keep lattice lines on their mid-planes (mjrft.geometry), so pure
# translations converge at p ~ 1 like the rest (a lattice cutting a mid-plane gives p = 0.4-0.6
# there). The script reports the rule's margin over that envelope, then validates the rule on
# shapes not used in the fit: the validation, not the margin, is what the rule must pass.
RULE_C = 5.2
RULE_P = 0.8
RULE_FLOOR = 200  # below ~200 triangles errors are not yet asymptotic (capsule: 20 % at 28)
# Envelope margin of rule A over its measured points: covers geometry's +-25 % rounding of
# n_triangles (1.25^p = 1.2) and the spread between shapes (slender ones converge with larger C).
# Rules at 1.5x and 2x a smaller envelope (C = 2.6 and 3.4) missed held-out cases by 1-7 % (the
# slender 5 x 10 x 30 mm ellipsoid; a long capsule in tests/test_tolerance.py), so the held-out
# shapes below are not blind to the choice of C, except FRESH_HELD_OUT.
MARGIN = 3.0
FRESH_HELD_OUT = ("disc cylinder", "disc cylinder, down+lateral")

Motion = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # pos, rot, lin_vel, ang_vel


# --------------------------------------------------------------------------------------------
# Prescribed trajectories
# --------------------------------------------------------------------------------------------


def axis_angle(axis, angle) -> np.ndarray:
    """(..., 3, 3) rotation matrices about a fixed axis by angle(s) [rad] (Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    ang = np.asarray(angle, dtype=float)[..., None, None]
    return np.eye(3) + np.sin(ang) * k + (1.0 - np.cos(ang)) * (k @ k)


def generic_motion(
    shape: ElementSet,
    r0: np.ndarray,
    dt: float,
    *,
    duration: float = 3.0,
    descent: float = 0.01,
    lateral: float = 0.003,
    spin: float = 1.0,
    axis=(1.0, 1.0, 0.0),
) -> Motion:
    """Lowest point starting at the surface; descent [m/s] + lateral x [m/s] + spin [rad/s].

    The body starts at orientation r0 and spins about the fixed world axis; the body origin
    moves in a straight line.
    """
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    rot = axis_angle(axis, spin * t) @ r0
    z0 = -(shape.vertices @ r0.T)[:, 2].min()
    pos = np.zeros((len(t), 3))
    pos[:, 0] = lateral * t
    pos[:, 2] = z0 - descent * t
    vel = np.zeros_like(pos)
    vel[:, 0], vel[:, 2] = lateral, -descent
    ang = np.tile(spin * np.asarray(axis) / np.linalg.norm(axis), (len(t), 1))
    return pos, rot, vel, ang


def ellipsoid_rig_motion(dt: float) -> Motion:
    """mjrft.demos.ellipsoid_pitch's trajectory: pitch 9 deg at 0.625 Hz, descent 0.5 cm/s."""
    t = np.arange(0.0, demos.ELLIPSOID_DURATION + 0.5 * dt, dt)
    w = 2.0 * np.pi * demos.ELLIPSOID_PITCH_FREQUENCY
    amp = demos.ELLIPSOID_PITCH_AMPLITUDE
    pos = np.zeros((len(t), 3))
    pos[:, 2] = demos.ELLIPSOID_START_HEIGHT - demos.ELLIPSOID_DESCENT_SPEED * t
    vel = np.zeros_like(pos)
    vel[:, 2] = -demos.ELLIPSOID_DESCENT_SPEED
    ang = np.zeros_like(pos)
    ang[:, 1] = amp * w * np.cos(w * t)
    return pos, demos._rot_y(amp * np.sin(w * t)), vel, ang


def root_rig_motion(dt: float) -> Motion:
    """mjrft.demos.root_circumnutation's trajectory: tilt 10 deg, yaw 15 deg/s, helical descent."""
    t = np.arange(0.0, demos.ROOT_DURATION + 0.5 * dt, dt)
    rot = demos._rot_z(demos.ROOT_YAW_RATE * t) @ demos._rot_y(np.full_like(t, demos.ROOT_TILT))
    descent = demos.ROOT_HELICAL_PITCH * demos.ROOT_YAW_RATE / (2.0 * np.pi)
    pos = np.zeros((len(t), 3))
    pos[:, 2] = -descent * t
    vel = np.zeros_like(pos)
    vel[:, 2] = -descent
    ang = np.zeros_like(pos)
    ang[:, 2] = demos.ROOT_YAW_RATE
    return pos, rot, vel, ang


def root_shape(n: int) -> ElementSet:
    """The demo's paraboloid placed as in the demo: apex ``ROOT_PIVOT_ABOVE_APEX`` below the
    body origin (the pivot)."""
    shape = geometry.paraboloid(demos.ROOT_RADIUS, demos.ROOT_LENGTH, n_triangles=n)
    return shape.transformed(np.eye(3), np.array([0.0, 0.0, -demos.ROOT_PIVOT_ABOVE_APEX]))


_NO_REGION = np.zeros((2, 3))
_FLAT = surface.flat(0.0)


def evaluate(shape: ElementSet, motion: Motion) -> tuple[np.ndarray, float]:
    """(T, 6) force and moment about the body origin along the motion; seconds per sample."""
    pos, rot, vel, ang = motion
    cent = np.ascontiguousarray(shape.centroids)
    norm = np.ascontiguousarray(shape.normals)
    area = np.ascontiguousarray(shape.areas)
    rot = np.ascontiguousarray(rot)
    co, ay, zeta = MATERIAL.kernel_coefficients, MATERIAL.alpha_y0, MATERIAL.zeta
    elem = np.zeros((len(area), 3))
    out = np.zeros((len(pos), 6))
    t0 = time.perf_counter()
    for i in range(len(pos)):
        _kernel.body_wrench(
            cent, norm, area, 0, len(area), co, ay, zeta, _FLAT.prm, _FLAT.grid, False,
            _NO_REGION,
            rot[i], pos[i], ang[i], vel[i], pos[i], pos[i], out[i], elem,
        )  # fmt: skip
    return out, (time.perf_counter() - t0) / len(pos)


def errors(w: np.ndarray, ref: np.ndarray, size: float) -> tuple[float, float]:
    """(force error, moment error) as defined in the module docstring."""
    fmax = np.linalg.norm(ref[:, :3], axis=1).max()
    ef = math.sqrt(np.mean(np.sum((w[:, :3] - ref[:, :3]) ** 2, axis=1))) / fmax
    em = math.sqrt(np.mean(np.sum((w[:, 3:] - ref[:, 3:]) ** 2, axis=1))) / (fmax * size)
    return ef, em


def midplanes(shape: ElementSet) -> tuple[bool, bool, bool]:
    """Whether mesh vertices lie on the x, y, z mid-planes of the shape's bounding box."""
    v = shape.vertices
    c = 0.5 * (v.max(axis=0) + v.min(axis=0))
    tol = 1e-9 * np.abs(v).max()
    return tuple(bool(np.any(np.abs(v[:, k] - c[k]) < tol)) for k in range(3))


def reference_shape(make: Callable[[int], ElementSet], n: int, tries: int) -> ElementSet:
    """The mesh near n triangles with the most mid-planes on lattice lines (see the parity study:
    a leading-edge or waterline boundary along a lattice line has no first-order error)."""
    best, best_score = None, -1
    for j in range(tries):
        shape = make(round(n * 1.015**j))
        score = sum(midplanes(shape))
        if score > best_score:
            best, best_score = shape, score
        if score == 3:
            break
    return best


class Case:
    """A shape family (n -> ElementSet) under one prescribed motion, with its reference."""

    def __init__(self, name: str, make: Callable[[int], ElementSet], motion_fn, ref_n: int):
        self.name = name
        self.make = make
        ref_shape = reference_shape(make, ref_n, tries=12)
        self.motion: Motion = motion_fn(ref_shape)
        self.size = float(np.linalg.norm(ref_shape.vertices, axis=1).max())
        self.ref_n = len(ref_shape)
        self.ref, _ = evaluate(ref_shape, self.motion)

    def error_at(self, n: int, repeats: int = 1) -> dict:
        shape = self.make(n)
        costs = []
        for _ in range(repeats):
            w, c = evaluate(shape, self.motion)
            costs.append(c)
        ef, em = errors(w, self.ref, self.size)
        return {
            "case": self.name,
            "requested": n,
            "triangles": len(shape),
            "midplane_lines_xyz": "".join("1" if m else "0" for m in midplanes(shape)),
            "force_error": ef,
            "moment_error": em,
            "us_per_sample": 1e6 * float(np.median(costs)),
        }


def no_pitch(motion: Motion) -> Motion:
    """The ellipsoid demo's descent without pitching (mjrft.demos.ellipsoid_pitch(amplitude=0))."""
    pos, rot, vel, ang = motion
    return pos, np.broadcast_to(np.eye(3), rot.shape).copy(), vel, np.zeros_like(ang)


# Cases of the fit. The first three rotate (the rig motions); the last two are the pure
# translations of the same shapes: the sphere_drop rig's fall and the ellipsoid demo without pitch.
ROTATING = ("sphere", "ellipsoid", "paraboloid")


def fitted_cases(ref_n: int, quick: bool) -> list[Case]:
    sphere_dt, ell_dt, root_dt = (0.03, 0.05, 0.5) if quick else (0.01, 0.01, 0.1)

    def sphere(n: int) -> ElementSet:
        return geometry.sphere(10 * MM, n_triangles=n)

    def ellipsoid(n: int) -> ElementSet:
        return geometry.ellipsoid(demos.ELLIPSOID_SEMI_AXES, n_triangles=n)

    return [
        Case("sphere", sphere, lambda s: generic_motion(s, np.eye(3), sphere_dt), ref_n),
        Case("ellipsoid", ellipsoid, lambda s: ellipsoid_rig_motion(ell_dt), ref_n),
        Case("paraboloid", root_shape, lambda s: root_rig_motion(root_dt), ref_n),
        Case(
            "sphere, straight down",
            sphere,
            lambda s: generic_motion(s, np.eye(3), sphere_dt, spin=0.0, lateral=0.0),
            ref_n,
        ),
        Case(
            "ellipsoid, no pitch",
            ellipsoid,
            lambda s: no_pitch(ellipsoid_rig_motion(ell_dt)),
            ref_n,
        ),
    ]


TILT = axis_angle((1.0, 0.0, 0.0), math.radians(17.0))


def held_out_cases(ref_n: int, quick: bool) -> list[Case]:
    dt = 0.03 if quick else 0.01

    def gen(s: ElementSet) -> Motion:
        return generic_motion(s, TILT, dt)

    def translate(s: ElementSet) -> Motion:  # no rotation, lattice aligned with the surface
        return generic_motion(s, np.eye(3), dt, spin=0.0)

    def straight_down(s: ElementSet) -> Motion:
        return generic_motion(s, np.eye(3), dt, spin=0.0, lateral=0.0)

    capsule = lambda n: geometry.capsule(6 * MM, 12 * MM, n_triangles=n)  # noqa: E731
    cylinder = lambda n: geometry.cylinder(8 * MM, 10 * MM, n_triangles=n)  # noqa: E731
    box = lambda n: geometry.box([12 * MM, 8 * MM, 5 * MM], n_triangles=n)  # noqa: E731
    ell = lambda n: geometry.ellipsoid([5 * MM, 10 * MM, 30 * MM], n_triangles=n)  # noqa: E731
    pancake = lambda n: geometry.ellipsoid([30 * MM, 20 * MM, 6 * MM], n_triangles=n)  # noqa: E731
    long_capsule = lambda n: geometry.capsule(3 * MM, 25 * MM, n_triangles=n)  # noqa: E731
    disc = lambda n: geometry.cylinder(15 * MM, 2 * MM, n_triangles=n)  # noqa: E731
    return [
        Case("capsule", capsule, gen, ref_n),
        Case("cylinder", cylinder, gen, ref_n),
        Case("box", box, gen, ref_n),
        Case("ellipsoid 5x10x30", ell, gen, ref_n),
        # Worst cases: pure translations with the mesh lattice aligned to the surface.
        Case("capsule upright, straight down", capsule, straight_down, ref_n),
        Case("capsule upright, down+lateral", capsule, translate, ref_n),
        Case("ellipsoid 5x10x30, straight down", ell, straight_down, ref_n),
        Case("cylinder upright, down+lateral", cylinder, translate, ref_n),
        Case("box aligned, down+lateral", box, translate, ref_n),
        Case("pancake ellipsoid 30x20x6", pancake, gen, ref_n),
        Case("long capsule", long_capsule, gen, ref_n),
        Case("pancake ellipsoid 30x20x6, down", pancake, straight_down, ref_n),
        # FRESH_HELD_OUT: blind to the choice of the rule's margin.
        Case(FRESH_HELD_OUT[0], disc, gen, ref_n),
        Case(FRESH_HELD_OUT[1], disc, translate, ref_n),
    ]


def fit(rows: list[dict], n_max: float) -> tuple[float, float]:
    """(C, p) of error = C n^-p, least squares in log-log over FIT_MIN <= n <= n_max."""
    sel = [r for r in rows if FIT_MIN <= r["triangles"] <= n_max and r["force_error"] > 0]
    x = np.log([r["triangles"] for r in sel])
    y = np.log([r["force_error"] for r in sel])
    slope, intercept = np.polyfit(x, y, 1)
    return float(math.exp(intercept)), float(-slope)


def rule_n(tol: float, c: float = RULE_C, p: float = RULE_P) -> int:
    """Triangle count for a relative force tolerance: max(floor, ceil((c / tol)^(1 / p)))."""
    return max(RULE_FLOOR, math.ceil((c / tol) ** (1.0 / p)))


def envelope(rows: list[dict], p: float, n_max: float) -> float:
    """MARGIN x the largest error * n^p over the measured points with FIT_MIN <= n <= n_max."""
    return MARGIN * max(
        r["force_error"] * r["triangles"] ** p for r in rows if FIT_MIN <= r["triangles"] <= n_max
    )


# --------------------------------------------------------------------------------------------
# MuJoCo: cost per step, error vs timestep
# --------------------------------------------------------------------------------------------


def clone(model: mujoco.MjModel, d: mujoco.MjData) -> mujoco.MjData:
    e = mujoco.MjData(model)
    e.qpos[:], e.qvel[:], e.act[:], e.ctrl[:] = d.qpos, d.qvel, d.act, d.ctrl
    e.time = d.time
    return e


def state_at(model: mujoco.MjModel, t: float) -> mujoco.MjData:
    """State at time t from keyframe 0, simulated with the model's own triangle counts."""
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, 0)
    with GranularField(model).installed():
        while d.time < t - 1e-12:
            mujoco.mj_step(model, d)
    return d


def time_steps(model, d0, fld, repeats: int, target_s: float = 0.1) -> tuple[float, float]:
    """Median seconds per mj_step from d0 (field installed if given), and the acting fraction."""
    n = 20
    times = []
    s0 = fld.stats if fld is not None else None
    for rep in range(repeats + 1):
        d = clone(model, d0)
        if fld is None:
            mujoco.mj_step(model, d)
            t0 = time.perf_counter()
            for _ in range(n):
                mujoco.mj_step(model, d)
            dt = time.perf_counter() - t0
        else:
            with fld.installed():
                mujoco.mj_step(model, d)  # registers this MjData (Python)
                t0 = time.perf_counter()
                for _ in range(n):
                    mujoco.mj_step(model, d)
                dt = time.perf_counter() - t0
        if rep == 0:  # calibration run: choose the step count for ~target_s per repeat
            n = max(20, min(5000, int(n * target_s / max(dt, 1e-6))))
            continue
        times.append(dt / n)
    acting = 0.0
    if fld is not None:
        s1 = fld.stats
        calls = max(1, s1["calls"] - s0["calls"])
        acting = (s1["acting"] - s0["acting"]) / calls / fld.n_elements
    return float(np.median(times)), acting


def cost_sweep(counts, repeats: int) -> list[dict]:
    rows = []
    for rig, t_state in (("sphere_drop", 0.3), ("ellipsoid_pitch", 10.0)):
        model = simulate.load_model(MODELS / f"{rig}.xml")
        d0 = state_at(model, t_state)
        plain, _ = time_steps(model, d0, None, repeats)
        for n in counts:
            fld = GranularField(model, n_triangles=n)
            us, acting = time_steps(model, d0, fld, repeats)
            rows.append(
                {
                    "rig": rig,
                    "state_t_s": t_state,
                    "requested": n,
                    "triangles": fld.n_elements,
                    "us_per_step": 1e6 * us,
                    "plain_us_per_step": 1e6 * plain,
                    "acting_fraction": acting,
                }
            )
            r = rows[-1]
            print(
                f"  {rig:16s} {r['triangles']:6d} tri: {r['us_per_step']:8.1f} us/step "
                f"(plain {r['plain_us_per_step']:.1f}, acting {acting:.2f})",
                flush=True,
            )
    return rows


def simulate_series(rig: str, dt: float, duration: float, n_tri: int, grid: float):
    """(times, RFT force (T,3), CoM position (T,3)) on multiples of `grid`, or an error string."""
    model = simulate.load_model(MODELS / f"{rig}.xml")
    simulate.configure(model, dt, "euler")
    fld = GranularField(model, n_triangles=n_tri)
    body = int(fld.body_ids[0])
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, 0)
    every = max(1, round(grid / dt))
    n_steps = round(duration / dt)
    ts, fs, xs = [], [], []
    try:
        with fld.installed():
            for i in range(n_steps):
                t_prev = d.time
                mujoco.mj_step(model, d)  # Euler: derived quantities stay at the pre-step state
                if i % every == 0:
                    ts.append(t_prev)
                    fs.append(fld.last_wrench[body, :3].copy())
                    xs.append(d.xipos[body].copy())
    except Exception as exc:  # a failure is a result here
        return f"{type(exc).__name__}: {str(exc).splitlines()[0][:80]} (t = {d.time:.4f} s)"
    f, x = np.array(fs), np.array(xs)
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(x))):
        return "non-finite state"
    return np.array(ts), f, x


def dt_study(dts, dt_ref: float, n_tri: int, quick: bool) -> list[dict]:
    grid = max(dts)
    rows = []
    for rig, duration in (("ellipsoid_pitch", 2.0 if quick else 4.0), ("sphere_drop", 1.0)):
        ref = simulate_series(rig, dt_ref, duration, n_tri, grid)
        if isinstance(ref, str):
            raise RuntimeError(f"{rig}: reference run failed: {ref}")
        t_ref, f_ref, x_ref = ref
        fmax = np.linalg.norm(f_ref, axis=1).max()
        depth_ref = -x_ref[-1, 2]
        for dt in dts:
            res = simulate_series(rig, dt, duration, n_tri, grid)
            row = {"rig": rig, "dt_ms": 1e3 * dt, "triangles": n_tri, "status": "ok"}
            if isinstance(res, str):
                row.update(status=res, force_error=math.nan, position_error_um=math.nan)
            else:
                t, f, x = res
                fi = np.stack([np.interp(t_ref, t, f[:, k]) for k in range(3)], axis=1)
                xi = np.stack([np.interp(t_ref, t, x[:, k]) for k in range(3)], axis=1)
                row["force_error"] = math.sqrt(np.mean(np.sum((fi - f_ref) ** 2, 1))) / fmax
                row["position_error_um"] = 1e6 * math.sqrt(np.mean(np.sum((xi - x_ref) ** 2, 1)))
                row["final_depth_mm"] = -1e3 * x[-1, 2]
            row["ref_final_depth_mm"] = 1e3 * depth_ref
            rows.append(row)
            print(
                f"  {rig:16s} dt {row['dt_ms']:5.3f} ms: force error "
                f"{100 * row['force_error']:7.3f} %  CoM position error "
                f"{row['position_error_um']:9.3f} um  final CoM depth "
                f"{row.get('final_depth_mm', math.nan):.3f} mm (ref "
                f"{row['ref_final_depth_mm']:.3f})  [{row['status']}]",
                flush=True,
            )
    return rows


# --------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------


def write_csv(path: Path, rows: list[dict]) -> None:
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def plot(path: Path, acc, fits, rule_a, cost, dtr) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(18, 5.6))
    styles = {
        "sphere": ("C0", "o-"),
        "ellipsoid": ("C1", "o-"),
        "paraboloid": ("C2", "o-"),
        "sphere, straight down": ("C0", "v--"),
        "ellipsoid, no pitch": ("C1", "v--"),
    }
    ax = axes[0]
    for name, (col, st) in styles.items():
        rr = [r for r in acc if r["case"] == name]
        c, p = fits[name]
        ax.loglog(
            [r["triangles"] for r in rr], [100 * r["force_error"] for r in rr], st, color=col,
            ms=4, label=f"{name}: fit {c:.2g} n^-{p:.2f}",
        )  # fmt: skip
    nn = np.logspace(2, 5.4, 50)
    ax.loglog(
        nn, 100 * RULE_C * nn**-RULE_P, "k-", lw=2,
        label=f"proposed rule: {RULE_C:g} n^-{RULE_P:g} (floor {RULE_FLOOR})",
    )  # fmt: skip
    ax.loglog(
        nn, 100 * rule_a[0] * nn ** -rule_a[1], "k:", label=f"rule A (rig motions only): "
        f"{rule_a[0]:.2g} n^-{rule_a[1]:.2f}",
    )  # fmt: skip
    ax.set_xlabel("triangles n")
    ax.set_ylabel("force error vs ~400k-triangle reference [%]")
    ax.set_title("Force error vs triangles (solid: rig motions; dashed: pure translations)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7.5)

    ax = axes[1]
    for name, rig, label in (
        ("sphere", "sphere_drop", True),
        ("sphere, straight down", "sphere_drop", False),
        ("ellipsoid", "ellipsoid_pitch", True),
    ):
        col, st = styles[name]
        err = {r["requested"]: r for r in acc if r["case"] == name}
        pts = [(r["us_per_step"], err.get(r["requested"])) for r in cost if r["rig"] == rig]
        pts = [(x, e) for x, e in pts if e is not None]
        ax.loglog(
            [x for x, _ in pts], [100 * e["force_error"] for _, e in pts], st, color=col, ms=4,
            label=f"{name}: MuJoCo step of {rig}.xml",
        )  # fmt: skip
        for x, e in pts if label else []:
            ax.annotate(
                str(e["triangles"]), (x, 100 * e["force_error"]), fontsize=7,
                xytext=(3, 3), textcoords="offset points", color=col,
            )  # fmt: skip
    rr = [r for r in acc if r["case"] == "paraboloid" and r["triangles"] <= 60_000]
    ax.loglog(
        [r["us_per_sample"] for r in rr], [100 * r["force_error"] for r in rr], "s:",
        color="C2", ms=4, label="paraboloid: RFT evaluation per sample (prescribed)",
    )  # fmt: skip
    for r in rr:
        ax.annotate(
            str(r["triangles"]), (r["us_per_sample"], 100 * r["force_error"]), fontsize=7,
            xytext=(3, -9), textcoords="offset points", color="C2",
        )  # fmt: skip
    ax.set_xlabel("cost [µs per step / per sample]")
    ax.set_ylabel("force error [%]")
    ax.set_title("Pareto: force error vs cost (labels: triangles)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)

    ax = axes[2]
    for rig, key, lab, mk in (
        ("ellipsoid_pitch", "force_error", "ellipsoid rig: RFT force error [%]", "o-"),
        ("sphere_drop", "position_error_um", "sphere drop: CoM position error [µm]", "s-"),
    ):
        rr = [r for r in dtr if r["rig"] == rig and r["status"] == "ok"]
        scale = 100.0 if key == "force_error" else 1.0
        ax.loglog([r["dt_ms"] for r in rr], [scale * r[key] for r in rr], mk, label=lab)
        for r in dtr:
            if r["rig"] == rig and r["status"] != "ok":
                ax.axvline(r["dt_ms"], color="r", ls=":", label=f"{rig} dt={r['dt_ms']:g}: failed")
    ax.set_xlabel("timestep dt [ms] (Euler; reference dt = 0.125 ms)")
    ax.set_ylabel("error (units in legend)")
    ax.set_title("Trajectory error vs timestep (2000 triangles)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller reference, fewer counts (~1 min)")
    args = ap.parse_args()
    quick = args.quick
    OUT.mkdir(exist_ok=True)
    tag = "pareto_quick" if quick else "pareto"
    ref_n = 100_000 if quick else REF_TRIANGLES
    counts = tuple(n for n in COUNTS if n <= ref_n // 5) if quick else COUNTS
    start = time.perf_counter()

    # 0. The fast evaluator is the library's trajectory evaluation.
    shape = geometry.ellipsoid(demos.ELLIPSOID_SEMI_AXES, n_triangles=1000)
    mot = ellipsoid_rig_motion(0.1)
    a, _ = evaluate(shape, mot)
    b = trajectory_wrenches(shape, *mot, MATERIAL)
    dev = max(
        np.abs(a[:, :3] - b.force).max() / np.abs(b.force).max(),
        np.abs(a[:, 3:] - b.moment).max() / np.abs(b.moment).max(),
    )
    print(f"kernel evaluator vs mjrft.body.trajectory_wrenches: max rel. difference {dev:.1e}")
    assert dev < 1e-9, dev

    # 1. Force error vs triangle count on the three rig shapes.
    print(f"\n1. Error vs triangles (reference ~{ref_n} triangles; errors in %)")
    acc = []
    fits = {}
    for case in fitted_cases(ref_n, quick):
        print(f"  {case.name} ({case.ref_n} reference triangles, {len(case.ref)} samples)")
        rows = [case.error_at(n, repeats=3 if n <= 20_000 else 1) for n in counts]
        for r in rows:
            print(
                f"    {r['triangles']:7d}  force {100 * r['force_error']:7.3f}  moment "
                f"{100 * r['moment_error']:7.3f}  {r['us_per_sample']:9.1f} us/sample",
                flush=True,
            )
        fits[case.name] = fit(rows, ref_n / 8)
        acc += rows

    print("\n2. Fits error = C n^-p (force, 400 <= n <= reference/8)")
    for name, (c, p) in fits.items():
        print(f"  {name:24s} C = {c:.3g}  p = {p:.3f}")
    rot_rows = [r for r in acc if r["case"] in ROTATING]
    p_rot = min(fits[k][1] for k in ROTATING)
    rule_a = (envelope(rot_rows, p_rot, ref_n / 8), p_rot)
    env_b = envelope(acc, RULE_P, ref_n / 8)
    env_b4 = envelope(acc, RULE_P, ref_n / 4)  # up to the largest n validated below
    print(
        f"  rule A (rig motions only): p = min p = {p_rot:.3f}, C = {rule_a[0]:.3g} "
        f"(x{MARGIN} over every measured point, {FIT_MIN} <= n <= reference/8)"
    )
    print(
        f"  rule B (all five cases): p = {RULE_P:g}, envelope C = {env_b:.3g} "
        f"(n <= reference/8), {env_b4:.3g} (n <= reference/4)"
    )
    margin = MARGIN * RULE_C / max(env_b, env_b4)  # over the envelope of the measured points
    print(
        f"  proposed: n(tol) = max({RULE_FLOOR}, ceil(({RULE_C:g} / tol)^(1/{RULE_P:g}))), "
        f"{margin:.2f}x the envelope of the five cases"
        + ("" if margin >= 1 else "  [WARNING: below the measured errors]")
    )
    for tol in TOLERANCES:
        print(
            f"    tol {100 * tol:5.1f} %: rule A n = {rule_n(tol, *rule_a):6d}, "
            f"proposed n = {rule_n(tol):6d}"
        )

    print("\n   validation on shapes not used in the fit: force error % at the rule's n")
    val = []
    held = held_out_cases(ref_n, quick)
    for case in held:
        for rule, (c, p) in (("A", rule_a), ("proposed", (RULE_C, RULE_P))):
            line = f"  {case.name:34s} {rule:8s}"
            for tol in TOLERANCES:
                n = rule_n(tol, c, p)
                if n > ref_n // 4:
                    line += f"  {100 * tol:4.1f}%: (n = {n} too close to the reference)"
                    continue
                r = case.error_at(n)
                r.update(rule=rule, tol=tol, holds=r["force_error"] <= tol)
                val.append(r)
                line += (
                    f"  {100 * tol:4.1f}%: {r['triangles']:6d} -> {100 * r['force_error']:6.3f}"
                    + ("" if r["holds"] else " FAIL")
                )
            print(line, flush=True)
    if not quick:
        print("  held-out convergence (force error % at n triangles; not used in the fit):")
        for case in held:
            rows = [case.error_at(n) for n in counts if n <= 50_000]
            c, p = fit(rows, ref_n / 8)
            acc += rows
            print(
                f"    {case.name:34s} C = {c:.3g} p = {p:.3f}: "
                + " ".join(f"{r['triangles']}:{100 * r['force_error']:.3f}" for r in rows),
                flush=True,
            )

    # 2c. Lattice parity: straight-down motions with and without a lattice line on the equator.
    print("\n   parity: straight-down force error % with / without mesh vertices on z = 0")
    parity = []
    for case in fitted_cases(ref_n, quick)[3:] if not quick else []:
        for target in (1000, 4000, 16_000):
            rows = [case.error_at(round(target * 1.03**j)) for j in range(8)]
            rows = list({r["triangles"]: r for r in rows}.values())
            parity += rows
            on = [r["force_error"] for r in rows if r["midplane_lines_xyz"][2] == "1"]
            off = [r["force_error"] for r in rows if r["midplane_lines_xyz"][2] == "0"]
            print(
                f"    {case.name:24s} ~{target:6d} triangles: with "
                + (f"{100 * np.mean(on):.3f} ({len(on)} meshes)" if on else "-")
                + "  without "
                + (f"{100 * np.mean(off):.3f} ({len(off)} meshes)" if off else "-"),
                flush=True,
            )

    # 3. Cost per step.
    print("\n3. Cost per mj_step vs triangles (dt = 1 ms, Euler, field installed)")
    cost_counts = (100, 400, 2000, 10_000) if quick else COUNTS[:9]
    cost = cost_sweep(cost_counts, repeats=3 if quick else 7)
    for rig in ("sphere_drop", "ellipsoid_pitch"):
        rr = [r for r in cost if r["rig"] == rig]
        b, a = np.polyfit([r["triangles"] for r in rr], [r["us_per_step"] for r in rr], 1)
        print(f"  {rig}: us/step ~ {a:.1f} + {1e3 * b:.1f} ns x triangles (least squares)")

    # 4. Error vs timestep.
    print("\n4. Trajectory error vs timestep (Euler, 2000 triangles, reference dt = 0.125 ms)")
    dtr = dt_study((0.00025, 0.0005, 0.001, 0.002), 0.000125, 2000, quick)

    write_csv(OUT / f"{tag}_accuracy.csv", acc)
    write_csv(OUT / f"{tag}_validation.csv", val)
    if parity:
        write_csv(OUT / f"{tag}_parity.csv", parity)
    write_csv(
        OUT / f"{tag}_fits.csv",
        [{"case": k, "C": c, "p": p} for k, (c, p) in fits.items()]
        + [
            {"case": "rule A (rig motions, envelope)", "C": rule_a[0], "p": rule_a[1]},
            {"case": "rule B envelope", "C": env_b, "p": RULE_P},
            {"case": "proposed", "C": RULE_C, "p": RULE_P, "floor": RULE_FLOOR},
        ],
    )
    write_csv(OUT / f"{tag}_cost.csv", cost)
    write_csv(OUT / f"{tag}_dt.csv", dtr)
    png = OUT / f"{tag}.png"
    plot(png, acc, fits, rule_a, cost, dtr)
    print(f"\nwrote {OUT}/{tag}_*.csv and {png.name} in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
