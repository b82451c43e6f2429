"""The Go2-class quadruped (models/go2_sand.xml) on sand against the same robot on a plain floor.

Run: python benchmarks/quadruped.py [--duration 3] [--repeats 5] [--triangles N ...]
     python benchmarks/quadruped.py --keyframe      (the model's "home" keyframe: prints it)
     python benchmarks/quadruped.py --zeta-table    (docs/choosing_zeta.md's table: prints it)
     python benchmarks/quadruped.py --force-models  (docs/models.md: each force model's stance
                                                     depth and trot)
     python benchmarks/quadruped.py --thighs        (docs/environments.md: the trot with the
                                                     thighs tagged too)

Cost: for standing (home ctrl held) and trotting (``mjrft.envs.go2_sand.trot_ctrl``), steps the
robot for --duration s on the medium (the engine plugin, ``mjrft.load_model``; the model's own
RFT resolution, and each --triangles count per tagged primitive) and, back to back in the same
process, the same robot compiled without the field on a plane with MuJoCo's contacts (its feet
set on the plane). Prints the wall time per step, the median over --repeats runs with the cases
interleaved, and its ratio to the plain floor's in the same repeat (median of the ratios), with
what each run did: the torso's drift while standing [mm], the trot's forward distance [m] and
the torso's largest tilt [deg]. Writes results/quadruped.csv.

--keyframe sets the robot down with its feet on the surface (the home pose and ctrl, Euler at
the model's 2 ms), waits 6 s until it rests, starts a new MjData at rest there and waits 3 s
more (a new MjData's first step feels no RFT yet, so it re-settles once), and prints the qpos
the keyframe holds.
"""

from __future__ import annotations

import argparse
import csv
import math
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from mjrft.envs import go2_sand  # noqa: E402

import mjrft  # noqa: E402
from mjrft.app import metadata  # noqa: E402

MODEL = ROOT / "models" / "go2_sand.xml"
OUT = Path(__file__).resolve().parent / "results"
FOOT_RADIUS = 0.022
GAITS = ("stand", "trot")


def sand(triangles: int | None) -> mujoco.MjModel:
    """The model with the field (its own resolution, or ``triangles`` per tagged primitive)."""
    return mjrft.load_model(str(MODEL), n_triangles=triangles)


def floor() -> mujoco.MjModel:
    """The same robot without the field, on a plane at z = 0 with MuJoCo's contacts."""
    spec = go2_sand.plain_spec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5.0, 5.0, 0.1])
    return spec.compile()


