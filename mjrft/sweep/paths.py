"""Where a study's values go: MJCF attributes (through ``mujoco.MjSpec``), ``mjrft:`` custom
values, the field's options, actuator control schedules and a controller's arguments.

Path forms (``[i]``, ``[i:j]`` or ``[i,j,...]`` address elements of a vector attribute):

* ``<kind>.<name>.<attribute>[i]``: an attribute of a named MJCF element, e.g.
  ``body.root.euler[1]``, ``geom.ball.size[0]``, ``actuator.yaw.gear[0]``, ``key.start.qvel[1]``
  (kinds: ``SPEC_KINDS``); orientations (``euler``, ``axisangle``, ``xyaxes``, ``zaxis``) in the
  model's own angle unit (``<compiler angle>``);
* ``option.<attribute>[i]``: ``option.timestep`` [s], ``option.integrator`` (``euler``, ``rk4``,
  ``implicit``, ``implicitfast``), ``option.gravity[2]`` [m/s^2], ...;
* ``mjrft:<name>[i]``: a ``<custom>`` numeric or text of the scene (``mjrft.field.scene.KEYS``),
  added to the model if it has none;
* ``material``, ``triangles``, ``tolerance``, ``low_speed``, ``stick_reach``: scene options
  (``mjrft.SceneOptions``, given to ``mjrft.load_model``); ``timestep`` and ``integrator``:
  ``option.timestep`` and ``option.integrator``;
* ``ctrl.<actuator>``: a constant control, or ``ctrl.<actuator>.offset|amplitude|frequency|phase``:
  u(t) = offset + amplitude sin(2 pi frequency t + phase) (frequency [Hz], phase [rad]), written
  before every step;
* ``controller.<argument>``: a keyword argument of the study's controller factory.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from mjrft.field.options import SceneOptions
from mjrft.sweep.errors import StudyError

#: Kinds of named MJCF elements a path may address (MjSpec finds them by name).
SPEC_KINDS = (
    "body", "geom", "site", "joint", "actuator", "sensor", "tendon", "camera", "light",
    "equality", "mesh", "material", "key",
)  # fmt: skip
#: MJCF alternatives to ``quat`` (MjSpec keeps them in ``alt``).
ORIENTATIONS = {
    "euler": mujoco.mjtOrientation.mjORIENTATION_EULER,
    "axisangle": mujoco.mjtOrientation.mjORIENTATION_AXISANGLE,
    "xyaxes": mujoco.mjtOrientation.mjORIENTATION_XYAXES,
    "zaxis": mujoco.mjtOrientation.mjORIENTATION_ZAXIS,
}
#: Scene options a path may set, with the ``mjrft.SceneOptions`` field each goes to.
FIELD_OPTIONS = {
    "material": "material",
    "triangles": "n_triangles",
    "tolerance": "tolerance",
    "low_speed": "low_speed",
    "stick_reach": "stick_reach",
}
ALIASES = {"timestep": "option.timestep", "integrator": "option.integrator"}
SINE_FIELDS = ("offset", "amplitude", "frequency", "phase")
FORMS = (
    "<kind>.<name>.<attribute>[i] (kinds: " + ", ".join(SPEC_KINDS) + "), option.<attribute>, "
    "mjrft:<name>, " + ", ".join([*FIELD_OPTIONS, *ALIASES]) + ", ctrl.<actuator>, "
    "ctrl.<actuator>.offset|amplitude|frequency|phase, controller.<argument>"
)
_INDEX = re.compile(r"^(?P<head>.*?)(?:\[(?P<index>[0-9:, ]+)\])?$")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


@dataclass(frozen=True)
class Target:
    """One place a value goes. where: "spec" (kind, name, attr), "custom" (name: the key after
    ``mjrft:``), "field" (name: the GranularField keyword), "ctrl" (name: actuator, attr: "value"
    or a SINE_FIELDS entry) or "controller" (name: the argument); index: elements of a vector."""

    path: str
    where: str
    kind: str = ""
    name: str = ""
    attr: str = ""
    index: tuple[int, ...] | None = None


def parse(path: str) -> Target:
    """The Target a path names (its syntax only; ``check`` binds it to a model)."""
    if not isinstance(path, str) or not path.strip():
        raise StudyError(f"a path must be a non-empty string, got {path!r}; valid forms: {FORMS}")
    text = ALIASES.get(path.strip(), path.strip())
    m = _INDEX.match(text)
    head, index = m.group("head"), _parse_index(m.group("index"), path)
    if head.startswith("mjrft:"):
        return Target(path, "custom", name=head[len("mjrft:") :], index=index)
    if head in FIELD_OPTIONS and index is None:
        return Target(path, "field", name=FIELD_OPTIONS[head])
    parts = head.split(".")
    if parts[0] == "option" and len(parts) == 2:
        return Target(path, "spec", kind="option", attr=parts[1], index=index)
    if parts[0] == "ctrl" and len(parts) in (2, 3) and index is None:
        attr = parts[2] if len(parts) == 3 else "value"
        if attr not in ("value", *SINE_FIELDS):
            raise StudyError(f"path {path!r}: a control schedule has {', '.join(SINE_FIELDS)}")
        return Target(path, "ctrl", name=parts[1], attr=attr)
    if parts[0] == "controller" and len(parts) == 2 and _NAME.match(parts[1]) and index is None:
        return Target(path, "controller", name=parts[1])
    if parts[0] in SPEC_KINDS and len(parts) >= 3:
        name = ".".join(parts[1:-1])  # MJCF names may contain dots
        return Target(path, "spec", kind=parts[0], name=name, attr=parts[-1], index=index)
    raise StudyError(f"unknown path {path!r}; valid forms: {FORMS}")


def _parse_index(text: str | None, path: str) -> tuple[int, ...] | None:
    if text is None:
        return None
    try:
        if ":" in text:
            start, stop = (int(p) for p in text.split(":"))
            index = tuple(range(start, stop))
        else:
            index = tuple(int(p) for p in text.split(","))
    except ValueError:
        raise StudyError(f"path {path!r}: an index is [i], [i:j] or [i,j,...]") from None
    if not index or min(index) < 0:
        raise StudyError(f"path {path!r}: the index selects no element")
    return index


# ---------------------------------------------------------------------------- MjSpec targets


def _names(items) -> str:
    names = [x.name for x in items if x.name]
    return ", ".join(names[:40]) + (", ..." if len(names) > 40 else "") or "none"


def spec_object(spec: mujoco.MjSpec, t: Target) -> Any:
    """The MjSpec element (or ``spec.option``) a spec target addresses, or a StudyError that
    names the element and lists those of its kind."""
    if t.kind == "option":
        return spec.option
    found = getattr(spec, t.kind)(t.name)
    if found is None:
        plural = {"body": "bodies", "key": "keys", "mesh": "meshes", "equality": "equalities"}
        items = getattr(spec, plural.get(t.kind, t.kind + "s"))
        raise StudyError(
            f"path {t.path!r}: the model has no {t.kind} named {t.name!r} "
            f"({plural.get(t.kind, t.kind + 's')}: {_names(items)})"
        )
    return found


def _attributes(obj: Any) -> list[str]:
    names = [a for a in dir(obj) if not a.startswith("_") and not callable(getattr(obj, a))]
    if hasattr(obj, "alt"):
        names += list(ORIENTATIONS)
    return sorted(set(names) - {"alt", "id", "signature", "compiler", "plugin"})


def _holder(obj: Any, t: Target) -> tuple[Any, str]:
    """(object, attribute) that hold the target's value, with MJCF orientation aliases
    resolved: setting one selects it as the element's orientation."""
    if t.attr in ORIENTATIONS and hasattr(obj, "alt"):
        return obj.alt, t.attr
    if t.attr.startswith("_") or not hasattr(obj, t.attr) or callable(getattr(obj, t.attr)):
        what = "option" if t.kind == "option" else f"{t.kind} {t.name!r}"
        raise StudyError(
            f"path {t.path!r}: {what} has no attribute {t.attr!r} "
            f"(valid: {', '.join(_attributes(obj))})"
        )
    return obj, t.attr


