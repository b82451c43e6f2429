"""One parameter set through the public API (``run_one``, ``evaluate``), and a study under
Optuna (its default sampler, a pruner) and Ray Tune (a search algorithm, an early-stopping
scheduler, a restored experiment) on a local Ray instance."""

from __future__ import annotations

import math
import os
import shutil
import signal
import tempfile
from pathlib import Path

import pytest

from mjrft.sweep import RunFailed, Study, StudyError, evaluate, load_results, run_one, run_study


@pytest.fixture(autouse=True)
def _signal_handlers():
    """Ray Tune installs SIGINT/SIGTERM handlers of its own in this process (its first Ctrl-C
    stops an experiment gracefully, without KeyboardInterrupt) and leaves them: put back what
    the process had, so later tests in this worker see Python's own handlers."""
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    for s, handler in saved.items():
        signal.signal(s, handler)


# A steel sphere 1 cm across dropped onto glass beads from a release height drawn in
# [1.1, 3] cm: 60 ms of simulated time, 60 steps.
DROP = """
[study]
model = "sphere_drop"
duration = 0.06
sampling = "random"
samples = 3
seed = 5

[parameters.z]
path = "key.start.qpos[2]"
low = 0.011
high = 0.03

[set]
triangles = 200

[metrics]
depth_m = { kind = "final_depth", body = "sphere" }
fz_peak_N = { kind = "peak_force", body = "sphere", component = "z" }
fz_mean_N = { kind = "mean_force", body = "sphere", component = "z" }
"""
METRICS = ("depth_m", "fz_peak_N", "fz_mean_N")


@pytest.fixture(scope="module")
def drop(tmp_path_factory) -> Study:
    path = tmp_path_factory.mktemp("drop") / "drop.toml"
    path.write_text(DROP)
    return Study.load(path)


def test_run_one_gives_the_row_a_sweep_writes_and_evaluate_its_metrics(drop, tmp_path):
    run_study(drop, tmp_path / "out", backend="serial", plots=False)
    for row in load_results(tmp_path / "out"):
        again = run_one(drop, {"z": row["z"]})
        assert again["run_id"] == row["run_id"] and again["seed"] == row["seed"]
        assert [again[m] for m in METRICS] == [row[m] for m in METRICS]  # bit for bit
        metrics = evaluate(drop, {"z": row["z"]})
        assert [metrics[m] for m in METRICS] == [row[m] for m in METRICS]
        assert metrics["max_froude"] == row["max_froude"]
    off_grid = evaluate(drop, {"z": 0.0123})  # any value, not only the study's draws
    assert off_grid["depth_m"] > 0


def test_reports_come_while_the_run_goes_and_leave_its_metrics_unchanged(drop):
    reports = []
    row = run_one(drop, {"z": 0.02}, report=lambda t, m: reports.append((t, m)))
    assert row == {**run_one(drop, {"z": 0.02}), "wall_s": row["wall_s"]}
    times = [t for t, _ in reports]
    assert len(times) == 9 and times == sorted(times) and times[-1] < drop.duration
    assert all(set(m) == set(METRICS) for _, m in reports)
    peaks = [m["fz_peak_N"] for _, m in reports]
    assert peaks == sorted(peaks) and peaks[-1] <= row["fz_peak_N"]  # a peak only grows


def test_a_missing_or_unknown_parameter_is_refused_and_a_failed_run_raises(drop):
    with pytest.raises(StudyError, match=r"missing 'z'; unknown 'height' \(parameters: z\)"):
        evaluate(drop, {"height": 0.02})
    bad = Study.from_toml(
        DROP.replace('path = "key.start.qpos[2]"', 'path = "geom.sphere.size[0]"')
    )
    with pytest.raises(RunFailed, match="size 0 must be positive") as failed:
        evaluate(bad, {"z": -0.01})
    assert failed.value.row["status"] == "failed" and math.isnan(failed.value.row["depth_m"])


def test_optuna_with_its_default_sampler_finds_and_records_its_trials(drop):
    optuna = pytest.importorskip("optuna")
    from mjrft.sweep.optuna import objective

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    search = optuna.create_study(direction="maximize", sampler=optuna.samplers.TPESampler(seed=3))
    search.optimize(objective(drop, "fz_peak_N", prune=False), n_trials=6)
    assert isinstance(search.sampler, optuna.samplers.TPESampler)  # Optuna's default
    trials = search.get_trials(states=[optuna.trial.TrialState.COMPLETE])
    assert len(trials) == 6 and all(0.011 <= t.params["z"] <= 0.03 for t in trials)
    best = search.best_trial
    again = evaluate(drop, best.params)
    assert best.value == again["fz_peak_N"] and best.user_attrs["depth_m"] == again["depth_m"]
    # A pruner that stops a trial whose peak force so far is under 0.05 N: each one at its first
    # report (t = 6 ms), before the sphere, released at least 1 mm above the sand, reaches it.
    threshold = optuna.pruners.ThresholdPruner(lower=0.05)
    pruned = optuna.create_study(direction="maximize", pruner=threshold)
    pruned.optimize(objective(drop, "fz_peak_N"), n_trials=2)
    for t in pruned.trials:
        assert t.state == optuna.trial.TrialState.PRUNED and len(t.intermediate_values) == 1


