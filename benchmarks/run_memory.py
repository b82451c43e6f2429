"""Peak memory of `mjrft run` does not grow with the length of the run.

Run: python benchmarks/run_memory.py [--steps 10000 1000000]
Runs `mjrft run` on a small scene (a 1 cm sphere of 48 triangles resting in glass beads, dt =
1 ms, a CSV row every step) for each number of steps in a fresh process, and reports the
process's peak resident memory (getrusage, RUSAGE_CHILDREN), the wall time and the CSV's size.
Writes benchmarks/results/run_memory.csv.
"""

from __future__ import annotations

import argparse
import csv
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

OUT = Path(__file__).resolve().parent / "results"
SCENE = """<mujoco><option timestep="0.001"><flag contact="disable"/></option><custom>
  <text name="mjrft:material" data="glass_beads"/>
  <tuple name="mjrft:intruders"><element objtype="geom" objname="g" prm="48"/></tuple>
  </custom><worldbody><body pos="0 0 0.005"><freejoint/><geom name="g" size="0.01"/></body>
  </worldbody></mujoco>"""


def measure(steps: int, folder: Path) -> dict:
    """One `mjrft run` of `steps` steps in a child process: peak RSS [MB], wall [s], CSV [MB]."""
    scene = folder / "scene.xml"
    scene.write_text(SCENE)
    out = folder / f"run_{steps}"
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "mjrft.app.cli", "run", str(scene), "--duration",
         str(steps * 1e-3), "--out", str(out)],
        check=True, capture_output=True,
    )  # fmt: skip
    wall = time.perf_counter() - t0
    # ru_maxrss of RUSAGE_CHILDREN is the largest child so far: run the sizes in increasing order.
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    csv_mb = (out / "timeseries.csv").stat().st_size / 1e6
    return {"steps": steps, "peak_rss_MB": peak_mb, "wall_s": wall, "csv_MB": csv_mb}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, nargs="+", default=[10_000, 1_000_000])
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for steps in sorted(args.steps):
            rows.append(measure(steps, Path(tmp)))
            r = rows[-1]
            print(
                f"{steps:>9,d} steps: peak RSS {r['peak_rss_MB']:.0f} MB, {r['wall_s']:.1f} s, "
                f"CSV {r['csv_MB']:.1f} MB"
            )
    OUT.mkdir(exist_ok=True)
    with open(OUT / "run_memory.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
