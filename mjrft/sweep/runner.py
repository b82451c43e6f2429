"""``run_study``: a study's runs on a backend, into a results folder, resumable."""

from __future__ import annotations

import contextlib
import functools
import signal
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from mjrft.field.signals import HeldSignals
from mjrft.sweep import backends
from mjrft.sweep.errors import StudyError, SweepStopped, one_line
from mjrft.sweep.executor import STATUS_OK, STATUS_RETRY, stops_the_sweep
from mjrft.sweep.results import RESULTS_CSV, ResultsTable, describe, load_results
from mjrft.sweep.study import RunSpec, Study

#: progress(done, total, row): after each finished run (row None at the start); counts are of
#: the runs this call computes.
Progress = Callable[[int, int, "dict | None"], None]


@dataclass
class SweepSummary:
    """What ``run_study`` did: runs in the study, already in the folder (skipped), computed now,
    failed among those (status "failed" or "retry"), "retry" among those (a resume runs them
    again), failed among the skipped ones; the results table and plots written; and the
    warnings the runs computed now raised: "Category: message" -> the runs that raised it."""

    total: int
    skipped: int
    computed: int = 0
    failed: int = 0
    retry: int = 0
    failed_before: int = 0
    table: Path = Path()
    plots: list[Path] = field(default_factory=list)
    warnings: dict[str, list[str]] = field(default_factory=dict)

    def warning_groups(self) -> list[tuple[str, int, str]]:
        """(category, how many runs raised it, the first message) per category of warning the
        runs computed now raised (each run's own are in its warnings column)."""
        groups: dict[str, tuple[str, set[str]]] = {}
        for text, run_ids in self.warnings.items():
            category, message = text.split(": ", 1)
            groups.setdefault(category, (message, set()))[1].update(run_ids)
        return [(c, len(ids), first) for c, (first, ids) in groups.items()]

    def warning_lines(self) -> list[str]:
        """One line per category of warning (``warning_groups``), for a summary printed once
        per sweep."""
        return [
            f"{category} in {n} of {self.computed} runs; the first: {first}"
            for category, n, first in self.warning_groups()
        ]


def run_study(
    study: Study,
    out: str | Path,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    resume: bool = False,
    plots: bool = True,
    progress: Progress | None = None,
) -> SweepSummary:
    """Run every run of `study` not yet in the folder `out` and append its row to
    ``out/results.csv`` as it finishes; then draw the plots (``plot_study``).

    Args:
      workers: processes (local; default all cores) or CPUs of a new local Ray instance.
      backend: "local" (worker processes), "ray" or "serial" (this process).
      address: the Ray cluster ("auto", "HOST:6379"); None starts a local instance unless Ray
        is already initialised in this process.
      resume: continue the sweep `out` holds (refused if its study differs, naming what);
        without it a folder that holds a sweep is refused.
    Raises:
      StudyError for bad input, and before any run starts and anything is written when every
      run would fail to load alike (``check_loads``); FolderLocked (a StudyError) when another
      sweep is writing `out`; KeyboardInterrupt (Ctrl-C) after ending the runs in flight, with
      every finished row on disk (resume with ``resume=True``); SweepStopped, likewise, when
      something outside the runs fails (the disk full: the table keeps every whole row, the
      run that met it is "retry").
    """
    if backend not in backends.BACKENDS:
        raise StudyError(f"backend {backend!r}; valid: {', '.join(backends.BACKENDS)}")
    if workers is not None and workers < 1:
        raise StudyError(f"workers = {workers}: need at least 1")
    out = Path(out)
    check_loads(study)
    session = (
        backends.ray_session(workers, address) if backend == "ray" else contextlib.nullcontext()
    )
    with session as own_instance:  # Ray reached before the folder is written
        backend_run = _backend(backend, workers, own_instance)
        return _sweep(study, out, resume, plots, progress, backend_run)


def _backend(backend: str, workers: int | None, own_instance: bool | None) -> Callable:
    """The function ``run(study, runs, out, on_row)`` of `backend`."""
    if backend == "serial":
        return backends.serial
    if backend == "local":
        return functools.partial(backends.local, workers=workers or backends.cores())
    return functools.partial(backends.ray_backend, own_instance=bool(own_instance))