def start(model: mujoco.MjModel, on_floor: bool) -> mujoco.MjData:
    """MjData at the home keyframe; on the floor raised so that the lowest foot touches it."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    if on_floor:
        mujoco.mj_kinematics(model, data)
        feet = [model.geom(f"{leg}_foot").id for leg in go2_sand.LEGS]
        data.qpos[2] -= data.geom_xpos[feet, 2].min() - FOOT_RADIUS
        mujoco.mj_forward(model, data)
    return data


def run(model: mujoco.MjModel, data: mujoco.MjData, gait: str, duration: float):
    """Steps for duration [s]; returns (seconds per step, drift [mm] while standing or forward
    distance [m] trotting, largest torso tilt [deg])."""
    n = round(duration / model.opt.timestep)
    start_xyz = data.qpos[:3].copy()
    lowest_up = 1.0
    t0 = time.perf_counter()
    for _ in range(n):
        if gait == "trot":
            data.ctrl[:] = go2_sand.trot_ctrl(data.time)
        mujoco.mj_step(model, data)
        lowest_up = min(lowest_up, data.xmat[1][8])
    per_step = (time.perf_counter() - t0) / n
    moved = data.qpos[:3] - start_xyz
    what = 1e3 * float(np.abs(moved).max()) if gait == "stand" else float(moved[0])
    return per_step, what, math.degrees(math.acos(min(1.0, lowest_up)))


def cost(duration: float, repeats: int, triangle_counts: list[int]) -> list[dict]:
    cases = [("floor", None)] + [("sand", None)] + [("sand", n) for n in triangle_counts]
    models = {case: floor() if case[0] == "floor" else sand(case[1]) for case in cases}
    times = {(c, g): [] for c in cases for g in GAITS}
    ratios = {(c, g): [] for c in cases for g in GAITS}
    seen = {}
    for _ in range(repeats):
        for gait in GAITS:
            for case in cases:  # interleaved: every case under the same load
                model = models[case]
                per_step, what, tilt = run(model, start(model, case[0] == "floor"), gait, duration)
                times[case, gait].append(per_step)
                seen[case, gait] = (what, tilt)
            for case in cases:
                ratios[case, gait].append(times[case, gait][-1] / times[cases[0], gait][-1])
    rows = []
    for gait in GAITS:
        for case in cases:
            model = models[case]
            fld = mjrft.GranularField(model) if case[0] == "sand" else None
            what, tilt = seen[case, gait]
            rows.append({
                "gait": gait,
                "ground": case[0],
                "triangles": sum(len(b.centroids) for b in fld.bodies) if fld else 0,
                "us_per_step": 1e6 * float(np.median(times[case, gait])),
                "ratio_to_floor": float(np.median(ratios[case, gait])),
                "drift_mm_or_forward_m": what,
                "max_tilt_deg": tilt,
            })  # fmt: skip
    return rows


def set_down(model: mujoco.MjModel) -> mujoco.MjData:
    """The robot in its home pose with its feet on the surface and the home ctrl held, at rest,
    let go: 6 s later it rests on the medium."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    data.qpos[7:] = go2_sand.HOME_CTRL
    mujoco.mj_kinematics(model, data)
    feet = [model.geom(f"{leg}_foot").id for leg in go2_sand.LEGS]
    data.qpos[2] -= data.geom_xpos[feet, 2].min() - FOOT_RADIUS  # feet on the surface
    data.ctrl[:] = go2_sand.HOME_CTRL
    for _ in range(round(6.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    return data


def force_models() -> None:
    """Set down and trotting under each force model: feet depth at rest, then 6 s of trot."""
    base = mjrft.Material.generic(2e6)
    media = {
        "treers2021": base,
        "agarwal3d": base.with_model("agarwal3d"),
        "treers2021 + dynamic": base.with_dynamic(1500.0),
    }
    feet_names = [f"{leg}_foot" for leg in go2_sand.LEGS]
    for name, material in media.items():
        model = mjrft.load_model(str(MODEL), material=material)
        data = set_down(model)
        feet = [model.geom(f).id for f in feet_names]
        depth = -(data.geom_xpos[feet, 2] - FOOT_RADIUS)
        data.time = 0.0
        x0 = data.qpos[0]
        lowest_up, deepest = 1.0, 0.0
        for _ in range(round(6.0 / model.opt.timestep)):
            data.ctrl[:] = go2_sand.trot_ctrl(data.time)
            mujoco.mj_step(model, data)
            lowest_up = min(lowest_up, data.xmat[1][8])
            deepest = max(deepest, float(-(data.geom_xpos[feet, 2] - FOOT_RADIUS).min()))
        tilt = math.degrees(math.acos(min(1.0, lowest_up)))
        print(f"{name:22} at rest feet {100 * depth.min():.1f}-{100 * depth.max():.1f} cm deep; "
              f"trot: {data.qpos[0] - x0:.2f} m in 6 s, tilt <= {tilt:.1f} deg")  # fmt: skip


def thighs() -> None:
    """The trot (6 s from the home keyframe) with the calves' subtrees tagged, as the model is,
    and with the thighs' subtrees tagged as well (their boxes at the model's 100 triangles):
    how deep the thighs' boxes reach into the medium, the walk, the tilt and the triangles."""
    for tag in (False, True):
        spec = go2_sand.build_spec()
        if tag:
            (names,) = [x for x in spec.texts if x.name == "mjrft:intruders_subtree"]
            names.data = " ".join(f"{leg}_thigh" for leg in go2_sand.LEGS)
        model = mjrft.load_model(spec, watch_sinking=False)
        data = start(model, False)
        boxes = [model.geom(f"{leg}_thigh").id for leg in go2_sand.LEGS]
        x0, lowest_up, deepest = data.qpos[0], 1.0, 0.0
        for _ in range(round(6.0 / model.opt.timestep)):
            data.ctrl[:] = go2_sand.trot_ctrl(data.time)
            mujoco.mj_step(model, data)
            lowest_up = min(lowest_up, data.xmat[1][8])
            for g in boxes:  # the box's lowest corner below the surface at z = 0
                low = data.geom_xpos[g, 2] - np.abs(data.geom_xmat[g, 6:9]) @ model.geom_size[g]
                deepest = max(deepest, -float(low))
        tilt = math.degrees(math.acos(min(1.0, lowest_up)))
        case = "thighs tagged" if tag else "calves tagged"
        triangles = sum(len(b.areas) for b in mjrft.GranularField(model).bodies)
        print(f"{case:14} {triangles} triangles; thighs reach {100 * deepest:.1f} cm deep; trot: "
              f"{data.qpos[0] - x0:.3f} m in 6 s, tilt <= {tilt:.1f} deg")  # fmt: skip


def keyframe() -> None:
    model = sand(None)
    data = set_down(model)
    # Started again at rest from that pose (as a keyframe starts), a new MjData re-settles once
    # (3.7 mm: its first step feels no RFT yet); from there on a restart moves 0.016 mm.
    again = mujoco.MjData(model)
    again.qpos[:], again.ctrl[:] = data.qpos, data.ctrl
    for _ in range(round(3.0 / model.opt.timestep)):
        mujoco.mj_step(model, again)
    print(f"at rest: largest |qvel| {np.abs(again.qvel).max():.2g}")
    qpos = again.qpos.copy()
    qpos[0:2] = 0.0
    print("qpos:", " ".join(f"{v:.6g}" for v in qpos))


def zeta_table() -> None:
    sys.path.insert(0, str(ROOT / "tests"))
    from test_choosing_zeta import drop_depth, plate_force, sphere_force, static_depth

    g = 9.81
    robots = [
        ("0.5 kg quadruped, 1 cm sphere feet", 0.5, 4, "sphere", 0.01),
        ("3 kg hexapod, 1.5 cm sphere feet, 3 on the ground", 3.0, 3, "sphere", 0.015),
        ("15.2 kg Go2, 2.2 cm sphere feet", 15.2064, 4, "sphere", 0.022),
        ("50 kg quadruped, 3 cm sphere feet", 50.0, 4, "sphere", 0.03),
        ("50 kg quadruped, 10 x 10 cm flat feet", 50.0, 4, "plate", 0.01),
        ("70 kg biped, 10 x 25 cm flat feet, one on the ground", 70.0, 1, "plate", 0.025),
    ]
    for name, mass, feet, kind, size in robots:
        weight = mass * g / feet

        def force(d, zeta, kind=kind, size=size):
            return sphere_force(d, size, zeta) if kind == "sphere" else plate_force(d, size, zeta)

        depths = [
            f"{100 * static_depth(lambda d, z=z: force(d, z), weight):.1f} "
            f"({100 * drop_depth(lambda d, z=z: force(d, z), weight):.1f})"
            for z in (0.33e6, 1e6, 2e6, 5e6)
        ]
        zetas = [f"{weight / force(d, 1.0) / 1e6:.2g}" for d in (0.01, 0.02, 0.03)]
        print(f"| {name} | {weight:.1f} | " + " | ".join(depths + zetas) + " |")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--duration", type=float, default=3.0, help="seconds simulated per run")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--triangles", type=int, nargs="*", default=[],
                   help="also these triangle counts per tagged primitive")  # fmt: skip
    p.add_argument("--keyframe", action="store_true", help="print the home keyframe's qpos")
    p.add_argument("--zeta-table", action="store_true", help="print docs/choosing_zeta.md's table")
    p.add_argument("--force-models", action="store_true",
                   help="set down and trot under each force model (docs/models.md)")  # fmt: skip
    p.add_argument("--thighs", action="store_true",
                   help="the trot with the thighs tagged too (docs/environments.md)")  # fmt: skip
    args = p.parse_args(argv)
    if args.keyframe:
        return keyframe()
    if args.zeta_table:
        return zeta_table()
    if args.force_models:
        return force_models()
    if args.thighs:
        return thighs()
    rows = cost(args.duration, args.repeats, args.triangles)
    cpu = metadata.machine()["cpu"] or platform.machine()
    print(f"{cpu}; mujoco {mujoco.__version__}; {args.duration} s per run, {args.repeats} repeats")
    print(f"{'gait':6} {'ground':6} {'triangles':>9} {'us/step':>8} {'x floor':>8} "
          f"{'drift mm / forward m':>21} {'tilt deg':>8}")  # fmt: skip
    for r in rows:
        print(f"{r['gait']:6} {r['ground']:6} {r['triangles']:9d} {r['us_per_step']:8.1f} "
              f"{r['ratio_to_floor']:8.2f} {r['drift_mm_or_forward_m']:21.4f} "
              f"{r['max_tilt_deg']:8.2f}")  # fmt: skip
    OUT.mkdir(exist_ok=True)
    with open(OUT / "quadruped.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main()
