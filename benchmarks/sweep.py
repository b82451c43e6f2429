"""Sweep throughput: runs per second of `mjrft sweep`'s backends against a serial loop.

Run: python benchmarks/sweep.py [--repeats R] [--duration S] [--workers N] [--no-ray]

1. A 16-run study of the root rig (studies/root_circumnutation.toml's tip angles 5-30 deg x
   nutation rates 0-30 deg/s, each run `--duration` simulated seconds, about 1.1 s of wall time
   at the default 16 s): a serial loop of ``mjrft.sweep.executor.execute`` in this process,
   ``run_study`` in this process (backend "serial": the loop plus the results folder, its lock
   and a row written and fsync'ed per run), then ``run_study`` on the local backend (pool
   start-up included), `--repeats` rounds; and, unless --no-ray, ``run_study`` on a new local
   Ray instance (`ray_init_s` is its start, not included in `wall_s`).
2. Per-run overhead: a 32-run study of runs that do almost nothing (models/sphere_drop.xml, one
   step each) on each backend: overhead per run = wall x workers / runs - the serial time per
   run (the CPU-seconds a run costs beyond its own work); and the CPU time of this process and
   its children per run (`cpu_s`), which other processes on a shared machine disturb less than
   the wall time.

On a shared machine every measurement also records the CPU the machine spent outside this
process and its children (`others_cores`, from /proc/stat; for Ray its own worker processes
count there too): the summary takes the median over the measurements with others_cores < 0.1
where there are any. Writes benchmarks/results/sweep.csv (one row per measurement).
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from mjrft.app.metadata import machine
from mjrft.sweep import Study, run_study
from mjrft.sweep.executor import execute

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results"
ROOT_STUDY = ROOT / "studies" / "root_circumnutation.toml"
TINY = """
[study]
model = "sphere_drop"
duration = 0.001
[parameters.z]
path = "key.start.qpos[2]"
range = { start = 0.011, stop = 0.0265, step = 0.0005 }
[metrics]
depth_m = { kind = "final_depth", body = "sphere" }
"""
QUIET = 0.1  # cores used by other processes below which a measurement counts as clean


def root_study(duration: float) -> Study:
    """studies/root_circumnutation.toml cut to 16 runs of `duration` s."""
    text = ROOT_STUDY.read_text().replace("duration = 24.0", f"duration = {duration}")
    text = text.replace("values = [0, 7.5, 15, 30, 60]", "values = [0, 7.5, 15, 30]")
    text = text.replace("after = 22.0", f"after = {duration - 2.0}")
    return Study.from_toml(text, base=ROOT_STUDY.parent, name="root16")


class Meter:
    """Wall time and the CPU other processes used meanwhile [cores]."""

    @staticmethod
    def _busy() -> float:
        with open("/proc/stat") as fh:
            ticks = [int(x) for x in fh.readline().split()[1:9]]
        return (sum(ticks) - ticks[3] - ticks[4]) / os.sysconf("SC_CLK_TCK")

    @staticmethod
    def _own() -> float:
        t = os.times()
        return t.user + t.system + t.children_user + t.children_system

    def __enter__(self) -> Meter:
        self.t0, self.busy0, self.own0 = time.perf_counter(), self._busy(), self._own()
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall = time.perf_counter() - self.t0
        self.cpu = self._own() - self.own0
        others = self._busy() - self.busy0 - self.cpu
        self.others = max(0.0, others) / self.wall


def measure(study: Study, backend: str, workers: int) -> dict:
    """One measurement: wall, first row, others' cores (and Ray's start-up)."""
    out = Path(tempfile.mkdtemp(prefix="mjrft-bench-"))
    row: dict = {"backend": backend}
    if backend == "ray":
        import ray

        t0 = time.perf_counter()
        ray.init(address="local", num_cpus=workers, include_dashboard=False, log_to_driver=False)
        row["ray_init_s"] = time.perf_counter() - t0
    first = []
    t0 = time.perf_counter()

    def progress(done: int, total: int, row: dict | None) -> None:
        if done == 1:
            first.append(time.perf_counter() - t0)

    try:
        with Meter() as m:
            if backend == "serial":
                for run in study.runs():
                    execute(study, run)
            else:
                t0 = time.perf_counter()
                how = "serial" if backend == "table" else backend
                run_study(study, out / "o", workers, how, plots=False, progress=progress)
    finally:
        shutil.rmtree(out)
        if backend == "ray":
            ray.shutdown()
    return row | {"wall_s": m.wall, "cpu_s": m.cpu, "first_row_s": first[0] if first else None,
                  "others_cores": m.others}  # fmt: skip


def summary(rows: list[dict], n: int, workers: int) -> dict:
    """Medians per backend over the clean measurements (all, if none is clean)."""
    out = {}
    for backend in ("serial", "table", "local", "ray"):
        mine = [r for r in rows if r["backend"] == backend]
        clean = [r for r in mine if r["others_cores"] < QUIET]
        if mine:
            used = clean or mine
            wall = statistics.median(r["wall_s"] for r in used)
            steady = [r["wall_s"] - r["first_row_s"] for r in used if r["first_row_s"]]
            out[backend] = (wall, statistics.median(steady) if steady else wall, len(clean), mine)
            cpu = statistics.median(r["cpu_s"] for r in used)
            print(f"  {backend:6s} CPU {1e3 * cpu / n:7.2f} ms per run (this process and its "
                  "children; Ray's workers are not its children)")  # fmt: skip
    serial = out["serial"][0]
    for backend, (wall, steady, k, mine) in out.items():
        cores = workers if backend in ("local", "ray") else 1
        overhead = wall * cores / n - serial / n
        after_first = steady * cores / (n - 1) - serial / n  # start-up left out
        print(
            f"  {backend:6s} {wall:7.3f} s ({k}/{len(mine)} clean"
            f"{'' if k else ', all used'}), {n / wall:6.2f} runs/s, {serial / wall:5.2f}x "
            "serial"
            + ("" if backend == "serial" else f", overhead per run {overhead:+.4f} s "
               f"({after_first:+.4f} s after the first row)")
        )  # fmt: skip
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--duration", type=float, default=16.0, help="simulated s per root run")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-ray", action="store_true")
    ap.add_argument("--only", choices=("root16", "tiny32"), default=None, help="one study")
    args = ap.parse_args()
    m = machine()
    print(f"{m['cpu']}, {m['cpu_count']} cores; {args.workers} workers")
    rows = []
    for name, study in (("root16", root_study(args.duration)),
                        ("tiny32", Study.from_toml(TINY, name="tiny"))):  # fmt: skip
        if args.only not in (None, name):
            continue
        mine = []
        for i in range(args.repeats):
            for backend in ("serial", "table", "local") + (() if args.no_ray else ("ray",)):
                r = {"study": name, "runs": len(study.runs()), "repeat": i}
                r |= measure(study, backend, args.workers)
                print("  ", {k: round(v, 4) if isinstance(v, float) else v for k, v in r.items()})
                mine.append(r)
        print(f"{name}:")
        summary(mine, len(study.runs()), args.workers)
        rows += mine
    OUT.mkdir(exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(OUT / "sweep.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, keys)
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {OUT / 'sweep.csv'}")


if __name__ == "__main__":
    main()
