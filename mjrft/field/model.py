"""A field's static tables, built once from a compiled MjModel and its scene.

The tagged geoms are meshed once (``mjrft.field.scene.geom_elements``), moved into their body's
frame, and laid out as the engine's tables (``engine_tables``; engine/fields.h): elements grouped
by geom, geoms by body, bodies in id order.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from mjrft.core import quadrature, surface
from mjrft.core.elements import ElementSet
from mjrft.field import lowspeed
from mjrft.field.scene import Intruder, Scene, geom_elements


@dataclass(frozen=True, eq=False)
class BodyElements:
    """All tagged elements of one body, in the body frame (built once at load).

    Attributes:
      body: body id; name: body name.
      centroids: (n, 3) [m], normals: (n, 3) unit, areas: (n,) [m^2]; body frame.
      geoms: (k,) tagged geom ids; segments: (k + 1,) element offsets of each geom's block.
      corners: (n, 9) each triangle's three vertices [m], body frame, counter-clockwise seen
        from outside (the deforming ground rasterises them: mjrft.core.soil).
      corner_normals: (n, 3, 3) unit normals at those vertices, body frame.
    """

    body: int
    name: str
    centroids: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    geoms: np.ndarray
    segments: np.ndarray
    corners: np.ndarray
    corner_normals: np.ndarray

    @property
    def quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        """(reach (n,) [m], patch (n, PATCH_SIZE)) of mjrft.core.quadrature, body frame."""
        return quadrature.patch_table(
            self.centroids, self.corners.reshape(-1, 3, 3), self.normals, self.corner_normals
        )


def _quat_mat(q: np.ndarray) -> np.ndarray:
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, dtype=np.float64))
    return m.reshape(3, 3)


def body_elements(
    model: mujoco.MjModel, scene: Scene
) -> tuple[tuple[BodyElements, ...], dict[int, ElementSet]]:
    """Each tagged body's elements in its frame (bodies in id order), and each tagged geom's
    ElementSet in its body frame (geom id -> set)."""
    by_body: dict[int, list[tuple[Intruder, ElementSet]]] = {}
    for intr in scene.intruders:
        es = geom_elements(model, intr)
        # Geom frame -> body frame (geom_pos/quat already absorb MuJoCo's mesh re-centring).
        body_set = es.transformed(_quat_mat(model.geom_quat[intr.geom]), model.geom_pos[intr.geom])
        by_body.setdefault(intr.body, []).append((intr, body_set))
    geoms: dict[int, ElementSet] = {}
    bodies = []
    for body, items in sorted(by_body.items()):
        for intr, es in items:
            geoms[intr.geom] = es
        sizes = [len(es) for _, es in items]
        bodies.append(
            BodyElements(
                body=body,
                name=items[0][0].body_name,
                centroids=np.concatenate([es.centroids for _, es in items]),
                normals=np.concatenate([es.normals for _, es in items]),
                areas=np.concatenate([es.areas for _, es in items]),
                geoms=np.array([intr.geom for intr, _ in items], dtype=np.int64),
                segments=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                corners=np.concatenate([es.vertices[es.faces].reshape(-1, 9) for _, es in items]),
                corner_normals=np.concatenate([es.corner_normals for _, es in items]),
            )
        )
    return tuple(bodies), geoms


def free_rigid(model: mujoco.MjModel, b: int, tagged: set[int]) -> bool:
    """True if body b moves as one free rigid body the field sees all of (the low-speed
    treatment's condition): a single free joint, no descendant with a joint, mass or tagged
    geoms, and no equality constraint (connect, weld, joint) on it."""
    if (
        model.body_jntnum[b] != 1
        or model.jnt_type[model.body_jntadr[b]] != mujoco.mjtJoint.mjJNT_FREE
    ):
        return False
    for c in range(b + 1, model.nbody):
        p = c
        while p > b:
            p = int(model.body_parentid[p])
        if p == b and (model.body_jntnum[c] > 0 or c in tagged or model.body_mass[c] > 0.0):
            return False
    for e in range(model.neq):
        kind = int(model.eq_type[e])
        ids = (int(model.eq_obj1id[e]), int(model.eq_obj2id[e]))
        if kind == mujoco.mjtEq.mjEQ_JOINT and model.body_jntadr[b] in ids:
            return False
        if kind in (mujoco.mjtEq.mjEQ_CONNECT, mujoco.mjtEq.mjEQ_WELD):
            if int(model.eq_objtype[e]) == mujoco.mjtObj.mjOBJ_SITE:
                ids = tuple(int(model.site_bodyid[i]) if i >= 0 else -1 for i in ids)
            if b in ids:
                return False
    return True


def dof_mask(model: mujoco.MjModel, b: int) -> np.ndarray:
    """(nv,) True where dof j moves body b: its joint's body is b or an ancestor of b."""
    chain, p = set(), b
    while p > 0:
        chain.add(p)
        p = int(model.body_parentid[p])
    return np.array([int(model.dof_bodyid[j]) in chain for j in range(model.nv)], dtype=bool)


def mechanism_body(model: mujoco.MjModel, b: int) -> bool:
    """True if some joint moves body b (a body welded to the world has nothing to treat)."""
    return bool(dof_mask(model, b).any())


GAIN_FIXED, GAIN_AFFINE = int(mujoco.mjtGain.mjGAIN_FIXED), int(mujoco.mjtGain.mjGAIN_AFFINE)
BIAS_NONE, BIAS_AFFINE = int(mujoco.mjtBias.mjBIAS_NONE), int(mujoco.mjtBias.mjBIAS_AFFINE)


def _affine_actuators(model: mujoco.MjModel) -> np.ndarray:
    """(nu,) True for the actuators whose force the mechanism treatment predicts at the current
    state: fixed or affine gain, no or affine bias, activation not used early."""
    return (
        np.isin(model.actuator_gaintype, (GAIN_FIXED, GAIN_AFFINE))
        & np.isin(model.actuator_biastype, (BIAS_NONE, BIAS_AFFINE))
        & ~model.actuator_actearly.astype(bool)
    )


def watched_geoms(model: mujoco.MjModel, scene: Scene) -> np.ndarray:
    """(nwatch,) ids of the geoms the engine reports when they sink untagged (engine/watch.h):
    collision geoms (contype or conaffinity nonzero) of bodies that move (not welded to the
    world, or mocap), not intruders, not planes or height fields; none if the scene says so."""
    if not scene.watch_sinking:
        return np.zeros(0, dtype=np.int64)
    tagged = {i.geom for i in scene.intruders}
    flat = (int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_HFIELD))
    out = []
    for g in range(model.ngeom):
        b = int(model.geom_bodyid[g])
        moves = model.body_weldid[b] != 0 or model.body_mocapid[b] >= 0
        collides = model.geom_contype[g] != 0 or model.geom_conaffinity[g] != 0
        if moves and collides and g not in tagged and int(model.geom_type[g]) not in flat:
            out.append(g)
    return np.array(out, dtype=np.int64)


