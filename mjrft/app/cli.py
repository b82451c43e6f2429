"""Command-line interface: ``mjrft demo``, ``mjrft run``, ``mjrft sweep``, ``mjrft view``,
``mjrft view-recording``. Nothing below the app layer imports it.

Building the parser imports no mujoco, matplotlib, rerun, dm_control or ``mjrft.sweep``: each
subcommand imports what it needs when it runs, so ``mjrft --help`` answers at once."""

from __future__ import annotations

import argparse
import difflib
import os
import signal
import sys
import threading
import time
from pathlib import Path

from mjrft.app.recording_defaults import (
    DEFAULT_CONNECT_URL,
    DEFAULT_MAX_ARROWS,
    DEFAULT_STRESS_MAX_PA,
)

DEFAULT_DEMO_DIR = "mjrft-demo"

# Simulated durations of the dynamic rigs in `mjrft demo` [s]: the ellipsoid's whole descent and
# one full circumnutation turn of the root.
DEMO_RIGS = (("ellipsoid_pitch", 12.0), ("root_circumnutation", 24.0))
# The rig whose run `mjrft demo` records to demo.rrd (one recording per file).
DEMO_RRD_RIG = "ellipsoid_pitch"
DEMO_RRD = "demo.rrd"


def _demo(args: argparse.Namespace) -> int:
    import numpy as np

    from mjrft.app import demos, report
    from mjrft.core.material import Material

    out = Path(args.out)
    material = Material.preset(args.material)
    t0 = time.perf_counter()
    results = [
        demos.ellipsoid_pitch(n_triangles=args.triangles, material=material),
        demos.ellipsoid_pitch(n_triangles=args.triangles, material=material, amplitude=0.0),
        demos.root_circumnutation(n_triangles=args.triangles, material=material),
    ]
    written = []
    for r in results:
        written.append(report.write_csv(out / f"{r.name}.csv", report.demo_columns(r)))
        written.append(report.plot_demo(r, out / f"{r.name}.png"))
    written.append(report.plot_time_series(results[0], out / "ellipsoid_pitch_time.png"))
    osc = demos.oscillation_summary(results[0])
    print(f"mjrft demo: material {material.name}, {args.triangles} triangles per primitive")
    print(
        "  prescribed ellipsoid: lateral force oscillates at "
        f"{osc['lateral_frequency_hz']:.3f} Hz about a mean of {osc['lateral_mean_n']:+.2e} N "
        f"(RMS {osc['lateral_rms_n']:.3f} N); vertical force at "
        f"{osc['vertical_frequency_hz']:.3f} Hz (pitch at {demos.ELLIPSOID_PITCH_FREQUENCY} Hz)"
    )
    peak = [float(r.force[:, 2].max()) for r in results[:2]]
    print(
        f"  prescribed ellipsoid peak vertical force: {peak[0]:.3f} N pitching, {peak[1]:.3f} N not"
    )
    prescribed = {"ellipsoid_pitch": results[0], "root_circumnutation": results[2]}
    for name, duration in DEMO_RIGS:
        rrd = out / DEMO_RRD if name == DEMO_RRD_RIG else None
        fld, rec = _demo_rig(name, duration, scene_options(args), rrd)
        if rrd is not None:
            written.append(rrd)
        cols = dict(zip(rec.columns, rec.array().T, strict=True))
        written.append(report.write_csv(out / f"rig_{name}.csv", cols))
        written += report.plot_run(rec, fld.surface_z, out, stem=f"rig_{name}_")
        body = rec.body_names[0]
        written.append(
            report.plot_rig_vs_prescribed(
                rec,
                body,
                prescribed[name],
                out / f"rig_{name}_vs_prescribed.png",
                f"{name}.xml simulated in MuJoCo vs the prescribed trajectory",
            )
        )
        print(
            f"  rig {name}.xml: {duration:g} s simulated, peak vertical RFT force "
            f"{np.max(cols[f'{body}_rft_force_z_N']):.3f} N"
        )
    elapsed = time.perf_counter() - t0
    print(f"wrote {len(written)} files to {out.resolve()} in {elapsed:.1f} s:")
    for p in written:
        print(f"  {p}")
    return 0


def _demo_rig(name: str, duration: float, options, rrd: Path | None):
    """Simulate models/<name>.xml for `duration` s for `mjrft demo` under the scene options
    (``mjrft.SceneOptions``); record it to `rrd` if given.

    Returns (field, simulate.Recording with a row every 10 steps).
    """
    from mjrft.app import simulate
    from mjrft.field.granular_field import GranularField

    model = simulate.load_model(simulate.models_dir() / f"{name}.xml", options)
    fld = GranularField(model)
    recorder = None
    if rrd is not None:
        from mjrft.app import viz

        recorder = viz.Recorder(model, fld, rrd, recording_id=f"mjrft-demo-{name}")
    try:
        _, rec = simulate.run(
            model,
            duration,
            fld=fld,
            record_every=10,
            progress=_Progress(f"  rig {name}", 0.0),
            observer=recorder,
            observe_every=recorder.every if recorder is not None else 1,
        )
    finally:
        if recorder is not None:
            recorder.close()
    return fld, rec


class _Progress:
    """Progress on stderr once a run has taken more than `after` seconds: one line redrawn in
    place on a terminal, otherwise a line per 10% (so logs stay short)."""

    def __init__(self, label: str, after: float = 2.0) -> None:
        self.label, self.after, self.t0 = label, after, time.perf_counter()
        self.shown, self.next_decile = False, 0.1
        self.tty = sys.stderr.isatty()

    def __call__(self, fraction: float) -> None:
        elapsed = time.perf_counter() - self.t0
        if (elapsed < self.after and fraction < 1.0) or (not self.shown and fraction >= 1.0):
            return
        if not self.tty and fraction + 1e-12 < self.next_decile:
            return
        self.next_decile = (int(fraction * 10 + 1e-9) + 1) / 10
        eta = elapsed * (1.0 - fraction) / max(fraction, 1e-9)
        text = f"{self.label}: {100 * fraction:5.1f}%  {elapsed:6.1f} s elapsed, ~{eta:5.1f} s left"
        if self.tty:
            print("\r" + text, end="\n" if fraction >= 1.0 else "", file=sys.stderr, flush=True)
        else:
            print(text, file=sys.stderr, flush=True)
        self.shown = True


