"""Kernel speed: the engine's C++ kernel vs the straightforward NumPy baseline; first-call time.

Run: python benchmarks/kernel.py [--repeats N]
Inputs: random submerged elements with random normal and velocity directions (about half lead)
and, separately, all-leading elements. Medians over repeats; ratios measured in the same run.
The kernel is called through ``mjrft.core.engine.forces`` (ctypes; trusted arrays, no checks).
Writes benchmarks/results/kernel.csv and kernel_latency.csv.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from numpy_baseline import baseline_forces

import mjrft
from mjrft.core import engine
from mjrft.core.rft import _unit_rows, numpy_forces

OUT = Path(__file__).resolve().parent / "results"


def make_inputs(n: int, leading: bool, seed: int = 0):
    rng = np.random.default_rng(seed)
    pos = rng.normal(scale=0.05, size=(n, 3))
    pos[:, 2] = -np.abs(pos[:, 2]) - 1e-3
    n_hat, _ = _unit_rows(rng.normal(size=(n, 3)))
    vel = n_hat + 0.5 * rng.normal(size=(n, 3)) if leading else rng.normal(size=(n, 3))
    return pos, n_hat, rng.uniform(1e-6, 1e-4, n), vel


def median_time(fn, repeats: int, budget: float = 2.0) -> float:
    fn()
    times = []
    t_end = time.perf_counter() + budget
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
        if time.perf_counter() > t_end and len(times) >= 3:
            break
    return float(np.median(times))


def first_call_latency() -> dict[str, float]:
    """Seconds to import mjrft and get the first kernel result in a fresh process (the engine
    library is loaded on first use; nothing is compiled at run time), and of the first call
    alone after the import."""
    code = (
        "import time; t0 = time.perf_counter(); import numpy as np, mjrft; "
        "m = mjrft.Material.preset('glass_beads'); t1 = time.perf_counter(); "
        "mjrft.element_forces([[0,0,-1.0]], [[0,0,-1.0]], [1.0], [[0,0,-1.0]], m); "
        "t2 = time.perf_counter(); print(t2 - t0, t2 - t1)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    total, first = (float(x) for x in out.stdout.strip().splitlines()[-1].split())
    return {"import_and_first_call_s": total, "first_call_s": first}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=30)
    args = ap.parse_args()
    OUT.mkdir(exist_ok=True)
    m = mjrft.Material.preset("glass_beads")
    co, ay, zeta = m.kernel_coefficients, m.alpha_y0, m.zeta
    rows = []
    for leading in (False, True):
        for n in (1_000, 10_000, 100_000):
            pos, n_hat, area, vel = make_inputs(n, leading)
            out = np.empty((n, 3))

            def kern(pos=pos, n_hat=n_hat, area=area, vel=vel, out=out):
                engine.forces(pos, n_hat, area, vel, co, ay, zeta, 0.0, out)

            kern()
            base = baseline_forces(pos, n_hat, area, vel, m)
            ident = numpy_forces(pos, n_hat, area, vel, m, 0.0)
            scale = np.abs(base).max()
            err = max(np.abs(out - base).max(), np.abs(ident - base).max()) / scale
            assert err < 1e-10, f"kernel and baseline disagree by {err:.2e} relative"
            t_k = median_time(kern, args.repeats)
            t_b = median_time(
                lambda a=(pos, n_hat, area, vel): baseline_forces(*a, m), args.repeats
            )
            t_i = median_time(
                lambda a=(pos, n_hat, area, vel): numpy_forces(*a, m, 0.0), args.repeats
            )
            rows.append(
                {
                    "inputs": "all leading" if leading else "random (about half lead)",
                    "n": n,
                    "kernel_ns_per_elem": 1e9 * t_k / n,
                    "numpy_baseline_ns_per_elem": 1e9 * t_b / n,
                    "numpy_identities_ns_per_elem": 1e9 * t_i / n,
                    "speedup_vs_baseline": t_b / t_k,
                    "max_rel_diff": err,
                }
            )
            r = rows[-1]
            print(
                f"{r['inputs']:26s} n={n:>7d}: kernel {r['kernel_ns_per_elem']:6.1f} ns/elem, "
                f"baseline {r['numpy_baseline_ns_per_elem']:7.1f}, NumPy identities "
                f"{r['numpy_identities_ns_per_elem']:6.1f}; "
                f"speed-up {r['speedup_vs_baseline']:5.1f}x; max rel diff {err:.1e}"
            )
    lat = first_call_latency()
    print(
        f"first call in a fresh process: {lat['import_and_first_call_s']:.2f} s with the import, "
        f"{1e3 * lat['first_call_s']:.1f} ms the call alone (loads the engine library)"
    )
    with open(OUT / "kernel.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with open(OUT / "kernel_latency.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(lat))
        w.writeheader()
        w.writerow(lat)


if __name__ == "__main__":
    main()
