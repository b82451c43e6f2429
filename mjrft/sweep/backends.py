"""Where a study's runs execute: in this process (``serial``), on local worker processes
(``local``) or on Ray (``ray``). Each backend calls ``on_row(row)`` in this process as runs
finish; on KeyboardInterrupt it stops scheduling, ends the runs in flight and re-raises.

Every run builds its model and field from scratch in its worker (``executor.execute``), so a
run's metrics do not depend on the backend, the worker or the order.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import select
import signal
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from mjrft.sweep.errors import StudyError, one_line
from mjrft.sweep.executor import STATUS_FAILED, STATUS_RETRY, execute, versions
from mjrft.sweep.study import RunSpec, Study

Row = dict[str, Any]
OnRow = Callable[[Row], None]
BACKENDS = ("local", "ray", "serial")


def cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def serial(study: Study, runs: list[RunSpec], out: Path, on_row: OnRow) -> None:
    """Every run in this process, one after the other."""
    for run in runs:
        on_row(execute(study, run, out))


def _init_worker(sweep_pid: int) -> None:
    # Ctrl-C reaches the whole process group: the parent decides what stops, and how; and a
    # forked worker must not run the parent's SIGTERM handler when the parent ends it.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _exit_with(sweep_pid)


def _exit_with(pid: int) -> None:
    """End this worker as soon as process `pid` (the sweep) ends: after a SIGKILL of the sweep
    nothing else would, and an idle worker would wait for work forever."""
    try:
        fd = os.pidfd_open(pid)  # readable once the process has ended (Linux >= 5.3)
    except (AttributeError, OSError):
        return

    def wait() -> None:
        select.select([fd], [], [])
        os._exit(1)

    threading.Thread(target=wait, name="exit-with-the-sweep", daemon=True).start()


def _context() -> multiprocessing.context.BaseContext:
    """How workers start. By fork when this process runs no other thread (as in ``mjrft
    sweep``): a forked worker inherits the imported modules and starts in milliseconds, and
    with a single thread there is no lock another thread could hold across the fork. Otherwise
    from a forkserver that has imported mjrft and loaded the engine library once (fork-safe:
    the server starts clean); spawn where neither exists."""
    methods = multiprocessing.get_all_start_methods()
    if "fork" in methods and threading.active_count() == 1:
        return multiprocessing.get_context("fork")
    if "forkserver" in methods:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["mjrft.sweep.preload"])
        return ctx
    return multiprocessing.get_context("spawn")


def local(study: Study, runs: list[RunSpec], out: Path, on_row: OnRow, workers: int) -> None:
    """The runs on `workers` local processes (a ProcessPoolExecutor). A worker that dies (a
    crash in native code, a kill from outside) takes the pool's unfinished runs with it: those
    then run one at a time, each in a new pool, and the one whose worker dies again is recorded
    with status "retry" (a resume runs it again)."""
    broken = _pool_pass(study, runs, out, on_row, workers)
    for run in broken:
        if _pool_pass(study, [run], out, on_row, 1):
            on_row(_died(study, run, "its worker process died twice while running it"))


def _pool_pass(
    study: Study, runs: list[RunSpec], out: Path, on_row: OnRow, workers: int
) -> list[RunSpec]:
    """Run `runs` on a new pool; returns those lost to a dying worker."""
    if not runs:
        return []
    pool = ProcessPoolExecutor(
        max(1, min(workers, len(runs))),
        mp_context=_context(),
        initializer=_init_worker,
        initargs=(os.getpid(),),
    )
    broken = []
    try:
        futures = {pool.submit(execute, study, run, out): run for run in runs}
        for future, run in _as_completed(futures):
            if isinstance(future.exception(), BrokenProcessPool):
                broken.append(run)
            else:
                on_row(future.result())
    except BaseException:
        _stop(pool)
        raise
    pool.shutdown(wait=True)
    return sorted(broken, key=lambda r: r.index)


def _as_completed(futures: dict[Future, RunSpec]) -> Iterator[tuple[Future, RunSpec]]:
    """(future, run) as each finishes; waits in short slices so Ctrl-C is seen at once."""
    left = set(futures)
    while left:
        done, left = wait(left, timeout=0.5, return_when=FIRST_COMPLETED)
        for f in done:
            yield f, futures[f]


def _stop(pool: ProcessPoolExecutor) -> None:
    """Cancel what has not started and end the worker processes now."""
    processes = list(getattr(pool, "_processes", {}).values())  # no public handle before 3.14
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    for p in processes:
        p.join(timeout=5)


def _died(study: Study, run: RunSpec, error: str, status: str = STATUS_RETRY) -> Row:
    """The row of a run that returned none: its process died (status "retry": the cause may be
    outside the run), or Ray failed it otherwise."""
    return {
        "run_id": run.run_id, **run.values, **{m.name: float("nan") for m in study.metrics},
        "max_froude": float("nan"), "quasi_static": None, "status": status, "error": error,
        "warnings": "", "wall_s": float("nan"), "seed": run.seed, "versions": versions(),
    }  # fmt: skip


@contextlib.contextmanager
def ray_session(workers: int | None, address: str | None) -> Iterator[bool]:
    """Ray for a sweep: the instance already initialised in this process, else the cluster at
    `address` ("auto": RAY_ADDRESS or the one ``ray start`` runs here), else a new local
    instance of `workers` CPUs (all cores by default), whatever an earlier ``ray start`` left in
    Ray's temporary folder; one this started is shut down at the end. Yields whether it started
    one. Ray's SIGTERM handler is not kept: this process's own handlers stay."""
    try:
        import ray
    except ImportError:
        raise StudyError("the ray backend needs Ray: pip install 'mjrft[ray]'") from None
    started = not ray.is_initialized()
    if started:
        init_ray(address, workers or cores())
    try:
        yield started
    finally:
        if started:
            with _own_handlers():
                ray.shutdown()


def ray_backend(
    study: Study, runs: list[RunSpec], out: Path, on_row: OnRow, own_instance: bool
) -> None:
    """The runs as Ray tasks (one CPU each) on the Ray this process is connected to
    (``ray_session``); `own_instance`: a local one this sweep started, whose tasks end with it."""
    import ray

    task = ray.remote(num_cpus=1, max_retries=0)(execute)
    shared = ray.put(study)
    refs = {task.remote(shared, run, str(out)): run for run in runs}
    try:
        while refs:
            done, _ = ray.wait(list(refs), num_returns=1, timeout=0.5)
            for ref in done:
                on_row(_ray_row(ray, study, refs.pop(ref), ref))
    except BaseException:
        if not own_instance:  # a new local instance ends with its tasks at ray.shutdown()
            for ref in refs:
                # Not force=True: forcing a task that is finishing aborts the driver (Ray
                # 2.60, task_manager.cc "Tried to complete task that was not pending").
                ray.cancel(ref)
        raise


def init_ray(address: str | None, cpus: int) -> None:
    """``ray.init`` of the cluster at `address`, or of a new local instance of `cpus` CPUs
    (``address="local"``: not the cluster RAY_ADDRESS or Ray's temporary folder names), keeping
    this process's SIGINT and SIGTERM handlers (``ray.init`` installs its own for SIGTERM,
    which would exit with 15 without the resume line)."""
    import ray

    kwargs = {"address": address} if address else {"address": "local", "num_cpus": cpus}
    try:
        with _own_handlers():
            ray.init(include_dashboard=False, log_to_driver=False, **kwargs)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        where = f"the Ray cluster at {address!r}" if address else "a local Ray instance"
        raise StudyError(
            f"cannot start or reach {where}: {one_line(str(exc))}; --ray HOST:PORT names a "
            "cluster's head, --ray auto the cluster `ray start` runs on this machine, --ray "
            "alone starts a local instance"
        ) from None


@contextlib.contextmanager
def _own_handlers() -> Iterator[None]:
    """Restore SIGINT's and SIGTERM's handlers after the block (in the main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in saved.items():
            signal.signal(s, handler)


def _ray_row(ray: Any, study: Study, run: RunSpec, ref: Any) -> Row:
    """The row a finished Ray task returned, or the row of one that returned none: its worker
    or node lost ("retry"), or an error in the task outside ``execute``'s capture ("failed")."""
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as exc:
        return _died(study, run, one_line(f"Ray: {type(exc).__name__}: {exc}"), STATUS_FAILED)
    except ray.exceptions.RayError as exc:  # the worker died, or lost its node
        return _died(study, run, one_line(f"Ray: {type(exc).__name__}: {exc}"))
