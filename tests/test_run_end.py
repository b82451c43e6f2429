"""`mjrft run` ends with complete files and a final run.json status whatever ends it: a signal
right after the loop, two signals, a signal during start-up, a full disk.

Signals are real: sent to a child process from outside, or sent by the child to itself at a
chosen moment (a wrapper around one of its functions, so the moment is exact)."""

import errno
import json
import os
import resource
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from mjrft.app import cli, simulate

MODELS = Path(__file__).resolve().parents[1] / "models"


def _child(tmp_path: Path, args: list[str], hook: str = "", **popen) -> subprocess.Popen:
    """`mjrft run ARGS` in a child process, after `hook` (Python run first in the child)."""
    script = tmp_path / "child.py"
    script.write_text(
        "import os, signal, sys\nfrom mjrft.app import cli\n"
        + textwrap.dedent(hook)
        + "\nsys.exit(cli.main(sys.argv[1:]))\n"
    )
    return subprocess.Popen(
        [sys.executable, str(script), "run", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **popen,
    )  # fmt: skip


def _sphere(out: Path, duration: float, *extra: str) -> list[str]:
    return [str(MODELS / "sphere_drop.xml"), "--duration", str(duration), "--out", str(out),
            "--triangles", "200", *extra]  # fmt: skip


def _whole_rows(csv: Path) -> np.ndarray:
    """The CSV's rows, checking that every one is whole and the file ends with a newline."""
    text = csv.read_text()
    assert text.endswith("\n"), "the last row is cut"
    lines = text.splitlines()
    width = len(lines[0].split(","))
    assert all(len(line.split(",")) == width for line in lines[1:]), "a row is cut"
    return np.array([[float(x) for x in line.split(",")] for line in lines[1:]])


def _finished(out: Path, proc: subprocess.Popen, code: int, status: str) -> tuple[dict, str]:
    stdout, stderr = proc.communicate(timeout=180)
    assert proc.returncode == code, stderr
    assert "Traceback" not in stderr, stderr
    record = json.loads((out / cli.RUN_JSON).read_text())
    assert record["status"] == status
    rows = _whole_rows(out / cli.RUN_CSV)
    assert record["rows"] == len(rows)
    assert record["simulated_s"] == rows[-1, 0]
    return record, stdout + stderr


# A wrapper that sends the child `SIG` just before it draws its plots (after the loop ended).
_SIGNAL_BEFORE_PLOTS = """
from mjrft.app import report
_plot_run = report.plot_run
def plot_run(*args, **kwargs):
    for sig in SIGNALS:
        os.kill(os.getpid(), sig)
    return _plot_run(*args, **kwargs)
report.plot_run = plot_run
"""


@pytest.mark.parametrize(
    ("signals", "code"),
    [(["SIGINT"], 130), (["SIGTERM"], 143), (["SIGINT", "SIGINT", "SIGTERM"], 130)],
)
def test_a_signal_after_the_loop_waits_for_the_files(tmp_path, signals, code):
    """The run completed: its status says so, every plot is drawn, the exit code says a signal
    came (so a shell loop around it stops)."""
    out = tmp_path / "out"
    hook = f"SIGNALS = [{', '.join('signal.' + s for s in signals)}]\n" + _SIGNAL_BEFORE_PLOTS
    proc = _child(tmp_path, _sphere(out, 0.3, "--all-figures"), hook)
    record, text = _finished(out, proc, code, "completed")
    assert record["signals"] == signals
    assert record["simulated_s"] == pytest.approx(0.3)
    assert {p.name for p in out.glob("*.png")} == set(cli.RUN_PLOTS)
    assert f"received {', '.join(signals)}; the run's files were completed first" in text


@pytest.mark.parametrize("how", ["SIGINT", "SIGTERM"])
def test_two_signals_during_the_run_end_it_once_with_complete_files(tmp_path, how):
    """The first signal stops the loop; the second, sent at once, lands while the files are
    being finished and waits for them."""
    out = tmp_path / "out"
    proc = _child(tmp_path, _sphere(out, 1000.0))
    csv = out / cli.RUN_CSV
    t0 = time.monotonic()
    while not (csv.exists() and len(csv.read_text().splitlines()) > 2):
        assert proc.poll() is None and time.monotonic() - t0 < 60, proc.communicate()
        time.sleep(0.05)
    proc.send_signal(getattr(signal, how))
    time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    code, status = {"SIGINT": (130, "interrupted"), "SIGTERM": (143, "terminated")}[how]
    record, _ = _finished(out, proc, code, status)
    assert record["signals"][0] == how and len(record["signals"]) == 2
    assert {p.name for p in out.glob("*.png")} == set(cli.RUN_PLOTS)


def test_a_signal_during_start_up_before_any_file_exits_cleanly(tmp_path):
    out = tmp_path / "out"
    hook = """
    _scene = cli._scene
    def scene(*args):
        os.kill(os.getpid(), signal.SIGTERM)
        return _scene(*args)
    cli._scene = scene
    """
    proc = _child(tmp_path, _sphere(out, 0.3), hook)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == cli.EXIT_TERMINATED, stderr
    assert "Traceback" not in stderr
    assert "terminated by SIGTERM during start-up, before the first step" in stderr
    assert not (out / cli.RUN_JSON).exists() and not (out / cli.RUN_CSV).exists()


def test_a_signal_after_run_json_is_written_ends_with_its_final_status(tmp_path):
    """A signal between writing run.json ("running") and the first step (while the recording
    opens) leaves run.json 'interrupted', with the header-only CSV, not 'running'."""
    out = tmp_path / "out"
    hook = """
    _recorder = cli._recorder
    def recorder(*args):
        os.kill(os.getpid(), signal.SIGINT)
        return _recorder(*args)
    cli._recorder = recorder
    """
    proc = _child(tmp_path, _sphere(out, 0.3), hook)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == cli.EXIT_INTERRUPTED, stderr
    assert "Traceback" not in stderr
    record = json.loads((out / cli.RUN_JSON).read_text())
    assert record["status"] == "interrupted" and record["rows"] == 0
    assert (out / cli.RUN_CSV).read_text().count("\n") == 1  # the header, whole
    assert ": interrupted at t = 0 s, 0 rows" in stdout


# Files may grow to this many bytes in the child: the CSV of the run below outgrows it (about
# 60 kB per simulated second at 200 triangles), its plots (< 100 kB each) and run.json do not.
FSIZE_LIMIT = 150_000


def test_a_full_disk_fails_the_run_by_name_with_whole_rows_and_plots(tmp_path):
    """RLIMIT_FSIZE makes writes past the limit fail with EFBIG, as a full disk fails them with
    ENOSPC (Python ignores SIGXFSZ, so the write raises instead of killing the process)."""
    out = tmp_path / "out"

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (FSIZE_LIMIT, FSIZE_LIMIT))

    proc = _child(tmp_path, _sphere(out, 20.0), preexec_fn=limit)
    record, text = _finished(out, proc, cli.EXIT_FAILED, "failed")
    csv = out / cli.RUN_CSV
    assert record["error"].startswith(f"OutputError: cannot write {csv}: File too large")
    assert f"mjrft run: failed: OutputError: cannot write {csv}: File too large" in text
    assert 0 < record["simulated_s"] < 20.0
    assert csv.stat().st_size <= FSIZE_LIMIT
    assert {p.name for p in out.glob("*.png")} == set(cli.RUN_PLOTS)  # of the rows kept


