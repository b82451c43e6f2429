"""Speed of the public calls: prescribed trajectories against the authors' code, element_forces
against its kernel.

Run: python benchmarks/prescribed.py [--repeats N]
1. ``mjrft.body.trajectory_wrenches`` on the inputs of the authors' two demos
   (``mjrft.app.demos``: the mole-crab ellipsoid at 2352 triangles, 121 samples 0.1 s apart; the
   root tip at its rig's mesh size), timed alone (the demo's meshing and set-up excluded) and as
   the whole demo call, in ns per triangle and sample, against the authors' MATLAB
   ``rft_3D_body`` under GNU Octave. Octave and their code are not part of mjrft: the figure used
   is 0.5 us per plate and evaluation, measured once with Octave 8 on the Zen 1 VM
   (``AUTHORS_US_PER_PLATE``), stated as such in the output.
2. ``mjrft.element_forces`` (checked inputs, unit normals) against the kernel it calls
   (``mjrft.core.engine.forces``, the C++ kernel through ctypes, trusted arrays) at 1k, 10k and
   100k elements.
Medians over repeats; writes benchmarks/results/prescribed.csv.
"""

from __future__ import annotations

import argparse
import csv
import functools
import time
from pathlib import Path

import numpy as np

import mjrft
from mjrft.app import demos
from mjrft.core import body, engine

OUT = Path(__file__).resolve().parent / "results"
#: The authors' rft_3D_body under GNU Octave 8, per plate and evaluation [us] (Zen 1 VM).
AUTHORS_US_PER_PLATE = 0.5


def median_time(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def row(case, triangles, samples, wall_s, ns, vs_authors, kernel_s=float("nan")) -> dict:
    """One CSV row; ``public_over_kernel`` only where a kernel time is given."""
    return {
        "case": case,
        "triangles": triangles,
        "samples": samples,
        "wall_s": wall_s,
        "ns_per_triangle_sample": ns,
        "vs_authors": vs_authors,
        "kernel_s": kernel_s,
        "public_over_kernel": wall_s / kernel_s,
    }


def time_demo(name: str, run, repeats: int) -> list[dict]:
    """Rows for one demo: trajectory_wrenches on its inputs alone, and the whole demo call."""
    captured = {}

    def capture(*a, **kw):
        captured["args"], captured["kw"] = a, kw
        return body.trajectory_wrenches(*a, **kw)

    demos.trajectory_wrenches = capture
    try:
        res = run()
    finally:
        demos.trajectory_wrenches = body.trajectory_wrenches
    call = functools.partial(body.trajectory_wrenches, *captured["args"], **captured["kw"])
    samples, n_tri = len(res.time), res.n_elements
    rows = []
    for label, fn in (("trajectory_wrenches", call), ("whole demo call", run)):
        t = median_time(fn, repeats)
        ns = 1e9 * t / (samples * n_tri)
        ratio = 1e3 * AUTHORS_US_PER_PLATE / ns
        rows.append(row(f"{name}, {label}", n_tri, samples, t, ns, ratio))
        print(
            f"{name}, {label}: {n_tri} triangles x {samples} samples in {1e3 * t:.1f} ms, "
            f"{ns:.1f} ns per triangle and sample: {ratio:.0f}x the authors' code (their "
            f"{AUTHORS_US_PER_PLATE} us/plate under Octave, measured on the Zen 1 VM)"
        )
    return rows


def time_element_forces(n: int, repeats: int) -> list[dict]:
    """Rows for element_forces at n elements, unit normals and normals of any length."""
    glass = mjrft.Material.preset("glass_beads")
    rng = np.random.default_rng(0)
    pos = rng.normal(size=(n, 3)) * 0.01 - [0, 0, 0.02]
    normal = rng.normal(size=(n, 3))
    n_hat = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    area, vel, out = np.full(n, 1e-6), rng.normal(size=(n, 3)), np.empty((n, 3))
    co, ay, zeta = glass.kernel_coefficients, glass.alpha_y0, glass.zeta
    kern = functools.partial(engine.forces, pos, n_hat, area, vel, co, ay, zeta, 0.0, out)
    t_kernel = median_time(kern, repeats)
    rows = []
    for label, normals in (("unit normals", n_hat), ("normals of any length", normal)):
        public = functools.partial(mjrft.element_forces, pos, normals, area, vel, glass)
        t_public = median_time(public, repeats)
        rows.append(
            row(f"element_forces n={n}, {label}", n, 1, t_public, 1e9 * t_public / n,
                float("nan"), t_kernel)
        )  # fmt: skip
        print(
            f"element_forces n={n}, {label}: {1e9 * t_public / n:.1f} ns/element, the "
            f"kernel alone {1e9 * t_kernel / n:.1f}: {t_public / t_kernel:.2f}x"
        )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    args = ap.parse_args()
    rows = []
    cases = {
        "ellipsoid demo": lambda: demos.ellipsoid_pitch(n_triangles=2352, dt=0.1),
        "root demo": lambda: demos.root_circumnutation(dt=0.1),
    }
    for name, run in cases.items():
        rows += time_demo(name, run, args.repeats)
    for n in (1_000, 10_000, 100_000):
        rows += time_element_forces(n, 31)
    OUT.mkdir(exist_ok=True)
    with open(OUT / "prescribed.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
