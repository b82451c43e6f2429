"""MuJoCo's interactive viewer stepping a granular scene, the field's forces drawn.

``mjrft view MODEL`` runs ``launch``; in a loop of your own, step a model from
``mjrft.load_model`` (its engine plugin acts in every step) and call
``draw_forces(viewer.user_scn, ...)`` before ``viewer.sync()``
(docs/field.md, "In MuJoCo's viewer"). The arrows are scene decorations (``mjvScene`` user
geoms): they are drawn, never simulated. A deforming ground whose initial surface is an hfield
(``mjrft:surface_hfield``) is drawn by that hfield, rewritten in place (``draw_ground``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import mujoco
import numpy as np

from mjrft.app.view import has_display
from mjrft.field.granular_field import GranularField

#: Candidate arrow colours (RGB), saturated and far from MuJoCo's default greys and from each
#: other: ``arrow_colors`` picks, for each model, the two farthest from every colour the model's
#: visible geoms show (an orange arrow on an orange torso would vanish).
ARROW_PALETTE = np.array(
    [
        [1.0, 0.0, 1.0],  # magenta
        [0.0, 1.0, 1.0],  # cyan
        [1.0, 1.0, 0.0],  # yellow
        [0.2, 1.0, 0.0],  # green
        [1.0, 0.45, 0.0],  # orange
        [0.1, 0.35, 1.0],  # blue
        [1.0, 0.0, 0.2],  # red
    ],
    dtype=np.float32,
)
#: Opacity of the per-body and the per-triangle arrows.
BODY_ARROW_ALPHA, TRIANGLE_ARROW_ALPHA = 1.0, 0.85
#: With the automatic scale, no body arrow is longer than its body's size (the longest side of
#: the bounding box of its RFT triangles; the binding one is that long).
AUTO_BODY_ARROW_FRACTION = 1.0
#: ... and a body's longest triangle arrow is this fraction of its size, as in recordings (viz).
AUTO_ARROW_FRACTION = 0.3
#: The automatic scale shrinks at once when the forces grow and grows back at most by this
#: factor per simulated second when they fall, so that arrow lengths compare across frames
#: instead of flickering to one length.
AUTO_SCALE_RECOVERY_PER_S = 2.0
#: Arrow shaft width as a fraction of its length, with bounds as fractions of its body's size,
#: so that short arrows stay visible and long ones do not hide the body.
ARROW_WIDTH_FRACTION = 0.06
ARROW_WIDTH_MIN, ARROW_WIDTH_MAX = 0.03, 0.08
#: At most this many per-triangle arrows per body and frame (an even stride through the
#: triangles that feel a force): a frame stays cheap to draw.
DEFAULT_MAX_TRIANGLE_ARROWS = 200
#: Forces below this [N] draw no arrow (round-off of a body just at the surface).
MIN_ARROW_FORCE = 1e-9
#: The viewer redraws a deforming ground's hfield every this many simulated seconds.
GROUND_PERIOD_S = 0.05


def model_colors(model: mujoco.MjModel) -> np.ndarray:
    """(n, 3) RGB of the model's visible geoms (groups 0-2, MuJoCo's viewer default; their
    material's colour where they have one), without repeats."""
    rgba = model.geom_rgba.copy()
    mat = model.geom_matid >= 0
    rgba[mat] = model.mat_rgba[model.geom_matid[mat]]
    shown = (model.geom_group <= 2) & (rgba[:, 3] > 0)
    return np.unique(rgba[shown, :3].round(3), axis=0)


