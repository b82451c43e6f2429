"""CLI start-up: the wall time of `mjrft --help` and of every subcommand's `--help`.

Run: python benchmarks/cli_startup.py
Each command runs as `python -m mjrft.app.cli ...` in 5 fresh processes (after one untimed run
that warms the file cache); prints the machine, its load average (other processes slow a start-up
that is mostly reading files), the median per command and the modules of note (mujoco,
matplotlib, rerun, dm_control, mjrft.sweep) that `mjrft --help` imports; writes
benchmarks/results/cli_startup.csv (command, median, the 1-minute load average when measured).
"""

from __future__ import annotations

import csv
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "cli_startup.csv"
REPEATS = 5
COMMANDS = (
    ["--help"],
    ["demo", "--help"],
    ["run", "--help"],
    ["sweep", "--help"],
    ["fit", "--help"],
    ["view", "--help"],
    ["view-recording", "--help"],
)
HEAVY = ("mujoco", "matplotlib", "rerun", "dm_control", "mjrft.sweep")


def wall(args: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mjrft.app.cli", *args], check=True,
                   capture_output=True, cwd=ROOT)  # fmt: skip
    return time.perf_counter() - t0


def heavy_imports() -> list[str]:
    """The modules of HEAVY that building the parser and printing `mjrft --help` imports."""
    code = (
        "import sys\nfrom mjrft.app import cli\ntry:\n    cli.main(['--help'])\n"
        "except SystemExit:\n    pass\n"
        f"print(' '.join(m for m in {HEAVY!r} if m in sys.modules), file=sys.stderr)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    return done.stderr.split()


def main() -> None:
    from mjrft.app.metadata import machine

    m = machine()
    print(f"{m.get('cpu', '?')}, {m.get('cpu_count', '?')} cores")
    rows = []
    for args in COMMANDS:
        wall(args)
        median = statistics.median(wall(args) for _ in range(REPEATS))
        command = "mjrft " + " ".join(args)
        load = os.getloadavg()[0]
        rows.append((command, median, load))
        print(f"{command:28s} {median:6.3f} s   (load average {load:.1f})")
    print(f"imported by `mjrft --help`: {', '.join(heavy_imports()) or 'none of ' + str(HEAVY)}")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    with OUT.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["command", "median_s", "load_average"])
        w.writerows((c, f"{t:.4f}", f"{load:.2f}") for c, t, load in rows)


if __name__ == "__main__":
    main()
