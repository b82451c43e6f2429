"""Headless rerun recordings of a granular-field run: bodies, medium, per-element RFT forces.

A leaf module (only the CLI imports it; importing ``mjrft`` never imports rerun). A
:class:`Recorder` owns its own ``rerun.RecordingStream`` (never rerun's global one), writes to an
``.rrd`` file, and opens no port and spawns no viewer unless asked (``spawn=True`` /
``connect=URL``). Use it as a context manager or call :meth:`Recorder.close` in a ``finally``:
closing sends what is buffered, flushes and finalises the file, so a run that raises or is
interrupted (Ctrl-C) still leaves a complete, readable recording of every frame whose logging
completed, and of no other.

What one frame holds (entity paths; ``<body>`` is the MuJoCo body name, escaped for rerun):

* ``world/bodies/<body>`` - Transform3D: the body frame's pose (``xpos``, ``xmat``) in the world.
* ``world/bodies/<body>/rft_mesh`` - intruding bodies: the RFT surface triangles as a Mesh3D in
  the body frame (positions and normals static, each triangle with its own three vertices), and
  temporal vertex colours: each triangle coloured by its RFT stress |F| / dA on the fixed scale
  0 ... ``stress_max`` [Pa] (viridis; above the scale clipped to yellow), grey where no force
  acts. The grey of the first frame is logged at that frame.
* ``world/bodies/<body>/geoms`` - the body's other geoms as coarse static meshes (body frame).
* ``world/forces/<body>`` - Arrows3D in the world frame, one per triangle that feels a force (at
  most ``max_arrows`` per body: an even stride through them), coloured like the mesh: vector =
  RFT force on the triangle [N] times the frame's arrow scale [m/N], drawn so that its tip is the
  triangle's centroid (the arrow lies in the medium and pushes on the surface). Components
  ``element_index`` (each arrow's triangle index in ``field.bodies[i]`` order) and
  ``arrow_scale`` (the frame's scale [m/N]). The automatic scale makes the frame's longest
  arrow ``AUTO_ARROW_FRACTION`` of the body's size (the longest side of its RFT mesh's bounding
  box); a fixed ``arrow_scale`` holds for every frame.
* ``rft/<body>/force/{x,y,z}`` [N] and ``rft/<body>/torque/{x,y,z}`` [N m]: Scalars, the body's
  RFT force and torque about its CoM (world frame), the sums over all its triangles.
* ``sensors/<name>`` (1-D sensors) or ``sensors/<name>/<i>``: every MJCF sensor, as in the CSV.

Static (what never changes): ``world`` (z up), ``world/surface`` (the free surface z =
``surface_z``, translucent, over the medium's region or around the bodies), ``world/region`` (the
medium's box, if the MJCF sets one), the meshes' positions, normals and triangles, the series'
names and colours, and ``info`` (this legend with the run's scales). Everything that changes is
temporal, so rerun shows each frame's value (static data of a component would hide every
temporal value of it on that entity). Timelines: ``step`` (sequence: number of steps taken before
the logged state) and ``sim_time`` (duration: MuJoCo time of the logged state).

The default blueprint (sent with the first frame) opens a 3D view framed on the intruders at the
first frame, seen from the front (-y) and from just below the free surface (``CAMERA_DIRECTION``),
next to a force and a torque panel per intruding body (tabs if there are several) and a panel of
the MJCF sensors; the legend is a tab beside the 3D view, the side panels start collapsed.

Which state a frame shows: the state the step integrated from (for Euler and the implicit
integrators, the derived quantities MuJoCo leaves after ``mj_step`` describe the pre-step state:
the pose, ``cvel`` and sensors that produced the RFT force of that step). ``simulate.run`` calls
the recorder there, with that state's time; for RK4 it runs ``mj_forward`` first. Per-element
forces come from ``GranularField.element_states`` at exactly that state.
"""

from __future__ import annotations

import math
import os
import shutil
import sys
import tempfile
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb

from mjrft.app import rrd_file, simulate
from mjrft.app.recording_defaults import (
    DEFAULT_CONNECT_URL,
    DEFAULT_FRAME_PERIOD_S,
    DEFAULT_MAX_ARROWS,
    DEFAULT_STRESS_MAX_PA,
)
from mjrft.core import geometry, surface
from mjrft.field.granular_field import GranularField
from mjrft.field.signals import HeldSignals

