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
   time of one evaluation per trajectory sample (the engine's C++ kernel, the plugin's own hot
   path, through ``mjrft.core.engine.trajectory``; identical to
   ``mjrft.body.trajectory_wrenches``, checked here).
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
from mjrft.core import engine, quadrature
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

# The accuracy rule, per primitive type k: n(tol) = max(floor, ceil((C_k / tol)^(1 / p_k))),
# p_k the smallest order fitted on the type's cases (within [P_MIN, P_MAX]) and C_k MARGIN times
# the envelope of the type's measured errors e n^p_k over RULE_MIN <= n <= reference/8.
# MARGIN covers geometry's +-25 % rounding of n_triangles (1.25^p ~ 1.25) and shapes and
# motions between the fitted ones; the validation on HELD_OUT, not the margin, is what the
# rule must pass. mjrft.geometry.TOLERANCE_RULES holds the production rule this script checks.
MARGIN = 2.0
RULE_MIN = 200  # below ~200 triangles errors are not asymptotic (geometry.TOLERANCE_FLOOR)
P_MIN, P_MAX = 0.8, 1.0
#: The rule before mjrft.core.quadrature (one envelope for every type): (C, p, floor).
OLD_RULE = (5.2, 0.8, 200)

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


def one_point(shape: ElementSet) -> tuple[ElementSet, np.ndarray, np.ndarray]:
    """The shape as flat facets evaluated by the one-point rule alone (facet normals and areas,
    reach 0: nothing clipped): the quadrature of mjrft before mjrft.core.quadrature."""
    facets = ElementSet.from_triangles(shape.vertices, shape.faces)
    n = len(facets)
    return facets, np.zeros(n), np.zeros((n, quadrature.PATCH_SIZE))


