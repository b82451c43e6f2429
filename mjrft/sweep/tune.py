"""A study under Ray Tune (``pip install 'mjrft[ray]'``): ``trainable(study)`` is a function
trainable that runs one parameter set (``mjrft.sweep.single.run_one``) and reports the built-in
metrics as the run goes (so schedulers such as ASHA stop poor trials early) and all metrics at
its end; ``search_space(study)`` is Tune's search space of the study's parameters. Tune's own
experiment checkpoints resume an interrupted experiment (``Tuner.restore``; docs/sweeps.md).

    from ray import tune
    from mjrft.sweep import Study
    from mjrft.sweep.tune import search_space, trainable

    study = Study.load("drop.toml")
    tuner = tune.Tuner(trainable(study), param_space=search_space(study),
                       tune_config=tune.TuneConfig(metric="fz_peak_N", mode="max"))
    best = tuner.fit().get_best_result().config
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mjrft.sweep.errors import StudyError
from mjrft.sweep.executor import STATUS_OK
from mjrft.sweep.single import RunFailed, run_one
from mjrft.sweep.study import Study

#: Key of the simulated time [s] in every report (a ``time_attr`` for Tune's schedulers).
SIM_TIME = "sim_time_s"


def _tune() -> Any:
    try:
        from ray import tune
    except ImportError:
        raise StudyError("Ray Tune is needed: pip install 'mjrft[ray]'") from None
    return tune


def search_space(study: Study, grid: bool = False) -> dict[str, Any]:
    """Tune's search space of `study`'s parameters: a parameter with ``values`` (or a
    ``range``) is ``tune.choice`` of them (``tune.grid_search`` with `grid`: every value, the
    study's grid once with ``num_samples=1``), one value is that constant, and one with ``low``
    and ``high`` is ``tune.uniform`` (``loguniform`` with ``log``; ``randint`` or
    ``lograndint`` over low..high, both ends included, with ``integer``)."""
    tune = _tune()
    space: dict[str, Any] = {}
    for p in study.parameters:
        if p.values is not None:
            values = list(p.values)
            if len(values) == 1:
                space[p.name] = values[0]
            else:
                space[p.name] = tune.grid_search(values) if grid else tune.choice(values)
        elif p.integer:
            draw = tune.lograndint if p.log else tune.randint
            space[p.name] = draw(int(p.low), int(p.high) + 1)
        else:
            space[p.name] = (tune.loguniform if p.log else tune.uniform)(p.low, p.high)
    return space


def trainable(study: Study, report_every: float | None = None) -> Callable[[dict], None]:
    """A Tune function trainable of `study`: its config holds the parameter values (every
    parameter of the study, no other key). Every `report_every` simulated seconds (default a
    tenth of the run) it reports the built-in metrics over the run so far with ``sim_time_s``;
    at the end every metric, ``max_froude``, ``sim_time_s`` = the duration and ``run_id``. A
    run that fails raises RunFailed (Tune marks the trial ERROR; its error is the run's). A
    trial stopped by a scheduler ends its run at that report. Custom metrics exist only in the
    last report, so a scheduler needs a built-in metric."""
    tune = _tune()

    def report(t: float, metrics: dict[str, float]) -> None:
        tune.report({**metrics, SIM_TIME: t})

    def train(config: dict) -> None:
        row = run_one(study, dict(config), report=report, report_every=report_every)
        if row["status"] != STATUS_OK:
            raise RunFailed(row)
        final = {m.name: row[m.name] for m in study.metrics}
        tune.report({**final, "max_froude": row["max_froude"], SIM_TIME: study.duration,
                     "run_id": row["run_id"]})  # fmt: skip

    train.__name__ = train.__qualname__ = f"mjrft_{study.name}"
    return train


__all__ = ["SIM_TIME", "search_space", "trainable"]
