"""One run of a study, from scratch: its model built and compiled with the engine plugin, the
simulation, its metrics; any failure of the run itself (a value that does not compile, a
diverging simulation, an exception in user code) is the run's outcome, not the sweep's end. A
failure outside the run (the disk full while it writes its time series) is status "retry": a
resume runs it again, and the sweep stops (``stops_the_sweep``)."""

from __future__ import annotations

import errno
import functools
import math
import os
import random
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from mjrft.app.regime import FROUDE_QUASI_STATIC
from mjrft.sweep import callables
from mjrft.sweep.errors import StudyError, one_line
from mjrft.sweep.metrics import Outcome, Probe
from mjrft.sweep.results import STATUS_FAILED, STATUS_OK, STATUS_RETRY
from mjrft.sweep.study import RunSpec, Study

__all__ = ["STATUS_FAILED", "STATUS_OK", "STATUS_RETRY", "execute", "stops_the_sweep"]

#: OSError numbers that say the machine, not the run, failed (no space, over quota, file too
#: large for the process's limit, read-only or failing storage): the run is "retry" and the sweep
#: stops, since every later run would fail alike.
STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EIO})
#: report(time, metrics): a run's built-in metrics so far, every ``report_every`` seconds.
Report = Callable[[float, dict[str, float]], None]
#: Folder of per-run time series in a results folder (``timeseries = true``).
RUNS_DIR = "runs"


@functools.cache
def versions() -> str:
    """The software versions a row records: ``name=version`` pairs, ``;``-separated."""
    from mjrft.app.metadata import versions as installed

    return ";".join(f"{k}={v}" for k, v in installed().items())


def execute(
    study: Study,
    run: RunSpec,
    out: str | Path | None = None,
    report: Report | None = None,
    report_every: float | None = None,
) -> dict[str, Any]:
    """Run `run` of `study` in this process and return its results row: run_id, the parameter
    values, the metrics (NaN if it failed), max_froude and quasi_static, status ("ok", "failed"
    or "retry"), error (one line), warnings (those the run raised, one line; they are not
    shown), wall_s [s], seed, versions. With ``study.timeseries`` its time series goes to
    ``out/runs/<run_id>.csv``. With `report`, ``report(t, metrics)`` is called every
    `report_every` simulated seconds with the built-in metrics so far (an exception it raises
    ends the run and is raised, as Tune's and Optuna's early stopping need)."""
    t0 = time.perf_counter()
    # For controllers and metrics of the user's that draw from the legacy global generators.
    np.random.seed(run.seed)  # noqa: NPY002
    random.seed(run.seed)
    status, error, froude = STATUS_OK, "", {}
    caught = _Warnings()
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = caught.add
        try:
            metrics, froude = _simulate(study, run, _path(out), report, report_every)
        except _Stopped as stop:
            raise stop.reason from None
        except Exception as exc:  # every failure is recorded in the row, none stops the sweep
            status, error = STATUS_FAILED, one_line(f"{type(exc).__name__}: {exc}")
            if isinstance(exc, OSError) and exc.errno in STORAGE_ERRNOS:
                status = STATUS_RETRY
                if f"[Errno {exc.errno}]" not in error:  # what stops_the_sweep reads
                    error = f"{error} [Errno {exc.errno}]"
            metrics = {m.name: math.nan for m in study.metrics}
    largest = max(froude.values(), default=math.nan)
    return {
        "run_id": run.run_id,
        **run.values,
        **metrics,
        "max_froude": largest,
        "quasi_static": None if math.isnan(largest) else largest <= FROUDE_QUASI_STATIC,
        "status": status,
        "error": error,
        "warnings": caught.text(),
        "wall_s": time.perf_counter() - t0,
        "seed": run.seed,
        "versions": versions(),
    }


def stops_the_sweep(row: dict[str, Any]) -> bool:
    """Whether `row` failed for a reason every later run would share (``STORAGE_ERRNOS``)."""
    return row["status"] == STATUS_RETRY and any(
        f"[Errno {n}]" in row["error"] for n in STORAGE_ERRNOS
    )


def _path(out: str | Path | None) -> Path | None:
    return None if out is None else Path(out)


class _Warnings:
    """The distinct warnings a run raises ("Category: message"), kept instead of shown: at most
    ``MAX`` of them, then a count of the others (a warning raised every step stays one entry)."""

    MAX = 10

    def __init__(self) -> None:
        self.seen: dict[str, None] = {}
        self.more = 0

    def add(self, message: Warning | str, category: type[Warning], *args: Any, **kw: Any) -> None:
        text = f"{category.__name__}: {message}"
        if text in self.seen:
            return
        if len(self.seen) < self.MAX:
            self.seen[text] = None
        else:
            self.more += 1

    def text(self) -> str:
        """The warnings on one line, `` | ``-separated."""
        more = [f"and {self.more} more"] if self.more else []
        return one_line(" | ".join([*self.seen, *more]))


