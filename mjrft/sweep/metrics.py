"""The metrics a study records per run, and the probe that measures them while it runs.

Every metric is computed from the states ``mjrft.app.simulate.run`` observes: the initial state,
the state before every step and the final state, each with the field's per-body wrench of that
state (the one that acted in the step) and MuJoCo's actuator forces and sensors. A time average
or integral weights each state by the timestep (the final state by 0); ``after`` [s] restricts
it to the states at t >= after. World frame, SI units; forces are the RFT force on a body, torques
the RFT torque about its centre of mass (CoM).
"""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from mjrft.core.surface import Surface
from mjrft.sweep.errors import StudyError

FORCE_COMPONENTS = ("x", "y", "z", "xy", "norm")
MOTION_COMPONENTS = ("x", "y", "z", "xy", "xyz")
SENSOR_STATS = ("mean", "min", "max", "final")
_BODY, _WINDOW = ("body",), ("component", "after")
#: kind -> (required keys, optional keys, unit, what it is).
KINDS: dict[str, tuple[tuple[str, ...], tuple[str, ...], str, str]] = {
    "final_depth": ((), ("body", "site"), "m", "depth of a body's CoM or a site at the end"),
    "mean_force": (_BODY, _WINDOW, "N", "time mean of the RFT force on a body"),
    "peak_force": (_BODY, _WINDOW, "N", "largest |RFT force| on a body"),
    "mean_torque": (_BODY, _WINDOW, "N m", "time mean of the RFT torque about a body's CoM"),
    "peak_torque": (_BODY, _WINDOW, "N m", "largest |RFT torque| about a body's CoM"),
    "rft_work": (_BODY, ("after",), "J", "work a body does on the medium"),
    "actuator_work": ((), ("actuator", "absolute", "after"), "J", "work of an actuator or all"),
    "distance": (_BODY, _WINDOW, "m", "displacement of a body's CoM"),
    "speed": (_BODY, _WINDOW, "m/s", "mean velocity of a body's CoM"),
    "cost_of_transport": (_BODY, ("after",), "1", "actuator |work| / (weight x distance)"),
    "sensor": (("sensor", "stat"), ("index", "after"), "sensor's", "a sensor's mean/min/max/final"),
    "custom": (("function",), (), "yours", "a Python function of the run's outcome"),
}


@dataclass
class MetricSpec:
    """One metric of a study: its column name, kind (a KINDS key) and options."""

    name: str
    kind: str
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def after(self) -> float:
        """Start [s] of the time window the metric looks at."""
        return float(self.options.get("after", 0.0))


def parse_metric(name: str, table: Any, where: str) -> MetricSpec:
    """A MetricSpec from its TOML table, with keys and option values checked (names of bodies,
    sensors and actuators are checked against the model by ``check_metric``)."""
    if not isinstance(table, dict) or "kind" not in table:
        raise StudyError(
            f'{where}: expected a table with a kind, e.g. {{ kind = "mean_force", body = "..." }}'
        )
    kind = table["kind"]
    if kind not in KINDS:
        listing = "; ".join(f"{k} ({v[3]})" for k, v in KINDS.items())
        raise StudyError(f"{where}: unknown metric kind {kind!r}; valid kinds: {listing}")
    required, optional, _, _ = KINDS[kind]
    options = {k: v for k, v in table.items() if k != "kind"}
    missing = [k for k in required if k not in options]
    extra = [k for k in options if k not in (*required, *optional)]
    if missing or extra:
        problems = [f"needs {', '.join(missing)}"] if missing else []
        problems += [f"takes no {', '.join(extra)}"] if extra else []
        raise StudyError(
            f"{where}: kind {kind!r} {'; '.join(problems)} "
            f"(keys: {', '.join((*required, *optional)) or 'none'})"
        )
    if kind == "final_depth" and len(options) != 1:
        raise StudyError(f"{where}: final_depth needs one of body or site")
    _check_options(kind, options, where)
    return MetricSpec(name, kind, options)


