"""The authors' two demos with prescribed trajectories (Treers, Cao & Stuart, RA-L 2021, Sec. V).

Parameters are docs/rigs.md and the authors' released demo script: Li generic coefficients,
zeta = 0.33 N/cm^3 (0.8 mm glass beads). Pure computation: no mujoco, no plotting, no files.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mjrft.core import geometry
from mjrft.core.body import trajectory_wrenches
from mjrft.core.material import Material, as_material
from mjrft.core.units import CM, DEG, MM

# --- Mole-crab ellipsoid (Pacific mole crab, Emerita analoga): 36.1 mm tall x 19.2 mm wide/deep,
# the semi-axes of the authors' released mesh (ellipsoid-exp.stl) about its centre, which is the
# released demo's point of rotation.
ELLIPSOID_SEMI_AXES = (9.6 * MM, 9.6 * MM, 18.05 * MM)
ELLIPSOID_PITCH_AMPLITUDE = 9.0 * DEG
ELLIPSOID_PITCH_FREQUENCY = 0.625  # Hz, omega = 5 pi / 4 rad/s
ELLIPSOID_DESCENT_SPEED = 0.5 * CM  # m/s
ELLIPSOID_START_HEIGHT = 1.8 * CM  # pivot (centre) above the surface: the tip starts 0.05 mm below
ELLIPSOID_DURATION = 12.0  # s, as in the released demo

# --- Root-tip paraboloid circumnutation: the authors' released mesh (root-tip.stl), a paraboloid
# of revolution 34.6 mm from apex to base with a 10 mm base radius, yawing about the released
# demo's point of rotation on its axis, 35.8 mm above the apex (1.2 mm above the base).
ROOT_LENGTH = 34.6 * MM
ROOT_RADIUS = 10.0 * MM
ROOT_PIVOT_ABOVE_APEX = 35.8 * MM
ROOT_TILT = 10.0 * DEG
ROOT_YAW_RATE = 15.0 * DEG  # rad/s: one turn in 24 s
ROOT_HELICAL_PITCH = 4.0 * CM  # descent per turn -> 1/6 cm/s
ROOT_DURATION = 50.0  # s


@dataclass(frozen=True)
class DemoResult:
    """Force and moment time series of a prescribed-trajectory demo (world frame, SI).

    Attributes:
      name: demo identifier.
      title: one-line description for plots.
      time: (T,) [s].
      depth: (T,) depth of the body's pivot below the surface [m] (negative above it).
      force: (T, 3) total RFT force on the body, world frame [N].
      moment: (T, 3) RFT moment about the pivot, world frame [N m].
      extra: named (T,) series (pitch, yaw, ...) in SI.
      n_elements: number of surface triangles used.
    """

    name: str
    title: str
    time: np.ndarray
    depth: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    n_elements: int = 0


def _rot_y(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2
    )


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2
    )


def ellipsoid_pitch(
    *,
    n_triangles: int = 4000,
    material: Material | str | None = None,
    dt: float = 0.01,
    duration: float = ELLIPSOID_DURATION,
    amplitude: float = ELLIPSOID_PITCH_AMPLITUDE,
) -> DemoResult:
    """Ellipsoid descending at 0.5 cm/s while pitching amp*sin(2 pi f t) about its centre (world y).

    Args:
      n_triangles: surface triangles of the ellipsoid.
      material: the medium (default glass beads, zeta = 0.33 N/cm^3, Li generic coefficients).
      dt: sample spacing [s]; duration: [s]; amplitude: pitch amplitude [rad] (0: no oscillation).
    """
    material = as_material("glass_beads" if material is None else material)
    elements = geometry.ellipsoid(ELLIPSOID_SEMI_AXES, n_triangles=n_triangles)
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    w = 2.0 * np.pi * ELLIPSOID_PITCH_FREQUENCY
    pitch = amplitude * np.sin(w * t)
    pitch_rate = amplitude * w * np.cos(w * t)
    pos = np.zeros((len(t), 3))
    pos[:, 2] = ELLIPSOID_START_HEIGHT - ELLIPSOID_DESCENT_SPEED * t
    vel = np.zeros_like(pos)
    vel[:, 2] = -ELLIPSOID_DESCENT_SPEED
    ang = np.zeros_like(pos)
    ang[:, 1] = pitch_rate
    wr = trajectory_wrenches(elements, pos, _rot_y(pitch), vel, ang, material)
    motion = (
        f"pitch {np.degrees(amplitude):g} deg at {ELLIPSOID_PITCH_FREQUENCY:g} Hz"
        if amplitude
        else "no pitch"
    )
    return DemoResult(
        name="ellipsoid_pitch" if amplitude else "ellipsoid_no_pitch",
        title=(f"Mole-crab ellipsoid, {motion}, descending {ELLIPSOID_DESCENT_SPEED / CM:g} cm/s"),
        time=t,
        depth=-pos[:, 2],
        force=wr.force,
        moment=wr.moment,
        extra={"pitch": pitch, "pitch_rate": pitch_rate},
        n_elements=len(elements),
    )


def root_circumnutation(
    *,
    n_triangles: int = 4000,
    material: Material | str | None = None,
    dt: float = 0.1,
    duration: float = ROOT_DURATION,
) -> DemoResult:
    """Root-tip paraboloid tilted 10 deg, yawing 15 deg/s about the vertical through its pivot.

    The pivot (on the axis, ROOT_PIVOT_ABOVE_APEX above the apex) starts at the surface and
    descends 4 cm per turn, so the tip traces a helix, as in the authors' circumnutation demo.
    """
    material = as_material("glass_beads" if material is None else material)
    # Paraboloid apex at the shape origin pointing down; move the pivot to the body origin.
    shape = geometry.paraboloid(ROOT_RADIUS, ROOT_LENGTH, n_triangles=n_triangles)
    elements = shape.transformed(np.eye(3), np.array([0.0, 0.0, -ROOT_PIVOT_ABOVE_APEX]))
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    yaw = ROOT_YAW_RATE * t
    rot = _rot_z(yaw) @ _rot_y(np.full_like(t, ROOT_TILT))
    descent = ROOT_HELICAL_PITCH * ROOT_YAW_RATE / (2.0 * np.pi)
    pos = np.zeros((len(t), 3))
    pos[:, 2] = -descent * t
    vel = np.zeros_like(pos)
    vel[:, 2] = -descent
    ang = np.zeros_like(pos)
    ang[:, 2] = ROOT_YAW_RATE
    wr = trajectory_wrenches(elements, pos, rot, vel, ang, material)
    return DemoResult(
        name="root_circumnutation",
        title=(
            f"Root-tip paraboloid, tilt {np.degrees(ROOT_TILT):g} deg, yaw "
            f"{np.degrees(ROOT_YAW_RATE):g} deg/s, descending {descent / CM:.4g} cm/s"
        ),
        time=t,
        depth=-pos[:, 2],
        force=wr.force,
        moment=wr.moment,
        extra={"yaw": yaw},
        n_elements=len(elements),
    )


def dominant_frequency(t: np.ndarray, x: np.ndarray, detrend_degree: int = 2) -> float:
    """Frequency [Hz] of the largest spectral peak of x(t) after removing a polynomial trend.

    Args:
      t: (T,) uniformly spaced times [s]; x: (T,) signal.
    """
    resid = x - np.polyval(np.polyfit(t, x, detrend_degree), t)
    n = 8 * len(t)  # zero-padding refines the peak location
    spec = np.abs(np.fft.rfft(resid * np.hanning(len(t)), n))
    freqs = np.fft.rfftfreq(n, t[1] - t[0])
    return float(freqs[1:][np.argmax(spec[1:])])


def oscillation_summary(result: DemoResult, t_start: float = 4.0) -> dict[str, float]:
    """Dominant frequencies of the lateral (x) and vertical (z) force, and the lateral mean.

    Uses t >= t_start, when the ellipsoid is well into the medium. Returns frequencies [Hz], the
    lateral force's mean and RMS [N], and their ratio.
    """
    sel = result.time >= t_start
    t, fx, fz = result.time[sel], result.force[sel, 0], result.force[sel, 2]
    fx_mean = float(fx.mean())
    fx_rms = float(np.sqrt(np.mean((fx - fx_mean) ** 2)))
    return {
        "lateral_frequency_hz": dominant_frequency(t, fx, detrend_degree=0),
        "vertical_frequency_hz": dominant_frequency(t, fz),
        "lateral_mean_n": fx_mean,
        "lateral_rms_n": fx_rms,
        "lateral_mean_over_rms": fx_mean / fx_rms if fx_rms > 0 else 0.0,
    }
