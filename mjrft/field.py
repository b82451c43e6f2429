"""The granular force field: RFT wrenches on a compiled MjModel's intruding bodies, every step.

``GranularField(model)`` reads the scene from the MJCF (see ``mjrft.scene``), meshes the tagged
geoms once, and then maps any MjData of that model to one wrench per body, computed from that
data's current kinematics (``xpos``, ``xmat``, ``cvel``, ``subtree_com``: no lag, no finite
differences). Two ways to apply it:

* explicit: ``mj_forward``; ``d.xfrc_applied[:] = user + field.wrench(d)``; ``mj_step`` — the
  wrench is held over the step (all RK4 stages see the same force);
* installed: ``with field.installed(): mj_step(...)`` — in every forward pass (each RK4 stage sees
  its own state) the intruding bodies' rows of ``xfrc_applied`` are set to the user's part plus
  that pass's RFT wrench.

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
import weakref
from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass

import mujoco
import numpy as np

from mjrft import _callback
from mjrft.elements import ElementSet
from mjrft.material import Material
from mjrft.rft import unit_normal_forces
from mjrft.scene import Intruder, Scene, geom_elements, scene_from_model


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
XFRC_HISTORY = 100_000


class GranularField:
    """RFT force field bound to one compiled MjModel.

    Args:
      model: compiled model whose ``<custom>`` describes the scene (``mjrft.scene``).
      material: overrides the MJCF material if given.
      n_triangles: overrides the triangle count of every primitive geom (MJCF ``prm`` and
        ``mjrft:triangles``): fewer is faster and less accurate. Mesh geoms keep their own.
    Raises:
      mjrft.scene.SceneError (a ValueError) naming the geom or field at fault.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        material: Material | None = None,
        *,
        n_triangles: int | None = None,
    ) -> None:
        self.model = model
        self.scene: Scene = scene_from_model(model, material, n_triangles=n_triangles)
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
        #: (nbody, 6) wrench of the most recent forward pass of the installed field.
        self.last_wrench = np.zeros((model.nbody, 6))
        # Per MjData address: (weakref to it, user part of the intruding rows, rows written).
        self._xfrc_state: dict[int, tuple[weakref.ref, np.ndarray, np.ndarray]] = {}
        # Exact bytes of recently written rows -> the user part behind them (for MjData copies).
        self._written_history: OrderedDict[bytes, np.ndarray] = OrderedDict()

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

        Uses data's current kinematics (call ``mj_forward`` first outside a step).
        """
        out = []
        for be in self.bodies:
            idx = self._candidates(data, be)
            if idx is None:
                continue
            b = be.body
            rot = data.xmat[b].reshape(3, 3)
            pos = be.centroids[idx] @ rot.T + data.xpos[b]
            if self.region is not None:
                inside = np.all((pos >= self.region[0]) & (pos <= self.region[1]), axis=1)
                idx, pos = idx[inside], pos[inside]
            normal = be.normals[idx] @ rot.T
            # cvel = [w, v] with v at the subtree CoM of the body's root (DESIGN.md section 3).
            w, v0 = data.cvel[b, :3], data.cvel[b, 3:]
            vel = v0 + _cross(w, pos - data.subtree_com[self.model.body_rootid[b]])
            area = be.areas[idx]
            f = unit_normal_forces(pos, normal, area, vel, self.material, self.surface_z)
            out.append(ElementState(b, idx, pos, normal, area, vel, f))
        return out

    def wrench(self, data: mujoco.MjData, out: np.ndarray | None = None) -> np.ndarray:
        """RFT wrench on every body, ``xfrc_applied`` layout.

        Args:
          data: MjData of this model with current kinematics (``mj_forward`` outside a step).
          out: optional (nbody, 6) array to fill.
        Returns:
          (nbody, 6): world-frame force [N] then torque [N m] about each body's CoM (xipos);
          zero rows for bodies without intruding geoms or out of the medium.
        """
        if out is None:
            out = np.zeros((self.model.nbody, 6))
        else:
            out[:] = 0.0
        self._check_finite(data)
        for st in self.element_states(data):
            f = st.force
            out[st.body, :3] = f.sum(axis=0)
            out[st.body, 3:] = _cross(st.pos - data.xipos[st.body], f).sum(axis=0)
        return out

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
                f"{data.time:.6g} s; the granular field refuses to feed NaN forward (check the "
                "timestep and actuators)"
            )

    # ------------------------------------------------------------------ application
    def apply_passive(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Set the intruding rows of ``xfrc_applied`` to user part + RFT (the installed path).

        Runs inside MuJoCo's passive callback of every forward pass. Calls no mujoco function:
        inside a callback, any binding call resets the binding's per-thread error escape, after
        which an exception raised here would abort the process.
        """
        w = self.wrench(data)
        rows = self.body_ids
        xfrc = data.xfrc_applied
        current = xfrc[rows]
        key = data._address
        state = self._xfrc_state.get(key)
        if state is None or state[0]() is not data:
            user = self._adopt(current)
        else:
            _, user_prev, written = state
            # A row that differs from what the field wrote was assigned by the user.
            assigned = np.any(current != written, axis=1)
            user = np.where(assigned[:, None], current, user_prev)
        total = user + w[rows]
        xfrc[rows] = total
        self._xfrc_state[key] = (weakref.ref(data), user, total)
        history = self._written_history
        history[total.tobytes()] = user
        if len(history) > XFRC_HISTORY:
            history.popitem(last=False)
        self.last_wrench = w

    def _adopt(self, current: np.ndarray) -> np.ndarray:
        """User part of rows first seen on an MjData.

        A copy of a tracked MjData carries rows the field wrote (user + RFT); the field remembers
        the user part behind each of its last HISTORY writes, keyed by their exact bytes. Rows
        that match none are all the user's.
        """
        user = self._written_history.get(current.tobytes())
        return current.copy() if user is None else user.copy()

    def user_xfrc(self, data: mujoco.MjData) -> np.ndarray:
        """(nbody, 6) ``xfrc_applied`` without the field's contribution (the user's forces)."""
        out = np.array(data.xfrc_applied)
        state = self._xfrc_state.get(data._address)
        if state is not None and state[0]() is data:
            _, user, written = state
            rows = self.body_ids
            current = out[rows]
            assigned = np.any(current != written, axis=1)
            out[rows] = np.where(assigned[:, None], current, user)
        return out

    def _restore_user_xfrc(self) -> None:
        for ref, _, _ in list(self._xfrc_state.values()):
            data = ref()
            if data is not None:
                data.xfrc_applied[:] = self.user_xfrc(data)
        self._xfrc_state.clear()
        self._written_history.clear()

    @contextlib.contextmanager
    def installed(self) -> Iterator[GranularField]:
        """Make RFT forces act inside every ``mj_step``/``mj_forward`` of this model.

        Applies to every MjData of the model; other models (and model compilation) are not
        affected. A user's own passive callback keeps running.
        """
        _callback.install(self.model, lambda m, d: self.apply_passive(m, d))
        try:
            yield self
        finally:
            _callback.uninstall(self.model)
            self._restore_user_xfrc()