def _check_options(kind: str, options: dict[str, Any], where: str) -> None:
    components = FORCE_COMPONENTS if kind.endswith(("force", "torque")) else MOTION_COMPONENTS
    checks: dict[str, tuple[Callable[[Any], bool], str]] = {
        "component": (lambda v: v in components, f"one of {', '.join(components)}"),
        "after": (lambda v: _number(v) and v >= 0, "a time >= 0 [s]"),
        "absolute": (lambda v: isinstance(v, bool), "true or false"),
        "stat": (lambda v: v in SENSOR_STATS, f"one of {', '.join(SENSOR_STATS)}"),
        "index": (lambda v: _integer(v) and v >= 0, "an integer >= 0"),
        "function": (lambda v: isinstance(v, str) and ":" in v, "MODULE:FUNCTION or file.py:FUN"),
    }  # fmt: skip
    for key, value in options.items():
        if key in checks and not checks[key][0](value):
            raise StudyError(f"{where}: {key} = {value!r} is not valid; it takes {checks[key][1]}")
        if key in ("body", "site", "sensor", "actuator") and not isinstance(value, str):
            raise StudyError(f"{where}: {key} = {value!r} is not valid; it takes a name")


def _integer(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _lookup(model: mujoco.MjModel, obj: mujoco.mjtObj, kind: str, name: str, where: str) -> int:
    i = mujoco.mj_name2id(model, obj, name)
    if i < 0:
        count = {"body": model.nbody, "site": model.nsite, "sensor": model.nsensor,
                 "actuator": model.nu}[kind]  # fmt: skip
        names = [mujoco.mj_id2name(model, obj, j) for j in range(count)]
        raise StudyError(
            f"{where}: the model has no {kind} named {name!r} "
            f"({kind}s: {', '.join(n for n in names if n) or 'none'})"
        )
    return i


def check_metric(
    m: MetricSpec, model: mujoco.MjModel, intruders: list[str], duration: float, where: str
) -> None:
    """Check `m`'s names against a compiled model (force, torque and work metrics need a body
    that feels the medium, one of `intruders`) and its window against the duration [s]."""
    o = m.options
    if "body" in o:
        _lookup(model, mujoco.mjtObj.mjOBJ_BODY, "body", o["body"], where)
        if m.kind.endswith(("force", "torque")) or m.kind == "rft_work":
            if o["body"] not in intruders:
                raise StudyError(
                    f"{where}: body {o['body']!r} does not feel the medium "
                    f"(intruding bodies: {', '.join(intruders)})"
                )
    if "site" in o:
        _lookup(model, mujoco.mjtObj.mjOBJ_SITE, "site", o["site"], where)
    if "actuator" in o:
        _lookup(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "actuator", o["actuator"], where)
    if "sensor" in o:
        s = _lookup(model, mujoco.mjtObj.mjOBJ_SENSOR, "sensor", o["sensor"], where)
        dim = int(model.sensor_dim[s])
        if "index" not in o and dim > 1:
            raise StudyError(
                f"{where}: sensor {o['sensor']!r} has {dim} values; give index = 0..{dim - 1}"
            )
        if o.get("index", 0) >= dim:
            raise StudyError(
                f"{where}: index {o['index']} is out of range; sensor {o['sensor']!r} has "
                f"{dim} value(s)"
            )
    if m.after >= duration:
        raise StudyError(f"{where}: after = {m.after:g} s leaves nothing of the {duration:g} s run")


# ---------------------------------------------------------------------------- measuring


class _Series:
    """Running time statistics of one scalar series over the states in a window."""

    def __init__(self) -> None:
        self.sum_w = self.sum_wx = 0.0
        self.peak, self.lo, self.hi, self.last = 0.0, math.inf, -math.inf, math.nan

    def add(self, w: np.ndarray, x: np.ndarray, mask: np.ndarray) -> None:
        if len(x):
            self.last = float(x[-1])
        if not mask.any():
            return
        xm, wm = x[mask], w[mask]
        self.sum_w += float(wm.sum())
        self.sum_wx += float(wm @ xm)
        self.peak = max(self.peak, float(np.abs(xm).max()))
        self.lo, self.hi = min(self.lo, float(xm.min())), max(self.hi, float(xm.max()))

    @property
    def mean(self) -> float:
        return self.sum_wx / self.sum_w if self.sum_w > 0 else math.nan


def _component(v: np.ndarray, c: str) -> np.ndarray:
    """(n,) component c of (n, 3) world vectors: an axis, the horizontal magnitude, the norm."""
    if c in ("x", "y", "z"):
        return v[:, "xyz".index(c)]
    if c == "xy":
        return np.hypot(v[:, 0], v[:, 1])
    return np.linalg.norm(v, axis=1)


@dataclass
class Chunk:
    """A block of observed states: times t (n,) [s], weights w (n,) [s], and per probed body k
    its RFT wrench (n, 6), CoM twist [omega, v] (n, 6) and CoM (n, 3); actuator powers (n, nu)
    [W]; sensor data (n, nsensordata)."""

    t: np.ndarray
    w: np.ndarray
    wrench: np.ndarray
    twist: np.ndarray
    com: np.ndarray
    power: np.ndarray
    sensors: np.ndarray


class Metric:
    """A metric being measured: ``update`` with every Chunk, then ``value``."""

    def __init__(self, spec: MetricSpec, model: mujoco.MjModel, slot: Mapping[int, int]) -> None:
        self.spec, self.o = spec, spec.options
        self.k = slot.get(model.body(self.o["body"]).id, -1) if "body" in self.o else -1
        self.series = _Series()
        self.first_com: np.ndarray | None = None
        self.first_t = self.last_t = math.nan
        self.last_com = np.full(3, math.nan)
        self._setup(model)

    def _setup(self, model: mujoco.MjModel) -> None:
        o = self.o
        if "actuator" in o:
            self.actuators = [model.actuator(o["actuator"]).id]
        else:
            self.actuators = list(range(model.nu))
        if self.spec.kind == "sensor":
            s = model.sensor(o["sensor"]).id
            self.adr = int(model.sensor_adr[s]) + int(o.get("index", 0))
        if self.spec.kind == "cost_of_transport":
            b = model.body(o["body"]).id
            self.weight = float(model.body_subtreemass[b]) * float(
                np.linalg.norm(model.opt.gravity)
            )

    def _sample(self, c: Chunk) -> np.ndarray | None:
        kind, comp = self.spec.kind, self.o.get("component", "norm")
        if kind in ("mean_force", "peak_force"):
            return _component(c.wrench[:, self.k, :3], comp)
        if kind in ("mean_torque", "peak_torque"):
            return _component(c.wrench[:, self.k, 3:], comp)
        if kind == "rft_work":  # the medium's power on the body is F.v + tau.omega (<= 0)
            return -np.einsum("ij,ij->i", c.wrench[:, self.k, :3], c.twist[:, self.k, 3:]) - (
                np.einsum("ij,ij->i", c.wrench[:, self.k, 3:], c.twist[:, self.k, :3])
            )
        if kind in ("actuator_work", "cost_of_transport"):
            p = c.power[:, self.actuators]
            return (
                np.abs(p).sum(axis=1)
                if self.o.get("absolute", kind != "actuator_work")
                else p.sum(axis=1)
            )
        if kind == "sensor":
            return c.sensors[:, self.adr]
        return None

    def update(self, c: Chunk) -> None:
        """Take in one block of states."""
        mask = c.t >= self.spec.after - 1e-12
        x = self._sample(c)
        if x is not None:
            self.series.add(c.w, x, mask)
        if self.k >= 0 and len(c.t):
            if self.first_com is None and mask.any():
                i = int(np.argmax(mask))
                self.first_com, self.first_t = c.com[i, self.k].copy(), float(c.t[i])
            self.last_com, self.last_t = c.com[-1, self.k].copy(), float(c.t[-1])

    def value(self, data: mujoco.MjData, surface: Surface) -> float:
        """The metric, from everything taken in and the final state `data`; depths are below
        the free surface under the point (vertical)."""
        kind, s = self.spec.kind, self.series
        if kind == "final_depth":
            o = self.o
            p = data.site(o["site"]).xpos if "site" in o else data.body(o["body"]).xipos
            return float(surface.height(p[0], p[1])) - float(p[2])
        if kind in ("mean_force", "mean_torque"):
            return s.mean
        if kind in ("peak_force", "peak_torque"):
            return s.peak
        if kind in ("rft_work", "actuator_work"):
            return s.sum_wx
        if kind == "sensor":
            return {"mean": s.mean, "min": s.lo, "max": s.hi, "final": s.last}[self.o["stat"]]
        if self.first_com is None:
            return math.nan
        moved = _component((self.last_com - self.first_com)[None], self.o.get("component", "xy"))[0]
        if kind == "distance":
            return float(moved)
        if kind == "speed":
            span = self.last_t - self.first_t
            return float(moved) / span if span > 0 else math.nan
        horizontal = float(np.hypot(*(self.last_com - self.first_com)[:2]))
        return s.sum_wx / (self.weight * horizontal) if horizontal > 0 else math.inf


class Probe:
    """The observer of a run (``simulate.run(observer=...)``): it copies what the metrics need
    from every observed state into a block, and hands full blocks to the metrics, so its memory
    does not grow with the run."""

    BLOCK = 2048

    def __init__(self, specs: list[MetricSpec], model: mujoco.MjModel, fld: Any) -> None:
        self.model, self.fld = model, fld
        bodies = sorted({model.body(s.options["body"]).id for s in specs if "body" in s.options})
        self.ids = np.array(bodies, dtype=np.int64)
        self.roots = model.body_rootid[self.ids]
        slot = {b: k for k, b in enumerate(bodies)}
        self.metrics = [Metric(s, model, slot) for s in specs if s.kind != "custom"]
        kb, nu, ns = len(bodies), model.nu, model.nsensordata
        widths = [1, 6 * kb, 6 * kb, 3 * kb, 3 * kb, nu, nu, ns]
        edges = np.cumsum([0, *widths]).tolist()
        self.cuts = edges[1:-1]
        self.slices = [slice(a, b) for a, b in itertools.pairwise(edges)]
        self.rows = np.empty((self.BLOCK, edges[-1]))
        self.n = 0
        self.wrench: np.ndarray | None = None

    def __call__(self, step: int, time: float, data: mujoco.MjData) -> None:
        if self.n == self.BLOCK:
            self._flush(final=False)
        if self.wrench is None:
            self.wrench = self.fld.wrench_of(data)  # a live view of this MjData's last pass
        ids, row, s = self.ids, self.rows[self.n], self.slices
        row[0] = time
        row[s[1]] = self.wrench[ids].ravel()
        row[s[2]] = data.cvel[ids].ravel()
        row[s[3]] = data.xipos[ids].ravel()
        row[s[4]] = data.subtree_com[self.roots].ravel()
        row[s[5]] = data.actuator_force
        row[s[6]] = data.actuator_velocity
        row[s[7]] = data.sensordata
        self.n += 1

    def _chunk(self, final: bool) -> Chunk:
        """The states taken since the last flush as a Chunk."""
        rows, n, kb = self.rows[: self.n], self.n, len(self.ids)
        t, wr, cv, com, sub, f, v, sens = np.split(rows, self.cuts, axis=1)
        cv, com = cv.reshape(n, kb, 6), com.reshape(n, kb, 3)
        # cvel is (omega, v) at the subtree CoM of the body's root: move v to the body's CoM.
        v_com = cv[..., 3:] + np.cross(cv[..., :3], com - sub.reshape(n, kb, 3))
        w = np.full(n, self.model.opt.timestep)
        if final and n:
            w[-1] = 0.0  # the final state acts in no step
        twist = np.concatenate([cv[..., :3], v_com], axis=2)
        return Chunk(t[:, 0], w, wr.reshape(n, kb, 6), twist, com, f * v, sens)

    def _flush(self, final: bool) -> None:
        chunk = self._chunk(final)
        for m in self.metrics:
            m.update(chunk)
        self.n = 0

    def values(self, data: mujoco.MjData) -> dict[str, float]:
        """Every built-in metric's value (name -> float), once the run has ended at `data`."""
        self._flush(final=True)
        return {m.spec.name: float(m.value(data, self.fld.surface)) for m in self.metrics}

    def partial(self, data: mujoco.MjData) -> dict[str, float]:
        """Every built-in metric's value over the states taken so far, `data` the latest (for
        reports while the run goes); the run's own measurement is left as it was, so its final
        ``values`` do not depend on how often this is called."""
        chunk = self._chunk(final=False)
        out = {}
        for m in self.metrics:
            twin = copy.copy(m)
            twin.series = copy.copy(m.series)
            twin.update(chunk)
            out[m.spec.name] = float(twin.value(data, self.fld.surface))
        return out


@dataclass
class Outcome:
    """What a custom metric function ``f(outcome) -> float`` is given about a finished run.

    Attributes: model, data (the final state), field (the GranularField), parameters (name ->
    value), seed (the run's seed), metrics (the built-in metrics' values), series (the run's
    time series as ``mjrft.app.simulate.Recording``, rows every ``record_every`` steps, with the
    columns of ``mjrft run``'s timeseries.csv).
    """

    model: mujoco.MjModel
    data: mujoco.MjData
    field: Any
    parameters: dict[str, Any]
    seed: int
    metrics: dict[str, float]
    series: Any
