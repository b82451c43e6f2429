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
import threading
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

PLUGIN = "mjrft.granular"
PREFIX = PLUGIN + ":"
_LIBRARY_STEM = "libmjrft_granular"
_lock = threading.Lock()
_lib: ctypes.CDLL | None = None


class EngineError(RuntimeError):
    """The engine library is missing, was built for another MuJoCo, or a model lacks it."""


def library_path() -> Path:
    """Path of the engine library (installed beside mjrft's modules by ``pip install``)."""
    import mjrft

    env = os.environ.get("MJRFT_ENGINE_LIBRARY")
    if env:
        return Path(env)
    for folder in mjrft.__path__:
        for suffix in (".so", ".dylib", ".dll"):
            path = Path(folder) / (_LIBRARY_STEM + suffix)
            if path.exists():
                return path
    raise EngineError(
        f"the mjrft engine library ({_LIBRARY_STEM}.so) is not installed beside "
        f"{list(mjrft.__path__)}: mjrft was not built; install it with `pip install .` (or "
        "`pip install -e .`) from its source, which builds the C++ engine with CMake"
    )


def library() -> ctypes.CDLL:
    """The engine library, loaded once (and registered with MuJoCo as a plugin library)."""
    global _lib
    with _lock:
        if _lib is None:
            path = library_path()
            try:
                mujoco.mj_loadPluginLibrary(str(path))
                lib = ctypes.CDLL(str(path))
            except OSError as e:
                raise EngineError(
                    f"cannot load the mjrft engine {path}: {e}. It links one MuJoCo release "
                    f"exactly; this process has mujoco {mujoco.__version__}: rebuild mjrft "
                    "(`pip install .`) against the installed mujoco"
                ) from e
            _declare(lib)
            built = lib.mjrft_mujoco_version()
            if built != mujoco.mj_version():
                raise EngineError(
                    f"the mjrft engine {path} was built against MuJoCo {built}, this process "
                    f"runs {mujoco.mj_version()} ({mujoco.__version__}): rebuild mjrft "
                    "(`pip install .`) against the installed mujoco"
                )
            _lib = lib
        return _lib


def _declare(lib: ctypes.CDLL) -> None:
    p, i, s = ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p
    lib.mjrft_layout.restype = s
    lib.mjrft_mujoco_version.restype = i
    lib.mjrft_instance.argtypes = [p]
    lib.mjrft_instance.restype = i
    lib.mjrft_forward.argtypes = [p, p, i, i]
    lib.mjrft_forward.restype = ctypes.c_longlong
    lib.mjrft_state_array.argtypes = [p, p, i, s]
    lib.mjrft_state_array.restype = p


@dataclass(frozen=True)
class Layout:
    """The engine's table and state layout (engine/fields.h): names in order, with types."""

    format: int
    sizes: tuple[str, ...]
    scalars: tuple[tuple[str, str], ...]  # (type, name): type "f64" or "i64"
    arrays: tuple[tuple[str, str], ...]
    state: tuple[tuple[str, str], ...]


def layout() -> Layout:
    """The layout the loaded engine reads."""
    lines = dict(
        line.split(" ", 1) for line in library().mjrft_layout().decode().strip().splitlines()
    )
    pairs = lambda key: tuple(tuple(w.split(":")) for w in lines[key].split())  # noqa: E731
    return Layout(
        int(lines["format"]), tuple(lines["sizes"].split()), pairs("scalars"), pairs("arrays"),
        pairs("state"),
    )  # fmt: skip


def tables(model: mujoco.MjModel, **options) -> dict[str, np.ndarray]:
    """The engine's tables for a compiled model with an ``mjrft:`` section (options as
    ``GranularField``): name -> flat float64 array, in the engine's layout."""
    from mjrft.field.granular_field import GranularField
    from mjrft.field.scene import SceneError

    field = GranularField(model, **options)
    if not field.scene.material.compiled:
        raise SceneError(
            "the engine plugin evaluates media given by coefficients (Material presets, Fourier "
            "or 3D-RFT coefficients); a medium given by Python callables runs through "
            "GranularField's Python path only"
        )
    fm = field._tables.arrays
    lay = layout()
    nrow, ncol = fm.surface_grid.shape
    sizes = {
        "nelem": len(fm.elem_area), "ntgeom": len(fm.tgeom_geomid),
        "ntbody": len(fm.tbody_bodyid), "surface_nrow": nrow, "surface_ncol": ncol,
        "ncoef": len(fm.coef), "nvert": fm.elem_vert.shape[0], "nsoil": fm.nsoil,
    }  # fmt: skip
    out = {
        "format": np.array([lay.format], dtype=np.float64),
        "sizes": np.array([sizes[n] for n in lay.sizes], dtype=np.float64),
        "scalars": np.array([getattr(fm, n) for _, n in lay.scalars], dtype=np.float64),
    }
    for _, name in lay.arrays:
        out[name] = np.ascontiguousarray(getattr(fm, name), dtype=np.float64).ravel()
    return out


def add_granular(spec: mujoco.MjSpec, model: mujoco.MjModel | None = None, **options) -> None:
    """Add the engine's tables and an ``mjrft.granular`` instance to spec (in place).

    model: spec compiled (compiled here if not given): the tables are built from the compiled
    geoms (meshes are re-centred by the compiler). options: as ``GranularField`` (material,
    n_triangles, tolerance, low_speed, ...). Tables already in spec are replaced.
    """
    library()
    if model is None:
        model = spec.compile()
    for numeric in list(spec.numerics):
        if numeric.name.startswith(PREFIX):
            spec.delete(numeric)
    found = tables(model, **options)
    for name, data in found.items():
        spec.add_numeric(name=PREFIX + name, data=data.tolist(), size=max(1, len(data)))
    lay = layout()
    sizes = dict(zip(lay.sizes, found["sizes"].astype(int).tolist(), strict=True))
    # MuJoCo sizes the plugin's state before the numeric fields hold data: the sizes that fix
    # it travel in the instance's config as well (the engine checks them against the tables).
    config = {"ntbody": sizes["ntbody"], "ntgeom": sizes["ntgeom"], "nsoil": sizes["nsoil"]}
    plugins = [p for p in spec.plugins if p.plugin_name == PLUGIN]
    if not plugins:
        spec.activate_plugin(PLUGIN)
        plugins = [spec.add_plugin(name="mjrft", plugin_name=PLUGIN, active=True)]
    plugins[0].config = {k: str(v) for k, v in config.items()}


def load_model(path_or_xml: str | os.PathLike, **options) -> mujoco.MjModel:
    """A compiled model with the engine plugin, from an MJCF file or string whose ``<custom>``
    has an ``mjrft:`` section (docs/mjcf.md). options: as ``GranularField``."""
    library()
    text = str(path_or_xml)
    if isinstance(path_or_xml, os.PathLike) or (not text.lstrip().startswith("<")):
        spec = mujoco.MjSpec.from_file(str(path_or_xml))
    else:
        spec = mujoco.MjSpec.from_string(text)
    add_granular(spec, **options)
    return spec.compile()


def instance(model: mujoco.MjModel) -> int:
    """Index of model's ``mjrft.granular`` instance; EngineError if it has none."""
    i = library().mjrft_instance(ctypes.c_void_p(model._address))
    if i < 0:
        raise EngineError(
            "this MjModel has no mjrft.granular plugin instance: load it with "
            "mjrft.load_model(path_or_xml), or call mjrft.add_granular(spec) before compiling"
        )
    return i
