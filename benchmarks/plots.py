"""Wall time of `mjrft run`'s figures (mjrft.app.report.plot_run) for every shipped model.

Run: python benchmarks/plots.py [--durations 5 19.999] [--repeats 3] [--models NAME ...]
For each model in models/ and each duration, simulates the model at its default options with
its rows streamed to a CSV (as `mjrft run` does), reads the CSV back as `mjrft run` does
(Recording.from_csv: at most 20,000 rows, so 19.999 s at dt = 1 ms is the largest recording the
figures ever get), and times plot_run: the first call (which includes importing matplotlib) and
the best of --repeats further calls. Prints the simulation's wall time beside it, the size of
each PNG and the machine's CPU.
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from mjrft.app import metadata, report, simulate  # noqa: E402
from mjrft.field.granular_field import GranularField  # noqa: E402


@dataclass
class Run:
    """A simulated model as `mjrft run` hands it to plot_run."""

    rec: simulate.Recording  #: read back from the CSV
    surface_z: float  #: free-surface height [m]
    title: str  #: as `mjrft run` titles its figures
    wall_s: float  #: the simulation's wall time [s]


def simulate_to_csv(name: str, duration: float, folder: Path) -> Run:
    """Simulate models/<name>.xml for `duration` s, streaming its rows to a CSV in `folder`."""
    model = simulate.load_model(ROOT / "models" / f"{name}.xml")
    fld = GranularField(model)
    columns = simulate.new_recording(model, fld).columns
    sink = simulate.CsvSink(folder / f"{name}.csv", columns)
    rec = simulate.Recording(columns, [b.name for b in fld.bodies], sink=sink)
    t0 = time.perf_counter()
    simulate.run(model, duration, fld=fld, recording=rec)
    wall = time.perf_counter() - t0
    sink.close()
    plots = simulate.Recording.from_csv(sink.path, rec.body_names)
    title = f"{name}.xml: {fld.scene.material.name}, {fld.n_elements} triangles"
    return Run(plots, fld.surface_z, title, wall)


def time_plots(run: Run, folder: Path, repeats: int) -> tuple[float, float, list]:
    """(first call [s], best of `repeats` more [s], PNG (width, height) [px]) of plot_run."""
    from PIL import Image

    times = []
    for _ in range(1 + repeats):
        t0 = time.perf_counter()
        paths = report.plot_run(run.rec, run.surface_z, folder, title=run.title)
        times.append(time.perf_counter() - t0)
    sizes = [Image.open(p).size for p in paths]
    return times[0], min(times[1:], default=times[0]), sizes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--durations", type=float, nargs="+", default=[5.0, 19.999])
    ap.add_argument("--repeats", type=int, default=3)
    names = sorted(p.stem for p in (ROOT / "models").glob("*.xml"))
    ap.add_argument("--models", nargs="+", default=names)
    args = ap.parse_args()
    print(f"CPU: {metadata.machine()['cpu'] or 'unknown'}; Python {platform.python_version()}")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.models:
            for duration in args.durations:
                folder = Path(tmp) / f"{name}_{duration:g}"
                run = simulate_to_csv(name, duration, Path(tmp))
                first, best, sizes = time_plots(run, folder, args.repeats)
                px = " ".join(f"{w}x{h}" for w, h in sizes)
                print(
                    f"{name:20s} {duration:7.3f} s, {len(run.rec.rows):6d} rows, "
                    f"{len(run.rec.body_names)} bodies: simulation {run.wall_s:5.2f} s, "
                    f"plot_run first {first:5.2f} s, best {best:5.2f} s; PNGs {px}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
