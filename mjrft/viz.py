"""Headless rerun recordings of a granular-field run: bodies, medium, per-element RFT forces.

A leaf module (only the CLI imports it; importing ``mjrft`` never imports rerun). A
:class:`Recorder` owns its own ``rerun.RecordingStream`` (never rerun's global one), writes to an
``.rrd`` file, and opens no port and spawns no viewer unless asked (``spawn=True`` /
``connect=URL``). Use it as a context manager or call :meth:`Recorder.close` in a ``finally``:
closing flushes and finalises the file, so a run that raises or is interrupted (Ctrl-C) still
leaves a complete, readable recording of every frame logged before.

What one frame holds (entity paths; ``<body>`` is the MuJoCo body name, escaped for rerun):

* ``world/bodies/<body>`` - Transform3D: the body frame's pose (``xpos``, ``xmat``) in the world.
* ``world/bodies/<body>/rft_mesh`` - intruding bodies: the RFT surface triangles as a Mesh3D in
  the body frame (static, each triangle with its own three vertices), and per frame the vertex
  colours: each triangle coloured by its RFT stress |F| / dA on the fixed scale 0 ...
  ``stress_max`` [Pa] (viridis; above the scale clipped to yellow), grey where no force acts.
* ``world/bodies/<body>/geoms`` - the body's other geoms as coarse static meshes (body frame).
* ``world/forces/<body>`` - Arrows3D in the world frame: origin = triangle centroid [m], vector =
  RFT force on the triangle [N] times ``arrow_scale`` [m/N]; at most ``max_arrows`` per body (an
  even stride through the acting triangles), coloured like the mesh. Component
  ``element_index`` gives each arrow's triangle index in ``field.bodies[i]`` order.
* ``rft/<body>/force/{x,y,z}`` [N] and ``rft/<body>/torque/{x,y,z}`` [N m]: Scalars, the body's
  RFT force and torque about its CoM (world frame), the sums over all its triangles.
* ``sensors/<name>`` (1-D sensors) or ``sensors/<name>/<i>``: every MJCF sensor, as in the CSV.

Static: ``world`` (z up), ``world/surface`` (the free surface z = ``surface_z``, over the medium's
region or around the bodies), ``world/region`` (the medium's box, if the MJCF sets one) and
``info`` (this legend with the run's scales). Timelines: ``step`` (sequence: number of steps taken
before the logged state) and ``sim_time`` (duration: MuJoCo time of the logged state).

Which state a frame shows: the state the step integrated from (for Euler and the implicit
integrators, the derived quantities MuJoCo leaves after ``mj_step`` describe the pre-step state:
the pose, ``cvel`` and sensors that produced the RFT force of that step). ``simulate.run`` calls
the recorder there, with that state's time; for RK4 it runs ``mj_forward`` first. Per-element
forces come from ``GranularField.element_states`` at exactly that state.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from pathlib import Path

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from mjrft import geometry, simulate
from mjrft.field import GranularField

#: Default: log one frame every this many steps (100 frames per simulated second at dt = 1 ms).
DEFAULT_EVERY = 10
#: Default maximum number of force arrows per body and frame.
DEFAULT_MAX_ARROWS = 400
#: Default top of the stress colour scale [Pa] (20 kPa = 2 N/cm^2; 0.33 N/cm^3 glass beads reach
#: it about 6 cm deep for a triangle facing straight down).
DEFAULT_STRESS_MAX_PA = 2.0e4
#: With the automatic arrow scale, a triangle of median area at ``stress_max`` gets this length [m].
AUTO_ARROW_LENGTH_M = 0.01
#: Arrow shaft radius as a fraction of the median triangle's edge length sqrt(dA).
ARROW_RADIUS_PER_EDGE = 0.12
#: Target triangle count of each non-intruding primitive geom drawn (coarse: shape only).
OTHER_GEOM_TRIANGLES = 200
#: Colour of triangles on which no RFT force acts (RGB, 0-255).
NO_FORCE_RGB = (170, 170, 170)
#: Colour of the free surface (RGBA; translucent sand) and of the region box.
SURFACE_RGBA = (222, 194, 140, 110)
REGION_RGBA = (150, 120, 70, 255)
#: Half size of the drawn surface when the MJCF sets no region: model extent times this [-].
SURFACE_EXTENT_FACTOR = 0.5
#: gRPC address used by ``connect`` when none is given (rerun's default viewer port).
DEFAULT_CONNECT_URL = "rerun+http://127.0.0.1:9876/proxy"

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


def stress_colors(stress: np.ndarray, stress_max: float) -> np.ndarray:
    """(n, 4) uint8 RGBA colour of each triangle from its stress |F|/dA [Pa].

    Viridis over 0 ... ``stress_max`` [Pa], clipped above; exactly zero stress (no force acts)
    is grey ``NO_FORCE_RGB``. Fully opaque.
    """
    s = np.asarray(stress, dtype=np.float64)
    u = np.clip(s / stress_max, 0.0, 1.0) * (len(_VIRIDIS) - 1)
    lo = np.minimum(np.floor(u).astype(np.int64), len(_VIRIDIS) - 2)
    frac = (u - lo)[:, None]
    rgb = _VIRIDIS[lo] * (1.0 - frac) + _VIRIDIS[lo + 1] * frac
    rgb[s == 0.0] = NO_FORCE_RGB
    out = np.full((len(s), 4), 255, dtype=np.uint8)
    out[:, :3] = np.rint(rgb).astype(np.uint8)
    return out


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
    t = model.geom_type[g]
    kinds = {
        mujoco.mjtGeom.mjGEOM_SPHERE: "sphere",
        mujoco.mjtGeom.mjGEOM_ELLIPSOID: "ellipsoid",
        mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
        mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
        mujoco.mjtGeom.mjGEOM_BOX: "box",
    }
    if t == mujoco.mjtGeom.mjGEOM_MESH:
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


class Recorder:
    """Logs frames of a MuJoCo run with a GranularField to a rerun recording (headless).

    Args:
      model: the compiled model; fld: its field (the per-element forces come from it).
      path: ``.rrd`` file to write (parent folders created); None to only stream (needs
        ``spawn`` or ``connect``).
      every: log a frame every this many steps (used by :func:`record` / ``simulate.run``).
      max_arrows: maximum force arrows per body and frame (0: no arrows).
      arrow_scale: arrow length per newton [m/N]; None: automatic, so that a triangle of the
        body's median area at ``stress_max`` gets ``AUTO_ARROW_LENGTH_M`` (1 cm).
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
        every: int = DEFAULT_EVERY,
        max_arrows: int = DEFAULT_MAX_ARROWS,
        arrow_scale: float | None = None,
        stress_max: float = DEFAULT_STRESS_MAX_PA,
        spawn: bool = False,
        connect: str | None = None,
        other_geoms: bool = True,
        application_id: str = "mjrft",
        recording_id: str | None = None,
    ) -> None:
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
        self.frames = 0
        median_area = float(np.median(np.concatenate([be.areas for be in fld.bodies])))
        self.arrow_scale = (
            AUTO_ARROW_LENGTH_M / (stress_max * median_area) if arrow_scale is None else arrow_scale
        )
        self.arrow_radius = ARROW_RADIUS_PER_EDGE * math.sqrt(median_area)
        self._names = {b: _part(_body_name(model, b)) for b in range(1, model.nbody)}
        self._other = self._other_geom_meshes() if other_geoms else {}
        self._intruders = [be.body for be in fld.bodies]
        self._drawn = sorted(set(self._intruders) | set(self._other))
        self._sensor_paths = sensor_entities(model)
        self._closed = False

        self.rec = rr.RecordingStream(application_id, recording_id=recording_id)
        self.rec.set_log_time_enabled(False)  # only the simulation's timelines
        sinks = []
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(self.path)))
        if spawn:
            self.rec.spawn(connect=False)
            sinks.append(rr.GrpcSink(DEFAULT_CONNECT_URL))
        if connect:
            if not spawn or connect != DEFAULT_CONNECT_URL:
                sinks.append(rr.GrpcSink(connect))
        self.rec.set_sinks(*sinks, default_blueprint=self._blueprint())
        try:
            self._log_static()
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ static content
    def _other_geom_meshes(self) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per moving body: (vertices, faces, vertex RGBA) of its non-intruding geoms, body frame."""
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

    def _blueprint(self) -> rrb.Blueprint:
        return rrb.Blueprint(
            rrb.Horizontal(
                rrb.Spatial3DView(origin="world", name="bodies, medium, RFT forces"),
                rrb.Vertical(
                    rrb.TimeSeriesView(origin="rft", name="RFT force [N], torque [N m]"),
                    rrb.TimeSeriesView(origin="sensors", name="MJCF sensors"),
                ),
                column_shares=[3, 2],
            ),
            rrb.TimePanel(timeline="sim_time"),
            collapse_panels=False,
        )

    def _surface_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) xy corners of the drawn surface [m]."""
        if self.fld.region is not None:
            return self.fld.region[0, :2], self.fld.region[1, :2]
        centre = np.asarray(self.model.stat.center[:2], dtype=np.float64)
        half = SURFACE_EXTENT_FACTOR * float(self.model.stat.extent)
        return centre - half, centre + half

    def _log_static(self) -> None:
        rec, fld = self.rec, self.fld
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        (x0, y0), (x1, y1) = self._surface_box()
        z = fld.surface_z
        corners = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])
        rec.log(
            "world/surface",
            rr.Mesh3D(
                vertex_positions=corners,
                triangle_indices=[[0, 1, 2], [0, 2, 3]],
                albedo_factor=SURFACE_RGBA,
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
            colors = stress_colors(np.zeros(len(es)), self.stress_max)
            rec.log(
                f"world/bodies/{self._names[be.body]}/rft_mesh",
                rr.Mesh3D(
                    vertex_positions=tri,
                    vertex_normals=normals,
                    vertex_colors=np.repeat(colors, 3, axis=0),
                ),
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
                        rr.SeriesLines(names=f"{be.name} RFT {quantity} {axis} [{unit}]"),
                        static=True,
                    )
        rec.log("info", rr.TextDocument(self.legend(), media_type="text/markdown"), static=True)

    def legend(self) -> str:
        """Markdown legend of the recording: entities, frames, units and this run's scales."""
        return (
            "# mjrft recording\n\n"
            f"* `world/bodies/<body>`: body pose (world frame). `.../rft_mesh`: RFT triangles, "
            f"coloured by stress |F|/dA, viridis 0 ... {self.stress_max:g} Pa (clipped above; "
            "grey = no force). `.../geoms`: other geoms (coarse).\n"
            f"* `world/forces/<body>`: per-triangle RFT force arrows, world frame, "
            f"{self.arrow_scale:.4g} m per N, at most {self.max_arrows} per body (even stride "
            "over acting triangles); component `element_index` = triangle index.\n"
            "* `rft/<body>/force|torque/x|y|z`: RFT force [N] and torque about the CoM [N m], "
            "world frame.\n"
            "* `sensors/<name>[/i]`: MJCF sensors (MuJoCo units and frames).\n"
            "* `world/surface`: free surface; `world/region`: the medium's box (if any).\n\n"
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
        """
        if self._closed:
            raise RuntimeError("this Recorder is closed")
        rec, fld = self.rec, self.fld
        rec.set_time("step", sequence=int(step))
        rec.set_time("sim_time", duration=float(time))
        for b in self._drawn:
            rec.log(
                f"world/bodies/{self._names[b]}",
                rr.Transform3D(translation=data.xpos[b], mat3x3=data.xmat[b].reshape(3, 3)),
            )
        states = {st.body: st for st in fld.element_states(data)}
        for be in fld.bodies:
            b, name = be.body, self._names[be.body]
            st = states.get(b)
            n = len(be.areas)
            stress = np.zeros(n)
            force, torque = np.zeros(3), np.zeros(3)
            sel = np.zeros(0, dtype=np.int64)
            if st is not None:
                mag = np.linalg.norm(st.force, axis=1)
                stress[st.index] = mag / st.area
                force = st.force.sum(axis=0)
                torque = np.cross(st.pos - data.xipos[b], st.force).sum(axis=0)
                acting = np.flatnonzero(mag > 0.0)
                if len(acting) > self.max_arrows:
                    pick = np.linspace(0, len(acting) - 1, self.max_arrows)
                    acting = acting[np.rint(pick).astype(np.int64)] if self.max_arrows else acting[:0]
                sel = acting
            colors = stress_colors(stress, self.stress_max)
            rec.log(
                f"world/bodies/{name}/rft_mesh",
                rr.Mesh3D.from_fields(vertex_colors=np.repeat(colors, 3, axis=0)),
            )
            if st is None:
                origins = vectors = np.zeros((0, 3))
                arrow_colors = np.zeros((0, 4), dtype=np.uint8)
                index = np.zeros(0, dtype=np.int64)
            else:
                origins, vectors = st.pos[sel], st.force[sel] * self.arrow_scale
                index = st.index[sel]
                arrow_colors = colors[index]
            rec.log(
                f"world/forces/{name}",
                rr.Arrows3D(
                    origins=origins, vectors=vectors, colors=arrow_colors, radii=self.arrow_radius
                ),
                rr.AnyValues(element_index=index.astype(np.uint32)),
            )
            for quantity, vec in (("force", force), ("torque", torque)):
                for axis, value in zip("xyz", vec, strict=True):
                    rec.log(f"rft/{name}/{quantity}/{axis}", rr.Scalars(float(value)))
        for path, value in zip(self._sensor_paths, data.sensordata, strict=True):
            rec.log(path, rr.Scalars(float(value)))
        self.frames += 1

    def __call__(self, step: int, time: float, data: mujoco.MjData) -> None:
        """Observer for ``simulate.run``: same as :meth:`log_state`."""
        self.log_state(step, time, data)

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Flush everything and finalise the file (idempotent; call in a ``finally``)."""
        if self._closed:
            return
        self._closed = True
        try:
            self.rec.flush()
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


def iter_rows(path: str | os.PathLike, entity: str) -> Iterator[dict[str, object]]:
    """Rows logged to one entity of an ``.rrd`` file, read with rerun's own reader.

    Yields dicts of column name -> Python value (timelines ``step``, ``sim_time`` and components
    such as ``Arrows3D:vectors``), in file order. For quick checks and tests; for analysis use
    ``rerun.dataframe``.
    """
    from rerun.chunk import RrdReader

    want = entity if entity.startswith("/") else "/" + entity
    for chunk in RrdReader(str(path)).stream():
        if chunk.entity_path != want:
            continue
        yield from chunk.to_record_batch().to_pylist()
