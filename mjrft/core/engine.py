"""The C++ engine library (``engine/`` in the repository), as the core layer reaches it.

One shared library holds the whole engine: the MuJoCo plugin ``mjrft.granular`` (registered when
the library is loaded; ``mjrft.field.plugin``) and the C entry points the RFT-only API calls
(element forces, prescribed trajectories, surfaces). Python reaches it through ctypes: one
library serves every Python version, and the core layer needs no mujoco import for it.

The wrappers below (``forces``, ``input_flags``, ``checked_unit_normals``, ``body_wrench``,
``trajectory``, ``surface_heights``, ``surface_depths``) are the kernel's C ABI
(engine/capi_kernel.cc, engine/capi_surface.cc) with NumPy arrays. They take any real-valued
array-likes of the stated shapes as inputs (converted to C-contiguous float64, copied only if
they are not already) and write outputs into arrays they allocate, or into ``out``/``rows``
given by the caller, which must be writable C-contiguous float64 arrays of the stated shape.
Shapes, sizes and the surface's arrays are checked against each other before the library is
called, so a wrong argument raises ValueError (TypeError for a non-numeric one) naming it,
never reads or writes out of bounds. Values are not checked: ``mjrft.core.rft.element_forces``
and ``mjrft.core.body`` check theirs. World frame, SI units, rotations body -> world.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mjrft.core import quadrature, surface

_STEM = "libmjrft_granular"
_lock = threading.Lock()
_lib: ctypes.CDLL | None = None


class EngineError(RuntimeError):
    """The engine library is missing, was built for another MuJoCo, or a model lacks it."""


class SinkingWarning(UserWarning):
    """A collision geom that is not an intruder is below the medium's surface: the medium does
    not act on it (engine/watch.h; once per geom and MjData). Silence it with
    ``SceneOptions(watch_sinking=False)`` or ``warnings.filterwarnings``."""


_quiet = threading.local()


@contextlib.contextmanager
def quiet_reports() -> Iterator[None]:
    """No engine reports from this thread meanwhile: MuJoCo's compiler runs a forward pass on
    an mjData of its own, whose reports would repeat the user's first step's."""
    before = getattr(_quiet, "depth", 0)
    try:  # set inside: an exception from a signal handler cannot leave the reports muted
        _quiet.depth = before + 1
        yield
    finally:
        _quiet.depth = before


def _report(message: bytes) -> None:
    """The engine's reports (engine/watch.h), as Python warnings. Runs inside MuJoCo's step: an
    exception here (warnings turned into errors) cannot cross the C boundary, so it is printed
    instead (ctypes)."""
    if getattr(_quiet, "depth", 0):
        return
    import warnings

    warnings.warn(message.decode("utf-8", "replace"), SinkingWarning, stacklevel=2)


_REPORT = ctypes.CFUNCTYPE(None, ctypes.c_char_p)(_report)  # kept alive: the engine holds it


def library_path() -> Path:
    """Path of the engine library: ``MJRFT_ENGINE_LIBRARY`` if set, else the one ``pip install``
    put beside mjrft's modules."""
    import mjrft

    env = os.environ.get("MJRFT_ENGINE_LIBRARY")
    if env:
        return Path(env)
    for folder in mjrft.__path__:
        for suffix in (".so", ".dylib", ".dll"):
            path = Path(folder) / (_STEM + suffix)
            if path.exists():
                return path
    raise EngineError(
        f"the mjrft engine library ({_STEM}.so) is not installed in {list(mjrft.__path__)}: "
        "mjrft was not built; install it from its source with `pip install .` (or "
        "`pip install -e .`), which builds the C++ engine with CMake"
    )


def library() -> ctypes.CDLL:
    """The engine library, loaded once (loading it registers the MuJoCo plugin)."""
    global _lib
    with _lock:
        if _lib is None:
            path = library_path()
            try:
                lib = ctypes.CDLL(str(path))
            except OSError as e:
                raise EngineError(
                    f"cannot load the mjrft engine {path}: {e}. It links one MuJoCo release "
                    "exactly (the mujoco pinned in mjrft's pyproject.toml): reinstall mjrft "
                    "(`pip install .`) against the installed mujoco"
                ) from e
            _declare(lib)
            lib.mjrft_set_report_handler(_REPORT)
            _lib = lib
        return _lib


