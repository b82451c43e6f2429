"""One run of a study, from scratch: its model built and compiled with the engine plugin, the
simulation, its metrics; any failure (a value that does not compile, a diverging simulation, an
exception in user code) is the run's outcome, not the sweep's end."""

from __future__ import annotations

import functools
import os
import random
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from mjrft.sweep import callables
from mjrft.sweep.errors import StudyError, one_line
from mjrft.sweep.metrics import Outcome, Probe
from mjrft.sweep.study import RunSpec, Study

STATUS_OK, STATUS_FAILED = "ok", "failed"
#: Folder of per-run time series in a results folder (``timeseries = true``).
RUNS_DIR = "runs"


@functools.cache
def versions() -> str:
    """The software versions a row records: ``name=version`` pairs, ``;``-separated."""
    from mjrft.app.metadata import versions as installed

    return ";".join(f"{k}={v}" for k, v in installed().items())


def execute(study: Study, run: RunSpec, out: str | Path | None = None) -> dict[str, Any]:
    """Run `run` of `study` in this process and return its results row: run_id, the parameter
    values, the metrics (NaN if it failed), status ("ok" or "failed"), error (one line), wall_s
    [s], seed, versions. With ``study.timeseries`` its time series goes to
    ``out/runs/<run_id>.csv``."""
    t0 = time.perf_counter()
    # For controllers and metrics of the user's that draw from the legacy global generators.
    np.random.seed(run.seed)  # noqa: NPY002
    random.seed(run.seed)
    status, error = STATUS_OK, ""
    try:
        metrics = _simulate(study, run, None if out is None else Path(out))
    except Exception as exc:  # every failure is recorded in the row, none stops the sweep
        status, error = STATUS_FAILED, one_line(f"{type(exc).__name__}: {exc}")
        metrics = {m.name: float("nan") for m in study.metrics}
    return {
        "run_id": run.run_id,
        **run.values,
        **metrics,
        "status": status,
        "error": error,
        "wall_s": time.perf_counter() - t0,
        "seed": run.seed,
        "versions": versions(),
    }


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


def _simulate(study: Study, run: RunSpec, out: Path | None) -> dict[str, float]:
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
    try:
        data, rec = simulate.run(
            model, study.duration, fld=fld, observer=probe, recording=rec,
            record_every=every, keyframe=_keyframe(study, model), ctrl=ctrl,
        )  # fmt: skip
    finally:
        if tmp is not None:
            rec.sink.close()
            os.replace(tmp, final)  # rows up to a divergence are kept
    values = probe.values(data)
    if custom:
        series = simulate.Recording.from_csv(final, rec.body_names) if final else rec
        outcome = Outcome(model, data, fld, dict(run.values), run.seed, dict(values), series)
        for m in custom:
            values[m.name] = _custom_value(m.options["function"], outcome)
    return {m.name: values[m.name] for m in study.metrics}


def _custom_value(spec: str, outcome: Outcome) -> float:
    value = callables.load(spec, "custom metric")(outcome)
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise StudyError(f"custom metric {spec} returned {type(value).__name__}, not a number")
    return float(value)
