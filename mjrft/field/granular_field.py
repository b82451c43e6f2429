"""The granular force field: RFT wrenches on a compiled MjModel's intruding bodies, every step.

``GranularField(model)`` reads the scene from the MJCF (see ``mjrft.scene``), meshes the tagged
geoms once, and then maps any MjData of that model to one wrench per body, computed from that
data's current kinematics (``xpos``, ``xmat``, ``cvel``, ``subtree_com``: no lag, no finite
differences). Two ways to apply it:

* explicit: ``mj_forward``; ``d.xfrc_applied[:] = user + field.wrench(d, user_xfrc=user)``;
  ``mj_step`` — the wrench is held over the step (all RK4 stages see the same force);
* installed: ``with field.installed(): mj_step(...)`` — in every forward pass the intruding
  bodies' rows of ``xfrc_applied`` are set to the user's part plus that pass's RFT wrench; in an
  RK4 step, bodies the low-speed treatment holds (or is about to) keep the wrench of the first
  stage over the other three, bodies it moves implicitly keep the first stage's twist and
  implicit correction (``_native.rk4_hold``), other moving bodies are evaluated in every stage.

Why ``xfrc_applied`` and not ``qfrc_passive``: MuJoCo's force/torque sensors (load cells) see
external body forces only through ``cfrc_ext``, which is built from ``xfrc_applied`` and contacts.
A wrench added to ``qfrc_passive`` moves the bodies but is invisible to every load cell.

How the user's part survives: per MjData the field remembers the user's part of each intruding
row and what it wrote there. A row that no longer holds what the field wrote was assigned by the
user (a controller, the viewer's perturbation), and that value becomes the user's part; otherwise
the user's part is unchanged. So user forces are never lost or counted twice, for any number of
forward passes per step. Between steps the rows hold user + RFT (``user_xfrc`` gives the user's
part), and leaving ``installed()`` restores the user's values.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import weakref
from collections.abc import Iterator
from dataclasses import dataclass

import mujoco
import numpy as np

from mjrft.core.elements import ElementSet
from mjrft.core.material import Material
from mjrft.core.rft import unit_normal_forces
from mjrft.field import guard as _callback
from mjrft.field import lowspeed
from mjrft.field.scene import Intruder, Scene, geom_elements, scene_from_model


@dataclass(frozen=True, eq=False)
class BodyElements:
    """All tagged elements of one body, in the body frame (built once at load).

    Attributes:
      body: body id; name: body name.
      centroids: (n, 3) [m], normals: (n, 3) unit, areas: (n,) [m^2]; body frame.
      geoms: (k,) tagged geom ids; segments: (k + 1,) element offsets of each geom's block.
    """

    body: int
    name: str
    centroids: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    geoms: np.ndarray
    segments: np.ndarray


@dataclass(frozen=True)
class ElementState:
    """Per-element RFT state of one body at one instant, world frame, evaluated elements only.

    Attributes:
      body: body id. index: (n,) element indices into the body's BodyElements.
      pos: (n, 3) centroids [m]; normal: (n, 3) unit normals; area: (n,) [m^2];
      vel: (n, 3) centroid velocities [m/s]; force: (n, 3) RFT forces [N].
    """

    body: int
    index: np.ndarray
    pos: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    vel: np.ndarray
    force: np.ndarray


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a x b for (3,) or (n, 3) operands (np.cross is slow on small arrays)."""
    a, b = np.broadcast_arrays(a, b)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _quat_mat(q: np.ndarray) -> np.ndarray:
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, dtype=np.float64))
    return m.reshape(3, 3)


#: How many past writes of xfrc_applied rows the field remembers, to recognise MjData copies.
XFRC_HISTORY = 4096


_NO_REGION = np.zeros((2, 3))
# The RK4 stage record's layout and modes (mjrft._native.RK4_*; tests check they agree).
_RK4_HEAD, _RK4_BODY, _RK4_HOLD, _RK4_FROZEN = 2, 13, 1.0, 2.0


def _free_rigid(model: mujoco.MjModel, b: int, tagged: set[int]) -> bool:
    """True if body b moves as one free rigid body the field can see all of (mjrft.lowspeed):
    a single free joint, no descendant with a joint, mass or intruding geoms, and no equality
    constraint (connect, weld, joint) on it."""
    free = mujoco.mjtJoint.mjJNT_FREE
    if model.body_jntnum[b] != 1 or model.jnt_type[model.body_jntadr[b]] != free:
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


