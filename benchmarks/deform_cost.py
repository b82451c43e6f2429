"""Cost of the deforming ground against the same scene on pristine ground, back to back.

Run: python benchmarks/deform_cost.py [--scenes hexapod go2 wheel] [--seconds 10]
         [--cells 0.005 0.002] [--every 1 10] [--travel 0.25 1] [--frozen] [--repeats 3]
         [--baseline TREE --baseline-library LIB]
Scenes: ``hexapod`` (hexapod_sand, the 1 Hz alternating tripod), ``go2`` (models/go2_sand.xml
from its home keyframe, ``go2_sand.trot_ctrl``'s open-loop trot), ``go2_stand`` (the same
robot standing, its home ctrl held) and ``wheel``
(models/wheel_rig.xml at slip 0.3, one 15 cm pass, 1500 triangles), each on the pristine surface
and on deforming ground per cell [m] and per mjrft:deform_every (and per mjrft:deform_travel
[cells] with ``--travel``; the wheel rig updates at every step); ``--frozen`` adds, per cell,
ground that follows the intruders only at its first update (deform_every 1e8: the force pass
looks the grid up at every step, nothing else changes). The cases of a scene run interleaved,
repeat by repeat, so a busy machine slows them alike; medians of the wall time, its ratio to
the pristine run, and the ground's counters: volume drift relative to the volume cut, the share
of updates whose relaxation met its work budget, pair visits per update. Writes
benchmarks/results/deform_cost.csv. ``--baseline``: every case runs in its own process, once with
this checkout and once with the checkout TREE (its ``mjrft`` package) and its built engine LIB,
alternating, so two versions of the engine are compared on one busy machine.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

OUT = Path(__file__).resolve().parent / "results" / "deform_cost.csv"
#: Default cells [m] per scene: 5 mm and the cell deform_cell="auto" picks for its intruders
#: (mjrft.core.soil.auto_cell: the hexapod's feet 1.5 mm, the Go2's calves 2.2 mm, the wheel's
#: width 3 mm).
CELLS = {
    "hexapod": (0.005, 0.0015),
    "go2": (0.005, 0.0022),
    "go2_stand": (0.005, 0.0022),
    "wheel": (0.005, 0.003),
}
FROZEN = 10**8  # deform_every that never updates again after the first update
#: The Go2's medium [m] (xmin ymin zmin xmax ymax zmax): its open-loop trot covers about 1 m
#: in 4 s (leaving a smaller region it falls), and its calves reach 0.3 m deep on deforming
#: ground at a 5 mm cell.
GO2_REGION = [-0.5, -0.6, -0.6, 1.5, 0.6, 0.05]
WHEEL_SLIP, WHEEL_LENGTH, WHEEL_TRIANGLES = 0.3, 0.15, 1500


def _counters(field, data) -> dict:
    """The ground's counters as benchmark columns."""
    soil = field.soil(data)
    c = soil.counters
    return {"updates": c["updates"],
            "volume_drift": abs(soil.volume()) / c["excavated"] if c["excavated"] else 0.0,
            "unrelaxed_share": c["unrelaxed"] / max(c["updates"], 1.0),
            "visits_per_update": c.get("visits", math.nan) / max(c["updates"], 1.0)}  # fmt: skip


def rule_options(cell: float | None, every: float) -> dict:
    """The scene options of an update rule: every >= 1, deform_every [steps]; else
    deform_travel = -every [cells] (the cases' encoding); nothing on the pristine surface."""
    if not cell:
        return {}
    return {"deform_every": int(every)} if every >= 1 else {"deform_travel": -every}


