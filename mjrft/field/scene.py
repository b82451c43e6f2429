"""The granular scene a compiled MjModel describes in its ``<custom>`` section.

MJCF (all names start with ``mjrft:``; they survive compilation, unlike classes)::

    <custom>
      <text name="mjrft:material" data="glass_beads"/>   preset name, or instead:
      <numeric name="mjrft:zeta" data="330000"/>         Li generic set scaled by zeta [N/m^3],
      <numeric name="mjrft:coefficients" data="A00 A10 B11 B01 B-11 C11 C01 C-11 D10"/>
                                                         optional generic-form set with mjrft:zeta
      <text name="mjrft:model" data="treers2021"/>       force model: treers2021 (default) or
                                                         agarwal3d (mjrft.core.agarwal; its scale
                                                         matched to the material's)
      <numeric name="mjrft:mu_surf" data="10"/>          agarwal3d's intruder-medium friction,
                                                         0 to 100 (a warning without agarwal3d)
      <numeric name="mjrft:dynamic" data="1500 1"/>      dynamic RFT inertial term (off by
                                                         default): bulk density rho_c [kg/m^3]
                                                         and optional lambda (default 1); rho_c
                                                         to 25,000, lambda to 10
      <numeric name="mjrft:surface_z" data="0"/>         free-surface height [m] (default 0)
      <numeric name="mjrft:surface_slope" data="10 90"/> or a tilted plane through (0, 0,
                                                         surface_z): slope and downhill azimuth
                                                         from +x [degrees], slope 0-60, azimuth
                                                         -360..360
      <text name="mjrft:surface_hfield" data="dune"/>    or the surface of an <hfield> asset, placed
                                                         by the geom that uses it
      <numeric name="mjrft:region" data="xmin ymin zmin xmax ymax zmax"/>
                                                         optional box bounding the medium [m]
      <numeric name="mjrft:deform_cell" data="0.002"/>   the ground deforms and remembers, on a
                                                         grid of this cell [m] over the region
                                                         (mjrft.core.soil; needs mjrft:region)
      <numeric name="mjrft:repose" data="30"/>           its angle of repose [deg] (default: the
                                                         material's, mjrft.core.soil.REPOSE_DEG)
      <numeric name="mjrft:deform_every" data="1"/>      steps between its updates (default 1;
                                                         k > 1 is k times cheaper, the ground
                                                         lagging the intruders by up to k steps)
      <numeric name="mjrft:deform_travel" data="0.25"/>  instead, an update once the intruders
                                                         have travelled this many cells
                                                         (docs/terrain.md)
      <numeric name="mjrft:triangles" data="1000"/>      default triangles per primitive geom, or
      <numeric name="mjrft:tolerance" data="0.01"/>      a relative force tolerance instead (the
                                                         default: 0.01, counts by type and size)
      <text name="mjrft:low_speed" data="stick"/>        low-speed treatment: stick, free or off
      <numeric name="mjrft:stick_reach" data="4"/>       its reach (mjrft.field.lowspeed), default 4
      <numeric name="mjrft:watch_sinking" data="1"/>     0: no SinkingWarning for collision geoms
                                                         that are below the surface untagged
      <tuple name="mjrft:intruders">                     geoms (or bodies: all their geoms)
        <element objtype="geom" objname="shell" prm="4000"/>   prm: triangles (0 = default),
                                                         or a tolerance in (0, 1), e.g. 0.02
        <element objtype="body" objname="robot_foot" prm="0"/>
      </tuple>
      <text name="mjrft:intruders_subtree" data="leg"/>  and/or: every geom of these bodies and
                                                         their descendants ("world": the model's)
      <text name="mjrft:intruders_match" data="*foot*"/> every geom whose name matches a glob
      <text name="mjrft:intruders_collision" data="world"/>
                                                         every collision geom (contype or
                                                         conaffinity nonzero) of these subtrees
    </custom>

Imports mujoco only to read the model; no state.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import math
import warnings
from dataclasses import dataclass

import mujoco
import numpy as np

from mjrft.core import geometry, soil
from mjrft.core import surface as surface_mod
from mjrft.core.material import (
    AGARWAL_MU_SURF,
    MODELS,
    MU_SURF_MAX,
    PRESETS,
    FourierCoefficients,
    Material,
    warn_if_unusual_zeta,
)
from mjrft.core.surface import Surface
from mjrft.field.lowspeed import DEFAULT_REACH, MODES, LowSpeed

PREFIX = "mjrft:"
KEYS = {
    "text": (
        "material",
        "deform_cell",
        "low_speed",
        "surface_hfield",
        "model",
        "intruders_subtree",
        "intruders_match",
        "intruders_collision",
    ),
    "numeric": (
        "zeta",
        "coefficients",
        "surface_z",
        "surface_slope",
        "region",
        "triangles",
        "tolerance",
        "stick_reach",
        "max_triangles",
        "deform_cell",
        "repose",
        "deform_every",
        "deform_travel",
        "mu_surf",
        "dynamic",
        "watch_sinking",
    ),
    "tuple": ("intruders",),
}
COEFFICIENT_ORDER = ("A00", "A10", "B11", "B01", "B-11", "C11", "C01", "C-11", "D10")
SUPPORTED_GEOM_TYPES = {
    int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): "ellipsoid",
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder",
    int(mujoco.mjtGeom.mjGEOM_BOX): "box",
    int(mujoco.mjtGeom.mjGEOM_MESH): "mesh",
}


#: Prefix of the custom numeric fields that carry the engine plugin's tables
#: (``mjrft.field.plugin``); the scene reader leaves them alone.
ENGINE_PREFIX = "mjrft.granular:"


class SceneError(ValueError):
    """The MJCF scene description is invalid; the message names the element at fault."""


class SceneWarning(UserWarning):
    """The MJCF scene is legal but almost surely not what was meant; the message says why."""


#: A generic-form coefficient set whose alpha_z(0, pi/2) differs from 1 by more than this draws
#: a warning (the form is normalised to 1; Li's set gives 1.000).
GENERIC_NORM_TOLERANCE = 0.01
#: Memory per triangle [bytes] while a geom is meshed and checked (measured: the mesh checks
#: peak at 290 B per triangle under tracemalloc on a 327,680-face icosphere, plus the field's
#: body-frame copies), and per triangle and MjData of the running field (element forces and
#: scratch).
BYTES_PER_TRIANGLE, BYTES_PER_TRIANGLE_PER_DATA = 500, 48


@dataclass(frozen=True)
class Intruder:
    """One tagged geom: ids, names and resolution. Frames: geom frame for its elements."""

    geom: int
    name: str
    body: int
    body_name: str
    kind: str
    n_triangles: int | None  # None for meshes (their own triangles)
    tolerance: float | None = None  # the relative force tolerance n_triangles came from, if any


@dataclass(frozen=True)
class Scene:
    """Static description of the medium and the intruders, built once at load.

    Attributes:
      material: the medium.
      surface_z: free-surface height [m], world frame.
      region: (2, 3) [[xmin, ymin, zmin], [xmax, ymax, zmax]] world box of the medium, or None.
      intruders: tagged geoms in ascending geom id.
      low_speed: the low-speed treatment (mjrft.lowspeed).
      surface: the free surface (mjrft.core.surface; default the flat one at surface_z, which
        is otherwise its reference height).
      watch_sinking: report collision geoms of moving bodies that are not intruders when they
        are below the surface (mjrft.SinkingWarning; ``mjrft:watch_sinking``, default on).
    """

    material: Material
    surface_z: float
    region: np.ndarray | None
    intruders: tuple[Intruder, ...]
    low_speed: LowSpeed = dataclasses.field(default_factory=LowSpeed)
    surface: Surface | None = None
    watch_sinking: bool = True

    def __post_init__(self) -> None:
        if self.surface is None:
            object.__setattr__(self, "surface", surface_mod.flat(self.surface_z))


def _name(model: mujoco.MjModel, objtype: mujoco.mjtObj, i: int) -> str:
    return mujoco.mj_id2name(model, objtype, i) or f"<unnamed {objtype.name[6:].lower()} {i}>"


def _custom(model: mujoco.MjModel) -> dict[str, tuple[str, int]]:
    """{key: (kind, index)} of mjrft custom elements; rejects unknown mjrft: names."""
    found = {}
    sources = (
        ("text", mujoco.mjtObj.mjOBJ_TEXT, model.ntext),
        ("numeric", mujoco.mjtObj.mjOBJ_NUMERIC, model.nnumeric),
        ("tuple", mujoco.mjtObj.mjOBJ_TUPLE, model.ntuple),
    )
    for kind, objtype, n in sources:
        for i in range(n):
            name = mujoco.mj_id2name(model, objtype, i) or ""
            if name.startswith(ENGINE_PREFIX):  # the engine's tables (mjrft.field.plugin)
                continue
            if not name.startswith(PREFIX):
                _refuse_misspelt_prefix(kind, name)
                continue
            key = name[len(PREFIX) :]
            if key not in KEYS[kind]:
                valid = ", ".join(f"<{k} name='{PREFIX}{v}'>" for k, vs in KEYS.items() for v in vs)
                raise SceneError(f"unknown <{kind} name='{name}'> in <custom>; valid: {valid}")
            if key in found:  # deform_cell: a number or the text "auto"
                raise SceneError(
                    f"<{found[key][0]} name='{name}'> and <{kind} name='{name}'> both in <custom>: "
                    "give one"
                )
            found[key] = (kind, i)
    return found


def _refuse_misspelt_prefix(kind: str, name: str) -> None:
    """SceneError for a name that is almost surely meant as an mjrft element: 'mjrft' in any
    case, then ':', '_', '.', '-' or a space (MJRFT:region, mjrft_region, mjrft.low_speed)."""
    head, sep, key = name[:5], name[5:6], name[6:]
    if head.lower() == "mjrft" and sep in (":", "_", ".", "-", " ") and name[:6] != PREFIX:
        hint = f"; did you mean '{PREFIX}{key}'?" if key in KEYS[kind] else ""
        raise SceneError(
            f"<{kind} name='{name}'> in <custom> looks like an mjrft element, but mjrft reads "
            f"only names that start with '{PREFIX}' (lower case, a colon){hint}"
        )


def _numeric(model: mujoco.MjModel, idx: int) -> np.ndarray:
    adr, size = model.numeric_adr[idx], model.numeric_size[idx]
    return np.array(model.numeric_data[adr : adr + size], dtype=np.float64)


def _numeric_field(model, custom, key, sizes: tuple[int, ...], valid: str) -> np.ndarray | None:
    if key not in custom:
        return None
    data = _numeric(model, custom[key][1])
    if data.size not in sizes or not np.all(np.isfinite(data)):
        raise SceneError(
            f"<numeric name='{PREFIX}{key}'> has data {data.tolist()}; expected {valid}"
        )
    return data


def _text(model: mujoco.MjModel, idx: int) -> str:
    adr, size = model.text_adr[idx], model.text_size[idx]
    return bytes(model.text_data[adr : adr + size]).split(b"\0", 1)[0].decode().strip()


def material_from_model(model: mujoco.MjModel, custom: dict | None = None) -> Material | None:
    """The material the MJCF names, or None if it names none."""
    custom = _custom(model) if custom is None else custom
    if "material" in custom and ("zeta" in custom or "coefficients" in custom):
        raise SceneError(
            f"<custom> gives both {PREFIX}material and {PREFIX}zeta/{PREFIX}coefficients; "
            "use a preset name or zeta (+ optional coefficients), not both"
        )
    if "material" in custom:
        name = _text(model, custom["material"][1])
        if name not in PRESETS:
            raise SceneError(
                f"<text name='{PREFIX}material'> names unknown material {name!r}; "
                f"valid presets: {', '.join(sorted(PRESETS))}"
            )
        return Material.preset(name)
    if "coefficients" in custom and "zeta" not in custom:
        raise SceneError(f"{PREFIX}coefficients needs <numeric name='{PREFIX}zeta'> [N/m^3]")
    zeta = _numeric_field(model, custom, "zeta", (1,), "one number > 0, zeta in N/m^3")
    if zeta is None:
        return None
    where = f"<numeric name='{PREFIX}zeta'>"
    if not zeta[0] > 0:
        raise SceneError(f"{where} = {zeta[0]} must be > 0 [N/m^3]")
    try:
        warn_if_unusual_zeta(float(zeta[0]), where)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    coeffs = _numeric_field(
        model, custom, "coefficients", (9,), f"9 numbers: {' '.join(COEFFICIENT_ORDER)}"
    )
    if coeffs is None:
        return Material.generic(float(zeta[0]), name=f"mjcf generic (zeta={zeta[0]:g} N/m^3)")
    return _coefficients_material(coeffs, float(zeta[0]))


def _coefficients_material(coeffs: np.ndarray, zeta: float) -> Material:
    """The medium of mjrft:coefficients (generic form) scaled by mjrft:zeta, checked."""
    where = f"<numeric name='{PREFIX}coefficients'>"
    table = FourierCoefficients.from_mapping(dict(zip(COEFFICIENT_ORDER, coeffs, strict=True)))
    az_ref = float(table.alpha_z(0.0, np.pi / 2))
    if not az_ref > 0.0:
        raise SceneError(
            f"{where}: alpha_z(beta=0, gamma=pi/2) = {az_ref:g} must be > 0 (a horizontal plate "
            "pushed down must be resisted); the generic form has it equal to 1"
        )
    material = Material._from_fourier(table, zeta, "mjcf coefficients", "MJCF <custom>")
    try:
        material.check(where)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    if abs(az_ref - 1.0) > GENERIC_NORM_TOLERANCE:
        warnings.warn(
            f"{where}: alpha_z(beta=0, gamma=pi/2) = {az_ref:g}, not 1: a generic-form set is "
            f"normalised to 1, so the medium is {az_ref:g} x mjrft:zeta strong; for a table in "
            "N/cm^3 use Material.from_table",
            SceneWarning,
            stacklevel=4,
        )
    return material


def scene_from_model(
    model: mujoco.MjModel,
    material: Material | str | None = None,
    *,
    n_triangles: int | None = None,
    tolerance: float | None = None,
    low_speed: str | None = None,
    stick_reach: float | None = None,
    deform_cell: float | str | None = None,
    repose: float | None = None,
    deform_every: int | None = None,
    deform_travel: float | None = None,
    dynamic: float | tuple[float, float] | None = None,
    intruders: dict[str, str | list[str]] | None = None,
    watch_sinking: bool | None = None,
) -> Scene:
    """Read and validate the scene; the keyword arguments override the MJCF's.

    dynamic: the dynamic RFT term's rho_c [kg/m^3], or (rho_c, lambda), as
    ``mjrft:dynamic``; 0 turns off a term the MJCF asks for.

    deform_cell [m], repose [deg], deform_every [steps] and deform_travel [cells]: the
    deforming ground (``mjrft:deform_cell``, ``mjrft:repose``, ``mjrft:deform_every``,
    ``mjrft:deform_travel``); deform_cell = 0 turns off a deformation the MJCF asks for.

    tolerance: relative RMS force error per primitive geom; its triangle count comes from
    ``mjrft.geometry.triangles_for_tolerance``. low_speed ("stick", "free" or "off") and
    stick_reach: the low-speed treatment (``mjrft.field.lowspeed``).

    intruders: the geoms that feel the medium, instead of the MJCF's: a dict whose keys are
    among INTRUDER_FORMS (geoms, bodies, subtree, match, collision), each a list of names or
    one string of names separated by spaces; its geoms are the union of the selections.

    watch_sinking: False turns off the report of untagged collision geoms below the surface
    (``mjrft:watch_sinking``).
    """
    if n_triangles is not None and tolerance is not None:
        raise SceneError("give at most one of n_triangles and tolerance")
    if tolerance is not None:
        geometry.triangles_for_tolerance(tolerance)  # checks it (ValueError) before the scene
    if n_triangles is not None and (
        not isinstance(n_triangles, int | np.integer) or n_triangles < geometry.MIN_TRIANGLES
    ):
        raise SceneError(
            f"n_triangles = {n_triangles!r}: expected an integer >= {geometry.MIN_TRIANGLES}"
        )
    custom = _custom(model)
    mjcf_material = material_from_model(model, custom)
    if isinstance(material, str):  # a preset's name, as the environments accept
        try:
            material = Material.preset(material)
        except ValueError as exc:
            raise SceneError(f"material={material!r}: {exc}") from None
    elif material is not None and not isinstance(material, Material):
        raise SceneError(
            f"material must be a mjrft.Material or a preset name ({', '.join(sorted(PRESETS))}), "
            f"got {type(material).__name__}"
        )
    material = material or mjcf_material
    if material is None:
        raise SceneError(
            f"no material: add <text name='{PREFIX}material' data='glass_beads'/> (presets: "
            f"{', '.join(sorted(PRESETS))}) or <numeric name='{PREFIX}zeta' data='...'/> to "
            "<custom>, or pass material= to GranularField"
        )
    material = _dynamic_term(model, custom, _force_model(model, custom, material), dynamic)
    surface = _numeric_field(model, custom, "surface_z", (1,), "one finite number [m]")
    surface_z = 0.0 if surface is None else float(surface[0])
    region = _region(model, custom)
    free_surface = _surface(model, custom, surface_z, region)
    tagged = _tagged(model, custom, intruders)
    free_surface = _deforming(model, custom, free_surface, region, material, tagged,
                              (deform_cell, repose, deform_every, deform_travel))  # fmt: skip
    _warn_if_steep(model, custom, material, repose)
    default_tri, default_tol = _default_resolution(model, custom)
    cap = _numeric_field(model, custom, "max_triangles", (1,), "one integer >= 12")
    cap = geometry.MAX_TRIANGLES if cap is None else int(cap[0])
    intruders = _intruders(model, tagged, int(default_tri), default_tol, cap)
    _warn_if_suspicious(model, intruders)
    if n_triangles is not None or tolerance is not None:
        intruders = tuple(
            i
            if i.kind == "mesh"
            else dataclasses.replace(
                i,
                n_triangles=int(n_triangles)
                if tolerance is None
                else geometry.triangles_for_tolerance(tolerance, i.kind, model.geom_size[i.geom]),
                tolerance=tolerance,
            )
            for i in intruders
        )
    return Scene(
        material, free_surface.z0, region, intruders,
        _low_speed(model, custom, low_speed, stick_reach), free_surface,
        _watch_sinking(model, custom, watch_sinking),
    )  # fmt: skip


def _watch_sinking(model, custom, given: bool | None) -> bool:
    """Whether untagged geoms below the surface are reported: the argument, else the MJCF's
    ``mjrft:watch_sinking`` (0 or 1), else on."""
    if given is not None:
        if not isinstance(given, bool | np.bool_):
            raise SceneError(f"watch_sinking = {given!r}; expected True or False")
        return bool(given)
    value = _numeric_field(model, custom, "watch_sinking", (1,), "one number, 0 or 1")
    if value is None:
        return True
    if value[0] not in (0.0, 1.0):
        raise SceneError(f"<numeric name='{PREFIX}watch_sinking'> = {value[0]:g}; expected 0 or 1")
    return bool(value[0])


#: Steepest tilted-plane surface accepted [degrees]: dry granular media do not stand steeper
#: than their angle of repose, 20-40 degrees for sands and glass beads (docs/field.md).
MAX_SLOPE_DEG = 60.0
#: Largest |azimuth| of mjrft:surface_slope accepted [degrees]: one turn each way.
MAX_AZIMUTH_DEG = 360.0
DEG = math.pi / 180.0  # rad per degree: the MJCF gives angles in degrees


def _surface(model, custom, surface_z: float, region) -> Surface:
    """The free surface: flat at surface_z, the tilted plane of mjrft:surface_slope, or the
    height field of mjrft:surface_hfield."""
    if "surface_slope" in custom and "surface_hfield" in custom:
        raise SceneError(
            f"<custom> gives both {PREFIX}surface_slope and {PREFIX}surface_hfield; use one"
        )
    if "surface_slope" in custom:
        where = f"<numeric name='{PREFIX}surface_slope'>"
        valid = "2 numbers, finite angles in degrees: slope and downhill azimuth from +x"
        slope, azimuth = _numeric_field(model, custom, "surface_slope", (2,), valid)
        if not 0.0 <= slope <= MAX_SLOPE_DEG:
            raise SceneError(
                f"{where} slope = {slope} degrees; expected 0 to {MAX_SLOPE_DEG:g} (a granular "
                "slope stands at most at its angle of repose, 20-40 degrees)"
            )
        if not abs(azimuth) <= MAX_AZIMUTH_DEG:
            raise SceneError(
                f"{where} azimuth = {azimuth:g} degrees; expected an angle in degrees from "
                f"-{MAX_AZIMUTH_DEG:g} to {MAX_AZIMUTH_DEG:g} (one turn each way gives every "
                "direction; a larger angle is no direction anyone means, and a huge one reduces "
                "to nothing meaningful in floating point)"
            )
        return surface_mod.plane(surface_z, slope * DEG, azimuth * DEG)
    if "surface_hfield" in custom:
        if "surface_z" in custom:
            raise SceneError(
                f"<custom> gives both {PREFIX}surface_z and {PREFIX}surface_hfield; the height "
                "field's geom places the surface"
            )
        return _hfield_surface(model, _text(model, custom["surface_hfield"][1]), region)
    return surface_mod.flat(surface_z)


def _warn_if_steep(model, custom, material: Material, repose: float | None) -> None:
    """SceneWarning for a mjrft:surface_slope steeper than the medium's angle of repose (the
    repose override, else mjrft:repose, else ``soil.repose_of`` the material): such sand would
    flow, and the static plane does not."""
    if "surface_slope" not in custom:
        return
    slope = float(_numeric(model, custom["surface_slope"][1])[0])
    if repose is None:
        value = _numeric(model, custom["repose"][1]) if "repose" in custom else None
        name = material.name.removesuffix(" (agarwal3d)")
        repose = soil.repose_of(name) if value is None or value.size != 1 else float(value[0])
    if slope > repose:
        warnings.warn(
            f"<numeric name='{PREFIX}surface_slope'> slope = {slope:g} degrees is steeper than "
            f"the medium's angle of repose, {repose:g} degrees ({material.name}): such a slope "
            "of sand would flow, while the surface here stays a static plane",
            SceneWarning,
            stacklevel=4,
        )


def _hfield_surface(model, name: str, region) -> Surface:
    """The surface of hfield `name` as MuJoCo's collision builds it, placed by its geom."""
    where = f"<text name='{PREFIX}surface_hfield'> = {name!r}"
    h = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_HFIELD, name)
    if h < 0:
        names = [_name(model, mujoco.mjtObj.mjOBJ_HFIELD, i) for i in range(model.nhfield)]
        raise SceneError(f"{where}: no such hfield (hfields: {', '.join(names) or 'none'})")
    users = np.flatnonzero(
        (model.geom_type == mujoco.mjtGeom.mjGEOM_HFIELD) & (model.geom_dataid == h)
    )
    if len(users) != 1:
        raise SceneError(
            f"{where}: {len(users)} geoms use it; exactly one <geom type='hfield' hfield="
            f"'{name}'> on the worldbody must place it (contype='0' conaffinity='0' if the "
            "intruders should meet only the medium)"
        )
    g = int(users[0])
    geom = _name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
    if model.geom_bodyid[g] != 0:
        raise SceneError(f"{where}: its geom {geom!r} must be on the worldbody (static)")
    if not np.allclose(model.geom_quat[g], [1.0, 0.0, 0.0, 0.0], atol=1e-12):
        raise SceneError(
            f"{where}: its geom {geom!r} is rotated (quat {model.geom_quat[g].tolist()}); the "
            "surface needs the hfield's z axis along world z and its x axis along world x"
        )
    rx, ry, top, _ = (float(v) for v in model.hfield_size[h])
    nrow, ncol = int(model.hfield_nrow[h]), int(model.hfield_ncol[h])
    if nrow < 2 or ncol < 2:
        raise SceneError(f"{where}: it has {nrow} x {ncol} samples; a surface needs 2 x 2 or more")
    adr = int(model.hfield_adr[h])
    # float32 in MjModel; heights in float64 as MuJoCo's collision computes them.
    data = np.asarray(model.hfield_data[adr : adr + nrow * ncol], dtype=np.float64)
    data = data.reshape(nrow, ncol)
    x, y, z = (float(v) for v in model.geom_pos[g])
    # MuJoCo's collision: vertex (r, c) at (c dx - rx, r dy - ry, data[r, c] top), geom frame.
    dx, dy = 2.0 * rx / (ncol - 1), 2.0 * ry / (nrow - 1)
    out = surface_mod.grid(z + top * data, x - rx, y - ry, dx, dy)
    if region is not None:
        lo, hi = region[0, :2], region[1, :2]
        if lo[0] < x - rx or lo[1] < y - ry or hi[0] > x + rx or hi[1] > y + ry:
            raise SceneError(
                f"{where}: the hfield covers x {x - rx:g}..{x + rx:g}, y {y - ry:g}..{y + ry:g} "
                f"[m] but {PREFIX}region spans x {lo[0]:g}..{hi[0]:g}, y {lo[1]:g}..{hi[1]:g}; "
                "enlarge the hfield or shrink the region"
            )
    return out


