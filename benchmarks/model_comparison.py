"""The two force models and the dynamic term side by side on the paper's scenes and the hexapod.

Run: python benchmarks/model_comparison.py     (about 1 min on 2 cores)

Variants, all glass beads: treers2021 (the default), agarwal3d (scale matched at the plate
pushed down, ``Material.with_model``) and treers2021 with the dynamic term at rho_c = 1,500
kg/m^3, lambda = 1 (``Material.with_dynamic``). Scenes:
1. a 2 x 2 cm plate (box, 1 mm thick, 800 triangles) tilted by beta about y, its centre 2 cm
   deep, moving at 1 cm/s straight down (gamma = 90 deg) and along +x (gamma = 0): force
   components vs beta (the dynamic term at 1 m/s, since at 1 cm/s it is 1e-4 of the force);
2. the pitching ellipsoid and 3. the circumnutating root tip under their rigs' prescribed
   motions (benchmarks/pareto.py's trajectories, 2,000 triangles and the root's 2,976): force
   components vs time;
4. models/hexapod_sand.xml walking 3 s from its keyframe (field installed): forward speed and
   the largest vertical force on a leg.
Writes docs/model_comparison.png and benchmarks/results/model_comparison.csv.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import mujoco
import numpy as np
from pareto import ellipsoid_rig_motion, root_rig_motion, root_shape, write_csv

from mjrft import Material, geometry, simulate
from mjrft.app import demos
from mjrft.app.regime import QuasiStaticWarning
from mjrft.body import trajectory_wrenches
from mjrft.field import GranularField

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results"
RHO_C = 1500.0  # kg/m^3: glass beads of 2,500 kg/m^3 at a packing fraction of 0.6
GLASS = Material.preset("glass_beads")
VARIANTS = {
    "treers2021": GLASS,
    "agarwal3d": GLASS.with_model("agarwal3d"),
    "treers2021 + dynamic": GLASS.with_dynamic(RHO_C),
}
STYLE = {"treers2021": "-", "agarwal3d": "--", "treers2021 + dynamic": ":"}


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def plate_forces(material: Material, betas, gamma: float, speed: float) -> np.ndarray:
    """(len(betas), 3) world force [N] on the tilted plate moving at speed [m/s] along
    (cos gamma, 0, -sin gamma)."""
    plate = geometry.primitive("box", [0.01, 0.01, 0.0005], n_triangles=800)
    v = speed * np.array([np.cos(gamma), 0.0, -np.sin(gamma)])
    out = []
    for b in betas:
        w = trajectory_wrenches(plate, np.array([[0.0, 0.0, -0.02]]), rot_y(b)[None],
                                v[None], np.zeros((1, 3)), material)  # fmt: skip
        out.append(w.force[0])
    return np.array(out)


def rig_forces(material: Material, shape, motion) -> np.ndarray:
    pos, rot, vel, ang = motion
    return trajectory_wrenches(shape, pos, rot, vel, ang, material).force


def hexapod(material: Material, duration: float = 3.0) -> tuple[float, float]:
    """(forward speed [m/s], largest vertical RFT force on one body [N]) of the hexapod."""
    model = simulate.load_model(ROOT / "models" / "hexapod_sand.xml", material=material)
    fld = GranularField(model)
    peak = [0.0]

    def observe(step, time, data):
        peak[0] = max(peak[0], float(fld.wrench_of(data)[:, 2].max()))

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", QuasiStaticWarning)  # the legs swing at ~1 m/s
        d0 = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, d0, 0)
        data, _ = simulate.run(model, duration, fld=fld, observer=observe, record_every=100)
    return (float(data.qpos[0] - d0.qpos[0]) / duration, peak[0])


def main() -> None:
    OUT.mkdir(exist_ok=True)
    betas = np.radians(np.linspace(-90, 90, 37))
    ell_motion, root_motion = ellipsoid_rig_motion(0.02), root_rig_motion(0.1)
    ell = geometry.primitive("ellipsoid", demos.ELLIPSOID_SEMI_AXES, n_triangles=2000)
    root = root_shape(2976)
    fig, axes = plt.subplots(2, 3, figsize=(15, 8.5))
    rows = []
    for name, material in VARIANTS.items():
        ls = STYLE[name]
        for ax, gamma, label in ((axes[0, 0], np.pi / 2, "down"), (axes[0, 1], 0.0, "along +x")):
            speed = 1.0 if name.endswith("dynamic") and gamma > 0 else 0.01
            f = plate_forces(material, betas, gamma, speed)
            tag = f"{name} at {speed:g} m/s"
            ax.plot(np.degrees(betas), f[:, 2], "C0" + ls, label=f"Fz, {tag}")
            ax.plot(np.degrees(betas), f[:, 0], "C1" + ls, label=f"Fx, {tag}")
            ax.set_title(f"2 x 2 cm plate 2 cm deep, moving {label}")
            rows += [{"scene": f"plate {label}", "variant": name, "x": float(np.degrees(b)),
                      "fx_N": float(fi[0]), "fz_N": float(fi[2])}
                     for b, fi in zip(betas, f, strict=True)]  # fmt: skip
        for ax, shape, motion, title, dt in (
            (axes[0, 2], ell, ell_motion, "pitching ellipsoid (rig motion)", 0.02),
            (axes[1, 0], root, root_motion, "root tip (rig motion)", 0.1),
        ):
            f = rig_forces(material, shape, motion)
            t = dt * np.arange(len(f))
            ax.plot(t, f[:, 2], "C0" + ls, label=f"Fz, {name}")
            ax.plot(t, f[:, 0], "C1" + ls, label=f"Fx, {name}")
            ax.set_title(title)
            rows += [{"scene": title, "variant": name, "x": float(ti), "fx_N": float(fi[0]),
                      "fz_N": float(fi[2])}
                     for ti, fi in zip(t[::10], f[::10], strict=True)]  # fmt: skip
        speed, peak = hexapod(material)
        rows.append({"scene": "hexapod", "variant": name, "x": speed, "fx_N": 0.0, "fz_N": peak})
        print(f"hexapod, {name:22s}: forward speed {100 * speed:.2f} cm/s, largest vertical "
              f"force on a body {peak:.2f} N")  # fmt: skip
    for ax in axes[0, :2]:
        ax.set_xlabel("plate tilt beta [deg]")
        ax.set_ylabel("force [N]")
    for ax in (axes[0, 2], axes[1, 0]):
        ax.set_xlabel("time [s]")
        ax.set_ylabel("force on the body [N]")
    hexa = [r for r in rows if r["scene"] == "hexapod"]
    ax = axes[1, 1]
    ax.bar(range(len(hexa)), [100 * r["x"] for r in hexa], color=["C2", "C3", "C4"])
    ax.set_xticks(range(len(hexa)), [r["variant"] for r in hexa], fontsize=8)
    ax.set_ylabel("forward speed [cm/s]")
    ax.set_title("hexapod_sand.xml, 3 s from its keyframe")
    ax = axes[1, 2]
    ax.bar(range(len(hexa)), [r["fz_N"] for r in hexa], color=["C2", "C3", "C4"])
    ax.set_xticks(range(len(hexa)), [r["variant"] for r in hexa], fontsize=8)
    ax.set_ylabel("largest vertical RFT force on a body [N]")
    ax.set_title("hexapod_sand.xml, 3 s from its keyframe")
    for ax in axes.flat[:4]:
        ax.legend(fontsize=6)
        ax.grid(alpha=0.3)
    fig.suptitle("Force models on glass beads: treers2021, agarwal3d (scale matched at the plate "
                 "pushed down) and the dynamic term (rho_c = 1500 kg/m^3)")  # fmt: skip
    fig.tight_layout()
    fig.savefig(ROOT / "docs" / "model_comparison.png", dpi=110)
    write_csv(OUT / "model_comparison.csv", rows)


if __name__ == "__main__":
    main()