def hexapod(cell: float | None, every: float, seconds: float) -> dict:
    """The hexapod's tripod walk for seconds [s] of simulated time."""
    from mjrft.envs import hexapod_sand

    env = hexapod_sand.make(seed=0, time_limit=math.inf, deform_cell=cell,
                            **rule_options(cell, every))  # fmt: skip
    try:
        env.reset()
        action = np.array([1.0, math.pi])
        n = round(seconds / env.control_timestep())
        t0 = time.perf_counter()
        for _ in range(n):
            env.step(action)
        row = {"wall_s": time.perf_counter() - t0, "x_m": float(env.physics.data.qpos[0])}
        if cell:
            row.update(_counters(env.physics.field, env.physics.data.ptr))
        return row
    finally:
        env.close()


def go2(cell: float | None, every: float, seconds: float, trot: bool = True) -> dict:
    """The Go2's open-loop trot (trot False: its home ctrl held) from its home keyframe for
    seconds [s] of simulated time."""
    from mjrft.envs import go2_sand

    import mjrft

    options = mjrft.SceneOptions(deform_cell=cell, **rule_options(cell, every))
    spec = go2_sand.build_spec()
    spec.add_numeric(name="mjrft:region", data=GO2_REGION)  # both cases, the same scene
    model = mjrft.load_model(spec, options)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    substeps = round(0.02 / model.opt.timestep)
    t0 = time.perf_counter()
    for _ in range(round(seconds / 0.02)):
        if trot:
            data.ctrl[:] = go2_sand.trot_ctrl(data.time)
        mujoco.mj_step(model, data, substeps)
    row = {"wall_s": time.perf_counter() - t0, "x_m": float(data.qpos[0])}
    if cell:
        row.update(_counters(mjrft.GranularField(model), data))
    return row


def wheel(cell: float | None, every: float, seconds: float) -> dict:
    """One pass of the wheel rig (its length, not seconds, sets the duration)."""
    from mjrft.app import wheel as rig

    if every != 1:
        raise ValueError("the wheel rig updates its ground at every step (--every 1)")
    t0 = time.perf_counter()
    p = rig.run(WHEEL_SLIP, deform_cell=cell or 0.0, length=WHEEL_LENGTH,
                n_triangles=WHEEL_TRIANGLES)[0]  # fmt: skip
    return {"wall_s": time.perf_counter() - t0, "x_m": p.sinkage}


def go2_stand(cell: float | None, every: float, seconds: float) -> dict:
    """The Go2 standing: its home keyframe's ctrl held for seconds [s] of simulated time."""
    return go2(cell, every, seconds, trot=False)


SCENES = {"hexapod": hexapod, "go2": go2, "go2_stand": go2_stand, "wheel": wheel}


def cases(scene: str, cells: list[float] | None, everys: list[int], travels: list[float],
          frozen: bool) -> list:  # fmt: skip
    """(cell or None for pristine, rule) of one scene; rule: deform_every, or -deform_travel."""
    out = [(None, 1)]
    for cell in cells or CELLS[scene]:
        rules = [*everys, *(-t for t in travels if t > 0)] if scene != "wheel" else [1]
        out += [(cell, e) for e in rules]
        if frozen and scene != "wheel":
            out.append((cell, FROZEN))
    return out


#: Run in a child process: import mjrft from the checkout in argv[1] ("-": as installed; else
#: without the editable-install finder, its envs/ and models/ folders as mjrft.envs and
#: mjrft.models, as the wheel installs them), run one case (argv[3:]: scene, cell, every,
#: seconds) and print its row.
_CHILD = """
import importlib.util, json, sys, warnings
from pathlib import Path
warnings.simplefilter("ignore")
if sys.argv[1] != "-":
    tree = Path(sys.argv[1])
    sys.meta_path = [f for f in sys.meta_path if "skbc" not in type(f).__module__]
    sys.path.insert(0, str(tree))
    import mjrft
    for sub in ("envs", "models"):
        spec = importlib.util.spec_from_file_location("mjrft." + sub, tree / sub / "__init__.py",
                                                      submodule_search_locations=[str(tree / sub)])
        module = importlib.util.module_from_spec(spec)
        sys.modules["mjrft." + sub] = module
        setattr(mjrft, sub, module)
        spec.loader.exec_module(module)
sys.path.insert(0, sys.argv[2])
import deform_cost as dc
scene, (cell, every, seconds) = sys.argv[3], map(float, sys.argv[4:7])
print(json.dumps(dc.SCENES[scene](cell or None, every, seconds)))
"""


