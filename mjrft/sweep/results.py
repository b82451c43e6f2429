"""A study's results folder: ``study.toml`` (the study as given), ``study.json`` (what
identifies it, ``Study.record``), ``results.csv``, one row per finished run, appended and handed
to the disk as each run ends, so an interrupted sweep resumes where it stopped, and ``.lock``,
which names the sweep writing the folder (one at a time)."""

from __future__ import annotations

import csv
import errno
import fcntl
import io
import json
import math
import os
import socket
import time
import warnings
from pathlib import Path
from typing import Any

from mjrft.sweep.errors import FolderLocked, StudyError, SweepStopped
from mjrft.sweep.study import RESERVED, Study

RESULTS_CSV = "results.csv"
STUDY_JSON = "study.json"
STUDY_TOML = "study.toml"
#: The folder's lock file: flock(2) on it is held while a sweep writes the folder (released by
#: the kernel when that process ends, however it ends); its text names the holder.
LOCK_FILE = ".lock"
#: A run's status: "ok"; "failed" (the run's own outcome, e.g. a value that does not compile or a
#: divergence: kept by a resume); "retry" (it did not finish for a reason outside it, a full
#: disk or a killed worker: a resume runs it again and replaces the row).
STATUS_OK, STATUS_FAILED, STATUS_RETRY = "ok", "failed", "retry"
#: Columns after the metrics: the largest Froude number v^2/(g L) of a body in the medium and
#: whether it stayed <= 1 (``mjrft.app.regime``), then the run's outcome and provenance.
TAIL_COLUMNS = RESERVED[1:]


def columns(study: Study) -> list[str]:
    """The table's header: run_id, the parameters, the metrics, then TAIL_COLUMNS."""
    return ["run_id", *(p.name for p in study.parameters), *(m.name for m in study.metrics),
            *TAIL_COLUMNS]  # fmt: skip


def cell(value: Any) -> str:
    """A value as written in the table: floats exactly (shortest round-trip repr), NaN and None
    as an empty cell, booleans as true and false."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return str(value)


def parse_cell(text: str) -> Any:
    """A table cell read back: int, float (an empty cell is NaN) or the string itself."""
    if text == "":
        return math.nan
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _differences(old: Any, new: Any, prefix: str = "") -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        out = []
        for key in list(old) + [k for k in new if k not in old]:
            name = f"{prefix}.{key}" if prefix else str(key)
            out += _differences(old.get(key, "(absent)"), new.get(key, "(absent)"), name)
        return out
    return [] if old == new else [f"{prefix}: {_short(old)} in the folder, {_short(new)} now"]


def _short(value: Any) -> str:
    text = json.dumps(value, default=str)
    return text if len(text) <= 80 else text[:77] + "..."


class ResultsTable:
    """The results CSV of a folder, open for appending rows (``append``) as runs finish, and the
    folder's lock, held until ``close``.

    Attributes: path, columns, done (run ids already in the table: never recomputed).
    """

    def __init__(self, path: Path, header: list[str], done: set[str], lock: int) -> None:
        self.path, self.columns, self.done, self._lock = path, header, done, lock
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND)

    @classmethod
    def open(cls, out: str | Path, study: Study, resume: bool) -> ResultsTable:
        """Create `out` for `study`, or with `resume` reopen it, after checking that it holds
        this study (same record); refuses a folder holding results without `resume`, and one
        another sweep is writing (``FolderLocked``, naming it)."""
        out = Path(out)
        if out.exists() and not out.is_dir():
            raise StudyError(f"--out {str(out)!r} is a file, not a folder")
        path, record = out / RESULTS_CSV, json.loads(json.dumps(study.record(), default=str))
        if path.exists() and not (out / STUDY_JSON).exists():
            raise StudyError(f"{str(path)!r} exists but {STUDY_JSON} does not: not a sweep folder")
        out.mkdir(parents=True, exist_ok=True)
        lock = lock_folder(out)
        try:
            header = columns(study)
            if (out / STUDY_JSON).exists():
                if not resume:
                    raise StudyError(
                        f"{str(out)!r} already holds a sweep ({_count(path)} runs in "
                        f"{RESULTS_CSV}); pass --resume (resume=True) to continue it, or choose "
                        "another folder"
                    )
                check_same_study(out, study)
                return cls(path, header, _finished(path, header), lock)
            _create(out, study.text, record, header)
            return cls(path, header, set(), lock)
        except BaseException:
            os.close(lock)
            raise

    def append(self, row: dict[str, Any]) -> None:
        """Write one finished run's row and hand it to the disk (it survives a SIGKILL). If the
        disk refuses it (full, over quota, read-only), the file is cut back to the rows before
        and SweepStopped says why."""
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow([cell(row.get(c, "")) for c in self.columns])
        data = buf.getvalue().encode()
        size = os.fstat(self._fd).st_size
        try:
            written = 0
            while written < len(data):  # one write per row: a kill leaves at most its tail
                written += os.write(self._fd, data[written:])
            os.fsync(self._fd)
        except OSError as exc:
            try:
                os.ftruncate(self._fd, size)  # no cut row is left behind
            except OSError:
                pass  # the next resume drops it (``_finished``)
            raise SweepStopped(
                f"cannot write the row of run {row['run_id']} to {str(self.path)!r}: "
                f"{describe(exc)}; the table keeps every row before it, whole"
            ) from None
        self.done.add(row["run_id"])

    def close(self) -> None:
        """Close the file and release the folder, its lock file emptied (idempotent)."""
        if self._lock >= 0:
            try:
                os.ftruncate(self._lock, 0)  # names no one once released
            except OSError:
                pass
        for name in ("_fd", "_lock"):
            fd = getattr(self, name)
            if fd >= 0:
                os.close(fd)
                setattr(self, name, -1)


def _create(out: Path, text: str, record: dict, header: list[str]) -> None:
    """Write a new folder's study.toml, results.csv's header and, last, study.json (what makes
    it a sweep folder); if the disk refuses one, remove them and raise a StudyError."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(header)
    files = {
        STUDY_TOML: text,
        RESULTS_CSV: buf.getvalue(),
        STUDY_JSON: json.dumps(record, indent=2),
    }
    try:
        for name, content in files.items():
            (out / name).write_text(content if content.endswith("\n") else content + "\n")
    except OSError as exc:
        for name in files:
            (out / name).unlink(missing_ok=True)
        raise StudyError(f"cannot write the results folder {str(out)!r}: {describe(exc)}") from None