def _recorder(args: argparse.Namespace, model, fld):
    """The rerun Recorder the options ask for, or None (rerun is imported only then)."""
    if not (args.rrd or args.spawn or args.connect):
        return None
    from mjrft.app import viz

    return viz.Recorder(
        model,
        fld,
        args.rrd,
        every=args.rrd_every,
        max_arrows=args.max_arrows,
        arrow_scale=args.arrow_scale,
        stress_max=args.stress_max,
        spawn=args.spawn,
        connect=args.connect,
        recording_id=f"{Path(args.model).stem}-{time.strftime('%Y%m%d-%H%M%S')}",
    )


#: Files `mjrft run` writes into --out (besides the optional --rrd): the table (CSV, or
#: Parquet with --table-format parquet), run.json and the figures (report.RUN_FIGURES) in the
#: --figure-format (report.FIGURE_FORMATS; here so that building the parser imports no numpy).
RUN_CSV, RUN_PARQUET, RUN_JSON = "timeseries.csv", "timeseries.parquet", "run.json"
TABLE_FORMATS = ("csv", "parquet")
RUN_FIGURES = ("forces_vs_time", "forces_vs_depth", "rft_summary")
FIGURE_FORMATS = ("png", "svg", "pdf")
RUN_PLOTS = tuple(f"{name}.png" for name in RUN_FIGURES)
RUN_FILES = (RUN_CSV, RUN_PARQUET, RUN_JSON,
             *(f"{name}.{fmt}" for fmt in FIGURE_FORMATS for name in RUN_FIGURES))  # fmt: skip
#: Exit codes of `mjrft run` besides 0 (completed) and 2 (bad input).
EXIT_FAILED, EXIT_DIVERGED, EXIT_INTERRUPTED, EXIT_TERMINATED = 1, 3, 130, 143
#: Exit codes of `mjrft sweep`: runs failed (their rows say why); the sweep stopped for a failure
#: outside its runs (a full disk; sysexits.h's EX_IOERR).
EXIT_RUNS_FAILED, EXIT_SWEEP_STOPPED = 3, 74
#: The signals that stop `mjrft run`: name -> (run.json status, exit code 128 + signal number).
STOP_SIGNALS = {
    "SIGINT": ("interrupted", EXIT_INTERRUPTED),
    "SIGTERM": ("terminated", EXIT_TERMINATED),
    "SIGHUP": ("terminated", 129),
}


class Terminated(KeyboardInterrupt):
    """A signal that stops `mjrft run` (``STOP_SIGNALS``), raised where the run is so that it
    finishes its files as on Ctrl-C. Attributes: name ('SIGTERM'), status, code (exit code)."""

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        self.name = signal.Signals(signum).name
        self.status, self.code = STOP_SIGNALS[self.name]
        super().__init__(f"{self.status} by {self.name}")


class _StopSignals:
    """``STOP_SIGNALS``' handlers over `mjrft run`: the first signal raises ``Terminated`` where
    the run is (start-up or the loop); after it, and once ``disarm`` is called (the results are
    being written), a signal is only recorded in ``received``, so that whatever arrives the run
    ends with its files complete. A signal ignored when the run starts (``nohup``) stays
    ignored."""

    def __init__(self) -> None:
        self.received: list[str] = []
        self.armed = True
        self._previous: dict[int, object] = {}

    def __enter__(self) -> _StopSignals:
        if threading.current_thread() is not threading.main_thread():
            return self  # Python delivers signals to the main thread only
        for name in STOP_SIGNALS:
            sig = getattr(signal, name, None)
            if sig is not None and signal.getsignal(sig) is not signal.SIG_IGN:
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    def _handle(self, signum: int, frame) -> None:
        self.received.append(signal.Signals(signum).name)
        if self.armed:
            self.armed = False
            raise Terminated(signum)

    def disarm(self) -> None:
        """From now on signals are only recorded."""
        self.armed = False


