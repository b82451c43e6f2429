"""Runs never record garbage silently and never lose what they computed."""

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mjrft import simulate
from mjrft.app import cli

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


# ------------------------------------------------------------------ mjrft run


def rows_of(path: Path) -> np.ndarray:
    """The complete rows of a CSV that may end in a line cut short."""
    lines = path.read_text().splitlines()[1:]
    width = len(path.read_text().splitlines()[0].split(","))
    return np.array([[float(x) for x in line.split(",")] for line in lines
                     if len(line.split(",")) == width])  # fmt: skip


def test_a_diverging_cli_run_exits_3_and_keeps_its_rows(tmp_path, capsys):
    args = ["run", str(MODELS / "ellipsoid_pitch.xml"), "--duration", "3", "--out", str(tmp_path)]
    assert cli.main([*args, "--timestep", "0.005"]) == cli.EXIT_DIVERGED
    err = capsys.readouterr().err
    assert "diverged at t = " in err and "smaller timestep" in err
    t = rows_of(tmp_path / "timeseries.csv")[:, 0]
    assert len(t) > 10 and np.all(np.diff(t) > 0)


@pytest.mark.parametrize("case", ["out is a file", "rrd is the csv", "rrd exists"])
def test_outputs_are_checked_before_the_first_step(tmp_path, capsys, case):
    model = str(MODELS / "sphere_drop.xml")
    out = tmp_path / "out"
    extra = []
    if case == "out is a file":
        out.write_text("not a folder")
    elif case == "rrd is the csv":
        extra = ["--rrd", str(out / "timeseries.csv")]
    else:
        (tmp_path / "old.rrd").write_text("precious")
        extra = ["--rrd", str(tmp_path / "old.rrd")]
    code = cli.main(["run", model, "--duration", "0.05", "--out", str(out), *extra])
    assert code == 2
    err = capsys.readouterr().err
    assert {"out is a file": "is a file", "rrd is the csv": "would overwrite the run's own",
            "rrd exists": "exists; pass --overwrite"}[case] in err  # fmt: skip
    assert not (out / "timeseries.csv").exists() or case == "out is a file"
    if case == "rrd exists":
        assert (tmp_path / "old.rrd").read_text() == "precious"


def _start_run(tmp_path: Path, duration: float) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "mjrft.app.cli", "run", str(MODELS / "sphere_drop.xml"),
         "--duration", str(duration), "--out", str(tmp_path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def _wait_for_rows(csv: Path, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if csv.exists() and len(csv.read_text().splitlines()) > 2:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.2)
    raise AssertionError("no rows appeared")


@pytest.mark.parametrize("how", ["SIGTERM", "SIGINT", "SIGKILL"])
def test_a_stopped_run_keeps_what_it_computed(tmp_path, how):
    """SIGTERM and Ctrl-C finish the CSV and plots; SIGKILL loses at most the last second."""
    proc = _start_run(tmp_path, 1000.0)  # far longer than the test
    csv = tmp_path / "timeseries.csv"
    _wait_for_rows(csv, proc)
    time.sleep(1.5)
    before = len(rows_of(csv))  # rows on disk now, flushed at least every second
    proc.send_signal(getattr(signal, how))
    out, err = proc.communicate(timeout=120)
    rows = rows_of(csv)
    assert len(rows) >= before > 0 and np.all(np.diff(rows[:, 0]) > 0)
    if how == "SIGKILL":
        assert proc.returncode == -signal.SIGKILL
        return
    assert proc.returncode == {"SIGTERM": 143, "SIGINT": 130}[how], err
    status = {"SIGTERM": "terminated", "SIGINT": "interrupted"}[how]
    assert f": {status} at t = " in out
    assert (tmp_path / "rft_summary.png").exists()
    assert csv.read_text().endswith("\n")  # the last row is whole
