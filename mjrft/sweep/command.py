"""``mjrft sweep``: a study run from the command line (the parser is ``mjrft.app.cli``'s), with
its progress as a tqdm bar, the warnings summarised once, what stopped it and the command that
resumes; the exit codes of docs/cli.md."""

from __future__ import annotations

import argparse
import shlex
import signal
import sys
import time
import warnings
from pathlib import Path

from mjrft.app import cli
from mjrft.sweep.runner import SweepSummary

#: Set once SIGTERM arrived: the Terminated exception can come back from a library it passes
#: through as a plain KeyboardInterrupt (under --ray on a loaded machine, about 1 sweep in 6).
_SIGTERM_SEEN: list[bool] = [False]


def _on_sigterm(signum: int, frame: object) -> None:
    _SIGTERM_SEEN[0] = True
    raise cli.Terminated  # the sweep ends as on Ctrl-C: runs in flight stopped, rows kept


class _SweepProgress:
    """``run_study``'s progress on stderr as a tqdm bar (runs done, rate, ETA), and each failed
    run's error on a line of its own."""

    def __init__(self, name: str) -> None:
        self.name, self.done, self.total, self.bar = name, 0, 0, None

    def __call__(self, done: int, total: int, row: dict | None) -> None:
        from tqdm import tqdm

        self.done, self.total = done, total
        if row is None:
            if not total:
                return  # nothing to run: no bar
            tty = sys.stderr.isatty()
            self.bar = tqdm(
                total=total, desc=f"mjrft sweep {self.name}", unit="run", file=sys.stderr,
                dynamic_ncols=True, mininterval=0.2 if tty else 30.0, smoothing=0.1,
            )  # fmt: skip
            return
        if row["status"] != "ok":
            self.bar.write(f"  run {row['run_id']} {row['status']}: {row['error']}", sys.stderr)
        self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def main(args: argparse.Namespace) -> int:
    """Run ``mjrft sweep`` with its parsed arguments (``mjrft.app.cli``'s parser); returns the
    exit code. A warning raised in this process (loading the study, checking its first run) is
    printed once, as ``mjrft sweep: warning: Category: message``, without a source line; the
    runs' own are summarised at the end."""
    shown: set[str] = set()

    def show(message, category, *args, **kwargs) -> None:
        text = f"{category.__name__}: {message}"
        if text not in shown:
            shown.add(text)
            print(f"mjrft sweep: warning: {text}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = show
        return _main(args, shown)


def _main(args: argparse.Namespace, shown: set[str]) -> int:
    from mjrft import sweep

    study = sweep.Study.load(args.study)
    out = Path(args.out)
    if args.plots_only:
        sweep.check_same_study(out, study)
        for path in sweep.plot_study(study, out):
            print(f"  {path}")
        return 0
    progress = _SweepProgress(study.name)
    address = None if args.ray in (None, cli.RAY_LOCAL) else args.ray
    again = ["mjrft", "sweep", args.study, "--out", args.out, "--resume"]
    again += ["--workers", str(args.workers)] if args.workers else []
    again += ["--ray", args.ray] if args.ray else []
    _SIGTERM_SEEN[0] = False
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        summary = sweep.run_study(
            study, out, workers=args.workers, backend="ray" if args.ray else "local",
            address=address, resume=args.resume, progress=progress,
        )  # fmt: skip
    except (KeyboardInterrupt, sweep.SweepStopped) as exc:
        progress.close()
        terminated = isinstance(exc, cli.Terminated) or _SIGTERM_SEEN[0]
        how = "terminated" if terminated else "interrupted"
        if isinstance(exc, sweep.SweepStopped):
            how = f"stopped ({exc})"
        print(
            f"\nmjrft sweep: {how} after {progress.done} of {progress.total} runs; every finished "
            f"run is in {out / 'results.csv'}; resume with: {shlex.join(again)}",
            file=sys.stderr,
        )
        if isinstance(exc, sweep.SweepStopped):
            return cli.EXIT_SWEEP_STOPPED
        return cli.EXIT_TERMINATED if how == "terminated" else cli.EXIT_INTERRUPTED
    finally:
        progress.close()
        signal.signal(signal.SIGTERM, previous)
    elapsed = time.perf_counter() - args.started[0]
    return _report(study.name, summary, elapsed, again, shown)


def _report(
    name: str, summary: SweepSummary, elapsed: float, again: list[str], shown: set[str]
) -> int:
    """Print what a finished sweep did, its runs' warnings once per category (a message already
    `shown` is not repeated), and its failed runs; the exit code."""
    before = f" ({summary.failed_before} failed)" if summary.failed_before else ""
    print(
        f"mjrft sweep {name}: {summary.computed} runs computed ({summary.failed} failed, "
        f"see the error column), {summary.skipped} already in the table{before}, "
        f"{summary.total} in all; {len(summary.plots)} plots; {elapsed:.1f} s; wrote "
        f"{summary.table}"
    )
    for category, n, first in summary.warning_groups():
        what = "(above)" if f"{category}: {first}" in shown else f"(the first: {first})"
        print(
            f"mjrft sweep: warning: {category} in {n} of {summary.computed} runs {what}; each "
            "run's are in the warnings column",
            file=sys.stderr,
        )
    failed = summary.failed + summary.failed_before
    if summary.retry:
        print(
            f"mjrft sweep: {summary.retry} runs did not finish for a reason outside them (status "
            f"retry); run them again with: {shlex.join(again)}",
            file=sys.stderr,
        )
    if failed:
        print(
            f"mjrft sweep: {failed} of {summary.total} runs failed; their errors are in the "
            f"error column of {summary.table}",
            file=sys.stderr,
        )
        return cli.EXIT_RUNS_FAILED
    return 0
