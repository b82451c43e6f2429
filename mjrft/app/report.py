"""Result files: atomic CSV writes and labelled PNG plots. A leaf: the core never imports it."""

from __future__ import annotations

import contextlib
import csv
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from mjrft.app.demos import DemoResult
from mjrft.core.units import CM


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside `path`; it replaces `path` only if the block succeeds.

    A failed or interrupted write never leaves a truncated file under the final name.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; results are ordinary files
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_csv(path: str | os.PathLike, columns: dict[str, np.ndarray]) -> Path:
    """Write equal-length columns (header = names, SI units in the names) atomically."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[k], dtype=np.float64) for k in names])
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(names)
            for row in data:
                w.writerow([repr(float(x)) for x in row])
    return Path(path)


def demo_columns(result: DemoResult) -> dict[str, np.ndarray]:
    """CSV columns of a demo: time, depth, force, moment and extras, names carrying SI units."""
    cols = {"time_s": result.time, "pivot_depth_m": result.depth}
    for i, ax in enumerate("xyz"):
        cols[f"force_{ax}_N"] = result.force[:, i]
    for i, ax in enumerate("xyz"):
        cols[f"moment_{ax}_Nm"] = result.moment[:, i]
    for k, v in result.extra.items():
        cols[f"{k}_{'rad_per_s' if k.endswith('_rate') else 'rad'}"] = v
    return cols


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # headless: never needs a display
    import matplotlib.pyplot as plt

    return plt


def plot_demo(result: DemoResult, path: str | os.PathLike) -> Path:
    """Force and moment vs pivot depth (and lateral vs vertical force) as one PNG, atomically."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), constrained_layout=True)
    depth_cm = result.depth / CM
    for i, ax in enumerate("xyz"):
        axes[0].plot(depth_cm, result.force[:, i], label=f"$F_{ax}$")
        axes[1].plot(depth_cm, result.moment[:, i] * 1e3, label=f"$M_{ax}$")
    axes[0].set(xlabel="pivot depth [cm]", ylabel="RFT force [N]", title="Force vs depth")
    axes[1].set(xlabel="pivot depth [cm]", ylabel="RFT moment about pivot [mN m]")
    axes[1].set_title("Moment vs depth")
    axes[2].plot(result.force[:, 2], result.force[:, 0], lw=0.8)
    axes[2].set(xlabel="vertical force $F_z$ [N]", ylabel="lateral force $F_x$ [N]")
    axes[2].set_title("Lateral vs vertical force")
    for a in axes:
        a.grid(alpha=0.3)
    axes[0].legend()
    axes[1].legend()
    fig.suptitle(f"{result.title}  ({result.n_elements} triangles, world frame)")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return Path(path)


