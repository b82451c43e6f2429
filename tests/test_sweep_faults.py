"""Sweeps under faults: one writer per results folder, a full disk or a killed worker recorded so
that a resume runs those runs again, no cut row left behind, and a clear message instead of a
traceback."""

from __future__ import annotations

import os
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from test_sweep import _wait_for_rows, plate_study, table

from mjrft.app import cli
from mjrft.sweep import FolderLocked, Study, StudyError, load_results, run_study
from mjrft.sweep.results import LOCK_FILE, RESULTS_CSV

# The sphere drop, 8 runs of 20 steps: fast, and each run's time series (timeseries = true) is
# about 10 kB.
DROP = """
[study]
model = "sphere_drop"
duration = 0.02
timeseries = {timeseries}
{controller}
[parameters.z]
path = "key.start.qpos[2]"
range = {{ start = 0.011, stop = 0.018, step = 0.001 }}
[set]
triangles = 200
[metrics]
depth_m = {{ kind = "final_depth", body = "sphere" }}
"""


def drop_study(tmp_path: Path, timeseries: bool = False, controller: str = "") -> Path:
    path = tmp_path / "drop.toml"
    path.write_text(DROP.format(timeseries=str(timeseries).lower(), controller=controller))
    return path


def sweep_cmd(study: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "mjrft.app.cli", "sweep", str(study), "--out", str(out), *extra]


def limited(max_bytes: int):
    """A preexec_fn: files of this process and its workers end at max_bytes (RLIMIT_FSIZE), and
    a write past it fails with EFBIG instead of killing the process (SIGXFSZ ignored): a disk
    that fills at a chosen size, without a filesystem of that size."""

    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_bytes, max_bytes))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    return apply


def whole_rows(out: Path) -> list[str]:
    text = (out / RESULTS_CSV).read_text()
    assert text.endswith("\n"), "a cut row was left in the table"
    return text.splitlines()[1:]


