"""Recordings cut short (full disk, SIGKILL) read back up to their last complete message."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest

pytest.importorskip("rerun")
from mjrft.app import cli, rrd_file, view, viz

MODELS = Path(__file__).resolve().parents[1] / "models"
# A salvaged copy has no manifest: rerun reads it by scanning, and says so.
pytestmark = pytest.mark.filterwarnings("ignore:RRD file has no footer")


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("rec")
    rrd = out / "sphere.rrd"
    args = ["run", str(MODELS / "sphere_drop.xml"), "--duration", "0.3", "--out", str(out)]
    assert cli.main(args + ["--triangles", "200", "--no-plots", "--rrd", str(rrd)]) == 0
    return rrd


def _rows_per_entity(path: Path) -> Counter:
    from rerun.chunk import RrdReader

    counts: Counter = Counter()
    for chunk in RrdReader(str(path)).stream():
        counts[chunk.entity_path] += chunk.num_rows
    return counts


def test_a_closed_recording_is_finished_and_read_as_it_is(recording):
    found = rrd_file.scan(recording)
    assert found.finished and found.messages > 0 and found.complete < found.size  # + manifest
    assert view.readable_copy(recording) == recording


@pytest.mark.parametrize("fraction", [0.05, 0.3, 0.6, 0.95])
def test_a_cut_recording_reads_back_its_complete_messages(recording, tmp_path, fraction):
    data = recording.read_bytes()
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(data[: int(len(data) * fraction)])
    found = rrd_file.scan(cut)
    assert not found.finished and found.complete <= found.size
    from rerun.chunk import RrdReader

    if found.complete < found.size:  # a message cut in two: rerun's reader refuses the file
        with pytest.raises(RuntimeError, match="exceeds file size"):
            list(RrdReader(str(cut)).stream())
    copy = tmp_path / "salvaged.rrd"
    if found.messages == 0:  # cut inside the first message (how rerun batched it varies)
        with pytest.raises(ValueError, match="no complete message"):
            rrd_file.salvage(cut, copy)
        return
    assert rrd_file.salvage(cut, copy) == found
    assert copy.read_bytes() == data[: found.complete]  # a prefix, byte for byte
    full, kept = _rows_per_entity(recording), _rows_per_entity(copy)
    assert all(kept[e] <= full[e] for e in kept)
    # read_entity reads the cut file itself, as a prefix of the full file's rows.
    steps = [r["step"] for r in viz.read_entity(cut, "world/bodies/sphere") if "step" in r]
    all_steps = [r["step"] for r in viz.read_entity(recording, "world/bodies/sphere")]
    assert steps == all_steps[: len(steps)]


def test_view_recording_opens_a_salvaged_copy_of_a_cut_file(recording, tmp_path, capsys):
    data = recording.read_bytes()
    cut = tmp_path / "run.rrd"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    opened = view.readable_copy(cut)
    assert opened == tmp_path / "run.salvaged.rrd" and opened.is_file()
    assert "was not closed" in capsys.readouterr().err
    assert rrd_file.scan(opened).messages == rrd_file.scan(cut).messages


def test_what_is_not_a_recording_is_named(tmp_path):
    bad = tmp_path / "notes.rrd"
    bad.write_text("not a recording")
    with pytest.raises(ValueError, match="notes.rrd.*not a rerun recording"):
        rrd_file.scan(bad)
    with pytest.raises(ValueError, match="another file"):
        rrd_file.salvage(bad, bad)


def test_a_killed_run_keeps_its_recording_readable(tmp_path):
    out = tmp_path / "run"
    rrd = out / "sphere.rrd"
    cli_main = "from mjrft.app.cli import main; raise SystemExit(main())"
    cmd = [sys.executable, "-c", cli_main, "run", str(MODELS / "sphere_drop.xml")]
    cmd += ["--duration", "1000", "--out", str(out), "--triangles", "200", "--rrd", str(rrd)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and (not rrd.exists() or rrd.stat().st_size < 200_000):
            time.sleep(0.2)
        assert rrd.exists(), "the run wrote no recording"
        time.sleep(1.5)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    assert not rrd_file.scan(rrd).finished
    forces = viz.read_entity(rrd, "rft/sphere/force/z")
    assert len(forces) > 100  # frames from the run's first seconds, readable