def _force_model(model: mujoco.MjModel, custom: dict, material: Material) -> Material:
    """The material under the force model mjrft:model names (``material.MODELS``; default
    treers2021), with mjrft:mu_surf for agarwal3d."""
    name = _text(model, custom["model"][1]) if "model" in custom else None
    where = f"<text name='{PREFIX}model'> = {name!r}"
    if name is not None and name not in MODELS:
        raise SceneError(f"{where}: unknown force model; valid: {', '.join(MODELS)}")
    if name != "agarwal3d" and "mu_surf" in custom:
        warnings.warn(
            f"<numeric name='{PREFIX}mu_surf'> does nothing: it is the agarwal3d model's "
            f"intruder-medium friction, and the model is {name or 'treers2021 (the default)'}; "
            f"add <text name='{PREFIX}model' data='agarwal3d'/> or remove it",
            SceneWarning,
            stacklevel=4,
        )
    if name is None:
        return material
    mu = _numeric_field(
        model, custom, "mu_surf", (1,), f"one friction coefficient from 0 to {MU_SURF_MAX:g}"
    )
    try:
        return material.with_model(name, mu_surf=AGARWAL_MU_SURF if mu is None else float(mu[0]))
    except ValueError as exc:
        raise SceneError(f"{where}: {exc}") from None


