"""Honesty of mjrft fit's 95 % intervals: coverage over seeded trials of noisy synthetic plates.

Run: python benchmarks/fit_coverage.py [--trials 100] [--noise 0.02]

Each trial: glass-bead plates from the kernel (one leading element per plate, as
tests/test_fit.py makes them) on a 10-degree grid of attack and intrusion angles at random
depths 1-5 cm, 2 x 2 cm, plus Gaussian force noise of `noise` times the force scale zeta d A at
3 cm (per component); the first-order fit (``mjrft.core.fit.fit``) and, on yawed plates (beta
-75..75 deg, gamma -60..90 deg, yaw +-20..70 deg), the yawed-plate fit (``fit_yawed``). For
every coefficient: the share of trials whose 95 % interval holds the truth (the kernel's
coefficients, Treers et al.'s f1 and f23, the preset's constant alpha_y). Writes
benchmarks/results/fit_coverage.csv.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

import mjrft
from mjrft.core import law
from mjrft.core.fit import PlateData, YawedPlateData, fit, fit_yawed

OUT = Path(__file__).resolve().parent / "results"
AREA, DEPTHS = 4e-4, (0.01, 0.05)


def plate_forces(material, beta, gamma, psi, rng, noise):
    """(keep mask, depth, forces (n, 3)) of leading plates at the angles [rad]."""
    n = np.stack([np.sin(beta), 0 * beta, -np.cos(beta)], axis=1)
    u = np.stack([np.cos(gamma), 0 * gamma, -np.sin(gamma)], axis=1)
    v = np.cos(psi)[:, None] * u + np.sin(psi)[:, None] * np.array([0.0, 1.0, 0.0])
    lead = np.sum(n * v, axis=1)
    n[lead < 0] *= -1.0
    depth = rng.uniform(*DEPTHS, len(beta))
    pos = np.stack([0 * beta, 0 * beta, -depth], axis=1)
    f = mjrft.element_forces(pos, n, np.full(len(beta), AREA), v, material)
    return np.abs(lead) > 1e-3, depth, f + rng.normal(0.0, noise, f.shape)


def trial(material, rng, noise):
    """(in-plane Fit, YawFit) of one noisy draw."""
    b, g = (np.radians(a).ravel() for a in np.meshgrid(np.arange(-90, 90, 10.0),
                                                       np.arange(-90, 90.1, 10.0)))  # fmt: skip
    k, d, f = plate_forces(material, b, g, 0 * b, rng, noise)
    in_plane = fit(PlateData(b[k], g[k], d[k], np.full(k.sum(), AREA), f[k, 0], f[k, 2]))
    b, g, p = (np.radians(a).ravel() for a in np.meshgrid(
        np.arange(-75, 90, 15.0), np.arange(-60, 90.1, 30.0), [-60, -30, 20, 45, 70]))  # fmt: skip
    k, d, f = plate_forces(material, b, g, p, rng, noise)
    yawed = YawedPlateData(b[k], g[k], p[k], d[k], np.full(k.sum(), AREA), f[k, 0], f[k, 1],
                           f[k, 2])  # fmt: skip
    return in_plane, fit_yawed(yawed, in_plane)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--noise", type=float, default=0.02)
    args = ap.parse_args()
    material = mjrft.Material.preset("glass_beads")
    noise = args.noise * material.zeta * 0.03 * AREA
    truth = material.fourier.scaled(material.zeta).as_mapping()
    truth_yaw = {"ay0": material.alpha_y0 * material.zeta, "ay_cos2b": 0.0, "ay_sin2b": 0.0,
                 "f1_slope": law.F1_SLOPE, "f1_shift": law.F1_SHIFT,
                 "f23_slope": law.F23_SLOPE, "f23_shift": law.F23_SHIFT}  # fmt: skip
    hits: dict[str, int] = {}
    for t in range(args.trials):
        in_plane, yawed = trial(material, np.random.default_rng(1000 + t), noise)
        for name in in_plane.coefficients:
            lo, hi = in_plane.interval(name)
            hits[name] = hits.get(name, 0) + int(lo <= truth.get(name, 0.0) <= hi)
        for name, value in truth_yaw.items():
            lo, hi = yawed.interval(name)
            hits[name] = hits.get(name, 0) + int(lo <= value <= hi)
    OUT.mkdir(exist_ok=True)
    rows = [{"coefficient": k, "coverage": v / args.trials} for k, v in hits.items()]
    with open(OUT / "fit_coverage.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["coefficient", "coverage"])
        w.writeheader()
        w.writerows(rows)
    print(f"{args.trials} trials, {100 * args.noise:g} % noise: share of 95 % intervals that "
          "hold the truth")  # fmt: skip
    for r in rows:
        print(f"  {r['coefficient']:10s} {100 * r['coverage']:5.1f} %")
    print(f"lowest {100 * min(r['coverage'] for r in rows):.1f} %")


if __name__ == "__main__":
    main()
