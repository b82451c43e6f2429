"""Batched MuJoCo Warp with the granular field (mjrft.warp): physics steps per second vs nworld.

Run: python benchmarks/gpu.py [--device cuda:0] [--nworld 1 16 ...] [--steps N]
For each model (the hexapod standing in the medium, the ellipsoid rig driven into it) and each
nworld: steps per second summed over worlds with the field off ("off"), on as the pure model
("on", low_speed="off") and on with the low-speed treatment ("treated", the MJCF's default
low_speed="stick": free bodies and bodies in mechanisms), and the per-step split (the field's
own pass, `WarpField.passive`, against the step with it); for the hexapod also the treated field
on a deforming ground ("ground": 5 mm cells over 0.6 x 0.4 m; its field time is the step with
it less the step without, since the ground moves once per time) and the vector environment
(`HexapodVecEnv.advance`: gait controller, 20 physics steps with the treated field,
observations and reward on the device), as physics steps per second.

`--standing` instead runs the hexapod standing still (gait stopped) from its keyframe, and a
quadruped of two-joint legs (QUADRUPED) from its initial state, for `--seconds` (default 5) at
dt 1 and 2 ms under Euler and implicitfast, `--nworld` worlds at once, and prints the torso's
drift over the last second and the largest step-to-step change of the total vertical RFT force
over it, as a fraction of the weight (the targets: <= 1e-5 m and <= 1 %); writes
benchmarks/results/gpu_standing.csv.
On a CUDA device each timed loop is one captured CUDA graph of N steps, replayed (the first
replay is discarded); on the CPU device the steps are launched one by one. Every figure is the
median of --repeats timings. Writes benchmarks/results/gpu.csv.

Default nworld: 1 to 16384 by factors of 4 on a GPU, 1 to 16 on the CPU device.
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import time
from pathlib import Path

import mujoco
import numpy as np
import warp as wp

wp.config.quiet = True

import mujoco_warp as mjw  # noqa: E402

wp.config.quiet = True  # (importing MuJoCo Warp turns Warp's per-module messages back on)

from mjrft.app import metadata  # noqa: E402
from mjrft.warp import HexapodVecEnv, WarpField  # noqa: E402

OUT = Path(__file__).resolve().parent / "results"
MODELS = Path(__file__).resolve().parents[1] / "models"
FIELDS = ("model", "nworld", "triangles", "field", "steps_per_s", "step_us", "rft_us", "rft_share")


def initial_state(name: str, mjm: mujoco.MjModel, mjd: mujoco.MjData, nworld: int):
    """(nworld, nq), (nworld, nv): the worlds start in the medium, each a little different."""
    rng = np.random.default_rng(0)
    qpos = np.tile(mjd.qpos, (nworld, 1))
    qvel = np.zeros((nworld, mjm.nv))
    if name == "hexapod_sand":  # torso lowered: the legs stand in the medium
        qpos[:, 2] = 0.03 + 0.002 * rng.uniform(-1, 1, nworld)
    else:
        qvel[:] = 0.1 * rng.normal(size=qvel.shape)
    return qpos, qvel


def timed(device, fn, steps: int, repeats: int) -> float:
    """Median seconds for `steps` calls of fn (one CUDA graph of them on a GPU)."""
    fn()  # loads every kernel module outside a capture
    wp.synchronize_device(device)
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as capture:
            for _ in range(steps):
                fn()
        graph = capture.graph
        wp.capture_launch(graph)  # first replay: not timed
        run = lambda: wp.capture_launch(graph)  # noqa: E731
    else:
        run = lambda: [fn() for _ in range(steps)]  # noqa: E731
    wp.synchronize_device(device)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        run()
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t)
    return float(np.median(times))


#: The deforming ground of the "ground" column: cell [m] over the region (x0 y0 z0 x1 y1 z1) [m].
GROUND_CELL, GROUND_REGION = 0.005, (-0.3, -0.2, -0.1, 0.3, 0.2, 0.05)


def with_ground(name: str) -> mujoco.MjModel:
    """The rig compiled with a deforming ground (mjrft:deform_cell over mjrft:region)."""
    spec = mujoco.MjSpec.from_file(str(MODELS / f"{name}.xml"))
    spec.add_numeric(name="mjrft:region", data=list(GROUND_REGION), size=6)
    spec.add_numeric(name="mjrft:deform_cell", data=[GROUND_CELL], size=1)
    return spec.compile()


def measure(name: str, nworld: int, device, steps: int, repeats: int) -> list[dict]:
    mjm = mujoco.MjModel.from_xml_path(str(MODELS / f"{name}.xml"))
    mjd = mujoco.MjData(mjm)
    if mjm.nkey:
        mujoco.mj_resetDataKeyframe(mjm, mjd, 0)
    fields = {
        "on": WarpField(mjm, low_speed="off", device=str(device)),
        "treated": WarpField(mjm, device=str(device)),
    }
    if name == "hexapod_sand":
        fields["ground"] = WarpField(with_ground(name), device=str(device))
    qpos, qvel = initial_state(name, mjm, mjd, nworld)
    timings, rft = [], {}
    with wp.ScopedDevice(device):
        m = mjw.put_model(mjm)
        d = mjw.put_data(mjm, mjd, nworld=nworld)
        d.qpos.assign(qpos.astype(np.float32))
        d.qvel.assign(qvel.astype(np.float32))
        mjw.forward(m, d)
        timings.append(("off", timed(device, lambda: mjw.step(m, d), steps, repeats)))
        for label, field in fields.items():
            field.prepare(d)
            if label != "ground":  # the ground moves once per time: its pass is timed in steps
                rft[label] = timed(device, lambda f=field: f.passive(m, d), steps, repeats)
            with field.installed(m, d):
                timings.append((label, timed(device, lambda: mjw.step(m, d), steps, repeats)))
    rft["env"] = rft["treated"]
    if "ground" in fields:  # the step with the field less the step without it
        rft["ground"] = dict(timings)["ground"] - dict(timings)["off"]
    field = fields["on"]
    rows = []
    if name == "hexapod_sand":  # the vector environment: control steps of 20 physics steps
        env = HexapodVecEnv(nworld, device=str(device))
        env.reset(seed=0)
        action = wp.array(np.tile([1.0, np.pi], (nworld, 1)).astype(np.float32), dtype=float,
                          device=device)  # fmt: skip
        control = max(1, steps // env.substeps)
        t = timed(device, lambda: env.advance(action), control, repeats)
        timings.append(("env", t * steps / (control * env.substeps)))
    for label, t in timings:
        rows.append(
            {
                "model": name, "nworld": nworld, "triangles": field.nelem, "field": label,
                "steps_per_s": f"{nworld * steps / t:.4g}", "step_us": f"{t / steps * 1e6:.1f}",
                "rft_us": f"{rft[label] / steps * 1e6:.1f}" if label != "off" else "",
                "rft_share": f"{rft[label] / t:.3f}" if label not in ("off", "env") else "",
            }
        )  # fmt: skip
    return rows


_LEG = """
  <body name="thigh_{n}" pos="{x} {y} 0">
    <joint name="hip_{n}" axis="0 1 0" range="-1 1" armature="0.0005" damping="0.01"/>
    <geom type="capsule" fromto="0 0 0 0 0 -0.06" size="0.008" mass="0.05"/>
    <body name="shin_{n}" pos="0 0 -0.06">
      <joint name="knee_{n}" axis="0 1 0" range="-1.5 1.5" armature="0.0005" damping="0.01"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.06" size="0.006" mass="0.03"/>
      <geom name="foot_{n}" type="sphere" pos="0 0 -0.06" size="0.012" mass="0.02"/>
    </body>
  </body>"""
_LEGS = (("LF", 0.08, 0.05), ("RF", 0.08, -0.05), ("LH", -0.08, 0.05), ("RH", -0.08, -0.05))
#: A quadruped of two-joint legs (hip and knee position servos holding 0) standing on four ball
#: feet in glass beads, 1.4 kg: the second robot of the standing check.
QUADRUPED = f"""<mujoco model="quadruped_sand">
  <option timestep="0.001" integrator="Euler"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <tuple name="mjrft:intruders">{
    "".join(f'<element objtype="geom" objname="foot_{n}" prm="200"/>' for n, _, _ in _LEGS)
}</tuple>
  </custom>
  <worldbody>
    <body name="torso" pos="0 0 0.125">
      <freejoint/>
      <geom type="box" size="0.1 0.05 0.02" mass="1.0"/>
      {"".join(_LEG.format(n=n, x=x, y=y) for n, x, y in _LEGS)}
    </body>
  </worldbody>
  <actuator>{
    "".join(
        f'<position joint="{j}_{n}" kp="8" kv="0.05"/>'
        for n, _, _ in _LEGS
        for j in ("hip", "knee")
    )
}</actuator>
</mujoco>"""


STANDING_FIELDS = (
    "robot",
    "integrator",
    "dt_ms",
    "nworld",
    "seconds",
    "drift_m",
    "force_change",
    "s_per_step",
)


def stand(device, robot: str, integrator: str, dt: float, nworld: int, seconds: float) -> dict:
    """A robot standing with the treated field (the hexapod from its keyframe, gait stopped;
    the quadruped from its initial state): the torso's largest drift [m] over the last second,
    over all worlds, and the largest step-to-step change of the total vertical RFT force there
    over the weight."""
    if robot == "hexapod":
        mjm = mujoco.MjModel.from_xml_path(str(MODELS / "hexapod_sand.xml"))
    else:
        mjm = mujoco.MjModel.from_xml_string(QUADRUPED)
    mjm.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    mjm.opt.timestep = dt
    mjd = mujoco.MjData(mjm)
    if mjm.nkey:
        mujoco.mj_resetDataKeyframe(mjm, mjd, 0)
    mjd.ctrl[:] = 0.0
    mjd.qvel[:] = 0.0
    field = WarpField(mjm, device=str(device))
    weight = float(mjm.body_subtreemass[1]) * -mjm.opt.gravity[2]
    n, last = round(seconds / dt), round(1.0 / dt)
    pos, fz = [], []
    with wp.ScopedDevice(device):
        m = mjw.put_model(mjm)
        d = mjw.put_data(mjm, mjd, nworld=nworld)
        t = time.perf_counter()
        with field.installed(m, d):
            for i in range(n):
                mjw.step(m, d)
                if i >= n - last:  # copies: numpy() of a CPU-device array is a live view
                    pos.append(d.xpos.numpy()[:, 1].copy())
                    fz.append(field.wrenches(d)[:, field.body_ids, 2].sum(axis=1))
        elapsed = time.perf_counter() - t
    pos, fz = np.array(pos), np.array(fz)
    return {
        "robot": robot, "integrator": integrator, "dt_ms": f"{dt * 1e3:g}", "nworld": nworld,
        "seconds": f"{seconds:g}", "drift_m": f"{np.abs(pos - pos[0]).max():.3g}",
        "force_change": f"{np.abs(np.diff(fz, axis=0)).max() / weight:.3g}",
        "s_per_step": f"{elapsed / n:.3g}",
    }  # fmt: skip


def standing(args, device) -> list[dict]:
    """--standing: stand() of the hexapod and the quadruped at dt 1 and 2 ms under Euler and
    implicitfast; prints and writes benchmarks/results/gpu_standing.csv (or --out)."""
    nworld = (args.nworld or [4])[0]
    rows = []
    print(f"{'robot':10s} {'integrator':12s} {'dt ms':>5s} {'drift m':>9s} {'dF/weight':>9s} "
          f"{'s/step':>8s}")  # fmt: skip
    for robot in ("hexapod", "quadruped"):
        for integrator in ("Euler", "implicitfast"):
            for dt in (0.001, 0.002):
                r = stand(device, robot, integrator, dt, nworld, args.seconds)
                rows.append(r)
                print(f"{robot:10s} {integrator:12s} {r['dt_ms']:>5s} {r['drift_m']:>9s} "
                      f"{r['force_change']:>9s} {r['s_per_step']:>8s}", flush=True)  # fmt: skip
    out = args.out if args.out != OUT / "gpu.csv" else OUT / "gpu_standing.csv"
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=STANDING_FIELDS)
        w.writeheader()
        w.writerows(rows)
    return rows


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default=None, help="Warp device (default: cuda:0 if present)")
    ap.add_argument("--nworld", type=int, nargs="+", default=None)
    ap.add_argument("--models", nargs="+", default=["hexapod_sand", "ellipsoid_pitch"])
    ap.add_argument("--steps", type=int, default=100, help="steps per timed loop")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=OUT / "gpu.csv")
    ap.add_argument("--standing", action="store_true", help="the standing check instead")
    ap.add_argument("--seconds", type=float, default=5.0, help="--standing: seconds stood")
    args = ap.parse_args(argv)
    device = wp.get_device(args.device or ("cuda:0" if wp.is_cuda_available() else "cpu"))
    if args.standing:
        return standing(args, device)
    nworlds = args.nworld or ([4**k for k in range(8)] if device.is_cuda else [1, 4, 16])
    cpu = metadata.machine()["cpu"] or platform.machine()
    print(f"device: {device} ({device.name}); CPU: {cpu}, {os.cpu_count()} cores; "
          f"warp {wp.__version__}; steps {args.steps}, medians of {args.repeats}")  # fmt: skip
    print(f"{'model':16s} {'nworld':>7s} {'field':>7s} {'steps/s':>10s} {'us/step':>9s} "
          f"{'rft us':>8s} {'rft share':>9s}")  # fmt: skip
    rows = []
    for name in args.models:
        for nworld in nworlds:
            for r in measure(name, nworld, device, args.steps, args.repeats):
                rows.append(r)
                print(f"{r['model']:16s} {r['nworld']:7d} {r['field']:>7s} "
                      f"{r['steps_per_s']:>10s} {r['step_us']:>9s} {r['rft_us']:>8s} "
                      f"{r['rft_share']:>9s}", flush=True)  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        w.writerows(rows)
    return rows


if __name__ == "__main__":
    main()
