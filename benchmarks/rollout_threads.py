"""Thread scaling of the engine plugin under mujoco.rollout: C threads, one MjData each.

Run: python benchmarks/rollout_threads.py [--rollouts 8] [--steps 2000] [--repeats 5]
The hexapod standing in glass beads (models/hexapod_sand.xml at its keyframe) and a dropped
sphere (models/sphere_drop.xml), each as `rollouts` rollouts of `steps` steps from slightly
different states, with nthread = 1 and nthread = 2 (and more where the machine has the cores),
alternating; medians of the wall time. Prints physics steps per second summed over rollouts and
the speed-up over one thread; writes benchmarks/results/rollout_threads.csv.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

import mjrft
from mjrft.app.simulate import resolve_model

OUT = Path(__file__).resolve().parent / "results" / "rollout_threads.csv"


def states(model: mujoco.MjModel, n: int) -> np.ndarray:
    """n full physics states near keyframe 0 (qvel perturbed by a seeded 1 mm/s)."""
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = np.zeros((n, mujoco.mj_stateSize(model, spec)))
    rng = np.random.default_rng(0)
    for i in range(n):
        d = mujoco.MjData(model)
        if model.nkey:
            mujoco.mj_resetDataKeyframe(model, d, 0)
        d.qvel[:] += rng.normal(0.0, 1e-3, model.nv)
        mujoco.mj_getState(model, d, out[i], spec)
    return out


def timed(model, initial, steps: int, nthread: int) -> float:
    datas = [mujoco.MjData(model) for _ in range(nthread)]
    ctrl = model.key_ctrl[0] if model.nkey else np.zeros(model.nu)
    control = np.tile(ctrl, (len(initial), steps, 1))
    t0 = time.perf_counter()
    rollout.rollout(model, datas, initial, control, nstep=steps)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rollouts", type=int, default=8)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    threads = sorted({1, 2, os.cpu_count() or 1})
    rows = []
    for name in ("hexapod_sand", "sphere_drop"):
        model = mjrft.load_model(resolve_model(name))
        initial = states(model, args.rollouts)
        timed(model, initial, 10, 1)  # first touches
        walls = {n: [] for n in threads}
        for _ in range(args.repeats):
            for n in threads:
                walls[n].append(timed(model, initial, args.steps, n))
        base = statistics.median(walls[1])
        for n in threads:
            wall = statistics.median(walls[n])
            rate = args.rollouts * args.steps / wall
            rows.append({"scene": name, "nthread": n, "wall_s": wall, "steps_per_s": rate,
                         "speedup": base / wall})  # fmt: skip
            print(f"{name:14s} nthread {n:2d}: {rate:10.0f} steps/s, {base / wall:4.2f}x")
    OUT.parent.mkdir(exist_ok=True)
    with OUT.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
