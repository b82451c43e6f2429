"""The figure rules of mjrft.app.report: decimation, axis limits, abscissa, layout and legends.

Synthetic recordings (seeded), checked against plainly written references and against what the
figures' docstrings promise; no simulation, so the module runs in about a second.
"""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from mjrft.app import report
from mjrft.app.simulate import Recording


def _envelope_reference(v: np.ndarray, n_bins: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per run of ceil(n / n_bins) rows: (min, max) of every column, by a plain loop."""
    size = -(-len(v) // n_bins)
    return [
        (v[s : s + size].min(axis=0), v[s : s + size].max(axis=0)) for s in range(0, len(v), size)
    ]


@pytest.mark.parametrize("n, k, n_bins", [(10_007, 3, 100), (5_000, 1, 7), (2_001, 2, 1000)])
def test_envelope_indices_keep_every_runs_extremes(n, k, n_bins):
    rng = np.random.default_rng(3)
    v = rng.standard_normal((n, k)).cumsum(axis=0)
    keep = report.envelope_indices(v, n_bins)
    assert keep[0] == 0 and keep[-1] == n - 1
    assert np.all(np.diff(keep) > 0)  # sorted, unique
    assert len(keep) <= 2 * k * n_bins + 2
    size = -(-n // n_bins)
    for run, (lo, hi) in enumerate(_envelope_reference(v, n_bins)):
        picked = v[keep[(keep >= run * size) & (keep < (run + 1) * size)]]
        np.testing.assert_array_equal(picked.min(axis=0), lo)
        np.testing.assert_array_equal(picked.max(axis=0), hi)


def test_envelope_indices_keep_short_series_whole():
    np.testing.assert_array_equal(report.envelope_indices(np.arange(20.0), 10), np.arange(20))


def test_a_spike_survives_decimation():
    v = np.zeros(1_000_000)
    v[123_457] = 5.0  # one sample: a collision's impulse
    keep = report.envelope_indices(v, report.LINE_BINS)
    assert 123_457 in keep and len(keep) <= 2 * report.LINE_BINS + 2


def test_value_limits_draw_round_off_flat():
    rng = np.random.default_rng(0)
    signal = np.linspace(0.5, 1.0, 50)
    noise = 1e-17 * rng.standard_normal(50)  # a symmetric body's lateral force
    lo, hi = report.value_limits([signal, noise], report.FORCE_FLOOR_N)
    m = report.LIMIT_MARGIN
    # The noise sets no limit, but its flat line at zero is in view: span [0, 1] plus margins.
    assert lo == pytest.approx(-m) and hi == pytest.approx(1 + m)
    # Alone, noise below the floor gives the floor's band, not a 1e-17 axis.
    assert report.value_limits([noise], report.FORCE_FLOOR_N) == (
        -report.FORCE_FLOOR_N,
        report.FORCE_FLOOR_N,
    )


def test_value_limits_of_a_constant_and_non_finite_values():
    lo, hi = report.value_limits([np.array([0.3226, np.nan, 0.3226, np.inf, 0.3226])], 1e-6)
    m = report.LIMIT_MARGIN
    assert (lo, hi) == pytest.approx((0.3226 * (1 - m), 0.3226 * (1 + m)))


def test_abscissa_is_depth_for_a_drop_and_travel_for_a_drag():
    n = 100
    drop = np.column_stack([np.zeros(n), np.zeros(n), np.linspace(0.0, -0.05, n)])
    x = report.abscissa(drop, surface_z=0.0)
    assert x.name == "depth"
    np.testing.assert_allclose(x.values, np.linspace(0.0, 5.0, n))  # cm
    drag = np.column_stack([np.linspace(0, 0.03, n), np.linspace(0, 0.04, n), np.full(n, -0.02)])
    drag[:, 2] += 1e-4 * np.sin(np.arange(n))  # 0.2 mm of bobbing: about constant depth
    x = report.abscissa(drag, surface_z=0.0)
    assert x.name == "horizontal distance"
    np.testing.assert_allclose(x.values, np.linspace(0, 5.0, n))  # |(3, 4)| cm at the end


def _recording(n_bodies: int, n_rows: int, seed: int = 1) -> Recording:
    """A recording of `n_bodies` bodies sinking at different rates; F_x is round-off."""
    rng = np.random.default_rng(seed)
    names = [f"body{i}" for i in range(n_bodies)]
    columns = ["time_s"]
    for b in names:
        columns += [f"{b}_com_{a}_m" for a in "xyz"]
        columns += [f"{b}_rft_force_{a}_N" for a in "xyz"]
        columns += [f"{b}_rft_torque_{a}_Nm" for a in "xyz"]
    t = np.linspace(0.0, 2.0, n_rows)
    blocks = [t[:, None]]
    for i in range(n_bodies):
        depth = 0.01 * (1 + i) * t
        com = np.column_stack([0.1 * i + 0 * t, 0 * t, -depth])
        force = np.column_stack(
            [1e-17 * rng.standard_normal(n_rows), 0.1 * np.sin(t), (1 + i) * depth * 100]
        )
        torque = 1e-3 * rng.standard_normal((n_rows, 3))
        blocks += [com, force, torque]
    data = np.column_stack(blocks)
    return Recording(columns, names, rows=list(data))


def test_legend_line_styles_are_those_of_the_lines():
    rec = _recording(2, 300)
    t, bodies = report.run_series(rec)
    fig = report.time_figure(t, bodies, "title")
    styles = {h.get_label(): h.get_linestyle() for h in fig.legends[0].legend_handles}
    assert len(styles) == 3
    for ax in fig.axes:
        for line in ax.get_lines():
            component = line.get_label()[-2]  # '$F_y$' -> 'y'
            (style,) = [s for label, s in styles.items() if f"_{component}$" in label]
            assert line.get_linestyle() == style, (ax.get_title(), line.get_label())
    assert styles["$F_y$, $M_y$"] == "--"  # y is the dashed one, and the legend says so


def test_round_off_panel_is_flat_and_signal_sets_the_axis():
    rec = _recording(1, 200)
    t, bodies = report.run_series(rec)
    fig = report.time_figure(t, bodies)
    lo, hi = fig.axes[0].get_ylim()  # body0's force: F_x ~ 1e-17, F_z up to 2 N
    assert lo < 0 < hi and hi - lo > 1.0


def test_figures_of_many_bodies_and_long_runs_stay_bounded(tmp_path):
    rec = _recording(12, 50_000)
    paths = report.plot_run(rec, 0.0, tmp_path, title="twelve bodies: glass_beads, 100 triangles")
    assert [p.name for p in paths] == list(report.RUN_PNGS)
    for p in paths:
        w, h = Image.open(p).size
        assert max(w, h) <= report.MAX_PNG_PX, (p.name, w, h)
    t, bodies = report.run_series(rec)
    fig = report.time_figure(t, bodies)
    lines = [ln for ax in fig.axes for ln in ax.get_lines()]
    assert len(lines) == 6 * report.MAX_LINES  # six component panels, the largest bodies only
    assert max(len(ln.get_xdata()) for ln in lines) <= 2 * report.LINE_BINS + 2
    notes = [x.get_text() for x in fig.texts if "not shown" in x.get_text()]
    assert notes and "body0" in notes[0]  # the smallest forces are left out, and named
    assert "body11" in {ln.get_label() for ln in lines}


def test_titles_carry_the_run_title():
    rec = _recording(1, 50)
    t, bodies = report.run_series(rec)
    fig = report.paper_figure(t, bodies, 0.0, "sphere_drop.xml: glass_beads, 2976 triangles")
    assert fig._suptitle.get_text().startswith("sphere_drop.xml: glass_beads, 2976 triangles\n")


# ----------------------------------------------------------------------------------------------
# Which figures and panels a run gets: never an empty panel, depth only for a CoM that goes in.


def _bodies_recording(n_rows: int = 400) -> Recording:
    """Three bodies: 'leg' sinks 2 cm (CoM below the surface), feels a vertical force, a
    lateral one and a torque; 'torso' feels a vertical force with its CoM 3 cm above the surface
    throughout (its belly touches); 'arm' never touches the medium (no force)."""
    t = np.linspace(0.0, 1.0, n_rows)
    zero = np.zeros(n_rows)
    com = {"leg": np.column_stack([zero, zero, 0.01 - 0.03 * t]),
           "torso": np.column_stack([zero, zero, 0.03 + 0.005 * np.sin(t)]),
           "arm": np.column_stack([zero + 0.1, zero, zero + 0.2])}  # fmt: skip
    force = {"leg": np.column_stack([0.1 * np.sin(6 * t), zero, 2.0 * t]),
             "torso": np.column_stack([1e-18 * np.cos(t), zero, 3.0 * t]),
             "arm": np.zeros((n_rows, 3))}  # fmt: skip
    torque = {"leg": np.column_stack([1e-3 * t, zero, zero]),
              "torso": np.zeros((n_rows, 3)), "arm": np.zeros((n_rows, 3))}  # fmt: skip
    columns, blocks = ["time_s"], [t[:, None]]
    for b in com:
        columns += [f"{b}_com_{a}_m" for a in "xyz"]
        columns += [f"{b}_rft_force_{a}_N" for a in "xyz"]
        columns += [f"{b}_rft_torque_{a}_Nm" for a in "xyz"]
        blocks += [com[b], force[b], torque[b]]
    return Recording(columns, list(com), rows=list(np.column_stack(blocks)))


def _panels(fig) -> list:
    """The figure's data panels (not colour bars)."""
    return [ax for ax in fig.axes if ax.get_title()]


def _assert_no_empty_panel(fig) -> None:
    for ax in _panels(fig):
        peaks = [np.max(np.abs(ln.get_ydata())) for ln in ax.get_lines()]
        floor = report.FORCE_FLOOR_N if "torque" not in ax.get_title() else 1e-9 * 1e3
        assert peaks and max(peaks) >= floor, ax.get_title()


def _notes(fig) -> str:
    return " | ".join(t.get_text() for t in fig.texts)


def test_force_vs_depth_only_for_bodies_whose_com_goes_into_the_medium():
    t, bodies = report.run_series(_bodies_recording())
    fig = report.position_figure(bodies, 0.0)
    assert [ax.get_title() for ax in _panels(fig)] == ["leg: force vs depth"]
    assert "not drawn against depth: torso" in _notes(fig)
    assert "never in the medium (no RFT force), not drawn: arm" in _notes(fig)
    summary = report.paper_figure(t, bodies, 0.0)
    titles = [ax.get_title() for ax in _panels(summary)]
    assert titles == ["leg: force vs depth", "leg: torque vs depth", "leg: force vs time",
                      "leg: lateral vs vertical force", "torso: force vs time"]  # fmt: skip
    for figure in (fig, summary, report.time_figure(t, bodies)):
        _assert_no_empty_panel(figure)


def test_a_sphere_dropped_straight_down_gets_no_torque_or_lateral_panel():
    """Its torque and lateral force are round-off: the summary has force vs depth and vs time
    only, the time figure no torque row."""
    n = 300
    t = np.linspace(0, 1, n)
    cols = ["time_s", *(f"sphere_com_{a}_m" for a in "xyz"),
            *(f"sphere_rft_force_{a}_N" for a in "xyz"),
            *(f"sphere_rft_torque_{a}_Nm" for a in "xyz")]  # fmt: skip
    rng = np.random.default_rng(5)
    rows = np.column_stack([t, 0 * t, 0 * t, 0.011 - 0.02 * t, 1e-17 * rng.standard_normal((n, 2)),
                            0.5 * t, 1e-19 * rng.standard_normal((n, 3))])  # fmt: skip
    rec = Recording(cols, ["sphere"], rows=list(rows))
    t, bodies = report.run_series(rec)
    summary = report.paper_figure(t, bodies, 0.0)
    assert [ax.get_title() for ax in _panels(summary)] == [
        "sphere: force vs depth", "sphere: force vs time"]  # fmt: skip
    time_fig = report.time_figure(t, bodies)
    assert [ax.get_title() for ax in _panels(time_fig)] == ["sphere: RFT force"]
    for fig in (summary, time_fig, report.position_figure(bodies, 0.0)):
        _assert_no_empty_panel(fig)


def test_a_run_that_never_touched_the_medium_gets_no_figures(tmp_path):
    rec = _bodies_recording()
    keep = [i for i, c in enumerate(rec.columns) if c == "time_s" or c.startswith("arm_")]
    quiet = Recording([rec.columns[i] for i in keep], ["arm"], rows=[r[keep] for r in rec.rows])
    assert report.plot_run(quiet, 0.0, tmp_path) == []
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(("fmt", "magic"), [("png", b"\x89PNG"), ("svg", b"<?xml"),
                                            ("pdf", b"%PDF")])  # fmt: skip
def test_figures_in_each_format(tmp_path, fmt, magic):
    paths = report.plot_run(_bodies_recording(), 0.0, tmp_path, fmt=fmt)
    assert [p.name for p in paths] == [f"{n}.{fmt}" for n in report.RUN_FIGURES]
    for p in paths:
        assert p.read_bytes().startswith(magic), p
    with pytest.raises(ValueError, match="figure format 'jpg'; valid: png, svg, pdf"):
        report.plot_run(_bodies_recording(), 0.0, tmp_path, fmt="jpg")


def test_panel_counts_are_the_figures_panels():
    for rec in (_bodies_recording(), _recording(12, 500), _recording(2, 300)):
        t, bodies = report.run_series(rec)
        counts = report.panel_counts(t, bodies, 0.0)
        figures = {"forces_vs_time": report.time_figure(t, bodies),
                   "forces_vs_depth": report.position_figure(bodies, 0.0),
                   "rft_summary": report.paper_figure(t, bodies, 0.0)}  # fmt: skip
        for name, fig in figures.items():
            assert counts[name] == (len(_panels(fig)) if fig is not None else 0), name


def test_figures_are_drawn_by_priority_while_their_estimated_cost_fits(tmp_path, monkeypatch):
    """A clock that advances 0.4 s per panel written, a budget of 2.6 s: the summary (5 panels,
    estimated at PANEL_S each, times ESTIMATE_MARGIN) is drawn and takes 2 s; forces_vs_time
    (3 panels, now estimated at 0.4 s each) would end at 2 + 1.25 x 1.2 = 3.5 s and is left
    out; forces_vs_depth (1 panel: 2 + 1.25 x 0.4 = 2.5 s) fits."""
    import matplotlib.figure  # noqa: F401  (imported: no import cost in the estimate)

    now = [0.0]
    save = report.save_figure

    def timed_save(fig, path):
        now[0] += 0.4 * len(_panels(fig))
        return save(fig, path)

    monkeypatch.setattr(report, "save_figure", timed_save)
    rec = _bodies_recording()
    paths, skipped = report.plot_run_within(rec, 0.0, tmp_path, 2.6, clock=lambda: now[0])
    assert [p.name for p in paths] == ["forces_vs_depth.png", "rft_summary.png"]
    assert skipped == ["forces_vs_time"] and now[0] == pytest.approx(2.4)
    now[0] = 0.0
    assert report.plot_run_within(rec, 0.0, tmp_path, 0.0, clock=lambda: now[0]) == (
        [], list(report.FIGURE_PRIORITY))  # fmt: skip