def _declare(lib: ctypes.CDLL) -> None:
    p, i, s = ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p
    f, n = ctypes.c_double, ctypes.c_int64
    lib.mjrft_layout.restype = s
    lib.mjrft_mujoco_version.restype = i
    lib.mjrft_instance.argtypes = [p]
    lib.mjrft_instance.restype = i
    lib.mjrft_forward.argtypes = [p, p, i, i]
    lib.mjrft_forward.restype = ctypes.c_longlong
    lib.mjrft_state_array.argtypes = [p, p, i, s]
    lib.mjrft_state_array.restype = p
    lib.mjrft_state_size.argtypes = [p, p, i, s]
    lib.mjrft_state_size.restype = ctypes.c_longlong
    lib.mjrft_set_report_handler.argtypes = [ctypes.CFUNCTYPE(None, ctypes.c_char_p)]
    lib.mjrft_set_report_handler.restype = None
    # engine/capi_kernel.cc
    lib.mjrft_forces.argtypes = [p, p, p, p, n, p, n, f, f, f, p]
    lib.mjrft_forces.restype = i
    lib.mjrft_checked_unit_normals.argtypes = [p, p, p, p, n, p, ctypes.POINTER(n)]
    lib.mjrft_checked_unit_normals.restype = i
    lib.mjrft_input_flags.argtypes = [p, p, p, p, n, ctypes.POINTER(i), ctypes.POINTER(i)]
    lib.mjrft_input_flags.restype = None
    lib.mjrft_body_wrench.argtypes = [p, p, p, p, p, n, n, p, n, f, f, p, p, i, p, p,
                                      p, p, p, p, p, p, p, p, p, f]  # fmt: skip
    lib.mjrft_body_wrench.restype = i
    lib.mjrft_trajectory.argtypes = [p, p, p, p, p, n, p, n, f, f, f, p, p, p, p, p, n, p]
    lib.mjrft_trajectory.restype = None
    # engine/capi_surface.cc
    lib.mjrft_surface_heights.argtypes = [p, p, p, p, p, n, p]
    lib.mjrft_surface_heights.restype = None
    lib.mjrft_surface_depths.argtypes = [p, p, p, p, p, p, n, f, p]
    lib.mjrft_surface_depths.restype = None


@dataclass(frozen=True)
class Layout:
    """The engine's table and state layout (engine/fields.h): names in order, with types."""

    format: int
    sizes: tuple[str, ...]
    scalars: tuple[tuple[str, str], ...]  # (type, name): type "f64" or "i64"
    arrays: tuple[tuple[str, str], ...]
    state: tuple[tuple[str, str], ...]


@functools.cache
def layout() -> Layout:
    """The layout the loaded engine reads."""
    text = library().mjrft_layout().decode()
    lines = dict(line.split(" ", 1) for line in text.strip().splitlines())
    pairs = lambda key: tuple(tuple(w.split(":")) for w in lines[key].split())  # noqa: E731
    return Layout(
        int(lines["format"]), tuple(lines["sizes"].split()), pairs("scalars"), pairs("arrays"),
        pairs("state"),
    )  # fmt: skip


# ---------------------------------------------------------------------------- the RFT kernel
#: Columns of ``body_wrench``'s quadrature rows (kernel::kRow): point [m] (3), unit normal (3),
#: velocity direction (3, any scale), weight W = depth x area [m^3] (1), area [m^2] (1) of the
#: part that acts (the element's, or its submerged leading part where the quadrature clips it);
#: world frame.
ROW = 11
#: Codes of ``checked_unit_normals`` (kernel::InputCode): which input of an element is bad.
INPUT_OK, BAD_POS, BAD_NORMAL, BAD_AREA, BAD_VEL, NEGATIVE_AREA, ZERO_NORMAL = range(7)
#: A normal counts as unit if | |n|^2 - 1 | is below this (kernel::kUnitNormalSlack: a few ulp,
#: what normalising gives).
UNIT_NORMAL_SLACK = 4.0 * np.finfo(np.float64).eps
#: Length of the treers2021 model's coefficients (``Material.kernel_coefficients``), the fewest
#: any force model reads. The kernel tells the models apart by the length: one entry more
#: carries the dynamic term's lambda rho_c [kg/m^3] last (engine/law.h).
N_COMBINED = 18


