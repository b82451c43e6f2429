"""Runs never record garbage silently and never lose what they computed."""

import json
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
    model = simulate.load_model(str(MODELS / "ellipsoid_pitch.xml"), n_triangles=200)
    simulate.configure(model, 0.005, None)
    rec = simulate.new_recording(model, simulate.GranularField(model))
    with pytest.raises(simulate.RunDiverged, match=r"diverged at t = .* s \(step \d+\).*QACC") as e:
        simulate.run(model, 3.0, recording=rec, fld=simulate.GranularField(model))
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


def test_a_run_in_a_folder_that_holds_one_needs_overwrite(tmp_path, capsys):
    """Another run's results are refused before the first step, not replaced; --overwrite
    replaces all of them (no stale plots beside a --no-plots run)."""
    model = str(MODELS / "sphere_drop.xml")
    args = ["run", model, "--duration", "0.1", "--out", str(tmp_path), "--triangles", "200"]
    assert cli.main([*args, "--all-figures"]) == 0
    plots = {p.name for p in tmp_path.glob("*.png")}
    assert plots == set(cli.RUN_PLOTS)
    files = (cli.RUN_CSV, cli.RUN_JSON, *cli.RUN_PLOTS)
    before = {name: (tmp_path / name).read_bytes() for name in files}
    capsys.readouterr()
    for kept in (cli.RUN_JSON, cli.RUN_PLOTS[0]):  # any one of its files marks a run
        for name in files:
            if name != kept:
                (tmp_path / name).unlink(missing_ok=True)
        assert cli.main([*args, "--no-plots"]) == 2
        err = capsys.readouterr().err
        assert f"--out folder {str(tmp_path)!r} already holds a run ({kept})" in err
        assert "pass --overwrite" in err
        assert (tmp_path / kept).read_bytes() == before[kept]
        for name, data in before.items():
            (tmp_path / name).write_bytes(data)
    assert cli.main([*args, "--no-plots", "--overwrite"]) == 0
    assert not list(tmp_path.glob("*.png"))
    assert json.loads((tmp_path / cli.RUN_JSON).read_text())["options"]["no_plots"] is True


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


def test_a_duration_shorter_than_one_timestep_is_refused_naming_both(tmp_path, capsys):
    """One step would end the run a whole timestep past its duration."""
    model = simulate.load_model("sphere_drop")
    simulate.configure(model, 0.5, None)
    with pytest.raises(ValueError, match=r"duration 0\.05 s is shorter than the timestep 0\.5 s"):
        simulate.run(model, 0.05)
    data, _ = simulate.run(model, 0.5)  # exactly one timestep is one step
    assert data.time == 0.5
    out = tmp_path / "o"
    args = ["run", "sphere_drop", "--duration", "0.05", "--timestep", "0.5", "--out", str(out)]
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    assert "duration 0.05 s is shorter than the timestep 0.5 s" in err
    assert not (out / "timeseries.csv").exists() and not (out / "run.json").exists()


def test_recorded_com_velocity_is_mujocos_object_velocity():
    import mujoco

    from mjrft.field.granular_field import GranularField

    model = simulate.load_model("hexapod_sand")  # a shipped model by name; articulated legs
    fld = GranularField(model)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    data.qvel[:] = np.random.default_rng(0).normal(size=model.nv)
    mujoco.mj_forward(model, data)
    row = simulate.record_row(model, data, fld)
    vel = np.zeros(6)
    for j, b in enumerate(fld.body_ids):
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, int(b), vel, 0)
        name = fld.bodies[j].name
        got = [row[simulate.new_recording(model, fld).columns.index(f"{name}_vel_{a}_m_per_s")]
               for a in "xyz"]  # fmt: skip
        np.testing.assert_allclose(got, vel[3:], rtol=1e-12, atol=1e-14)


