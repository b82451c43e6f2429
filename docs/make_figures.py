"""Regenerate the per-rig figures of docs/rigs.md: ``python docs/make_figures.py`` (about 10 s).

Runs every rig in models/ with the granular field for a few simulated seconds at a modest
triangle count (the root rig's mesh keeps its own 2976 triangles) and writes the paper-style
summary (mjrft.report.plot_paper: force and moment vs depth, force vs time, lateral vs vertical
force) to docs/<rig>.png.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from mjrft import simulate  # noqa: E402
from mjrft.app import report  # noqa: E402
from mjrft.field import GranularField  # noqa: E402

#: Triangles per primitive intruder (mesh intruders keep their own).
TRIANGLES = 1500
#: (rig, simulated duration [s], record every this many 1 ms steps, what the run shows).
RIGS = (
    ("plate_rig", 10.0, 10, "plate pitched 30 deg pushed straight down at 1 cm/s"),
    ("ellipsoid_pitch", 12.0, 10, "ellipsoid pitching 9 deg at 0.625 Hz, descending 0.5 cm/s"),
    ("root_circumnutation", 24.0, 10, "root tip tilted 10 deg yawing 15 deg/s, descending"),
    ("sphere_drop", 0.2, 1, "1 cm radius steel sphere released 1 mm above the surface"),
)


def make_figure(name: str, duration: float, record_every: int, caption: str) -> Path:
    """Run one rig and write docs/<name>.png; returns its path."""
    model = simulate.load_model(ROOT / "models" / f"{name}.xml", n_triangles=TRIANGLES)
    fld = GranularField(model)
    _, rec = simulate.run(model, duration, fld=fld, record_every=record_every)
    title = (
        f"models/{name}.xml: {caption}, {duration:g} s "
        f"({fld.n_elements} triangles, {fld.material.name})"
    )
    return report.plot_paper(rec, fld.surface_z, DOCS / f"{name}.png", title=title)


def main() -> None:
    for name, duration, record_every, caption in RIGS:
        t0 = time.perf_counter()
        path = make_figure(name, duration, record_every, caption)
        size_kb = path.stat().st_size / 1e3
        print(f"{path.relative_to(ROOT)}: {size_kb:.0f} kB in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
