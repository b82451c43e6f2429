"""Generate the C-leg hexapod: ``models/meshes/c_leg.obj`` and ``models/hexapod_sand.xml``.

Run from anywhere: ``python models/make_hexapod.py``. Every number of the robot is a constant
below; the MJCF (with its documentation header) and the leg mesh are written from them, so edit
the constants, rerun, and both stay consistent. Units SI (m, kg, s, rad).

The leg is a C-shaped half-ring (a 180 deg arc of a circle) in its body frame, the hinge (hip)
at the origin, turning about +y:

* centre line ``c(s) = (-R sin s, 0, -R (1 - cos s))``, s in [0, pi], R = LEG_REACH / 2, so the
  hip is at s = 0 and the tip at s = pi, LEG_REACH straight below the hip at leg angle 0;
* the arc bulges towards -x at angle 0, so a leg swinging down from the front (angle -pi/2 ->
  0, i.e. turning positively about +y) meets the medium with its convex side first and then
  rolls onto its tip: the RHex "c-leg" orientation;
* rectangular cross-section LEG_THICKNESS (radial) x LEG_WIDTH (along y), closed mesh with
  outward (counter-clockwise) faces.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

# --- the robot (see the SOURCES block written into the MJCF) ---------------------------------
LEG_REACH = 0.04  # m, hip to tip (radius of the circle the tip sweeps) = 2 R
LEG_WIDTH = 0.015  # m, along the hip axis (y)
LEG_THICKNESS = 0.003  # m, radial
LEG_DENSITY = 1200.0  # kg/m^3, 3D-printed plastic
LEG_ARC_SEGMENTS = 24  # mesh segments along the 180 deg arc (7.5 deg each)
LEG_WIDTH_SEGMENTS = 3  # mesh segments across the width
BODY_HALF = (0.075, 0.035, 0.0125)  # m, half sizes of the body box (15 x 7 x 2.5 cm)
BODY_MASS = 0.28  # kg (robot total = body + 6 legs ~ 0.30 kg)
BODY_RISE = 0.010  # m, body box centre above the hip axes (hips near the underside)
BODY_TRIANGLES = 300  # RFT triangles on the body box (belly drag when it touches the medium)
HIP_X = (0.06, 0.0, -0.06)  # m, front, middle, rear hips along the body x axis
HIP_Y_OUTER = 0.045  # m, |y| of the front and rear legs' mid-planes
HIP_Y_MIDDLE = 0.058  # m, |y| of the middle legs' mid-planes (staggered: legs never overlap)
ARMATURE = 2e-4  # kg m^2, reflected motor + gearbox inertia at each hip
KP = 5.0  # N m/rad, hip position servo stiffness
KV = 0.05  # N m s/rad, hip servo damping (about 0.8 of critical with ARMATURE)
DEFAULT_FREQUENCY = 1.0  # Hz, gait frequency of the keyframe (mjrft run walks at this)
TIMESTEP = 0.001  # s

#: Legs in actuator order: name, hip x, hip y, tripod (0 = A, 1 = B).
LEGS = (
    ("LF", HIP_X[0], HIP_Y_OUTER, 0),
    ("LM", HIP_X[1], HIP_Y_MIDDLE, 1),
    ("LR", HIP_X[2], HIP_Y_OUTER, 0),
    ("RF", HIP_X[0], -HIP_Y_OUTER, 1),
    ("RM", HIP_X[1], -HIP_Y_MIDDLE, 0),
    ("RR", HIP_X[2], -HIP_Y_OUTER, 1),
)


def leg_mesh() -> tuple[np.ndarray, np.ndarray]:
    """Closed C-leg mesh in the leg frame: (V, 3) vertices [m], (F, 3) outward faces."""
    r = LEG_REACH / 2
    n, m = LEG_ARC_SEGMENTS, LEG_WIDTH_SEGMENTS
    s = np.linspace(0.0, math.pi, n + 1)
    y = np.linspace(-LEG_WIDTH / 2, LEG_WIDTH / 2, m + 1)
    centre = np.stack([-r * np.sin(s), np.zeros_like(s), -r * (1 - np.cos(s))], axis=1)
    radial = np.stack([-np.sin(s), np.zeros_like(s), np.cos(s)], axis=1)  # away from arc centre
    tangent = np.stack([-np.cos(s), np.zeros_like(s), -np.sin(s)], axis=1)  # hip -> tip
    verts = []
    index = {}
    for side, sign in (("out", 1.0), ("in", -1.0)):
        for k in range(n + 1):
            for j in range(m + 1):
                p = centre[k] + sign * (LEG_THICKNESS / 2) * radial[k]
                index[side, k, j] = len(verts)
                verts.append([p[0], y[j], p[2]])
    v = np.array(verts)
    faces = []

    def quad(a: int, b: int, c: int, d: int, outward: np.ndarray) -> None:
        for tri in ((a, b, c), (a, c, d)):
            p0, p1, p2 = v[list(tri)]
            if np.dot(np.cross(p1 - p0, p2 - p0), outward) < 0:
                tri = (tri[0], tri[2], tri[1])
            faces.append(tri)

    for k in range(n):
        mid_radial = radial[k] + radial[k + 1]
        for j in range(m):
            for side, sign in (("out", 1.0), ("in", -1.0)):
                quad(
                    index[side, k, j],
                    index[side, k + 1, j],
                    index[side, k + 1, j + 1],
                    index[side, k, j + 1],
                    sign * mid_radial,
                )
        for j, sign in ((0, -1.0), (m, 1.0)):  # the flat sides at y = -+ width/2
            quad(
                index["out", k, j],
                index["out", k + 1, j],
                index["in", k + 1, j],
                index["in", k, j],
                np.array([0.0, sign, 0.0]),
            )
    for k, outward in ((0, -tangent[0]), (n, tangent[n])):  # end caps at the hip and the tip
        for j in range(m):
            quad(
                index["out", k, j],
                index["out", k, j + 1],
                index["in", k, j + 1],
                index["in", k, j],
                outward,
            )
    return v, np.array(faces, dtype=np.int64)


def write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray, header: str) -> None:
    """Write a triangle mesh as Wavefront OBJ (1-based indices), deterministic text."""
    lines = [f"# {line}" for line in header.splitlines()]
    lines += [f"v {x:.9g} {yy:.9g} {z:.9g}" for x, yy, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def _fmt(*values: float) -> str:
    return " ".join(f"{v:.9g}" for v in values)


def mjcf() -> str:
    """The MJCF text of models/hexapod_sand.xml."""
    hip_height = LEG_REACH + LEG_THICKNESS / 2  # tripod A's tips touch the surface at the start
    omega = 2 * math.pi * DEFAULT_FREQUENCY
    lag = KV * omega / KP  # intvelocity steady-state lag, pre-loaded into act
    q_legs = [0.0 if tripod == 0 else math.pi for _, _, _, tripod in LEGS]
    leg_mass = LEG_DENSITY * LEG_THICKNESS * LEG_WIDTH * math.pi * LEG_REACH / 2
    total = BODY_MASS + 6 * leg_mass
    bodies = []
    for name, x, y, _ in LEGS:
        bodies.append(
            f'      <body name="leg_{name}" pos="{_fmt(x, y, 0.0)}">\n'
            f'        <joint name="hip_{name}" type="hinge" axis="0 1 0"'
            f' armature="{ARMATURE:g}"/>\n'
            f'        <geom name="leg_{name}" type="mesh" mesh="c_leg" density="{LEG_DENSITY:g}"'
            f' rgba="0.2 0.2 0.25 1"/>\n'
            f'        <site name="tip_{name}" pos="0 0 {-LEG_REACH:.9g}" size="0.002"/>\n'
            f"      </body>"
        )
    actuators = "\n".join(
        f'    <intvelocity name="hip_{n}" joint="hip_{n}" kp="{KP:g}" kv="{KV:g}"'
        f' ctrlrange="-60 60" actrange="-1e6 1e6"/>'
        for n, _, _, _ in LEGS
    )
    tags = "\n".join(
        f'      <element objtype="geom" objname="leg_{n}" prm="0"/>' for n, _, _, _ in LEGS
    )
    sensors = "\n".join(
        f'    <jointpos name="hip_{n}_angle" joint="hip_{n}"/>\n'
        f'    <jointvel name="hip_{n}_rate" joint="hip_{n}"/>'
        for n, _, _, _ in LEGS
    )
    key_qpos = _fmt(0, 0, hip_height, 1, 0, 0, 0, *q_legs)
    key_qvel = _fmt(*([0.0] * 6 + [omega] * 6))
    key_act = _fmt(*[q + lag for q in q_legs])
    key_ctrl = _fmt(*([omega] * 6))
    reach, width, thick, dens = LEG_REACH, LEG_WIDTH, LEG_THICKNESS, LEG_DENSITY
    box = " x ".join(f"{2 * h:g}" for h in BODY_HALF)
    hips_x, y_out, y_mid = _fmt(*HIP_X), HIP_Y_OUTER, HIP_Y_MIDDLE
    f0, tri = DEFAULT_FREQUENCY, BODY_TRIANGLES
    n_leg_tri = len(leg_mesh()[1])
    n_arc, n_wid = LEG_ARC_SEGMENTS, LEG_WIDTH_SEGMENTS
    header = f"""<!--
