"""Result files: atomic CSV writes and labelled PNG figures. A leaf: the core never imports it.

Figures are drawn with matplotlib's object API (no pyplot state) at fixed margins. Every line is
decimated to a min/max envelope (``envelope_indices``: peaks survive), a panel's axis limits
draw round-off noise flat at zero (``value_limits``), every PNG is at most ``MAX_PNG_PX`` pixels
wide and high, and a scene of many bodies gets a bounded number of panels, so a figure costs
about the same for any run length and any number of bodies.
"""

from __future__ import annotations

import contextlib
import csv
import functools
import math
import os
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from mjrft.app.demos import DemoResult
from mjrft.core.surface import Surface
from mjrft.core.units import CM

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


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


# ----------------------------------------------------------------------------------------------
# Figure rules: pure functions of the data.

#: Largest width and height of any PNG written here [px].
MAX_PNG_PX = 2000
#: Resolution of the figures [dots per inch]; a figure that would exceed MAX_PNG_PX gets less.
DPI = 100
#: Runs of rows a plotted line is decimated to (``envelope_indices``): at most 2 points per run
#: for a time series, 4 for a curve of two series; more than a 2000-px panel can show.
LINE_BINS = 1000
#: zlib level of the PNGs: level 1 writes these line plots several times faster than level 6
#: for files about a quarter larger.
PNG_COMPRESSION = 1
#: A series whose peak |value| is below this fraction of its panel's largest peak sets no axis
#: limit: far above round-off (1e-16 relative) and far below what a 2000-px axis resolves (5e-4).
NOISE_FRACTION = 1e-6
#: Forces below this [N] are drawn flat at zero: 1 uN is less than the weight of one 0.8 mm glass
#: bead (6.6 uN), the grain of the paper's medium, so no continuum RFT force is that small.
FORCE_FLOOR_N = 1e-6
#: Torques below this [N m] are drawn flat at zero: a 1 uN force on a 1 mm lever (one grain's
#: weight at about one grain's size).
TORQUE_FLOOR_NM = 1e-9
#: A CoM depth that spans less than this over a run [m] (and less than the CoM's horizontal
#: travel) counts as constant: about one 0.8 mm glass bead.
DEPTH_SPAN_M = 1e-3
#: Axis margin beyond the data, a fraction of the data's span on each side.
LIMIT_MARGIN = 0.05


