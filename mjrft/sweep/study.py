"""A study: one MJCF model, the parameters to vary and where each goes, the values it takes,
and the metrics to record per run (a TOML file; the format is docs/sweeps.md).

``Study.load(path)`` reads and checks everything it can before any run: the model compiles,
every path exists and every value has the right type (compilation errors that depend on a
value are a run's outcome, recorded in the results table); ``Study.runs()`` lists the runs, each
identified by a hash of its parameter values.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from mjrft.sweep import callables, expressions, paths
from mjrft.sweep.errors import StudyError
from mjrft.sweep.metrics import MetricSpec, check_metric, parse_metric
from mjrft.sweep.paths import RunConfig, Target

SECTIONS = {
    "study": ("name", "model", "duration", "keyframe", "sampling", "samples", "seed",
              "timeseries", "record_every", "controller", "description"),
    "parameters": (),
    "set": (),
    "metrics": (),
}  # fmt: skip
PARAMETER_KEYS = ("path", "values", "range", "low", "high", "log", "integer")
SAMPLINGS = ("grid", "random")
#: The most runs a study may have, refused before its runs are listed or checked. Listing costs
#: about 0.4 kB and 10 us per run and checking every run's values against the model 0.3 ms (the
#: sphere drop; more for larger models), so at the cap a study takes ~0.4 GB and 5 minutes or
#: more before its first run, and its runs (each a model compilation and a simulation, 10 ms to
#: minutes) take hours to days even on many cores: a larger count is almost always a range whose
#: step is far too fine.
MAX_RUNS = 1_000_000
#: Columns of the results table besides the parameters and metrics (``results.columns``).
RESERVED = ("run_id", "max_froude", "quasi_static", "status", "error", "warnings", "wall_s",
            "seed", "versions")  # fmt: skip
#: Significant digits ranges are rounded to (so a step of 0.1 gives 0.3, not 0.30000000000000004).
RANGE_DIGITS = 15


@dataclass(frozen=True)
class Parameter:
    """A varied parameter: its column name, the targets its value goes to (none: it only feeds
    ``[set]`` expressions), and its values (grid) or the interval it is drawn from (random)."""

    name: str
    targets: tuple[Target, ...]
    values: tuple[Any, ...] | None
    low: float | None = None
    high: float | None = None
    log: bool = False
    integer: bool = False

    def draw(self, rng: np.random.Generator) -> Any:
        """One random value (random sampling)."""
        if self.values is not None:
            return self.values[int(rng.integers(len(self.values)))]
        if self.integer:
            return int(rng.integers(int(self.low), int(self.high) + 1))
        if self.log:
            return float(math.exp(rng.uniform(math.log(self.low), math.log(self.high))))
        return float(rng.uniform(self.low, self.high))


@dataclass(frozen=True)
class RunSpec:
    """One run: its position in the study, id (hash of the parameter values), parameter values
    (name -> value) and seed."""

    index: int
    run_id: str
    values: dict[str, Any]
    seed: int


def run_id(values: dict[str, Any]) -> str:
    """Stable id of a run: 16 hex digits of the SHA-256 of its parameter names and values."""
    text = json.dumps([[k, v] for k, v in values.items()], separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Study:
    """A checked study description (``Study.load``). Times in s."""

    name: str
    model: Path
    model_arg: str
    duration: float
    keyframe: int | str | None
    parameters: tuple[Parameter, ...]
    settings: tuple[tuple[Target, Any], ...]
    metrics: tuple[MetricSpec, ...]
    sampling: str = "grid"
    samples: int | None = None
    seed: int = 0
    timeseries: bool = False
    record_every: int = 1
    controller: str | None = None
    description: str = ""
    text: str = ""
    source: Path | None = None

    @classmethod
    def load(cls, path: str | Path) -> Study:
        """Read and check a study file (TOML)."""
        path = Path(path)
        try:
            text = path.read_text()
        except OSError as exc:
            raise StudyError(f"cannot read study {str(path)!r}: {exc.strerror}") from None
        return cls.from_toml(text, base=path.parent, name=path.stem, source=path)

    @classmethod
    def from_toml(
        cls, text: str, base: str | Path = ".", name: str = "study", source: Path | None = None
    ) -> Study:
        """A study from TOML text; relative files (model, ``file.py:function``) are found from
        `base`."""
        where = str(source) if source else "the study"
        try:
            table = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise StudyError(f"{where} is not valid TOML: {exc}") from None
        study = _build(table, Path(base), name, where)
        study = _replace(study, text=text, source=source)
        _validate(study, where)
        return study

    def runs(self) -> list[RunSpec]:
        """The runs, in study order (grid: the last parameter varies fastest); a random draw
        that repeats an earlier run is left out."""
        names = [p.name for p in self.parameters]
        if self.sampling == "grid":
            combos = itertools.product(*(p.values for p in self.parameters))
        else:
            rng = np.random.default_rng(self.seed)
            combos = ([p.draw(rng) for p in self.parameters] for _ in range(self.samples))
        out, seen = [], set()
        for combo in combos:
            values = dict(zip(names, combo, strict=True))
            rid = run_id(values)
            if rid not in seen:
                seen.add(rid)
                out.append(RunSpec(len(out), rid, values, self._seed(rid)))
        return out

    def run(self, values: dict[str, Any]) -> RunSpec:
        """The run of one set of parameter values (name -> value; every parameter, no other
        name), on the grid or not: its id and seed as ``runs`` would give them. NumPy scalars
        become Python numbers. Raises StudyError naming a missing or unknown parameter."""
        names = [p.name for p in self.parameters]
        missing = [n for n in names if n not in values]
        unknown = [k for k in values if k not in names]
        if missing or unknown:
            what = f"missing {', '.join(map(repr, missing))}" if missing else ""
            what += ("; " if missing and unknown else "") + (
                f"unknown {', '.join(map(repr, unknown))}" if unknown else ""
            )
            raise StudyError(
                f"study {self.name!r}: parameter values {what} (parameters: {', '.join(names)})"
            )
        plain = {n: _plain(values[n]) for n in names}
        rid = run_id(plain)
        return RunSpec(0, rid, plain, self._seed(rid))

    def _seed(self, rid: str) -> int:
        digest = hashlib.sha256(f"{self.seed}/{rid}".encode()).digest()
        return int.from_bytes(digest[:4], "big")

    def configure(self, spec: mujoco.MjSpec, run: RunSpec) -> RunConfig:
        """Write run's settings and parameter values into `spec` (the ``[set]`` entries first,
        then the parameters); returns the rest of its configuration."""
        config = RunConfig()
        for target, value in self.settings:
            if isinstance(value, dict):
                value = _derived(value["expr"], run.values, f"set.{target.path!r}")
            _apply(spec, config, target, value, f"set.{target.path!r}")
        for p in self.parameters:
            for target in p.targets:
                _apply(spec, config, target, run.values[p.name], f"parameters.{p.name}")
        return config

    def record(self) -> dict[str, Any]:
        """What identifies the study's results (``study.json`` in a results folder): model and
        its files' hashes, duration, runs, targets, metrics, code files' hashes."""
        from mjrft.app.metadata import file_sha256, model_files

        files = model_files(self.model)
        code = [s.split(":")[0] for s in self._functions() if s.split(":")[0].endswith(".py")]
        return {
            "model": self.model_arg,
            "model_files_sha256": {Path(k).name: v for k, v in files.items()},
            "duration_s": self.duration,
            "keyframe": self.keyframe,
            "sampling": self.sampling,
            "samples": self.samples,
            "seed": self.seed,
            "parameters": {
                p.name: {
                    "path": [t.path for t in p.targets],
                    "values": p.values,
                    "low": p.low,
                    "high": p.high,
                    "log": p.log,
                    "integer": p.integer,
                }
                for p in self.parameters
            },
            "set": {t.path: v for t, v in self.settings},
            "metrics": {m.name: {"kind": m.kind, **m.options} for m in self.metrics},
            "controller": self.controller,
            "code_sha256": {Path(f).name: file_sha256(f) for f in code},
            "timeseries": self.timeseries,
            "record_every": self.record_every,
        }

    def _functions(self) -> list[str]:
        fns = [m.options["function"] for m in self.metrics if m.kind == "custom"]
        return fns + ([self.controller] if self.controller else [])


def _plain(value: Any) -> Any:
    """A value as TOML would give it: NumPy scalars and arrays (as Tune and Optuna hand them
    out) become Python numbers and lists."""
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def _replace(study: Study, **changes: Any) -> Study:
    import dataclasses

    return dataclasses.replace(study, **changes)


def _derived(expr: str, values: dict[str, Any], where: str) -> float:
    return expressions.evaluate(expr, values, where)


def _apply(spec, config: RunConfig, target: Target, value: Any, where: str) -> None:
    try:
        paths.apply(spec, config, target, value)
    except StudyError as exc:
        raise StudyError(f"{where}: {exc}") from None


# ---------------------------------------------------------------------------- reading


def _keys(table: Any, valid: tuple[str, ...], where: str) -> dict:
    if not isinstance(table, dict):
        raise StudyError(f"{where}: expected a table, got {table!r}")
    extra = [k for k in table if k not in valid]
    if extra:
        raise StudyError(f"{where}: unknown key {extra[0]!r} (valid: {', '.join(valid)})")
    return table


def _build(table: dict, base: Path, default_name: str, where: str) -> Study:
    from mjrft.app.simulate import resolve_model

    _keys(table, tuple(SECTIONS), where)
    head = _keys(table.get("study", {}), SECTIONS["study"], f"{where} [study]")
    for key in ("model", "duration"):
        if key not in head:
            raise StudyError(f"{where} [study]: {key} is required")
    model_arg = head["model"]
    if not isinstance(model_arg, str):
        raise StudyError(f"{where} [study]: model = {model_arg!r} is not a path or a model name")
    local = base / model_arg
    try:
        model = resolve_model(local if local.exists() else model_arg)
    except ValueError as exc:
        raise StudyError(f"{where} [study]: {exc}") from None
    duration = head["duration"]
    if not (isinstance(duration, int | float) and not isinstance(duration, bool)
            and math.isfinite(duration) and duration > 0):  # fmt: skip
        raise StudyError(f"{where} [study]: duration = {duration!r} is not a time > 0 [s]")
    options = _study_options(head, base, where)
    sections = {}
    for key in ("parameters", "set", "metrics"):
        sections[key] = table.get(key, {})
        if not isinstance(sections[key], dict):
            raise StudyError(f"{where}: [{key}] must be a table")
    params = tuple(
        _parameter(name, spec, options["sampling"], f"{where} [parameters.{name}]")
        for name, spec in sections["parameters"].items()
    )
    settings = tuple(
        (_target(path, f"{where} [set]"), _setting(value, f"{where} [set] {path!r}"))
        for path, value in sections["set"].items()
    )
    metrics = tuple(
        _metric(name, spec, base, f"{where} [metrics.{name}]")
        for name, spec in sections["metrics"].items()
    )
    if not metrics:
        raise StudyError(f'{where}: no [metrics]; add e.g. [metrics.depth_m] kind = "final_depth"')
    _check_size(params, options, where)
    return Study(
        name=head.get("name", default_name), model=model, model_arg=model_arg,
        duration=float(duration), parameters=params, settings=settings, metrics=metrics,
        **options,
    )  # fmt: skip


def _check_size(params: tuple[Parameter, ...], options: dict[str, Any], where: str) -> None:
    """Refuse a study of more than MAX_RUNS runs, naming the count, before its runs exist."""
    if options["sampling"] == "random":
        count, how = options["samples"], f"samples = {options['samples']:,}"
    else:
        count = math.prod(len(p.values) for p in params)
        how = "the grid of " + " x ".join(f"{p.name} {len(p.values):,}" for p in params)
    if count > MAX_RUNS:
        raise StudyError(
            f"{where}: the study has {count:,} runs ({how}), more than the {MAX_RUNS:,} a study "
            "may have; use fewer values (a coarser range step or num) or split it into studies"
        )


def _study_options(head: dict, base: Path, where: str) -> dict[str, Any]:
    sampling = head.get("sampling", "grid")
    if sampling not in SAMPLINGS:
        raise StudyError(f"{where} [study]: sampling = {sampling!r}; valid: {', '.join(SAMPLINGS)}")
    samples = head.get("samples")
    if sampling == "random" and not (isinstance(samples, int) and samples > 0):
        raise StudyError(f"{where} [study]: random sampling needs samples = N (an integer > 0)")
    ints = {"seed": head.get("seed", 0), "record_every": head.get("record_every", 1)}
    for key, v in ints.items():
        if not isinstance(v, int) or isinstance(v, bool) or v < (key == "record_every"):
            raise StudyError(f"{where} [study]: {key} = {v!r} is not a valid integer")
    keyframe = head.get("keyframe", 0)
    if keyframe == "none":
        keyframe = None
    elif isinstance(keyframe, bool) or not isinstance(keyframe, int | str):
        raise StudyError(f"{where} [study]: keyframe = {keyframe!r}: an index, a name or 'none'")
    controller = head.get("controller")
    if controller is not None:
        controller = callables.resolve(str(controller), base, f"{where} [study] controller")
    if not isinstance(head.get("timeseries", False), bool):
        raise StudyError(f"{where} [study]: timeseries = {head['timeseries']!r}: true or false")
    return {
        "keyframe": keyframe, "sampling": sampling, "samples": samples,
        "timeseries": head.get("timeseries", False), "controller": controller,
        "description": str(head.get("description", "")), **ints,
    }  # fmt: skip


def _target(path: Any, where: str) -> Target:
    try:
        return paths.parse(path)
    except StudyError as exc:
        raise StudyError(f"{where}: {exc}") from None


def _setting(value: Any, where: str) -> Any:
    if isinstance(value, dict):
        _keys(value, ("expr",), where)
        if not isinstance(value.get("expr"), str):
            raise StudyError(f'{where}: expected {{ expr = "..." }}')
        expressions.parse(value["expr"], where)
    return value


def _parameter(name: str, spec: Any, sampling: str, where: str) -> Parameter:
    if not name.isidentifier():
        raise StudyError(f"{where}: a parameter's name is a column name: letters, digits, _")
    spec = _keys(spec, PARAMETER_KEYS, where)
    raw = spec.get("path", [])
    targets = tuple(_target(p, where) for p in ([raw] if isinstance(raw, str) else raw))
    given = [k for k in ("values", "range", "low") if k in spec]
    if len(given) != 1 or ("low" in spec) != ("high" in spec):
        raise StudyError(f"{where}: give one of values = [...], range = {{...}} or low and high")
    if "low" in spec:
        if sampling != "random":
            raise StudyError(f"{where}: low/high are for random sampling; use values or range")
        lo, hi = spec["low"], spec["high"]
        if not (_real(lo) and _real(hi) and lo < hi and (lo > 0 or not spec.get("log"))):
            raise StudyError(f"{where}: low = {lo!r}, high = {hi!r}: need low < high (> 0 if log)")
        return Parameter(name, targets, None, float(lo), float(hi),
                         bool(spec.get("log")), bool(spec.get("integer")))  # fmt: skip
    values = _range(spec["range"], where) if "range" in spec else spec["values"]
    if not isinstance(values, list) or not values:
        raise StudyError(f"{where}: values must be a non-empty list, got {values!r}")
    return Parameter(name, targets, tuple(values))


def _real(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _range(spec: Any, where: str) -> list[Any]:
    """start, start + step, ... up to stop (included when on the grid), or num values from start
    to stop, both included."""
    r = _keys(spec, ("start", "stop", "step", "num"), f"{where} range")
    if not (_real(r.get("start")) and _real(r.get("stop")) and (("step" in r) != ("num" in r))):
        raise StudyError(f"{where}: range = {{ start, stop, and step or num }}, got {spec!r}")
    start, stop = r["start"], r["stop"]
    if "num" in r:
        if not (isinstance(r["num"], int) and r["num"] >= 1):
            raise StudyError(f"{where}: range num = {r['num']!r} is not an integer >= 1")
        _check_count(r["num"], where)
        raw = np.linspace(start, stop, r["num"]).tolist()
    else:
        step = r["step"]
        if not (_real(step) and step != 0 and (stop - start) / step >= 0):
            raise StudyError(f"{where}: range step = {step!r} does not lead from start to stop")
        steps = (stop - start) / step * (1 + 1e-12) + 1e-9
        _check_count(steps + 1, where)
        n = math.floor(steps) + 1
        if all(isinstance(v, int) for v in (start, stop, step)):
            return [start + k * step for k in range(n)]
        raw = [start + k * step for k in range(n)]
    return [float(f"{v:.{RANGE_DIGITS}g}") for v in raw]


def _check_count(n: float, where: str) -> None:
    """Refuse a range of more than MAX_RUNS values before listing them."""
    if n > MAX_RUNS:
        raise StudyError(
            f"{where}: the range has {n:,.0f} values, more than the {MAX_RUNS:,} runs a study may "
            "have; use a coarser step or a smaller num"
        )


def _metric(name: str, spec: Any, base: Path, where: str) -> MetricSpec:
    if not name.isidentifier():
        raise StudyError(f"{where}: a metric's name is a column name: letters, digits, _")
    m = parse_metric(name, spec, where)
    if m.kind == "custom":
        m.options["function"] = callables.resolve(m.options["function"], base, where)
        callables.load(m.options["function"], where)
    return m


# ---------------------------------------------------------------------------- checking


def _validate(study: Study, where: str) -> None:
    """Check the study against its model: every run's values go where they say (without
    compiling each run), targets do not conflict, and the metrics' names exist."""
    names = [p.name for p in study.parameters]
    clash = set(names) & {m.name for m in study.metrics}
    if clash:
        raise StudyError(f"{where}: {sorted(clash)[0]!r} is both a parameter and a metric")
    taken = sorted((set(names) | {m.name for m in study.metrics}) & set(RESERVED))
    if taken:
        raise StudyError(
            f"{where}: {taken[0]!r} names a column of the results table; parameters and metrics "
            f"take other names than {', '.join(RESERVED)}"
        )
    paths.check_exclusive(
        [(f"[set] {t.path!r}", t) for t, _ in study.settings]
        + [(f"parameter {p.name!r}", t) for p in study.parameters for t in p.targets]
    )
    for target, value in study.settings:
        if isinstance(value, dict):
            unknown = expressions.names(value["expr"], where) - set(names)
            if unknown:
                raise StudyError(
                    f"{where} [set] {target.path!r}: unknown name {sorted(unknown)[0]!r} in "
                    f"{value['expr']!r} (parameters: {', '.join(names) or 'none'}; pi, e, tau)"
                )
    runs = study.runs()
    if not runs:
        raise StudyError(f"{where}: the study has no runs")
    first = None
    for run in runs:  # each run's spec is dropped once checked: memory stays one spec's
        spec = _spec(study)
        config = study.configure(spec, run)
        first = first or (spec, config)
    _check_config(study, first[1], where)
    model = _checking_model(study, first[0], where)
    _check_names(study, model, where)


