"""Cost of the force models: element_forces per element, treers2021 against agarwal3d.

Run: python benchmarks/models.py [--elements 100000] [--repeats 15]
Random submerged elements (unit normals, random velocities, seeded), the glass-bead medium under
each model, the two timed alternately; medians over repeats [ns per element] and their ratio.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import mjrft
from mjrft import Material


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--elements", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=15)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    n = args.elements
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    vel = rng.normal(size=(n, 3))
    pos = rng.uniform(-0.05, 0.05, (n, 3))
    pos[:, 2] = -np.abs(pos[:, 2])
    area = np.full(n, 1e-5)
    glass = Material.preset("glass_beads")
    models = {"treers2021": glass, "agarwal3d": glass.with_model("agarwal3d")}
    times: dict[str, list[float]] = {k: [] for k in models}
    for m in models.values():  # compile or load, and warm the caches
        mjrft.element_forces(pos, normal, area, vel, m)
    for _ in range(args.repeats):
        for name, m in models.items():
            t0 = time.perf_counter()
            mjrft.element_forces(pos, normal, area, vel, m)
            times[name].append((time.perf_counter() - t0) / n * 1e9)
    med = {k: float(np.median(v)) for k, v in times.items()}
    for k, v in med.items():
        print(f"{k}: {v:.1f} ns per element")
    print(f"agarwal3d / treers2021: {med['agarwal3d'] / med['treers2021']:.2f}")


if __name__ == "__main__":
    main()
