"""A study under Optuna (``pip install 'mjrft[optuna]'``): ``objective(study, metric)`` is an
objective for ``optuna.Study.optimize`` that draws the study's parameters from the trial
(``suggest``), runs them (``mjrft.sweep.single.run_one``) and returns the metric; it reports
the metric as the run goes, so Optuna's pruners stop poor trials early.

    import optuna
    from mjrft.sweep import Study
    from mjrft.sweep.optuna import objective

    study = Study.load("drop.toml")
    search = optuna.create_study(direction="maximize")  # the default sampler (TPE)
    search.optimize(objective(study, "fz_peak_N"), n_trials=20)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from mjrft.sweep.errors import StudyError
from mjrft.sweep.executor import STATUS_OK
from mjrft.sweep.single import run_one
from mjrft.sweep.study import Study


def _optuna() -> Any:
    try:
        import optuna
    except ImportError:
        raise StudyError("Optuna is needed: pip install 'mjrft[optuna]'") from None
    return optuna


def suggest(trial: Any, study: Study) -> dict[str, Any]:
    """`study`'s parameter values drawn from the Optuna `trial`: ``suggest_categorical`` of a
    parameter's ``values`` (numbers or strings), ``suggest_float`` between ``low`` and
    ``high`` (``log``), ``suggest_int`` with ``integer``; one value is that constant."""
    values: dict[str, Any] = {}
    for p in study.parameters:
        if p.values is not None:
            choices = list(p.values)
            if any(isinstance(c, list | dict) for c in choices):
                raise StudyError(
                    f"parameter {p.name!r}: Optuna draws numbers or strings, not the lists "
                    f"{choices[0]!r}, ...; give the list's parts as parameters of their own"
                )
            values[p.name] = (
                choices[0] if len(choices) == 1 else trial.suggest_categorical(p.name, choices)
            )
        elif p.integer:
            values[p.name] = trial.suggest_int(p.name, int(p.low), int(p.high), log=p.log)
        else:
            values[p.name] = trial.suggest_float(p.name, p.low, p.high, log=p.log)
    return values


def objective(
    study: Study,
    metric: str | Sequence[str],
    report_every: float | None = None,
    prune: bool = True,
) -> Callable[[Any], float | tuple[float, ...]]:
    """An Optuna objective of `study`: the value of `metric` (a tuple of the metrics for a
    list, for a multi-objective ``optuna.create_study(directions=...)``). Every metric,
    ``max_froude``, ``run_id`` and a failed run's ``error`` become the trial's user attributes.
    A failed run returns NaN (Optuna records the trial as failed and goes on). With `prune` (a
    single built-in metric), the metric so far is reported every `report_every` simulated
    seconds (default a tenth of the run; step = the report's number) and a trial the pruner
    stops raises ``optuna.TrialPruned``."""
    optuna = _optuna()
    names = [metric] if isinstance(metric, str) else list(metric)
    valid = [m.name for m in study.metrics]
    for name in names:
        if name not in valid:
            raise StudyError(f"metric {name!r} is not one of the study's ({', '.join(valid)})")
    single = isinstance(metric, str)
    builtin = single and next(m for m in study.metrics if m.name == metric).kind != "custom"

    def run(trial: Any) -> float | tuple[float, ...]:
        step = [0]

        def report(t: float, metrics: dict[str, float]) -> None:
            step[0] += 1
            trial.report(metrics[metric], step[0])
            if trial.should_prune():
                raise optuna.TrialPruned(f"pruned at t = {t:g} s")

        row = run_one(study, suggest(trial, study), report=report if prune and builtin else None,
                      report_every=report_every)  # fmt: skip
        for key in [*valid, "max_froude", "run_id"]:
            trial.set_user_attr(key, row[key])
        if row["status"] != STATUS_OK:
            trial.set_user_attr("error", row["error"])
            return math.nan if single else tuple(math.nan for _ in names)
        return row[metric] if single else tuple(row[n] for n in names)

    return run


__all__ = ["objective", "suggest"]
