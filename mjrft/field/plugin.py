"""The C++ engine plugin ``mjrft.granular``: its library, and models that carry it.

The engine (``engine/`` in the repository; a MuJoCo engine plugin in C++) computes the field
inside MuJoCo's passive stage, from tables it reads out of the compiled model: custom numeric
fields named ``mjrft.granular:<table>``, written here from the model's ``mjrft:`` section
(``add_granular``), so a compiled model is self-contained (as MJB too) and runs wherever the
library is loaded: ``mj_step``, ``mujoco.rollout``'s threads, MuJoCo's viewers, C programs.

``load_model(path_or_xml)`` is the usual entry: MJCF in, an ``MjModel`` with the plugin's
instance and tables out. The table layout is the library's own (``engine/fields.h``, read through
``mjrft_layout``), so it is declared once.
"""

from __future__ import annotations

import ctypes
import os
import warnings
import weakref

import mujoco
import numpy as np

from mjrft.core.engine import EngineError, Layout, layout, quiet_reports  # noqa: F401 (re-exported)
from mjrft.core.engine import library as _library
from mjrft.field.model import FieldSetup, field_setup
from mjrft.field.options import SceneOptions
from mjrft.field.scene import ENGINE_PREFIX, SceneError, SceneWarning, scene_from_model

PLUGIN = "mjrft.granular"
PREFIX = ENGINE_PREFIX
#: The sensor plugin: per intruder geom, the applied RFT wrench and the sinkage (add_sensors).
SENSOR = "mjrft.sensor"
#: The values of one mjrft.sensor reading, in order: force [N] and torque [N m] about the geom's
#: centre, world frame, then the sinkage [m] (the surface's height above the geom's lowest point).
READING = ("fx", "fy", "fz", "tx", "ty", "tz", "sinkage")


def library():
    """The engine library, loaded and checked against the running MuJoCo (``mjrft.core.engine``).

    Loading it registers the plugin with MuJoCo; the version check refuses a library built
    against another MuJoCo release than the one this process imported."""
    lib = _library()
    built = lib.mjrft_mujoco_version()
    if built != mujoco.mj_version():
        raise EngineError(
            f"the mjrft engine was built against MuJoCo {built}, this process runs "
            f"{mujoco.mj_version()} (mujoco {mujoco.__version__}): rebuild mjrft "
            "(`pip install .`) against the installed mujoco"
        )
    return lib


#: The options each model of this process was loaded with (GranularField rebuilds the same scene
#: from them; a model from elsewhere, an MJB file say, is read with the MJCF's own values).
_options: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def options_of(model: mujoco.MjModel) -> SceneOptions:
    """The scene options model was loaded with by ``load_model`` in this process (else none)."""
    return _options.get(model, SceneOptions())


def setup(model: mujoco.MjModel, options: SceneOptions | None = None) -> FieldSetup:
    """The field's setup (scene, elements, tables) of a compiled model with an ``mjrft:``
    section, under options."""
    scene = scene_from_model(model, **(options or SceneOptions()).given())
    try:  # a medium given by callables is tabulated (and its callables checked) here
        scene.material.kernel_coefficients  # noqa: B018
    except ValueError as exc:
        raise SceneError(f"material {scene.material.name!r}: {exc}") from None
    return field_setup(model, scene)


def numerics(tables: dict) -> dict[str, np.ndarray]:
    """The custom numeric fields (name without PREFIX -> flat float64) that carry tables."""
    lay = layout()
    out = {
        "format": np.array([lay.format], dtype=np.float64),
        "sizes": np.array([tables[n] for n in lay.sizes], dtype=np.float64),
        "scalars": np.array([tables[n] for _, n in lay.scalars], dtype=np.float64),
    }
    for _, name in lay.arrays:
        out[name] = np.asarray(tables[name], dtype=np.float64).ravel()
    return out


def add_granular(
    spec: mujoco.MjSpec,
    model: mujoco.MjModel | None = None,
    options: SceneOptions | None = None,
    **overrides,
) -> None:
    """Add the engine's tables and an ``mjrft.granular`` instance to spec (in place).

    model: spec compiled (compiled here if not given): the tables are built from the compiled
    geoms (MuJoCo re-centres meshes). options, overrides: SceneOptions (material, n_triangles,
    tolerance, low_speed, ...) on top of the MJCF's ``mjrft:`` section. Tables already in spec
    are replaced.
    """
    library()
    options = SceneOptions.of(options, **overrides)
    # An instance or tables already in spec (a spec loaded twice, MJCF saved with them) go: a
    # model compiled with an instance but without its tables would be refused by the engine.
    for element in [*spec.numerics, *spec.plugins]:
        if element.name.startswith(PREFIX) or getattr(element, "plugin_name", "") == PLUGIN:
            spec.delete(element)
    sensors = _our_sensors(spec)
    if model is None:
        model = _compile(spec)
    _warn_if_passive_skipped(model)
    tables = setup(model, options).tables
    _check_sensors(sensors, model, tables)
    for name, data in numerics(tables).items():
        spec.add_numeric(name=PREFIX + name, data=data.tolist(), size=max(1, len(data)))
    # MuJoCo sizes a plugin's state before the model's numeric fields hold data: the sizes that
    # fix it travel in the instance's config too (the engine checks them against the tables).
    config = {k: str(int(tables[k])) for k in ("ntbody", "ntgeom", "nsoil")}
    spec.activate_plugin(PLUGIN)
    spec.add_plugin(name="mjrft", plugin_name=PLUGIN, active=True).config = config


