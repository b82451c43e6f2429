"""Parameter sweeps: the same study gives the same table on every backend, a stopped sweep
resumes without recomputing a finished run, a failing run is a row, and bad input is named."""

from __future__ import annotations

import math
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from mjrft.app import cli
from mjrft.sweep import Study, StudyError, load_results, run_study
from mjrft.sweep.results import RESULTS_CSV

# The plate rig started 4 mm deep, driven down at each speed for 0.1 s (100 steps); the
# keyframe's servo target carries the servo's static lag: (M g + kv v) / kp with M g = 1.622 N
# (gantry carriage and plate), kv = 1800 N s/m, kp = 4e5 N/m (models/plate_rig.xml).
PLATE = """
[study]
model = "plate_rig"
duration = {duration}

[parameters.pitch_deg]
path = "body.plate.euler[1]"
values = {pitches}

[parameters.speed]
path = ["key.start.ctrl[2]", "key.start.qvel[2]"]
values = [-0.01, -0.03]

[parameters.triangles]
path = "triangles"
values = [60, 120]

[set]
"key.start.qpos[2]" = -0.004
"key.start.act[2]" = {{ expr = "-0.004 + (1.622 + 1800 * speed) / 4e5" }}

[metrics]
depth_m = {{ kind = "final_depth", body = "plate" }}
fz_mean_N = {{ kind = "mean_force", body = "plate", component = "z" }}
f_peak_N = {{ kind = "peak_force", body = "plate" }}
ty_mean_Nm = {{ kind = "mean_torque", body = "plate", component = "y" }}
rft_work_J = {{ kind = "rft_work", body = "plate" }}
z_work_J = {{ kind = "actuator_work", actuator = "z" }}
load_cell_min_N = {{ kind = "sensor", sensor = "load_cell_force", index = 2, stat = "min" }}
vz_m_per_s = {{ kind = "speed", body = "plate", component = "z", after = 0.05 }}
dz_m = {{ kind = "distance", body = "plate", component = "z" }}
"""
PLATE_WEIGHT_N = 1.622  # gantry carriage 0.1 kg + steel plate 0.0653 kg, times g


def plate_study(tmp_path: Path, duration: float = 0.1, pitches=(0, 20)) -> Path:
    path = tmp_path / "plate.toml"
    path.write_text(PLATE.format(duration=duration, pitches=list(pitches)))
    return path


def columns(study: Study) -> list[str]:
    return [p.name for p in study.parameters] + [m.name for m in study.metrics]