def _spec(study: Study) -> mujoco.MjSpec:
    try:
        return mujoco.MjSpec.from_file(str(study.model))
    except ValueError as exc:
        raise StudyError(f"cannot load MJCF model {str(study.model)!r}: {exc}") from None


def _check_config(study: Study, config: RunConfig, where: str) -> None:
    for actuator, schedule in config.schedules.items():
        if "value" in schedule and len(schedule) > 1:
            raise StudyError(
                f"{where}: ctrl.{actuator} is given both as a constant and as a sine "
                f"(ctrl.{actuator}.{'|'.join(paths.SINE_FIELDS)}); use one"
            )
    if config.schedules and study.controller:
        raise StudyError(f"{where}: both a controller and ctrl.* schedules drive the actuators")
    if config.controller_kwargs and not study.controller:
        raise StudyError(f"{where}: controller.* values are given but [study] has no controller")
    if "n_triangles" in config.scene and "tolerance" in config.scene:
        raise StudyError(f"{where}: both triangles and tolerance are set; use one")
    if study.controller:
        callables.load(study.controller, f"{where} [study] controller")


def _checking_model(study: Study, spec: mujoco.MjSpec, where: str) -> mujoco.MjModel:
    """The model of the first run with the engine plugin (its MJCF scene), or of the model as
    it is if that run's values do not compile (that is the run's outcome, not an error of the
    study)."""
    from mjrft.field.plugin import load_model

    try:
        spec.compile()
    except ValueError:
        spec = _spec(study)
        try:
            spec.compile()
        except ValueError as exc:
            raise StudyError(f"cannot compile MJCF model {str(study.model)!r}: {exc}") from None
    try:
        return load_model(spec)
    except ValueError as exc:
        raise StudyError(f"{where}: the model's scene is invalid: {exc}") from None


def _check_names(study: Study, model: mujoco.MjModel, where: str) -> None:
    from mjrft.field.granular_field import GranularField

    key = mujoco.mjtObj.mjOBJ_KEY
    if isinstance(study.keyframe, str) and mujoco.mj_name2id(model, key, study.keyframe) < 0:
        raise StudyError(f"{where} [study]: the model has no keyframe named {study.keyframe!r}")
    if isinstance(study.keyframe, int) and study.keyframe and not study.keyframe < model.nkey:
        raise StudyError(f"{where} [study]: keyframe {study.keyframe}: the model has {model.nkey}")
    intruders = [be.name for be in GranularField(model).bodies]
    for m in study.metrics:
        if m.kind != "custom":
            check_metric(m, model, intruders, study.duration, f"{where} [metrics.{m.name}]")
