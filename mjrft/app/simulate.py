"""Run an MJCF scene that carries the granular field and record its time series.

Used by ``mjrft run`` and ``mjrft demo``; no plotting or CLI code here.
"""

from __future__ import annotations

import contextlib
import difflib
import math
import os
import signal
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from mjrft.app.regime import FroudeWatch, com_velocity
from mjrft.field import plugin
from mjrft.field.granular_field import GranularField
from mjrft.field.options import SceneOptions
from mjrft.field.signals import HeldSignals

INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}
#: A controller: ``ctrl(t, data)`` -> (nu,) controls, or None if it wrote ``data.ctrl`` itself.
Controller = Callable[[float, mujoco.MjData], "np.ndarray | None"]


def models_dir() -> Path:
    """The rig models shipped with mjrft (the repository's models/ folder)."""
    import mjrft.models

    return Path(mjrft.models.__file__).parent


def resolve_model(name: str | os.PathLike) -> Path:
    """An MJCF path, or the shipped model of that name (``ellipsoid_pitch`` or
    ``ellipsoid_pitch.xml`` from ``models_dir()``) when no such file exists."""
    path = Path(name)
    if path.exists():
        return path
    stem = path.name[: -len(".xml")] if path.name.endswith(".xml") else path.name
    shipped = models_dir() / f"{stem}.xml"
    if path.parent == Path(".") and shipped.exists():
        return shipped
    names = sorted(p.stem for p in models_dir().glob("*.xml"))
    close = difflib.get_close_matches(stem, names, n=1) if path.parent == Path(".") else []
    hint = f"; did you mean {close[0]!r}?" if close else ""
    raise ValueError(
        f"no MJCF file {str(name)!r} and no shipped model of that name ({', '.join(names)}){hint}"
    )


def load_model(
    path: str | os.PathLike, options: SceneOptions | None = None, **overrides
) -> mujoco.MjModel:
    """Compile an MJCF file (or a shipped model by name, ``resolve_model``) with the engine
    plugin (``mjrft.load_model``; options, overrides: ``mjrft.SceneOptions`` and its fields,
    e.g. n_triangles, deform_cell [m], 0 off, repose [deg]), with an error that names the file."""
    path = resolve_model(path)
    try:
        return plugin.load_model(mujoco.MjSpec.from_file(str(path)), options, **overrides)
    except (ValueError, FileNotFoundError) as exc:
        raise ValueError(f"cannot load MJCF model {str(path)!r}: {exc}") from exc


def configure(model: mujoco.MjModel, timestep: float | None, integrator: str | None) -> None:
    """Override the model's timestep [s] and integrator (names in INTEGRATORS), validated."""
    if timestep is not None:
        if not (math.isfinite(timestep) and timestep > 0):
            raise ValueError(f"timestep must be a finite number > 0 s, got {timestep}")
        model.opt.timestep = timestep
    if integrator is not None:
        key = integrator.lower()
        if key not in INTEGRATORS:
            raise ValueError(
                f"unknown integrator {integrator!r}; valid: {', '.join(sorted(INTEGRATORS))}"
            )
        model.opt.integrator = INTEGRATORS[key]


class RunDiverged(RuntimeError):
    """MuJoCo found the state diverging (NaN, Inf or huge qpos, qvel or qacc) during a run.

    MuJoCo then resets the state to the model's defaults and goes on (auto-reset), so a run
    that went on would record a different simulation from that step on; ``run`` stops instead.
    Attributes: time [s] of the step that diverged, step (its index), warning (MuJoCo's text).
    """

    def __init__(self, time: float, step: int, warning: str, timestep: float) -> None:
        super().__init__(
            f"the simulation diverged at t = {time:.6g} s (step {step}): MuJoCo warned '{warning}' "
            f"and reset the state, so the run stops here (rows up to it are kept); a smaller "
            f"timestep than {timestep:g} s usually cures it"
        )
        self.time, self.step, self.warning = time, step, warning