def in_process(tree: Path | None, library: str | None, scene: str, cell, every: float,
               seconds: float):  # fmt: skip
    """One case in a child process importing mjrft from checkout tree with engine library
    (tree None: this checkout, as installed)."""
    env = dict(os.environ)
    if library:
        env["MJRFT_ENGINE_LIBRARY"] = library
    here = str(Path(__file__).resolve().parent)
    args = [sys.executable, "-c", _CHILD, str(tree) if tree else "-", here, scene,
            str(cell or 0.0), str(every), str(seconds)]  # fmt: skip
    out = subprocess.run(args, env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def report(row: dict, cell, every: float) -> None:
    """Prints one row."""
    rule = f"every {every:g}" if every >= 1 else f"travel {-every:g} cells"
    label = "pristine" if cell is None else f"{cell * 1e3:g} mm, {rule}"
    extra = (f", drift {row['volume_drift']:.1e}, budget met at {row['unrelaxed_share']:.1%} "
             f"of updates, {row['visits_per_update']:.0f} visits/update"
             if "volume_drift" in row else "")  # fmt: skip
    print(f"{row['version']}: {row['scene']} {label}: {row['wall_s']:.3f} s "
          f"({row['vs_pristine']:.2f}x){extra}", flush=True)  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", choices=sorted(SCENES), default=sorted(SCENES))
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated time per walk [s]")
    ap.add_argument("--cells", type=float, nargs="+", help="cells [m] (default: per scene)")
    ap.add_argument("--every", type=int, nargs="+", default=[1], help="mjrft:deform_every")
    ap.add_argument("--travel", type=float, nargs="+", default=[], help="mjrft:deform_travel")
    ap.add_argument("--frozen", action="store_true", help="add never-updated ground per cell")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--baseline", type=Path, help="another checkout to compare, case by case")
    ap.add_argument("--baseline-library", help="its built engine (libmjrft_granular.so)")
    args = ap.parse_args()
    if args.baseline and not args.baseline_library:
        ap.error("--baseline needs --baseline-library (the engine built from that checkout)")
    versions = [("this", None)] + ([("baseline", args.baseline)] if args.baseline else [])
    rows = []
    for scene in args.scenes:
        todo = cases(scene, args.cells, args.every, args.travel, args.frozen)
        runs = {(v, c): [] for v, _ in versions for c in todo}
        for _ in range(args.repeats):
            for cell, every in todo:
                for version, tree in versions:
                    if args.baseline:
                        lib = args.baseline_library if tree else None
                        row = in_process(tree, lib, scene, cell, every, args.seconds)
                    else:
                        row = SCENES[scene](cell, every, args.seconds)
                    runs[(version, (cell, every))].append(row)
        for version, _ in versions:
            base = statistics.median(r["wall_s"] for r in runs[(version, todo[0])])
            for cell, every in todo:
                rs = runs[(version, (cell, every))]
                wall = statistics.median(r["wall_s"] for r in rs)
                row = {"version": version, "scene": scene, "cell_m": cell or 0.0,
                       "every": every if every >= 1 else "", "travel": -every if every < 0 else "",
                       **rs[0], "wall_s": wall, "vs_pristine": wall / base}  # fmt: skip
                rows.append(row)
                report(row, cell, every)
    OUT.parent.mkdir(exist_ok=True)
    keys = ["version", "scene", "cell_m", "every", "travel", "wall_s", "vs_pristine", "x_m",
            "volume_drift", "unrelaxed_share", "visits_per_update", "updates"]  # fmt: skip
    with OUT.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows({k: r.get(k, "") for k in keys} for r in rows)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