def _dynamic_term(model: mujoco.MjModel, custom: dict, material: Material, override) -> Material:
    """The material with the dynamic RFT term that override (rho_c [kg/m^3] or (rho_c,
    lambda)) or else mjrft:dynamic asks for."""
    where = "dynamic"
    if override is None:
        data = _numeric_field(
            model, custom, "dynamic", (1, 2), "rho_c [kg/m^3] >= 0 and optional lambda >= 0"
        )
        where = f"<numeric name='{PREFIX}dynamic'>"
    else:
        data = np.atleast_1d(np.asarray(override, dtype=float))
        if data.size not in (1, 2):
            raise SceneError(f"dynamic = {override!r}: expected rho_c or (rho_c, lambda)")
    if data is None:
        return material
    try:
        return material.with_dynamic(float(data[0]), float(data[1]) if data.size == 2 else 1.0)
    except ValueError as exc:
        raise SceneError(f"{where}: {exc}") from None


def _deforming(model, custom, initial: Surface, region, material, tagged, options) -> Surface:
    """The deforming ground over the region if mjrft:deform_cell (or the cell of options, the
    overrides (cell [m] or "auto", repose [deg], every [steps], travel [cells]), None where not
    given) asks for it, else the initial surface; checks the cell, the grid's size, the angle of
    repose, the update rule. tagged: the intruders' geom ids ("auto" sizes the cell by them)."""
    cell, repose, every, travel = options
    where = "deform_cell"
    if cell is None and custom.get("deform_cell", ("",))[0] == "text":
        where = f"<text name='{PREFIX}deform_cell'>"
        cell = _text(model, custom["deform_cell"][1])
    elif cell is None:
        where = f"<numeric name='{PREFIX}deform_cell'>"
        value = _numeric_field(model, custom, "deform_cell", (1,), "one cell size [m] > 0")
        cell = None if value is None else float(value[0])
    if isinstance(cell, str):
        if cell != "auto":
            raise SceneError(f"{where} = {cell!r}: expected a cell size [m] > 0 or 'auto'")
        if region is None:
            raise SceneError(
                f"{where} = 'auto': the deforming ground covers the medium's region: add "
                f"<numeric name='{PREFIX}region' data='xmin ymin zmin xmax ymax zmax'/>"
            )
        cell = _auto_cell(model, tagged, region)
    if cell is None or cell == 0.0:
        _warn_if_unused(model, custom, cell, {"repose": repose, "deform_every": every,
                                              "deform_travel": travel})  # fmt: skip
        return initial
    if not (math.isfinite(cell) and cell > 0.0):
        raise SceneError(f"{where} = {cell!r}: expected a cell size > 0 [m] (e.g. 0.002) or 'auto'")
    if region is None:
        raise SceneError(
            f"{where}: the deforming ground covers the medium's region: add <numeric name='"
            f"{PREFIX}region' data='xmin ymin zmin xmax ymax zmax'/>"
        )
    nrow, ncol = soil.grid_shape(region, cell)
    if nrow * ncol > soil.MAX_VERTICES:
        raise SceneError(
            f"{where} = {cell:g} m: the grid over {PREFIX}region would have {nrow} x {ncol} = "
            f"{nrow * ncol:,} vertices ({32 * nrow * ncol / 2**20:.0f} MiB per MjData), over the "
            f"cap of {soil.MAX_VERTICES:,}; use a coarser cell or a smaller region"
        )
    if repose is None:
        value = _numeric_field(model, custom, "repose", (1,), "one angle in (0, 90) [deg]")
        repose = soil.repose_of(material.name) if value is None else float(value[0])
    if not 0.0 < repose < 90.0:
        raise SceneError(
            f"angle of repose = {repose!r} deg ({PREFIX}repose): expected a value in (0, 90) "
            "degrees (dry sands and glass beads: 20-40)"
        )
    every, travel = _update_rule(model, custom, every, travel)
    return soil.grid_over(initial, region, cell, repose, every, travel)