def test_a_second_writer_of_a_folder_is_refused_naming_the_first(tmp_path):
    path = plate_study(tmp_path, duration=3.0, pitches=(0, 5, 10, 15))  # 16 runs of ~0.2 s
    study, out = Study.load(path), tmp_path / "out"
    first = subprocess.Popen(sweep_cmd(path, out, "--workers", "1"), stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        _wait_for_rows(out / RESULTS_CSV, first, 1)
        holder = f"pid {first.pid} on host {socket.gethostname()}"
        second = subprocess.run(sweep_cmd(path, out, "--resume"), capture_output=True, text=True,
                                timeout=120)  # fmt: skip
        assert second.returncode == 2, second.stderr
        assert "is being written by another sweep" in second.stderr and holder in second.stderr
        with pytest.raises(FolderLocked, match=holder):
            run_study(study, out, backend="serial", resume=True, plots=False)
    finally:
        first.send_signal(signal.SIGTERM)
        _, err = first.communicate(timeout=60)
    assert first.returncode == cli.EXIT_TERMINATED, err
    # The lock went with its process: a resume now runs the rest, each run once.
    summary = run_study(study, out, workers=2, resume=True, plots=False)
    ids = [r["run_id"] for r in load_results(out)]
    assert summary.computed > 0 and sorted(ids) == sorted(r.run_id for r in study.runs())
    assert (out / LOCK_FILE).read_text() == ""  # released: it names no one


def test_a_full_disk_under_the_table_stops_the_sweep_without_a_cut_row(tmp_path):
    path = drop_study(tmp_path)
    study = Study.load(path)
    run_study(study, tmp_path / "whole", backend="serial", plots=False)
    lines = (tmp_path / "whole" / RESULTS_CSV).read_text().splitlines(keepends=True)
    # Room for study.json (the largest file written before the rows), then half a row more than
    # the whole rows that fit: the next row gets cut.
    study_json = (tmp_path / "whole" / "study.json").stat().st_size
    kept = next(k for k in range(1, len(lines)) if sum(map(len, lines[: k + 1])) > study_json)
    room = sum(map(len, lines[: kept + 1])) + len(lines[kept + 1]) // 2
    out = tmp_path / "out"
    proc = subprocess.run(sweep_cmd(path, out, "--workers", "2"), capture_output=True, text=True,
                          timeout=300, preexec_fn=limited(room))  # fmt: skip
    assert proc.returncode == cli.EXIT_SWEEP_STOPPED, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "File too large (EFBIG)" in proc.stderr and "the table keeps every row" in proc.stderr
    assert f"resume with: mjrft sweep {path} --out {out} --resume" in proc.stderr
    assert len(whole_rows(out)) == kept
    summary = run_study(study, out, workers=2, resume=True, plots=False)
    assert summary.skipped == kept and summary.computed == 8 - kept and summary.failed == 0
    assert table(out, study) == table(tmp_path / "whole", study)


def test_a_run_whose_files_meet_a_full_disk_is_retried_by_the_resume(tmp_path):
    """Each run's time series is larger than the disk's room: the first run that meets it is
    recorded as "retry" (not "failed"), the sweep stops, and a resume with room reruns it."""
    path = drop_study(tmp_path, timeseries=True)
    study, out = Study.load(path), tmp_path / "out"
    proc = subprocess.run(sweep_cmd(path, out, "--workers", "1"), capture_output=True,
                          text=True, timeout=300, preexec_fn=limited(4000))  # fmt: skip
    assert proc.returncode == cli.EXIT_SWEEP_STOPPED, proc.stderr
    assert "Traceback" not in proc.stderr and "could not write its files" in proc.stderr
    rows = load_results(out)
    assert [r["status"] for r in rows] == ["retry"] and "File too large" in rows[0]["error"]
    assert not list((out / "runs").glob(".*.tmp")), "a half-written time series was left"
    summary = run_study(study, out, workers=1, resume=True, plots=False)
    assert summary.skipped == 0 and summary.computed == 8 and summary.failed == 0
    rows = load_results(out)
    assert sorted(r["run_id"] for r in rows) == sorted(r.run_id for r in study.runs())
    assert {r["status"] for r in rows} == {"ok"}
    assert len(list((out / "runs").glob("*.csv"))) == 8


KILLER = """
import os, signal
from pathlib import Path

def make(model):
    flag = Path(__file__).with_name("kill_at.txt")
    if flag.exists() and float(flag.read_text()) == float(model.key_qpos[0, 2]):
        os.kill(os.getpid(), signal.SIGKILL)  # the worker dies, as under the OOM killer
    return lambda t, data: None
"""


def test_a_run_whose_worker_is_killed_is_retried_by_the_resume(tmp_path):
    (tmp_path / "killer.py").write_text(KILLER)
    (tmp_path / "kill_at.txt").write_text("0.015")
    path = drop_study(tmp_path, controller='controller = "killer.py:make"')
    study, out = Study.load(path), tmp_path / "out"
    summary = run_study(study, out, workers=2, plots=False)
    assert summary.computed == 8 and summary.retry == 1 and summary.failed == 1
    (killed,) = [r for r in load_results(out) if r["status"] != "ok"]
    assert killed["z"] == 0.015 and killed["status"] == "retry"
    assert "worker process died twice" in killed["error"]
    os.remove(tmp_path / "kill_at.txt")
    summary = run_study(study, out, workers=2, resume=True, plots=False)
    assert summary.skipped == 7 and summary.computed == 1 and summary.failed == 0
    rows = load_results(out)
    assert sorted(r["run_id"] for r in rows) == sorted(r.run_id for r in study.runs())
    assert {r["status"] for r in rows} == {"ok"}


def test_ray_starts_its_own_instance_and_sigterm_exits_143_with_the_resume_line(tmp_path):
    """Ray's temporary folder names a cluster that is gone (as an old ``ray start`` leaves
    /tmp/ray/ray_current_cluster): plain --ray still starts a local instance; and SIGTERM ends
    the sweep as without Ray (Ray's own SIGTERM handler would exit with 15)."""
    pytest.importorskip("ray", reason="ray is not installed (pip install 'mjrft[ray]')")
    # Ray's folder here, not /tmp/ray: short, since Ray's sockets live under it (108 bytes max).
    ray_tmp = Path(tempfile.mkdtemp(prefix="mjrft-ray-", dir="/tmp"))
    try:
        (ray_tmp / "ray").mkdir()
        (ray_tmp / "ray" / "ray_current_cluster").write_text("127.0.0.1:1\n")  # nothing there
        env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
        env["RAY_TMPDIR"] = str(ray_tmp)
        path = plate_study(tmp_path, duration=3.0, pitches=(0, 5, 10, 15))  # 16 runs of ~0.2 s
        out = tmp_path / "out"
        cmd = sweep_cmd(path, out, "--ray", "--workers", "1")
        pipes = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "text": True}
        proc = subprocess.Popen(cmd, env=env, **pipes)
        _wait_for_rows(out / RESULTS_CSV, proc, 2, timeout=180)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    finally:
        shutil.rmtree(ray_tmp, ignore_errors=True)
    assert proc.returncode == cli.EXIT_TERMINATED, err
    assert "terminated after" in err and f"--out {out} --resume --workers 1 --ray local" in err
    assert 2 <= len(whole_rows(out)) < 16