def test_a_failed_write_is_cut_back_to_the_last_whole_row(tmp_path, monkeypatch):
    """The writer fails half-way through a block (ENOSPC after some bytes landed): the file
    keeps the whole rows that landed and ends at the last of them, the error names the file and
    what it keeps, and the close raises the same error instead of writing past the gap."""
    columns = ["time_s", "a"]
    sink = simulate.CsvSink(tmp_path / "t.csv", columns, flush_s=1e9)
    for i in range(10):
        sink.append(np.array([0.001 * i, float(i)]))
    sink.flush()
    whole = (tmp_path / "t.csv").read_bytes()
    real_write = os.write

    def full_disk(fd, data):
        if len(data) > 5:  # half a block lands, then the disk is full
            return real_write(fd, bytes(data[: len(data) // 2]))
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(simulate.os, "write", full_disk)
    for i in range(10, 20):
        sink.append(np.array([0.001 * i, float(i)]))
    with pytest.raises(simulate.OutputError, match=r"t\.csv: No space left on device") as e:
        sink.flush()
    monkeypatch.setattr(simulate.os, "write", real_write)
    kept = sink.rows_written - 10
    assert 0 < kept < 10  # the whole rows of the half that landed
    assert f"the {sink.rows_written} rows written before, each whole" in str(e.value)
    rows = _whole_rows(tmp_path / "t.csv")
    assert (tmp_path / "t.csv").read_bytes().startswith(whole)
    np.testing.assert_array_equal(rows[:, 1], np.arange(10 + kept))
    assert sink.last_written[1] == rows[-1, 1]
    size = (tmp_path / "t.csv").stat().st_size
    sink.append(np.array([1.0, 1.0]))
    with pytest.raises(simulate.OutputError):
        sink.close()
    assert (tmp_path / "t.csv").stat().st_size == size  # nothing written past the gap


def test_a_run_from_another_thread_needs_no_signal_handlers(tmp_path):
    """Python delivers signals to the main thread only, and installs handlers only there."""
    import threading

    codes = []
    args = ["run", *_sphere(tmp_path / "out", 0.01), "--no-plots"]
    worker = threading.Thread(target=lambda: codes.append(cli.main(args)))
    worker.start()
    worker.join()
    assert codes == [0]
    assert json.loads((tmp_path / "out" / cli.RUN_JSON).read_text())["status"] == "completed"