def _scan(base: int, span: int, ctype, sentinel) -> int:
    """Address in [base - span, base + span) holding ctype(sentinel), or 0."""
    step = ctypes.sizeof(ctype)
    for off in range(-span, span, step):
        if ctype.from_address(base + off).value == sentinel:
            return base + off
    return 0


def _model_addresses(model: mujoco.MjModel) -> np.ndarray:
    """Addresses of the live MjModel fields the native treatment reads (mjrft._native M_*).

    ``opt.gravity`` and the body arrays are NumPy views of the model's memory; the scalars
    ``opt.timestep``, ``opt.disableflags`` and ``opt.integrator`` are found next to
    ``opt.gravity`` (same mjOption struct) by writing a sentinel and restoring it, so later
    changes by the user are seen.
    """
    from mjrft.field import native as nt

    opt = model.opt
    grav = opt.gravity.ctypes.data
    out = np.zeros(nt.MODEL_WORDS, dtype=np.uint64)
    dt = opt.timestep
    try:
        opt.timestep = 1.2345678901234567e-3
        out[nt.M_TIMESTEP] = _scan(grav, 512, ctypes.c_double, opt.timestep)
    finally:
        opt.timestep = dt
    flags = opt.disableflags
    try:
        opt.disableflags = 0x2A5A5A5
        out[nt.M_DISABLEFLAGS] = _scan(grav, 512, ctypes.c_int32, 0x2A5A5A5)
    finally:
        opt.disableflags = flags
    integrator = opt.integrator
    try:
        opt.integrator = 0x2A5A5A6
        out[nt.M_INTEGRATOR] = _scan(grav, 512, ctypes.c_int32, 0x2A5A5A6)
    finally:
        opt.integrator = integrator
    if not (out[nt.M_TIMESTEP] and out[nt.M_DISABLEFLAGS] and out[nt.M_INTEGRATOR]):
        raise RuntimeError(
            "cannot locate opt.timestep / opt.disableflags / opt.integrator in this MuJoCo build"
        )
    out[nt.M_GRAVITY] = grav
    out[nt.M_BODY_MASS] = model.body_mass.ctypes.data
    out[nt.M_BODY_INERTIA] = model.body_inertia.ctypes.data
    out[nt.M_BODY_GRAVCOMP] = model.body_gravcomp.ctypes.data
    return out


def _time_address(data: mujoco.MjData) -> int:
    """Address of the scalar ``data.time``, found just before ``data.energy`` (mjData declares
    ``time`` then ``energy[2]``) by writing a sentinel and restoring it."""
    t = data.time
    try:
        data.time = -1.2345678901234567e-300
        addr = _scan(data.energy.ctypes.data, 64, ctypes.c_double, data.time)
    finally:
        data.time = t
    if not addr:
        raise RuntimeError("cannot locate MjData.time in this MuJoCo build")
    return addr


@dataclass(eq=False)
class _DataState:
    """xfrc ownership of one MjData: user part and rows written (intruding bodies' rows), its
    RK4 stage record (mjrft._native.rk4_hold), and the address table the native pass reads."""

    ref: weakref.ref
    user: np.ndarray
    written: np.ndarray
    entry: np.ndarray
    rk4: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))  # + body blocks
    finalizer: weakref.finalize | None = None


def _native_words() -> int:
    from mjrft.field.native import DATA_WORDS

    return DATA_WORDS