def test_a_resume_cleans_the_table_of_cut_repeated_and_retry_rows_keeping_the_rest(tmp_path):
    """A folder written without a lock (two sweeps at once) or left by a kill: the resume keeps
    one whole row per run, byte for byte, reruns the "retry" run, and runs nothing twice."""
    path = drop_study(tmp_path)
    study, out = Study.load(path), tmp_path / "out"
    run_study(study, out, backend="serial", plots=False)
    text, cells = (out / RESULTS_CSV).read_text(), table(out, study)
    header, *rows = text.splitlines(keepends=True)
    status = header.split(",").index("status")
    retry = rows[3].split(",")
    retry[status] = "retry"
    dirty = [*rows[:3], ",".join(retry), *rows[3:], rows[0], rows[1], rows[2][:40]]
    (out / RESULTS_CSV).write_text(header + "".join(dirty))
    summary = run_study(study, out, backend="serial", resume=True, plots=False)
    assert summary.skipped == 8 and summary.computed == 0  # every run has an ok row
    assert (out / RESULTS_CSV).read_text() == text
    # Without its ok row, the retry row's run runs again, once.
    (out / RESULTS_CSV).write_text(header + "".join([*rows[:3], ",".join(retry), *rows[4:]]))
    summary = run_study(study, out, backend="serial", resume=True, plots=False)
    assert summary.skipped == 7 and summary.computed == 1
    after = (out / RESULTS_CSV).read_text().splitlines(keepends=True)
    assert after[:8] == [header, *rows[:3], *rows[4:]] and len(after) == 9
    assert table(out, study) == cells  # the rerun gives the same metrics, bit for bit


def test_a_filesystem_without_locks_gets_a_warning_and_the_sweep_runs(tmp_path, monkeypatch):
    import errno
    import fcntl

    def no_locks(fd, op):
        raise OSError(errno.ENOLCK, os.strerror(errno.ENOLCK))

    monkeypatch.setattr(fcntl, "flock", no_locks)
    study = Study.load(drop_study(tmp_path))
    with pytest.warns(RuntimeWarning, match=r"No locks available \(ENOLCK\).*would not be refused"):
        summary = run_study(study, tmp_path / "out", backend="serial", plots=False)
    assert summary.computed == 8 and summary.failed == 0


def test_a_ray_cluster_that_cannot_be_reached_is_named_in_a_study_error(tmp_path, monkeypatch):
    ray = pytest.importorskip("ray", reason="ray is not installed (pip install 'mjrft[ray]')")

    def none_there(**kwargs):  # what ray.init raises for --ray auto with no cluster running
        raise ConnectionError("Could not find any running Ray instance.")

    monkeypatch.setattr(ray, "init", none_there)
    study = Study.load(drop_study(tmp_path))
    with pytest.raises(StudyError, match=r"cannot start or reach the Ray cluster at 'auto': "
                       r"Could not find any running Ray instance\.; --ray HOST:PORT"):  # fmt: skip
        run_study(study, tmp_path / "out", backend="ray", address="auto", plots=False)
    assert not (tmp_path / "out").exists()  # nothing written: fix the address and run it again