def envelope_indices(values: np.ndarray, n_bins: int) -> np.ndarray:
    """Rows of `values` that keep its min/max envelope: the decimation of a plotted line.

    Args:
      values: (n,) or (n, k) samples in row (time) order.
      n_bins: number of runs of ceil(n / n_bins) consecutive rows the rows are cut into (>= 1).
    Returns:
      Sorted row indices: the first and last rows and, in every run, the rows of the least and
      the greatest value of each column (all rows when n <= 2 n_bins). The minimum and maximum
      of every column over any set of whole runs are therefore kept exactly.
    """
    v = np.asarray(values, dtype=np.float64)
    v = v.reshape(len(v), -1)
    n = len(v)
    if n <= 2 * n_bins:
        return np.arange(n)
    size = -(-n // n_bins)
    n_runs = -(-n // size)
    # Pad with the last row so the runs reshape; a padded pick is clipped back to that row.
    padded = np.concatenate([v, np.repeat(v[-1:], n_runs * size - n, axis=0)])
    runs = padded.reshape(n_runs, size, v.shape[1])
    start = (np.arange(n_runs) * size)[:, None]
    picks = np.concatenate([start + runs.argmin(axis=1), start + runs.argmax(axis=1)], axis=1)
    return np.unique(np.concatenate([[0, n - 1], np.minimum(picks.ravel(), n - 1)]))


def value_limits(
    series: Sequence[np.ndarray], floor: float, margin: float = LIMIT_MARGIN
) -> tuple[float, float]:
    """Axis limits (lo, hi) of the series drawn in one panel, with round-off noise drawn flat.

    A series is significant when its peak |value| reaches both `floor` and NOISE_FRACTION of the
    largest peak in the panel. The limits span the significant series, and zero when some series
    is not significant (so it shows as a flat line at zero), widened by `margin` of the span on
    each side; a span below NOISE_FRACTION of that largest peak counts as none, and the limits
    are then +-`margin` of the value around it. With no significant series: (-floor, floor).

    Args:
      series: arrays in the panel's unit; non-finite values are ignored.
      floor: smallest meaningful |value| in that unit (> 0), e.g. FORCE_FLOOR_N.
      margin: fraction of the span added on each side.
    """
    finite = [
        s[np.isfinite(s)] for s in (np.ravel(np.asarray(x, dtype=np.float64)) for x in series)
    ]
    peaks = [float(np.max(np.abs(s))) if s.size else 0.0 for s in finite]
    top = max(peaks, default=0.0)
    keep = [s for s, p in zip(finite, peaks, strict=True) if p >= max(floor, NOISE_FRACTION * top)]
    if not keep:
        return -floor, floor
    lo, hi = min(float(s.min()) for s in keep), max(float(s.max()) for s in keep)
    if len(keep) < len(finite):
        lo, hi = min(lo, 0.0), max(hi, 0.0)
    span = hi - lo
    pad = margin * (span if span >= NOISE_FRACTION * top else max(abs(lo), abs(hi)))
    return lo - pad, hi + pad


class Abscissa(NamedTuple):
    """The abscissa of a body's force-vs-position panels."""

    values: np.ndarray  #: (n,) [cm]
    name: str  #: 'depth' or 'horizontal distance'
    label: str  #: axis label, with unit


def abscissa(com: np.ndarray, surface_z: float | Surface) -> Abscissa:
    """Where a body's RFT force is plotted against: its CoM depth, or else its horizontal travel.

    The CoM depth below the surface under it (height - z) when the depth varies substantially
    over the run: its range is at least DEPTH_SPAN_M or at least the CoM's largest horizontal
    distance from its start. Otherwise (motion at about constant depth, e.g. a plate dragged
    sideways) the horizontal distance of the CoM from its start, |(x, y) - (x0, y0)|.

    Args:
      com: (n, 3) CoM positions, world frame [m], n >= 1. surface_z: free-surface height [m],
        or the field's Surface (a tilted plane or height field: its height under each CoM).
    """
    com = np.asarray(com, dtype=np.float64)
    if isinstance(surface_z, Surface):
        surface_z = surface_z.height(com[:, 0], com[:, 1])
    depth = surface_z - com[:, 2]
    travel = np.hypot(com[:, 0] - com[0, 0], com[:, 1] - com[0, 1])
    span = float(np.ptp(depth)) if len(depth) else 0.0
    if span >= DEPTH_SPAN_M or span >= float(np.max(travel, initial=0.0)):
        return Abscissa(depth / CM, "depth", "CoM depth below surface [cm]")
    return Abscissa(travel / CM, "horizontal distance", "CoM horizontal distance from start [cm]")


def goes_in(com: np.ndarray, surface_z: float | Surface) -> bool:
    """True if a body's CoM (n, 3) [m], world frame, is below the free surface (`surface_z`
    [m] or the Surface under it) at some row: its force is worth drawing against its depth. A
    walking robot's torso, whose belly may touch the medium while its CoM stays above, is not.
    """
    com = np.asarray(com, dtype=np.float64)
    if isinstance(surface_z, Surface):
        surface_z = surface_z.height(com[:, 0], com[:, 1])
    return bool(np.any(surface_z - com[:, 2] > 0.0))


def figure_title(title: str | None, what: str) -> str:
    """A figure's title: the run's `title` (scene, material, triangles) over what it shows."""
    return f"{title}\n{what}" if title else what


def shown_bodies(names: Sequence[str], peaks: Sequence[float], limit: int) -> list[int]:
    """Indices of the at most `limit` bodies with the largest `peaks`, in their given order
    (ties: the earlier body)."""
    order = sorted(range(len(names)), key=lambda i: (-peaks[i], i))
    return sorted(order[:limit])


# ----------------------------------------------------------------------------------------------
# The series of a run.


@dataclass(frozen=True)
class BodySeries:
    """One intruding body's recorded series, world frame, SI.

    Attributes: name; com (n, 3) CoM position [m]; force (n, 3) RFT force [N]; torque (n, 3)
    RFT torque about the CoM [N m].
    """

    name: str
    com: np.ndarray
    force: np.ndarray
    torque: np.ndarray

    @property
    def peak_force(self) -> float:
        """Largest |F| over the run [N] (0 if none is finite)."""
        return _peak(self.force)

    @property
    def entered(self) -> bool:
        """True if the body went into the medium: it felt an RFT force of FORCE_FLOOR_N or
        more (a body that never touches the medium feels none)."""
        return self.peak_force >= FORCE_FLOOR_N

    @property
    def has_torque(self) -> bool:
        """True if the RFT torque about the CoM reached TORQUE_FLOOR_NM (a sphere's does not)."""
        return _peak(self.torque) >= TORQUE_FLOOR_NM

    @property
    def has_lateral(self) -> bool:
        """True if the horizontal RFT force (F_x, F_y) reached FORCE_FLOOR_N."""
        return _peak(self.force[:, :2]) >= FORCE_FLOOR_N


def _peak(v: np.ndarray) -> float:
    """Largest finite row norm of (n, k) `v` (0 if none)."""
    norms = np.linalg.norm(v, axis=1)
    norms = norms[np.isfinite(norms)]
    return float(norms.max()) if norms.size else 0.0


def run_series(rec) -> tuple[np.ndarray, list[BodySeries]]:
    """(time (n,) [s], per body its BodySeries) of a mjrft.app.simulate.Recording."""
    data = rec.array()
    col = {c: i for i, c in enumerate(rec.columns)}

    def block(body: str, fmt: str) -> np.ndarray:
        return data[:, [col[fmt.format(body, a)] for a in "xyz"]]

    bodies = [
        BodySeries(
            b,
            block(b, "{}_com_{}_m"),
            block(b, "{}_rft_force_{}_N"),
            block(b, "{}_rft_torque_{}_Nm"),
        )
        for b in rec.body_names or []
    ]
    return data[:, col["time_s"]], bodies


# ----------------------------------------------------------------------------------------------
# Drawing helpers.

#: Colour and line style of the x, y, z components in every figure (the legends say so).
COMPONENT_STYLE = {"x": ("C0", "-"), "y": ("C1", "--"), "z": ("C2", "-")}
#: Bodies up to which `forces_vs_time.png` has a column per body; beyond, a panel per component.
MAX_BODY_COLUMNS = 3
#: Bodies drawn in a panel per component (the largest peak |F|; the others are named).
MAX_LINES = 8
#: Panels of `forces_vs_depth.png` (one per body, the largest peak |F|) and panels per row.
MAX_POSITION_PANELS, POSITION_COLUMNS = 8, 4
#: Bodies in the paper-style summary, a 2 x 2 block each (the largest peak |F|).
MAX_SUMMARY_BODIES = 2
#: Time markers on each curve of a lateral-vs-vertical panel.
TIME_MARKERS = 12
#: Text sizes and grid of every figure (matplotlib rcParams).
STYLE = {
    "font.size": 9,
    "axes.titlesize": 9,
    "axes.labelsize": 9,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "legend.fontsize": 9,
    "figure.titlesize": 10,
    # A fixed title height: matplotlib otherwise measures every panel's tick labels to place it.
    "axes.titley": 1.0,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "lines.linewidth": 1.0,
}
_TITLE_IN, _LEGEND_IN = 0.42, 0.3  # heights of a two-line title and a legend row [in]


def _styled(fn):
    """Run a figure function under STYLE (rcParams are read as artists are made and drawn)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        import matplotlib

        with matplotlib.rc_context(STYLE):
            return fn(*args, **kwargs)

    return wrapper


@dataclass(frozen=True)
class Grid:
    """A figure of equal panels at fixed margins: sizes in inches.

    Attributes: rows, cols; panel (width, height); gap (horizontal, vertical) between panels,
    room for tick labels, axis labels and titles; margins (left, right, top, bottom), the top
    holding the figure title and legend.
    """

    rows: int
    cols: int
    panel: tuple[float, float] = (5.0, 2.6)
    gap: tuple[float, float] = (0.85, 0.75)
    margins: tuple[float, float, float, float] = (0.8, 0.3, 1.25, 0.55)

    @property
    def size(self) -> tuple[float, float]:
        """(width, height) of the figure [in]."""
        left, right, top, bottom = self.margins
        w = left + self.cols * self.panel[0] + (self.cols - 1) * self.gap[0] + right
        h = top + self.rows * self.panel[1] + (self.rows - 1) * self.gap[1] + bottom
        return w, h

    @property
    def dpi(self) -> float:
        """DPI, lowered so that neither side exceeds MAX_PNG_PX."""
        return min(DPI, math.floor(MAX_PNG_PX / max(self.size) * 1e3) / 1e3)


def new_figure(grid: Grid, n_panels: int | None = None) -> tuple[Figure, list[Axes]]:
    """A Figure laid out by `grid` and its first `n_panels` axes (all cells by default), in
    row-major order."""
    from matplotlib.figure import Figure

    w, h = grid.size
    left, right, top, bottom = grid.margins
    fig = Figure(figsize=(w, h), dpi=grid.dpi)
    gs = fig.add_gridspec(
        grid.rows,
        grid.cols,
        left=left / w,
        right=1 - right / w,
        top=1 - top / h,
        bottom=bottom / h,
        wspace=grid.gap[0] / grid.panel[0],
        hspace=grid.gap[1] / grid.panel[1],
    )
    n = grid.rows * grid.cols if n_panels is None else n_panels
    axes = [fig.add_subplot(gs[k // grid.cols, k % grid.cols]) for k in range(n)]
    for ax in axes:
        ax.locator_params(nbins=5)  # fewer ticks: tick artists dominate the drawing time
    return fig, axes


def _head(fig: Figure, title: str, handles: list, ncol: int | None = None) -> None:
    """Figure title at the top and a legend of `handles` under it, outside every panel."""
    h = fig.get_figheight()
    fig.suptitle(title, y=1 - 0.06 / h, va="top")
    if handles:
        fig.legend(
            handles=handles,
            loc="upper center",
            bbox_to_anchor=(0.5, 1 - (0.06 + _TITLE_IN) / h),
            ncol=ncol or len(handles),
            frameon=False,
        )


def _note(fig: Figure, text: str, line: int = 0) -> None:
    """A line of text at the bottom left of the figure, below every panel (`line` 0 the
    lowest, each next one 0.25 in above)."""
    y = (0.06 + 0.25 * line) / fig.get_figheight()
    fig.text(0.01, y, text, fontsize=8, va="bottom", color="0.3")


def _component_handles(symbols: str) -> list:
    """Legend handles of the x, y, z components, labelled e.g. '$F_x$, $M_x$' for 'FM'."""
    from matplotlib.lines import Line2D

    return [
        Line2D([], [], color=c, ls=ls, label=", ".join(f"${s}_{a}$" for s in symbols))
        for a, (c, ls) in COMPONENT_STYLE.items()
    ]


def _line(ax: Axes, x: np.ndarray, y: np.ndarray, curve: bool = False, **style):
    """Plot y against x decimated to its envelope (of y; of x and y when `curve`)."""
    keep = envelope_indices(np.column_stack([x, y]) if curve else y, LINE_BINS)
    return ax.plot(x[keep], y[keep], **style)[0]


def _components(
    ax: Axes, x: np.ndarray, v: np.ndarray, symbol: str, floor: float, curve: bool = False
) -> None:
    """Plot the x, y, z columns of v (n, 3) against x in COMPONENT_STYLE, labelled '$<symbol>_a$',
    with y limits by value_limits(floor)."""
    for i, (a, (color, ls)) in enumerate(COMPONENT_STYLE.items()):
        _line(ax, x, v[:, i], curve=curve, color=color, ls=ls, label=f"${symbol}_{a}$")
    ax.set_ylim(*value_limits(list(v.T), floor))


def _time_axis(ax: Axes, t: np.ndarray) -> None:
    if len(t) and t[-1] > t[0]:
        ax.set_xlim(t[0], t[-1])


def lateral_panel(fig: Figure, ax: Axes, t: np.ndarray, force: np.ndarray, what: str) -> None:
    """Lateral (F_x, F_y) against vertical (F_z) force [N], in COMPONENT_STYLE, with dots at
    TIME_MARKERS evenly spaced instants coloured by time and a time colour bar beside.

    t: (n,) [s]. force: (n, 3) world frame [N]. what: the panel's title.
    """
    from matplotlib.colors import Normalize

    fz = force[:, 2]
    for i, a in enumerate("xy"):
        color, ls = COMPONENT_STYLE[a]
        _line(ax, fz, force[:, i], curve=True, color=color, ls=ls, label=f"$F_{a}$")
    if len(t):
        marks = np.unique(np.linspace(0, len(t) - 1, TIME_MARKERS).round().astype(int))
        norm = Normalize(t[0], t[-1] if t[-1] > t[0] else t[0] + 1.0)
        for i in (0, 1):
            dots = ax.scatter(
                fz[marks], force[marks, i], c=t[marks], cmap="viridis", norm=norm, s=14, zorder=3
            )
        fig.colorbar(dots, cax=ax.inset_axes([1.03, 0.0, 0.035, 1.0]), label="time [s] (dots)")
    ax.set_xlim(*value_limits([fz], FORCE_FLOOR_N))
    ax.set_ylim(*value_limits([force[:, 0], force[:, 1]], FORCE_FLOOR_N))
    ax.set(xlabel="vertical force $F_z$ [N]", ylabel="lateral force [N]", title=what)


#: Figure file formats (``mjrft run --figure-format``): PNG (raster, at most MAX_PNG_PX a side),
#: SVG and PDF (vector: every decimated line point, any zoom).
FIGURE_FORMATS = ("png", "svg", "pdf")


def save_figure(fig: Figure, path: str | os.PathLike) -> Path:
    """Write `fig` in the format of `path`'s suffix (FIGURE_FORMATS) at its own dpi,
    atomically."""
    fmt = Path(path).suffix.lstrip(".").lower()
    if fmt not in FIGURE_FORMATS:
        raise ValueError(f"figure format {fmt!r} of {str(path)!r}; valid: {FIGURE_FORMATS}")
    extra = {"pil_kwargs": {"compress_level": PNG_COMPRESSION}} if fmt == "png" else {}
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=fig.dpi, **extra)
    return Path(path)


def _not_shown(bodies: list[BodySeries], shown: list[int], where: str) -> str | None:
    """The note naming the bodies a figure leaves out, or None."""
    hidden = [b.name for i, b in enumerate(bodies) if i not in shown]
    if not hidden:
        return None
    names = ", ".join(hidden[:6]) + (", ..." if len(hidden) > 6 else "")
    return f"{len(hidden)} bodies with smaller peak |F| not shown ({names}): see {where}"


# ----------------------------------------------------------------------------------------------
# Figures of `mjrft run`.

#: File name of the paper-style summary figure that `mjrft run` writes next to the CSV.
PAPER_PNG = "rft_summary.png"
#: The three figures of ``plot_run`` (names without the format's suffix), in the order written.
RUN_FIGURES = ("forces_vs_time", "forces_vs_depth", "rft_summary")
#: Their PNG file names.
RUN_PNGS = tuple(f"{name}.png" for name in RUN_FIGURES)
#: Resolution of the summary figure [dots per inch].
PAPER_DPI = DPI


def time_figure(t: np.ndarray, bodies: list[BodySeries], title: str | None = None) -> Figure | None:
    """RFT force [N] and torque about the CoM [mN m] vs time [s], world frame, of the bodies
    that went into the medium (``BodySeries.entered``); None if none did.

    Up to MAX_BODY_COLUMNS bodies: a column per body, its x, y, z components in each panel.
    More: a panel per component (F_x ... M_z), a line per body for the MAX_LINES bodies of the
    largest peak |F| (the others named below). The torque row is left out when no body's torque
    reached TORQUE_FLOOR_NM (a panel is never empty).
    """
    left_out = [b.name for b in bodies if not b.entered]
    bodies = [b for b in bodies if b.entered]
    if not bodies:
        return None
    torque = any(b.has_torque for b in bodies)
    what = "RFT force" + (" and torque about the CoM" if torque else "") + " vs time (world frame)"
    if len(bodies) > MAX_BODY_COLUMNS:
        return _time_by_component(t, bodies, figure_title(title, what), torque, left_out)
    rows = 2 if torque else 1
    fig, axes = new_figure(Grid(rows, len(bodies), margins=_margins(left_out)))
    for j, b in enumerate(bodies):
        top = axes[j]
        _components(top, t, b.force, "F", FORCE_FLOOR_N)
        top.set(title=f"{b.name}: RFT force", ylabel="force [N]")
        _time_axis(top, t)
        last = top
        if torque:
            bottom = axes[len(bodies) + j]
            if b.has_torque:
                _components(bottom, t, b.torque * 1e3, "M", TORQUE_FLOOR_NM * 1e3)
                bottom.set(title=f"{b.name}: RFT torque", ylabel="torque about CoM [mN m]")
                _time_axis(bottom, t)
                last = bottom
            else:  # no empty panel: this body's torque is zero throughout
                fig.delaxes(bottom)
        last.set_xlabel("time [s]")
    _head(fig, figure_title(title, what), _component_handles("FM" if torque else "F"))
    _never_entered(fig, left_out)
    return fig


def _margins(left_out: list[str], extra: int = 0) -> tuple[float, float, float, float]:
    """Grid margins with room at the bottom for `extra` notes and the never-entered note."""
    lines = extra + (1 if left_out else 0)
    return (0.8, 0.3, 1.25, 0.55 + 0.25 * lines)


def _never_entered(fig: Figure, names: list[str], line: int = 0) -> None:
    """The note naming the bodies left out because they never went into the medium."""
    if names:
        shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
        _note(fig, f"never in the medium (no RFT force), not drawn: {shown}", line)


def _time_by_component(
    t: np.ndarray, bodies: list[BodySeries], title: str, torque: bool, left_out: list[str]
) -> Figure:
    """time_figure's panel-per-component layout: F_x, F_y, F_z over M_x, M_y, M_z (the torque
    row only if `torque`)."""
    from matplotlib.lines import Line2D

    shown = shown_bodies([b.name for b in bodies], [b.peak_force for b in bodies], MAX_LINES)
    note = _not_shown(bodies, shown, "the table")
    rows = 2 if torque else 1
    fig, axes = new_figure(Grid(rows, 3, margins=_margins(left_out, 1 if note else 0)))
    quantities = (("F", "N", 1.0, FORCE_FLOOR_N), ("M", "mN m", 1e3, TORQUE_FLOOR_NM * 1e3))
    for i, a in enumerate("xyz"):
        for row, (symbol, unit, scale, floor) in enumerate(quantities[:rows]):
            ax = axes[3 * row + i]
            series = [
                (bodies[k].force if row == 0 else bodies[k].torque)[:, i] * scale for k in shown
            ]
            for k, y in zip(shown, series, strict=True):
                _line(ax, t, y, color=f"C{k % 10}", label=bodies[k].name)
            ax.set_ylim(*value_limits(series, floor))
            ax.set(title=f"${symbol}_{a}$ [{unit}]" + (" about each CoM" if symbol == "M" else ""))
            _time_axis(ax, t)
            if row == rows - 1:
                ax.set_xlabel("time [s]")
    handles = [Line2D([], [], color=f"C{k % 10}", label=bodies[k].name) for k in shown]
    _head(fig, title, handles)
    if note:
        _note(fig, note, 1 if left_out else 0)
    _never_entered(fig, left_out)
    return fig


def position_figure(
    bodies: list[BodySeries], surface_z: float | Surface, title: str | None = None
) -> Figure | None:
    """RFT force [N] vs the body's ``abscissa`` (CoM depth, or horizontal distance at about
    constant depth) of the bodies that went into the medium (``BodySeries.entered``; None if
    none did), a panel per body for the MAX_POSITION_PANELS of the largest peak |F|,
    POSITION_COLUMNS to a row; world frame."""
    left_out = [b.name for b in bodies if not b.entered]
    above = [b.name for b in bodies if b.entered and not goes_in(b.com, surface_z)]
    bodies = [b for b in bodies if b.entered and b.name not in above]
    if not bodies:
        return None
    shown = shown_bodies([b.name for b in bodies], [b.peak_force for b in bodies],
                         MAX_POSITION_PANELS)  # fmt: skip
    note = _not_shown(bodies, shown, "forces_vs_time")
    cols = min(len(shown), POSITION_COLUMNS)
    rows = -(-len(shown) // cols)
    margins = _margins(left_out, (1 if note else 0) + (1 if above else 0))
    fig, axes = new_figure(Grid(rows, cols, panel=(4.3, 2.8), margins=margins), len(shown))
    for ax, k in zip(axes, shown, strict=True):
        b = bodies[k]
        x = abscissa(b.com, surface_z)
        _components(ax, x.values, b.force, "F", FORCE_FLOOR_N, curve=True)
        ax.set(title=f"{b.name}: force vs {x.name}", xlabel=x.label, ylabel="RFT force [N]")
    what = "RFT force vs CoM depth (or horizontal distance at constant depth), world frame"
    _head(fig, figure_title(title, what), _component_handles("F"))
    notes = [n for n in (note, _above_note(above)) if n]
    for line, text in enumerate(notes, start=1 if left_out else 0):
        _note(fig, text, line)
    _never_entered(fig, left_out)
    return fig


def _above_note(names: list[str]) -> str | None:
    """The note naming the bodies not drawn against their depth: their CoM stays above."""
    if not names:
        return None
    shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
    return f"CoM never below the surface, not drawn against depth: {shown} (see forces_vs_time)"


def _summary_panels(
    bodies: list[BodySeries], shown: list[int], surface_z: float | Surface
) -> list[tuple[str, int]]:
    """The summary's panels, (kind, body index), each with something to show: force vs time
    always; force vs position if the CoM goes below the surface (``goes_in``), torque vs
    position too if the torque reached its floor; lateral vs vertical force if the lateral
    force did."""
    panels = []
    for k in shown:
        b = bodies[k]
        if goes_in(b.com, surface_z):
            panels += [("force", k)] + ([("torque", k)] if b.has_torque else [])
        panels += [("time", k)] + ([("lateral", k)] if b.has_lateral else [])
    return panels


def paper_figure(
    t: np.ndarray, bodies: list[BodySeries], surface_z: float | Surface, title: str | None = None
) -> Figure | None:
    """Paper-style summary of the MAX_SUMMARY_BODIES bodies of the largest peak |F| that went
    into the medium (None if none did), world frame, two panels to a row: (a) RFT force [N] vs
    the body's ``abscissa`` (CoM depth, or horizontal distance at about constant depth) [cm];
    (b) RFT torque about the CoM [mN m] vs the same; (c) force vs time [s]; (d)
    ``lateral_panel``: F_x, F_y vs F_z, dots coloured by time. (a) and (b) only for a CoM that
    goes below the surface, (b) and (d) only where the torque or the lateral force reached its
    floor (``_summary_panels``: no empty panel, no depth above the surface)."""
    left_out = [b.name for b in bodies if not b.entered]
    bodies = [b for b in bodies if b.entered]
    if not bodies:
        return None
    shown = shown_bodies([b.name for b in bodies], [b.peak_force for b in bodies],
                         MAX_SUMMARY_BODIES)  # fmt: skip
    note = _not_shown(bodies, shown, "forces_vs_time")
    panels = _summary_panels(bodies, shown, surface_z)
    margins = (0.8, 0.95, *_margins(left_out, 1 if note else 0)[2:])
    grid = Grid(-(-len(panels) // 2), 2, panel=(5.0, 3.0), gap=(0.9, 0.8), margins=margins)
    fig, axes = new_figure(grid, len(panels))
    for ax, (kind, k) in zip(axes, panels, strict=True):
        b = bodies[k]
        x = abscissa(b.com, surface_z)
        if kind == "force":
            _components(ax, x.values, b.force, "F", FORCE_FLOOR_N, curve=True)
            ax.set(title=f"{b.name}: force vs {x.name}", xlabel=x.label, ylabel="RFT force [N]")
        elif kind == "torque":
            _components(ax, x.values, b.torque * 1e3, "M", TORQUE_FLOOR_NM * 1e3, curve=True)
            ax.set(title=f"{b.name}: torque vs {x.name}", xlabel=x.label)
            ax.set_ylabel("RFT torque about CoM [mN m]")
        elif kind == "time":
            _components(ax, t, b.force, "F", FORCE_FLOOR_N)
            ax.set(title=f"{b.name}: force vs time", xlabel="time [s]", ylabel="RFT force [N]")
            _time_axis(ax, t)
        else:
            lateral_panel(fig, ax, t, b.force, f"{b.name}: lateral vs vertical force")
    torque = any(kind == "torque" for kind, _ in panels)
    _head(fig, figure_title(title, "RFT summary (world frame)"),
          _component_handles("FM" if torque else "F"))  # fmt: skip
    if note:
        _note(fig, note, 1 if left_out else 0)
    _never_entered(fig, left_out)
    return fig


@_styled
def plot_run(
    rec,
    surface_z: float | Surface,
    out_dir: str | os.PathLike,
    stem: str = "",
    title: str | None = None,
    fmt: str = "png",
) -> list[Path]:
    """The figures of a `mjrft run` recording (``time_figure``, ``position_figure``,
    ``paper_figure``) that have something to show: a figure of bodies that never went into the
    medium is not drawn. A PNG is at most MAX_PNG_PX pixels wide and high.

    Args:
      rec: mjrft.app.simulate.Recording. surface_z: free-surface height [m], or the Surface.
      out_dir: directory; files are '<stem>forces_vs_time.<fmt>', '<stem>forces_vs_depth.<fmt>'
        and '<stem>rft_summary.<fmt>' (RUN_FIGURES).
      stem: file name prefix. title: first line of every figure's title (e.g. the scene, its
        material and triangle count), or None. fmt: 'png', 'svg' or 'pdf' (FIGURE_FORMATS).
    Returns:
      The paths written, in RUN_FIGURES order.
    """
    if fmt not in FIGURE_FORMATS:
        raise ValueError(f"figure format {fmt!r}; valid: {', '.join(FIGURE_FORMATS)}")
    t, bodies = run_series(rec)
    figures = (
        time_figure(t, bodies, title),
        position_figure(bodies, surface_z, title),
        paper_figure(t, bodies, surface_z, title),
    )
    out = Path(out_dir)
    return [
        save_figure(f, out / f"{stem}{name}.{fmt}")
        for f, name in zip(figures, RUN_FIGURES, strict=True)
        if f is not None
    ]


def panel_counts(
    t: np.ndarray, bodies: list[BodySeries], surface_z: float | Surface
) -> dict[str, int]:
    """The number of panels each figure of ``plot_run`` will have (0: not drawn), by
    RUN_FIGURES name, computed from the data alone (no matplotlib): what a figure costs."""
    entered = [b for b in bodies if b.entered]
    torque = any(b.has_torque for b in entered)
    if len(entered) > MAX_BODY_COLUMNS:
        n_time = 3 * (2 if torque else 1)
    else:
        n_time = len(entered) + sum(b.has_torque for b in entered)
    inside = [b for b in entered if goes_in(b.com, surface_z)]
    shown = shown_bodies([b.name for b in entered], [b.peak_force for b in entered],
                         MAX_SUMMARY_BODIES)  # fmt: skip
    return {
        "forces_vs_time": n_time,
        "forces_vs_depth": min(len(inside), MAX_POSITION_PANELS),
        "rft_summary": len(_summary_panels(entered, shown, surface_z)) if entered else 0,
    }


#: The order in which ``plot_run_within`` draws the figures: the summary holds the most in one
#: figure, the time series next.
FIGURE_PRIORITY = ("rft_summary", "forces_vs_time", "forces_vs_depth")
#: Estimates of a figure's cost before any was timed, measured on the Xeon VM of RESULTS.md
#: (benchmarks/plots.py): importing matplotlib [s] and drawing and writing one panel [s].
MATPLOTLIB_IMPORT_S, PANEL_S = 0.5, 0.12
#: A figure is drawn only if its estimate times this still fits: the estimates come from the
#: figures before it and the machine's load changes (one 10 s run overran by 2 % without it).
ESTIMATE_MARGIN = 1.25


def figure_floor_s() -> float:
    """The least a figure can cost [s] by the estimates: one panel, and importing matplotlib
    if it is not imported yet (``plot_run_within``)."""
    import sys

    least = PANEL_S + (0.0 if "matplotlib.figure" in sys.modules else MATPLOTLIB_IMPORT_S)
    return ESTIMATE_MARGIN * least


@_styled
def plot_run_within(
    rec,
    surface_z: float | Surface,
    out_dir: str | os.PathLike,
    budget_s: float,
    title: str | None = None,
    fmt: str = "png",
    clock=time.perf_counter,
) -> tuple[list[Path], list[str]]:
    """``plot_run``'s figures, drawn in FIGURE_PRIORITY order only while their cost stays
    within `budget_s` [s] (e.g. the simulation's wall time), counted from this call: a figure
    is drawn if the time spent so far plus ESTIMATE_MARGIN times its estimated cost fits. The
    estimate is its panels (``panel_counts``) times the cost per panel measured on the figures
    drawn so far (PANEL_S before the first), plus MATPLOTLIB_IMPORT_S if matplotlib is not
    imported yet.

    Returns:
      (the paths written, in RUN_FIGURES order; the names of the figures left out for the
      budget, in FIGURE_PRIORITY order).
    """
    import sys

    if fmt not in FIGURE_FORMATS:
        raise ValueError(f"figure format {fmt!r}; valid: {', '.join(FIGURE_FORMATS)}")
    start = clock()
    t, bodies = run_series(rec)
    panels = panel_counts(t, bodies, surface_z)
    build = {
        "forces_vs_time": lambda: time_figure(t, bodies, title),
        "forces_vs_depth": lambda: position_figure(bodies, surface_z, title),
        "rft_summary": lambda: paper_figure(t, bodies, surface_z, title),
    }
    written: dict[str, Path] = {}
    skipped: list[str] = []
    drawn_panels, drawing_s = 0, 0.0
    for name in FIGURE_PRIORITY:
        if not panels[name]:
            continue
        per_panel = drawing_s / drawn_panels if drawn_panels else PANEL_S
        estimate = panels[name] * per_panel
        if "matplotlib.figure" not in sys.modules:
            estimate += MATPLOTLIB_IMPORT_S
        if clock() - start + ESTIMATE_MARGIN * estimate > budget_s:
            skipped.append(name)
            continue
        import matplotlib.figure  # noqa: F401  (imported here, timed apart from the drawing)

        t0 = clock()
        fig = build[name]()
        if fig is not None:
            written[name] = save_figure(fig, Path(out_dir) / f"{name}.{fmt}")
        drawing_s += clock() - t0
        drawn_panels += panels[name]
    return [written[n] for n in RUN_FIGURES if n in written], skipped


@_styled
def plot_paper(
    rec, surface_z: float | Surface, path: str | os.PathLike, title: str | None = None
) -> Path | None:
    """The paper-style summary (``paper_figure``) of a run, written atomically in the format
    of `path`'s suffix; None (nothing written) if no body went into the medium.

    Args:
      rec: mjrft.app.simulate.Recording. surface_z: free-surface height [m].
      path: figure file. title: first line of the figure's title (default: none).
    """
    t, bodies = run_series(rec)
    fig = paper_figure(t, bodies, surface_z, title)
    return None if fig is None else save_figure(fig, path)


# ----------------------------------------------------------------------------------------------
# Figures of `mjrft demo`.


@_styled
def plot_demo(result: DemoResult, path: str | os.PathLike) -> Path:
    """Force and moment vs pivot depth, and lateral vs vertical force, of a prescribed demo as
    one PNG (world frame), written atomically."""
    fig, (ax_f, ax_m, ax_lv) = new_figure(
        Grid(1, 3, panel=(4.3, 3.2), margins=(0.8, 0.95, 1.2, 0.6))
    )
    depth_cm = result.depth / CM
    _components(ax_f, depth_cm, result.force, "F", FORCE_FLOOR_N, curve=True)
    _components(ax_m, depth_cm, result.moment * 1e3, "M", TORQUE_FLOOR_NM * 1e3, curve=True)
    ax_f.set(xlabel="pivot depth [cm]", ylabel="RFT force [N]", title="force vs depth")
    ax_m.set(xlabel="pivot depth [cm]", ylabel="RFT moment about pivot [mN m]")
    ax_m.set_title("moment vs depth")
    lateral_panel(fig, ax_lv, result.time, result.force, "lateral vs vertical force")
    title = f"{result.title}\n{result.n_elements} triangles, world frame"
    _head(fig, title, _component_handles("FM"))
    return save_figure(fig, path)


@_styled
def plot_time_series(result: DemoResult, path: str | os.PathLike) -> Path:
    """Force components vs time of a prescribed demo, with the pitch (if any) on a second axis,
    as a PNG."""
    from matplotlib.lines import Line2D

    fig, (ax,) = new_figure(Grid(1, 1, panel=(8.5, 3.2), margins=(0.8, 0.8, 1.0, 0.55)))
    _components(ax, result.time, result.force, "F", FORCE_FLOOR_N)
    ax.set(xlabel="time [s]", ylabel="RFT force [N] (world frame)")
    _time_axis(ax, result.time)
    handles = _component_handles("F")
    if "pitch" in result.extra:
        ax2 = ax.twinx()
        _line(ax2, result.time, np.degrees(result.extra["pitch"]), color="k", ls=":")
        ax2.set_ylabel("pitch [deg]")
        handles.append(Line2D([], [], color="k", ls=":", label="pitch"))
    _head(fig, result.title, handles)
    return save_figure(fig, path)


@_styled
def plot_rig_vs_prescribed(
    rec, body: str, prescribed: DemoResult, path: str | os.PathLike, title: str
) -> Path:
    """RFT force vs time of a simulated rig (solid) against the prescribed-trajectory demo
    (dashed), world frame, as a PNG."""
    t, bodies = run_series(rec)
    force = next(b.force for b in bodies if b.name == body)
    fig, (ax,) = new_figure(Grid(1, 1, panel=(8.5, 3.4), margins=(0.8, 0.3, 1.15, 0.55)))
    for i, a in enumerate("xyz"):
        color = COMPONENT_STYLE[a][0]
        _line(ax, t, force[:, i], color=color, label=f"$F_{a}$ simulated rig")
        _line(ax, prescribed.time, prescribed.force[:, i], color=color, ls="--",
              label=f"$F_{a}$ prescribed")  # fmt: skip
    shown = prescribed.time <= (t[-1] if len(t) else np.inf)  # the rig's time span only
    ax.set_ylim(*value_limits([*force.T, *prescribed.force[shown].T], FORCE_FLOOR_N))
    _time_axis(ax, t)
    ax.set(xlabel="time [s]", ylabel="RFT force on the intruder [N]")
    _head(fig, f"{title}\nworld frame", ax.get_lines(), ncol=3)
    return save_figure(fig, path)
