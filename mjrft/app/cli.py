"""Command-line interface: ``mjrft demo``, ``mjrft run``. Nothing below the app layer imports it."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np

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
        fld, rec = _demo_rig(name, duration, material, args.triangles, rrd)
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


def _demo_rig(name: str, duration: float, material, n_triangles: int, rrd: Path | None):
    """Simulate models/<name>.xml for `duration` s for `mjrft demo`; record it to `rrd` if given.

    Returns (field, simulate.Recording with a row every 10 steps).
    """
    from mjrft.app import simulate
    from mjrft.field.granular_field import GranularField

    model = simulate.load_model(simulate.models_dir() / f"{name}.xml")
    fld = GranularField(model, material=material, n_triangles=n_triangles)
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


#: Files `mjrft run` writes into --out (besides the optional --rrd).
RUN_CSV = "timeseries.csv"
RUN_PLOTS = ("forces_vs_time.png", "forces_vs_depth.png", "rft_summary.png")
#: Exit codes of `mjrft run` besides 0 (completed) and 2 (bad input).
EXIT_DIVERGED, EXIT_INTERRUPTED, EXIT_TERMINATED = 3, 130, 143


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that the run finishes its files as on Ctrl-C."""


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
    if args.rrd:
        rrd = Path(args.rrd)
        ours = {(out / name).resolve() for name in (RUN_CSV, *RUN_PLOTS)}
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
    from mjrft.app import simulate
    from mjrft.field.granular_field import GranularField

    out = _check_outputs(args)
    model = simulate.load_model(args.model)
    simulate.configure(model, args.timestep, args.integrator)
    fld = GranularField(model, low_speed=args.low_speed, stick_reach=args.stick_reach)
    columns = simulate.new_recording(model, fld).columns
    # Rows go to the CSV as the run goes (flushed every second): memory stays bounded and a
    # crash or SIGKILL loses at most the last second.
    sink = simulate.CsvSink(out / RUN_CSV, columns)
    rec = simulate.Recording(columns, [be.name for be in fld.bodies], sink=sink)
    recorder = _recorder(args, model, fld)
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    t0 = time.perf_counter()
    status, code = "completed", 0
    try:
        simulate.run(
            model,
            args.duration,
            fld=fld,
            record_every=args.record_every,
            progress=_Progress(f"mjrft run {Path(args.model).name}"),
            recording=rec,
            observer=recorder,
            observe_every=recorder.every if recorder is not None else 1,
        )
    except simulate.RunDiverged as exc:
        status, code = "diverged", EXIT_DIVERGED
        print(f"mjrft run: {exc}", file=sys.stderr)
    except Terminated:
        status, code = "terminated", EXIT_TERMINATED
    except KeyboardInterrupt:
        status, code = "interrupted", EXIT_INTERRUPTED
    except Exception:
        status = "failed"
        raise
    finally:
        # Whatever was computed is written, even when the run fails or is interrupted; a second
        # Ctrl-C or a SIGTERM waits until the CSV and the recording are complete.
        with DeferredSignals():
            sink.close()
            if recorder is not None:
                recorder.close()  # completes the .rrd file
        signal.signal(signal.SIGTERM, previous)
        _write_run_results(args, model, fld, rec, recorder, out, status, t0)
    return code


class DeferredSignals:
    """Hold SIGINT and SIGTERM over a block (files being completed), then act on them."""

    def __enter__(self) -> DeferredSignals:
        self.pending: list[int] = []
        self._previous = {
            sig: signal.signal(sig, lambda signum, frame: self.pending.append(signum))
            for sig in (signal.SIGINT, signal.SIGTERM)
        }
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        if self.pending and exc[0] is None:
            raise Terminated if signal.SIGTERM in self.pending else KeyboardInterrupt