def _auto_cell(model: mujoco.MjModel, tagged, region: np.ndarray) -> float:
    """The cell [m] of deform_cell = "auto": soil.auto_cell of the intruders' widths (the
    smallest extent of each geom's bounding box), coarsened with a SceneWarning if the grid
    over the region would pass soil.MAX_VERTICES."""
    if not tagged:
        raise SceneError("deform_cell = 'auto': there are no intruders to size the cell by")
    geoms = list(tagged)
    widths = [2.0 * float(model.geom_aabb[g, 3:].min()) for g in geoms]
    cell = soil.auto_cell(widths)
    fitted = soil.fit_cell(region, cell)
    if fitted > cell:
        narrowest = geoms[int(np.argmin(widths))]
        narrow = (
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, narrowest) or f"geom {narrowest}"
        )
        warnings.warn(
            f"deform_cell = 'auto': {soil.CELLS_ACROSS} cells across the narrowest intruder "
            f"('{narrow}', {min(widths) * 1e3:.3g} mm) would be {cell * 1e3:.3g} mm, and the grid "
            f"over {PREFIX}region would pass {soil.MAX_VERTICES:,} vertices; using "
            f"{fitted * 1e3:.3g} mm ({min(widths) / fitted:.1f} cells across: coarser than the "
            "error docs/terrain.md states): give a smaller region or an explicit cell",
            SceneWarning,
            stacklevel=5,
        )
    return fitted


