"""What a surface that varies with position costs: the compiled kernel under a flat surface, a
tilted plane and a height field.

Run: python benchmarks/surface.py [--elements 4000] [--repeats 40]
The kernel (``mjrft.core.kernel.body_wrench``) on one body of --elements seeded random elements
(centroids within 1 cm of the origin, so about half are below a surface through it), moving
obliquely, under: the flat surface z = 0; a 20-degree plane through the origin; a 65 x 65 height
field over +-5 cm of random heights within +-2 mm. Each repeat times 200 calls of every variant
in turn; prints the median time per call and the median of each variant's time over the flat
surface's in the same repeat. Writes benchmarks/results/surface.csv.
"""

from __future__ import annotations

import argparse
import csv
import math
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

import numpy as np  # noqa: E402

from mjrft import Material  # noqa: E402
from mjrft.app import metadata  # noqa: E402
from mjrft.core import kernel, quadrature, surface  # noqa: E402

OUT = Path(__file__).resolve().parent / "results"
CALLS = 200


def variants() -> dict[str, surface.Surface]:
    """The surfaces compared, each passing through about the origin."""
    rng = np.random.default_rng(1)
    heights = rng.uniform(-0.002, 0.002, (65, 65))
    return {
        "flat": surface.flat(0.0),
        "plane 20 deg": surface.plane(0.0, math.radians(20.0), 0.0),
        "height field 65x65": surface.grid(heights, -0.05, -0.05, 0.1 / 64, 0.1 / 64),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--elements", type=int, default=4000)
    ap.add_argument("--repeats", type=int, default=40)
    args = ap.parse_args()
    cpu = metadata.machine()["cpu"] or platform.machine()
    print(f"CPU: {cpu}; Python {platform.python_version()}")
    glass = Material.preset("glass_beads")
    rng = np.random.default_rng(0)
    n = args.elements
    cent = rng.normal(size=(n, 3)) * 0.01
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    area = np.full(n, 1e-5)
    # Point elements (reach 0): the one-point rule, the cost this script compares across surfaces.
    reach, patch = np.zeros(n), np.zeros((n, quadrature.PATCH_SIZE))
    wrench, elem_force, zero = np.zeros(6), np.zeros((n, 3)), np.zeros(3)
    vel = np.array([0.1, 0.0, -0.2])
    surfaces = variants()
    medium = (glass.kernel_coefficients, glass.alpha_y0, glass.zeta)
    motion = (np.eye(3), zero, zero, vel, zero, zero, wrench, elem_force, np.empty((0, kernel.ROW)))
    args_of = {
        name: (
            cent,
            normal,
            area,
            reach,
            patch,
            0,
            n,
            *medium,
            s.prm,
            s.grid,
            False,
            np.zeros((2, 3)),
            np.zeros(1),
            *motion,
        )
        for name, s in surfaces.items()
    }
    times = {name: [] for name in surfaces}
    for name in surfaces:
        kernel.body_wrench(*args_of[name])  # compile or load
    for _ in range(args.repeats):
        for name in surfaces:
            t0 = time.perf_counter()
            for _ in range(CALLS):
                kernel.body_wrench(*args_of[name])
            times[name].append((time.perf_counter() - t0) / CALLS)
    flat = np.array(times["flat"])
    rows = []
    for name in surfaces:
        t = np.array(times[name])
        rows.append({"surface": name, "elements": n, "us_per_call": 1e6 * float(np.median(t)),
                     "ratio_to_flat": float(np.median(t / flat))})  # fmt: skip
        print(f"{name:20s}: {rows[-1]['us_per_call']:7.2f} us per call, "
              f"{rows[-1]['ratio_to_flat']:.3f}x flat")  # fmt: skip
    OUT.mkdir(exist_ok=True)
    with open(OUT / "surface.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
