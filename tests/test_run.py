"""Runs never record garbage silently and never lose what they computed."""

from pathlib import Path

import numpy as np
import pytest

from mjrft import simulate

MODELS = Path(__file__).resolve().parents[1] / "models"


def test_a_diverging_run_stops_naming_the_time_and_keeps_the_rows_before():
    """The ellipsoid rig is unstable at 5 ms (with or without the field): MuJoCo warns and
    resets the state; the run must stop there instead of recording a different simulation."""
    model = simulate.load_model(str(MODELS / "ellipsoid_pitch.xml"))
    simulate.configure(model, 0.005, None)
    rec = simulate.new_recording(model, simulate.GranularField(model, n_triangles=200))
    with pytest.raises(simulate.RunDiverged, match=r"diverged at t = .* s \(step \d+\).*QACC") as e:
        simulate.run(model, 3.0, recording=rec, fld=simulate.GranularField(model, n_triangles=200))
    t = rec.array()[:, 0]
    assert len(t) > 10 and np.all(np.diff(t) > 0)  # time never runs backwards
    assert t[-1] < e.value.time  # nothing recorded from the diverged step on
    assert np.all(np.isfinite(rec.array()))


def test_rows_stream_to_the_csv_exactly_and_read_back_decimated(tmp_path):
    columns = ["time_s", "a", "b"]
    sink = simulate.CsvSink(tmp_path / "t.csv", columns, flush_s=1e9)  # flush only when asked
    rec = simulate.Recording(columns, [], sink=sink)
    rng = np.random.default_rng(1)
    rows = [np.array([0.001 * i, *rng.normal(size=2) * 10.0 ** rng.uniform(-300, 300, 2)])
            for i in range(1001)]  # fmt: skip
    for r in rows[:10]:
        rec.append(r)
    assert (tmp_path / "t.csv").read_text() == "time_s,a,b\n"  # header at once, rows buffered
    sink.flush()
    assert len((tmp_path / "t.csv").read_text().splitlines()) == 11
    for r in rows[10:]:
        rec.append(r)
    sink.close()
    assert rec.n_rows == 1001 and rec.rows == [] and rec.last_row is rows[-1]
    back = np.loadtxt(tmp_path / "t.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(back, np.array(rows))  # exact, through repr
    small = simulate.Recording.from_csv(tmp_path / "t.csv", [], max_rows=100)
    assert small.columns == columns and 50 <= small.n_rows <= 101  # every k-th row + the last
    np.testing.assert_array_equal(small.array()[-1], rows[-1])  # the last row always kept
    np.testing.assert_array_equal(small.array()[0], rows[0])