def _update_rule(model, custom, every, travel) -> tuple[int, float]:
    """(every [steps], travel [cells]) of the deforming ground's updates from the overrides
    every and travel (None: not given) and the MJCF's mjrft:deform_every and
    mjrft:deform_travel: every k >= 1 steps, or (every 0) once the intruders may have travelled
    `travel` cells. An override replaces the MJCF's rule whichever key it uses; two keys from
    one source are refused."""
    if every is not None or travel is not None:
        source = "deform_every and deform_travel"
    else:
        source = f"{PREFIX}deform_every and {PREFIX}deform_travel"
        value = _numeric_field(model, custom, "deform_every", (1,), "one whole number >= 1")
        every = None if value is None else float(value[0])
        value = _numeric_field(model, custom, "deform_travel", (1,), "one number of cells >= 0")
        travel = None if value is None else float(value[0])
    if every is not None and travel is not None:
        raise SceneError(
            f"{source} both given ({every!r} steps, {travel!r} cells): the ground follows the "
            "intruders either every k steps or once they have travelled so many cells; give one"
        )
    if every is not None and not (every == int(every) and every >= 1):
        raise SceneError(
            f"deform_every = {every!r} ({PREFIX}deform_every): expected a whole number of steps "
            ">= 1 between updates of the ground (1: every step)"
        )
    if travel is not None and not (math.isfinite(travel) and travel >= 0.0):
        raise SceneError(
            f"deform_travel = {travel!r} ({PREFIX}deform_travel): expected a number of cells "
            ">= 0 the intruders travel between updates of the ground (0: every step)"
        )
    if travel:
        return 0, float(travel)
    return 1 if every is None else int(every), 0.0


