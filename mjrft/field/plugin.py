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

from mjrft.core.engine import EngineError, Layout, layout  # noqa: F401 (re-exported)
from mjrft.core.engine import library as _library
from mjrft.field.model import FieldSetup, field_setup
from mjrft.field.options import SceneOptions
from mjrft.field.scene import ENGINE_PREFIX, SceneError, SceneWarning, scene_from_model

PLUGIN = "mjrft.granular"
PREFIX = ENGINE_PREFIX


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
    if model is None:
        model = spec.compile()
    _warn_if_passive_skipped(model)
    tables = setup(model, options).tables
    for name, data in numerics(tables).items():
        spec.add_numeric(name=PREFIX + name, data=data.tolist(), size=max(1, len(data)))
    # MuJoCo sizes a plugin's state before the model's numeric fields hold data: the sizes that
    # fix it travel in the instance's config too (the engine checks them against the tables).
    config = {k: str(int(tables[k])) for k in ("ntbody", "ntgeom", "nsoil")}
    spec.activate_plugin(PLUGIN)
    spec.add_plugin(name="mjrft", plugin_name=PLUGIN, active=True).config = config


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
    deform_cell, repose, deform_every, dynamic) on top of the MJCF's values.
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
    model = spec.compile()
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