def table(out: Path, study: Study) -> dict[str, list[str]]:
    """run_id -> the parameter and metric cells as written (exact text)."""
    import csv

    rows = list(csv.reader((out / RESULTS_CSV).read_text().splitlines()))
    index = [rows[0].index(c) for c in columns(study)]
    return {r[0]: [r[i] for i in index] for r in rows[1:]}


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The plate study (8 runs) run in this process, one run after the other."""
    tmp = tmp_path_factory.mktemp("serial")
    study = Study.load(plate_study(tmp))
    run_study(study, tmp / "out", backend="serial", plots=False)
    return study, table(tmp / "out", study), load_results(tmp / "out")


def test_the_serial_table_holds_every_run_with_metrics_that_balance_energy(serial):
    study, _, rows = serial
    assert len(rows) == 8 == len(study.runs()) and {r["status"] for r in rows} == {"ok"}
    for r in rows:
        assert r["depth_m"] > 0.004 and r["fz_mean_N"] > 1.0 and r["f_peak_N"] >= r["fz_mean_N"]
        assert r["vz_m_per_s"] == pytest.approx(r["speed"], rel=0.01)
        # The z drive's work plus gravity's is what the plate does on the medium (the kinetic
        # energy does not change: the servo holds the speed).
        gravity = PLATE_WEIGHT_N * -r["dz_m"]
        assert r["z_work_J"] + gravity == pytest.approx(r["rft_work_J"], rel=0.01)
        assert r["load_cell_min_N"] < 0 and r["seed"] > 0 and "mujoco=3.17" in r["versions"]
        # A level plate feels no torque about its centre (round-off), a pitched one does.
        assert (abs(r["ty_mean_Nm"]) < 1e-12) == (r["pitch_deg"] == 0)


def test_the_local_backend_table_equals_the_serial_results_bit_for_bit(serial, tmp_path):
    study, cells, _ = serial
    summary = run_study(study, tmp_path / "out", workers=2, plots=False)
    assert summary.computed == 8 and summary.failed == 0
    assert table(tmp_path / "out", study) == cells


def test_the_ray_backend_table_equals_the_serial_results_bit_for_bit(serial, tmp_path):
    ray = pytest.importorskip("ray", reason="ray is not installed (pip install 'mjrft[ray]')")
    study, cells, _ = serial
    # A local instance of its own, in a folder of its own (not what /tmp/ray names; short,
    # since Ray's sockets live under it, 108 bytes at most).
    short = tempfile.mkdtemp(prefix="mjrft-ray-", dir="/tmp")
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False,
             _temp_dir=short)  # fmt: skip
    try:
        summary = run_study(study, tmp_path / "out", backend="ray", plots=False)
    finally:
        ray.shutdown()
        shutil.rmtree(short, ignore_errors=True)
    assert summary.computed == 8 and summary.failed == 0
    assert table(tmp_path / "out", study) == cells


def test_runs_are_identified_by_their_values_and_random_draws_are_seeded(tmp_path):
    text = plate_study(tmp_path).read_text()
    study = Study.from_toml(text)
    ranged = "range = { start = 60, stop = 120, step = 60 }"
    again = Study.from_toml(text.replace("values = [60, 120]", ranged))
    assert [r.run_id for r in study.runs()] == [r.run_id for r in again.runs()]
    assert len({r.run_id for r in study.runs()}) == 8
    assert [r.values for r in study.runs()][-1] == {
        "pitch_deg": 20,
        "speed": -0.03,
        "triangles": 120,
    }
    ranged = "range = { start = 0, stop = 0.3, step = 0.1 }"
    stepped = Study.from_toml(text.replace("values = [0, 20]", ranged))
    assert sorted({r.values["pitch_deg"] for r in stepped.runs()}) == [0.0, 0.1, 0.2, 0.3]
    drawn = "duration = 0.1\nsampling = 'random'\nsamples = 5\nseed = 3"
    random = text.replace("duration = 0.1", drawn)
    random = random.replace("values = [0, 20]", "low = 0.0\nhigh = 30.0")
    draws = [r.values for r in Study.from_toml(random).runs()]
    assert draws == [r.values for r in Study.from_toml(random).runs()] and len(draws) == 5
    assert all(0 <= d["pitch_deg"] < 30 for d in draws)
    other = [r.values for r in Study.from_toml(random.replace("seed = 3", "seed = 4")).runs()]
    assert other != draws


def _start_sweep(study: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "mjrft.app.cli", "sweep", str(study), "--out", str(out),
         "--workers", "1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def _wait_for_rows(csv: Path, proc: subprocess.Popen, n: int, timeout: float = 120.0) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if csv.exists() and len(csv.read_text().splitlines()) > n:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError(f"fewer than {n} rows appeared")


@pytest.mark.parametrize("how", ["SIGTERM", "SIGKILL"])
def test_a_stopped_sweep_resumes_where_it_stopped_and_recomputes_no_finished_run(tmp_path, how):
    path = plate_study(tmp_path, duration=3.0, pitches=(0, 5, 10, 15))  # 16 runs of ~0.2 s
    study, out = Study.load(path), tmp_path / "out"
    proc = _start_sweep(path, out)
    _wait_for_rows(out / RESULTS_CSV, proc, 3)
    proc.send_signal(getattr(signal, how))
    _, err = proc.communicate(timeout=60)
    if how == "SIGTERM":
        assert proc.returncode == cli.EXIT_TERMINATED, err
        assert "terminated after" in err and f"--out {out} --resume" in err
    else:
        assert proc.returncode == -signal.SIGKILL
    before = (out / RESULTS_CSV).read_text()
    before = before[: before.rfind("\n") + 1]  # a kill may leave the last row cut short
    finished = [line.split(",")[0] for line in before.splitlines()[1:]]
    assert 3 <= len(finished) < 16
    assert cli.main(["sweep", str(path), "--out", str(out)]) == 2  # no --resume: refused
    summary = run_study(study, out, workers=2, resume=True, plots=False)
    assert summary.skipped == len(finished) and summary.computed == 16 - len(finished)
    after = (out / RESULTS_CSV).read_text()
    assert after.startswith(before)  # the finished rows are untouched
    ids = [line.split(",")[0] for line in after.splitlines()[1:]]
    assert sorted(ids) == sorted(r.run_id for r in study.runs())  # each run exactly once
    run_study(study, tmp_path / "whole", workers=2, plots=False)
    assert table(out, study) == table(tmp_path / "whole", study)


def test_a_run_that_does_not_compile_or_diverges_is_a_failed_row_and_the_others_go_on(tmp_path):
    metric = tmp_path / "my_metrics.py"
    metric.write_text("def twice_the_depth(outcome):\n    return 2 * outcome.metrics['depth_m']\n")
    path = tmp_path / "bad.toml"
    path.write_text(f"""