# MuJoCo's warnings of a diverging state, after which mj_step resets the data (auto-reset).
_DIVERGING = {
    int(mujoco.mjtWarning.mjWARN_BADQPOS): "Nan, Inf or huge value in QPOS at DOF {}",
    int(mujoco.mjtWarning.mjWARN_BADQVEL): "Nan, Inf or huge value in QVEL at DOF {}",
    int(mujoco.mjtWarning.mjWARN_BADQACC): "Nan, Inf or huge value in QACC at DOF {}",
}


#: Signals held while a block of rows is written, so that no signal cuts a row in two.
_WRITE_HELD = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


class OutputError(OSError):
    """Writing a run's output failed (a full disk, a file-size limit, a vanished folder): the
    message names the file, the system's reason and what the file keeps."""

    def __str__(self) -> str:
        return str(self.strerror)


class CsvSink:
    """A CSV file written as a run goes: the header at once, rows buffered and flushed at least
    every ``flush_s`` seconds of wall time and at close, in memory that does not grow with the
    run. Values are written exactly (shortest round-trip repr). Rows on disk survive a crash
    or SIGKILL, up to the last flush; a block of rows is written with signals held, and a write
    that fails (``OutputError``: a full disk, a file-size limit) is cut back to the last whole
    row, so the file never ends in part of a row."""

    def __init__(self, path: str | Path, columns: list[str], flush_s: float = 1.0) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd: int | None = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        self._size = 0  # bytes of whole rows on disk
        self.flush_s = flush_s
        self._pending: list[np.ndarray] = []
        self._last_flush = _time.monotonic()
        self.n_rows = 0  # rows appended
        self.rows_written = 0  # rows on disk
        self.last_written: np.ndarray | None = None  # the last row on disk
        self.last_row: np.ndarray | None = None
        self.error: OutputError | None = None
        _, failure = self._write((",".join(columns) + "\n").encode())
        if failure is not None:
            os.close(self._fd)
            self._fd = None
            raise OutputError(failure.errno, f"cannot write {self.path}: {failure.strerror}")

    def append(self, row: np.ndarray) -> None:
        """Add one row (it is written within ``flush_s`` seconds)."""
        self._pending.append(row)
        self.n_rows += 1
        self.last_row = row
        if _time.monotonic() - self._last_flush >= self.flush_s or len(self._pending) >= 4096:
            self.flush()

    def flush(self) -> None:
        """Write the buffered rows and hand them to the operating system.

        Raises:
          OutputError if they cannot be written (the file keeps the rows written before)."""
        if self.error is not None:
            raise self.error
        if self._pending:
            block = np.vstack(self._pending).tolist()
            text = "".join(",".join(map(repr, r)) + "\n" for r in block).encode()
            # Held: a signal's exception must not fall between the write and its bookkeeping
            # (the rows would be written twice) nor cut a row in two.
            with HeldSignals(_WRITE_HELD):
                kept, failure = self._write(text)
                n = text.count(b"\n", 0, kept)
                self.rows_written += n
                if n:
                    self.last_written = self._pending[n - 1]
                del self._pending[:n]
                if failure is not None:
                    self.error = OutputError(
                        failure.errno,
                        f"cannot write {self.path}: {failure.strerror} (it keeps the header and "
                        f"the {self.rows_written} rows written before, each whole)",
                    )
                    raise self.error from None
        self._last_flush = _time.monotonic()

    def _write(self, data: bytes) -> tuple[int, OSError | None]:
        """Write `data` at the end of the file: (bytes kept, None), or on failure the whole
        rows that landed are kept, the rest cut back: (their bytes, the error)."""
        view, done = memoryview(data), 0
        try:
            while done < len(data):
                done += os.write(self._fd, view[done:])
        except OSError as exc:
            kept = data.rfind(b"\n", 0, done) + 1
            with contextlib.suppress(OSError):
                os.ftruncate(self._fd, self._size + kept)
                os.lseek(self._fd, self._size + kept, os.SEEK_SET)
            self._size += kept
            return kept, exc
        self._size += done
        return done, None

    def close(self) -> None:
        """Flush and close (idempotent). Closes the file even if the flush fails (and raises
        that OutputError)."""
        if self._fd is None:
            return
        try:
            self.flush()
            os.fsync(self._fd)
        except OSError as exc:
            if self.error is None:
                self.error = OutputError(exc.errno, f"cannot write {self.path}: {exc.strerror}")
            raise self.error from None
        finally:
            os.close(self._fd)
            self._fd = None


