"""Batched stepping throughput: sim-steps per second vs number of copies (ellipsoid rig).

Run: python benchmarks/batch.py [--triangles N] [--steps K]
Compares, at each number of copies, mjrft.batch.BatchedField (MuJoCo's threaded batch; the
engine plugin acts inside each copy's step) with a Python loop of mj_step over single MjData of
the same model. Copies start from keyframe 0 with different crank speeds and advance past
t = 4 s first so the ellipsoid is in the medium. Writes benchmarks/results/batch.csv.
"""

from __future__ import annotations

import argparse
import csv
import os
import time
from pathlib import Path

import mujoco
import numpy as np

from mjrft import simulate
from mjrft.batch import BatchedField
from mjrft.field import GranularField

OUT = Path(__file__).resolve().parent / "results"
MODEL = Path(__file__).resolve().parents[1] / "models" / "ellipsoid_pitch.xml"
T_IN_MEDIUM = 4.0  # s
COPIES = (1, 4, 16, 64, 256)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=2000)
    ap.add_argument("--steps", type=int, default=200)
    args = ap.parse_args()
    OUT.mkdir(exist_ok=True)
    model = simulate.load_model(MODEL, n_triangles=args.triangles)
    fld = GranularField(model)
    crank = model.actuator("crank").id
    warm = round(T_IN_MEDIUM / model.opt.timestep)
    rows = []
    print(f"{fld.n_elements} triangles, dt = {model.opt.timestep} s, {os.cpu_count()} cores")
    for n in COPIES:
        bf = BatchedField(fld, nsim=n)
        bf.reset(keyframe=np.zeros(n, dtype=int))
        bf.batch.bind("ctrl")[:, crank] *= np.linspace(0.8, 1.2, n)
        bf.step(warm)
        t0 = time.perf_counter()
        bf.step(args.steps)
        t_batch = time.perf_counter() - t0
        datas = []
        for i in range(n):
            d = mujoco.MjData(model)
            for f in ("time", "qpos", "qvel", "act", "ctrl", "qacc_warmstart", "plugin_state"):
                v = bf.batch.bind(f)[i]
                if f == "time":
                    d.time = float(v)
                else:
                    getattr(d, f)[:] = v
            datas.append(d)
        for d in datas:
            mujoco.mj_step(model, d)  # one untimed step, as the batch had its warm-up
        t0 = time.perf_counter()
        for _ in range(args.steps):
            for d in datas:
                mujoco.mj_step(model, d)
        t_loop = time.perf_counter() - t0
        rows.append(
            {
                "copies": n,
                "batch_steps_per_s": n * args.steps / t_batch,
                "loop_steps_per_s": n * args.steps / t_loop,
                "ratio": t_loop / t_batch,
            }
        )
        r = rows[-1]
        print(
            f"  {n:4d} copies: batched {r['batch_steps_per_s']:9.0f} sim-steps/s, Python loop "
            f"of mj_step {r['loop_steps_per_s']:9.0f}; ratio {r['ratio']:.2f}"
        )
    with open(OUT / "batch.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