class _Stopped(Exception):
    """Carries the exception a report callback raised out of the run, past the row's capture."""

    def __init__(self, reason: BaseException) -> None:
        super().__init__(str(reason))
        self.reason = reason


def build(study: Study, run: RunSpec) -> tuple[mujoco.MjModel, Any, Any]:
    """(compiled model with the engine plugin, GranularField, controller or None) of one run,
    from the MJCF file with the run's values and scene options."""
    from mjrft.field.granular_field import GranularField
    from mjrft.field.plugin import load_model
    from mjrft.sweep.paths import control_schedule

    spec = mujoco.MjSpec.from_file(str(study.model))
    config = study.configure(spec, run)
    # A ValueError with MuJoCo's message names the element at fault, a SceneError the geom or
    # mjrft: value.
    model = load_model(spec, config.options)
    fld = GranularField(model)
    ctrl = control_schedule(model, config.schedules)
    if study.controller:
        factory = callables.load(study.controller, "controller")
        ctrl = factory(model, **config.controller_kwargs)
    return model, fld, ctrl


def load(study: Study, run: RunSpec) -> tuple[mujoco.MjModel, Any, Any, Probe]:
    """Everything `run` builds before its first step: ``build``'s model, field and controller,
    and the probe of its metrics. Raises what the run would fail with before simulating."""
    model, fld, ctrl = build(study, run)
    return model, fld, ctrl, Probe(list(study.metrics), model, fld)


def _keyframe(study: Study, model: mujoco.MjModel) -> int | None:
    if isinstance(study.keyframe, str):
        return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, study.keyframe)
    return study.keyframe


def _simulate(
    study: Study, run: RunSpec, out: Path | None, report: Report | None, report_every: float | None
) -> tuple[dict[str, float], dict[str, float]]:
    """The run's metrics (name -> value) and each probed body's largest Froude number."""
    from mjrft.app import simulate

    model, fld, ctrl, probe = load(study, run)
    custom = [m for m in study.metrics if m.kind == "custom"]
    rec, tmp, final = None, None, None
    if study.timeseries and out is not None:
        final = out / RUNS_DIR / f"{run.run_id}.csv"
        tmp = final.with_name(f".{final.name}.{os.getpid()}.tmp")  # complete files only
        columns = simulate.new_recording(model, fld).columns
        sink = simulate.CsvSink(tmp, columns)
        rec = simulate.Recording(columns, [be.name for be in fld.bodies], sink=sink)
    elif custom:
        rec = simulate.new_recording(model, fld)
    # Without a time series the run records only its first and last rows.
    every = study.record_every if rec is not None else 1 << 62
    every_s = report_every if report_every is not None else study.duration / 10
    observer = probe
    if report is not None:
        last = simulate.step_count(study.duration, model.opt.timestep)
        observer = _reporting(probe, model, report, every_s, last)
    try:
        data, rec = simulate.run(
            model, study.duration, fld=fld, observer=observer, recording=rec,
            record_every=every, keyframe=_keyframe(study, model), ctrl=ctrl,
        )  # fmt: skip
    finally:
        if tmp is not None:
            _finish_file(rec.sink, tmp, final)
    values = probe.values(data)
    if custom:
        series = simulate.Recording.from_csv(final, rec.body_names) if final else rec
        outcome = Outcome(model, data, fld, dict(run.values), run.seed, dict(values), series)
        for m in custom:
            values[m.name] = _custom_value(m.options["function"], outcome)
    return {m.name: values[m.name] for m in study.metrics}, dict(rec.max_froude)


def _finish_file(sink: Any, tmp: Path, final: Path) -> None:
    """Close a run's time series and move it to its name (the rows up to a divergence are
    kept); a file that cannot be finished (the disk full) is removed, not left half-written."""
    try:
        sink.close()
        os.replace(tmp, final)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise


def _reporting(
    probe: Probe, model: mujoco.MjModel, report: Report, every_s: float, last: int
) -> Callable[[int, float, mujoco.MjData], None]:
    """The probe as the run's observer, calling ``report(t, probe.partial(data))`` every
    `every_s` simulated seconds before the final state (step `last`: the run's own result)."""
    if not every_s > 0:
        raise StudyError(f"report_every = {every_s}: need a time > 0 [s]")
    k = max(1, round(every_s / float(model.opt.timestep)))

    def observe(step: int, t: float, data: mujoco.MjData) -> None:
        probe(step, t, data)
        if 0 < step < last and step % k == 0:
            try:
                report(t, probe.partial(data))
            except BaseException as exc:
                raise _Stopped(exc) from exc

    return observe


def _custom_value(spec: str, outcome: Outcome) -> float:
    value = callables.load(spec, "custom metric")(outcome)
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise StudyError(f"custom metric {spec} returned {type(value).__name__}, not a number")
    return float(value)