def _sweep(
    study: Study,
    out: Path,
    resume: bool,
    plots: bool,
    progress: Progress | None,
    backend_run: Callable[[Study, list[RunSpec], Path, Callable[[dict], None]], None],
) -> SweepSummary:
    """``run_study`` once its first run loads and its backend is ready."""
    table = ResultsTable.open(out, study, resume)
    runs = study.runs()
    pending = [r for r in runs if r.run_id not in table.done]
    summary = SweepSummary(len(runs), len(runs) - len(pending), table=out / RESULTS_CSV)
    if summary.skipped:
        summary.failed_before = sum(r["status"] != STATUS_OK for r in load_results(out))

    def on_row(row: dict) -> None:
        with HeldSignals((signal.SIGINT, signal.SIGTERM)):  # a row is written whole or not
            table.append(row)
        _count(summary, row)
        if progress is not None:
            progress(summary.computed, len(pending), row)
        if stops_the_sweep(row):
            raise SweepStopped(
                f"run {row['run_id']} could not write its files: {row['error']}; every later "
                "run would fail alike, so the sweep stopped (the run is recorded with status "
                "retry and a resume runs it again)"
            )

    if progress is not None:
        progress(0, len(pending), None)
    try:
        _remove_partial_series(out)
        backend_run(study, pending, out, on_row)
        if plots:
            summary.plots = _plots(study, out)
    finally:
        _remove_partial_series(out)  # of runs stopped in flight: never recorded
        table.close()
    return summary


def _count(summary: SweepSummary, row: dict) -> None:
    """Add a finished run's row to the summary: its status and its warnings."""
    summary.computed += 1
    summary.failed += row["status"] != STATUS_OK
    summary.retry += row["status"] == STATUS_RETRY
    for text in (w for w in row.get("warnings", "").split(" | ") if ": " in w):
        summary.warnings.setdefault(text, []).append(row["run_id"])


def _remove_partial_series(out: Path) -> None:
    """Remove the unfinished time series (``runs/.<run_id>.csv.<pid>.tmp``) of runs that were
    stopped in flight, by this sweep or an earlier one: with the folder locked and this sweep's
    workers ended, no run is writing them."""
    from mjrft.sweep.executor import RUNS_DIR

    for tmp in (out / RUNS_DIR).glob(".*.csv.*.tmp"):
        tmp.unlink(missing_ok=True)


def _plots(study: Study, out: Path) -> list[Path]:
    from mjrft.sweep.plots import plot_study

    try:
        return plot_study(study, out)
    except OSError as exc:
        raise SweepStopped(
            f"every run is in {str(out / RESULTS_CSV)!r}, but its figures could not be written: "
            f"{describe(exc)}; draw them with --plots-only (plot_study) once there is room"
        ) from None


def check_loads(study: Study) -> None:
    """Stop a study whose every run would fail before its first step, with that error, instead
    of failing each run: the first run is loaded here as its worker loads it (``executor.load``:
    the model compiled with the engine, its field, controller and metrics), without simulating.
    If it fails, so is the run most unlike it (for a grid the last, which differs in every
    parameter that varies); the same error from both is the study's own (its model, a ``[set]``
    value), not a parameter value's, and raises a StudyError. An error that a value causes is
    left to the sweep: those runs are failed rows and the others go on."""
    runs = study.runs()
    first = runs[0]
    error = _load_error(study, first)
    if error is None:
        return
    if len(runs) > 1:
        names = [p.name for p in study.parameters]
        other = max(runs[1:], key=lambda r: sum(r.values[k] != first.values[k] for k in names))
        if _load_error(study, other) != error:
            return
        what = (
            f"its first run ({first.run_id}) and the one most unlike it ({other.run_id}) fail "
            "to load with the same error, which no parameter value causes"
        )
    else:
        what = f"its only run ({first.run_id}) fails to load"
    raise StudyError(f"study {study.name!r}: {what}; no run was started: {error}")


def _load_error(study: Study, run: RunSpec) -> str | None:
    """The error `run` fails with before its first step, as its results row would give it."""
    from mjrft.sweep.executor import load

    try:
        load(study, run)
    except Exception as exc:  # what executor.execute records as the run's error
        return one_line(f"{type(exc).__name__}: {exc}")
    return None