class GranularField:
    """RFT force field bound to one compiled MjModel.

    Args:
      model: compiled model whose ``<custom>`` describes the scene (``mjrft.scene``).
      material: overrides the MJCF material if given.
      n_triangles: overrides the triangle count of every primitive geom (MJCF ``prm`` and
        ``mjrft:triangles``): fewer is faster and less accurate. Mesh geoms keep their own.
      tolerance: instead of n_triangles, the relative RMS force error wanted per primitive geom
        (e.g. 0.01); the count comes from ``mjrft.geometry.triangles_for_tolerance``.
      low_speed: "stick" (default) or "off": the low-speed stick/slip treatment of free bodies
        (``mjrft.lowspeed``); overrides MJCF ``mjrft:low_speed``.
      stick_reach: the treatment's reach (default 4, lowspeed.DEFAULT_REACH); overrides MJCF
        ``mjrft:stick_reach``.
    Raises:
      mjrft.scene.SceneError (a ValueError) naming the geom or field at fault.

    One field keeps per-pass state (``last_wrench``, element forces, work arrays), so step the
    MjData of an installed field from one thread at a time; for many copies in parallel use
    ``mjrft.batch.BatchedField``.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        material: Material | None = None,
        *,
        n_triangles: int | None = None,
        tolerance: float | None = None,
        low_speed: str | None = None,
        stick_reach: float | None = None,
    ) -> None:
        self.model = model
        self.scene: Scene = scene_from_model(
            model,
            material,
            n_triangles=n_triangles,
            tolerance=tolerance,
            low_speed=low_speed,
            stick_reach=stick_reach,
        )
        #: The low-speed treatment (mode, reach).
        self.low_speed: lowspeed.LowSpeed = self.scene.low_speed
        self.material = self.scene.material
        self.surface_z = self.scene.surface_z
        self.region = self.scene.region
        by_body: dict[int, list[tuple[Intruder, ElementSet]]] = {}
        for intr in self.scene.intruders:
            es = geom_elements(model, intr)
            # Geom frame -> body frame (geom_pos/quat already absorb MuJoCo's mesh re-centring).
            es_body = es.transformed(
                _quat_mat(model.geom_quat[intr.geom]), model.geom_pos[intr.geom]
            )
            by_body.setdefault(intr.body, []).append((intr, es_body))
        self.geom_elements: dict[int, ElementSet] = {}
        self.bodies: tuple[BodyElements, ...] = tuple(
            self._pack(b, items) for b, items in sorted(by_body.items())
        )
        self.body_ids = np.array([be.body for be in self.bodies], dtype=np.int64)
        self._body_names = {be.body: be.name for be in self.bodies}
        # The compiled kernel serves Fourier-form media with a constant alpha_y (the presets and
        # tables); callables take the NumPy path.
        self._compiled = self.material.fourier is not None and self.material.alpha_y_fn is None
        self._root = {int(b): int(model.body_rootid[b]) for b in self.body_ids}
        n_el = self.n_elements
        # One element index space over all bodies (bodies' blocks in body order).
        offsets = np.cumsum([0] + [len(be.areas) for be in self.bodies])
        self._elem_force_all = np.zeros((n_el, 3))
        #: Per body: (n, 3) world-frame force [N] on each element at the last compiled evaluation.
        self._elem_force = {
            be.body: self._elem_force_all[o : o + len(be.areas)]
            for be, o in zip(self.bodies, offsets, strict=False)
        }
        from mjrft.field.native import N_STATS

        self._stats = np.zeros(N_STATS, dtype=np.int64)
        #: Per body of ``body_ids``: True if the low-speed treatment can act on it (a free rigid
        #: body: free joint, no jointed or massive descendants, no other intruding body below
        #: it, not in an equality constraint).
        self.stick_eligible = np.array(
            [_free_rigid(model, int(b), set(self.body_ids.tolist())) for b in self.body_ids],
            dtype=bool,
        )
        #: Per body of ``body_ids``: the treatment's decision in the last pass (mjrft.lowspeed
        #: PURE, STICK, SLIP or IMPLICIT).
        self.last_decision = np.zeros(len(self.body_ids), dtype=np.int64)
        # Per body: its RK4 stage record block of the last evaluated pass (_native.rk4_hold).
        self._rk4_block = np.zeros((len(self.body_ids), _RK4_BODY))
        #: (nbody, 6) wrench of the most recent forward pass of the installed field (updated in
        #: place: keep a reference if you like).
        self.last_wrench = np.zeros((model.nbody, 6))
        # Recent writes to the intruding xfrc rows and the user part behind each: an MjData copy
        # carries rows the field wrote, and is recognised by them. Slot 0 holds the counter.
        n_bt = len(self.bodies)
        self._ring = np.zeros((XFRC_HISTORY + 1, 2, n_bt, 6))
        # Per MjData address: its state (user part, rows written, native address table).
        self._data: dict[int, _DataState] = {}
        self._table = self._native_table(offsets) if self._compiled else None

    def _native_table(self, offsets: np.ndarray) -> np.ndarray:
        """Publish the static arrays for mjrft._native.step (kept alive by self)."""
        from mjrft.field import native as nt

        self._n_cent = np.ascontiguousarray(np.concatenate([be.centroids for be in self.bodies]))
        self._n_norm = np.ascontiguousarray(np.concatenate([be.normals for be in self.bodies]))
        self._n_area = np.ascontiguousarray(np.concatenate([be.areas for be in self.bodies]))
        rows = []
        for be, o in zip(self.bodies, offsets, strict=False):
            for gi, g in enumerate(be.geoms):
                start, stop = o + be.segments[gi], o + be.segments[gi + 1]
                rows.append((int(g), be.body, start, stop, self._root[be.body]))
        self._n_gint = np.array(rows, dtype=np.int64).reshape(-1, 5)
        self._n_grb = np.array([self.model.geom_rbound[r[0]] for r in rows], dtype=np.float64)
        self._n_par = np.zeros(nt.N_PARAMS)
        self._n_par[nt.P_SURFACE] = self.surface_z
        self._n_par[nt.P_ZETA] = self.material.zeta
        self._n_par[nt.P_AY] = self.material.alpha_y0
        if self.region is not None:
            self._n_par[nt.P_USE_REGION] = 1.0
            self._n_par[nt.P_REGION : nt.P_REGION + 6] = self.region.ravel()
        self._n_coef = np.ascontiguousarray(self.material.kernel_coefficients)
        t = np.zeros(nt.FIELD_WORDS, dtype=np.uint64)
        t[nt.F_NELEM] = len(self._n_area)
        t[nt.F_CENT] = self._n_cent.ctypes.data
        t[nt.F_NORM] = self._n_norm.ctypes.data
        t[nt.F_AREA] = self._n_area.ctypes.data
        t[nt.F_NGEOM] = len(rows)
        t[nt.F_GINT] = self._n_gint.ctypes.data
        t[nt.F_GRB] = self._n_grb.ctypes.data
        t[nt.F_NBODY_TAGGED] = len(self.body_ids)
        t[nt.F_BODIES] = self.body_ids.ctypes.data
        t[nt.F_PARAMS] = self._n_par.ctypes.data
        t[nt.F_COEF] = self._n_coef.ctypes.data
        t[nt.F_NBODY] = self.model.nbody
        t[nt.F_LAST_WRENCH] = self.last_wrench.ctypes.data
        t[nt.F_ELEM_FORCE] = self._elem_force_all.ctypes.data
        t[nt.F_STATS] = self._stats.ctypes.data
        t[nt.F_RING] = self._ring.ctypes.data
        t[nt.F_RING_SIZE] = XFRC_HISTORY
        self._n_dirty = np.ones(len(rows), dtype=np.int64)
        t[nt.F_DIRTY] = self._n_dirty.ctypes.data
        self._n_par[nt.P_TREAT] = 1.0 if self.low_speed.on else 0.0
        self._n_par[nt.P_REACH] = self.low_speed.reach
        self._n_par[nt.P_DSBL_GRAVITY] = float(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
        self._n_par[nt.P_RK4_HOLD] = lowspeed.RK4_HOLD_STEPS
        self._n_par[nt.P_JAC_STEP] = lowspeed.JACOBIAN_STEP
        self._n_model = _model_addresses(self.model)
        t[nt.F_MODEL] = self._n_model.ctypes.data
        self._n_eligible = self.stick_eligible.astype(np.int64)
        t[nt.F_ELIGIBLE] = self._n_eligible.ctypes.data
        t[nt.F_DECISION] = self.last_decision.ctypes.data
        self._n_scratch = np.zeros((max(len(self._n_area), 1), 3))
        t[nt.F_SCRATCH] = self._n_scratch.ctypes.data
        n_bt = len(self.body_ids)
        self._n_work = np.zeros(2 * self.model.nbody + len(rows) + n_bt, dtype=np.int64)
        t[nt.F_WORK] = self._n_work.ctypes.data
        self._n_frozen = np.zeros((max(n_bt, 1), 12))
        t[nt.F_FROZEN] = self._n_frozen.ctypes.data
        return t

    @property
    def stats(self) -> dict[str, int]:
        """Work counters since construction: ``calls`` (evaluations of the field), ``evaluated``
        (triangles handed to the kernel: those of geoms not culled by their bounding sphere) and
        ``acting`` (triangles that felt a force: submerged and leading), and of the low-speed
        treatment ``stuck``, ``slipping`` and ``implicit`` (body-passes held at rest, given the
        force of their free direction of motion, or moved with the linearly implicit force;
        ``mjrft.lowspeed``)."""
        c, e, a, st, sl, im = (int(x) for x in self._stats)
        return {
            "calls": c, "evaluated": e, "acting": a, "stuck": st, "slipping": sl, "implicit": im,
        }  # fmt: skip

    def _pack(self, body: int, items: list[tuple[Intruder, ElementSet]]) -> BodyElements:
        for intr, es in items:
            self.geom_elements[intr.geom] = es
        sizes = [len(es) for _, es in items]
        return BodyElements(
            body=body,
            name=items[0][0].body_name,
            centroids=np.concatenate([es.centroids for _, es in items]),
            normals=np.concatenate([es.normals for _, es in items]),
            areas=np.concatenate([es.areas for _, es in items]),
            geoms=np.array([intr.geom for intr, _ in items], dtype=np.int64),
            segments=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        )

    # ------------------------------------------------------------------ queries
    def body_element_set(self, body: int) -> ElementSet:
        """All tagged elements of a body as one ElementSet in the body frame."""
        be = next((x for x in self.bodies if x.body == body), None)
        if be is None:
            raise ValueError(f"body {body} has no intruding geoms")
        sets = [self.geom_elements[int(g)] for g in be.geoms]
        offsets = np.cumsum([0] + [len(es.vertices) for es in sets[:-1]])
        return ElementSet(
            centroids=be.centroids,
            normals=be.normals,
            areas=be.areas,
            vertices=np.concatenate([es.vertices for es in sets]),
            faces=np.concatenate([es.faces + o for es, o in zip(sets, offsets, strict=True)]),
        )

    @property
    def n_elements(self) -> int:
        """Total number of surface triangles over all intruding geoms."""
        return int(sum(len(be.areas) for be in self.bodies))

    def _geom_may_act(self, data: mujoco.MjData, g: int) -> bool:
        """False if the geom's bounding sphere is above the surface or outside the region."""
        c = data.geom_xpos[g]
        r = self.model.geom_rbound[g]
        if r <= 0.0:  # MuJoCo leaves rbound 0 for some geoms: never cull those
            return True
        if c[2] - r >= self.surface_z:
            return False
        if self.region is not None:
            if np.any(c + r < self.region[0]) or np.any(c - r > self.region[1]):
                return False
        return True

    def _candidates(self, data: mujoco.MjData, be: BodyElements) -> np.ndarray | None:
        """Element indices of geoms that may be in the medium; None if none may."""
        keep = [self._geom_may_act(data, int(g)) for g in be.geoms]
        if not any(keep):
            return None
        if all(keep):
            return np.arange(be.segments[-1])
        return np.concatenate(
            [np.arange(be.segments[i], be.segments[i + 1]) for i, k in enumerate(keep) if k]
        )

    def element_states(self, data: mujoco.MjData) -> list[ElementState]:
        """Per-element world-frame state and RFT force of every body with geoms in the medium.

        Uses data's current kinematics (call ``mj_forward`` first outside a step). Forces are the
        pure model's (the low-speed treatment acts on whole bodies: see ``wrench``).
        """
        out = []
        for be in self.bodies:
            idx = self._candidates(data, be)
            if idx is None:
                continue
            b = be.body
            # cvel = [w, v] with v at the subtree CoM of the body's root (DESIGN.md section 3).
            w, v0 = data.cvel[b, :3], data.cvel[b, 3:]
            p_ref = data.subtree_com[self.model.body_rootid[b]]
            out.append(self._state_at(data, be, idx, w, v0, p_ref))
        return out

    def _state_at(
        self,
        data: mujoco.MjData,
        be: BodyElements,
        idx: np.ndarray,
        omega: np.ndarray,
        v_ref: np.ndarray,
        p_ref: np.ndarray,
    ) -> ElementState:
        """Elements idx of a body at its current pose, moving with angular velocity omega (3,)
        [rad/s] and linear velocity v_ref (3,) [m/s] at the world point p_ref (3,) [m]."""
        b = be.body
        rot = data.xmat[b].reshape(3, 3)
        pos = be.centroids[idx] @ rot.T + data.xpos[b]
        if self.region is not None:
            inside = np.all((pos >= self.region[0]) & (pos <= self.region[1]), axis=1)
            idx, pos = idx[inside], pos[inside]
        normal = be.normals[idx] @ rot.T
        vel = v_ref + _cross(omega, pos - p_ref)
        area = be.areas[idx]
        f = unit_normal_forces(pos, normal, area, vel, self.material, self.surface_z)
        return ElementState(b, idx, pos, normal, area, vel, f)

    def wrench(
        self,
        data: mujoco.MjData,
        out: np.ndarray | None = None,
        *,
        user_xfrc: np.ndarray | None = None,
    ) -> np.ndarray:
        """RFT wrench on every body, ``xfrc_applied`` layout, low-speed treatment included.

        Args:
          data: MjData of this model with current kinematics (``mj_forward`` outside a step).
          out: optional (nbody, 6) array to fill.
          user_xfrc: (nbody, 6) the other applied wrenches you will add to ``xfrc_applied``
            (world force [N], torque about the CoM [N m]); the treatment balances them when it
            holds a body at rest. Default: none.
        Returns:
          (nbody, 6): world-frame force [N] then torque [N m] about each body's CoM (xipos);
          zero rows for bodies without intruding geoms or out of the medium.
        """
        out = self._pure_wrench(data, out)
        self.last_decision[:] = lowspeed.PURE
        self._rk4_block[:] = 0.0
        if self.low_speed.on:
            self._treat(data, out, user_xfrc)
        return out

    def _pure_wrench(self, data: mujoco.MjData, out: np.ndarray | None = None) -> np.ndarray:
        """(nbody, 6) RFT wrench of the pure model (no low-speed treatment); see ``wrench``."""
        if out is None:
            out = np.zeros((self.model.nbody, 6))
        else:
            out[:] = 0.0
        self._check_finite(data)
        if self._compiled:
            self._wrench_compiled(data, out)
        else:
            for st in self.element_states(data):
                f = st.force
                out[st.body, :3] = f.sum(axis=0)
                out[st.body, 3:] = _cross(st.pos - data.xipos[st.body], f).sum(axis=0)
                self._count(len(st.index), int(np.count_nonzero(np.any(f != 0.0, axis=1))))
        return out

    def _wrench_at(
        self, data: mujoco.MjData, be: BodyElements, idx: np.ndarray, twist: np.ndarray
    ) -> np.ndarray:
        """(6,) RFT wrench on elements idx of a body at its pose moving with the world-frame
        twist (6,) (CoM velocity [m/s], angular velocity [rad/s]); torque about the CoM."""
        b = be.body
        com = data.xipos[b]
        out = np.zeros(6)
        if self._compiled:
            from mjrft.core import kernel as _kernel

            m = self.material
            use_region = self.region is not None
            region = self.region if use_region else _NO_REGION
            scratch = np.zeros((len(be.areas), 3))
            rot = data.xmat[b].reshape(3, 3)
            for gi, g in enumerate(be.geoms):
                if not self._geom_may_act(data, int(g)):
                    continue
                _kernel.body_wrench(
                    be.centroids, be.normals, be.areas, be.segments[gi], be.segments[gi + 1],
                    rot, data.xpos[b], twist[3:], twist[:3], com, com, m.kernel_coefficients,
                    m.alpha_y0, m.zeta, self.surface_z, use_region, region, out, scratch,
                )  # fmt: skip
            return out
        st = self._state_at(data, be, idx, twist[3:], twist[:3], com)
        out[:3] = st.force.sum(axis=0)
        out[3:] = _cross(st.pos - com, st.force).sum(axis=0)
        return out

    def _treat(self, data: mujoco.MjData, w: np.ndarray, user: np.ndarray | None) -> None:
        """The low-speed treatment (mjrft.lowspeed.treat) of the eligible bodies in w (nbody, 6)."""
        m = self.model
        dt = float(m.opt.timestep)
        gravity = np.zeros(3)
        if not m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY):
            gravity = np.array(m.opt.gravity)
        semi = m.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4
        for k, be in enumerate(self.bodies):
            b = be.body
            mass, inertia = float(m.body_mass[b]), np.array(m.body_inertia[b])
            if not (self.stick_eligible[k] and dt > 0.0 and mass > 0.0 and np.all(inertia > 0)):
                continue
            idx = self._candidates(data, be)
            if idx is None:
                continue
            x = data.ximat[b].reshape(3, 3)
            iw = (x * inertia) @ x.T
            om = np.array(data.cvel[b, :3])
            v = data.cvel[b, 3:] + _cross(om, data.xipos[b] - data.subtree_com[self._root[b]])
            u = np.zeros(6) if user is None else np.asarray(user[b], dtype=float)
            other = np.concatenate(
                [mass * gravity * (1.0 - m.body_gravcomp[b]) + u[:3], u[3:] - _cross(om, iw @ om)]
            )
            twist, pure = np.concatenate([v, om]), w[b].copy()
            w[b], dec = lowspeed.treat(
                pure,
                lambda tw, be=be, idx=idx: self._wrench_at(data, be, idx, tw),
                twist,
                mass,
                iw,
                other,
                dt,
                self.low_speed.reach,
                semi_implicit=semi,
            )
            self.last_decision[k] = dec
            if dec == lowspeed.IMPLICIT:
                self._rk4_block[k] = (_RK4_FROZEN, *twist, *(w[b] - pure))
            elif dec != lowspeed.PURE or not lowspeed.keeps_sense(
                pure, twist, mass, iw, other, dt, lowspeed.RK4_HOLD_STEPS
            ):
                self._rk4_block[k, 0] = _RK4_HOLD
            if dec == lowspeed.STICK:
                self._stats[3] += 1
            elif dec == lowspeed.SLIP:
                self._stats[4] += 1
            elif dec == lowspeed.IMPLICIT:
                self._stats[5] += 1

    def _wrench_compiled(self, data: mujoco.MjData, out: np.ndarray) -> None:
        """The hot path: one fused kernel call per evaluated geom block (mjrft._kernel)."""
        from mjrft.core import kernel as _kernel

        m = self.material
        co, ay, zeta = m.kernel_coefficients, m.alpha_y0, m.zeta
        use_region = self.region is not None
        region = self.region if use_region else _NO_REGION
        for be in self.bodies:
            b = be.body
            rot = pos = omega = v_ref = p_ref = com = None
            evaluated = acting = 0
            for gi, g in enumerate(be.geoms):
                start, stop = be.segments[gi], be.segments[gi + 1]
                if not self._geom_may_act(data, int(g)):
                    self._elem_force[b][start:stop] = 0.0
                    continue
                if rot is None:
                    rot = data.xmat[b].reshape(3, 3)
                    pos, com = data.xpos[b], data.xipos[b]
                    omega, v_ref = data.cvel[b, :3], data.cvel[b, 3:]
                    p_ref = data.subtree_com[self._root[b]]
                acting += _kernel.body_wrench(
                    be.centroids, be.normals, be.areas, start, stop, rot, pos, omega, v_ref,
                    p_ref, com, co, ay, zeta, self.surface_z, use_region, region, out[b],
                    self._elem_force[b],
                )  # fmt: skip
                evaluated += stop - start
            self._count(evaluated, acting)

    def _count(self, evaluated: int, acting: int) -> None:
        self._stats[:3] += (1, evaluated, acting)

    def _check_finite(self, data: mujoco.MjData) -> None:
        b = self.body_ids
        if not (np.all(np.isfinite(data.xpos[b])) and np.all(np.isfinite(data.cvel[b]))):
            bad = next(
                int(i)
                for i in b
                if not (np.all(np.isfinite(data.xpos[i])) and np.all(np.isfinite(data.cvel[i])))
            )
            raise FloatingPointError(
                f"body '{self._body_names[bad]}' has a non-finite position or velocity at time "
                f"{data.time:.6g} s (step {self._step_index(data)}); the granular field refuses "
                "to feed NaN forward (check the timestep and actuators)"
            )

    def _step_index(self, data: mujoco.MjData) -> int:
        """Index of the step being taken (time / timestep; no mujoco call)."""
        dt = float(self.model.opt.timestep)
        return round(data.time / dt) if dt > 0 and np.isfinite(data.time) else -1

    # ------------------------------------------------------------------ application
    def apply_passive(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Set the intruding rows of ``xfrc_applied`` to user part + RFT (the installed path).

        Runs in MuJoCo's passive callback, for every forward pass the native guard does not
        handle itself: an MjData seen for the first time (registered here), a problem the
        native pass reported (raised here), Python-only materials, or a chained user callback.
        Calls no mujoco function: inside a callback, any binding call resets the binding's
        per-thread error escape, after which an exception raised here would abort the process.
        """
        st = self._state(data)
        if self._table is not None:
            from mjrft.field import native as _native

            status = _native.step(self._table.ctypes.data, st.entry.ctypes.data)
            if status != _native.OK:
                self._check_finite(data)  # raises, naming the body
                raise FloatingPointError(f"granular field failed with status {status}")
            return
        rows = self.body_ids
        keep = np.zeros(len(rows), dtype=bool)  # bodies holding their RK4 step's first wrench
        held = False
        if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
            from mjrft.field.native import rk4_hold

            held = bool(rk4_hold(data.time, model.opt.timestep, st.rk4))
            if held:
                blocks = st.rk4[_RK4_HEAD:].reshape(len(rows), _RK4_BODY)
                keep = blocks[:, 0] == _RK4_HOLD
                if keep.all():
                    return
        current = np.array(data.xfrc_applied[rows])
        assigned = np.any(current != st.written, axis=1)
        st.user[assigned] = current[assigned]
        user = np.zeros((self.model.nbody, 6))
        user[rows] = st.user
        if held:  # the other bodies feel the pure model of this stage, decisions unchanged
            w = self._pure_wrench(data)
            w[rows[keep]] = self.last_wrench[rows[keep]]
            for k in np.flatnonzero(blocks[:, 0] == _RK4_FROZEN):
                be = self.bodies[k]
                idx = self._candidates(data, be)
                if idx is not None:
                    w[be.body] = self._wrench_at(data, be, idx, blocks[k, 1:7]) + blocks[k, 7:]
        else:
            w = self.wrench(data, user_xfrc=user)
            st.rk4[_RK4_HEAD:] = self._rk4_block.ravel()
        total = st.user + w[rows]
        total[keep] = current[keep]
        data.xfrc_applied[rows] = total
        st.written[:] = total
        counter = int(self._ring[0, 0, 0, 0])
        slot = 1 + counter % XFRC_HISTORY
        self._ring[slot, 0], self._ring[slot, 1] = total, st.user
        self._ring[0, 0, 0, 0] = counter + 1
        self.last_wrench[:] = w

    def _state(self, data: mujoco.MjData) -> _DataState:
        """Ownership state of an MjData, registering it (and its arrays) on first sight."""
        key = data._address
        st = self._data.get(key)
        if st is not None and st.ref() is data:
            return st
        current = np.array(data.xfrc_applied[self.body_ids])
        st = _DataState(
            ref=weakref.ref(data),
            user=self._adopt(current),
            written=current.copy(),
            entry=np.zeros(_native_words(), dtype=np.uint64),
            rk4=np.zeros(_RK4_HEAD + _RK4_BODY * len(self.body_ids)),
        )
        if self._table is not None:
            from mjrft.field import native as nt

            for word, arr in (
                (nt.D_XPOS, data.xpos),
                (nt.D_XMAT, data.xmat),
                (nt.D_XIPOS, data.xipos),
                (nt.D_CVEL, data.cvel),
                (nt.D_SUBTREE_COM, data.subtree_com),
                (nt.D_GEOM_XPOS, data.geom_xpos),
                (nt.D_XFRC, data.xfrc_applied),
                (nt.D_USER, st.user),
                (nt.D_WRITTEN, st.written),
                (nt.D_XIMAT, data.ximat),
                (nt.D_RK4, st.rk4),
            ):
                st.entry[word] = arr.ctypes.data
            st.entry[nt.D_TIME] = _time_address(data)
            _callback.register_data(self.model, key, st.entry.ctypes.data)
        st.finalizer = weakref.finalize(data, self._forget, key, st)
        self._data[key] = st
        return st

    def _forget(self, key: int, st: _DataState) -> None:
        if self._data.get(key) is st:
            self._data.pop(key)
            _callback.unregister_data(key)

    def _adopt(self, current: np.ndarray) -> np.ndarray:
        """User part of rows first seen on an MjData.

        A copy of a tracked MjData carries rows the field wrote (user + RFT); the field keeps
        the user part behind each of its last XFRC_HISTORY writes. Rows matching none of them
        are all the user's.
        """
        n = min(int(self._ring[0, 0, 0, 0]), XFRC_HISTORY)
        if n:
            hits = np.flatnonzero(np.all(self._ring[1 : n + 1, 0] == current, axis=(1, 2)))
            if hits.size:
                return self._ring[1 + hits[-1], 1].copy()
        return current.copy()

    def user_xfrc(self, data: mujoco.MjData) -> np.ndarray:
        """(nbody, 6) ``xfrc_applied`` without the field's contribution (the user's forces)."""
        out = np.array(data.xfrc_applied)
        st = self._data.get(data._address)
        if st is not None and st.ref() is data:
            rows = self.body_ids
            current = out[rows]
            assigned = np.any(current != st.written, axis=1)
            out[rows] = np.where(assigned[:, None], current, st.user)
        return out

    def _restore_user_xfrc(self) -> None:
        for key, st in list(self._data.items()):
            data = st.ref()
            if data is not None:
                data.xfrc_applied[:] = self.user_xfrc(data)
            st.finalizer.detach()
            self._data.pop(key)
            _callback.unregister_data(key)
        self._ring[0, 0, 0, 0] = 0.0

    @contextlib.contextmanager
    def installed(self) -> Iterator[GranularField]:
        """Make RFT forces act inside every ``mj_step``/``mj_forward`` of this model.

        Applies to every MjData of the model; other models (and model compilation) are not
        affected. A user's own passive callback keeps running.
        """
        table = 0 if self._table is None else self._table.ctypes.data
        _callback.install(self.model, lambda m, d: self.apply_passive(m, d), table)
        try:
            yield self
        finally:
            _callback.uninstall(self.model)
            self._restore_user_xfrc()
