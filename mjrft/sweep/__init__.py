"""Parameter sweeps: a study (TOML) of one MJCF model, its runs on local processes or Ray, a
resumable results table, and figures (docs/sweeps.md).

Modules: ``study`` (the description, its runs), ``paths`` (where values go in the model),
``expressions`` (values derived from parameters), ``metrics`` (what a run records), ``executor``
(one run), ``backends`` (serial, local processes, Ray), ``results`` (the folder and its table),
``runner`` (``run_study``), ``single`` (``run_one``, ``evaluate``: one parameter set),
``tune`` and ``optuna`` (a study under Ray Tune or Optuna), ``plots``, ``command`` (``mjrft
sweep``).

    from mjrft.sweep import Study, run_study
    study = Study.load("studies/root_circumnutation.toml")
    summary = run_study(study, "out", workers=2)
"""

from mjrft.sweep.errors import FolderLocked, StudyError, SweepStopped
from mjrft.sweep.plots import plot_study
from mjrft.sweep.results import check_same_study, load_results
from mjrft.sweep.runner import SweepSummary, run_study
from mjrft.sweep.single import RunFailed, evaluate, run_one
from mjrft.sweep.study import Parameter, RunSpec, Study

__all__ = [
    "FolderLocked",
    "Parameter",
    "RunFailed",
    "RunSpec",
    "Study",
    "StudyError",
    "SweepStopped",
    "SweepSummary",
    "check_same_study",
    "evaluate",
    "load_results",
    "plot_study",
    "run_one",
    "run_study",
]