def arrow_colors(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """(body arrow RGBA, triangle arrow RGBA): the two ARROW_PALETTE colours farthest (RGB
    distance to the nearest) from every colour of the model's visible geoms, the second also
    far from the first."""
    own = model_colors(model)
    if len(own) == 0:
        own = np.zeros((1, 3), dtype=np.float32)
    gap = np.linalg.norm(ARROW_PALETTE[:, None, :] - own[None, :, :], axis=2).min(axis=1)
    first = int(np.argmax(gap))
    apart = np.linalg.norm(ARROW_PALETTE - ARROW_PALETTE[first], axis=1)
    second = int(np.argmax(np.where(np.arange(len(gap)) == first, -1.0, np.minimum(gap, apart))))
    body = np.append(ARROW_PALETTE[first], BODY_ARROW_ALPHA).astype(np.float32)
    tri = np.append(ARROW_PALETTE[second], TRIANGLE_ARROW_ALPHA).astype(np.float32)
    return body, tri


def body_sizes(fld: GranularField) -> np.ndarray:
    """(n_intruders,) size [m] of each intruding body: the longest side of the bounding box of
    its RFT triangles' vertices (body frame), in ``fld.body_ids`` order."""
    vertices = [np.asarray(fld.body_element_set(b).vertices) for b in fld.body_ids]
    return np.array([float(np.ptp(v, axis=0).max()) for v in vertices])


class ArrowScale:
    """The automatic arrow scale [m/N] of a viewer: per frame, the largest scale at which no
    body's force arrow is longer than AUTO_BODY_ARROW_FRACTION of its body's size; it follows a
    smaller value at once and a larger one at most AUTO_SCALE_RECOVERY_PER_S per simulated
    second. ``fixed`` [m/N] holds the scale instead."""

    def __init__(self, sizes: np.ndarray, fixed: float | None = None) -> None:
        if fixed is not None and not (math.isfinite(fixed) and fixed > 0):
            raise ValueError(f"force_scale must be a finite number > 0 m/N, got {fixed}")
        self.sizes, self.fixed = np.asarray(sizes, dtype=np.float64), fixed
        self.value = math.inf if fixed is None else float(fixed)
        self._time = -math.inf

    def update(self, forces: np.ndarray, time: float) -> float:
        """The scale for a frame at simulated `time` [s] whose bodies feel `forces` (n, 3) [N]
        (world frame, in ``fld.body_ids`` order)."""
        if self.fixed is not None:
            return self.value
        mag = np.linalg.norm(forces, axis=1)
        acting = mag > MIN_ARROW_FORCE
        if acting.any():
            wanted = AUTO_BODY_ARROW_FRACTION * float(np.min(self.sizes[acting] / mag[acting]))
            grown = self.value * AUTO_SCALE_RECOVERY_PER_S ** max(time - self._time, 0.0)
            self.value = min(wanted, grown)
            self._time = time
        return self.value


def _add_arrow(scn: mujoco.MjvScene, tail: np.ndarray, head: np.ndarray, rgba, size: float) -> bool:
    """Append an arrow from tail to head (world frame [m]) to scn, its width set by its length
    and its body's `size` [m]; False if scn is full."""
    if scn.ngeom >= scn.maxgeom:
        return False
    length = float(np.linalg.norm(head - tail))
    width = min(max(ARROW_WIDTH_FRACTION * length, ARROW_WIDTH_MIN * size), ARROW_WIDTH_MAX * size)
    g = scn.geoms[scn.ngeom]
    mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                        rgba)  # fmt: skip
    mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_ARROW, width, tail, head)
    scn.ngeom += 1
    return True


class ForceArrows:
    """What ``draw_forces`` needs of a model besides its state, computed once: each intruding
    body's size, the arrow colours (``arrow_colors``) and the arrow scale (``ArrowScale``;
    ``force_scale`` [m/N] fixes it, None is automatic)."""

    def __init__(
        self, model: mujoco.MjModel, fld: GranularField, force_scale: float | None = None
    ) -> None:
        self.sizes = body_sizes(fld)
        self.body_rgba, self.triangle_rgba = arrow_colors(model)
        self.scale = ArrowScale(self.sizes, force_scale)


