"""What a surface that varies with position costs: the engine's kernel under a flat surface, a
tilted plane and a height field.

Run: python benchmarks/surface.py [--elements 4000] [--repeats 40]
The kernel (engine/kernel.h's BodyWrench, ``mjrft.core.engine.body_wrench``) on one body of
--elements seeded random elements (centroids within 1 cm of the origin, so about half are below
a surface through it), moving obliquely, under: the flat surface z = 0; a 20-degree plane
through the origin; a 65 x 65 height field over +-5 cm of random heights within +-2 mm. Each
variant's arguments are checked once by ``engine.body_wrench``; the timed calls go to the C
entry point ``mjrft_body_wrench`` directly (ctypes, about 1 us per call), so the argument checks
do not blur the comparison. Each repeat times 200 calls of every variant in turn; prints the
median time per call and the median of each variant's time over the flat surface's in the same
repeat. Writes benchmarks/results/surface.csv.
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
from mjrft.core import engine, quadrature, surface  # noqa: E402

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
    rot, vel, region, no_soil = np.eye(3), np.array([0.1, 0.0, -0.2]), np.zeros((2, 3)), np.zeros(1)
    surfaces = variants()
    co = glass.kernel_coefficients
    ptr = lambda a: a.ctypes.data  # noqa: E731
    calls = {}
    for name, s in surfaces.items():
        engine.body_wrench(cent, normal, area, reach, patch, co, glass.alpha_y0, glass.zeta,
                           s.prm, s.grid, None, None, rot, zero, zero, vel, zero, zero)  # fmt: skip
        calls[name] = (
            ptr(cent), ptr(normal), ptr(area), ptr(reach), ptr(patch), 0, n, ptr(co), len(co),
            glass.alpha_y0, glass.zeta, ptr(s.prm), ptr(s.grid), 0, ptr(region), ptr(no_soil),
            ptr(rot), ptr(zero), ptr(zero), ptr(vel), ptr(zero), ptr(zero), ptr(wrench),
            ptr(elem_force), None,
        )  # fmt: skip
    body_wrench = engine.library().mjrft_body_wrench
    times = {name: [] for name in surfaces}
    for _ in range(args.repeats):
        for name in surfaces:
            call = calls[name]
            t0 = time.perf_counter()
            for _ in range(CALLS):
                body_wrench(*call)
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
