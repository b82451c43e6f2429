"""What `mjrft run`'s figures cost against its simulation, for every shipped model.

Run: python benchmarks/plots.py [--durations 1 10 60] [--repeats 3] [--models NAME ...]
     [--figure-format png] [--all-figures]
For each model in models/ and each duration, runs `mjrft run MODEL --duration D --out TMP` in a
fresh process, as a user would (default options: the table decimated to about 2,000 rows, the
figures drawn from it after the run within the simulation's wall time; with --all-figures every
figure), and reads the parts run.json records: the simulation's wall time and the figures'
(reading the table back, importing matplotlib, drawing and writing the figures). Prints the
medians over --repeats runs, their ratio, the command's total, the rows, the figures written and
those left out, and the machine's CPU. Writes benchmarks/results/plots.csv (plots_all.csv with
--all-figures).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def cpu() -> str:
    """The CPU model (from /proc/cpuinfo where there is one)."""
    try:
        with open("/proc/cpuinfo") as fh:
            names = [ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")]
        return names[0] if names else platform.processor()
    except OSError:
        return platform.processor() or "unknown"


def run_once(name: str, duration: float, fmt: str, every: bool) -> dict:
    """One `mjrft run` of a shipped model; run.json's timings, rows and outputs."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [sys.executable, "-m", "mjrft.app.cli", "run", name, "--duration", str(duration),
               "--out", str(out), "--figure-format", fmt]  # fmt: skip
        cmd += ["--all-figures"] if every else []
        env = {**os.environ, "PYTHONWARNINGS": "ignore"}
        subprocess.run(cmd, check=True, capture_output=True, env=env)
        record = json.loads((out / "run.json").read_text())
    timing = record["timing"]
    return {
        "simulation_s": timing["simulation_s"],
        "plots_s": timing.get("plots_s", 0.0),
        "total_s": timing["total_s"],
        "rows": record["rows"],
        "figures": len(record["outputs"]) - 1,
        "left_out": len(record["figures_skipped"]),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--durations", type=float, nargs="+", default=[1.0, 10.0, 60.0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--figure-format", default="png", choices=("png", "svg", "pdf"))
    ap.add_argument("--all-figures", action="store_true")
    names = sorted(p.stem for p in (ROOT / "models").glob("*.xml"))
    ap.add_argument("--models", nargs="+", default=names)
    args = ap.parse_args()
    print(f"CPU: {cpu()}, {os.cpu_count()} cores; Python {platform.python_version()}")
    rows = []
    for name in args.models:
        for duration in args.durations:
            runs = [run_once(name, duration, args.figure_format, args.all_figures)
                    for _ in range(args.repeats)]  # fmt: skip
            row = {"model": name, "duration_s": duration, "format": args.figure_format}
            for key in ("simulation_s", "plots_s", "total_s"):
                row[key] = statistics.median(r[key] for r in runs)
            row["plots_per_simulation"] = row["plots_s"] / row["simulation_s"]
            row["rows"], row["figures"] = runs[0]["rows"], runs[0]["figures"]
            row["left_out"] = runs[0]["left_out"]
            rows.append(row)
            print(
                f"{name:20s} {duration:5g} s: simulation {row['simulation_s']:6.2f} s, figures "
                f"{row['plots_s']:5.2f} s ({row['plots_per_simulation']:5.2f}x), command "
                f"{row['total_s']:6.2f} s; {row['rows']} rows, {row['figures']} figures "
                f"({row['left_out']} left out)",
                flush=True,
            )
    out = RESULTS / ("plots_all.csv" if args.all_figures else "plots.csv")
    RESULTS.mkdir(exist_ok=True)
    with out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