def draw_forces(
    scn: mujoco.MjvScene,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    fld: GranularField,
    *,
    force_scale: float | None = None,
    triangles: bool = False,
    max_triangle_arrows: int = DEFAULT_MAX_TRIANGLE_ARROWS,
    arrows: ForceArrows | None = None,
    keep: int = 0,
) -> int:
    """Replace scn's geoms from index `keep` on (the viewer's ``user_scn``: all of them; a
    ``mujoco.Renderer``'s scene: keep its model geoms) by the RFT force on every intruding
    body, as arrows in colours that stand out from the model's (``arrow_colors``).

    Per body: an arrow along the field's latest force on it (``fld.wrench_of(data)``), world
    frame, starting half the body's size out of its CoM (``data.xipos``) in that direction (so
    that it stands outside the body), ``force_scale`` [m/N] long per newton, or with None the
    automatic scale (``ArrowScale``: no arrow longer than its body's size; pass the same
    `arrows` every frame so that it carries over). With triangles, also the
    per-triangle forces (``fld.element_states``, which evaluates the pure model at data's
    kinematics: call it after a step or ``mj_forward``), each drawn with its tip on the triangle,
    the longest of a body AUTO_ARROW_FRACTION of its size (with a fixed scale: that scale times
    the body's acting triangles over the arrows drawn, so that they add up to about the body's
    arrow). Returns the number of arrows drawn (fewer if scn.maxgeom is reached).
    """
    arrows = arrows or ForceArrows(model, fld, force_scale)
    scn.ngeom = keep
    drawn = 0
    forces = fld.wrench_of(data)[fld.body_ids, :3]
    scale = arrows.scale.update(forces, data.time)
    for k, b in enumerate(fld.body_ids):
        f = forces[k]
        magnitude = float(np.linalg.norm(f))
        if magnitude > MIN_ARROW_FORCE:
            # From half the body's size out of its CoM along the force: outside the body, seen.
            tail = data.xipos[b] + (0.5 * arrows.sizes[k] / magnitude) * f
            drawn += _add_arrow(scn, tail, tail + scale * f, arrows.body_rgba, arrows.sizes[k])
    if triangles:
        for k, st in enumerate(fld.element_states(data)):
            mag = np.linalg.norm(st.force, axis=1)
            acting = np.flatnonzero(mag > MIN_ARROW_FORCE)
            if not len(acting):
                continue
            pick = acting[:: max(1, -(-len(acting) // max(max_triangle_arrows, 1)))]
            if arrows.scale.fixed is None:
                each = AUTO_ARROW_FRACTION * arrows.sizes[k] / mag[acting].max()
            else:
                each = arrows.scale.fixed * len(acting) / len(pick)
            for i in pick:
                head = st.pos[i]
                drawn += _add_arrow(scn, head - each * st.force[i], head, arrows.triangle_rgba,
                                    arrows.sizes[k])  # fmt: skip
    return drawn


def track(viewer_cam: mujoco.MjvCamera, model: mujoco.MjModel, body: str | None) -> None:
    """Make `viewer_cam` a tracking camera following `body` (a body name), at a distance of
    about twice the model's extent; None leaves the camera free.

    Raises:
      ValueError naming the body and the model's bodies (the closest first) if there is none of
      that name.
    """
    if body is None:
        return
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if bid <= 0:  # the world body cannot be tracked
        import difflib

        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) or f"#{i}"
                 for i in range(1, model.nbody)]  # fmt: skip
        close = difflib.get_close_matches(body, names, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ValueError(f"--track {body!r}: the model has no such body ({', '.join(names)}){hint}")
    viewer_cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
    viewer_cam.trackbodyid = bid
    viewer_cam.fixedcamid = -1
    viewer_cam.distance = 2.0 * float(model.stat.extent)


def ground_hfield(model: mujoco.MjModel, fld: GranularField) -> int:
    """The hfield that draws fld's deforming ground: the one ``mjrft:surface_hfield`` names;
    -1 if the ground does not deform or has no hfield."""
    t = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, "mjrft:surface_hfield")
    if not fld.deforms or t < 0:
        return -1
    from mjrft.field.scene import _text  # the MJCF text as the scene reads it

    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_HFIELD, _text(model, t))