@dataclass
class Recording:
    """Time series of a run, grown step by step; columns in SI, world frame.

    Attributes:
      columns: ordered column names (with units), e.g. 'time_s', '<body>_force_z_N'.
      rows: recorded rows, one per recorded step (kept in memory unless a sink streams them).
      body_names: intruding bodies, in column order.
      sink: a CsvSink the rows are streamed to instead (then ``rows`` stays empty).
      max_froude: after ``run``, body name -> the largest Froude number v^2/(g L) it reached in
        the medium (``mjrft.app.regime``; above 1 the run left the quasi-static regime).
    """

    columns: list[str]
    body_names: list[str]
    rows: list[np.ndarray] = field(default_factory=list)
    sink: CsvSink | None = None
    max_froude: dict[str, float] = field(default_factory=dict)

    def append(self, row: np.ndarray) -> None:
        """Record one row."""
        if self.sink is not None:
            self.sink.append(row)
        else:
            self.rows.append(row)

    @property
    def n_rows(self) -> int:
        """Rows recorded so far."""
        return self.sink.n_rows if self.sink is not None else len(self.rows)

    @property
    def last_row(self) -> np.ndarray | None:
        """The most recent row, or None."""
        if self.sink is not None:
            return self.sink.last_row
        return self.rows[-1] if self.rows else None

    @classmethod
    def from_csv(cls, path: str | Path, body_names: list[str], max_rows: int = 20_000) -> Recording:
        """A recording read back from a CSV written by CsvSink (``from_file``)."""
        return cls.from_file(path, body_names, max_rows)

    @classmethod
    def from_file(
        cls, path: str | Path, body_names: list[str], max_rows: int = 20_000
    ) -> Recording:
        """A recording read back from a run's table (a CSV written by CsvSink, or the Parquet
        file of ``write_parquet``), every k-th row (and the last) so that at most ``max_rows``
        are held: enough for plots, bounded for any run length. Read with pyarrow (a rerun
        dependency), values exactly as written (nan and inf included)."""
        columns, table = read_table(path)
        n = len(table)
        k = max(1, -(-n // max_rows))
        keep = np.unique(np.append(np.arange(0, n, k), n - 1)) if n else np.arange(0)
        return cls(columns, body_names, list(table[keep]))

    def array(self) -> np.ndarray:
        """(n_rows, n_columns) array of everything recorded so far."""
        if not self.rows:
            return np.zeros((0, len(self.columns)))
        return np.vstack(self.rows)

    def column(self, name: str) -> np.ndarray:
        """One recorded column by name."""
        return self.array()[:, self.columns.index(name)]


def ground_balance(fld: GranularField, data: mujoco.MjData) -> dict[str, float] | None:
    """The deforming ground's volume account of `data` since it was reset, or None if the
    ground does not deform: ``excavated_m3`` (volume cut by the intruders), ``lost_m3`` (cut
    volume that found no place on the grid to go, the engine's ``unplaced`` counter: cut at the
    edge of ``mjrft:region``, whose outer ring of vertices never changes, or under a footprint
    that covers the whole region; it is gone from the ground), ``lost_fraction`` (lost_m3 /
    excavated_m3, 0 when nothing was cut), ``edge_vertices`` (footprint vertices on that
    outer ring, summed over the updates: where an intruder met ground that cannot deform), and
    the relaxation's account: ``updates``, ``unrelaxed_updates`` (those whose relaxation spent
    its work budget before every slope reached the angle of repose; the next update goes on)
    and ``relaxed`` (whether the last update left every slope at repose); and the grid:
    ``cell_m`` [m] and ``grid`` (rows, columns of vertices)."""
    if not fld.deforms:
        return None
    ground = fld.soil(data)
    counters = ground.counters
    cut, lost = counters["excavated"], counters["unplaced"]
    return {
        "excavated_m3": cut,
        "lost_m3": lost,
        "lost_fraction": lost / cut if cut > 0 else 0.0,
        "edge_vertices": int(counters["edge"]),
        "updates": int(counters["updates"]),
        "unrelaxed_updates": int(counters["unrelaxed"]),
        "relaxed": ground.relaxed,
        "cell_m": ground.cell,
        "grid": [int(ground.y.size), int(ground.x.size)],
    }


#: Table formats of ``mjrft run`` (``--table-format``).
TABLE_FORMATS = ("csv", "parquet")


def read_table(path: str | Path) -> tuple[list[str], np.ndarray]:
    """(column names, (n_rows, n_columns) float64 array) of a run's table: a CSV written by
    CsvSink or a Parquet file (by its suffix)."""
    import pyarrow.csv
    import pyarrow.parquet

    path = Path(path)
    if path.suffix == ".parquet":
        table = pyarrow.parquet.read_table(path)
    else:
        # No null values: CsvSink writes nan as 'nan', which must stay NaN.
        convert = pyarrow.csv.ConvertOptions(null_values=[], strings_can_be_null=False)
        table = pyarrow.csv.read_csv(path, convert_options=convert)
    columns = list(table.column_names)
    if table.num_rows == 0:
        return columns, np.zeros((0, len(columns)))
    return columns, np.column_stack([table.column(c).to_numpy() for c in columns]).astype(float)


def write_parquet(csv: str | Path, path: str | Path) -> Path:
    """Write the run's CSV table `csv` as a Parquet file `path` (float64 columns, zstd),
    atomically; the CSV is left in place."""
    import pyarrow
    import pyarrow.parquet

    from mjrft.app.report import atomic_path

    columns, values = read_table(csv)
    table = pyarrow.table({c: values[:, i] for i, c in enumerate(columns)})
    with atomic_path(path) as tmp:
        pyarrow.parquet.write_table(table, tmp, compression="zstd")
    return Path(path)


#: Rows a run's figures draw: each line is a min/max envelope over ``report.LINE_BINS`` = 1000
#: runs of rows, two points per run.
FIGURE_ROWS = 2000


def figure_record_every(n_steps: int) -> int:
    """The recording period [steps] that gives a run of `n_steps` steps about FIGURE_ROWS rows
    (at least every step): what its figures draw, and no more."""
    return max(1, n_steps // FIGURE_ROWS)


def _sensor_columns(model: mujoco.MjModel) -> list[str]:
    cols = []
    for s in range(model.nsensor):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, s) or f"sensor{s}"
        dim = int(model.sensor_dim[s])
        cols += [f"sensor_{name}"] if dim == 1 else [f"sensor_{name}_{i}" for i in range(dim)]
    return cols


def new_recording(model: mujoco.MjModel, fld: GranularField) -> Recording:
    """Empty recording with the columns of `mjrft run`'s timeseries.csv."""
    cols = ["time_s"]
    names = [be.name for be in fld.bodies]
    for n in names:
        cols += [f"{n}_com_{a}_m" for a in "xyz"]
        cols += [f"{n}_vel_{a}_m_per_s" for a in "xyz"]
        cols += [f"{n}_rft_force_{a}_N" for a in "xyz"]
        cols += [f"{n}_rft_torque_{a}_Nm" for a in "xyz"]
    return Recording(cols + _sensor_columns(model), names)


def record_row(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    fld: GranularField,
    wrench: np.ndarray | None = None,
    time: float | None = None,
) -> np.ndarray:
    """One row: time, per intruding body CoM position, CoM velocity, RFT wrench; all sensors.

    Evaluated from data's derived quantities (xipos, cvel, sensordata), which must all describe
    one state: after mj_forward, or after an Euler/implicit mj_step, which leaves them at the
    pre-step state (pass that state's `time` then). `wrench` (nbody, 6) is the field's wrench at
    that state if already known.
    """
    w = fld.wrench(data) if wrench is None else wrench
    ids = fld.body_ids
    per_body = np.empty((len(ids), 12))  # column order: CoM, its velocity, wrench
    per_body[:, :3] = data.xipos[ids]
    com_velocity(model, data, ids, per_body[:, 3:6])
    per_body[:, 6:] = w[ids]
    t = data.time if time is None else time
    return np.concatenate([[t], per_body.ravel(), data.sensordata])


def _diverging_count(warnings: np.ndarray) -> int:
    return sum(int(warnings[i]) for i in _DIVERGING)


def _divergence(data: mujoco.MjData, step: int, time: float, timestep: float) -> RunDiverged:
    """The RunDiverged of the step that made MuJoCo warn (the last diverging warning)."""
    latest = max(_DIVERGING, key=lambda i: (int(data.warning[i].number) > 0, i))
    text = _DIVERGING[latest].format(int(data.warning[latest].lastinfo))
    return RunDiverged(time, step, text, timestep)


def run(
    model: mujoco.MjModel,
    duration: float,
    *,
    fld: GranularField | None = None,
    record_every: int = 1,
    progress: Callable[[float], None] | None = None,
    recording: Recording | None = None,
    observer: Callable[[int, float, mujoco.MjData], None] | None = None,
    observe_every: int = 1,
    keyframe: int | None = 0,
    ctrl: Controller | None = None,
    data: mujoco.MjData | None = None,
) -> tuple[mujoco.MjData, Recording]:
    """Simulate `duration` seconds from a keyframe; the engine plugin the model carries adds the
    field's forces inside every step.

    Args:
      model: a model from ``load_model`` (``mjrft.load_model``: it carries the engine plugin),
        timestep/integrator already configured.
      duration: simulated time [s], at least the model's timestep; the run takes
        ``step_count(duration, timestep)`` steps.
      fld: the field (built from the model if None).
      record_every: record one row every this many steps (the initial state is always recorded).
      progress: called with the fraction done, about 100 times over the run.
      recording: an existing Recording to append to (it keeps what was recorded if this raises;
        give it a CsvSink to stream the rows to a file instead of memory).
      observer: called as ``observer(step, time, data)`` every ``observe_every`` steps and at the
        final state, where data's derived quantities (kinematics, ``cvel``, sensors) describe the
        state after ``step`` steps, at MuJoCo time ``time`` [s] (for Euler/implicit: right after
        the step that integrated from it, so ``data.qpos`` is already the next state; for RK4
        after an ``mj_forward`` at it). The field's wrench of that state acted in the step.
      observe_every: observer period in steps (>= 1).
      keyframe: index of the keyframe to start from; the default 0 starts from keyframe 0 if
        the model has one, else from qpos0; None always starts from qpos0.
      ctrl: a controller ``ctrl(t, data)`` called before every step with the MuJoCo time t [s]:
        it returns the (nu,) actuator controls, or None after writing ``data.ctrl`` itself.
      data: the MjData to step (its state is first reset to the keyframe); a new one if None.
        Pass one to read its state (e.g. the field's counters) even when the run raises.
    Returns:
      (final MjData, Recording).
    Raises:
      ValueError if the duration is not at least one timestep (``step_count``).
      RunDiverged if MuJoCo warns of a diverging state (and resets it) in a step: the rows
      before that step are recorded, none after.
    """
    n_steps = step_count(duration, model.opt.timestep)
    if record_every < 1:
        raise ValueError(f"record_every must be >= 1, got {record_every}")
    if observe_every < 1:
        raise ValueError(f"observe_every must be >= 1, got {observe_every}")
    fld = fld or GranularField(model)
    rec = recording or new_recording(model, fld)
    data = reset_data(model, keyframe, data)
    apply_ctrl = checked_controller(model, ctrl)
    tick = max(1, n_steps // 100)
    # mj_step with Euler or the implicit integrators leaves kinematics, sensors and the field's
    # wrench at the pre-step state, so that state is recorded after the step at no extra cost.
    # RK4 leaves its last stage there, so it needs a forward pass at the recorded state.
    rk4 = model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    warnings = data.warning.number  # a live view: MuJoCo counts each warning here
    diverged = _diverging_count(warnings)
    watch = FroudeWatch(model, fld)
    rec.max_froude = watch.max_froude
    wrench = fld.wrench_of(data)  # a live view of this MjData's last pass
    for i in range(n_steps):
        record = i % record_every == 0
        observe = observer is not None and i % observe_every == 0
        t_prev = data.time
        if (record or observe) and rk4:
            mujoco.mj_forward(model, data)
            if record:
                rec.append(record_row(model, data, fld, wrench))
                watch.observe(t_prev, data, wrench)
            if observe:
                observer(i, t_prev, data)
        if apply_ctrl is not None:
            apply_ctrl(data)
        mujoco.mj_step(model, data)
        if _diverging_count(warnings) != diverged:
            raise _divergence(data, i, t_prev, model.opt.timestep)
        if not rk4:
            watch.check(i, t_prev, data, wrench)
        if record and not rk4:
            rec.append(record_row(model, data, fld, wrench, time=t_prev))
        if observe and not rk4:
            observer(i, t_prev, data)
        if progress is not None and ((i + 1) % tick == 0 or i + 1 == n_steps):
            progress((i + 1) / n_steps)
    mujoco.mj_forward(model, data)
    rec.append(record_row(model, data, fld, wrench))
    if observer is not None:
        observer(n_steps, data.time, data)
    return data, rec


def step_count(duration: float, timestep: float) -> int:
    """The number of steps of a `duration` [s] run at `timestep` [s]: round(duration / timestep),
    so the run ends within half a step of `duration`.

    Raises:
      ValueError if the duration is not a finite time > 0 or is shorter than one timestep (one
      step would end the run a whole timestep past it; a relative 1e-9 forgives rounding).
    """
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a finite number > 0 s, got {duration}")
    if duration < timestep * (1.0 - 1e-9):
        raise ValueError(
            f"duration {duration:g} s is shorter than the timestep {timestep:g} s: one step would "
            f"end the run at t = {timestep:g} s; give a duration of at least one timestep or a "
            "smaller timestep"
        )
    return round(duration / timestep)


def reset_data(
    model: mujoco.MjModel, keyframe: int | None = 0, data: mujoco.MjData | None = None
) -> mujoco.MjData:
    """A new MjData (or `data`, reset) at keyframe `keyframe` (0: keyframe 0 if the model has
    keyframes, else qpos0; None: qpos0)."""
    if data is None:
        data = mujoco.MjData(model)
    else:
        mujoco.mj_resetData(model, data)
    if keyframe is None or (keyframe == 0 and model.nkey == 0):
        return data
    if not 0 <= keyframe < model.nkey:
        raise ValueError(
            f"keyframe {keyframe} does not exist: the model has {model.nkey} keyframe(s)"
            + (f", 0-{model.nkey - 1}" if model.nkey else "")
        )
    mujoco.mj_resetDataKeyframe(model, data, keyframe)
    return data


def checked_controller(
    model: mujoco.MjModel, ctrl: Controller | None
) -> Callable[[mujoco.MjData], None] | None:
    """A per-step function writing ctrl(t, data)'s controls into data, checked, or None."""
    if ctrl is None:
        return None
    if not callable(ctrl):
        raise TypeError(f"ctrl must be a callable ctrl(t, data), got {type(ctrl).__name__}")
    name = getattr(ctrl, "__qualname__", repr(ctrl))

    def apply(data: mujoco.MjData) -> None:
        u = ctrl(data.time, data)
        if u is None:
            u = data.ctrl
        else:
            u = np.asarray(u, dtype=np.float64)
            if u.shape != (model.nu,) and not (model.nu == 1 and u.shape == ()):
                raise ValueError(
                    f"controller {name} returned shape {u.shape} at t = {data.time:g} s; the "
                    f"model has nu = {model.nu} actuators, expected ({model.nu},) or None"
                )
            data.ctrl[:] = u
        if not np.all(np.isfinite(u)):
            i = int(np.flatnonzero(~np.isfinite(np.atleast_1d(u)))[0])
            act = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"#{i}"
            raise ValueError(
                f"controller {name} gave a non-finite control {np.atleast_1d(u)[i]} for "
                f"actuator {act} at t = {data.time:g} s"
            )

    return apply