def _warn_if_unused(model, custom, cell, overrides: dict) -> None:
    """SceneWarning for each setting of the deforming ground given without one (cell: the
    deform_cell override, 0 where it turns off the MJCF's ground; the MJCF's settings then go
    unwarned, since the override switches them off on purpose). overrides: the settings' names
    and override values (None: not given)."""
    for key, override in overrides.items():
        if override is not None:
            given = f"{key} = {override!r}"
        elif key in custom and cell is None:
            given = f"<numeric name='{PREFIX}{key}'>"
        else:
            continue
        warnings.warn(
            f"{given} does nothing: there is no deforming ground (it is a setting of the "
            f"ground that {PREFIX}deform_cell or deform_cell turns on); remove it or give a "
            "cell",
            SceneWarning,
            stacklevel=5,
        )


def _region(model: mujoco.MjModel, custom: dict) -> np.ndarray | None:
    """(2, 3) world box of the medium from mjrft:region, or None."""
    region = _numeric_field(
        model, custom, "region", (6,), "6 finite numbers: xmin ymin zmin xmax ymax zmax [m]"
    )
    if region is None:
        return None
    region = region.reshape(2, 3)
    if not np.all(region[0] < region[1]):
        raise SceneError(
            f"<numeric name='{PREFIX}region'> = {region.ravel().tolist()}: each min must be "
            "below its max (xmin ymin zmin xmax ymax zmax)"
        )
    return region


def _default_resolution(model: mujoco.MjModel, custom: dict) -> tuple[float, float | None]:
    """(default triangles per primitive geom, the tolerance it comes from or None): the MJCF's
    ``mjrft:triangles``, or a tolerance (``mjrft:tolerance``, else geometry.DEFAULT_TOLERANCE)
    whose rule gives each primitive its count by type and size."""
    tri = _numeric_field(model, custom, "triangles", (1,), "one integer >= 12")
    tol = _numeric_field(model, custom, "tolerance", (1,), "one number in (0, 1)")
    if tri is not None and tol is not None:
        raise SceneError(
            f"<custom> gives both {PREFIX}triangles and {PREFIX}tolerance; use one of them"
        )
    default_tol = None
    if tri is None:  # a tolerance: the MJCF's, else the default (geometry.DEFAULT_TOLERANCE)
        value = geometry.DEFAULT_TOLERANCE if tol is None else tol[0]
        try:
            default_tri = geometry.triangles_for_tolerance(value)
        except ValueError as exc:
            raise SceneError(f"<numeric name='{PREFIX}tolerance'>: {exc}") from None
        default_tol = float(value)
    else:
        default_tri = tri[0]
    if default_tri != int(default_tri) or default_tri < geometry.MIN_TRIANGLES:
        raise SceneError(
            f"<numeric name='{PREFIX}triangles'> = {default_tri}: expected an integer >= "
            f"{geometry.MIN_TRIANGLES}"
        )
    return default_tri, default_tol


def _low_speed(model, custom, mode: str | None, reach: float | None) -> LowSpeed:
    """The low-speed treatment from the MJCF, overridden by the arguments given."""
    if mode is None:
        mode = _text(model, custom["low_speed"][1]) if "low_speed" in custom else "stick"
        if mode not in MODES:
            raise SceneError(
                f"<text name='{PREFIX}low_speed'> = {mode!r}; expected one of {', '.join(MODES)}"
            )
    if reach is None:
        r = _numeric_field(model, custom, "stick_reach", (1,), "one number in (0, 1000]")
        reach = DEFAULT_REACH if r is None else float(r[0])
        if r is not None and not 0.0 < reach <= 1e3:
            raise SceneError(
                f"<numeric name='{PREFIX}stick_reach'> = {reach}; expected a number in (0, 1000]"
            )
    try:
        return LowSpeed(mode, reach)
    except ValueError as exc:
        raise SceneError(str(exc)) from None