def _write_run_results(args, model, fld, rec, recorder, out: Path, status: str, t0: float) -> None:
    """Plots from the CSV and the one-line summary of `mjrft run` (also after a failure)."""
    from mjrft.app import report, simulate

    if rec.n_rows == 0:
        return
    wall = time.perf_counter() - t0
    t_end = float(rec.last_row[0])
    plots = simulate.Recording.from_csv(rec.sink.path, rec.body_names)
    pngs = report.plot_run(plots, fld.surface_z, out) if rec.body_names else []
    print(
        f"mjrft run {Path(args.model).name}: {status} at t = {t_end:.4g} s, "
        f"{rec.n_rows} rows, {fld.n_elements} triangles, dt = {model.opt.timestep:g} s, "
        f"{_integrator_name(model)}, {wall:.1f} s wall ({t_end / max(wall, 1e-9):.2f}x "
        f"real time); wrote {rec.sink.path} and {len(pngs)} plots"
    )
    if recorder is not None and recorder.path is not None and recorder.path.exists():
        size_mb = recorder.path.stat().st_size / 1e6
        print(
            f"  recording: {recorder.path} ({size_mb:.1f} MB, {recorder.frames} frames, one per "
            f"{recorder.every} steps, arrows {recorder.arrow_scale:.3g} m/N); open it with "
            f"`rerun {recorder.path}`"
        )


def _integrator_name(model) -> str:
    from mjrft.app.simulate import INTEGRATORS

    return next((k for k, v in INTEGRATORS.items() if v == model.opt.integrator), "?")


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite positive number, got {text}")
    return v


def build_parser() -> argparse.ArgumentParser:
    from mjrft import __version__

    p = argparse.ArgumentParser(
        prog="mjrft", description="Granular Resistive Force Theory (3D RFT) for MuJoCo."
    )
    p.add_argument("--version", action="version", version=f"mjrft {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    _add_demo(sub)
    _add_run(sub)
    return p


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
            "recording of the ellipsoid rig's run (open it with `rerun demo.rrd`)."
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
            "Simulate MODEL.xml with the granular RFT field installed (the medium, material and "
            "intruding geoms come from the model's <custom> section; see docs/mjcf.md). Starts "
            "from keyframe 0 if the model has one. Writes DIR/timeseries.csv (time; per intruding "
            "body: CoM position and linear velocity, RFT force and torque about the CoM, all in "
            "the world frame and SI units; then every MJCF sensor) and PNG plots of the RFT "
            "forces vs time and vs depth and a paper-style summary (rft_summary.png), and with "
            "--rrd a rerun recording. The CSV is written as the run goes (flushed every second); "
            "on Ctrl-C or SIGTERM the run stops and finishes its CSV, recording and plots. Exit "
            "codes: 0 completed, 2 bad input, 3 the simulation diverged (MuJoCo reset its state; "
            "the rows before are kept), 130 interrupted, 143 terminated."
        ),
    )
    r.add_argument("model", metavar="MODEL.xml", help="MJCF model file")
    r.add_argument(
        "--duration", type=_positive_float, required=True, help="simulated time in seconds"
    )
    r.add_argument("--out", required=True, metavar="DIR", help="output directory (created)")
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
        "--low-speed",
        choices=["stick", "off"],
        default=None,
        help="low-speed treatment of free bodies (docs/stability.md): stick holds bodies at "
        "rest like static friction, off is the pure model (default: the model's "
        "mjrft:low_speed, else stick)",
    )
    r.add_argument(
        "--stick-reach",
        type=_positive_float,
        default=None,
        metavar="R",
        help="the treatment's reach (default: the model's mjrft:stick_reach, else 4)",
    )
    r.add_argument(
        "--record-every",
        type=_positive_int,
        default=1,
        metavar="K",
        help="write one CSV row every K steps (default: 1, every step)",
    )
    r.add_argument(
        "--overwrite",
        action="store_true",
        help="let --rrd replace an existing file (refused otherwise)",
    )
    _add_recording_options(r)
    r.set_defaults(func=_run)


def _add_recording_options(r) -> None:
    """``mjrft run``'s rerun recording options."""
    g = r.add_argument_group(
        "rerun recording",
        "A recording of the run for the rerun viewer (see docs/recording.md): body "
        "meshes and poses, the medium's surface and region, per-triangle RFT force arrows and "
        "stress colours, per-body RFT force/torque and every sensor as time series. Headless: "
        "nothing is displayed and no port is opened unless --spawn or --connect is given. The "
        "file is complete even if the run fails or is interrupted. Open it with `rerun FILE`.",
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
        help="arrow length per newton of triangle force, in m/N (default: automatic, a 1 cm "
        "arrow for a triangle of median area at the top of the stress colour scale)",
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
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValueError as exc:
        print(f"mjrft {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
