"""Cold start: install from the source tree into a fresh virtual environment, then the first demo,
the import and the test suite's start.

Run: python benchmarks/startup.py [--no-cache]
Creates a virtual environment in a temporary folder, times `pip install .` (with pip's wheel
cache as it is on this machine, or none with --no-cache, which downloads every package), the
first `mjrft demo` (plots and a rerun recording), `import mjrft` (median of 5 fresh processes),
and in the environment running this script the time `python -m pytest` (the README's test
command, pyproject's workers) takes to collect the whole suite and run one test. Prints the
figures; writes benchmarks/results/startup.csv.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "startup.csv"


def timed(cmd: list[str], cwd: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=cwd, check=True, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-cache", action="store_true", help="pip --no-cache-dir")
    args = ap.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        venv = tmp / "venv"
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        py = str(venv / "bin" / "python")
        pip = [py, "-m", "pip", "install", "-q", *(["--no-cache-dir"] if args.no_cache else [])]
        rows["pip_install_s"] = timed([*pip, str(ROOT)], tmp)
        rows["first_demo_s"] = timed([str(venv / "bin" / "mjrft"), "demo", "--out", "demo"], tmp)
        rows["import_s"] = statistics.median(
            timed([py, "-c", "import mjrft"], tmp) for _ in range(5)
        )
    # The suite's start in this (development) environment: collect every test, start the
    # workers (pyproject's addopts) and run one.
    rows["pytest_first_test_s"] = timed(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-k",
         "test_generic_units"], ROOT,
    )  # fmt: skip
    for k, v in rows.items():
        print(f"{k:28s} {v:8.2f}")
    OUT.parent.mkdir(exist_ok=True)
    with OUT.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows))
        w.writeheader()
        w.writerow(rows)


if __name__ == "__main__":
    main()
