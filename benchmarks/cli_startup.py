"""CLI start-up: the wall time of `mjrft --help` and of every subcommand's `--help`.

Run: python benchmarks/cli_startup.py
Each command runs as `python -m mjrft.app.cli ...` in 5 fresh processes (after one untimed run
that warms the file cache); prints the median per command and the modules of note (mujoco,
matplotlib, rerun, dm_control, mjrft.sweep) that `mjrft --help` imports; writes
benchmarks/results/cli_startup.csv.
"""

from __future__ import annotations

import csv
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
    rows = []
    for args in COMMANDS:
        wall(args)
        median = statistics.median(wall(args) for _ in range(REPEATS))
        command = "mjrft " + " ".join(args)
        rows.append((command, median))
        print(f"{command:28s} {median:6.3f} s")
    print(f"imported by `mjrft --help`: {', '.join(heavy_imports()) or 'none of ' + str(HEAVY)}")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    with OUT.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["command", "median_s"])
        w.writerows((c, f"{m:.4f}") for c, m in rows)


if __name__ == "__main__":
    main()