[study]
model = "{Path(cli.__file__).parents[2] / "models" / "ellipsoid_pitch.xml"}"
duration = 3.0
[parameters.timestep]
path = "timestep"
values = [0.001, 0.005]
[parameters.width_m]
path = "geom.ellipsoid.size[0]"
values = [0.0096, -0.01]
[set]
triangles = 200
[metrics]
depth_m = {{ kind = "final_depth", body = "ellipsoid" }}
twice_m = {{ kind = "custom", function = "my_metrics.py:twice_the_depth" }}
""")
    study = Study.load(path)
    summary = run_study(study, tmp_path / "out", backend="serial")
    rows = {(r["timestep"], r["width_m"]): r for r in load_results(tmp_path / "out")}
    assert summary.computed == 4 and summary.failed == 3
    ok = rows[(0.001, 0.0096)]
    assert ok["status"] == "ok" and ok["error"] == "" and ok["twice_m"] == 2 * ok["depth_m"]
    for width in (0.0096, -0.01):
        bad = rows[(0.005, width)] if width > 0 else rows[(0.001, width)]
        assert bad["status"] == "failed" and math.isnan(bad["depth_m"])
    assert "size 0 must be positive in geom" in rows[(0.001, -0.01)]["error"]
    assert "Element name 'ellipsoid'" in rows[(0.001, -0.01)]["error"]  # MuJoCo's whole message
    assert "diverged at t = " in rows[(0.005, 0.0096)]["error"]
    assert len(summary.plots) == 2 and all(p.stat().st_size > 1000 for p in summary.plots)


@pytest.mark.parametrize("backend", ["serial", "local"])
def test_an_error_every_run_shares_stops_the_sweep_before_any_run(tmp_path, capsys, backend):
    """A blanked preset passes Study.load (its own check compiles the model as it is) but no run
    compiles: the sweep stops with MuJoCo's error before writing anything."""
    path = plate_study(tmp_path)
    path.write_text(path.read_text().replace("[set]\n", '[set]\n"mjrft:material" = ""\n'))
    study = Study.load(path)
    shared = r"fail to load with the same error.*no run was started: ValueError: .*mjrft:material"
    with pytest.raises(StudyError, match=shared):
        run_study(study, tmp_path / "out", backend=backend, workers=2)
    assert not (tmp_path / "out").exists()
    assert cli.main(["sweep", str(path), "--out", str(tmp_path / "out"), "--workers", "2"]) == 2
    assert "size cannot be zero" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_sweep_with_failed_runs_exits_3_saying_how_many(tmp_path, capsys):
    """The first run fails to load on its own value, the others do not: the sweep goes on, and
    its exit code and a line on stderr say how many failed, counting those a resume finds."""
    path = tmp_path / "widths.toml"
    path.write_text(f"""
[study]
model = "{Path(cli.__file__).parents[2] / "models" / "ellipsoid_pitch.xml"}"
duration = 0.02
[parameters.width_m]
path = "geom.ellipsoid.size[0]"
values = [-0.01, 0.0096, 0.009]
[set]
triangles = 200
[metrics]
depth_m = {{ kind = "final_depth", body = "ellipsoid" }}
""")
    out = tmp_path / "out"
    assert cli.main(["sweep", str(path), "--out", str(out), "--workers", "2"]) == 3
    printed = capsys.readouterr()
    assert "3 runs computed (1 failed" in printed.out
    assert f"1 of 3 runs failed; their errors are in the error column of {out}" in printed.err
    rows = load_results(out)
    assert sorted(r["status"] for r in rows) == ["failed", "ok", "ok"]
    assert cli.main(["sweep", str(path), "--out", str(out), "--resume"]) == 3
    printed = capsys.readouterr()
    assert "3 already in the table (1 failed)" in printed.out
    assert "1 of 3 runs failed" in printed.err


