"""Wheel on sand: drawbar pull, wheel torque and sinkage vs slip, fresh ground and own rut.

Run: python benchmarks/wheel_slip.py [--cell 0.005] [--length 0.15] [--triangles 1500]
models/wheel_rig.xml at slips -0.2 to 0.9: on the pristine surface (no memory), and with the
deforming ground (``--cell``) for two passes along the same track (the second in the first's
rut). Means over the second half of each pass (``mjrft.app.wheel``). Writes
benchmarks/results/wheel_slip.csv and docs/wheel_slip.png.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from mjrft.app import wheel

ROOT = Path(__file__).resolve().parents[1]
SLIPS = (-0.2, 0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
N_PER_M, MNM_PER_NM, MM_PER_M = 1.0, 1e3, 1e3


def measure(cell: float, length: float, triangles: int) -> list[dict]:
    """One row per slip and case (fresh; memory pass 1; memory pass 2)."""
    rows = []
    for s in SLIPS:
        t0 = time.perf_counter()
        fresh = wheel.run(s, length=length, n_triangles=triangles)[0]
        t1 = time.perf_counter()
        first, rut = wheel.run(s, deform_cell=cell, length=length, n_triangles=triangles, passes=2)
        t2 = time.perf_counter()
        for case, p, wall in (("fresh, no memory", fresh, t1 - t0),
                              ("memory, first pass", first, (t2 - t1) / 2),
                              ("memory, own rut", rut, (t2 - t1) / 2)):  # fmt: skip
            rows.append({"slip": s, "case": case, "drawbar_pull_N": p.drawbar_pull,
                         "torque_Nm": p.torque, "sinkage_m": p.sinkage,
                         "wall_s": wall})  # fmt: skip
        print(f"slip {s:+.2f}: fresh DP {fresh.drawbar_pull:+.3f} N, torque "
              f"{fresh.torque * MNM_PER_NM:.2f} mN m; rut/first torque "
              f"{rut.torque / first.torque:.3f}; {t2 - t0:.1f} s", flush=True)  # fmt: skip
    return rows


def plot(rows: list[dict], path: Path, title: str) -> None:
    """Three panels vs slip, one line per case."""
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8), constrained_layout=True)
    panels = (("drawbar_pull_N", N_PER_M, "drawbar pull [N]"),
              ("torque_Nm", MNM_PER_NM, "wheel torque [mN m]"),
              ("sinkage_m", MM_PER_M, "sinkage [mm]"))  # fmt: skip
    for case, style in (("fresh, no memory", "k-o"), ("memory, first pass", "C0-s"),
                        ("memory, own rut", "C3--^")):  # fmt: skip
        sel = [r for r in rows if r["case"] == case]
        for ax, (key, scale, label) in zip(axes, panels, strict=True):
            ax.plot([r["slip"] for r in sel], [r[key] * scale for r in sel], style, ms=4,
                    label=case)  # fmt: skip
            ax.set_xlabel("slip s = 1 - v / (omega r)")
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
    axes[0].axhline(0.0, color="0.5", lw=0.8)
    axes[0].legend(loc="upper left", fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cell", type=float, default=0.005, help="deforming ground's cell [m]")
    ap.add_argument("--length", type=float, default=0.15, help="length of each pass [m]")
    ap.add_argument("--triangles", type=int, default=1500, help="triangles on the wheel")
    args = ap.parse_args()
    rows = measure(args.cell, args.length, args.triangles)
    out = ROOT / "benchmarks" / "results" / "wheel_slip.csv"
    out.parent.mkdir(exist_ok=True)
    with out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    title = (f"wheel_rig.xml: r = 5 cm, width 3 cm, load 1.96 N, omega = {wheel.OMEGA:g} rad/s, "
             f"glass beads, {args.triangles} triangles; memory: {args.cell * MM_PER_M:g} mm "
             f"cell; means over the second half of {args.length:g} m passes")  # fmt: skip
    plot(rows, ROOT / "docs" / "wheel_slip.png", title)
    print(f"wrote {out} and docs/wheel_slip.png")


if __name__ == "__main__":
    main()