hexapod_sand.xml - a six-legged robot with rotating C-shaped legs walking on a granular medium.
GENERATED by models/make_hexapod.py (edit the constants there and rerun; do not edit by hand).

WHAT
  A RHex-class hexapod in the spirit of the RFT-validated robot of Li, Zhang & Goldman,
  "A terradynamics of legged locomotion on granular media", Science 339:1408 (2013): a rigid
  body on a free joint with six C-shaped (half-ring) legs, each on a hip hinge about the body's
  lateral axis (+y) driven by a position servo that follows a continuously rotating reference,
  in an alternating tripod gait (tripod A = LF, RM, LR; tripod B = RF, LM, RR, half a turn
  behind). The body rests on the medium only through granular RFT: the six legs and the body box
  (belly drag) are mjrft intruders; there is no other ground and contacts are disabled.
  Body frame: x forward, y left, z up; positive hip angles swing the lowest leg point backwards,
  so positive gait frequency walks towards +x. Leg frame: hip at the origin, at angle 0 the tip
  is {reach:g} m straight below the hip and the arc bulges backwards (-x), so each leg meets
  the medium convex side first (the RHex "c-leg" orientation; models/make_hexapod.py).

SOURCES OF THE NUMBERS
  alternating tripod gait, continuously rotating C-legs ..... Li, Zhang & Goldman 2013 (and RHex)
  medium glass beads, zeta 0.33 N/cm^3 ...................... as the other rigs (docs/rigs.md);
    Li 2013 ran poppy seeds: envs.load("hexapod_sand", material="poppy_seeds_lp") uses those
  legs: reach (hip to tip) {reach:g} m = diameter of the half ring, width {width:g} m,
    thickness {thick:g} m, 3D-printed plastic {dens:g} kg/m^3 ({leg_mass * 1e3:.2f} g each)
    ..... our choice, in the size range of small C-leg robots (a few hundred grams, leg radius
    3-4 cm); Li 2013's exact robot dimensions are not transcribed here
  body box {box} m, {BODY_MASS:g} kg (robot {total:.3f} kg) ....... our choice
  hips at x = {hips_x} m, |y| = {y_out:g} m (front, rear) and {y_mid:g} m (middle:
    staggered so no two legs share a plane) .................. our choice
  hip servos: intvelocity, kp {KP:g} N m/rad, kv {KV:g} N m s/rad, armature {ARMATURE:g} kg m^2
    ..... our choice: a 0.1 N m leg load lags the reference by 0.02 rad; ~0.8 of critical damping
  RFT resolution: each leg its mesh's {n_leg_tri} triangles ({n_arc} arc x {n_wid} width
    segments); the body box {tri} triangles

