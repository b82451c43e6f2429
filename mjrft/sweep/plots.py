"""Figures of a study's results, one PNG per metric in the results folder (``<metric>.png``):
a line against the parameter when one parameter varies, a heat map when two vary on a grid, and
otherwise a panel per parameter with the metric against it (scatter). Failed runs are left out
(a heat map marks their cells); matplotlib's object API, Agg canvas."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from mjrft.sweep.executor import STATUS_OK
from mjrft.sweep.metrics import KINDS, MetricSpec
from mjrft.sweep.results import load_results
from mjrft.sweep.study import Parameter, Study

#: Heat map cells up to this many are labelled with their values.
MAX_LABELLED_CELLS = 100


def _label(m: MetricSpec) -> str:
    unit = KINDS[m.kind][2]
    return m.name if unit in ("sensor's", "yours", "1") else f"{m.name} [{unit}]"


def _axis(values: list[Any]) -> tuple[list[Any], bool]:
    """The distinct values in axis order (sorted if all numbers) and whether they are numbers."""
    distinct = list(dict.fromkeys(json.dumps(v) for v in values))
    vals = [json.loads(v) for v in distinct]
    numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in vals)
    return (sorted(vals) if numeric else vals), numeric


def varied(study: Study) -> list[Parameter]:
    """The parameters that take more than one value in the study's runs."""
    runs = study.runs()
    return [p for p in study.parameters if len(_axis([r.values[p.name] for r in runs])[0]) > 1]


def plot_study(study: Study, out: str | Path) -> list[Path]:
    """Draw the figures of the results in `out`; returns the PNGs written (none if no parameter
    varies or no run succeeded)."""
    import matplotlib

    from mjrft.app import report

    out = Path(out)
    rows = [r for r in load_results(out) if r["status"] == STATUS_OK]
    params = varied(study)
    failed = len(load_results(out)) - len(rows)
    if not params or not rows:
        return []
    written = []
    with matplotlib.rc_context(report.STYLE):
        for m in study.metrics:
            if len(params) == 1:
                fig = _line(study, params[0], m, rows)
            elif len(params) == 2 and study.sampling == "grid":
                fig = _heat_map(study, params, m, load_results(out))
            else:
                fig = _scatter(study, params, m, rows)
            note = f"{len(rows)} runs" + (f", {failed} failed (not shown)" if failed else "")
            fig.text(0.01, 0.01, f"{study.name}: {note}; results.csv", fontsize=8, color="0.3")
            written.append(report.save_figure(fig, out / f"{m.name}.png"))
    return written


def _positions(values: list[Any], axis: list[Any], numeric: bool) -> np.ndarray:
    if numeric:
        return np.array(values, dtype=float)
    keys = [json.dumps(a) for a in axis]
    return np.array([keys.index(json.dumps(v)) for v in values], dtype=float)


def _tick(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _categories(ax: Any, axis: list[Any], which: str) -> None:
    ticks, labels = list(range(len(axis))), [_tick(a) for a in axis]
    if which == "x":
        ax.set_xticks(ticks, labels)
    else:
        ax.set_yticks(ticks, labels)


def _line(study: Study, p: Parameter, m: MetricSpec, rows: list[dict]) -> Any:
    from mjrft.app import report

    fig, (ax,) = report.new_figure(
        report.Grid(1, 1, panel=(6.0, 3.6), margins=(0.9, 0.3, 0.6, 0.7))
    )
    axis, numeric = _axis([r[p.name] for r in rows])
    x = _positions([r[p.name] for r in rows], axis, numeric)
    y = np.array([r[m.name] for r in rows], dtype=float)
    order = np.argsort(x, kind="stable")
    ax.plot(x[order], y[order], "o-", color="C0")
    if not numeric:
        _categories(ax, axis, "x")
    ax.set(xlabel=p.name, ylabel=_label(m), title=f"{study.name}: {m.name} vs {p.name}")
    ax.grid(alpha=0.3)
    return fig


def _heat_map(study: Study, params: list[Parameter], m: MetricSpec, rows: list[dict]) -> Any:
    from mjrft.app import report

    px, py = params
    runs = study.runs()
    xs, _ = _axis([r.values[px.name] for r in runs])
    ys, _ = _axis([r.values[py.name] for r in runs])
    grid = np.full((len(ys), len(xs)), math.nan)
    failed = np.zeros_like(grid, dtype=bool)
    kx, ky = [json.dumps(v) for v in xs], [json.dumps(v) for v in ys]
    for r in rows:
        j, i = ky.index(json.dumps(r[py.name])), kx.index(json.dumps(r[px.name]))
        if r["status"] == STATUS_OK:
            grid[j, i] = r[m.name]
        else:
            failed[j, i] = True
    g = report.Grid(1, 1, panel=(6.0, 4.2), margins=(1.0, 1.2, 0.6, 0.8))
    fig, (ax,) = report.new_figure(g)
    image = ax.imshow(np.ma.masked_invalid(grid), origin="lower", aspect="auto", cmap="viridis")
    fig.colorbar(image, cax=ax.inset_axes([1.03, 0.0, 0.04, 1.0]), label=_label(m))
    if grid.size <= MAX_LABELLED_CELLS:
        finite = grid[np.isfinite(grid)]
        middle = 0.5 * (finite.min() + finite.max()) if finite.size else 0.0
        for (j, i), v in np.ndenumerate(grid):
            text = "failed" if failed[j, i] else ("" if math.isnan(v) else f"{v:.3g}")
            ax.text(i, j, text, ha="center", va="center", fontsize=7,
                    color="white" if v < middle or failed[j, i] else "black")  # fmt: skip
    _categories(ax, xs, "x")
    _categories(ax, ys, "y")
    ax.grid(False)  # the style's grid would cross the cells
    ax.set(xlabel=px.name, ylabel=py.name, title=f"{study.name}: {_label(m)}")
    return fig


def _scatter(study: Study, params: list[Parameter], m: MetricSpec, rows: list[dict]) -> Any:
    from mjrft.app import report

    cols = min(3, len(params))
    grid = report.Grid(math.ceil(len(params) / cols), cols, panel=(4.0, 3.0),
                       margins=(0.9, 0.3, 0.6, 0.7))  # fmt: skip
    fig, axes = report.new_figure(grid, len(params))
    y = np.array([r[m.name] for r in rows], dtype=float)
    for ax, p in zip(axes, params, strict=True):
        axis, numeric = _axis([r[p.name] for r in rows])
        ax.plot(_positions([r[p.name] for r in rows], axis, numeric), y, "o", ms=4, alpha=0.7)
        if not numeric:
            _categories(ax, axis, "x")
        ax.set(xlabel=p.name, ylabel=_label(m))
        ax.grid(alpha=0.3)
    fig.suptitle(f"{study.name}: {m.name} against each parameter")
    return fig