#: The ways of selecting intruders: by geom or body name (the ``mjrft:intruders`` tuple), and by
#: ``<text name="mjrft:intruders_FORM">`` for the rest; the keys of SceneOptions.intruders.
INTRUDER_FORMS = ("geoms", "bodies", "subtree", "match", "collision")
TEXT_FORMS = ("subtree", "match", "collision")


def _tagged(model: mujoco.MjModel, custom: dict, given: dict | None) -> dict[int, float]:
    """{geom: prm} of the intruders: those of given (SceneOptions.intruders) if any, else the
    MJCF's tuple and texts; a geom selected by several forms is counted once (the tuple's prm
    kept)."""
    if given is not None:
        if not isinstance(given, dict) or not given:
            raise SceneError(
                f"intruders={given!r}: expected a non-empty dict with keys among "
                f"{', '.join(INTRUDER_FORMS)}, e.g. {{'match': '*foot*'}}"
            )
        unknown = sorted(set(given) - set(INTRUDER_FORMS))
        if unknown:
            raise SceneError(
                f"intruders: unknown key(s) {', '.join(map(repr, unknown))}; valid: "
                f"{', '.join(INTRUDER_FORMS)}"
            )
        tagged: dict[int, float] = {}
        for form, value in given.items():
            words = value.split() if isinstance(value, str) else [str(v) for v in value]
            if not words:
                raise SceneError(f"intruders[{form!r}] is empty: give at least one name")
            for g in _select(model, form, words, f"intruders[{form!r}]"):
                tagged.setdefault(g, 0.0)
        return tagged
    texts = [f for f in TEXT_FORMS if f"intruders_{f}" in custom]
    if "intruders" not in custom and not texts:
        raise SceneError(
            f"no intruding geoms: add <tuple name='{PREFIX}intruders'> with "
            "<element objtype='geom' objname='...' prm='0'/> entries, or "
            f"<text name='{PREFIX}intruders_match' data='*foot*'/> (or intruders_subtree, "
            "intruders_collision), to <custom>; or pass intruders= (docs/mjcf.md)"
        )
    tagged = _tuple_tags(model, custom["intruders"][1]) if "intruders" in custom else {}
    for form in texts:
        where = f"<text name='{PREFIX}intruders_{form}'>"
        words = _text(model, custom[f"intruders_{form}"][1]).split()
        if not words:
            raise SceneError(f"{where} is empty: give at least one name")
        for g in _select(model, form, words, where):
            tagged.setdefault(g, 0.0)
    return tagged


def _listing(names: list[str], limit: int = 40) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f", ... ({len(names) - limit} more)" if len(names) > limit else "") or "none"


def _select(model: mujoco.MjModel, form: str, words: list[str], where: str) -> list[int]:
    """The geoms one selection form picks by these names or patterns; a word that picks
    nothing is refused, naming it and what exists."""
    names = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(model.ngeom)
    ]
    geom_names = [n for n in names if n]
    body_names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(model.nbody)]
    out: list[int] = []
    for w in words:
        if form == "match":
            picked = [g for g, n in enumerate(names) if n and fnmatch.fnmatchcase(n, w)]
            if not picked:
                raise SceneError(
                    f"{where}: pattern '{w}' matches no geom name; geoms: {_listing(geom_names)}"
                )
        elif form == "geoms":
            g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, w)
            if g < 0:
                raise SceneError(f"{where}: no geom named '{w}'; geoms: {_listing(geom_names)}")
            picked = [g]
        else:
            b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, w)
            if b < 0:
                raise SceneError(f"{where}: no body named '{w}'; bodies: {_listing(body_names)}")
            if form == "bodies":
                picked = [g for g in range(model.ngeom) if model.geom_bodyid[g] == b]
            else:  # subtree, collision: the body's and its descendants', never the world's own
                inside = _subtree(model, b)
                picked = [
                    g
                    for g in range(model.ngeom)
                    if model.geom_bodyid[g] != 0 and inside[model.geom_bodyid[g]]
                ]
                if form == "collision":
                    picked = [
                        g for g in picked if model.geom_contype[g] or model.geom_conaffinity[g]
                    ]
            if not picked:
                what = {
                    "bodies": "has no geoms",
                    "subtree": "has no geoms in its subtree",
                    "collision": "has no collision geom (contype or conaffinity nonzero) in its "
                    "subtree",
                }[form]
                raise SceneError(f"{where}: body '{w}' {what}")
        out.extend(picked)
    return out


def _subtree(model: mujoco.MjModel, root: int) -> list[bool]:
    """Per body: True if it is root or one of its descendants (parents precede children)."""
    inside = [False] * model.nbody
    inside[root] = True
    for b in range(1, model.nbody):
        inside[b] = inside[b] or inside[int(model.body_parentid[b])]
    return inside


def _tuple_tags(model: mujoco.MjModel, t: int) -> dict[int, float]:
    """{geom: prm} of the mjrft:intruders tuple; a geom listed twice is refused."""
    adr, size = model.tuple_adr[t], model.tuple_size[t]
    tagged: dict[int, float] = {}
    entry: dict[int, int] = {}  # geom -> the element that tagged it
    for k in range(adr, adr + size):
        objtype, objid, prm = model.tuple_objtype[k], model.tuple_objid[k], model.tuple_objprm[k]
        if not math.isfinite(prm):
            raise SceneError(
                f"{PREFIX}intruders element {k - adr} has prm = {prm}; expected 0 (default), a "
                "tolerance in (0, 1) or an integer triangle count"
            )
        if objtype == mujoco.mjtObj.mjOBJ_GEOM:
            geoms = [int(objid)]
        elif objtype == mujoco.mjtObj.mjOBJ_BODY:
            geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == objid]
            if not geoms:
                raise SceneError(
                    f"{PREFIX}intruders: body '{_name(model, mujoco.mjtObj.mjOBJ_BODY, objid)}' "
                    "has no geoms"
                )
        else:
            raise SceneError(
                f"{PREFIX}intruders element {k - adr} has objtype "
                f"'{mujoco.mjtObj(objtype).name[6:].lower()}'; use objtype='geom' or 'body'"
            )
        for g in geoms:
            if g in entry:
                raise SceneError(
                    f"geom '{_name(model, mujoco.mjtObj.mjOBJ_GEOM, g)}' is tagged twice in "
                    f"<tuple name='{PREFIX}intruders'> (elements {entry[g]} and {k - adr}); "
                    "tag each geom once (a body element tags all its geoms)"
                )
            tagged[g] = float(prm)
            entry[g] = k - adr
    if not tagged:
        raise SceneError(f"<tuple name='{PREFIX}intruders'> is empty: tag at least one geom")
    return tagged


