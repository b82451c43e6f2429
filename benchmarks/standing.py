"""A robot standing on sand: the hexapod held in its stance by its hip servos, left for 10 s.

Run: python benchmarks/standing.py [--duration 10] [--timesteps 0.5 1 2] [--low-speed stick free]
     [--walk 0.5 1 2 3] [--repeats 5]
For each low-speed mode, timestep [ms] and integrator (Euler, implicitfast, RK4), loads
models/hexapod_sand.xml at its keyframe with every hip's gait rate set to zero (ctrl = 0 and
qvel = 0: each intvelocity servo holds its keyframe angle) with the field (the engine plugin,
``mjrft.load_model``) and steps for --duration s. Prints, over the last half of the run: the
torso's horizontal drift and its sinking [mm], the median step-to-step change of the total RFT
vertical force on the robot as a fraction of its weight, the RFT vertical force over the weight
at the end, and the wall time per step (median of --repeats runs, the modes interleaved, with
the median ratio of the first mode's time to each mode's in the same repeat). Writes
results/standing.csv. The numbers the low-speed treatment of mechanisms must hold: drift < 0.1
mm, force change < 1 % of the weight (docs/stability.md, "Mechanisms"). With --walk, also the
alternating-tripod gait at each frequency [Hz] (1 ms, Euler): its forward speed over 3 cycles
after a transient of max(1 s, one cycle), and the wall time per step.
"""

from __future__ import annotations

import argparse
import csv
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import mjrft  # noqa: E402
from mjrft.app import metadata  # noqa: E402
from mjrft.field import GranularField  # noqa: E402

OUT = Path(__file__).resolve().parent / "results"
INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
}


def hexapod(gait_hz: float, timestep: float = 1e-3, integrator: str = "euler", low_speed=None):
    """(model, field, data): the hexapod at its keyframe pose under the low-speed mode low_speed
    (None: the model's), every hip turning at gait_hz [Hz] (0: the gait stopped, each
    intvelocity servo holding its keyframe angle)."""
    model = mjrft.load_model(ROOT / "models" / "hexapod_sand.xml", low_speed=low_speed)
    model.opt.timestep = timestep
    model.opt.integrator = INTEGRATORS[integrator]
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    data.ctrl[:] = 2 * np.pi * gait_hz  # every hip's rate; the keyframe sets the phases
    data.qvel[:] = 0.0
    data.qvel[6:] = 2 * np.pi * gait_hz
    return model, GranularField(model), data


def stand(timestep: float, integrator: str, duration: float, low_speed: str) -> dict:
    """One standing run; the figures over its last half (see the module docstring)."""
    model, fld, data = hexapod(0.0, timestep, integrator, low_speed)
    torso = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "torso")
    weight = float(model.body_subtreemass[torso]) * -model.opt.gravity[2]
    n = round(duration / timestep)
    pos = np.empty((n + 1, 3))
    fz = np.empty(n + 1)
    pos[0] = data.xpos[torso]
    fz[0] = 0.0
    wrench = fld.wrench_of(data)  # a view, updated by every step
    t0 = time.perf_counter()
    for i in range(1, n + 1):
        mujoco.mj_step(model, data)
        pos[i] = data.xpos[torso]
        fz[i] = wrench[fld.body_ids, 2].sum()
    wall = time.perf_counter() - t0
    half = n // 2
    return {
        "low_speed": low_speed,
        "timestep_ms": timestep * 1e3,
        "integrator": integrator,
        "drift_mm": 1e3 * float(np.hypot(*(pos[-1, :2] - pos[half, :2]))),
        "sink_mm": 1e3 * float(pos[half, 2] - pos[-1, 2]),
        "force_change": float(np.median(np.abs(np.diff(fz[half:])))) / weight,
        "fz_over_weight": float(fz[-1]) / weight,
        "us_per_step": 1e6 * wall / n,
    }


def walk(frequency: float, low_speed: str) -> dict:
    """Forward speed [m/s] and wall time per step of the gait at `frequency` [Hz]."""
    model, _, data = hexapod(frequency, low_speed=low_speed)
    dt = model.opt.timestep
    for _ in range(round(max(1.0, 1.0 / frequency) / dt)):
        mujoco.mj_step(model, data)
    x0, n = float(data.qpos[0]), round(3.0 / frequency / dt)
    t0 = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(model, data)
    wall = time.perf_counter() - t0
    return {"speed": (float(data.qpos[0]) - x0) / (n * dt), "us_per_step": 1e6 * wall / n}


def repeated(run, modes: list[str], repeats: int) -> dict[str, dict]:
    """run(mode) for each mode, interleaved, `repeats` times: each mode's result with its median
    wall time per step, and (beside the first mode) the median over repeats of the ratio of the
    first mode's wall time to this mode's, measured in the same repeat."""
    times = {mode: [] for mode in modes}
    out = {}
    for _ in range(repeats):
        for mode in modes:
            out[mode] = run(mode)
            times[mode].append(out[mode]["us_per_step"])
    for mode in modes:
        out[mode]["us_per_step"] = float(np.median(times[mode]))
        ratios = np.array(times[modes[0]]) / np.array(times[mode])
        out[mode]["cost_ratio"] = float(np.median(ratios))
    return out


def ratio_note(first: str, mode: str, r: dict) -> str:
    """' (first/mode 1.23x)' beside every mode but the first."""
    return "" if mode == first else f" ({first}/{mode} {r['cost_ratio']:.2f}x)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--timesteps", type=float, nargs="+", default=[0.5, 1.0, 2.0], help="[ms]")
    ap.add_argument("--low-speed", nargs="+", default=["stick", "free"])
    ap.add_argument("--walk", type=float, nargs="*", default=[], help="gait frequencies [Hz]")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs per cell (median)")
    args = ap.parse_args()
    cpu = metadata.machine()["cpu"] or platform.machine()
    print(f"CPU: {cpu}; Python {platform.python_version()}; medians of {args.repeats} repeats")
    first = args.low_speed[0]
    rows = []
    for dt in args.timesteps:
        for name in INTEGRATORS:
            runs = repeated(
                lambda mode, dt=dt, name=name: stand(dt * 1e-3, name, args.duration, mode),
                args.low_speed, args.repeats,
            )  # fmt: skip
            for mode, r in runs.items():
                rows.append(r)
                print(
                    f"{mode:5s} dt {dt:4g} ms {name:12s}: drift {r['drift_mm']:8.3f} mm, "
                    f"sink {r['sink_mm']:8.3f} mm, force change {100 * r['force_change']:7.3f} "
                    f"% of weight, Fz/weight {r['fz_over_weight']:.4f}, "
                    f"{r['us_per_step']:6.1f} us/step{ratio_note(first, mode, r)}",
                    flush=True,
                )
    for f in args.walk:
        runs = repeated(lambda mode, f=f: walk(f, mode), args.low_speed, args.repeats)
        for mode, r in runs.items():
            print(
                f"walking {f:4g} Hz, {mode:5s}: {100 * r['speed']:8.4f} cm/s, "
                f"{r['us_per_step']:6.1f} us/step{ratio_note(first, mode, r)}",
                flush=True,
            )
    OUT.mkdir(exist_ok=True)
    with open(OUT / "standing.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