#: Frames are buffered and sent every this many frames (and when the recorder closes).
FLUSH_FRAMES = 100
#: With the automatic arrow scale, the longest arrow of a frame is this fraction of the body's
#: size (the longest side of its RFT mesh's bounding box, body frame).
AUTO_ARROW_FRACTION = 0.3
#: Arrow shaft radius as a fraction of the body's size.
ARROW_RADIUS_PER_SIZE = 0.004
#: Target triangle count of each non-intruding primitive geom drawn (coarse: shape only).
OTHER_GEOM_TRIANGLES = 200
#: Colour of triangles on which no RFT force acts (RGB, 0-255).
NO_FORCE_RGB = (170, 170, 170)
#: Colour of the free surface (RGBA; translucent sand, so that what is behind it stays visible)
#: and of the region box.
SURFACE_RGBA = (222, 194, 140, 60)
REGION_RGBA = (150, 120, 70, 255)
#: Half size of the drawn surface when the MJCF sets no region: model extent times this [-].
SURFACE_EXTENT_FACTOR = 0.5
#: Samples per side of the drawn surface when it is not flat (a tilted plane or a height field).
SURFACE_SAMPLES = 65
#: Deforming ground: its heights are logged every this many frames (0.1 s at the default frame
#: period), on at most this many vertices per side (every k-th row and column of its grid).
GROUND_EVERY_FRAMES = 10
GROUND_MAX_SIDE = 200
#: Default camera: distance from the look target in diagonals of the intruders' bounding box,
#: and the direction from the target to the eye (world frame): from the front (-y, the pitch
#: plane of the rigs faces it), a little to the right and a little below the target, so that the
#: parts in the medium are seen directly, not through the translucent surface (which tints them).
CAMERA_DISTANCE_PER_DIAGONAL = 2.5
CAMERA_DIRECTION = (0.45, -1.0, -0.15)
#: Colours of the x, y, z series of the force and torque panels (RGB, rerun's axis colours).
AXIS_RGB = {"x": (225, 70, 70), "y": (60, 170, 70), "z": (60, 110, 230)}

# Viridis, sampled at 0, 1/8, ..., 1 (RGB, 0-255); linear interpolation between samples.
_VIRIDIS = np.array(
    [
        [68, 1, 84],
        [71, 44, 122],
        [59, 81, 139],
        [44, 113, 142],
        [33, 144, 141],
        [39, 173, 129],
        [92, 200, 99],
        [170, 220, 50],
        [253, 231, 37],
    ],
    dtype=np.float64,
)


def _rgba32(rgb: np.ndarray) -> np.ndarray:
    """Pack (n, 3) RGB in 0..255 into rerun's Rgba32 (0xRRGGBBAA, opaque) as uint32."""
    c = np.rint(rgb).astype(np.uint32)
    return (c[:, 0] << 24) | (c[:, 1] << 16) | (c[:, 2] << 8) | np.uint32(255)


#: Number of colour levels of the stress scale.
STRESS_LEVELS = 256
_STRESS_LUT = _rgba32(
    np.column_stack(
        [
            np.interp(np.linspace(0.0, 1.0, STRESS_LEVELS), np.linspace(0, 1, len(_VIRIDIS)), c)
            for c in _VIRIDIS.T
        ]
    )
)
_NO_FORCE = _rgba32(np.array([NO_FORCE_RGB]))[0]


def stress_colors(stress: np.ndarray, stress_max: float) -> np.ndarray:
    """Colour of each triangle from its stress |F|/dA [Pa], as (n,) uint32 Rgba32 (0xRRGGBBAA).

    Viridis in ``STRESS_LEVELS`` steps over 0 ... ``stress_max`` [Pa], clipped above; exactly
    zero stress (no force acts) is grey ``NO_FORCE_RGB``. Opaque.
    """
    s = np.asarray(stress, dtype=np.float64)
    level = np.rint(np.clip(s / stress_max, 0.0, 1.0) * (STRESS_LEVELS - 1)).astype(np.int64)
    return np.where(s == 0.0, _NO_FORCE, _STRESS_LUT[level]).astype(np.uint32)


def _body_name(model: mujoco.MjModel, b: int) -> str:
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"


def _part(name: str) -> str:
    """One entity-path component (rerun escapes '/', spaces and other special characters)."""
    return rr.escape_entity_path_part(name)


def sensor_entities(model: mujoco.MjModel) -> list[str]:
    """Entity path of every sensordata entry, in sensordata order (mirrors the CSV columns)."""
    out = []
    for s in range(model.nsensor):
        name = _part(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, s) or f"sensor{s}")
        dim = int(model.sensor_dim[s])
        out += [f"sensors/{name}"] if dim == 1 else [f"sensors/{name}/{i}" for i in range(dim)]
    return out


def _quat_mat(q: np.ndarray) -> np.ndarray:
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, dtype=np.float64))
    return m.reshape(3, 3)