def _dof_masks(model: mujoco.MjModel, bodies) -> np.ndarray:
    out = np.zeros((len(bodies), model.nv), dtype=np.int64)
    for k, be in enumerate(bodies):
        out[k] = dof_mask(model, be.body)
    return out


def engine_tables(
    model: mujoco.MjModel,
    scene: Scene,
    bodies: tuple[BodyElements, ...],
    treat: np.ndarray,
    mech: np.ndarray,
) -> dict[str, np.ndarray | int | float]:
    """The engine's static tables (engine/fields.h) by name: sizes and scalars as numbers, arrays
    as C-contiguous float64 or int64 arrays. treat (ntbody,) bool: bodies the free-body
    treatment may act on; mech (ntbody,) bool: bodies the mechanism treatment acts on."""
    geoms, tbody, adr, num, rbound = [], [], [], [], []
    geomadr, geomnum, offset = [], [], 0
    for k, be in enumerate(bodies):
        geomadr.append(len(geoms))
        geomnum.append(len(be.geoms))
        for gi, g in enumerate(be.geoms):
            geoms.append(int(g))
            tbody.append(k)
            adr.append(offset + int(be.segments[gi]))
            num.append(int(be.segments[gi + 1] - be.segments[gi]))
            rbound.append(float(model.geom_rbound[g]))
        offset += len(be.areas)
    f8 = lambda x: np.ascontiguousarray(x, dtype=np.float64)  # noqa: E731
    i8 = lambda x: np.ascontiguousarray(x, dtype=np.int64)  # noqa: E731
    soil = scene.surface.kind == surface.SOIL
    material, region = scene.material, scene.region
    coef = material.kernel_coefficients
    nrow, ncol = scene.surface.grid.shape
    quad = [be.quadrature for be in bodies]
    cat = lambda parts, width: (  # noqa: E731
        np.concatenate(parts) if parts else np.zeros((0, width))
    )
    return {
        # sizes
        "nelem": offset, "ntgeom": len(geoms), "ntbody": len(bodies), "surface_nrow": nrow,
        "surface_ncol": ncol, "ncoef": len(coef), "nvert": offset if soil else 1,
        "nsoil": surface.soil_block(nrow, ncol) if soil else 1,
        "nwatch": len(watched := watched_geoms(model, scene)),
        # scalars
        "surface_z": float(scene.surface_z), "use_region": int(region is not None),
        "zeta": float(material.zeta), "alpha_y": float(material.alpha_y0),
        "treat": int(scene.low_speed.on), "reach": float(scene.low_speed.reach),
        "jacobian_step": lowspeed.JACOBIAN_STEP, "rk4_hold_steps": lowspeed.RK4_HOLD_STEPS,
        "mech": int(np.any(mech)), "soil": int(soil),
        # arrays
        "elem_pos": f8(cat([be.centroids for be in bodies], 3)),
        "elem_normal": f8(cat([be.normals for be in bodies], 3)),
        "elem_area": f8(cat([be.areas for be in bodies], 1).ravel()),
        "tgeom_geomid": i8(geoms), "tgeom_tbody": i8(tbody), "tgeom_elemadr": i8(adr),
        "tgeom_elemnum": i8(num), "tgeom_rbound": f8(rbound),
        "tbody_bodyid": i8([be.body for be in bodies]),
        "tbody_rootid": i8([model.body_rootid[be.body] for be in bodies]),
        "tbody_geomadr": i8(geomadr), "tbody_geomnum": i8(geomnum), "tbody_treat": i8(treat),
        "region": f8(np.zeros((2, 3)) if region is None else region),
        "coef": f8(coef),
        "tbody_mech": i8(mech), "tbody_dofmask": i8(_dof_masks(model, bodies)),
        "actuator_affine": i8(_affine_actuators(model)),
        "actuator_gainaffine": i8(model.actuator_gaintype == GAIN_AFFINE),
        "actuator_biasaffine": i8(model.actuator_biastype == BIAS_AFFINE),
        "actuator_actadr": i8(model.actuator_actadr),
        "actuator_ctrllimited": i8(model.actuator_ctrllimited),
        "actuator_forcelimited": i8(model.actuator_forcelimited),
        "surface_prm": f8(scene.surface.prm), "surface_grid": f8(scene.surface.grid),
        "elem_vert": f8(cat([be.corners for be in bodies], 9) if soil else np.zeros((1, 9))),
        "elem_reach": f8(cat([q[0] for q in quad], 1).ravel()),
        "elem_patch": f8(cat([q[1] for q in quad], quadrature.PATCH_SIZE)),
        "watch_geomid": i8(watched),
    }  # fmt: skip


