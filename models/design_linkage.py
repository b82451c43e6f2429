"""Solve the crank-rocker linkage of models/ellipsoid_pitch.xml and print its MJCF numbers.

Run: ``python models/design_linkage.py [--amplitude DEG] [--rocker H] [--coupler LC]``.

Planar four-bar in the carriage's x-z plane, every hinge about +y (MuJoCo: rotating (x, z) by a
about +y gives (x cos a + z sin a, -x sin a + z cos a)). Carriage origin = rocker pin B at pitch 0;
pitch pivot P = (0, -H); crank centre C = (cx, 0); crank pin A = C + r (sin phi, cos phi); the
coupler (length Lc) joins A to B = P + H (sin theta, cos theta). We solve r and cx so that the pitch
extremes over a crank turn are exactly +-amplitude, then the crank angle phi0 where pitch = 0 and
rising. The crank pin is put at phi0 in the crank body, so all joints are 0 in the start pose.
"""

from __future__ import annotations

import argparse

import numpy as np


def ry(a: float, v: np.ndarray) -> np.ndarray:
    """Rotate the (x, z) vector v by a about +y."""
    c, s = np.cos(a), np.sin(a)
    return np.array([v[0] * c + v[1] * s, -v[0] * s + v[1] * c])


def pitch_of(phi: float, r: float, cx: float, h: float, lc: float) -> float:
    """Pitch angle theta (branch near 0) closing the loop at crank angle phi."""
    a = np.array([cx + r * np.sin(phi), r * np.cos(phi)])
    th = 0.0
    for _ in range(60):
        b = np.array([h * np.sin(th), h * np.cos(th) - h])
        d = b - a
        db = np.array([h * np.cos(th), -h * np.sin(th)])
        step = (d @ d - lc**2) / (2.0 * (d @ db))
        th -= step
        if abs(step) < 1e-15:
            break
    return th


def solve(amplitude: float, h: float, lc: float) -> tuple[float, float, float]:
    """(r, cx, phi0) giving pitch extremes +-amplitude and pitch(phi0) = 0."""
    r, cx = h * np.sin(amplitude), -lc
    phis = np.linspace(0.0, 2.0 * np.pi, 20001)
    for _ in range(30):
        p = np.array([pitch_of(q, r, cx, h, lc) for q in phis])
        hi, lo = p.max(), p.min()
        if abs(hi - amplitude) < 1e-12 and abs(lo + amplitude) < 1e-12:
            break
        r *= 2.0 * amplitude / (hi - lo)
        cx -= 0.5 * (hi + lo) * h
    lo_phi, hi_phi = -0.5, 0.5
    for _ in range(200):
        mid = 0.5 * (lo_phi + hi_phi)
        if pitch_of(mid, r, cx, h, lc) < 0.0:
            lo_phi = mid
        else:
            hi_phi = mid
    return r, cx, 0.5 * (lo_phi + hi_phi)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--amplitude", type=float, default=9.0, help="pitch amplitude [deg]")
    ap.add_argument("--rocker", type=float, default=0.09, help="rocker arm H [m]")
    ap.add_argument("--coupler", type=float, default=0.27, help="coupler length Lc [m]")
    ap.add_argument("--frequency", type=float, default=0.625, help="pitch frequency [Hz]")
    ap.add_argument("--kp", type=float, default=1000.0, help="crank servo kp [N m/rad]")
    ap.add_argument("--kv", type=float, default=6.0, help="crank servo kv [N m s/rad]")
    args = ap.parse_args()
    amp, h, lc = np.radians(args.amplitude), args.rocker, args.coupler
    w = 2.0 * np.pi * args.frequency
    r, cx, phi0 = solve(amp, h, lc)
    pin = r * np.array([np.sin(phi0), np.cos(phi0)])
    end = -(np.array([cx, 0.0]) + pin)  # coupler end at B0 = carriage origin
    # Start velocities by central differences of the closed-loop solution.
    eps = 1e-6

    def coupler_rel(q: float) -> float:
        a = np.array([cx, 0.0]) + ry(q, pin)
        th = pitch_of(phi0 + q, r, cx, h, lc)
        b = np.array([h * np.sin(th), h * np.cos(th) - h])
        d = b - a  # = ry(q + qc, end)
        alpha = np.arctan2(end[1], end[0]) - np.arctan2(d[1], d[0])  # ry rotates clockwise in x-z
        return alpha - q

    dpitch = (pitch_of(phi0 + eps, r, cx, h, lc) - pitch_of(phi0 - eps, r, cx, h, lc)) / (2 * eps)
    dcoup = (coupler_rel(eps) - coupler_rel(-eps)) / (2 * eps)
    print(f"crank radius r = {r:.12g} m, crank centre cx = {cx:.12g} m, phi0 = {phi0:.12g} rad")
    print(f'crank body pos    = "{cx:.12g} 0 0"')
    print(f'crank_pin / coupler body pos = "{pin[0]:.12g} 0 {pin[1]:.12g}"')
    print(f'coupler_end site pos = "{end[0]:.12g} 0 {end[1]:.12g}"', f"(Lc {np.hypot(*end):.12g})")
    print(f'pitch_body pos    = "0 0 {-h:.12g}", rocker_pin pos = "0 0 {h:.12g}"')
    print(f"keyframe qvel (crank, coupler, pitch) = {w:.12g} {dcoup * w:.12g} {dpitch * w:.12g}")
    print(f"keyframe ctrl crank = {w:.12g}, act crank = kv w / kp = {args.kv * w / args.kp:.12g}")
    t = np.linspace(0.0, 1.0 / args.frequency, 2001)
    p = np.array([pitch_of(phi0 + w * x, r, cx, h, lc) for x in t])
    dev = np.degrees(np.abs(p - amp * np.sin(w * t)).max())
    print(f"max |pitch - A sin(w t)| = {dev:.4f} deg, mean pitch = {np.degrees(p.mean()):.4f} deg")


if __name__ == "__main__":
    main()