def describe(exc: OSError) -> str:
    """An OSError as "No space left on device (ENOSPC)"."""
    name = errno.errorcode.get(exc.errno or 0, "")
    what = exc.strerror or str(exc)
    return f"{what} ({name})" if name else what


def lock_folder(out: Path) -> int:
    """Take `out`'s lock (flock on ``out/.lock``, written with this process's pid, host and start
    time) and return its descriptor; raises FolderLocked naming the sweep that holds it."""
    fd = os.open(out / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        holder = os.pread(fd, 4096, 0).decode(errors="replace").strip()
        if exc.errno in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS):
            warnings.warn(
                f"cannot lock {str(out / LOCK_FILE)!r}: {describe(exc)} (the filesystem has no "
                "locks): a second sweep writing this folder at once would not be refused",
                RuntimeWarning,
                stacklevel=3,
            )
            return fd
        os.close(fd)
        if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise StudyError(f"cannot lock {str(out / LOCK_FILE)!r}: {describe(exc)}") from None
        raise FolderLocked(
            f"{str(out)!r} is being written by another sweep ({holder or 'starting'}); two "
            "sweeps in one folder would run and record the same runs twice: wait for it to end "
            "or stop it (Ctrl-C or SIGTERM keep its rows), or choose another folder"
        ) from None
    stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    text = f"pid {os.getpid()} on host {socket.gethostname()}, since {stamp}\n".encode()
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, text, 0)
    except OSError:
        pass  # a full disk: the lock holds all the same, nameless
    return fd


def check_same_study(out: str | Path, study: Study) -> None:
    """Raise a StudyError naming every difference between `study` and the one `out` holds."""
    out = Path(out)
    try:
        old = json.loads((out / STUDY_JSON).read_text())
    except (OSError, ValueError) as exc:
        raise StudyError(f"cannot read {str(out / STUDY_JSON)!r}: {exc}") from None
    new = json.loads(json.dumps(study.record(), default=str))
    diffs = _differences(old, new)
    if diffs:
        raise StudyError(
            f"the study differs from the one in {str(out)!r}, so its results cannot be "
            f"continued there: {'; '.join(diffs[:8])}" + (" ..." if len(diffs) > 8 else "")
        )


def _count(path: Path) -> int:
    return max(0, len(path.read_text().splitlines()) - 1) if path.exists() else 0


def _finished(path: Path, header: list[str]) -> set[str]:
    """Run ids of the finished runs, after cleaning the table for a resume: a row a kill left
    half-written, the rows of status "retry" (to run again) and any repeat of a run's row are
    dropped (the file replaced atomically); the rows kept are unchanged, byte for byte."""
    if not path.exists():
        with open(path, "w", newline="") as fh:
            csv.writer(fh, lineterminator="\n").writerow(header)
        return set()
    data = path.read_bytes()
    whole = data[: data.rfind(b"\n") + 1]
    lines = whole.decode().splitlines(keepends=True)
    if not lines or next(csv.reader(lines[:1])) != header:
        raise StudyError(f"{str(path)!r} has other columns than this study's ({', '.join(header)})")
    status = header.index("status")
    kept, done = [lines[0]], set()
    for line in lines[1:]:
        r = next(csv.reader([line]), [])
        if len(r) == len(header) and r[0] not in done and r[status] != STATUS_RETRY:
            kept.append(line)
            done.add(r[0])
    if len(kept) < len(lines) or len(whole) < len(data):
        _replace_file(path, "".join(kept).encode())
    return done


def _replace_file(path: Path, data: bytes) -> None:
    """Replace `path`'s content by `data` atomically (a crash leaves the old or the new file)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        what = f"cannot rewrite {str(path)!r} for the resume: {describe(exc)}"
        raise SweepStopped(what) from None
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def load_results(out: str | Path) -> list[dict[str, Any]]:
    """The rows of a results folder's table (complete rows, in the order they finished), cells
    parsed (``parse_cell``; error, warnings and versions kept as text, quasi_static a bool or
    None for a run that did not finish)."""
    path = Path(out) / RESULTS_CSV
    if not path.exists():
        raise StudyError(f"no results table {str(path)!r}")
    rows = list(csv.reader(io.StringIO(path.read_text())))
    header, out_rows = rows[0], []
    text = [c for c in ("run_id", "error", "warnings", "versions") if c in header]
    for r in rows[1:]:
        if len(r) != len(header):
            continue
        row = {k: parse_cell(v) for k, v in zip(header, r, strict=True)}
        row.update({c: r[header.index(c)] for c in text})
        if "quasi_static" in row:
            flag = r[header.index("quasi_static")]
            row["quasi_static"] = {"true": True, "false": False}.get(flag)
        out_rows.append(row)
    return out_rows