def draw_ground(
    model: mujoco.MjModel, data: mujoco.MjData, fld: GranularField, hfield: int
) -> None:
    """Write data's deforming ground into hfield's samples (``model.hfield_data``, in place,
    clipped to the hfield's elevation range) where they lie over the ground's grid; call the
    viewer's ``update_hfield(hfield)`` after. The engine starts every MjData's ground from its
    own tables, but a GranularField made from this model while the samples are rewritten would
    read another surface than the tables hold (and refuse the model): restore ``hfield_data``
    after (``launch`` does)."""
    g = int(np.flatnonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_HFIELD)
                           & (model.geom_dataid == hfield))[0])  # fmt: skip
    rx, ry, top, _ = (float(v) for v in model.hfield_size[hfield])
    nrow, ncol = int(model.hfield_nrow[hfield]), int(model.hfield_ncol[hfield])
    x0, y0, z0 = (float(v) for v in model.geom_pos[g])
    x, y = np.meshgrid(np.linspace(x0 - rx, x0 + rx, ncol), np.linspace(y0 - ry, y0 + ry, nrow))
    soil = fld.soil(data)
    inside = ((x >= soil.x[0]) & (x <= soil.x[-1]) & (y >= soil.y[0])
              & (y <= soil.y[-1])).ravel()  # fmt: skip
    adr = int(model.hfield_adr[hfield])
    samples = model.hfield_data[adr : adr + nrow * ncol]
    h = soil.height_at(x.ravel()[inside], y.ravel()[inside])
    samples[inside] = np.clip((h - z0) / top, 0.0, 1.0)


def launch(
    model: mujoco.MjModel,
    fld: GranularField,
    *,
    data: mujoco.MjData | None = None,
    ctrl: Callable[[float, mujoco.MjData], np.ndarray | None] | None = None,
    force_scale: float | None = None,
    triangles: bool = False,
    duration: float | None = None,
    track_body: str | None = None,
) -> mujoco.MjData:
    """Simulate fld's model in MuJoCo's passive viewer, in real time, the field's forces drawn
    (``draw_forces``; `force_scale` [m/N] or None for the automatic scale), until the window is
    closed (or `duration` simulated seconds pass); `track_body` names a body the camera follows
    (``track``).

    ctrl: an optional controller ``ctrl(t, data)`` as in ``mjrft.app.simulate.run``. Returns the
    final MjData. Raises RuntimeError naming what is missing when no window can be opened, and
    ValueError naming a `track_body` the model lacks.
    """
    import mujoco.viewer

    from mjrft.app.simulate import checked_controller

    if not has_display():
        raise RuntimeError(
            "mjrft view needs a display (DISPLAY and WAYLAND_DISPLAY are unset); on a headless "
            "machine record the run instead: mjrft run MODEL --duration T --out DIR --rrd run.rrd"
        )
    data = data if data is not None else mujoco.MjData(model)
    apply_ctrl = checked_controller(model, ctrl)
    arrows = ForceArrows(model, fld, force_scale)
    track(mujoco.MjvCamera(), model, track_body)  # a missing body is named before any window
    hfield = ground_hfield(model, fld)
    initial = model.hfield_data.copy()
    try:
        with mujoco.viewer.launch_passive(model, data) as viewer:
            with viewer.lock():
                track(viewer.cam, model, track_body)
            wall0, sim0 = time.perf_counter(), data.time
            drawn = -math.inf
            while viewer.is_running() and (duration is None or data.time - sim0 < duration):
                with viewer.lock():
                    if apply_ctrl is not None:
                        apply_ctrl(data)
                    mujoco.mj_step(model, data)
                    draw_forces(viewer.user_scn, model, data, fld, triangles=triangles,
                                arrows=arrows)  # fmt: skip
                    if hfield >= 0 and data.time - drawn >= GROUND_PERIOD_S:
                        draw_ground(model, data, fld, hfield)
                        drawn = data.time
                if drawn == data.time:
                    viewer.update_hfield(hfield)
                viewer.sync()
                ahead = (data.time - sim0) - (time.perf_counter() - wall0)
                if ahead > 0:
                    time.sleep(ahead)  # real time: never faster than the simulation clock
    finally:
        model.hfield_data[:] = initial  # the model's own initial surface again
    return data