def test_a_controller_drives_the_actuators_and_bad_controls_are_named():
    model = simulate.load_model("hexapod_sand")
    seen = []

    def ctrl(t, data):
        seen.append(t)
        return np.full(model.nu, 0.2)

    data, _ = simulate.run(model, 0.01, ctrl=ctrl)
    assert len(seen) == 10 and seen[0] == 0.0 and np.all(data.ctrl == 0.2)
    with pytest.raises(ValueError, match=r"returned shape \(2,\).*nu = 6"):
        simulate.run(model, 0.01, ctrl=lambda t, d: [0.0, 1.0])
    with pytest.raises(ValueError, match="non-finite control nan for actuator"):
        simulate.run(model, 0.01, ctrl=lambda t, d: np.full(model.nu, np.nan))


def test_keyframes(tmp_path):
    model = simulate.load_model("hexapod_sand")
    keyed, _ = simulate.run(model, 0.001)
    plain, _ = simulate.run(model, 0.001, keyframe=None)
    assert not np.allclose(keyed.qpos, plain.qpos)  # the keyframe differs from qpos0
    with pytest.raises(ValueError, match="keyframe 5 does not exist"):
        simulate.run(model, 0.001, keyframe=5)
    with pytest.raises(ValueError, match="no shipped model of that name.*sphere_drop"):
        simulate.load_model("no_such_model")


def test_cli_options_reach_the_run_and_run_json(tmp_path, capsys):
    import json

    ctrl = tmp_path / "my_ctrl.py"
    ctrl.write_text("def ctrl(t, data):\n    return [0.1] * data.ctrl.shape[0]\n")
    args = ["run", "hexapod_sand", "--duration", "0.02", "--out", str(tmp_path / "o"),
            "--triangles", "300", "--material", "poppy_seeds_lp", "--keyframe", "none",
            "--ctrl", f"{ctrl}:ctrl", "--no-plots"]  # fmt: skip
    assert cli.main(args) == 0
    out = capsys.readouterr().out
    assert "the simulation alone" in out and "in all" in out
    meta = json.loads((tmp_path / "o" / "run.json").read_text())
    assert meta["status"] == "completed" and meta["rows"] == 21
    assert meta["field"]["material"] == "poppy_seeds_lp" and meta["model"]["keyframe"] is None
    assert meta["options"]["triangles"] == 300 and meta["versions"]["mujoco"]
    xml = meta["model"]["file"]
    assert len(meta["model"]["sha256"][xml]) == 64 and len(meta["model"]["sha256"]) >= 2
    assert not list((tmp_path / "o").glob("*.png"))
    default = tmp_path / "d"
    assert cli.main(["run", "hexapod_sand", "--duration", "0.02", "--out", str(default),
                     "--no-plots"]) == 0  # fmt: skip
    capsys.readouterr()
    assert json.loads((default / "run.json").read_text())["field"]["triangles"] != 0
    assert cli.main([*args[:6], "--overwrite", "--ctrl", "os:no_such"]) == 2
    assert "has no callable 'no_such'" in capsys.readouterr().err
    assert cli.main([*args[:6], "--overwrite", "--keyframe", "walk"]) == 2
    assert "no keyframe of that name" in capsys.readouterr().err


def test_cli_deform_options_turn_on_the_ground_that_remembers(tmp_path, capsys):
    import json

    out = tmp_path / "w"
    args = ["run", "wheel_rig", "--duration", "0.2", "--out", str(out), "--no-plots",
            "--triangles", "300", "--deform-cell", "0.01", "--repose", "25"]  # fmt: skip
    assert cli.main(args) == 0
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "completed" and meta["field"]["deforms"] is True
    assert meta["options"]["deform_cell"] == 0.01 and meta["options"]["repose"] == 25.0
    assert cli.main([*args[:7], "--overwrite", "--deform-cell", "0"]) == 0
    assert json.loads((out / "run.json").read_text())["field"]["deforms"] is False
    capsys.readouterr()
    with pytest.raises(SystemExit):
        cli.main([*args[:7], "--deform-cell", "-1"])
    assert "expected a finite number >= 0, got -1" in capsys.readouterr().err
