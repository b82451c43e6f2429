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

from mjrft.app.recording_defaults import DEFAULT_FORCE_SCALE
from mjrft.app.view import has_display
from mjrft.field.granular_field import GranularField

#: Colour of the per-body RFT force arrows (RGBA): orange, apart from MuJoCo's own contact
#: force arrows.
BODY_ARROW_RGBA = np.array([1.0, 0.45, 0.0, 1.0], dtype=np.float32)
#: Colour of the per-triangle RFT force arrows (RGBA).
TRIANGLE_ARROW_RGBA = np.array([0.1, 0.6, 1.0, 0.8], dtype=np.float32)
#: Arrow shaft width as a fraction of its length, with bounds [m] so that short arrows stay
#: visible and long ones do not hide the body.
ARROW_WIDTH_FRACTION = 0.04
ARROW_WIDTH_MIN, ARROW_WIDTH_MAX = 0.0008, 0.006
#: At most this many per-triangle arrows per body and frame (an even stride through the
#: triangles that feel a force): a frame stays cheap to draw.
DEFAULT_MAX_TRIANGLE_ARROWS = 200
#: Forces below this [N] draw no arrow (round-off of a body just at the surface).
MIN_ARROW_FORCE = 1e-9
#: The viewer redraws a deforming ground's hfield every this many simulated seconds.
GROUND_PERIOD_S = 0.05


def _add_arrow(scn: mujoco.MjvScene, tail: np.ndarray, head: np.ndarray, rgba) -> bool:
    """Append an arrow from tail to head (world frame [m]) to scn; False if scn is full."""
    if scn.ngeom >= scn.maxgeom:
        return False
    length = float(np.linalg.norm(head - tail))
    width = min(max(ARROW_WIDTH_FRACTION * length, ARROW_WIDTH_MIN), ARROW_WIDTH_MAX)
    g = scn.geoms[scn.ngeom]
    mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                        rgba)  # fmt: skip
    mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_ARROW, width, tail, head)
    scn.ngeom += 1
    return True


def draw_forces(
    scn: mujoco.MjvScene,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    fld: GranularField,
    *,
    force_scale: float = DEFAULT_FORCE_SCALE,
    triangles: bool = False,
    max_triangle_arrows: int = DEFAULT_MAX_TRIANGLE_ARROWS,
) -> int:
    """Replace scn's user geoms by the RFT force on every intruding body, as arrows.

    Per body: an arrow from its CoM (``data.xipos``) along the field's latest force on it
    (``fld.wrench_of(data)``), force_scale [m/N] long per newton, world frame. With triangles,
    also the per-triangle forces (``fld.element_states``, which evaluates the pure model at
    data's kinematics: call it after a step or ``mj_forward``), each drawn with its tip on the
    triangle, at the same scale times the body's triangle count over the arrows drawn, so
    that the triangle arrows of a body add up to about its arrow's length. Returns the number of
    arrows drawn (fewer if scn.maxgeom is reached).
    """
    if not (math.isfinite(force_scale) and force_scale > 0):
        raise ValueError(f"force_scale must be a finite number > 0 m/N, got {force_scale}")
    scn.ngeom = 0
    drawn = 0
    wrench = fld.wrench_of(data)
    for b in fld.body_ids:
        f = wrench[b, :3]
        if np.linalg.norm(f) > MIN_ARROW_FORCE:
            tail = data.xipos[b]
            drawn += _add_arrow(scn, tail, tail + force_scale * f, BODY_ARROW_RGBA)
    if triangles:
        for st in fld.element_states(data):
            acting = np.flatnonzero(np.linalg.norm(st.force, axis=1) > MIN_ARROW_FORCE)
            pick = acting[:: max(1, -(-len(acting) // max(max_triangle_arrows, 1)))]
            scale = force_scale * len(acting) / max(len(pick), 1)
            for i in pick:
                head = st.pos[i]
                drawn += _add_arrow(scn, head - scale * st.force[i], head, TRIANGLE_ARROW_RGBA)
    return drawn


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
    force_scale: float = DEFAULT_FORCE_SCALE,
    triangles: bool = False,
    duration: float | None = None,
) -> mujoco.MjData:
    """Simulate fld's model in MuJoCo's passive viewer, in real time, the field's forces drawn,
    until the window is closed (or `duration` simulated seconds pass).

    ctrl: an optional controller ``ctrl(t, data)`` as in ``mjrft.app.simulate.run``. Returns the
    final MjData. Raises RuntimeError naming what is missing when no window can be opened.
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
    hfield = ground_hfield(model, fld)
    initial = model.hfield_data.copy()
    try:
        with mujoco.viewer.launch_passive(model, data) as viewer:
            wall0, sim0 = time.perf_counter(), data.time
            drawn = -math.inf
            while viewer.is_running() and (duration is None or data.time - sim0 < duration):
                with viewer.lock():
                    if apply_ctrl is not None:
                        apply_ctrl(data)
                    mujoco.mj_step(model, data)
                    draw_forces(viewer.user_scn, model, data, fld, force_scale=force_scale,
                                triangles=triangles)  # fmt: skip
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