def _check_outputs(args: argparse.Namespace) -> Path:
    """Refuse, before the first step, outputs that could not be written or would clobber each
    other or an existing recording; returns the output folder (created)."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} is a file, not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create --out folder {str(out)!r}: {exc.strerror}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise ValueError(f"--out folder {str(out)!r} is not writable")
    previous = [name for name in RUN_FILES if (out / name).exists()]
    if previous and not args.overwrite:
        raise ValueError(
            f"--out folder {str(out)!r} already holds a run ({', '.join(previous)}); pass "
            "--overwrite to replace it, or choose another folder"
        )
    if args.rrd:
        rrd = Path(args.rrd)
        ours = {(out / name).resolve() for name in RUN_FILES}
        if rrd.resolve() in ours:
            raise ValueError(f"--rrd {str(rrd)!r} would overwrite the run's own {rrd.name}")
        if rrd.exists() and not args.overwrite:
            raise ValueError(
                f"--rrd {str(rrd)!r} exists; pass --overwrite to replace it, or choose another file"
            )
        parent = rrd.resolve().parent
        if parent.exists() and not os.access(parent, os.W_OK | os.X_OK):
            raise ValueError(f"--rrd folder {str(parent)!r} is not writable")
    return out


def _on_sigterm(signum, frame) -> None:
    raise Terminated


def _run(args: argparse.Namespace) -> int:
    if args.plots_only:
        return _plots_only(args)
    if args.duration is None:
        raise ValueError("--duration SECONDS is required (except with --plots-only)")
    with _StopSignals() as stop:
        try:
            # A signal that escapes _run_prepared came before its first file was written.
            return _run_prepared(args, _prepare_run(args), stop)
        except Terminated as exc:
            print(
                f"mjrft run: {exc} during start-up, before the first step: nothing was written",
                file=sys.stderr,
            )
            return exc.code


def _plots_only(args: argparse.Namespace) -> int:
    """`mjrft run MODEL --out DIR --plots-only`: every figure of the run in DIR, drawn from its
    table (nothing is simulated; MODEL and the scene options give the bodies and the surface)."""
    from mjrft.app import report, simulate

    out = Path(args.out)
    table = next((out / n for n in (RUN_CSV, RUN_PARQUET) if (out / n).is_file()), None)
    if table is None:
        raise ValueError(
            f"--out {str(out)!r} holds no run table ({RUN_CSV} or {RUN_PARQUET}): run "
            "`mjrft run MODEL --out DIR` first"
        )
    xml = simulate.resolve_model(args.model)
    _, _, fld = _scene(args, xml)
    names = [be.name for be in fld.bodies]
    columns = simulate.read_table(table)[0]
    missing = [b for b in names if f"{b}_rft_force_x_N" not in columns]
    if missing:
        raise ValueError(
            f"{table} has no columns of bodies {missing} of {xml.name}: it was written by another "
            "model or other scene options (give the run's own MODEL and options)"
        )
    rec = simulate.Recording.from_file(table, names)
    title = f"{xml.name}: {fld.scene.material.name}, {fld.n_elements} triangles"
    paths = report.plot_run(rec, fld.surface, out, title=title, fmt=args.figure_format)
    print(f"mjrft run {xml.name}: drew {len(paths)} figures from {table}")
    return 0


def _prepare_run(args: argparse.Namespace) -> _RunInfo:
    """Everything `mjrft run` checks and builds before it writes a file."""
    from mjrft.app import simulate

    xml = simulate.resolve_model(args.model)
    out = _check_outputs(args)
    ctrl = _load_controller(args.ctrl) if args.ctrl else None
    model, keyframe, fld = _scene(args, xml)
    n_steps = simulate.step_count(args.duration, model.opt.timestep)  # refused before any file
    run = _RunInfo(xml, out, model, fld, keyframe, ctrl)
    run.record_every = args.record_every or simulate.figure_record_every(n_steps)
    return run


def _run_prepared(args: argparse.Namespace, run: _RunInfo, stop: _StopSignals) -> int:
    """Simulate and write the results; whatever ends the run (a signal, a full disk, an error),
    its files end complete: the CSV's whole rows, the plots of them, run.json's final status."""
    import mujoco

    from mjrft.app import metadata, simulate

    out, model, fld = run.out, run.model, run.fld
    columns = simulate.new_recording(model, fld).columns
    rec = simulate.Recording(columns, [be.name for be in fld.bodies])
    data = mujoco.MjData(model)
    recorder = None
    status, code = "completed", 0
    try:
        # A replaced run leaves nothing behind (no plots of it beside a --no-plots run's CSV).
        for name in RUN_FILES:
            (out / name).unlink(missing_ok=True)
        metadata.write(out / RUN_JSON, run.record(args, "running"))
        # Rows go to the CSV as the run goes (flushed every second): memory stays bounded and a
        # crash or SIGKILL loses at most the last second.
        rec.sink = simulate.CsvSink(out / RUN_CSV, columns)
        recorder = _recorder(args, model, fld)
        t_sim = time.perf_counter()
        try:
            simulate.run(
                model,
                args.duration,
                fld=fld,
                record_every=run.record_every,
                progress=_Progress(f"mjrft run {run.xml.name}"),
                recording=rec,
                observer=recorder,
                observe_every=recorder.every if recorder is not None else 1,
                keyframe=run.keyframe,
                ctrl=run.ctrl,
                data=data,
            )
        finally:
            run.simulation = time.perf_counter() - t_sim
        stop.disarm()
    except simulate.RunDiverged as exc:
        status, code = "diverged", EXIT_DIVERGED
        print(f"mjrft run: {exc}", file=sys.stderr)
    except Terminated as exc:
        status, code = exc.status, exc.code
    except KeyboardInterrupt:  # raised by other code than our handler (a controller, a test)
        status, code = "interrupted", EXIT_INTERRUPTED
    except OSError as exc:  # the outputs cannot be written (a full disk, a size limit)
        status, code, run.error = "failed", EXIT_FAILED, f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # a bug or the user's controller: the traceback follows
        status, code, run.error = "failed", EXIT_FAILED, f"{type(exc).__name__}: {exc}"
        raise
    finally:
        # Whatever was computed is written, even when the run fails or is interrupted; any
        # signal from here on waits until the files are complete.
        stop.disarm()
        code = _finish_run(args, run, rec, recorder, data, status, code, stop.received)
    return code


class _RunInfo:
    """What `mjrft run` ran and how long its parts took [s], for its summary and run.json."""

    def __init__(self, xml: Path, out: Path, model, fld, keyframe: int | None, ctrl) -> None:
        self.xml, self.out, self.model, self.fld = xml, out, model, fld
        self.keyframe, self.ctrl = keyframe, ctrl
        self.simulation = self.plots = float("nan")
        self.error: str | None = None
        self.notes: list[str] = []  # what could not be written besides the run's own error
        self.ground: dict | None = None  # simulate.ground_balance at the end
        self.record_every = 1  # steps per row of the table
        self.figures_skipped: list[str] = []  # left out to stay within the simulation's time

    def record(self, args: argparse.Namespace, status: str, **extra) -> dict:
        """The run.json record (``mjrft.app.metadata``)."""
        from mjrft.app import metadata

        m, f = self.model, self.fld
        material = f.scene.material
        return {
            "status": status,
            "error": self.error,
            "command": metadata.command_line(),
            "options": {k: v for k, v in vars(args).items() if k not in ("func", "started")},
            "model": {
                "file": str(self.xml.resolve()),
                "sha256": metadata.model_files(self.xml),
                "timestep_s": m.opt.timestep,
                "integrator": _integrator_name(m),
                "keyframe": self.keyframe if m.nkey else None,
                "nbody": m.nbody, "nq": m.nq, "nv": m.nv, "nu": m.nu,
            },
            "field": {
                "material": material.name,
                "zeta_N_per_m3": material.zeta,
                "triangles": f.n_elements,
                "bodies": [be.name for be in f.bodies],
                "surface_z_m": f.surface_z,
                "deforms": f.deforms,
            },
            "versions": metadata.versions(),
            "machine": metadata.machine(),
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(args.started[1])),
            "record_every_steps": self.record_every,
            **extra,
        }  # fmt: skip


def _keyframe(model, text: str | None) -> int | None:
    """--keyframe as a keyframe index: an index, a keyframe name, or "none" (qpos0)."""
    if text is None:
        return 0
    if text.lower() == "none":
        return None
    if text.lstrip("-").isdigit():
        k = int(text)
    else:
        import mujoco

        k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, text)
        if k < 0:
            names = [
                mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, i) for i in range(model.nkey)
            ]
            raise ValueError(
                f"--keyframe {text!r}: no keyframe of that name (the model has {names})"
            )
    if not 0 <= k < model.nkey:
        raise ValueError(f"--keyframe {k}: the model has {model.nkey} keyframe(s)")
    return k


def _load_controller(spec: str):
    """The controller ``ctrl(t, data)`` named by MODULE:NAME or path/to/file.py:NAME."""
    import importlib
    import importlib.util

    module_name, sep, attr = spec.rpartition(":")
    if not sep or not module_name or not attr:
        raise ValueError(f"--ctrl {spec!r}: expected MODULE:FUNCTION or path/to/file.py:FUNCTION")
    try:
        if module_name.endswith(".py"):
            path = Path(module_name)
            if not path.is_file():
                raise ValueError(f"--ctrl {spec!r}: no file {module_name!r}")
            loader = importlib.util.spec_from_file_location(path.stem, path)
            module = importlib.util.module_from_spec(loader)
            loader.loader.exec_module(module)
        else:
            module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ValueError(f"--ctrl {spec!r}: cannot import {module_name!r}: {exc}") from None
    fn = getattr(module, attr, None)
    if not callable(fn):
        raise ValueError(f"--ctrl {spec!r}: {module_name!r} has no callable {attr!r}")
    return fn


def _finish_run(
    args, run: _RunInfo, rec, recorder, data, status: str, code: int, signals: list[str]
) -> int:
    """Complete `mjrft run`'s files whatever ended it: close the CSV (its whole rows) and the
    recording, draw the plots from the CSV, write run.json's final status and print the summary.
    An I/O error here (a full disk) turns a completed run into a failed one, named; it never
    stops the other files. Returns the exit code."""
    from mjrft.app import metadata, simulate

    sink = rec.sink
    if sink is not None:
        try:
            sink.close()
        except OSError as exc:
            if run.error is None:
                status, code, run.error = "failed", EXIT_FAILED, f"{type(exc).__name__}: {exc}"
    if recorder is not None:
        try:
            recorder.close()  # completes the .rrd file
        except Exception as exc:  # the rest is still written
            run.notes.append(f"the recording could not be completed: {type(exc).__name__}: {exc}")
    rows = sink.rows_written if sink is not None else 0
    last = sink.last_written if sink is not None else None
    t_end = float(last[0]) if last is not None else 0.0
    table = _table(args, run, sink)
    pngs = _run_plots(args, run, rec, table, everything=status != "completed") if rows else []
    if signals and code == 0:  # completed, then asked to stop: every file is complete
        code = STOP_SIGNALS[signals[0]][1]
    total = time.perf_counter() - args.started[0]
    outputs = [str(table)] if table is not None else []
    outputs += map(str, pngs)
    if recorder is not None and recorder.path is not None:
        outputs.append(str(recorder.path))
    timing = {"simulation_s": run.simulation, "plots_s": run.plots, "total_s": total}
    run.ground = simulate.ground_balance(run.fld, data)
    record = run.record(
        args, status, simulated_s=t_end, rows=rows, outputs=outputs,
        timing={k: v for k, v in timing.items() if v == v}, max_froude=rec.max_froude,
        ground=run.ground, figures_skipped=run.figures_skipped, signals=signals, notes=run.notes,
    )  # fmt: skip
    try:
        metadata.write(run.out / RUN_JSON, record)
    except OSError as exc:
        run.notes.append(f"{run.out / RUN_JSON} could not be written: {exc}")
        code = code or EXIT_FAILED
    _print_summary(run, status, t_end, rows, len(pngs), total, signals, recorder, table)
    return code


def _table(args, run: _RunInfo, sink) -> Path | None:
    """The run's table on disk: the CSV, or with --table-format parquet the Parquet file made
    from it (the CSV, the run's journal, then goes; it stays if the Parquet file cannot be
    written, named in run.notes)."""
    from mjrft.app import simulate

    if sink is None or not sink.path.exists():
        return None
    if args.table_format != "parquet":
        return sink.path
    try:
        path = simulate.write_parquet(sink.path, run.out / RUN_PARQUET)
    except Exception as exc:  # a full disk, or the CSV cut by the error that ended the run
        run.notes.append(f"the Parquet table could not be written ({exc}); the rows are in "
                         f"{sink.path}")  # fmt: skip
        return sink.path
    sink.path.unlink()
    return path


def _run_plots(args, run: _RunInfo, rec, table: Path | None, everything: bool) -> list:
    """The figures of the rows on disk (none with --no-plots): every figure with --all-figures
    or `everything` (a run that stopped early: what it computed is shown), else those that fit
    in the simulation's wall time (``report.plot_run_within``). A figure that cannot be written
    is named in run.notes, and the run's other files are still written."""
    from mjrft.app import report, simulate

    if args.no_plots or not rec.body_names or table is None:
        return []
    fld = run.fld
    budget = run.simulation if run.simulation == run.simulation else 0.0
    if not (args.all_figures or everything) and budget < report.figure_floor_s():
        run.figures_skipped = list(report.FIGURE_PRIORITY)  # not even one would fit
        return []
    t0 = time.perf_counter()
    try:
        plots = simulate.Recording.from_file(table, rec.body_names)
        title = f"{run.xml.name}: {fld.scene.material.name}, {fld.n_elements} triangles"
        if args.all_figures or everything:
            pngs = report.plot_run(plots, fld.surface, run.out, title=title,
                                   fmt=args.figure_format)  # fmt: skip
        else:  # within the simulation's own wall time, counted from reading the table
            budget -= time.perf_counter() - t0
            pngs, run.figures_skipped = report.plot_run_within(
                plots, fld.surface, run.out, budget, title=title, fmt=args.figure_format
            )
    except OSError as exc:
        run.notes.append(f"the plots could not be written: {exc}")
        return []
    except Exception as exc:  # a plotting bug must not cost the run's record
        import traceback

        traceback.print_exc()
        run.notes.append(f"the plots failed: {type(exc).__name__}: {exc}")
        return []
    run.plots = time.perf_counter() - t0
    return pngs


