"""``run_study``: a study's runs on a backend, into a results folder, resumable."""

from __future__ import annotations

import signal
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from mjrft.field.signals import HeldSignals
from mjrft.sweep import backends
from mjrft.sweep.errors import StudyError
from mjrft.sweep.executor import STATUS_OK
from mjrft.sweep.results import RESULTS_CSV, ResultsTable
from mjrft.sweep.study import Study

#: progress(done, total, row): after each finished run (row None at the start); counts are of
#: the runs this call computes.
Progress = Callable[[int, int, "dict | None"], None]


@dataclass
class SweepSummary:
    """What ``run_study`` did: runs in the study, already in the folder (skipped), computed now,
    failed among those; the results table and plots written."""

    total: int
    skipped: int
    computed: int = 0
    failed: int = 0
    table: Path = Path()
    plots: list[Path] = field(default_factory=list)


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
      StudyError for bad input; KeyboardInterrupt (Ctrl-C) after ending the runs in flight,
      with every finished row on disk (resume with ``resume=True``).
    """
    if backend not in backends.BACKENDS:
        raise StudyError(f"backend {backend!r}; valid: {', '.join(backends.BACKENDS)}")
    if workers is not None and workers < 1:
        raise StudyError(f"workers = {workers}: need at least 1")
    out = Path(out)
    table = ResultsTable.open(out, study, resume)
    runs = study.runs()
    pending = [r for r in runs if r.run_id not in table.done]
    summary = SweepSummary(len(runs), len(runs) - len(pending), table=out / RESULTS_CSV)

    def on_row(row: dict) -> None:
        with HeldSignals((signal.SIGINT, signal.SIGTERM)):  # a row is written whole or not
            table.append(row)
        summary.computed += 1
        summary.failed += row["status"] != STATUS_OK
        if progress is not None:
            progress(summary.computed, len(pending), row)

    if progress is not None:
        progress(0, len(pending), None)
    try:
        if backend == "serial":
            backends.serial(study, pending, out, on_row)
        elif backend == "local":
            backends.local(study, pending, out, on_row, workers or backends.cores())
        else:
            backends.ray_backend(study, pending, out, on_row, workers, address)
    finally:
        table.close()
    if plots:
        from mjrft.sweep.plots import plot_study

        summary.plots = plot_study(study, out)
    return summary