def _geom_mesh(model: mujoco.MjModel, g: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices, faces) of a geom in its geom frame for drawing, or None if not drawable."""
    t = int(model.geom_type[g])
    kinds = {
        int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
        int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): "ellipsoid",
        int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
        int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder",
        int(mujoco.mjtGeom.mjGEOM_BOX): "box",
    }
    if t == int(mujoco.mjtGeom.mjGEOM_MESH):
        mid = model.geom_dataid[g]
        va, vn = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        fa, fn = model.mesh_faceadr[mid], model.mesh_facenum[mid]
        return (
            np.array(model.mesh_vert[va : va + vn], dtype=np.float64),
            np.array(model.mesh_face[fa : fa + fn], dtype=np.int64),
        )
    if t not in kinds:
        return None
    try:
        es = geometry.primitive(kinds[t], model.geom_size[g], n_triangles=OTHER_GEOM_TRIANGLES)
    except ValueError:
        return None
    return np.asarray(es.vertices), np.asarray(es.faces)


def _viewer_executable() -> str | None:
    """The ``rerun`` viewer on PATH, else the one installed next to this Python (a venv that
    is not activated), else None (rerun then reports how to install it)."""
    found = shutil.which("rerun")
    if found:
        return found
    beside = Path(sys.executable).with_name("rerun")
    return str(beside) if beside.exists() else None


@dataclass(frozen=True)
class _Frame:
    """One frame as logged: everything a flush sends (built whole, then appended at once)."""

    step: int
    time: float
    xpos: np.ndarray  # (drawn, 3)
    xmat: np.ndarray  # (drawn, 9)
    scalars: np.ndarray  # (scalar paths,)
    # per intruder whose appearance is logged at this frame: (k in fld.bodies, vertex colours
    # (3 n_tri,), element_index, origins, vectors, arrow scale [m/N] or None without arrows)
    looks: tuple[tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float | None], ...]
    ground: np.ndarray | None  # (vertices, 3) of the deforming ground [m, world], or None


def _stride(n: int) -> np.ndarray:
    """At most GROUND_MAX_SIDE indices of 0..n-1, evenly spread, the first and last included."""
    return np.unique(np.rint(np.linspace(0, n - 1, min(n, GROUND_MAX_SIDE))).astype(np.int64))


class Recorder:
    """Logs frames of a MuJoCo run with a GranularField to a rerun recording (headless).

    Args:
      model: the compiled model; fld: its field (the per-element forces come from it).
      path: ``.rrd`` file to write (parent folders created); None to only stream (needs
        ``spawn`` or ``connect``).
      every: log a frame every this many steps (used by :func:`record` / ``simulate.run``);
        None: ``DEFAULT_FRAME_PERIOD_S`` of simulated time, round(0.01 s / timestep) steps.
      max_arrows: maximum force arrows per body and frame (0: no arrows).
      arrow_scale: arrow length per newton [m/N] for every frame; None: automatic, per body and
        frame, so that the frame's longest arrow is ``AUTO_ARROW_FRACTION`` of the body's size.
      stress_max: top of the triangle colour scale [Pa].
      spawn: also start a rerun viewer and stream to it (opens a local port).
      connect: also stream to a running viewer at this gRPC URL (e.g. ``DEFAULT_CONNECT_URL``).
      other_geoms: draw the non-intruding geoms of moving bodies (coarse, static per body).
      application_id, recording_id: rerun's identifiers (recording_id random if None).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        fld: GranularField,
        path: str | os.PathLike | None,
        *,
        every: int | None = None,
        max_arrows: int = DEFAULT_MAX_ARROWS,
        arrow_scale: float | None = None,
        stress_max: float = DEFAULT_STRESS_MAX_PA,
        spawn: bool = False,
        connect: str | None = None,
        other_geoms: bool = True,
        application_id: str = "mjrft",
        recording_id: str | None = None,
    ) -> None:
        if every is None:
            every = max(1, round(DEFAULT_FRAME_PERIOD_S / model.opt.timestep))
        if every < 1:
            raise ValueError(f"every must be >= 1 step, got {every}")
        if max_arrows < 0:
            raise ValueError(f"max_arrows must be >= 0, got {max_arrows}")
        if arrow_scale is not None and not (math.isfinite(arrow_scale) and arrow_scale > 0):
            raise ValueError(f"arrow_scale must be a finite number > 0 m/N, got {arrow_scale}")
        if not (math.isfinite(stress_max) and stress_max > 0):
            raise ValueError(f"stress_max must be a finite number > 0 Pa, got {stress_max}")
        if path is None and not spawn and not connect:
            raise ValueError("a recording needs a file path, spawn=True or connect=URL")
        self.model, self.fld = model, fld
        self.path = None if path is None else Path(path)
        self.every, self.max_arrows, self.stress_max = int(every), int(max_arrows), stress_max
        self.fixed_arrow_scale = None if arrow_scale is None else float(arrow_scale)
        self._last_arrow_scale = math.nan
        self._names = {b: _part(_body_name(model, b)) for b in range(1, model.nbody)}
        self._other = self._other_geom_meshes() if other_geoms else {}
        self._intruders = [be.body for be in fld.bodies]
        self._drawn = sorted(set(self._intruders) | set(self._other))
        # Body-frame vertices of each intruder's RFT mesh: its size and the camera framing.
        self._vertices = [np.asarray(fld.body_element_set(b).vertices) for b in self._intruders]
        self.body_sizes = np.array([float(np.ptp(v, axis=0).max()) for v in self._vertices])
        self.arrow_radii = ARROW_RADIUS_PER_SIZE * self.body_sizes
        self._scalar_paths = [
            f"rft/{self._names[be.body]}/{q}/{a}"
            for be in fld.bodies
            for q in ("force", "torque")
            for a in "xyz"
        ] + sensor_entities(model)
        # Per intruder, what its entities show now: None (nothing logged yet), False (grey, no
        # arrows) or True (stress colours and arrows).
        self._shown: list[bool | None] = [None] * len(fld.bodies)
        # The deforming ground's drawn vertices: every k-th row and column of its grid.
        self._ground_rows = self._ground_cols = None
        if fld.deforms:
            soil0 = fld.soil(mujoco.MjData(model))
            self._ground_rows = _stride(len(soil0.y))
            self._ground_cols = _stride(len(soil0.x))
            self._ground_xy = np.meshgrid(soil0.x[self._ground_cols], soil0.y[self._ground_rows])
        self._buffer: list[_Frame] = []
        self._sent = 0
        self._blueprint_sent = False
        self._closed = False

        self.rec = rr.RecordingStream(application_id, recording_id=recording_id)
        self.rec.set_log_time_enabled(False)  # only the simulation's timelines
        sinks = []
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(self.path)))
        if spawn:
            try:
                rr.spawn(connect=False, executable_path=_viewer_executable(), recording=self.rec)
            except RuntimeError as exc:  # no viewer executable, or it failed to start
                raise ValueError(f"cannot start the rerun viewer (spawn): {exc}") from exc
            sinks.append(rr.GrpcSink(DEFAULT_CONNECT_URL))
        if connect:
            if not spawn or connect != DEFAULT_CONNECT_URL:
                sinks.append(rr.GrpcSink(connect))
        self.rec.set_sinks(*sinks)
        try:
            self._log_static()
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ properties
    @property
    def frames(self) -> int:
        """Number of frames whose logging completed (sent or buffered)."""
        return self._sent + len(self._buffer)

    @property
    def arrow_scale(self) -> float:
        """The fixed arrow scale [m/N]; automatic: the latest frame's (NaN before any arrow)."""
        if self.fixed_arrow_scale is not None:
            return self.fixed_arrow_scale
        return self._last_arrow_scale

    @property
    def arrow_scale_text(self) -> str:
        """The arrow scale in words, for summaries (``"0.25 m/N"`` or the automatic rule)."""
        if self.fixed_arrow_scale is not None:
            return f"{self.fixed_arrow_scale:.4g} m/N"
        return f"automatic, longest arrow {AUTO_ARROW_FRACTION:.0%} of the body's size"

    # ------------------------------------------------------------------ static content
    def _other_geom_meshes(self) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per moving body: (vertices, faces, RGBA) of its non-intruding geoms, body frame."""
        m = self.model
        tagged = set(self.fld.geom_elements)
        parts: dict[int, list] = {}
        for g in range(m.ngeom):
            b = int(m.geom_bodyid[g])
            if b == 0 or g in tagged or m.geom_rgba[g, 3] == 0:
                continue
            mesh = _geom_mesh(m, g)
            if mesh is None:
                continue
            v, f = mesh
            v = v @ _quat_mat(m.geom_quat[g]).T + m.geom_pos[g]
            rgba = np.rint(np.clip(m.geom_rgba[g], 0, 1) * 255).astype(np.uint8)
            parts.setdefault(b, []).append((v, f, np.tile(rgba, (len(v), 1))))
        out = {}
        for b, items in parts.items():
            offs = np.cumsum([0] + [len(v) for v, _, _ in items[:-1]])
            out[b] = (
                np.concatenate([v for v, _, _ in items]),
                np.concatenate([f + o for (_, f, _), o in zip(items, offs, strict=True)]),
                np.concatenate([c for _, _, c in items]),
            )
        return out

    def _eye(self, xpos: np.ndarray | None, xmat: np.ndarray | None) -> rrb.EyeControls3D:
        """Default camera framed on the intruders at the given poses ((nbody, 3), (nbody, 9);
        None: the model's reference pose), looking from ``CAMERA_DIRECTION``."""
        if xpos is None or xmat is None:
            data = mujoco.MjData(self.model)
            if self.model.nkey > 0:  # simulate.run starts from keyframe 0
                mujoco.mj_resetDataKeyframe(self.model, data, 0)
            mujoco.mj_kinematics(self.model, data)
            xpos, xmat = data.xpos, data.xmat
        pts = np.concatenate(
            [
                v @ xmat[b].reshape(3, 3).T + xpos[b]
                for b, v in zip(self._intruders, self._vertices, strict=True)
            ]
        )
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        target = 0.5 * (lo + hi)
        # Bodies that start above the medium are watched where they enter it.
        target[2] = min(target[2], self.fld.surface_z)
        direction = np.asarray(CAMERA_DIRECTION, dtype=np.float64)
        distance = CAMERA_DISTANCE_PER_DIAGONAL * float(np.linalg.norm(hi - lo))
        eye = target + distance * direction / np.linalg.norm(direction)
        return rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital, position=eye, look_target=target, eye_up=(0.0, 0.0, 1.0)
        )

    def _blueprint(
        self, xpos: np.ndarray | None = None, xmat: np.ndarray | None = None
    ) -> rrb.Blueprint:
        """The recording's default layout, the camera framed on the intruders at these poses."""
        scene = rrb.Tabs(
            rrb.Spatial3DView(
                origin="world",
                name="bodies, medium, RFT forces",
                eye_controls=self._eye(xpos, xmat),
            ),
            rrb.TextDocumentView(origin="info", name="legend"),
            active_tab=0,
        )
        per_body = []
        for be in self.fld.bodies:
            name = self._names[be.body]
            per_body.append(
                rrb.Vertical(
                    rrb.TimeSeriesView(
                        origin=f"rft/{name}/force", name=f"{be.name}: RFT force [N]"
                    ),
                    rrb.TimeSeriesView(
                        origin=f"rft/{name}/torque",
                        name=f"{be.name}: RFT torque about the CoM [N m]",
                    ),
                    name=be.name,
                )
            )
        plots = [per_body[0] if len(per_body) == 1 else rrb.Tabs(*per_body)]
        if self.model.nsensor:
            plots.append(
                rrb.TimeSeriesView(
                    origin="sensors",
                    name="MJCF sensors",
                    plot_legend=rrb.PlotLegend(visible=False),  # one entry per sensor: too many
                )
            )
        return rrb.Blueprint(
            rrb.Horizontal(
                scene,
                rrb.Vertical(*plots, row_shares=[2, 1][: len(plots)]),
                column_shares=[3, 2],
            ),
            rrb.BlueprintPanel(state="collapsed"),
            rrb.SelectionPanel(state="collapsed"),
            rrb.TimePanel(timeline="sim_time", state="collapsed"),
        )

    def _send_blueprint(self, xpos: np.ndarray | None, xmat: np.ndarray | None) -> None:
        rr.send_blueprint(
            self._blueprint(xpos, xmat), make_active=True, make_default=True, recording=self.rec
        )
        self._blueprint_sent = True

    def _surface_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) xy corners of the drawn surface [m]."""
        if self.fld.region is not None:
            return self.fld.region[0, :2], self.fld.region[1, :2]
        centre = np.asarray(self.model.stat.center[:2], dtype=np.float64)
        half = SURFACE_EXTENT_FACTOR * float(self.model.stat.extent)
        return centre - half, centre + half

    def _surface_mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """Vertices (k, 3) [m, world] and triangles (t, 3) of the drawn free surface: two
        triangles when flat, else a SURFACE_SAMPLES x SURFACE_SAMPLES grid of its heights (the
        deforming ground: its decimated grid, initial heights)."""
        if self._ground_rows is not None:
            x, y = self._ground_xy
        else:
            (x0, y0), (x1, y1) = self._surface_box()
            n = 2 if self.fld.surface.kind == surface.FLAT else SURFACE_SAMPLES
            x, y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
        vertices = np.stack([x, y, self.fld.surface.height(x, y)], axis=-1).reshape(-1, 3)
        nr, nc = x.shape
        r, c = np.meshgrid(np.arange(nr - 1), np.arange(nc - 1), indexing="ij")
        a = (r * nc + c).ravel()
        triangles = np.concatenate([np.stack([a, a + 1, a + nc + 1], 1),
                                    np.stack([a, a + nc + 1, a + nc], 1)])  # fmt: skip
        return vertices, triangles

    def _ground(self, data: mujoco.MjData) -> np.ndarray | None:
        """The deforming ground's drawn vertices (k, 3) [m, world] if this frame shows it."""
        if self._ground_rows is None or self.frames % GROUND_EVERY_FRAMES:
            return None
        h = self.fld.soil(data).height[np.ix_(self._ground_rows, self._ground_cols)]
        return np.stack([*self._ground_xy, h], axis=-1).reshape(-1, 3)

    def _log_static(self) -> None:
        rec, fld = self.rec, self.fld
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        vertices, triangles = self._surface_mesh()
        if self._ground_rows is None:
            rec.log(
                "world/surface",
                rr.Mesh3D(
                    vertex_positions=vertices,
                    triangle_indices=triangles,
                    albedo_factor=SURFACE_RGBA,
                    face_rendering=rr.components.MeshFaceRendering.DoubleSided,
                ),
                static=True,
            )
        else:  # the heights change: only the rest is static (static data hides later frames)
            rec.log(
                "world/surface",
                rr.Mesh3D.from_fields(
                    triangle_indices=triangles,
                    albedo_factor=SURFACE_RGBA,
                    face_rendering=rr.components.MeshFaceRendering.DoubleSided,
                ),
                static=True,
            )
        if fld.region is not None:
            lo, hi = fld.region
            rec.log(
                "world/region",
                rr.Boxes3D(mins=[lo], sizes=[hi - lo], colors=[REGION_RGBA], radii=0.0005),
                static=True,
            )
        for be in fld.bodies:
            es = fld.body_element_set(be.body)
            tri = np.asarray(es.vertices)[np.asarray(es.faces)].reshape(-1, 3)
            normals = np.repeat(np.asarray(es.normals), 3, axis=0)
            # Only what never changes: static vertex colours would hide the per-frame ones.
            rec.log(
                f"world/bodies/{self._names[be.body]}/rft_mesh",
                rr.Mesh3D.from_fields(vertex_positions=tri, vertex_normals=normals),
                static=True,
            )
        for b, (v, f, c) in self._other.items():
            rec.log(
                f"world/bodies/{self._names[b]}/geoms",
                rr.Mesh3D(vertex_positions=v, triangle_indices=f, vertex_colors=c),
                static=True,
            )
        for be in fld.bodies:
            name = self._names[be.body]
            for quantity, unit in (("force", "N"), ("torque", "N m")):
                for axis in "xyz":
                    rec.log(
                        f"rft/{name}/{quantity}/{axis}",
                        rr.SeriesLines(
                            names=f"{be.name} {quantity} {axis} [{unit}]",
                            colors=[AXIS_RGB[axis]],
                        ),
                        static=True,
                    )
        rec.log("info", rr.TextDocument(self.legend(), media_type="text/markdown"), static=True)

    def legend(self) -> str:
        """Markdown legend of the recording: entities, frames, units and this run's scales."""
        if self.fixed_arrow_scale is not None:
            arrows = f"{self.fixed_arrow_scale:.4g} m per N"
        else:
            sizes = ", ".join(
                f"{be.name} {1000 * s:.3g} mm"
                for be, s in zip(self.fld.bodies, self.body_sizes, strict=True)
            )
            arrows = (
                f"automatic scale: the longest arrow of a frame is {AUTO_ARROW_FRACTION:.0%} of "
                f"the body's size ({sizes}); the frame's scale [m/N] is the arrows' "
                "`arrow_scale` component"
            )
        return (
            "# mjrft recording\n\n"
            f"* `world/bodies/<body>`: body pose (world frame). `.../rft_mesh`: RFT triangles, "
            f"coloured by stress |F|/dA, viridis 0 ... {self.stress_max:g} Pa (clipped above; "
            "grey = no force). `.../geoms`: other geoms (coarse).\n"
            "* `world/forces/<body>`: per-triangle RFT force arrows, world frame, tip at the "
            f"triangle's centroid, {arrows}; at most {self.max_arrows} per body (even stride "
            "over acting triangles); component `element_index` = triangle index.\n"
            "* `rft/<body>/force|torque/x|y|z`: RFT force [N] and torque about the CoM [N m], "
            "world frame.\n"
            "* `sensors/<name>[/i]`: MJCF sensors (MuJoCo units and frames).\n"
            "* `world/surface`: free surface (translucent; sampled if not flat); `world/region`: "
            "the medium's box (if any).\n\n"
            f"A frame every {self.every} steps; timelines `step` and `sim_time`. Each frame shows "
            "the state a step integrated from and the forces computed there."
        )

    # ------------------------------------------------------------------ frames
    def log_state(self, step: int, time: float, data: mujoco.MjData) -> None:
        """Log one frame from data's derived quantities (xpos, xmat, cvel, sensordata).

        Args:
          step: value on the ``step`` timeline. time: value on ``sim_time`` [s] (the time of
            the state the derived quantities describe; after an Euler step, the pre-step time).
          data: MjData whose derived quantities are consistent (after ``mj_forward``, or after
            an Euler/implicit ``mj_step``).

        The frame is built whole and then buffered in one step; the buffer is sent every
        ``FLUSH_FRAMES`` frames and on :meth:`close` (poses and scalars as one column per
        entity: logging stays well below the cost of the steps). So a frame interrupted at any
        point (Ctrl-C) is left out entirely, and every frame logged before it is kept. Mesh
        colours and arrows of a body are logged at the first frame, while it feels a force, and
        once more (grey, no arrows) when it stops.
        """
        if self._closed:
            raise RuntimeError("this Recorder is closed")
        fld = self.fld
        xpos, xmat = data.xpos[self._drawn].copy(), data.xmat[self._drawn].copy()
        states = {st.body: st for st in fld.element_states(data)}
        scalars, looks, shown = [], [], list(self._shown)
        for k, be in enumerate(fld.bodies):
            b = be.body
            st = states.get(b)
            force, torque = np.zeros(3), np.zeros(3)
            active = False
            if st is not None:
                mag = np.sqrt(np.einsum("ij,ij->i", st.force, st.force))
                acting = np.flatnonzero(mag > 0.0)
                active = len(acting) > 0
                force = st.force.sum(axis=0)
                r, f = st.pos - data.xipos[b], st.force
                torque = np.array(
                    [
                        np.dot(r[:, 1], f[:, 2]) - np.dot(r[:, 2], f[:, 1]),
                        np.dot(r[:, 2], f[:, 0]) - np.dot(r[:, 0], f[:, 2]),
                        np.dot(r[:, 0], f[:, 1]) - np.dot(r[:, 1], f[:, 0]),
                    ]
                )  # sum of r x f about the CoM
            scalars += [force, torque]
            if shown[k] is False and not active:
                continue  # unchanged since the last logged frame: grey, no arrows
            shown[k] = active
            stress = np.zeros(len(be.areas))
            index = np.zeros(0, dtype=np.int64)
            origins = vectors = np.zeros((0, 3))
            scale = None
            if active:
                stress[st.index] = mag / st.area
                if len(acting) > self.max_arrows:  # an even stride through the acting triangles
                    pick = np.linspace(0, len(acting) - 1, self.max_arrows)
                    acting = acting[np.rint(pick).astype(np.int64)]
                if len(acting):
                    scale = self.fixed_arrow_scale
                    if scale is None:
                        scale = AUTO_ARROW_FRACTION * self.body_sizes[k] / mag[acting].max()
                    index = st.index[acting]
                    vectors = st.force[acting] * scale
                    origins = st.pos[acting] - vectors  # tip on the triangle, shaft in the medium
            colors = np.repeat(stress_colors(stress, self.stress_max), 3)
            looks.append((k, colors, index, origins, vectors, scale))
        scalars.append(np.asarray(data.sensordata, dtype=np.float64))
        frame = _Frame(int(step), float(time), xpos, xmat, np.concatenate(scalars), tuple(looks),
                       self._ground(data))  # fmt: skip
        if not self._blueprint_sent:
            self._send_blueprint(data.xpos, data.xmat)
        self._buffer.append(frame)  # the frame is complete: from here on it is in the file
        self._shown = shown
        for look in looks:
            if look[5] is not None:
                self._last_arrow_scale = float(look[5])
        if len(self._buffer) >= FLUSH_FRAMES:
            self._send_buffered()

    def _send_buffered(self) -> None:
        """Send the buffered frames (Ctrl-C held until done): poses and scalars as one column
        chunk per entity, then each frame's mesh colours and arrows."""
        with HeldSignals():
            frames = self._buffer
            if not frames:
                return
            rec = self.rec
            indexes = [
                rr.TimeColumn("step", sequence=[f.step for f in frames]),
                rr.TimeColumn("sim_time", duration=[f.time for f in frames]),
            ]
            xpos = np.stack([f.xpos for f in frames])  # (frames, drawn, 3)
            xmat = np.stack([f.xmat for f in frames])  # (frames, drawn, 9)
            values = np.stack([f.scalars for f in frames])  # (frames, scalar paths)
            for j, b in enumerate(self._drawn):
                rec.send_columns(
                    f"world/bodies/{self._names[b]}",
                    indexes=indexes,
                    columns=rr.Transform3D.columns(
                        translation=xpos[:, j], mat3x3=xmat[:, j].reshape(-1, 3, 3)
                    ),
                )
            for k, path in enumerate(self._scalar_paths):
                rec.send_columns(
                    path, indexes=indexes, columns=rr.Scalars.columns(scalars=values[:, k])
                )
            for f in frames:
                if not f.looks and f.ground is None:
                    continue
                rec.set_time("step", sequence=f.step)
                rec.set_time("sim_time", duration=f.time)
                if f.ground is not None:
                    rec.log("world/surface", rr.Mesh3D.from_fields(vertex_positions=f.ground))
                for k, colors, index, origins, vectors, scale in f.looks:
                    name = self._names[self._intruders[k]]
                    rec.log(
                        f"world/bodies/{name}/rft_mesh",
                        rr.Mesh3D.from_fields(vertex_colors=colors),
                    )
                    rec.log(
                        f"world/forces/{name}",
                        rr.Arrows3D(
                            origins=origins,
                            vectors=vectors,
                            colors=colors[3 * index],
                            radii=self.arrow_radii[k],
                        ),
                        rr.AnyValues(
                            element_index=pa.array(index, type=pa.uint32()),
                            arrow_scale=pa.array(
                                [] if scale is None else [scale], type=pa.float64()
                            ),
                        ),
                    )
            self._sent += len(frames)
            self._buffer = []

    def __call__(self, step: int, time: float, data: mujoco.MjData) -> None:
        """Observer for ``simulate.run``: same as :meth:`log_state`."""
        self.log_state(step, time, data)

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Send what is buffered, flush, finalise the file (idempotent; call in a ``finally``).

        Safe after an exception or a KeyboardInterrupt anywhere in :meth:`log_state`: the file
        then holds exactly the frames whose logging completed. A viewer that cannot be reached
        (``connect``) only warns: the file is still completed.
        """
        if self._closed:
            return
        self._closed = True
        try:
            if not self._blueprint_sent:
                self._send_blueprint(None, None)
            self._send_buffered()
            self.rec.flush()
        except RuntimeError as exc:  # rerun reports unreachable gRPC sinks this way
            warnings.warn(f"rerun: {exc}", RuntimeWarning, stacklevel=2)
        finally:
            self.rec.disconnect()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def record(
    model: mujoco.MjModel,
    duration: float,
    path: str | os.PathLike | None,
    *,
    fld: GranularField | None = None,
    record_every: int = 1,
    progress: Callable[[float], None] | None = None,
    recording: simulate.Recording | None = None,
    **recorder_options: object,
) -> tuple[mujoco.MjData, simulate.Recording]:
    """``simulate.run`` with a :class:`Recorder` logging every ``every`` steps to ``path``.

    The recorder is closed (file complete) however the run ends. Keyword arguments of
    :class:`Recorder` (``every``, ``max_arrows``, ``arrow_scale``, ``stress_max``, ``spawn``,
    ``connect``, ...) pass through; the rest are those of ``simulate.run``.
    """
    fld = fld or GranularField(model)
    with Recorder(model, fld, path, **recorder_options) as rec:
        return simulate.run(
            model,
            duration,
            fld=fld,
            record_every=record_every,
            progress=progress,
            recording=recording,
            observer=rec,
            observe_every=rec.every,
        )


def read_entity(path: str | os.PathLike, entity: str) -> list[dict[str, object]]:
    """Every row logged to one entity of an ``.rrd`` file, read back with rerun's own reader.

    Returns dicts of column -> Python value, sorted by ``step`` where the rows have one: the
    timelines ``step`` (int) and ``sim_time`` (float seconds) and the components under their
    rerun names (``Arrows3D:vectors``: list of [x, y, z]; ``Scalars:scalars``: [value]; ...).
    Static rows have no timeline. These are the rows as logged; what the viewer shows at a time
    is, per component, the static value if there is one, else the latest row at or before it.
    Built on ``rerun.chunk.RrdReader`` (chunks as pyarrow record batches); ``rerun rrd print``,
    ``rerun rrd stats`` and ``rerun rrd verify`` inspect a file from the shell. A file cut short
    (a full disk, a killed run) is read up to its last complete message
    (``mjrft.app.rrd_file.salvage``).
    """
    if not rrd_file.scan(path).finished:
        with tempfile.TemporaryDirectory() as tmp:
            copy = Path(tmp) / "salvaged.rrd"
            rrd_file.salvage(path, copy)
            return _read_rows(copy, entity)
    return _read_rows(Path(path), entity)


def _read_rows(path: Path, entity: str) -> list[dict[str, object]]:
    from rerun.chunk import RrdReader

    want = entity if entity.startswith("/") else "/" + entity
    rows: list[dict[str, object]] = []
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="RRD file has no footer")  # a salvaged copy
        reader = RrdReader(str(path))
    for chunk in reader.stream():
        if chunk.entity_path != want:
            continue
        batch = chunk.to_record_batch()
        cols = {}
        for name in batch.schema.names:
            if name.startswith("rerun.controls."):
                continue
            arr = batch.column(name)
            if pa.types.is_duration(arr.type):
                cols[name] = [v * 1e-9 for v in arr.cast(pa.int64()).to_pylist()]  # ns -> s
            else:
                cols[name] = arr.to_pylist()
        rows += [{k: v[i] for k, v in cols.items()} for i in range(batch.num_rows)]
    return sorted(rows, key=lambda r: r.get("step", -1))
