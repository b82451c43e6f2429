"""The granular scene a compiled MjModel describes in its ``<custom>`` section.

MJCF (all names start with ``mjrft:``; they survive compilation, unlike classes)::

    <custom>
      <text name="mjrft:material" data="glass_beads"/>   preset name, or instead:
      <numeric name="mjrft:zeta" data="330000"/>         Li generic set scaled by zeta [N/m^3],
      <numeric name="mjrft:coefficients" data="A00 A10 B11 B01 B-11 C11 C01 C-11 D10"/>
                                                         optional generic-form set with mjrft:zeta
      <numeric name="mjrft:surface_z" data="0"/>         free-surface height [m] (default 0)
      <numeric name="mjrft:region" data="xmin ymin zmin xmax ymax zmax"/>
                                                         optional box bounding the medium [m]
      <numeric name="mjrft:triangles" data="1000"/>      default triangles per primitive geom, or
      <numeric name="mjrft:tolerance" data="0.01"/>      default relative force tolerance instead
      <text name="mjrft:low_speed" data="stick"/>        low-speed treatment: stick (default) or off
      <numeric name="mjrft:stick_reach" data="4"/>       its reach (mjrft.field.lowspeed), default 4
      <tuple name="mjrft:intruders">                     geoms (or bodies: all their geoms)
        <element objtype="geom" objname="shell" prm="4000"/>   prm: triangles (0 = default),
                                                         or a tolerance in (0, 1), e.g. 0.02
        <element objtype="body" objname="robot_foot" prm="0"/>
      </tuple>
    </custom>

Imports mujoco only to read the model; no state.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import mujoco
import numpy as np

from mjrft.core import geometry
from mjrft.core.material import PRESETS, FourierCoefficients, Material
from mjrft.field.lowspeed import DEFAULT_REACH, MODES, LowSpeed

PREFIX = "mjrft:"
KEYS = {
    "text": ("material", "low_speed"),
    "numeric": (
        "zeta",
        "coefficients",
        "surface_z",
        "region",
        "triangles",
        "tolerance",
        "stick_reach",
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


class SceneError(ValueError):
    """The MJCF scene description is invalid; the message names the element at fault."""


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
    """

    material: Material
    surface_z: float
    region: np.ndarray | None
    intruders: tuple[Intruder, ...]
    low_speed: LowSpeed = dataclasses.field(default_factory=LowSpeed)


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
            if not name.startswith(PREFIX):
                continue
            key = name[len(PREFIX) :]
            if key not in KEYS[kind]:
                valid = ", ".join(f"<{k} name='{PREFIX}{v}'>" for k, vs in KEYS.items() for v in vs)
                raise SceneError(f"unknown <{kind} name='{name}'> in <custom>; valid: {valid}")
            found[key] = (kind, i)
    return found


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
    if not zeta[0] > 0:
        raise SceneError(f"<numeric name='{PREFIX}zeta'> = {zeta[0]} must be > 0 [N/m^3]")
    coeffs = _numeric_field(
        model, custom, "coefficients", (9,), f"9 numbers: {' '.join(COEFFICIENT_ORDER)}"
    )
    if coeffs is None:
        return Material.generic(float(zeta[0]), name=f"mjcf generic (zeta={zeta[0]:g} N/m^3)")
    table = FourierCoefficients.from_mapping(dict(zip(COEFFICIENT_ORDER, coeffs, strict=True)))
    return Material._from_fourier(table, float(zeta[0]), "mjcf coefficients", "MJCF <custom>")


def scene_from_model(
    model: mujoco.MjModel,
    material: Material | None = None,
    *,
    n_triangles: int | None = None,
    tolerance: float | None = None,
    low_speed: str | None = None,
    stick_reach: float | None = None,
) -> Scene:
    """Read and validate the scene; the keyword arguments override the MJCF's.

    tolerance: relative RMS force error per primitive geom; its triangle count comes from
    ``mjrft.geometry.triangles_for_tolerance``. low_speed ("stick" or "off") and stick_reach:
    the low-speed treatment (``mjrft.field.lowspeed``).
    """
    if n_triangles is not None and tolerance is not None:
        raise SceneError("give at most one of n_triangles and tolerance")
    if tolerance is not None:
        n_triangles = geometry.triangles_for_tolerance(tolerance)
    if n_triangles is not None and (
        not isinstance(n_triangles, int | np.integer) or n_triangles < geometry.MIN_TRIANGLES
    ):
        raise SceneError(
            f"n_triangles = {n_triangles!r}: expected an integer >= {geometry.MIN_TRIANGLES}"
        )
    custom = _custom(model)
    mjcf_material = material_from_model(model, custom)
    material = material or mjcf_material
    if material is None:
        raise SceneError(
            f"no material: add <text name='{PREFIX}material' data='glass_beads'/> (presets: "
            f"{', '.join(sorted(PRESETS))}) or <numeric name='{PREFIX}zeta' data='...'/> to "
            "<custom>, or pass material= to GranularField"
        )
    surface = _numeric_field(model, custom, "surface_z", (1,), "one finite number [m]")
    surface_z = 0.0 if surface is None else float(surface[0])
    region = _region(model, custom)
    default_tri, default_tol = _default_resolution(model, custom)
    if "intruders" not in custom:
        raise SceneError(
            f"no intruding geoms: add <tuple name='{PREFIX}intruders'> with "
            "<element objtype='geom' objname='...' prm='0'/> entries to <custom>"
        )
    intruders = _intruders(model, custom["intruders"][1], int(default_tri), default_tol)
    if n_triangles is not None:
        intruders = tuple(
            i
            if i.kind == "mesh"
            else dataclasses.replace(i, n_triangles=int(n_triangles), tolerance=tolerance)
            for i in intruders
        )
    return Scene(
        material, surface_z, region, intruders, _low_speed(model, custom, low_speed, stick_reach)
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
    """(default triangles per primitive geom, the tolerance it comes from or None)."""
    tri = _numeric_field(model, custom, "triangles", (1,), "one integer >= 12")
    tol = _numeric_field(model, custom, "tolerance", (1,), "one number in (0, 1)")
    if tri is not None and tol is not None:
        raise SceneError(
            f"<custom> gives both {PREFIX}triangles and {PREFIX}tolerance; use one of them"
        )
    default_tol = None
    if tol is not None:
        try:
            default_tri = geometry.triangles_for_tolerance(tol[0])
        except ValueError as exc:
            raise SceneError(f"<numeric name='{PREFIX}tolerance'>: {exc}") from None
        default_tol = float(tol[0])
    else:
        default_tri = geometry.DEFAULT_N_TRIANGLES if tri is None else tri[0]
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


def _intruders(
    model: mujoco.MjModel, t: int, default_tri: int, default_tol: float | None
) -> tuple[Intruder, ...]:
    adr, size = model.tuple_adr[t], model.tuple_size[t]
    tagged: dict[int, float] = {}
    for k in range(adr, adr + size):
        objtype, objid, prm = model.tuple_objtype[k], model.tuple_objid[k], model.tuple_objprm[k]
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
            tagged[g] = float(prm)
    if not tagged:
        raise SceneError(f"<tuple name='{PREFIX}intruders'> is empty: tag at least one geom")
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
        if 0 < prm < 1:  # a relative force tolerance for this geom
            tol = prm
            try:
                prm = geometry.triangles_for_tolerance(prm)
            except ValueError as exc:
                raise SceneError(f"geom '{name}': prm={tol:g}: {exc}") from None
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