CONFIGURE
  * Gait frequency f: every hip actuator's ctrl = 2 pi f [rad/s] (keyframe: f = {f0:g} Hz);
    act = the integrated reference angle, pre-loaded with the servo lag kv 2 pi f / kp.
  * Phase offsets: the difference of the hips' act values (keyframe: tripod B = A + pi).
  * Medium: <custom> below, or envs.load("hexapod_sand", material=...).
  * Dimensions and masses: the constants of models/make_hexapod.py.

ACTUATORS (intvelocity, one per hip, order LF LM LR RF RM RR)
  hip_XX: ctrl = reference angular velocity [rad/s], act = reference angle [rad]; no force limit.

SENSORS
  torso_pos, torso_quat (world), torso_linvel, torso_angvel (world) of site "torso";
  hip_XX_angle, hip_XX_rate [rad, rad/s].
-->
"""
    body_geom_size = _fmt(*BODY_HALF)
    return (
        header
        + f"""<mujoco model="hexapod_sand">
  <compiler angle="radian" meshdir="meshes" autolimits="true"/>
  <option timestep="{TIMESTEP:g}" integrator="Euler">
    <flag contact="disable"/>
  </option>
  <statistic center="0 0 0.03" extent="0.3"/>

  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <numeric name="mjrft:surface_z" data="0"/>
    <numeric name="mjrft:triangles" data="{BODY_TRIANGLES}"/>
    <tuple name="mjrft:intruders">
      <element objtype="geom" objname="body" prm="{BODY_TRIANGLES}"/>
{tags}
    </tuple>
  </custom>

  <asset>
    <mesh name="c_leg" file="c_leg.obj" inertia="exact"/>
  </asset>

  <default>
    <geom contype="0" conaffinity="0"/>
  </default>

  <worldbody>
    <light name="sun" pos="0 0 1" dir="0 0 -1" directional="true"/>
    <!-- Visual only: the free surface of the medium at z = 0. -->
    <geom name="sand_surface" type="box" size="1 0.3 0.0005" pos="0.5 0 -0.0005"
          rgba="0.86 0.76 0.55 0.45" group="1" mass="0"/>
    <camera name="side" pos="0 -0.5 0.15" xyaxes="1 0 0 0 0.3 1" mode="trackcom"/>
    <body name="torso" pos="0 0 {hip_height:.9g}">
      <freejoint name="root"/>
      <geom name="body" type="box" size="{body_geom_size}" pos="0 0 {BODY_RISE:g}"
            mass="{BODY_MASS:g}" rgba="0.8 0.45 0.2 1"/>
      <site name="torso" size="0.004"/>
{chr(10).join(bodies)}
    </body>
  </worldbody>

  <actuator>
{actuators}
  </actuator>

  <sensor>
    <framepos name="torso_pos" objtype="site" objname="torso"/>
    <framequat name="torso_quat" objtype="site" objname="torso"/>
    <framelinvel name="torso_linvel" objtype="site" objname="torso"/>
    <frameangvel name="torso_angvel" objtype="site" objname="torso"/>
{sensors}
  </sensor>

  <keyframe>
    <!-- Tripod A (LF RM LR) straight down with its tips on the surface, tripod B up; walking
         at {f0:g} Hz. qpos: torso x y z, quat w x y z, then hips LF LM LR RF RM RR. -->
    <key name="start" qpos="{key_qpos}"
         qvel="{key_qvel}"
         ctrl="{key_ctrl}"
         act="{key_act}"/>
  </keyframe>
</mujoco>
"""
    )


def main() -> None:
    v, f = leg_mesh()
    obj = HERE / "meshes" / "c_leg.obj"
    obj.parent.mkdir(exist_ok=True)
    write_obj(
        obj,
        v,
        f,
        f"c_leg.obj: C-shaped hexapod leg (half ring), reach {LEG_REACH} m, width {LEG_WIDTH} m,\n"
        f"thickness {LEG_THICKNESS} m, metres; hip at the origin, tip at (0, 0, -{LEG_REACH}).\n"
        "Generated by models/make_hexapod.py; do not edit.",
    )
    xml = HERE / "hexapod_sand.xml"
    xml.write_text(mjcf())
    print(f"wrote {obj} ({len(f)} triangles) and {xml}")


if __name__ == "__main__":
    main()
