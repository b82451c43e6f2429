"""Sweep the hexapod's gait frequency and plot forward speed vs frequency.

    python scripts/hexapod_frequency_sweep.py [--out docs/hexapod_speed_vs_frequency.png]
        [--frequencies 0.25 0.5 ...] [--cycles 3] [--materials glass_beads poppy_seeds_lp]

For each medium and frequency f [Hz] it resets ``envs.load("hexapod_sand", seed=0)``, walks the
alternating tripod gait (tripod B half a turn behind A) for a transient of max(1 s, one cycle),
then measures the torso's forward (world x) speed over ``--cycles`` gait cycles
(``envs.hexapod_sand.forward_speed``). Prints a table (speed and distance per cycle) and writes
the figure. The trend to compare with Li, Zhang & Goldman, Science 339:1408 (2013), Fig. 4:
speed rises with leg frequency at low frequency (quasi-static regime: about constant distance per
cycle). About a minute on a 2-core machine with the defaults.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mjrft.envs import hexapod_sand  # noqa: E402

DEFAULT_FREQUENCIES = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0)
DEFAULT_MATERIALS = ("glass_beads", "poppy_seeds_lp")


def sweep(frequencies: list[float], material: str, cycles: float) -> np.ndarray:
    """Forward speeds [m/s] at each frequency [Hz] on one medium."""
    env = hexapod_sand.make(seed=0, time_limit=float("inf"), material=material)
    try:
        return np.array(
            [hexapod_sand.forward_speed(f, env=env, cycles=cycles) for f in frequencies]
        )
    finally:
        env.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--out", type=Path, default=ROOT / "docs" / "hexapod_speed_vs_frequency.png"
    )
    parser.add_argument("--frequencies", type=float, nargs="+", default=DEFAULT_FREQUENCIES)
    parser.add_argument("--cycles", type=float, default=3.0, help="gait cycles measured")
    parser.add_argument("--materials", nargs="+", default=DEFAULT_MATERIALS)
    args = parser.parse_args(argv)
    freqs = sorted(args.frequencies)
    results = {}
    for mat in args.materials:
        t0 = time.perf_counter()
        results[mat] = sweep(freqs, mat, args.cycles)
        print(f"{mat}: {time.perf_counter() - t0:.1f} s wall", file=sys.stderr)

    header = "f [Hz] | " + " | ".join(f"{m} v [cm/s], per cycle [cm]" for m in results)
    print(header)
    print("-" * len(header))
    for i, f in enumerate(freqs):
        cells = [f"{100 * v[i]:7.2f}, {100 * v[i] / f:6.2f}" for v in results.values()]
        print(f"{f:6.2f} | " + " | ".join(cells))

    fig, (ax_v, ax_s) = plt.subplots(1, 2, figsize=(10, 4.2))
    for mat, v in results.items():
        ax_v.plot(freqs, 100 * v, "o-", label=mat)
        ax_s.plot(freqs, 100 * v / np.array(freqs), "o-", label=mat)
    ax_v.set(xlabel="leg (gait) frequency f [Hz]", ylabel="forward speed [cm/s]")
    ax_v.set_title("C-leg hexapod on granular media (RFT)")
    ax_s.set(xlabel="leg (gait) frequency f [Hz]", ylabel="distance per gait cycle [cm]")
    ax_s.set_ylim(bottom=0)
    ax_s.set_title("stride: speed / f")
    for ax in (ax_v, ax_s):
        ax.set_xlim(left=0)
        ax.grid(alpha=0.3)
        ax.legend()
    ax_v.set_ylim(bottom=0)
    fig.text(
        0.01,
        0.01,
        "envs.load('hexapod_sand'): 0.30 kg, six 4 cm C-legs, alternating tripod; "
        f"speed over {args.cycles:g} cycles after a transient of max(1 s, 1 cycle)",
        fontsize=7,
    )
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