@dataclass(frozen=True, eq=False)
class FieldSetup:
    """Everything a field is built from, once per model and options.

    Attributes:
      scene: the validated scene (mjrft.field.scene).
      bodies: tagged bodies (id order), their elements in the body frame.
      geom_elements: tagged geom id -> its ElementSet in the body frame.
      body_ids: (ntbody,) ids of the tagged bodies.
      stick_eligible: (ntbody,) True where the free-body treatment may act (free_rigid).
      mechanism_eligible: (ntbody,) True where the mechanism treatment acts.
      tables: the engine's static tables (engine_tables).
    """

    scene: Scene
    bodies: tuple[BodyElements, ...]
    geom_elements: dict[int, ElementSet]
    body_ids: np.ndarray
    stick_eligible: np.ndarray
    mechanism_eligible: np.ndarray
    tables: dict


def field_setup(model: mujoco.MjModel, scene: Scene) -> FieldSetup:
    """Mesh the scene's tagged geoms, decide which bodies the treatments act on, and lay out the
    engine's tables."""
    bodies, geoms = body_elements(model, scene)
    body_ids = np.array([be.body for be in bodies], dtype=np.int64)
    tagged = set(body_ids.tolist())
    stick = np.array([free_rigid(model, int(b), tagged) for b in body_ids], dtype=bool)
    mech = (
        np.array([mechanism_body(model, int(b)) for b in body_ids], dtype=bool)
        & ~stick
        & scene.low_speed.mechanisms
    )
    tables = engine_tables(model, scene, bodies, stick, mech)
    return FieldSetup(scene, bodies, geoms, body_ids, stick, mech, tables)