def _ptr(a: np.ndarray) -> int:
    return a.ctypes.data


def _real(who: str, name: str, a) -> np.ndarray:
    """a as a C-contiguous float64 array (a copy only if it is not one)."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous:
        return a
    x = np.asarray(a)
    if x.dtype.kind not in "biuf":
        raise TypeError(f"{who}: {name} must be a real-valued array, got dtype {x.dtype}")
    return np.asarray(x, dtype=np.float64, order="C")  # keeps 0-d (ascontiguousarray does not)


def _shape_text(shape: tuple) -> str:
    return "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


def _in(who: str, name: str, a, shape: tuple) -> np.ndarray:
    """Input a as float64 C array of exactly shape (entries None: any size)."""
    x = _real(who, name, a)
    if x.ndim != len(shape) or any(
        w is not None and w != s for w, s in zip(shape, x.shape, strict=True)
    ):
        want = _shape_text(tuple("n" if w is None else w for w in shape))
        raise ValueError(f"{who}: {name} has shape {x.shape}, expected {want}")
    return x


def _out(who: str, name: str, a, shape: tuple) -> np.ndarray:
    """A caller's output array, written in place: float64, C-contiguous, writable, shape."""
    if a is None:
        return np.zeros(shape)
    if not isinstance(a, np.ndarray) or a.dtype != np.float64:
        got = a.dtype if isinstance(a, np.ndarray) else type(a).__name__
        raise TypeError(f"{who}: {name} must be a float64 NumPy array, got {got}")
    if a.shape != shape:
        raise ValueError(f"{who}: {name} has shape {a.shape}, expected {_shape_text(shape)}")
    if not (a.flags.c_contiguous and a.flags.writeable):
        raise ValueError(f"{who}: {name} must be C-contiguous and writable (it is written)")
    return a


def _elements(who: str, pos, normal, area, vel) -> tuple[np.ndarray, ...]:
    """World-frame element arrays pos, normal, vel (n, 3) and area (n,), n from pos."""
    pos = _in(who, "pos", pos, (None, 3))
    n = pos.shape[0]
    return (pos, _in(who, "normal", normal, (n, 3)), _in(who, "area", area, (n,)),
            _in(who, "vel", vel, (n, 3)))  # fmt: skip


def _body_elements(who: str, cent, norm, area, reach, patch) -> tuple[np.ndarray, ...]:
    """Body-frame element arrays (``body_wrench``), n from cent."""
    cent = _in(who, "cent", cent, (None, 3))
    n = cent.shape[0]
    return (
        cent, _in(who, "norm", norm, (n, 3)), _in(who, "area", area, (n,)),
        _in(who, "reach", reach, (n,)), _in(who, "patch", patch, (n, quadrature.PATCH_SIZE)),
    )  # fmt: skip


def _coef(who: str, coef) -> np.ndarray:
    co = _in(who, "coef", coef, (None,))
    if co.shape[0] < N_COMBINED:
        raise ValueError(
            f"{who}: coef has {co.shape[0]} entries, a force model reads at least {N_COMBINED} "
            "(Material.kernel_coefficients)"
        )
    return co


def forces(pos, n_hat, area, vel, coef, alpha_y: float, zeta: float, surface_z: float,
           out: np.ndarray | None = None) -> tuple[np.ndarray, int]:  # fmt: skip
    """RFT forces on n world-frame elements under the flat surface at surface_z [m], one-point
    rule, no input checks beyond shapes (``mjrft.core.rft.unit_normal_forces``).

    pos (n, 3) centroids [m], n_hat (n, 3) unit normals, area (n,) [m^2], vel (n, 3) [m/s];
    coef: the model's coefficients (``Material.kernel_coefficients``), alpha_y the generic
    out-of-plane coefficient, zeta [N/m^3]. Returns (forces (n, 3) [N], written into out if
    given; #acting: elements with a nonzero force).
    """
    who = "forces"
    pos, n_hat, area, vel = _elements(who, pos, n_hat, area, vel)
    co = _coef(who, coef)
    out = _out(who, "out", out, pos.shape)
    acting = library().mjrft_forces(
        _ptr(pos), _ptr(n_hat), _ptr(area), _ptr(vel), pos.shape[0], _ptr(co), co.shape[0],
        float(alpha_y), float(zeta), float(surface_z), _ptr(out),
    )  # fmt: skip
    return out, acting