def _intruders(
    model: mujoco.MjModel,
    tagged: dict[int, float],
    default_tri: int,
    default_tol: float | None,
    cap: int,
) -> tuple[Intruder, ...]:
    out = []
    for g, prm in sorted(tagged.items()):
        name = _name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        gtype = int(model.geom_type[g])
        kind = SUPPORTED_GEOM_TYPES.get(gtype)
        if kind is None:
            raise SceneError(
                f"geom '{name}' has type '{mujoco.mjtGeom(gtype).name[7:].lower()}', which RFT "
                f"cannot mesh; supported: {', '.join(SUPPORTED_GEOM_TYPES.values())}"
            )
        tol = default_tol if prm == 0 else None
        rule = kind if kind in geometry.TOLERANCE_RULES else None
        size = model.geom_size[g]
        if 0 < prm < 1:  # a relative force tolerance for this geom
            tol = prm
            try:
                prm = geometry.triangles_for_tolerance(prm, rule, size)
            except ValueError as exc:
                raise SceneError(f"geom '{name}': prm={tol:g}: {exc}") from None
        elif prm == 0 and tol is not None and rule is not None:  # the scene's, by type
            try:
                prm = geometry.triangles_for_tolerance(tol, rule, size)
            except ValueError as exc:
                raise SceneError(f"geom '{name}': tolerance {tol:g}: {exc}") from None
        elif prm < 0 or prm != int(prm) or (0 < prm < geometry.MIN_TRIANGLES):
            raise SceneError(
                f"geom '{name}': prm={prm:g} must be 0 (default), a tolerance in (0, 1) or an "
                f"integer triangle count >= "
                f"{geometry.MIN_TRIANGLES}"
            )
        if kind == "mesh" and prm != 0:
            raise SceneError(
                f"geom '{name}' is a mesh: it uses its own triangles, so prm must be 0 "
                f"(got {prm:g})"
            )
        count = int(model.mesh_facenum[model.geom_dataid[g]]) if kind == "mesh" else int(prm)
        if count > cap:
            raise SceneError(
                f"geom '{name}' would have {count:,} triangles, above the cap of {cap:,} "
                f"(<numeric name='{PREFIX}max_triangles'>): it would take about "
                f"{count * BYTES_PER_TRIANGLE / 1e9:.1f} GB to check and mesh, and "
                f"{count * BYTES_PER_TRIANGLE_PER_DATA / 1e6:.0f} MB per MjData; decimate the "
                "mesh, or raise the cap if the memory is there"
            )
        body = int(model.geom_bodyid[g])
        if body == 0:
            raise SceneError(f"geom '{name}' belongs to the world body, which cannot move")
        out.append(
            Intruder(
                geom=g,
                name=name,
                body=body,
                body_name=_name(model, mujoco.mjtObj.mjOBJ_BODY, body),
                kind=kind,
                n_triangles=None if kind == "mesh" else int(prm or default_tri),
                tolerance=None if kind == "mesh" else tol,
            )
        )
    return tuple(out)


def _warn_if_suspicious(model: mujoco.MjModel, intruders: tuple[Intruder, ...]) -> None:
    """SceneWarning for tagged geoms that are legal but almost surely a mistake: on a body
    welded to the world (the force moves nothing), or colliding with the ground (contacts carry
    the body and the medium's force reads near 0)."""
    ground = [
        h
        for h in range(model.ngeom)
        if int(model.geom_type[h])
        in (int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_HFIELD))
    ]
    contacts = not model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    for intr in intruders:
        g = intr.geom
        if model.body_weldid[intr.body] == 0:
            warnings.warn(
                f"geom '{intr.name}' is tagged, but its body '{intr.body_name}' is welded to the "
                "world (no joint between them): its RFT force moves nothing",
                SceneWarning,
                stacklevel=4,
            )
        hits = [
            h
            for h in ground
            if contacts
            and model.geom_bodyid[h] != intr.body
            and (
                model.geom_contype[g] & model.geom_conaffinity[h]
                or model.geom_contype[h] & model.geom_conaffinity[g]
            )
        ]
        if hits:
            warnings.warn(
                f"geom '{intr.name}' is tagged and also collides with "
                f"'{_name(model, mujoco.mjtObj.mjOBJ_GEOM, hits[0])}' (contype/conaffinity): "
                "contacts will carry the body and the medium's force will read near 0; set "
                "contype and conaffinity to 0 on the intruder or on the ground (docs/mjcf.md)",
                SceneWarning,
                stacklevel=4,
            )


def geom_elements(model: mujoco.MjModel, intruder: Intruder):
    """ElementSet of a tagged geom in its geom frame (MuJoCo re-centres meshes to that frame)."""
    g = intruder.geom
    if intruder.kind == "mesh":
        mid = model.geom_dataid[g]
        va, vn = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        fa, fn = model.mesh_faceadr[mid], model.mesh_facenum[mid]
        verts = np.array(model.mesh_vert[va : va + vn], dtype=np.float64)
        faces = np.array(model.mesh_face[fa : fa + fn], dtype=np.int64)
        mesh_name = _name(model, mujoco.mjtObj.mjOBJ_MESH, mid)
        return geometry.from_mesh(
            verts, faces, name=f"mesh '{mesh_name}' of geom '{intruder.name}'"
        )
    try:
        return geometry.primitive(
            intruder.kind, model.geom_size[g], n_triangles=intruder.n_triangles
        )
    except ValueError as exc:
        raise SceneError(f"geom '{intruder.name}': {exc}") from exc