def _print_summary(
    run: _RunInfo, status, t_end, rows, n_plots, total, signals, recorder, table
) -> None:
    """`mjrft run`'s summary line on stdout; errors and notes on stderr."""
    model, fld, sim = run.model, run.fld, run.simulation
    rate = f"{t_end / sim:.2f}x real time" if sim == sim and sim > 0 else "no steps"
    plots = f"plots {run.plots:.2f} s, " if run.plots == run.plots else ""
    print(
        f"mjrft run {run.xml.name}: {status} at t = {t_end:.4g} s, {rows} rows (one per "
        f"{run.record_every} steps), {fld.n_elements} triangles, dt = {model.opt.timestep:g} s, "
        f"{_integrator_name(model)}; simulation {sim:.2f} s wall ({rate}, the simulation "
        f"alone), {plots}{total:.1f} s in all; wrote {table or 'no table'}, {RUN_JSON} and "
        f"{n_plots} figures",
        flush=True,
    )
    if run.figures_skipped:
        print(
            f"  figures not drawn, to stay within the simulation's {sim:.2f} s: "
            f"{', '.join(run.figures_skipped)} (--plots-only draws them from the table now; "
            "--all-figures draws every figure in a run)"
        )
    if run.ground is not None:
        g = run.ground
        print(
            f"  deforming ground ({g['cell_m'] * 1e3:.3g} mm cell, {g['grid'][0]} x "
            f"{g['grid'][1]} vertices): {g['excavated_m3']:.4g} m^3 cut, "
            f"{g['lost_m3']:.4g} m^3 lost at the region's edge ({g['lost_fraction']:.3g} of the "
            "cut volume); "
            f"{g['unrelaxed_updates']} of {g['updates']} updates ended before every slope "
            f"reached repose{'' if g['relaxed'] else ', the last one too'}"
        )
        if g["lost_m3"] > 0:
            print(
                f"mjrft run: {g['lost_m3']:.4g} m^3 of the deforming ground was cut where it "
                "could not be placed (at the edge of mjrft:region) and is lost from the ground; "
                "a region that keeps the intruders away from its edge conserves it",
                file=sys.stderr,
            )
    if status == "failed" and run.error:
        print(f"mjrft run: failed: {run.error}", file=sys.stderr)
    if signals:
        print(
            f"mjrft run: received {', '.join(signals)}; the run's files were completed first",
            file=sys.stderr,
        )
    for note in run.notes:
        print(f"mjrft run: {note}", file=sys.stderr)
    if recorder is not None and recorder.path is not None and recorder.path.exists():
        size_mb = recorder.path.stat().st_size / 1e6
        print(
            f"  recording: {recorder.path} ({size_mb:.1f} MB, {recorder.frames} frames, one per "
            f"{recorder.every} steps, arrows {recorder.arrow_scale_text}); open it with "
            f"`mjrft view-recording {recorder.path}`"
        )