def evaluate(shape: ElementSet, motion: Motion, *, old: bool = False) -> tuple[np.ndarray, float]:
    """(T, 6) force and moment about the body origin along the motion; seconds per sample.
    old: the one-point rule on flat facets (``one_point``) instead of mjrft's quadrature."""
    pos, rot, vel, ang = (np.ascontiguousarray(a, dtype=np.float64) for a in motion)
    shape, reach, patch = one_point(shape) if old else (shape, *shape.quadrature)
    cent = np.ascontiguousarray(shape.centroids)
    norm = np.ascontiguousarray(shape.normals)
    area = np.ascontiguousarray(shape.areas)
    co, ay, zeta = MATERIAL.kernel_coefficients, MATERIAL.alpha_y0, MATERIAL.zeta
    # One call for the whole trajectory (the arguments are checked once, outside the loop over
    # samples): each sample is BodyWrench about the body origin, the plugin's own pass.
    t0 = time.perf_counter()
    out = engine.trajectory(cent, norm, area, reach, patch, co, ay, zeta, 0.0, rot, pos, vel,
                            ang, pos)  # fmt: skip
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

    def __init__(
        self, name: str, make: Callable[[int], ElementSet], motion_fn, ref_n: int, kind: str
    ):
        self.name = name
        self.kind = kind  # the primitive type whose rule it fits or checks
        self.make = make
        ref_shape = reference_shape(make, ref_n, tries=12)
        self.motion: Motion = motion_fn(ref_shape)
        self.size = float(np.linalg.norm(ref_shape.vertices, axis=1).max())
        self.ref_n = len(ref_shape)
        self.ref, _ = evaluate(ref_shape, self.motion)

    def error_at(self, n: int, repeats: int = 1, old: bool = False) -> dict:
        shape = self.make(n)
        costs = []
        for _ in range(repeats):
            w, c = evaluate(shape, self.motion, old=old)
            costs.append(c)
        ef, em = errors(w, self.ref, self.size)
        return {
            "case": self.name,
            "kind": self.kind,
            "quadrature": "one-point" if old else "clipped",
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


# Cases of the fit, per primitive type: the rig motions (sphere, ellipsoid, the paraboloid,
# which is not a MuJoCo primitive and is only reported), pure translations of the same shapes
# (the sphere_drop rig's fall, the ellipsoid demo without pitch), and for the other types one
# generic and one aligned motion.
TILT = axis_angle((1.0, 0.0, 0.0), math.radians(17.0))
OBLIQUE = (1.0, 2.0, 3.0)  # a spin axis off every symmetry axis of the shapes


def _shapes() -> dict[str, Callable[[int], ElementSet]]:
    def make(kind: str, size) -> Callable[[int], ElementSet]:
        def shape(n: int) -> ElementSet:
            return geometry.primitive(kind, size, n_triangles=n)

        shape.size = np.asarray(size, dtype=float)  # MuJoCo size [m], for the aspect rule
        return shape

    return {
        "sphere": make("sphere", [10 * MM]),
        "ellipsoid": make("ellipsoid", demos.ELLIPSOID_SEMI_AXES),
        "paraboloid": root_shape,
        "capsule": make("capsule", [6 * MM, 12 * MM]),
        "cylinder": make("cylinder", [8 * MM, 10 * MM]),
        "box": make("box", [12 * MM, 8 * MM, 5 * MM]),
        "slender ellipsoid": make("ellipsoid", [5 * MM, 10 * MM, 30 * MM]),
        "pancake ellipsoid": make("ellipsoid", [30 * MM, 20 * MM, 6 * MM]),
        "oblate ellipsoid": make("ellipsoid", [8 * MM, 12 * MM, 20 * MM]),
        "long capsule": make("capsule", [3 * MM, 25 * MM]),
        "disc cylinder": make("cylinder", [15 * MM, 2 * MM]),
        "short cylinder": make("cylinder", [10 * MM, 5 * MM]),
        "flat box": make("box", [15 * MM, 10 * MM, 4 * MM]),
        "plate": make("box", [20 * MM, 20 * MM, 2 * MM]),
        # blind to the aspect-ratio rule (geometry.TOLERANCE_ASPECT), added after it was set
        "prolate ellipsoid": make("ellipsoid", [6 * MM, 6 * MM, 24 * MM]),
        "slim capsule": make("capsule", [4 * MM, 20 * MM]),
    }


def _motions(dt: float) -> dict[str, Callable[[ElementSet], Motion]]:
    return {
        "generic": lambda s: generic_motion(s, TILT, dt),
        "generic, level start": lambda s: generic_motion(s, np.eye(3), dt),
        "straight down": lambda s: generic_motion(s, np.eye(3), dt, spin=0.0, lateral=0.0),
        "down+lateral": lambda s: generic_motion(s, np.eye(3), dt, spin=0.0),
        # spin 3 rad/s about an oblique axis while sinking and drifting
        "tumbling": lambda s: generic_motion(s, TILT, dt, spin=3.0, axis=OBLIQUE),
        # skimming the surface, tilted: 2 mm/s down, 2 cm/s sideways, yawing at 0.5 rad/s
        "grazing": lambda s: generic_motion(
            s, TILT, dt, descent=0.002, lateral=0.02, spin=0.5, axis=(0.0, 0.0, 1.0)
        ),
    }


#: (case name, shape, motion, kind). FITTED set the rules: the rig motions and, for each
#: type's standard shape, a generic, an aligned, a tumbling and a grazing motion. HELD_OUT only
#: check them: other shapes of every type (slender, flat, disc-like, long) under those motions.
FITTED = (
    ("sphere", "sphere", "generic, level start", "sphere"),
    ("sphere, straight down", "sphere", "straight down", "sphere"),
    ("sphere tumbling", "sphere", "tumbling", "sphere"),
    ("sphere grazing", "sphere", "grazing", "sphere"),
    ("ellipsoid", "ellipsoid", "rig", "ellipsoid"),
    ("ellipsoid, no pitch", "ellipsoid", "rig, no pitch", "ellipsoid"),
    ("ellipsoid tumbling", "ellipsoid", "tumbling", "ellipsoid"),
    ("ellipsoid grazing", "ellipsoid", "grazing", "ellipsoid"),
    ("paraboloid", "paraboloid", "rig", "paraboloid"),
    ("capsule", "capsule", "generic", "capsule"),
    ("capsule upright, straight down", "capsule", "straight down", "capsule"),
    ("capsule tumbling", "capsule", "tumbling", "capsule"),
    ("capsule grazing", "capsule", "grazing", "capsule"),
    ("cylinder", "cylinder", "generic", "cylinder"),
    ("cylinder upright, down+lateral", "cylinder", "down+lateral", "cylinder"),
    ("cylinder tumbling", "cylinder", "tumbling", "cylinder"),
    ("cylinder grazing", "cylinder", "grazing", "cylinder"),
    ("box", "box", "generic", "box"),
    ("box aligned, down+lateral", "box", "down+lateral", "box"),
    ("box tumbling", "box", "tumbling", "box"),
    ("box grazing", "box", "grazing", "box"),
)
HELD_OUT = (
    ("ellipsoid 5x10x30", "slender ellipsoid", "generic", "ellipsoid"),
    ("ellipsoid 5x10x30, straight down", "slender ellipsoid", "straight down", "ellipsoid"),
    ("ellipsoid 5x10x30 tumbling", "slender ellipsoid", "tumbling", "ellipsoid"),
    ("ellipsoid 5x10x30 grazing", "slender ellipsoid", "grazing", "ellipsoid"),
    ("pancake ellipsoid 30x20x6", "pancake ellipsoid", "generic", "ellipsoid"),
    ("pancake ellipsoid 30x20x6, down", "pancake ellipsoid", "straight down", "ellipsoid"),
    ("pancake ellipsoid tumbling", "pancake ellipsoid", "tumbling", "ellipsoid"),
    ("pancake ellipsoid grazing", "pancake ellipsoid", "grazing", "ellipsoid"),
    ("ellipsoid 8x12x20 tumbling", "oblate ellipsoid", "tumbling", "ellipsoid"),
    ("ellipsoid 8x12x20 grazing", "oblate ellipsoid", "grazing", "ellipsoid"),
    ("capsule upright, down+lateral", "capsule", "down+lateral", "capsule"),
    ("long capsule", "long capsule", "generic", "capsule"),
    ("long capsule tumbling", "long capsule", "tumbling", "capsule"),
    ("long capsule grazing", "long capsule", "grazing", "capsule"),
    ("disc cylinder", "disc cylinder", "generic", "cylinder"),
    ("disc cylinder, down+lateral", "disc cylinder", "down+lateral", "cylinder"),
    ("disc cylinder tumbling", "disc cylinder", "tumbling", "cylinder"),
    ("disc cylinder grazing", "disc cylinder", "grazing", "cylinder"),
    ("short cylinder tumbling", "short cylinder", "tumbling", "cylinder"),
    ("short cylinder grazing", "short cylinder", "grazing", "cylinder"),
    ("flat box tumbling", "flat box", "tumbling", "box"),
    ("flat box grazing", "flat box", "grazing", "box"),
    ("plate", "plate", "generic", "box"),
    ("plate grazing", "plate", "grazing", "box"),
    ("ellipsoid 6x6x24 tumbling", "prolate ellipsoid", "tumbling", "ellipsoid"),
    ("ellipsoid 6x6x24 grazing", "prolate ellipsoid", "grazing", "ellipsoid"),
    ("capsule 4x20 tumbling", "slim capsule", "tumbling", "capsule"),
    ("capsule 4x20 grazing", "slim capsule", "grazing", "capsule"),
)


def cases(table, ref_n: int, quick: bool) -> list[Case]:
    """The Cases of FITTED or HELD_OUT."""
    dt = 0.03 if quick else 0.01
    shapes, motions = _shapes(), _motions(dt)
    ell_dt, root_dt = (0.05, 0.5) if quick else (0.01, 0.1)
    motions["rig, no pitch"] = lambda s: no_pitch(ellipsoid_rig_motion(ell_dt))
    rig = {"ellipsoid": lambda s: ellipsoid_rig_motion(ell_dt),
           "paraboloid": lambda s: root_rig_motion(root_dt)}  # fmt: skip
    out = []
    for name, shape, motion, kind in table:
        fn = rig[shape] if motion == "rig" else motions[motion]
        out.append(Case(name, shapes[shape], fn, ref_n, kind))
    return out


def fitted_cases(ref_n: int, quick: bool) -> list[Case]:
    return cases(FITTED, ref_n, quick)


def held_out_cases(ref_n: int, quick: bool) -> list[Case]:
    return cases(HELD_OUT, ref_n, quick)


def fit(rows: list[dict], n_max: float) -> tuple[float, float]:
    """(C, p) of error = C n^-p, least squares in log-log over FIT_MIN <= n <= n_max."""
    sel = [r for r in rows if FIT_MIN <= r["triangles"] <= n_max and r["force_error"] > 0]
    x = np.log([r["triangles"] for r in sel])
    y = np.log([r["force_error"] for r in sel])
    slope, intercept = np.polyfit(x, y, 1)
    return float(math.exp(intercept)), float(-slope)


def rule_n(tol: float, c: float, p: float, floor: int) -> int:
    """Triangle count for a relative force tolerance: max(floor, ceil((c / tol)^(1 / p)))."""
    return max(floor, math.ceil((c / tol) ** (1.0 / p)))


def kind_rule(rows: list[dict], fits: dict, kind: str, n_max: float) -> tuple[float, float]:
    """(C, p) of the proposed rule for one primitive type from its fitted cases' rows."""
    names = [name for name, _, _, k in FITTED if k == kind]
    p = min(P_MAX, max(P_MIN, min(fits[name][1] for name in names)))
    c = MARGIN * max(
        r["force_error"] * r["triangles"] ** p
        for r in rows
        if r["case"] in names and RULE_MIN <= r["triangles"] <= n_max
    )
    return c, p


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


def plot(path: Path, acc, fits, cost, dtr) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(18, 5.6))
    colours = {"sphere": "C0", "ellipsoid": "C1", "paraboloid": "C2"}
    ax = axes[0]
    for name, col in colours.items():
        for quad, st in (("clipped", "o-"), ("one-point", "v--")):
            rr = [r for r in acc if r["case"] == name and r["quadrature"] == quad]
            c, p = fits[name, quad]
            ax.loglog(
                [r["triangles"] for r in rr], [100 * r["force_error"] for r in rr], st,
                color=col, ms=4, label=f"{name}, {quad}: {c:.2g} n^-{p:.2f}",
            )  # fmt: skip
    nn = np.logspace(2, 5.4, 50)
    for kind, ls in (("sphere", "-"), ("ellipsoid", "-.")):
        c, p = geometry.TOLERANCE_RULES[kind]
        ax.loglog(nn, 100 * c * nn**-p, "k" + ls, lw=1.5, label=f"rule, {kind}: {c:g} n^-{p:g}")
    c, p, _ = OLD_RULE
    ax.loglog(nn, 100 * c * nn**-p, "k:", label=f"rule before (every type): {c:g} n^-{p:g}")
    ax.set_xlabel("triangles n")
    ax.set_ylabel("force error vs ~400k-triangle reference [%]")
    ax.set_title("Force error vs triangles, rig motions (solid: clipped; dashed: one-point)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)

    ax = axes[1]
    for name, col in colours.items():
        for quad, st in (("clipped", "o-"), ("one-point", "v--")):
            rr = [
                r for r in acc
                if r["case"] == name and r["quadrature"] == quad and r["triangles"] <= 60_000
            ]  # fmt: skip
            ax.loglog(
                [r["us_per_sample"] for r in rr], [100 * r["force_error"] for r in rr], st,
                color=col, ms=4, label=f"{name}, {quad}",
            )  # fmt: skip
            for r in rr if quad == "clipped" else []:
                ax.annotate(
                    str(r["triangles"]), (r["us_per_sample"], 100 * r["force_error"]),
                    fontsize=6, xytext=(3, 3), textcoords="offset points", color=col,
                )  # fmt: skip
    ax.set_xlabel("cost of one RFT evaluation of the body [µs] (the engine's kernel)")
    ax.set_ylabel("force error [%]")
    ax.set_title("Pareto: force error vs cost (labels: triangles)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)

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

    # 1. Force error vs triangle count, both quadratures.
    print(f"\n1. Error vs triangles (reference ~{ref_n} triangles; errors in %)")
    acc, fits = [], {}
    for case in fitted_cases(ref_n, quick):
        print(f"  {case.name} ({case.ref_n} reference triangles, {len(case.ref)} samples)")
        for old in (False, True):
            rows = [case.error_at(n, repeats=3 if n <= 20_000 else 1, old=old) for n in counts]
            fits[case.name, rows[0]["quadrature"]] = fit(rows, ref_n / 8)
            acc += rows
        line = "    n: one-point -> clipped force error %  "
        new = [r for r in acc if r["case"] == case.name and r["quadrature"] == "clipped"]
        old_rows = [r for r in acc if r["case"] == case.name and r["quadrature"] == "one-point"]
        print(line + "  ".join(
            f"{a['triangles']}: {100 * b['force_error']:.3f} -> {100 * a['force_error']:.3f}"
            for a, b in zip(new, old_rows, strict=True)
        ), flush=True)  # fmt: skip

    print("\n2. Fits error = C n^-p (force, 400 <= n <= reference/8): one-point, clipped")
    for name, _, _, _ in FITTED:
        (c0, p0), (c1, p1) = fits[name, "one-point"], fits[name, "clipped"]
        print(f"  {name:32s} C = {c0:.3g} p = {p0:.3f};  C = {c1:.3g} p = {p1:.3f}")
    fitted_rows = [r for r in acc if r["quadrature"] == "clipped"]
    clipped_fits = {name: fits[name, "clipped"] for name, _, _, _ in FITTED}
    proposed = {
        k: kind_rule(fitted_rows, clipped_fits, k, ref_n / 8) for k in geometry.PRIMITIVE_KINDS
    }
    print(f"  proposed per type (x{MARGIN} over the envelope, n >= {RULE_MIN}) and production:")
    for k in geometry.PRIMITIVE_KINDS:
        c, p = proposed[k]
        pc, pp = geometry.TOLERANCE_RULES[k]
        counts_k = [geometry.triangles_for_tolerance(t, k) for t in TOLERANCES]  # fitted shapes
        print(
            f"    {k:10s} proposed C = {c:.3g} p = {p:.2f}; production C = {pc:g} p = {pp:g}:"
            f" n = {counts_k} at {[f'{100 * t:g} %' for t in TOLERANCES]}"
        )
    print(f"    before: n = {[rule_n(t, *OLD_RULE) for t in TOLERANCES]} for every type")

    print("\n   validation on cases not used in the fit: force error % at the rule's n (and n/2)")
    val = []
    held = held_out_cases(ref_n, quick)
    for case in held:
        line = f"  {case.name:34s}"
        for tol in TOLERANCES:
            n = geometry.triangles_for_tolerance(tol, case.kind, getattr(case.make, "size", None))
            if n > ref_n // 4:
                line += f"  {100 * tol:4.1f}%: (n = {n} too close to the reference)"
                continue
            r, h = case.error_at(n), case.error_at(max(geometry.MIN_TRIANGLES, n // 2))
            r.update(tol=tol, holds=r["force_error"] <= tol, half_error=h["force_error"],
                     half_triangles=h["triangles"])  # fmt: skip
            val.append(r)
            line += (
                f"  {100 * tol:4.1f}%: {r['triangles']:6d} -> {100 * r['force_error']:6.3f}"
                f" ({100 * h['force_error']:.3f})" + ("" if r["holds"] else " FAIL")
            )
        print(line, flush=True)
    worst = {t: max(r["force_error"] / t for r in val if r["tol"] == t) for t in TOLERANCES}
    print("  worst held-out error / tolerance: " + ", ".join(
        f"{100 * t:g} %: {w:.2f}" for t, w in worst.items()
    ))  # fmt: skip
    if not quick:
        print("  held-out convergence (force error % at n triangles; not used in the fit):")
        for case in held:
            for old in (False, True):
                rows = [case.error_at(n, old=old) for n in counts if n <= 50_000]
                c, p = fit(rows, ref_n / 8)
                acc += rows
                print(
                    f"    {case.name:34s} {rows[0]['quadrature']:9s} C = {c:.3g} p = {p:.3f}: "
                    + " ".join(f"{r['triangles']}:{100 * r['force_error']:.3f}" for r in rows),
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
    write_csv(
        OUT / f"{tag}_fits.csv",
        [{"case": k, "quadrature": q, "C": c, "p": p} for (k, q), (c, p) in fits.items()]
        + [{"case": f"proposed rule, {k}", "C": c, "p": p} for k, (c, p) in proposed.items()]
        + [{"case": f"production rule, {k}", "C": c, "p": p}
           for k, (c, p) in geometry.TOLERANCE_RULES.items()],
    )  # fmt: skip
    write_csv(OUT / f"{tag}_cost.csv", cost)
    write_csv(OUT / f"{tag}_dt.csv", dtr)
    png = OUT / f"{tag}.png"
    plot(png, acc, fits, cost, dtr)
    print(f"\nwrote {OUT}/{tag}_*.csv and {png.name} in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
