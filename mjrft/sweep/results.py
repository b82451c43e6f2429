"""A study's results folder: ``study.toml`` (the study as given), ``study.json`` (what
identifies it, ``Study.record``) and ``results.csv``, one row per finished run, appended and
flushed to disk as each run ends, so an interrupted sweep resumes where it stopped."""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path
from typing import Any

from mjrft.sweep.errors import StudyError
from mjrft.sweep.study import Study

RESULTS_CSV = "results.csv"
STUDY_JSON = "study.json"
STUDY_TOML = "study.toml"
TAIL_COLUMNS = ("status", "error", "wall_s", "seed", "versions")


def columns(study: Study) -> list[str]:
    """The table's header: run_id, the parameters, the metrics, then TAIL_COLUMNS."""
    return ["run_id", *(p.name for p in study.parameters), *(m.name for m in study.metrics),
            *TAIL_COLUMNS]  # fmt: skip


def cell(value: Any) -> str:
    """A value as written in the table: floats exactly (shortest round-trip repr), NaN as an
    empty cell."""
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
    """The results CSV of a folder, open for appending rows (``append``) as runs finish.

    Attributes: path, columns, done (run ids already in the table: never recomputed).
    """

    def __init__(self, path: Path, header: list[str], done: set[str]) -> None:
        self.path, self.columns, self.done = path, header, done
        self._fh = open(path, "a", newline="")

    @classmethod
    def open(cls, out: str | Path, study: Study, resume: bool) -> ResultsTable:
        """Create `out` for `study`, or with `resume` reopen it, after checking that it holds
        this study (same record); refuses a folder holding results without `resume`."""
        out = Path(out)
        if out.exists() and not out.is_dir():
            raise StudyError(f"--out {str(out)!r} is a file, not a folder")
        out.mkdir(parents=True, exist_ok=True)
        path, record = out / RESULTS_CSV, json.loads(json.dumps(study.record(), default=str))
        header = columns(study)
        if (out / STUDY_JSON).exists():
            if not resume:
                raise StudyError(
                    f"{str(out)!r} already holds a sweep ({_count(path)} runs in {RESULTS_CSV}); "
                    "pass --resume (resume=True) to continue it, or choose another folder"
                )
            check_same_study(out, study)
            return cls(path, header, _finished(path, header))
        if path.exists():
            raise StudyError(f"{str(path)!r} exists but {STUDY_JSON} does not: not a sweep folder")
        (out / STUDY_TOML).write_text(study.text)
        with open(out / STUDY_JSON, "w") as fh:
            json.dump(record, fh, indent=2)
            fh.write("\n")
        with open(path, "w", newline="") as fh:
            csv.writer(fh, lineterminator="\n").writerow(header)
        return cls(path, header, set())

    def append(self, row: dict[str, Any]) -> None:
        """Write one finished run's row and hand it to the disk (it survives a SIGKILL)."""
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow([cell(row.get(c, "")) for c in self.columns])
        self._fh.write(buf.getvalue())  # one write per row: a kill leaves at most its tail
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self.done.add(row["run_id"])

    def close(self) -> None:
        """Close the file (idempotent)."""
        self._fh.close()


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
    """Run ids of the complete rows, after cutting off a row a kill left half-written."""
    if not path.exists():
        with open(path, "w", newline="") as fh:
            csv.writer(fh, lineterminator="\n").writerow(header)
        return set()
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        with open(path, "r+b") as fh:
            fh.truncate(data.rfind(b"\n") + 1)
    rows = list(csv.reader(io.StringIO(path.read_text())))
    if not rows or rows[0] != header:
        raise StudyError(f"{str(path)!r} has other columns than this study's ({', '.join(header)})")
    return {r[0] for r in rows[1:] if len(r) == len(header)}


def load_results(out: str | Path) -> list[dict[str, Any]]:
    """The rows of a results folder's table (complete rows, in the order they finished), cells
    parsed (``parse_cell``; error and versions kept as text)."""
    path = Path(out) / RESULTS_CSV
    if not path.exists():
        raise StudyError(f"no results table {str(path)!r}")
    rows = list(csv.reader(io.StringIO(path.read_text())))
    header, out_rows = rows[0], []
    for r in rows[1:]:
        if len(r) != len(header):
            continue
        row = {k: parse_cell(v) for k, v in zip(header, r, strict=True)}
        row["error"], row["versions"] = r[header.index("error")], r[header.index("versions")]
        row["run_id"] = r[0]
        out_rows.append(row)
    return out_rows