def _integrator_name(model) -> str:
    from mjrft.app.simulate import INTEGRATORS

    return next((k for k, v in INTEGRATORS.items() if v == model.opt.integrator), "?")


def _cell(text: str) -> float | str:
    """--deform-cell: a cell [m] >= 0, or 'auto'."""
    return "auto" if text == "auto" else _nonnegative_float(text)


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite positive number, got {text}")
    return v


def _nonnegative_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not v >= 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text}")
    return v


#: ``mjrft.field.lowspeed.MODES``, here so that building the parser does not import mujoco
#: (``mjrft.field`` does).
LOW_SPEED_MODES = ("stick", "free", "off")


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose "invalid choice" errors (a subcommand, --integrator, ...) suggest
    the closest valid choice."""

    def _check_value(self, action, value):
        try:
            super()._check_value(action, value)
        except argparse.ArgumentError as exc:
            close = difflib.get_close_matches(str(value), [str(c) for c in action.choices], n=1)
            if not close:
                raise
            raise argparse.ArgumentError(
                action, f"{exc.message}; did you mean {close[0]!r}?"
            ) from None


def build_parser() -> argparse.ArgumentParser:
    from mjrft import __version__

    p = _Parser(prog="mjrft", description="Granular Resistive Force Theory (3D RFT) for MuJoCo.")
    p.add_argument("--version", action="version", version=f"mjrft {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    _add_demo(sub)
    _add_run(sub)
    _add_sweep(sub)
    _add_fit(sub)
    _add_view(sub)
    _add_view_model(sub)
    return p


_MODEL_HELP = (
    "MJCF model file, or the name of a shipped model (dune_drop, ellipsoid_pitch, go2_sand, "
    "hexapod_sand, plate_rig, root_circumnutation, sphere_drop)"
)


def _add_demo(sub) -> None:
    """The ``mjrft demo`` subcommand."""
    d = sub.add_parser(
        "demo",
        help="run the paper's demos and write CSV + PNG plots and a rerun recording",
        description=(
            "Reproduce the two demos of Treers, Cao & Stuart (RA-L 2021) with prescribed "
            "trajectories: the mole-crab ellipsoid pitching 9 deg at 0.625 Hz while descending "
            "0.5 cm/s (with and without pitching), and the root-tip paraboloid circumnutating; "
            "then simulate the rigs that produce those motions in MuJoCo with the granular field "
            "(models/ellipsoid_pitch.xml, 12 s; models/root_circumnutation.xml, one 24 s turn). "
            "Writes CSV files (SI units, world frame), PNG plots, and demo.rrd: a rerun "
            "recording of the ellipsoid rig's run (open it with `mjrft view-recording demo.rrd`)."
        ),
    )
    d.add_argument(
        "--out",
        default=DEFAULT_DEMO_DIR,
        help=f"output directory, created if needed (default: ./{DEFAULT_DEMO_DIR})",
    )
    d.add_argument(
        "--triangles",
        type=_positive_int,
        default=4000,
        help="surface triangles per primitive body (the root rig's mesh keeps its own): more is "
        "more accurate and slower (default: 4000)",
    )
    d.add_argument(
        "--material",
        default="glass_beads",
        help="material preset (glass_beads, poppy_seeds_lp, poppy_seeds_cp, generic_1ncm3; "
        "default: glass_beads, zeta = 0.33 N/cm^3 with Li's generic coefficients)",
    )
    d.set_defaults(func=_demo)


def _add_run(sub) -> None:
    """The ``mjrft run`` subcommand."""
    r = sub.add_parser(
        "run",
        help="simulate an MJCF scene with granular forces and write a time series",
        description=(
            "Simulate MODEL with the granular RFT field (the medium, material and "
            "intruding geoms come from the model's <custom> section; see docs/mjcf.md; the "
            "options below override them). Starts from keyframe 0 if the model has one. Writes "
            "DIR/run.json (versions, machine, options, model hashes, timings, outcome), "
            "DIR/timeseries.csv (time; per intruding "
            "body: CoM position and linear velocity, RFT force and torque about the CoM, all in "
            "the world frame and SI units; then every MJCF sensor) and PNG plots of the RFT "
            "forces vs time and vs depth and a paper-style summary (rft_summary.png), and with "
            "--rrd a rerun recording. The CSV is written as the run goes (flushed every second); "
            "on Ctrl-C, SIGTERM or SIGHUP the run stops and finishes its CSV, recording, plots "
            "and run.json (later signals wait for them); an output that cannot be written (a "
            "full disk) ends it 'failed', naming the file, with the whole rows written kept. "
            "Exit codes: 0 completed, 1 failed (run.json's error says why), 2 bad input, 3 the "
            "simulation diverged (MuJoCo reset its state; the rows before are kept), 129 hang-up, "
            "130 interrupted, 143 terminated."
        ),
    )
    r.add_argument("model", metavar="MODEL", help=_MODEL_HELP)
    r.add_argument(
        "--duration",
        type=_positive_float,
        default=None,
        help="simulated time in seconds (required, except with --plots-only)",
    )
    r.add_argument(
        "--out",
        required=True,
        metavar="DIR",
        help="output directory (created; one that holds a run needs --overwrite)",
    )
    _add_scene_options(r)
    figures = r.add_mutually_exclusive_group()
    figures.add_argument(
        "--no-plots",
        action="store_true",
        help="draw no figures (the table, run.json and any recording are still written)",
    )
    figures.add_argument(
        "--plots-only",
        action="store_true",
        help="simulate nothing: draw every figure of the run already in --out from its table "
        "(give the run's MODEL and scene options)",
    )
    figures.add_argument(
        "--all-figures",
        action="store_true",
        help="draw every figure whatever it costs (default: the figures of a completed run, "
        "the summary first, are drawn from the table after the run only while their cost stays "
        "within the simulation's own wall time, those left out named; a run that stopped early "
        "draws them all)",
    )
    r.add_argument(
        "--figure-format",
        choices=FIGURE_FORMATS,
        default="png",
        help="the figures' file format: png (raster, at most 2000 px a side), svg or pdf "
        "(vector) (default: png)",
    )
    r.add_argument(
        "--record-every",
        type=_positive_int,
        default=None,
        metavar="K",
        help="write one table row every K steps (default: what the figures draw, about 2,000 "
        "rows over the run: K = steps // 2000, at least 1; 1 for every step)",
    )
    r.add_argument(
        "--table-format",
        choices=TABLE_FORMATS,
        default="csv",
        help="the time series' file: csv (timeseries.csv) or parquet (timeseries.parquet, "
        "made from the CSV the run streams to, which then goes) (default: csv)",
    )
    r.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the run already in DIR (its CSV, run.json and plots) and an existing "
        "--rrd file (both refused otherwise)",
    )
    _add_recording_options(r)
    r.set_defaults(func=_run)


#: ``--ray`` without an address: a new local Ray instance.
RAY_LOCAL = "local"


def _add_sweep(sub) -> None:
    """The ``mjrft sweep`` subcommand (mjrft.sweep; docs/sweeps.md)."""
    s = sub.add_parser(
        "sweep",
        help="run a parameter study on local processes or Ray into a resumable results table",
        description=(
            "Run every run of STUDY (a TOML file: the model, the parameters and where each goes "
            "in the model, their values, the duration and the metrics; docs/sweeps.md), each in "
            "a worker built from scratch, and append one row per finished run to "
            "DIR/results.csv (run id, parameters, metrics, max_froude and quasi_static, status, "
            "error, warnings, wall time, seed, versions), flushed as runs finish; then write a "
            "PNG per metric into DIR (a line over one varied parameter, a heat map over two). "
            "One sweep at a time writes DIR (a second is refused, naming the first's pid and "
            "host). The first run is loaded before any starts: if it and the run most unlike it "
            "fail to load with the same error, the sweep stops with that error. A run that fails "
            "(its values do not compile, it diverges, user code raises) is recorded with its "
            "error and the others go on; one that fails for a reason outside it (its worker "
            "killed, the disk full) has status retry and --resume runs it again. On Ctrl-C, "
            "SIGTERM or a full disk no new run starts, the runs in flight are stopped, the "
            "finished rows are kept whole and the command says how to resume. Exit codes: 0 "
            "done, every run ok, 2 bad input or DIR in use, 3 done with failed or retry runs "
            "(the command says how many), 74 stopped by a failure outside the runs (a full "
            "disk), 130 interrupted, 143 terminated."
        ),
    )
    s.add_argument("study", metavar="STUDY", help="the study description (TOML)")
    s.add_argument("--out", required=True, metavar="DIR", help="results folder (created)")
    s.add_argument(
        "--workers",
        type=_positive_int,
        default=None,
        metavar="N",
        help="worker processes (default: all cores); with --ray and no address, the CPUs of "
        "the local Ray instance",
    )
    s.add_argument(
        "--ray",
        nargs="?",
        const=RAY_LOCAL,
        default=None,
        metavar="ADDRESS",
        help="run on Ray (pip install 'mjrft[ray]'): a cluster's HOST:PORT, 'auto' for the one "
        "`ray start` runs on this machine, or nothing for a new local instance",
    )
    s.add_argument(
        "--resume",
        action="store_true",
        help="continue the sweep DIR holds: finished runs are never recomputed (refused if "
        "the study differs from DIR's, naming what differs)",
    )
    s.add_argument(
        "--plots-only",
        action="store_true",
        help="run nothing: draw DIR's figures from its results table",
    )
    s.set_defaults(func=_sweep)


#: The handler of ``mjrft sweep``: it lives in the sweep layer (``mjrft.sweep``, which runs its
#: simulations through this layer), so it is named here, as console_scripts name entry points,
#: and imported only when the command runs: the app layer imports nothing of mjrft.sweep.
SWEEP_COMMAND = "mjrft.sweep.command:main"


def _sweep(args: argparse.Namespace) -> int:
    import importlib

    module, _, name = SWEEP_COMMAND.partition(":")
    return getattr(importlib.import_module(module), name)(args)


def _add_fit(sub) -> None:
    """The ``mjrft fit`` subcommand: plate data -> a fitted medium (mjrft.app.fitting)."""
    f = sub.add_parser(
        "fit",
        help="fit a medium's RFT coefficients to plate intrusion data (CSV)",
        description=(
            "Least-squares fit of Li 2013's Fourier coefficients to plate intrusion data: a CSV "
            "with columns beta_deg, gamma_deg, depth_m, area_m2, fx_N, fz_N (docs/materials.md); "
            "with yaw_deg and fy_N also alpha_y(beta) and f1, f23 from the yawed plates. "
            "Writes material.xml (mjrft:zeta and mjrft:coefficients to paste into <custom>), "
            "fit.json (coefficients with 95%% intervals) and residuals.png."
        ),
    )
    f.add_argument("data", type=Path, help="CSV of plate measurements")
    f.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    f.add_argument(
        "--order", choices=("auto", "first", "full"), default="auto",
        help="coefficient set: Li's first-order nine, every separable term, or auto (the full "
        "set with at least 27 plates that determine it; default)",
    )  # fmt: skip
    f.set_defaults(func=_fit)


def _fit(args: argparse.Namespace) -> int:
    from mjrft.app import fitting
    from mjrft.core.fit import fit_yawed

    data, yawed_data = fitting.read_plates(args.data)
    result = fitting.choose(data, args.order)
    yawed = None if yawed_data is None else fit_yawed(yawed_data, result)
    written = fitting.write_outputs(data, result, args.out, yawed)
    print(f"mjrft fit {args.data}: {result.n} plates, {result.order}-order set, zeta = "
          f"{result.material.zeta:.4g} N/m^3, RMS residual F_z {result.rms['z']:.3g} N, "
          f"F_x {result.rms['x']:.3g} N")  # fmt: skip
    for k, v in result.coefficients.items():
        lo, hi = result.interval(k)
        print(f"  {k:5s} {v:12.5g} N/m^3  (95%: {lo:.5g} .. {hi:.5g})")
    if yawed is not None:
        print(f"{yawed.n} yawed plates: alpha_y(beta) and the scaling functions f1, f23")
        for k, v in yawed.values.items():
            lo, hi = yawed.interval(k)
            print(f"  {k:9s} {v:12.5g}  (95%: {lo:.5g} .. {hi:.5g})")
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0


def _add_view(sub) -> None:
    """The ``mjrft view-recording`` subcommand (mjrft.app.view; it does not import rerun)."""
    from mjrft.app import view

    view.add_parser(sub)


def _add_view_model(sub) -> None:
    """The ``mjrft view`` subcommand: MuJoCo's interactive viewer with the field acting."""
    v = sub.add_parser(
        "view",
        help="open MODEL in MuJoCo's interactive viewer with the granular field acting",
        description=(
            "Simulate MODEL in real time in MuJoCo's interactive viewer (mujoco.viewer) with the "
            "granular RFT field, drawing each intruding body's RFT force as an arrow from its "
            "CoM (and with --triangle-arrows the per-triangle forces), in the colours farthest "
            "from the model's own, scaled so that no body arrow is longer than its body's size "
            "(a body's longest triangle arrow 30% of it) unless --force-scale fixes the scale. "
            "--track BODY follows a body with the camera. Needs a display; on a headless "
            "machine record with `mjrft run --rrd` instead."
        ),
    )
    v.add_argument("model", metavar="MODEL", help=_MODEL_HELP)
    v.add_argument(
        "--duration",
        type=_positive_float,
        default=None,
        help="close after this many simulated seconds (default: when the window is closed)",
    )
    v.add_argument(
        "--force-scale",
        type=_positive_float,
        default=None,
        metavar="M_PER_N",
        help="arrow length per newton [m/N] (default: automatic, no body arrow longer than its "
        "body's size)",
    )
    v.add_argument(
        "--track",
        default=None,
        metavar="BODY",
        help="a camera that follows BODY (a body name, e.g. torso) instead of a free camera",
    )
    v.add_argument(
        "--triangle-arrows",
        action="store_true",
        help="also draw per-triangle force arrows (at most 200 per body; slower)",
    )
    _add_scene_options(v)
    v.set_defaults(func=_view)