def test_a_run_shorter_than_its_timestep_is_a_failed_row_naming_both(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text("""
[study]
model = "sphere_drop"
duration = 0.05
[parameters.timestep]
path = "timestep"
values = [0.001, 0.5]
[set]
triangles = 60
[metrics]
depth_m = { kind = "final_depth", body = "sphere" }
""")
    summary = run_study(Study.load(path), tmp_path / "out", backend="serial")
    rows = {r["timestep"]: r for r in load_results(tmp_path / "out")}
    assert summary.computed == 2 and summary.failed == 1 and rows[0.001]["status"] == "ok"
    assert rows[0.5]["status"] == "failed" and math.isnan(rows[0.5]["depth_m"])
    assert "duration 0.05 s is shorter than the timestep 0.5 s" in rows[0.5]["error"]


# (the change to the first parameter, pieces of the message in order)
BAD = [
    ('path = "bdy.plate.pos"', ["unknown path 'bdy.plate.pos'; valid forms: <kind>.<name>"]),
    ('path = "body.nosuch.pos"', ["no body named 'nosuch' (bodies: world, gantry_x"]),
    ('path = "body.plate.poss"', ["body 'plate' has no attribute 'poss' (valid:", "euler", "pos"]),
    ('path = "geom.plate.size[5]"', ["index 5 is out of range; the attribute has 3"]),
    ('path = "body.plate.pos"', ["0 is not valid; it takes a list of 3 numbers"]),
    ('path = "option.timestep"\nvalues = ["fast"]', ["'fast' is not valid; it takes a number"]),
    ('path = "integrator"\nvalues = ["leap"]', ["'leap' is not an integrator (euler"]),
    ('path = "material"\nvalues = ["mud"]', ["'mud' is not valid; it takes a preset name"]),
    ('path = "mjrft:zetta"', ["no such scene value (valid: mjrft:material"]),
]


@pytest.mark.parametrize("change, pieces", BAD, ids=[b[0].split("\n")[0] for b in BAD])
def test_a_bad_parameter_is_refused_naming_its_path_and_what_is_valid(tmp_path, change, pieces):
    text = plate_study(tmp_path).read_text()
    text = text.replace('path = "body.plate.euler[1]"', change, 1)
    if "\nvalues" in change:
        text = text.replace("values = [0, 20]", "", 1)
    pattern = ".*".join(re.escape(p) for p in ["parameters.pitch_deg", *pieces])
    with pytest.raises(StudyError, match=pattern):
        Study.from_toml(text)


def test_a_study_of_too_many_runs_is_refused_naming_the_count_before_they_exist(tmp_path):
    text = plate_study(tmp_path).read_text()
    tracemalloc.start()
    for rng, count in (("num = 1_000_000_000", "1,000,000,000"), ("step = 1e-9", "1,000,000,001")):
        huge = text.replace("values = [0, 20]", f"range = {{ start = 0, stop = 1, {rng} }}", 1)
        with pytest.raises(StudyError, match=rf"parameters\.pitch_deg\]: the range has {count} "
                           r"values, more than the 1,000,000 runs a study may have"):  # fmt: skip
            Study.from_toml(huge)
    grid = text.replace("values = [0, 20]", "range = { start = 0, stop = 1, num = 250_001 }", 1)
    with pytest.raises(StudyError, match=r"the study has 1,000,004 runs \(the grid of pitch_deg "
                       r"250,001 x speed 2 x triangles 2\), more than the 1,000,000"):  # fmt: skip
        Study.from_toml(grid)
    drawn = text.replace("[study]", '[study]\nsampling = "random"\nsamples = 1_000_001', 1)
    with pytest.raises(StudyError, match=r"1,000,001 runs \(samples = 1,000,001\), more than"):
        Study.from_toml(drawn)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    # refused before any run exists: a million listed runs take ~400 MB (0.4 kB each)
    assert peak < 50e6


def test_an_unknown_metric_or_name_is_refused_listing_the_valid_ones(tmp_path):
    text = plate_study(tmp_path).read_text()
    listed = (
        r"metrics\.depth_m.*unknown metric kind 'depht'; valid kinds: final_depth \(.*mean_force"
    )
    with pytest.raises(StudyError, match=listed):
        Study.from_toml(text.replace('kind = "final_depth"', 'kind = "depht"'))
    with pytest.raises(StudyError, match="does not feel the medium \\(intruding bodies: plate\\)"):
        Study.from_toml(text.replace('mean_force", body = "plate', 'mean_force", body = "gantry_x'))
    with pytest.raises(StudyError, match="no sensor named 'cell' \\(sensors: load_cell_force"):
        Study.from_toml(text.replace('sensor = "load_cell_force"', 'sensor = "cell"'))
    with pytest.raises(StudyError, match="unknown name 'sped'.*parameters: pitch_deg, speed"):
        Study.from_toml(text.replace("1800 * speed", "1800 * sped"))
    with pytest.raises(StudyError, match="unknown key 'duraton' \\(valid: name, model, duration"):
        Study.from_toml(text.replace("duration = 0.1", "duration = 0.1\nduraton = 1"))


def test_resuming_a_different_study_is_refused_naming_the_differences(serial, tmp_path):
    study = Study.load(plate_study(tmp_path))
    run_study(study, tmp_path / "out", backend="serial", plots=False)
    changed = Study.load(plate_study(tmp_path, duration=0.2, pitches=(0, 10)))
    named = r"duration_s: 0.1 in the folder, 0.2 now.*parameters\.pitch_deg\.values"
    with pytest.raises(StudyError, match=named):
        run_study(changed, tmp_path / "out", backend="serial", resume=True)
    assert len(load_results(tmp_path / "out")) == 8  # nothing was added or lost


def test_plots_per_metric_time_series_per_run_and_the_plots_only_option(tmp_path, capsys):
    text = plate_study(tmp_path, pitches=(0, 20)).read_text()
    text = text.replace("values = [-0.01, -0.03]", "values = [-0.01]")  # two parameters vary
    text = text.replace("duration = 0.1", "duration = 0.1\ntimeseries = true\nrecord_every = 10")
    (tmp_path / "two.toml").write_text(text)
    out = tmp_path / "out"
    assert cli.main(["sweep", str(tmp_path / "two.toml"), "--out", str(out), "--workers", "2"]) == 0
    assert "4 runs computed (0 failed" in capsys.readouterr().out
    series = sorted((out / "runs").glob("*.csv"))
    assert len(series) == 4 and not list((out / "runs").glob(".*"))  # complete files only
    rows = np.loadtxt(series[0], delimiter=",", skiprows=1)
    assert rows.shape[0] == 10 + 1  # every 10th of the 100 steps, and the final state
    pngs = sorted(out.glob("*.png"))
    assert [p.stem for p in pngs] == sorted(m.name for m in Study.from_toml(text).metrics)
    for p in pngs:
        p.unlink()
    assert cli.main(["sweep", str(tmp_path / "two.toml"), "--out", str(out), "--plots-only"]) == 0
    assert len(list(out.glob("*.png"))) == len(pngs)
    assert len(load_results(out)) == 4  # --plots-only runs nothing


@pytest.mark.parametrize("name, runs", [("root_circumnutation", 20), ("hexapod_gait", 25)])
def test_the_shipped_studies_load_with_their_runs(name, runs):
    study = Study.load(Path(__file__).resolve().parents[1] / "studies" / f"{name}.toml")
    assert len(study.runs()) == runs and study.sampling == "grid"
    assert [p.name for p in study.parameters if p.targets] in (["tilt_deg"], [])


def test_a_constant_ctrl_a_sine_and_a_controller_factory_drive_the_actuators(tmp_path):
    (tmp_path / "gaits.py").write_text(
        "def make(model, speed):\n"
        "    return lambda t, data: [0.0, 0.0, speed]\n"
    )  # fmt: skip
    head = '[study]\nmodel = "plate_rig"\nduration = 0.2\n'
    metric = '[metrics]\ndz_m = { kind = "distance", body = "plate", component = "z" }\n'
    studies = {
        "constant": '[parameters.u]\npath = "ctrl.z"\nvalues = [-0.02]\n',
        "factory": 'controller = "gaits.py:make"\n'
        '[parameters.u]\npath = "controller.speed"\nvalues = [-0.02]\n',
        "sine": '[parameters.u]\npath = "ctrl.z.amplitude"\nvalues = [0.01]\n'
        '[set]\n"ctrl.z.offset" = -0.02\n"ctrl.z.frequency" = 2.5\n',
    }
    dz = {}
    for name, body in studies.items():
        (tmp_path / f"{name}.toml").write_text(head + body + metric)
        run_study(Study.load(tmp_path / f"{name}.toml"), tmp_path / name, backend="serial")
        (row,) = load_results(tmp_path / name)
        dz[name] = row["dz_m"]
    assert dz["constant"] == dz["factory"] == pytest.approx(-0.004, rel=0.02)  # 2 cm/s, 0.2 s
    # Half a period of the sine adds amplitude / (pi f) = 1.27 mm of climb to the descent.
    assert dz["sine"] - dz["constant"] == pytest.approx(0.01 / (math.pi * 2.5), rel=0.1)
    with pytest.raises(StudyError, match="both as a constant and as a sine"):
        Study.from_toml(head + studies["sine"] + '"ctrl.z" = 0.0\n' + metric)
