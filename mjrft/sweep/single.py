"""One parameter set of a study, run in this process: ``run_one`` (its results row) and
``evaluate`` (its metrics, or RunFailed): the programmatic path Ray Tune's and Optuna's adapters
(``mjrft.sweep.tune``, ``mjrft.sweep.optuna``) and your own loops build on."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mjrft.sweep.errors import StudyError
from mjrft.sweep.executor import RUNS_DIR, STATUS_OK, Report, execute
from mjrft.sweep.study import Study


class RunFailed(RuntimeError):
    """The run failed (status "failed" or "retry"); ``row`` is its results row (``error``: why)."""

    def __init__(self, row: dict[str, Any]) -> None:
        super().__init__(f"run {row['run_id']} {row['status']}: {row['error']}")
        self.row = row


def run_one(
    study: Study | str | Path,
    params: dict[str, Any],
    out: str | Path | None = None,
    report: Report | None = None,
    report_every: float | None = None,
) -> dict[str, Any]:
    """Run `study`'s model with one set of parameter values, in this process, as a sweep's
    worker runs it; returns its results row (``mjrft.sweep.executor.execute``: run_id, the
    values, the metrics, max_froude, quasi_static, status, error, warnings, wall_s, seed,
    versions). A failure of the run is in the row, not raised.

    Args:
      study: a Study, or the path of its TOML file.
      params: parameter name -> value, every parameter of the study and no other; any value,
        on the study's grid or range or not (Tune's and Optuna's draws).
      out: the folder of the run's time series (``runs/<run_id>.csv``) when the study has
        ``timeseries = true``; None writes nothing.
      report: called as ``report(t, metrics)`` every `report_every` simulated seconds (default
        a tenth of the run) with the built-in metrics over the states so far, t in s; an
        exception it raises stops the run and is raised here (early stopping).
    Raises:
      StudyError naming a missing or unknown parameter.
    """
    if not isinstance(study, Study):
        study = Study.load(study)
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / RUNS_DIR).mkdir(exist_ok=True)
    return execute(study, study.run(params), out, report, report_every)


def evaluate(
    study: Study | str | Path,
    params: dict[str, Any],
    report: Report | None = None,
    report_every: float | None = None,
) -> dict[str, float]:
    """The metrics (name -> value, the study's ``[metrics]`` units) of `study` run with one set
    of parameter values (``run_one``), plus ``max_froude``; raises RunFailed (its row says why)
    if the run failed, StudyError for a missing or unknown parameter."""
    if not isinstance(study, Study):
        study = Study.load(study)
    row = run_one(study, params, report=report, report_every=report_every)
    if row["status"] != STATUS_OK:
        raise RunFailed(row)
    return {**{m.name: row[m.name] for m in study.metrics}, "max_froude": row["max_froude"]}


__all__ = ["RunFailed", "StudyError", "evaluate", "run_one"]