def _view(args: argparse.Namespace) -> int:
    import mujoco

    from mjrft.app import mujoco_viewer, simulate

    if not mujoco_viewer.has_display():
        raise ValueError(
            "no display (DISPLAY and WAYLAND_DISPLAY are unset): record the run instead, e.g. "
            f"mjrft run {args.model} --duration 10 --out run --rrd run/run.rrd"
        )
    ctrl = _load_controller(args.ctrl) if args.ctrl else None
    model, keyframe, fld = _scene(args, args.model)
    mujoco_viewer.track(mujoco.MjvCamera(), model, args.track)  # a missing body, named at once
    data = simulate.reset_data(model, keyframe)
    mujoco_viewer.launch(model, fld, data=data, ctrl=ctrl, force_scale=args.force_scale,
                         triangles=args.triangle_arrows, duration=args.duration,
                         track_body=args.track)  # fmt: skip
    return 0


#: The command-line option (argparse dest) that sets each ``mjrft.SceneOptions`` field.
SCENE_OPTIONS = {
    "material": "material", "n_triangles": "triangles", "tolerance": "tolerance",
    "low_speed": "low_speed", "stick_reach": "stick_reach", "deform_cell": "deform_cell",
    "repose": "repose", "deform_every": "deform_every", "deform_travel": "deform_travel",
    "dynamic": "dynamic",
    "intruders": "intruders", "watch_sinking": "watch_sinking",
}  # fmt: skip