def test_a_failed_run_is_a_failed_optuna_trial_and_the_search_goes_on(tmp_path):
    optuna = pytest.importorskip("optuna")
    from mjrft.sweep.optuna import objective

    path = tmp_path / "bad.toml"  # every draw is a negative sphere radius
    path.write_text(DROP.replace("low = 0.011", "low = -0.02").replace("high = 0.03", "high = "
        "-0.01").replace('path = "key.start.qpos[2]"', 'path = "geom.sphere.size[0]"'))  # fmt: skip
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    search = optuna.create_study(sampler=optuna.samplers.TPESampler(seed=0))
    search.optimize(objective(Study.load(path), "depth_m"), n_trials=3)
    assert [t.state for t in search.trials] == [optuna.trial.TrialState.FAIL] * 3
    assert all("size 0 must be positive" in t.user_attrs["error"] for t in search.trials)


def _interrupt_after(tune, n: int):
    """A Tune callback that sends this process SIGINT (Ctrl-C) once `n` trials have finished."""

    class Interrupt(tune.Callback):
        done = 0

        def on_trial_complete(self, iteration, trials, trial, **info) -> None:
            self.done += 1
            if self.done == n:
                os.kill(os.getpid(), signal.SIGINT)

    return Interrupt()


def test_ray_tune_with_a_search_algorithm_and_asha_and_a_restored_experiment(drop, tmp_path):
    ray = pytest.importorskip("ray")
    pytest.importorskip("optuna")
    from ray import tune
    from ray.tune.schedulers import ASHAScheduler
    from ray.tune.search.optuna import OptunaSearch

    from mjrft.sweep.tune import SIM_TIME, search_space, trainable

    short = Path(tempfile.mkdtemp(prefix="mjrft-ray-", dir="/tmp"))  # Ray's sockets: 108 B max
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False,
             _temp_dir=str(short))  # fmt: skip
    try:
        asha = ASHAScheduler(time_attr=SIM_TIME, max_t=drop.duration, grace_period=0.012,
                             reduction_factor=2)  # fmt: skip
        tuner = tune.Tuner(
            trainable(drop),
            param_space=search_space(drop),
            tune_config=tune.TuneConfig(
                metric="fz_peak_N", mode="max", num_samples=4, max_concurrent_trials=1,
                search_alg=OptunaSearch(seed=7), scheduler=asha,
            ),
            run_config=tune.RunConfig(storage_path=str(tmp_path), name="drop", verbose=0),
        )  # fmt: skip
        results = tuner.fit()
        assert results.num_errors == 0 and len(results) == 4
        finished = [r for r in results if r.metrics[SIM_TIME] == drop.duration]
        stopped = [r for r in results if r.metrics[SIM_TIME] < drop.duration]
        assert finished and stopped, [r.metrics[SIM_TIME] for r in results]  # ASHA stopped some
        best = results.get_best_result()
        assert best.metrics[SIM_TIME] == drop.duration
        assert best.metrics["fz_peak_N"] == evaluate(drop, best.config)["fz_peak_N"]
        # An experiment interrupted (SIGINT after two trials, as Ctrl-C) resumes from Tune's
        # checkpoint of it: the finished trials are kept, the rest run.
        interrupted = tune.Tuner(
            trainable(drop),
            param_space=search_space(drop),
            tune_config=tune.TuneConfig(metric="fz_peak_N", mode="max", num_samples=4,
                                        max_concurrent_trials=1),
            run_config=tune.RunConfig(storage_path=str(tmp_path), name="cut", verbose=0,
                                      callbacks=[_interrupt_after(tune, 2)]),
        ).fit()  # fmt: skip
        first = sorted(r.metrics["run_id"] for r in interrupted)
        assert len(first) == 2 and tune.Tuner.can_restore(str(tmp_path / "cut"))
        resumed = tune.Tuner.restore(str(tmp_path / "cut"), trainable(drop),
                                     resume_unfinished=True).fit()  # fmt: skip
        assert resumed.num_errors == 0 and len(resumed) > 2
        done = {r.metrics["run_id"]: r.metrics["fz_peak_N"] for r in resumed}
        assert set(first) <= set(done)
        assert all(r.metrics[SIM_TIME] == drop.duration for r in resumed)
    finally:
        ray.shutdown()
        shutil.rmtree(short, ignore_errors=True)