def input_flags(pos, normal, area, vel) -> tuple[bool, bool]:
    """(any bad input: non-finite or negative area, any normal not of unit length within
    UNIT_NORMAL_SLACK) of element arrays (``forces``' shapes); about 1 ns per element."""
    pos, normal, area, vel = _elements("input_flags", pos, normal, area, vel)
    bad, nonunit = ctypes.c_int(), ctypes.c_int()
    library().mjrft_input_flags(
        _ptr(pos), _ptr(normal), _ptr(area), _ptr(vel), pos.shape[0], ctypes.byref(bad),
        ctypes.byref(nonunit),
    )  # fmt: skip
    return bool(bad.value), bool(nonunit.value)


def checked_unit_normals(pos, normal, area, vel) -> tuple[np.ndarray, int, int]:
    """(n_hat (n, 3), code, index): every element's unit normal, and INPUT_OK with index -1 or
    the code of the first bad element (a non-finite position, normal, area or velocity, a
    negative area, a zero-length normal) and its index. A normal already unit (within
    UNIT_NORMAL_SLACK) is copied unchanged; others are normalised without overflow."""
    pos, normal, area, vel = _elements("checked_unit_normals", pos, normal, area, vel)
    n_hat = np.empty_like(pos)
    index = ctypes.c_int64()
    code = library().mjrft_checked_unit_normals(
        _ptr(pos), _ptr(normal), _ptr(area), _ptr(vel), pos.shape[0], _ptr(n_hat),
        ctypes.byref(index),
    )  # fmt: skip
    return n_hat, int(code), int(index.value)