def scene_options(args: argparse.Namespace):
    """The ``mjrft.SceneOptions`` a command's options ask for (the only place the command line
    reaches the scene): options a command lacks or leaves unset keep the MJCF's values."""
    from mjrft.field.options import SceneOptions

    given = {field: getattr(args, dest, None) for field, dest in SCENE_OPTIONS.items()}
    dynamic = given["dynamic"]
    if isinstance(dynamic, list):  # --dynamic RHO_C [LAMBDA]
        given["dynamic"] = dynamic[0] if len(dynamic) == 1 else tuple(dynamic)
    if given["intruders"] is not None:  # --intruders FORM=NAMES, repeated
        selections: dict[str, list[str]] = {}
        for form, names in given["intruders"]:
            selections.setdefault(form, []).extend(names.split())
        given["intruders"] = selections
    return SceneOptions(**given)


def _scene(args: argparse.Namespace, xml):
    """(model, keyframe, field) of ``mjrft run`` and ``mjrft view``, with the scene options."""
    from mjrft.app import simulate
    from mjrft.field.granular_field import GranularField

    model = simulate.load_model(xml, scene_options(args))
    simulate.configure(model, args.timestep, args.integrator)
    keyframe = _keyframe(model, args.keyframe)
    return model, keyframe, GranularField(model)