def set_spec_value(spec: mujoco.MjSpec, t: Target, value: Any) -> None:
    """Write `value` to the MjSpec attribute `t` addresses (elements `t.index` of a vector), or
    raise a StudyError naming the path and what it takes."""
    obj = spec_object(spec, t)
    holder, attr = _holder(obj, t)
    if t.kind == "option" and attr == "integrator":
        new = _integrator(t, value)
    else:
        new = _merged(getattr(holder, attr), t, value)
    try:
        setattr(holder, attr, new)
    except (TypeError, ValueError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise StudyError(f"path {t.path!r}: cannot take {value!r} ({first})") from None
    if attr in ORIENTATIONS and holder is not obj:
        holder.type = ORIENTATIONS[attr]
    elif attr == "quat" and hasattr(obj, "alt"):
        obj.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT


def _integrator(t: Target, value: Any) -> int:
    from mjrft.app.simulate import INTEGRATORS

    if isinstance(value, str) and value.lower() in INTEGRATORS:
        return int(INTEGRATORS[value.lower()])
    raise StudyError(f"path {t.path!r}: {value!r} is not an integrator ({', '.join(INTEGRATORS)})")


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def _merged(current: Any, t: Target, value: Any) -> Any:
    """The attribute's new value: `value`, or the current vector with elements t.index replaced;
    checked against the current value's type."""
    if isinstance(current, str):
        if not isinstance(value, str) or t.index is not None:
            raise StudyError(f"path {t.path!r}: {value!r} is not valid; it takes a string")
        return value
    if hasattr(type(current), "__members__"):  # a MuJoCo enum: a member's name or number
        return _enum(type(current), t, value)
    if isinstance(current, bool | int | float):
        if t.index is not None:
            raise StudyError(f"path {t.path!r}: the attribute is one number; it takes no index")
        if isinstance(current, bool) and isinstance(value, bool):
            return value
        if not _is_number(value) or (isinstance(current, int) and value != int(value)):
            kind = "an integer" if isinstance(current, int) else "a number"
            raise StudyError(f"path {t.path!r}: {value!r} is not valid; it takes {kind}")
        return type(current)(value)
    fixed = isinstance(current, np.ndarray)  # MjSpec's arrays have a fixed size
    vec = np.array(current if fixed else list(current), dtype=float)
    return _vector(vec, t, value, fixed)


def _vector(vec: np.ndarray, t: Target, value: Any, fixed: bool = False) -> np.ndarray:
    if t.index is None:
        values = value if isinstance(value, list | tuple) else None
        wrong_size = fixed and values is not None and len(values) != vec.size
        if values is None or wrong_size or not all(_is_number(v) for v in values):
            raise StudyError(
                f"path {t.path!r}: {value!r} is not valid; it takes a list of {vec.size} numbers "
                f"(or one number with an index, e.g. {t.path}[0])"
            )
        return np.array(values, dtype=float)
    if max(t.index) >= vec.size:
        raise StudyError(
            f"path {t.path!r}: index {max(t.index)} is out of range; the attribute has "
            f"{vec.size} element(s) (set the whole list to give more)"
        )
    values = value if isinstance(value, list | tuple) else [value] * len(t.index)
    if len(values) != len(t.index) or not all(_is_number(v) for v in values):
        raise StudyError(
            f"path {t.path!r}: {value!r} is not valid; it takes a number"
            + (f" or a list of {len(t.index)} numbers" if len(t.index) > 1 else "")
        )
    vec[list(t.index)] = values
    return vec


def _enum(kind: type, t: Target, value: Any) -> Any:
    members = {k.lower(): v for k, v in kind.__members__.items()}
    short = {k.split("_", 1)[-1]: v for k, v in members.items()}
    if isinstance(value, str) and (value.lower() in members or value.lower() in short):
        return members.get(value.lower(), short.get(value.lower()))
    if _is_number(value) and int(value) in {int(v) for v in members.values()}:
        return kind(int(value))
    raise StudyError(
        f"path {t.path!r}: {value!r} is not valid; it takes one of {', '.join(sorted(short))}"
    )


# ---------------------------------------------------------------------------- other targets


def _check_custom(t: Target, value: Any) -> None:
    from mjrft.field.scene import KEYS

    if t.name in KEYS["text"]:
        if not isinstance(value, str) or t.index is not None:
            raise StudyError(f"path {t.path!r}: {value!r} is not valid; it takes a string")
    elif t.name in KEYS["numeric"]:
        ok = _is_number(value) or (
            isinstance(value, list | tuple) and all(_is_number(v) for v in value)
        )
        if not ok:
            raise StudyError(f"path {t.path!r}: {value!r} is not valid; it takes numbers")
    else:
        valid = ", ".join(f"mjrft:{k}" for k in (*KEYS["text"], *KEYS["numeric"]))
        raise StudyError(f"path {t.path!r}: no such scene value (valid: {valid})")


#: ``mjrft:`` values that exclude each other in a model (``mjrft.field.scene`` refuses both):
#: writing one removes the model's others, so that a study replaces a preset by zeta, a flat
#: surface by a height field, a triangle count by a tolerance, and back.
REPLACES = {
    "material": ("zeta", "coefficients"),
    "zeta": ("material",),
    "coefficients": ("material",),
    "surface_hfield": ("surface_z", "surface_slope"),
    "surface_z": ("surface_hfield",),
    "surface_slope": ("surface_hfield",),
    "triangles": ("tolerance",),
    "tolerance": ("triangles",),
}


def check_exclusive(targets: list[tuple[str, Target]]) -> None:
    """Refuse a study that writes two ``mjrft:`` values that replace each other (``REPLACES``):
    the one written last would silently remove the other. `targets`: (where, target) pairs."""
    custom = {t.name: where for where, t in targets if t.where == "custom"}
    for name, where in custom.items():
        for other in REPLACES.get(name, ()):
            if other in custom:
                raise StudyError(
                    f"{where} writes mjrft:{name} and {custom[other]} writes mjrft:{other}, "
                    f"which replace each other in a model (each removes the other); give one"
                )


def set_custom_value(spec: mujoco.MjSpec, t: Target, value: Any) -> None:
    """Write an ``mjrft:`` custom value, adding the element if the model has none and removing
    the model's values it replaces (``REPLACES``: e.g. mjrft:zeta removes mjrft:material)."""
    from mjrft.field.scene import KEYS

    _check_custom(t, value)
    for other in REPLACES.get(t.name, ()):
        element = spec.text(f"mjrft:{other}") or spec.numeric(f"mjrft:{other}")
        if element is not None:
            spec.delete(element)
    name = f"mjrft:{t.name}"
    if t.name in KEYS["text"]:
        element = spec.text(name) or spec.add_text(name=name, data="")
        element.data = value
        return
    element = spec.numeric(name) or spec.add_numeric(name=name, data=[])
    if t.index is None:
        element.data = [float(v) for v in (value if isinstance(value, list | tuple) else [value])]
    else:
        element.data = _vector(np.array(list(element.data), dtype=float), t, value).tolist()


def _check_field(t: Target, value: Any) -> None:
    from mjrft.core.geometry import MIN_TRIANGLES
    from mjrft.core.material import PRESETS
    from mjrft.field.lowspeed import MODES

    valid: dict[str, tuple[Callable[[Any], bool], str]] = {
        "material": (lambda v: v in PRESETS, f"a preset name ({', '.join(sorted(PRESETS))})"),
        "n_triangles": (
            lambda v: _is_number(v) and v == int(v) and v >= MIN_TRIANGLES,
            f"an integer >= {MIN_TRIANGLES}",
        ),
        "tolerance": (lambda v: _is_number(v) and 0 < v < 1, "a number in (0, 1)"),
        "low_speed": (lambda v: v in MODES, f"one of {', '.join(MODES)}"),
        "stick_reach": (lambda v: _is_number(v) and v > 0 and math.isfinite(v), "a number > 0"),
    }
    ok, what = valid[t.name]
    if not ok(value):
        raise StudyError(f"path {t.path!r}: {value!r} is not valid; it takes {what}")


@dataclass
class RunConfig:
    """What one run sets besides the MjSpec: scene options (``mjrft.SceneOptions`` field ->
    value), control schedules (actuator -> {"value" or SINE_FIELDS: number}) and the controller
    factory's arguments."""

    scene: dict[str, Any] = field(default_factory=dict)
    schedules: dict[str, dict[str, float]] = field(default_factory=dict)
    controller_kwargs: dict[str, Any] = field(default_factory=dict)

    @property
    def options(self) -> SceneOptions:
        """The run's scene options, for ``mjrft.load_model``."""
        return SceneOptions(**self.scene)


def apply(spec: mujoco.MjSpec, config: RunConfig, t: Target, value: Any) -> None:
    """Send `value` where `t` says: into `spec`, or into `config` (checked either way)."""
    if t.where == "spec":
        set_spec_value(spec, t, value)
    elif t.where == "custom":
        set_custom_value(spec, t, value)
    elif t.where == "field":
        _check_field(t, value)
        config.scene[t.name] = int(value) if t.name == "n_triangles" else value
    elif t.where == "ctrl":
        if spec.actuator(t.name) is None:
            raise StudyError(
                f"path {t.path!r}: the model has no actuator named {t.name!r} "
                f"(actuators: {_names(spec.actuators)})"
            )
        if not _is_number(value):
            raise StudyError(f"path {t.path!r}: {value!r} is not valid; it takes a number")
        config.schedules.setdefault(t.name, {})[t.attr] = float(value)
    else:
        config.controller_kwargs[t.name] = value


def control_schedule(
    model: mujoco.MjModel, schedules: Mapping[str, Mapping[str, float]]
) -> Callable[[float, mujoco.MjData], None] | None:
    """A controller ``ctrl(t, data)`` writing the scheduled actuators' controls (the others keep
    theirs), or None if nothing is scheduled."""
    if not schedules:
        return None
    ids = np.array([model.actuator(name).id for name in schedules], dtype=np.int64)
    rows = [[s.get(k, 0.0) for k in ("value", *SINE_FIELDS)] for s in schedules.values()]
    value, offset, amplitude, frequency, phase = np.array(rows, dtype=float).T
    base = value + offset  # a constant "value" and a sine's offset are never both given

    def ctrl(t: float, data: mujoco.MjData) -> None:
        data.ctrl[ids] = base + amplitude * np.sin(2 * math.pi * frequency * t + phase)

    return ctrl