def _surface(who: str, prm, grid, soil) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A surface's (prm, grid, soil) checked against each other (mjrft.core.surface): the
    grid a kind reads has prm's rows and columns, a deforming one's soil block its size. soil
    None: the stand-in of the surfaces without state (a SOIL surface needs its block)."""
    prm = _in(who, "surface prm", prm, (surface.PRM_SIZE,))
    kind = prm[surface.KIND]
    if kind not in (surface.FLAT, surface.PLANE, surface.GRID, surface.SOIL):
        raise ValueError(f"{who}: surface prm has kind {kind}, not one of mjrft.core.surface's")
    grid = _in(who, "surface grid", grid, (None, None))
    if kind in (surface.GRID, surface.SOIL):
        shape = (int(prm[surface.NROW]), int(prm[surface.NCOL]))
        if grid.shape != shape or min(shape) < 2:
            raise ValueError(
                f"{who}: surface grid has shape {grid.shape}, prm says {shape} (at least 2 x 2)"
            )
    elif grid.size == 0:
        raise ValueError(f"{who}: surface grid is empty (a flat or plane surface has a (1, 1) one)")
    if soil is None:
        if kind == surface.SOIL:
            raise ValueError(f"{who}: a deforming (SOIL) surface needs its soil block")
        return prm, grid, surface.NO_SOIL
    soil = _in(who, "soil", soil, (None,))
    if kind == surface.SOIL and soil.shape[0] < surface.soil_block(*grid.shape):
        raise ValueError(
            f"{who}: soil has {soil.shape[0]} entries, the grid's block needs "
            f"{surface.soil_block(*grid.shape)} (surface.soil_block)"
        )
    if soil.shape[0] == 0:
        raise ValueError(f"{who}: soil is empty (surfaces without state take a stand-in)")
    return prm, grid, soil


def _points(who: str, coords: dict) -> tuple[tuple[int, ...], list[np.ndarray]]:
    """Coordinates broadcast to one shape, flattened to float64 C arrays."""
    arrays = {k: _real(who, k, v) for k, v in coords.items()}
    try:
        shape = np.broadcast_shapes(*(a.shape for a in arrays.values()))
    except ValueError:
        shapes = ", ".join(f"{k} {a.shape}" for k, a in arrays.items())
        raise ValueError(f"{who}: the coordinates' shapes do not broadcast: {shapes}") from None
    flat = [np.asarray(np.broadcast_to(a, shape), order="C").reshape(-1) for a in arrays.values()]
    return shape, flat


def surface_heights(prm, grid, soil, x, y, out: np.ndarray | None = None) -> np.ndarray:
    """Surface heights [m] at horizontal positions x, y [m] (broadcast to one shape; world
    frame) of the surface (prm, grid, soil) (mjrft.core.surface; soil None for the surfaces
    without state). Returns an array of the broadcast shape (out if given)."""
    who = "surface_heights"
    prm, grid, soil = _surface(who, prm, grid, soil)
    shape, (xs, ys) = _points(who, {"x": x, "y": y})
    res = _out(who, "out", out, shape)
    library().mjrft_surface_heights(
        _ptr(prm), _ptr(grid), _ptr(soil), _ptr(xs), _ptr(ys), xs.shape[0], _ptr(res)
    )
    return res


def surface_depths(
    prm, grid, soil, x, y, z, out: np.ndarray | None = None, *, body: int = 0
) -> np.ndarray:
    """Resisting depths [m] (<= 0 outside the medium) of the world points (x, y, z) [m]
    (broadcast to one shape) under the surface (prm, grid, soil), as ``surface_heights``.
    body: k + 1 for points of a field's tagged body k, whose press marks on a deforming ground
    set the depth beside it (engine/surface.h, SoilDepth); 0 for none."""
    who = "surface_depths"
    prm, grid, soil = _surface(who, prm, grid, soil)
    shape, (xs, ys, zs) = _points(who, {"x": x, "y": y, "z": z})
    res = _out(who, "out", out, shape)
    library().mjrft_surface_depths(
        _ptr(prm), _ptr(grid), _ptr(soil), _ptr(xs), _ptr(ys), _ptr(zs), xs.shape[0],
        float(body), _ptr(res),
    )  # fmt: skip
    return res


def body_wrench(
    # The body's elements (body frame), then the medium and its surface
    cent, norm, area, reach, patch,
    coef, alpha_y: float, zeta: float, surface_prm, surface_grid, region, soil,
    # The body's pose and motion
    rot, pos, omega, v_ref, p_ref, com,
    rows: np.ndarray | None = None,
    *,
    start: int = 0,
    stop: int | None = None,
    body: int = 0,
) -> tuple[np.ndarray, np.ndarray, int]:  # fmt: skip
    """RFT wrench on a body's elements start..stop (default all), with the kernel's surface
    quadrature (mjrft.core.quadrature).

    Args:
      cent, norm: (n, 3) body-frame centroids [m] and unit normals; area (n,) [m^2]; reach (n,)
        [m] and patch (n, quadrature.PATCH_SIZE): the quadrature's corner data
        (``ElementSet.quadrature``, ``quadrature.patch_table``).
      coef: the model's coefficients (``Material.kernel_coefficients``); alpha_y the generic
        out-of-plane coefficient; zeta [N/m^3].
      surface_prm, surface_grid: the free surface (mjrft.core.surface; depth vertical).
      region: (2, 3) world box [m] of the medium (min corner, max corner), or None (no bound).
      soil: a deforming surface's soil block (its current state), or None for the others.
      rot: (3, 3) body -> world; pos: (3,) body origin [m]; omega: (3,) angular velocity
        [rad/s]; v_ref: (3,) linear velocity [m/s] of the world point p_ref (3,) [m] moving
        with the body; com: (3,) point torque is taken about [m]; all world frame.
      rows: None, or a writable C-contiguous float64 array (n, ROW): the quadrature points of
        the acting elements are written there instead of evaluated (for media given by Python
        callables: ``mjrft.core.rft.quadrature_forces``), rows of the others left as they are.
      body: k + 1 if these are the elements of a field's tagged body k (its press marks on a
        deforming ground, ``surface_depths``), 0 for none.
    Returns:
      (wrench (6,): force [N] then torque [N m] about com, world frame; elem_force (n, 3) [N],
      zero outside start..stop and where nothing acts; acting: elements with a force, or with
      rows given, the rows written (wrench and elem_force then zero)).
    """
    who = "body_wrench"
    cent, norm, area, reach, patch = _body_elements(who, cent, norm, area, reach, patch)
    n = cent.shape[0]
    stop = n if stop is None else int(stop)
    start = int(start)
    if not 0 <= start <= stop <= n:
        raise ValueError(f"{who}: elements {start}..{stop} are not within the {n} given")
    co = _coef(who, coef)
    prm, grid, soil = _surface(who, surface_prm, surface_grid, soil)
    use_region = region is not None
    box = _in(who, "region", region, (2, 3)) if use_region else np.zeros((2, 3))
    motion = [_in(who, "rot", rot, (3, 3))] + [
        _in(who, name, v, (3,))
        for name, v in (("pos", pos), ("omega", omega), ("v_ref", v_ref), ("p_ref", p_ref),
                        ("com", com))
    ]  # fmt: skip
    rws = None if rows is None else _out(who, "rows", rows, (n, ROW))
    wrench, elem_force = np.zeros(6), np.zeros((n, 3))
    acting = library().mjrft_body_wrench(
        _ptr(cent), _ptr(norm), _ptr(area), _ptr(reach), _ptr(patch), start, stop, _ptr(co),
        co.shape[0], float(alpha_y), float(zeta), _ptr(prm), _ptr(grid), int(use_region),
        _ptr(box), _ptr(soil), *(_ptr(a) for a in motion), _ptr(wrench), _ptr(elem_force),
        None if rws is None else _ptr(rws), float(body),
    )  # fmt: skip
    return wrench, elem_force, acting


def quadrature_rows(be, tables: dict, soil, rot, pos, omega, v_ref, p_ref, com) -> np.ndarray:
    """The kernel's quadrature rows (n, ROW) of every element of one body of a field.

    be: the body's ``mjrft.field.model.BodyElements`` (n elements); tables: the field's engine
    tables by name (``mjrft.field.model.engine_tables``), whose block of this body is used;
    soil: the MjData's soil block (the engine state's ``soil``); rot ... com as
    ``body_wrench``, the body's pose and motion in that MjData. Rows of elements that do not
    act are zero.
    """
    t = tables
    k = int(np.flatnonzero(np.asarray(t["tbody_bodyid"]) == be.body)[0])
    first = int(t["tgeom_elemadr"][int(t["tbody_geomadr"][k])])
    b = slice(first, first + len(be.areas))  # the body's block alone: rows sized to it
    rows = np.zeros((len(be.areas), ROW))
    nsoil = t["nsoil"]
    body_wrench(
        t["elem_pos"][b], t["elem_normal"][b], t["elem_area"][b], t["elem_reach"][b],
        t["elem_patch"][b], t["coef"], t["alpha_y"], t["zeta"], t["surface_prm"],
        np.reshape(t["surface_grid"], (t["surface_nrow"], t["surface_ncol"])),
        np.reshape(t["region"], (2, 3)) if t["use_region"] else None,
        np.reshape(soil, -1)[:nsoil], rot, pos, omega, v_ref, p_ref, com, rows, body=k + 1,
    )  # fmt: skip
    return rows


def trajectory(cent, norm, area, reach, patch, coef, alpha_y: float, zeta: float,
               surface_z: float, rot, pos, lin_vel, ang_vel, point) -> np.ndarray:  # fmt: skip
    """RFT wrenches of a body along a prescribed trajectory under the flat surface at
    surface_z [m], no region: (T, 6) = force [N], moment [N m] about point[t], world frame.

    The body's elements as ``body_wrench``'s (body frame); rot (T, 3, 3) body -> world, pos
    (T, 3) body origin [m], lin_vel (T, 3) its velocity [m/s], ang_vel (T, 3) [rad/s], point
    (T, 3) [m]. One thread, no BLAS.
    """
    who = "trajectory"
    cent, norm, area, reach, patch = _body_elements(who, cent, norm, area, reach, patch)
    co = _coef(who, coef)
    pos = _in(who, "pos", pos, (None, 3))
    T = pos.shape[0]
    rot = _in(who, "rot", rot, (T, 3, 3))
    lin_vel = _in(who, "lin_vel", lin_vel, (T, 3))
    ang_vel = _in(who, "ang_vel", ang_vel, (T, 3))
    point = _in(who, "point", point, (T, 3))
    out = np.zeros((T, 6))
    library().mjrft_trajectory(
        _ptr(cent), _ptr(norm), _ptr(area), _ptr(reach), _ptr(patch), cent.shape[0], _ptr(co),
        co.shape[0], float(alpha_y), float(zeta), float(surface_z), _ptr(rot), _ptr(pos),
        _ptr(lin_vel), _ptr(ang_vel), _ptr(point), T, _ptr(out),
    )  # fmt: skip
    return out