def _add_scene_options(r) -> None:
    """Options of ``mjrft run`` and ``mjrft view`` that override the model and its scene."""
    r.add_argument(
        "--timestep",
        type=_positive_float,
        default=None,
        metavar="DT",
        help="override the model's timestep in seconds (default: the model's <option timestep>)",
    )
    r.add_argument(
        "--integrator",
        choices=["euler", "rk4", "implicit", "implicitfast"],
        default=None,
        help="override the model's integrator (default: the model's <option integrator>)",
    )
    r.add_argument(
        "--material",
        default=None,
        metavar="NAME",
        help="override the model's mjrft:material with a preset (glass_beads, poppy_seeds_lp, "
        "poppy_seeds_cp, generic_1ncm3)",
    )
    mesh = r.add_mutually_exclusive_group()
    mesh.add_argument(
        "--triangles",
        type=_positive_int,
        default=None,
        metavar="N",
        help="surface triangles per primitive intruder geom (meshes keep their own): more is more "
        "accurate and slower (default: the model's mjrft:n_triangles or mjrft:tolerance)",
    )
    mesh.add_argument(
        "--tolerance",
        type=_positive_float,
        default=None,
        metavar="TOL",
        help="relative RMS force error per primitive geom in (0, 1), e.g. 0.02; sets its triangle "
        "count (docs/accuracy.md)",
    )
    r.add_argument(
        "--keyframe",
        default=None,
        metavar="K",
        help="start from keyframe K (an index or a name), or 'none' for the model's qpos0 "
        "(default: keyframe 0 if the model has one)",
    )
    r.add_argument(
        "--ctrl",
        default=None,
        metavar="MODULE:FUNCTION",
        help="a controller ctrl(t, data) called before every step, returning the nu actuator "
        "controls (or None after writing data.ctrl): an importable module or a path/to/file.py, "
        "then ':' and the function's name",
    )
    r.add_argument(
        "--low-speed",
        choices=list(LOW_SPEED_MODES),
        default=None,
        help="low-speed treatment (docs/stability.md): stick holds free bodies and bodies in "
        "mechanisms at rest like static friction, free only free bodies, off is the pure model "
        "(default: the model's mjrft:low_speed, else stick)",
    )
    r.add_argument(
        "--deform-cell",
        type=_cell,
        default=None,
        metavar="CELL",
        help="ground that deforms and remembers, on a grid of CELL m over mjrft:region "
        "(docs/terrain.md), or 'auto' (10 cells across the narrowest intruder); 0 turns it off "
        "(default: the model's mjrft:deform_cell, else off)",
    )
    r.add_argument(
        "--repose",
        type=_positive_float,
        default=None,
        metavar="DEG",
        help="the deforming ground's angle of repose in degrees (default: the model's "
        "mjrft:repose, else the material preset's)",
    )
    r.add_argument(
        "--deform-every",
        type=_positive_int,
        default=None,
        metavar="K",
        help="update the deforming ground every K steps: K times cheaper, the ground lagging the "
        "intruders by up to K steps (default: the model's mjrft:deform_every, else 1)",
    )
    r.add_argument(
        "--deform-travel",
        type=_nonnegative_float,
        default=None,
        metavar="CELLS",
        help="instead of --deform-every, update the deforming ground once the intruders have "
        "travelled CELLS cells since its last update (docs/terrain.md)",
    )
    r.add_argument(
        "--dynamic",
        type=_nonnegative_float,
        nargs="+",
        default=None,
        metavar=("RHO_C", "LAMBDA"),
        help="the dynamic RFT inertial term (docs/models.md): the medium's bulk density RHO_C in "
        "kg/m^3 and optionally LAMBDA (default 1); 0 turns it off (default: the model's "
        "mjrft:dynamic, else off)",
    )
    r.add_argument(
        "--stick-reach",
        type=_positive_float,
        default=None,
        metavar="R",
        help="the treatment's reach (default: the model's mjrft:stick_reach, else 4)",
    )
    r.add_argument(
        "--intruders",
        type=_intruder_selection,
        action="append",
        default=None,
        metavar="FORM=NAMES",
        help="the geoms that feel the medium, instead of the model's mjrft:intruders tagging: FORM "
        "is geoms, bodies, subtree, match (glob patterns on geom names) or collision, NAMES one "
        "or more names separated by spaces, e.g. --intruders 'match=*foot* *calf*'; repeat it "
        "to add selections (docs/mjcf.md)",
    )
    r.add_argument(
        "--no-watch-sinking",
        dest="watch_sinking",
        action="store_const",
        const=False,
        default=None,
        help="do not report collision geoms that are below the surface without being intruders "
        "(default: the model's mjrft:watch_sinking, else on; docs/mjcf.md)",
    )


#: The selection forms of --intruders (mjrft.field.scene.INTRUDER_FORMS).
INTRUDER_FORMS = ("geoms", "bodies", "subtree", "match", "collision")


def _intruder_selection(text: str) -> tuple[str, str]:
    form, sep, names = text.partition("=")
    if not sep or form not in INTRUDER_FORMS or not names.split():
        raise argparse.ArgumentTypeError(
            f"expected FORM=NAMES with FORM one of {', '.join(INTRUDER_FORMS)} and at least one "
            f"name, e.g. 'match=*foot*'; got {text!r}"
        )
    return form, names


def _add_recording_options(r) -> None:
    """``mjrft run``'s rerun recording options."""
    g = r.add_argument_group(
        "rerun recording",
        "A recording of the run for the rerun viewer (see docs/recording.md): body "
        "meshes and poses, the medium's surface and region, per-triangle RFT force arrows and "
        "stress colours, per-body RFT force/torque and every sensor as time series. Headless: "
        "nothing is displayed and no port is opened unless --spawn or --connect is given. The "
        "file is complete even if the run fails or is interrupted. Open it with "
        "`mjrft view-recording FILE` (a browser route on headless machines: docs/recording.md).",
    )
    g.add_argument("--rrd", metavar="FILE", default=None, help="write a rerun recording to FILE")
    g.add_argument(
        "--rrd-every",
        type=_positive_int,
        default=None,
        metavar="K",
        help="log one frame every K steps (default: every 10 ms of simulated time, K = 10 at "
        "dt = 1 ms; a 10 s run of models/ellipsoid_pitch.xml is then about 15 MB)",
    )
    g.add_argument(
        "--max-arrows",
        type=_nonnegative_int,
        default=DEFAULT_MAX_ARROWS,
        metavar="N",
        help="at most N per-triangle force arrows per body and frame, an even stride through the "
        f"triangles that feel a force; 0 for none (default: {DEFAULT_MAX_ARROWS})",
    )
    g.add_argument(
        "--arrow-scale",
        type=_positive_float,
        default=None,
        metavar="M_PER_N",
        help="arrow length per newton of triangle force, in m/N, for every frame (default: "
        "automatic per body and frame, the longest arrow 30%% of the body's size)",
    )
    g.add_argument(
        "--stress-max",
        type=_positive_float,
        default=DEFAULT_STRESS_MAX_PA,
        metavar="PA",
        help="top of the triangle stress colour scale |F|/dA in Pa; viridis from 0, clipped "
        f"above, grey = no force (default: {DEFAULT_STRESS_MAX_PA:g} Pa)",
    )
    g.add_argument(
        "--spawn",
        action="store_true",
        help="also start a rerun viewer and stream the recording to it live (opens a local port)",
    )
    g.add_argument(
        "--connect",
        nargs="?",
        const=DEFAULT_CONNECT_URL,
        default=None,
        metavar="URL",
        help="also stream to a running rerun viewer at URL (default when given without a URL: "
        f"{DEFAULT_CONNECT_URL})",
    )


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {v}")
    return v


def _nonnegative_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {v}")
    return v


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``mjrft`` command."""
    started = (time.perf_counter(), time.time())
    args = build_parser().parse_args(argv)
    args.started = started
    try:
        return args.func(args)
    except ValueError as exc:
        print(f"mjrft {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