def _compile(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """spec compiled, without the engine's reports of the compiler's own forward pass."""
    with quiet_reports():
        return spec.compile()


def _sensor_plugin(spec: mujoco.MjSpec, sensor) -> str:
    """The plugin name of a plugin sensor: its own, or its named instance's."""
    if sensor.plugin.plugin_name:
        return sensor.plugin.plugin_name
    for p in spec.plugins:
        if p.name and p.name == sensor.plugin.name:
            return p.plugin_name
    return ""


def _our_sensors(spec: mujoco.MjSpec) -> list:
    """The mjrft.sensor sensors of spec; SceneError naming one not on a geom."""
    out = [
        sensor
        for sensor in spec.sensors
        if sensor.type == mujoco.mjtSensor.mjSENS_PLUGIN and _sensor_plugin(spec, sensor) == SENSOR
    ]
    for sensor in out:
        if sensor.objtype != mujoco.mjtObj.mjOBJ_GEOM:
            raise SceneError(
                f'{SENSOR} sensor {sensor.name or "(unnamed)"!r}: objtype must be "geom" '
                "with objname an intruder geom"
            )
    return out


def _check_sensors(sensors: list, model: mujoco.MjModel, tables: dict) -> None:
    """Every one of sensors (mjrft.sensor) reads a geom the medium acts on (SceneError)."""
    tagged = set(np.asarray(tables["tgeom_geomid"]).tolist())
    for sensor in sensors:
        geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, sensor.objname)
        if geom not in tagged:
            names = sorted(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"#{g}"
                           for g in tagged)  # fmt: skip
            raise SceneError(
                f"{SENSOR} sensor {sensor.name or '(unnamed)'!r}: geom {sensor.objname!r} is not "
                f"an intruder of the granular medium; the intruder geoms are {names} (tag it: "
                'docs/mjcf.md, "Tagging a robot")'
            )


def add_sensors(
    spec: mujoco.MjSpec, geoms: list[str] | None = None, options: SceneOptions | None = None
) -> list[str]:
    """Add one ``mjrft.sensor`` per geom to spec (in place), named ``rft:<geom>``; returns the
    sensor names. Each reads 7 values (READING): the RFT force [N] and torque [N m] about the
    geom's centre that the engine applied to the geom, world frame, then its sinkage [m].

    geoms: names of intruder geoms; None: every named intruder geom of the scene (options: the
    SceneOptions the model will be loaded with, which decide what the intruders are). Compile
    spec with ``load_model(spec)`` afterwards. Raises SceneError naming a geom that is not an
    intruder, or an unnamed intruder.
    """
    library()
    if geoms is None:
        model = _compile(spec)
        scene = scene_from_model(model, **(options or SceneOptions()).given())
        unnamed = [i.geom for i in scene.intruders if not i.name]
        if unnamed:
            raise SceneError(
                f"add_sensors: intruder geoms {unnamed} have no name; name them, or pass geoms"
            )
        geoms = [i.name for i in scene.intruders]
    spec.activate_plugin(SENSOR)
    names = []
    for geom in geoms:
        sensor = spec.add_sensor(
            name=f"rft:{geom}",
            type=mujoco.mjtSensor.mjSENS_PLUGIN,
            objtype=mujoco.mjtObj.mjOBJ_GEOM,
            objname=geom,
        )
        # an instance of its own (MuJoCo's compiler refuses an unnamed implicit one from MjSpec)
        sensor.plugin = spec.add_plugin(plugin_name=SENSOR, active=True)
        names.append(sensor.name)
    return names


def _warn_if_passive_skipped(model: mujoco.MjModel) -> None:
    """MuJoCo's passive stage returns before its plugins when both the spring and the damper
    flags are disabled: the engine would never run, and nothing else would say so."""
    flags = int(model.opt.disableflags)
    both = int(mujoco.mjtDisableBit.mjDSBL_SPRING) | int(mujoco.mjtDisableBit.mjDSBL_DAMPER)
    if flags & both == both:
        warnings.warn(
            "<flag spring='disable' damper='disable'/>: MuJoCo skips its passive stage, and "
            "with it the granular engine, when both are disabled; the model will feel no RFT "
            "(enable either flag)",
            SceneWarning,
            stacklevel=3,
        )


def load_model(
    source: str | os.PathLike | mujoco.MjSpec, options: SceneOptions | None = None, **overrides
) -> mujoco.MjModel:
    """A compiled model carrying the engine plugin, from an MJCF file, an MJCF string or an
    MjSpec (changed in place) whose ``<custom>`` has an ``mjrft:`` section (docs/mjcf.md).

    options, overrides: SceneOptions (material, n_triangles, tolerance, low_speed, stick_reach,
    deform_cell, repose, deform_every, deform_travel, dynamic, intruders, watch_sinking) on top
    of the MJCF's
    values.
    Raises SceneError (a ValueError) naming the geom or field at fault, or ValueError naming the
    file MuJoCo could not read.
    """
    library()
    options = SceneOptions.of(options, **overrides)
    if isinstance(source, mujoco.MjSpec):
        spec = source
    else:
        text = os.fspath(source)
        is_xml = not isinstance(source, os.PathLike) and text.lstrip().startswith("<")
        try:
            spec = mujoco.MjSpec.from_string(text) if is_xml else mujoco.MjSpec.from_file(text)
        except ValueError as exc:
            where = "the MJCF string" if is_xml else repr(text)
            raise ValueError(f"cannot load MJCF model {where}: {exc}") from exc
    add_granular(spec, options=options)
    model = _compile(spec)
    _options[model] = options
    return model


def instance(model: mujoco.MjModel) -> int:
    """Index of model's ``mjrft.granular`` instance; EngineError if it has none."""
    i = library().mjrft_instance(ctypes.c_void_p(model._address))
    if i < 0:
        raise EngineError(
            "this MjModel has no mjrft.granular plugin instance: load it with "
            "mjrft.load_model(path_or_xml), or call mjrft.add_granular(spec) before compiling"
        )
    return i