def plot_time_series(result: DemoResult, path: str | os.PathLike) -> Path:
    """Force components vs time, with the pitch (if any) on a second axis, as a PNG."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(10, 4.2), constrained_layout=True)
    for i, c in enumerate("xyz"):
        ax.plot(result.time, result.force[:, i], label=f"$F_{c}$")
    ax.set(xlabel="time [s]", ylabel="RFT force [N]", title=result.title)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left")
    if "pitch" in result.extra:
        ax2 = ax.twinx()
        ax2.plot(result.time, np.degrees(result.extra["pitch"]), "k:", lw=0.8, label="pitch")
        ax2.set_ylabel("pitch [deg]")
        ax2.legend(loc="lower left")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return Path(path)


def plot_run(rec, surface_z: float, out_dir: str | os.PathLike, stem: str = "") -> list[Path]:
    """PNG plots of a `mjrft run` recording: RFT force/torque vs time, force vs depth and the
    paper-style summary (``plot_paper``).

    Args:
      rec: mjrft.simulate.Recording. surface_z: free-surface height [m].
      out_dir: directory; files are '<stem>forces_vs_time.png', '<stem>forces_vs_depth.png' and
        '<stem>rft_summary.png'.
    """
    plt = _pyplot()
    data = rec.array()
    col = {c: i for i, c in enumerate(rec.columns)}
    t = data[:, col["time_s"]]
    n = max(1, len(rec.body_names))
    written = []
    fig, axes = plt.subplots(2, n, figsize=(6.5 * n, 7), squeeze=False, constrained_layout=True)
    fig2, axes2 = plt.subplots(1, n, figsize=(6.5 * n, 4.2), squeeze=False, constrained_layout=True)
    for j, body in enumerate(rec.body_names):
        depth_cm = (surface_z - data[:, col[f"{body}_com_z_m"]]) / CM
        for a in "xyz":
            f = data[:, col[f"{body}_rft_force_{a}_N"]]
            axes[0, j].plot(t, f, label=f"$F_{a}$")
            axes[1, j].plot(t, data[:, col[f"{body}_rft_torque_{a}_Nm"]] * 1e3, label=f"$M_{a}$")
            axes2[0, j].plot(depth_cm, f, label=f"$F_{a}$")
        axes[0, j].set(title=f"{body}: RFT force (world frame)", ylabel="force [N]")
        axes[1, j].set(xlabel="time [s]", ylabel="torque about CoM [mN m]")
        axes2[0, j].set(
            title=f"{body}: RFT force vs depth",
            xlabel="CoM depth below surface [cm]",
            ylabel="force [N]",
        )
        for a in (axes[0, j], axes[1, j], axes2[0, j]):
            a.grid(alpha=0.3)
            a.legend()
    for figure, name in ((fig, "forces_vs_time.png"), (fig2, "forces_vs_depth.png")):
        path = Path(out_dir) / f"{stem}{name}"
        with atomic_path(path) as tmp:
            figure.savefig(tmp, format="png", dpi=110)
        plt.close(figure)
        written.append(path)
    written.append(plot_paper(rec, surface_z, Path(out_dir) / f"{stem}{PAPER_PNG}"))
    return written


#: File name of the paper-style summary figure that `mjrft run` writes next to the CSV.
PAPER_PNG = "rft_summary.png"
#: Resolution of the summary figure [dots per inch].
PAPER_DPI = 100


def plot_paper(rec, surface_z: float, path: str | os.PathLike, title: str | None = None) -> Path:
    """Paper-style summary of a run, a 2 x 2 block of panels per intruding body, as a PNG.

    Panels (world frame, SI except where the axis says otherwise): (a) RFT force vs CoM depth
    below the surface [cm]; (b) RFT torque about the CoM vs depth [mN m]; (c) RFT force vs time
    [s]; (d) lateral (F_x, F_y) vs vertical (F_z) force [N], the trajectory coloured by time.

    Args:
      rec: mjrft.simulate.Recording. surface_z: free-surface height [m].
      path: PNG file (written atomically). title: figure title (default: none).
    """
    from matplotlib.collections import LineCollection

    plt = _pyplot()
    data = rec.array()
    col = {c: i for i, c in enumerate(rec.columns)}
    t = data[:, col["time_s"]]
    bodies = rec.body_names or []
    n = max(1, len(bodies))
    fig, grid = plt.subplots(
        2 * n,
        2,
        figsize=(12, 7.4 * n + (0.4 if title else 0)),
        squeeze=False,
        constrained_layout=True,
    )
    axes = grid.reshape(n, 4)
    colors = {"x": "C0", "y": "C1", "z": "C2"}
    for j, body in enumerate(bodies):
        ax_fd, ax_md, ax_ft, ax_lv = axes[j]
        depth_cm = (surface_z - data[:, col[f"{body}_com_z_m"]]) / CM
        force = {a: data[:, col[f"{body}_rft_force_{a}_N"]] for a in "xyz"}
        torque = {a: data[:, col[f"{body}_rft_torque_{a}_Nm"]] * 1e3 for a in "xyz"}
        for a in "xyz":
            ax_fd.plot(depth_cm, force[a], color=colors[a], lw=1.0, label=f"$F_{a}$")
            ax_md.plot(depth_cm, torque[a], color=colors[a], lw=1.0, label=f"$M_{a}$")
            ax_ft.plot(t, force[a], color=colors[a], lw=1.0, label=f"$F_{a}$")
        ax_fd.set(xlabel="CoM depth below surface [cm]", ylabel="RFT force [N]")
        ax_fd.set_title(f"{body}: force vs depth")
        ax_md.set(xlabel="CoM depth below surface [cm]", ylabel="RFT torque about CoM [mN m]")
        ax_md.set_title(f"{body}: moment vs depth")
        ax_ft.set(xlabel="time [s]", ylabel="RFT force [N]")
        ax_ft.set_title(f"{body}: force vs time")
        norm = plt.Normalize(t[0], t[-1] if t[-1] > t[0] else t[0] + 1.0)
        for a, style in (("x", "solid"), ("y", "dashed")):
            pts = np.column_stack([force["z"], force[a]]).reshape(-1, 1, 2)
            segs = np.concatenate([pts[:-1], pts[1:]], axis=1)
            lc = LineCollection(segs, cmap="viridis", norm=norm, linestyles=style, linewidths=1.2)
            lc.set_array(0.5 * (t[:-1] + t[1:]))
            ax_lv.add_collection(lc)
            ax_lv.plot([], [], color="0.3", ls=style, label=f"$F_{a}$")
        ax_lv.autoscale()
        ax_lv.set(xlabel="vertical force $F_z$ [N]", ylabel="lateral force [N]")
        ax_lv.set_title(f"{body}: lateral vs vertical force")
        fig.colorbar(lc, ax=ax_lv, label="time [s]", pad=0.01)
        for a in axes[j]:
            a.grid(alpha=0.3)
            a.legend(fontsize=8, loc="best")
    if title:
        fig.suptitle(title)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=PAPER_DPI)
    plt.close(fig)
    return Path(path)


def plot_rig_vs_prescribed(
    rec, body: str, prescribed: DemoResult, path: str | os.PathLike, title: str
) -> Path:
    """RFT force vs time of a simulated rig against the prescribed-trajectory demo, as a PNG."""
    plt = _pyplot()
    data = rec.array()
    col = {c: i for i, c in enumerate(rec.columns)}
    t = data[:, col["time_s"]]
    fig, ax = plt.subplots(figsize=(10, 4.4), constrained_layout=True)
    for i, a in enumerate("xyz"):
        (line,) = ax.plot(
            t, data[:, col[f"{body}_rft_force_{a}_N"]], label=f"$F_{a}$ simulated rig"
        )
        ax.plot(
            prescribed.time,
            prescribed.force[:, i],
            ls="--",
            color=line.get_color(),
            label=f"$F_{a}$ prescribed",
        )
    ax.set_xlim(0, t[-1])
    ax.set(xlabel="time [s]", ylabel="RFT force on the intruder [N] (world frame)", title=title)
    ax.grid(alpha=0.3)
    ax.legend(ncol=3, fontsize=8)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return Path(path)
