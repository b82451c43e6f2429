"""Rerun recordings (mjrft.viz, `mjrft run --rrd`, `mjrft demo`), `mjrft view-recording`, and the
paper-style plots.

Recordings are read back with rerun's own reader (rerun.chunk.RrdReader, via viz.read_entity) and
compared with an independent re-simulation evaluated at exactly the logged states. What the viewer
shows is checked the way rerun resolves it (a static value of a component hides its temporal
ones; otherwise the latest row at or before the time), interrupts with real SIGINTs at several
points of a frame, and the web viewer is served and stopped for real on free loopback ports.
"""

import copy
import csv
import os
import queue
import signal
import subprocess
import sys
import threading
import urllib.request
from pathlib import Path

import mujoco
import numpy as np
import pytest

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

from mjrft import SceneOptions, simulate, viz  # noqa: E402
from mjrft.app import cli, report, view  # noqa: E402
from mjrft.core.material import Material  # noqa: E402
from mjrft.field import GranularField  # noqa: E402

MODELS = Path(__file__).resolve().parents[1] / "models"
TRIANGLES = 600  # coarse: these tests are about the recording, not resolution
EVERY = 25
MAX_ARROWS = 40
N_STEPS = 300


def rows(path, entity):
    return viz.read_entity(path, entity)


def temporal(path, entity):
    return [r for r in rows(path, entity) if "step" in r]


def steps_of(path, entity):
    return [r["step"] for r in temporal(path, entity)]


def entity_paths(path):
    return {c.entity_path for c in RrdReader(str(path)).stream()}


def timelines(path):
    names = set()
    for c in RrdReader(str(path)).stream():
        names |= set(c.timeline_names)
    return names


def resimulate(model, steps, integrator_rk4):
    """Independent run of `model` (same start, same stepping as simulate.run with record_every=1)
    returning, for each step in `steps`, the field's view of the state after that many steps."""
    fld = GranularField(model)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    wanted, out = set(steps), {}
    last = max(steps)
    for i in range(last + 1):
        if integrator_rk4:
            mujoco.mj_forward(model, data)  # simulate.run records every step: a forward each
        if i in wanted:
            probe = copy.copy(data)
            mujoco.mj_forward(model, probe)
            out[i] = {
                "time": probe.time,
                "xpos": probe.xpos.copy(),
                "xmat": probe.xmat.copy(),
                "xipos": probe.xipos.copy(),
                "sensordata": probe.sensordata.copy(),
                "wrench": fld.wrench(probe).copy(),
                "states": {st.body: st for st in fld.element_states(probe)},
            }
        if i < last:
            mujoco.mj_step(model, data)
    return fld, out


@pytest.fixture(scope="module", params=["euler", "rk4"])
def root_recording(request, tmp_path_factory):
    """0.3 s of the root rig (in the medium from the start, 2976-triangle mesh) recorded every
    25 steps with at most 40 arrows per frame."""
    model = simulate.load_model(MODELS / "root_circumnutation.xml", n_triangles=TRIANGLES)
    simulate.configure(model, None, request.param)
    fld = GranularField(model)
    path = tmp_path_factory.mktemp("rrd") / f"root_{request.param}.rrd"
    with viz.Recorder(model, fld, path, every=EVERY, max_arrows=MAX_ARROWS) as recorder:
        simulate.run(
            model,
            N_STEPS * model.opt.timestep,
            fld=fld,
            observer=recorder,
            observe_every=recorder.every,
        )
    steps = list(range(0, N_STEPS, EVERY)) + [N_STEPS]
    _, truth = resimulate(model, steps, request.param == "rk4")
    return {
        "model": model,
        "fld": fld,
        "path": path,
        "rec": recorder,
        "steps": steps,
        "truth": truth,
    }


# ------------------------------------------------------------------ layout
def test_recording_has_the_documented_entities_and_timelines(root_recording):
    r = root_recording
    path, model = r["path"], r["model"]
    paths = entity_paths(path)
    body = "root"
    expected = {
        "/world",
        "/world/surface",
        "/info",
        f"/world/bodies/{body}",
        f"/world/bodies/{body}/rft_mesh",
        f"/world/forces/{body}",
        *(f"/rft/{body}/{q}/{a}" for q in ("force", "torque") for a in "xyz"),
        *("/" + p for p in viz.sensor_entities(model)),
        # the drive is drawn too (non-intruding geoms, coarse meshes)
        "/world/bodies/carriage/geoms",
        "/world/bodies/yaw_frame/geoms",
    }
    assert expected <= paths, sorted(expected - paths)
    assert "/world/region" not in paths  # root_circumnutation.xml sets no region
    assert len(viz.sensor_entities(model)) == model.nsensordata
    assert timelines(path) == {"step", "sim_time"}  # no wall-clock log_time
    reader = RrdReader(str(path))
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1
    (legend,) = rows(path, "info")
    text = legend["TextDocument:text"][0]
    assert f"longest arrow of a frame is {viz.AUTO_ARROW_FRACTION:.0%} of the body's size" in text
    assert f"root {1000 * r['rec'].body_sizes[0]:.3g} mm" in text
    assert "automatic" in r["rec"].arrow_scale_text and r["rec"].arrow_scale > 0


def test_every_frame_has_poses_and_scalars_at_the_logged_steps(root_recording):
    r = root_recording
    path, steps, dt = r["path"], r["steps"], r["model"].opt.timestep
    assert r["rec"].frames == len(steps) == 13
    for entity in (
        "world/bodies/root",
        "world/bodies/yaw_frame",
        "rft/root/force/z",
        "rft/root/torque/y",
        "sensors/yaw",
        "sensors/load_cell_force/2",
    ):
        got = temporal(path, entity)
        assert [g["step"] for g in got] == steps, entity
        np.testing.assert_allclose([g["sim_time"] for g in got], np.array(steps) * dt, atol=1e-9)
    # static parts are logged once
    assert len(rows(path, "world/surface")) == 1
    assert len([x for x in rows(path, "world/bodies/root/rft_mesh") if "step" not in x]) == 1


def test_poses_sensors_and_body_forces_equal_the_state_after_that_many_steps(root_recording):
    r = root_recording
    path, truth, model = r["path"], r["truth"], r["model"]
    b = model.body("root").id
    yaw = model.body("yaw_frame").id
    for body, entity in ((b, "world/bodies/root"), (yaw, "world/bodies/yaw_frame")):
        for row in temporal(path, entity):
            t = truth[row["step"]]
            (trans,) = row["Transform3D:translation"]
            (mat,) = row["Transform3D:mat3x3"]  # rerun stores 3x3 matrices column-major
            np.testing.assert_allclose(trans, t["xpos"][body], atol=1e-7)
            np.testing.assert_allclose(
                np.reshape(mat, (3, 3)).T, t["xmat"][body].reshape(3, 3), atol=1e-6
            )
    scale = {
        q: max(1e-9, max(np.abs(t["wrench"][b, s]).max() for t in truth.values()))
        for q, s in (("force", slice(0, 3)), ("torque", slice(3, 6)))
    }
    assert scale["force"] > 0.2  # the root is really in the medium
    for q, offset in (("force", 0), ("torque", 3)):
        for k, a in enumerate("xyz"):
            got = temporal(path, f"rft/root/{q}/{a}")
            want = [truth[g["step"]]["wrench"][b, offset + k] for g in got]
            np.testing.assert_allclose(
                [g["Scalars:scalars"][0] for g in got], want, rtol=1e-9, atol=1e-9 * scale[q]
            )
    for k, entity in enumerate(viz.sensor_entities(model)):
        got = temporal(path, entity)
        want = [truth[g["step"]]["sensordata"][k] for g in got]
        np.testing.assert_allclose(
            [g["Scalars:scalars"][0] for g in got], want, rtol=1e-9, atol=1e-12
        )


def test_logged_element_forces_equal_the_fields_forces_at_those_steps(root_recording):
    r = root_recording
    path, truth, fld, rec = r["path"], r["truth"], r["fld"], r["rec"]
    b = r["model"].body("root").id
    arrows = temporal(path, "world/forces/root")
    acting_steps = [
        s for s, t in truth.items() if b in t["states"] and np.any(t["states"][b].force != 0)
    ]
    assert len(acting_steps) >= 5
    assert set(acting_steps) <= {a["step"] for a in arrows}
    n_checked = 0
    for row in arrows:
        st = truth[row["step"]]["states"].get(b)
        idx = np.array(row["element_index"], dtype=np.int64)
        origins = np.array(row["Arrows3D:origins"]).reshape(-1, 3)
        vectors = np.array(row["Arrows3D:vectors"]).reshape(-1, 3)
        if st is None or not np.any(st.force != 0):
            assert len(idx) == 0  # the frame that clears the arrows
            continue
        mag = np.linalg.norm(st.force, axis=1)
        acting = st.index[mag > 0]
        assert len(idx) == min(MAX_ARROWS, len(acting))
        assert set(idx) <= set(acting)
        row_of = {int(e): k for k, e in enumerate(st.index)}
        k = np.array([row_of[int(e)] for e in idx])
        fmax = np.abs(st.force).max()
        (scale,) = row["arrow_scale"]  # this frame's automatic scale [m/N]
        np.testing.assert_allclose(vectors / scale, st.force[k], atol=2e-6 * fmax)
        # the longest arrow of the frame is the stated fraction of the body's size
        longest = np.linalg.norm(vectors, axis=1).max()
        assert longest == pytest.approx(viz.AUTO_ARROW_FRACTION * rec.body_sizes[0], rel=1e-5)
        # tip on the triangle's centroid, the shaft in the medium
        np.testing.assert_allclose(origins + vectors, st.pos[k], atol=1e-7)
        n_checked += len(idx)
    assert n_checked > 100
    # Stress colours of every triangle, at every logged frame with colours.
    n_tri = len(fld.bodies[0].areas)
    for row in temporal(path, "world/bodies/root/rft_mesh"):
        st = truth[row["step"]]["states"].get(b)
        stress = np.zeros(n_tri)
        if st is not None:
            stress[st.index] = np.linalg.norm(st.force, axis=1) / st.area
        colors = np.array(row["Mesh3D:vertex_colors"], dtype=np.uint32)
        assert colors.shape == (3 * n_tri,)
        np.testing.assert_array_equal(
            colors, np.repeat(viz.stress_colors(stress, rec.stress_max), 3)
        )


def test_static_mesh_at_the_logged_pose_sits_on_the_field_elements(root_recording):
    r = root_recording
    path, truth = r["path"], r["truth"]
    b = r["model"].body("root").id
    (static,) = [x for x in rows(path, "world/bodies/root/rft_mesh") if "step" not in x]
    tri = np.array(static["Mesh3D:vertex_positions"]).reshape(-1, 3, 3)
    centroids = tri.mean(axis=1)  # body frame
    row = temporal(path, "world/bodies/root")[-1]
    rot = np.reshape(row["Transform3D:mat3x3"][0], (3, 3)).T
    world = centroids @ rot.T + np.array(row["Transform3D:translation"][0])
    st = truth[row["step"]]["states"][b]
    # element states sit at their centroids, or within the triangle where it is clipped
    gap = np.linalg.norm(world[st.index] - st.pos, axis=1)
    edge = np.linalg.norm(tri[:, 1] - tri[:, 0], axis=1).max()
    assert np.median(gap) < 1e-6 and gap.max() < edge


# ------------------------------------------------------------------ what the viewer resolves
def chunk_components(path):
    """entity -> (components held by static chunks, components held by temporal chunks)."""
    out: dict[str, tuple[set, set]] = {}
    for c in RrdReader(str(path)).stream():
        batch = c.to_record_batch()
        names = {
            n
            for n in batch.schema.names
            if ":" in n or n in ("element_index", "arrow_scale")
            if batch.column(n).null_count < batch.num_rows
        }
        out.setdefault(c.entity_path, (set(), set()))[0 if c.is_static else 1].update(names)
    return out


def resolved(path, entity, component, step):
    """The value rerun shows for `component` of `entity` at `step` (latest-at on the step
    timeline): the static value if a static chunk holds the component (static data hides every
    temporal value of it), else the latest temporal row at or before `step`; None if neither."""
    static = [r[component] for r in rows(path, entity) if "step" not in r and r.get(component)]
    if static:
        return static[-1]
    before = [r for r in temporal(path, entity) if r["step"] <= step and component in r]
    return before[-1][component] if before else None


@pytest.fixture(scope="module")
def sphere_recording(tmp_path_factory):
    """0.1 s of the sphere drop, a frame every 5 steps: out of the medium for steps 0-15, in it
    from step 20 on."""
    model = simulate.load_model(MODELS / "sphere_drop.xml", n_triangles=TRIANGLES)
    fld = GranularField(model)
    path = tmp_path_factory.mktemp("rrd") / "sphere.rrd"
    viz.record(model, 0.1, path, fld=fld, every=5, max_arrows=MAX_ARROWS)
    fz = {r["step"]: r["Scalars:scalars"][0] for r in temporal(path, "rft/sphere/force/z")}
    return {"model": model, "fld": fld, "path": path, "fz": fz}


def test_changing_components_are_never_static_so_the_viewer_shows_every_frame(
    root_recording, sphere_recording
):
    for path in (root_recording["path"], sphere_recording["path"]):
        components = chunk_components(path)
        for entity, (static, changing) in components.items():
            assert not static & changing, (entity, static & changing)
        for mesh in [e for e in components if e.endswith("/rft_mesh")]:
            static, changing = components[mesh]
            assert static == {"Mesh3D:vertex_positions", "Mesh3D:vertex_normals"}, mesh
            assert changing == {"Mesh3D:vertex_colors"}, mesh
        for arrows in [e for e in components if e.startswith("/world/forces/")]:
            assert not components[arrows][0], arrows  # nothing of the arrows is static
        poses = [e for e in components if "Transform3D:translation" in components[e][1]]
        assert poses and all(not components[e][0] for e in poses)  # poses: temporal only


def test_viewer_resolves_grey_out_of_the_medium_and_stress_colours_in_it(sphere_recording):
    path, fz = sphere_recording["path"], sphere_recording["fz"]
    out_step = max(s for s, f in fz.items() if f == 0.0)
    in_step = max(fz, key=lambda step: abs(fz[step]))
    # out of the medium until its lowest triangles reach it (clipped: before their centroids)
    assert out_step == 10 and fz[in_step] > 0.05
    grey = viz.stress_colors(np.zeros(1), 1.0)[0]
    mesh = "world/bodies/sphere/rft_mesh"
    # the first frame's grey is temporal, logged at that frame
    assert steps_of(path, mesh)[0] == 0 and steps_of(path, "world/forces/sphere")[0] == 0
    before = np.array(resolved(path, mesh, "Mesh3D:vertex_colors", out_step), dtype=np.uint32)
    after = np.array(resolved(path, mesh, "Mesh3D:vertex_colors", in_step), dtype=np.uint32)
    n_vertices = len(resolved(path, mesh, "Mesh3D:vertex_positions", in_step))
    assert len(before) == len(after) == n_vertices
    assert np.all(before == grey)
    assert np.mean(after != grey) > 0.1 and len(np.unique(after)) > 5  # a range of stresses
    assert resolved(path, "world/forces/sphere", "Arrows3D:vectors", out_step) == []
    assert len(resolved(path, "world/forces/sphere", "Arrows3D:vectors", in_step)) > 10
    # poses too are resolved per frame
    z = [resolved(path, "world/bodies/sphere", "Transform3D:translation", s)[0][2] for s in (0, 50)]
    assert z[1] < z[0]


def blueprint_rows(path):
    """entity -> {column: first value} of the recording's blueprint store."""
    reader = RrdReader(str(path))
    (store,) = reader.blueprints()
    out = {}
    for c in reader.stream(store=store):
        batch = c.to_record_batch()
        out[c.entity_path] = {n: batch.column(n)[0].as_py() for n in batch.schema.names if ":" in n}
    return out


def test_default_blueprint_frames_the_intruder_and_has_its_panels(sphere_recording):
    path, fld = sphere_recording["path"], sphere_recording["fld"]
    bp = blueprint_rows(path)
    views = {
        v["ViewBlueprint:space_origin"][0]: (v["ViewBlueprint:class_identifier"][0], e)
        for e, v in bp.items()
        if "ViewBlueprint:space_origin" in v
    }
    assert views["world"][0] == "3D"
    assert views["rft/sphere/force"][0] == views["rft/sphere/torque"][0] == "TimeSeries"
    assert views["sensors"][0] == "TimeSeries" and views["info"][0] == "TextDocument"
    eye = bp[views["world"][1] + "/EyeControls3D"]
    target = np.array(eye["EyeControls3D:look_target"][0])
    position = np.array(eye["EyeControls3D:position"][0])
    start = temporal(path, "world/bodies/sphere")[0]["Transform3D:translation"][0]
    np.testing.assert_allclose(target[:2], start[:2], atol=1e-6)  # on the sphere's start
    assert target[2] == pytest.approx(min(start[2], fld.surface_z), abs=0.02)
    vertices = np.asarray(fld.body_element_set(fld.bodies[0].body).vertices)
    diagonal = np.linalg.norm(np.ptp(vertices, axis=0))  # the sphere's box: turning keeps it
    distance = np.linalg.norm(position - target)
    assert distance == pytest.approx(viz.CAMERA_DISTANCE_PER_DIAGONAL * diagonal, rel=0.05)
    assert position[1] < target[1]  # from the front (-y)


# ------------------------------------------------------------------ robustness
def test_recording_is_complete_when_the_run_raises(tmp_path):
    def failing_progress(fraction):  # called after each 2nd step of 200 (and its frame)
        if fraction >= 0.25:
            raise RuntimeError("synthetic failure mid-run")

    model = simulate.load_model(MODELS / "sphere_drop.xml", n_triangles=TRIANGLES)
    path = tmp_path / "failed.rrd"
    with pytest.raises(RuntimeError, match="synthetic"):
        viz.record(
            model,
            0.2,
            path,
            fld=GranularField(model),
            every=5,
            progress=failing_progress,
        )
    RrdReader(str(path)).store()  # needs the footer: the file was finalised
    steps = steps_of(path, "world/bodies/sphere")
    assert steps == list(range(0, 50, 5))  # every frame before the failure at step 49
    assert steps_of(path, "rft/sphere/force/z") == steps
    assert steps_of(path, "sensors/sphere_pos/2") == steps


def test_cli_recording_is_complete_when_interrupted(tmp_path, monkeypatch):
    class Interrupting:
        def __init__(self, label):
            pass

        def __call__(self, fraction):
            if fraction >= 0.5:
                raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_Progress", Interrupting)
    out = tmp_path / "run"
    code = cli.main(
        ["run", str(MODELS / "sphere_drop.xml"), "--duration", "0.2", "--out", str(out)]
        + ["--rrd", str(out / "run.rrd"), "--rrd-every", "4"]
    )
    assert code == 130
    RrdReader(str(out / "run.rrd")).store()
    steps = steps_of(out / "run.rrd", "world/bodies/sphere")
    assert 20 <= len(steps) <= 30 and steps == list(range(0, 4 * len(steps), 4))
    csv_rows = list(csv.reader(open(out / "timeseries.csv")))
    assert float(csv_rows[-1][0]) == pytest.approx(steps[-1] * 0.001, abs=0.0045)


FRAME_STEPS = list(range(0, 60, 5))  # 12 frames of the sphere drop: in the medium from step 20


@pytest.mark.parametrize(
    ("where", "k"),
    [
        ("element_states", 1),  # in the first frame: nothing logged but the static data
        ("element_states", 8),  # at the start of a frame (the field's per-element forces)
        ("stress_colors", 4),  # in the middle of a frame (its third in the medium)
        ("frame", 5),  # as the frame is assembled, before it is buffered
        ("flush", 20),  # while the buffer is sent (13 sends a flush: the 2nd), held till done
    ],
)
def test_interrupt_anywhere_in_log_state_keeps_exactly_the_completed_frames(
    tmp_path, monkeypatch, where, k
):
    """A real SIGINT (Ctrl-C) raised on the k-th call of a function log_state uses; close() in
    the `finally` then writes exactly the frames whose logging completed, each once."""
    monkeypatch.setattr(viz, "FLUSH_FRAMES", 3)
    model = simulate.load_model(MODELS / "sphere_drop.xml", n_triangles=TRIANGLES)
    fld = GranularField(model)
    path = tmp_path / f"{where}_{k}.rrd"
    recorder = viz.Recorder(model, fld, path, every=5, max_arrows=MAX_ARROWS)
    calls = {"n": 0}

    def hooked(original):
        def call(*args, **kwargs):
            calls["n"] += 1
            if calls["n"] == k:
                signal.raise_signal(signal.SIGINT)  # KeyboardInterrupt at the next bytecode
            return original(*args, **kwargs)

        return call

    if where == "element_states":
        monkeypatch.setattr(fld, "element_states", hooked(fld.element_states))
    elif where == "stress_colors":
        monkeypatch.setattr(viz, "stress_colors", hooked(viz.stress_colors))
    elif where == "frame":
        monkeypatch.setattr(viz, "_Frame", hooked(viz._Frame))
    else:
        monkeypatch.setattr(recorder.rec, "send_columns", hooked(recorder.rec.send_columns))
    handler = signal.getsignal(signal.SIGINT)
    data = mujoco.MjData(model)
    completed = []
    with pytest.raises(KeyboardInterrupt):
        try:
            for step in range(FRAME_STEPS[-1] + 1):
                if step in FRAME_STEPS:
                    mujoco.mj_forward(model, data)
                    recorder.log_state(step, data.time, data)
                    completed.append(step)
                mujoco.mj_step(model, data)
        finally:
            recorder.close()
    assert signal.getsignal(signal.SIGINT) is handler  # the recorder's hold is undone
    # A Ctrl-C held during a flush is raised after it, once the frame is complete.
    assert recorder.frames == len(completed) + (where == "flush")
    kept = FRAME_STEPS[: recorder.frames]
    RrdReader(str(path)).store()  # finalised
    assert len(rows(path, "world/surface")) == 1
    for entity in ["world/bodies/sphere", *recorder._scalar_paths]:
        assert steps_of(path, entity) == kept, entity  # each completed frame once, no other
    looks = steps_of(path, "world/bodies/sphere/rft_mesh")
    assert looks == steps_of(path, "world/forces/sphere")
    assert looks == [s for s in kept if s == 0 or s >= 15]  # the first grey, then in the medium


def test_close_twice_and_log_after_close(tmp_path):
    model = simulate.load_model(MODELS / "sphere_drop.xml", n_triangles=TRIANGLES)
    fld = GranularField(model)
    recorder = viz.Recorder(model, fld, tmp_path / "empty.rrd")
    recorder.close()
    recorder.close()
    with pytest.raises(RuntimeError, match="closed"):
        recorder.log_state(0, 0.0, mujoco.MjData(model))
    RrdReader(str(tmp_path / "empty.rrd")).store()
    assert len(RrdReader(str(tmp_path / "empty.rrd")).blueprints()) == 1  # sent at close


# ------------------------------------------------------------------ CLI options and files
def test_cli_run_writes_the_recording_with_the_requested_decimation_and_scale(tmp_path, capsys):
    out = tmp_path / "run"
    rrd = out / "sphere.rrd"
    code = cli.main(
        ["run", str(MODELS / "sphere_drop.xml"), "--duration", "0.05", "--out", str(out)]
        + ["--rrd", str(rrd), "--rrd-every", "3", "--max-arrows", "100000"]
        + ["--arrow-scale", "0.25", "--stress-max", "5000", "--all-figures"]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert f"recording: {rrd}" in printed and f"mjrft view-recording {rrd}" in printed
    steps = steps_of(rrd, "world/bodies/sphere")
    assert steps == list(range(0, 50, 3)) + [50]
    legend = rows(rrd, "info")[0]["TextDocument:text"][0]
    assert "0.25 m per N" in legend and "5000 Pa" in legend
    # All arrows logged: their sum / arrow scale is the body's RFT force.
    fz = {g["step"]: g["Scalars:scalars"][0] for g in temporal(rrd, "rft/sphere/force/z")}
    arrows = temporal(rrd, "world/forces/sphere")
    checked = 0
    for row in arrows:
        vec = np.array(row["Arrows3D:vectors"]).reshape(-1, 3)
        assert np.sum(vec[:, 2]) / 0.25 == pytest.approx(fz[row["step"]], rel=1e-5, abs=1e-7)
        assert row["arrow_scale"] == ([0.25] if len(vec) else [])
        checked += fz[row["step"]] > 0.05
    assert checked >= 3
    # (0.05 s: the sphere's CoM is still above the surface, so no force-vs-depth figure.)
    for name in ("timeseries.csv", "forces_vs_time.png", report.PAPER_PNG):
        assert (out / name).stat().st_size > 1000, name


def test_cli_recording_options_are_validated(tmp_path, capsys):
    base = ["run", str(MODELS / "sphere_drop.xml"), "--duration", "0.01", "--out", str(tmp_path)]
    for bad in (["--rrd-every", "0"], ["--max-arrows", "-1"], ["--arrow-scale", "-2"]):
        with pytest.raises(SystemExit) as exc:
            cli.main(base + ["--rrd", str(tmp_path / "x.rrd")] + bad)
        assert exc.value.code == 2
    assert "--rrd-every" in capsys.readouterr().err


def test_no_recording_without_rrd(tmp_path):
    out = tmp_path / "run"
    assert (
        cli.main(["run", str(MODELS / "sphere_drop.xml"), "--duration", "0.01", "--out", str(out)])
        == 0
    )
    assert not list(out.glob("*.rrd"))


def test_demo_rig_writes_demo_rrd(tmp_path):
    rrd = tmp_path / cli.DEMO_RRD
    options = SceneOptions(material=Material.preset("glass_beads"), n_triangles=300)
    fld, rec = cli._demo_rig(cli.DEMO_RRD_RIG, 0.05, options, rrd)
    RrdReader(str(rrd)).store()
    assert steps_of(rrd, f"world/bodies/{fld.bodies[0].name}") == [0, 10, 20, 30, 40, 50]
    assert len(rec.rows) == 6
    assert cli.DEMO_RRD_RIG in {name for name, _ in cli.DEMO_RIGS}


# ------------------------------------------------------------------ mjrft view-recording
def _listening_on_loopback_only(port):
    """Whether /proc/net/tcp lists `port` listening, and only on 127.0.0.1 (Linux)."""
    local = []
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        address, state = line.split()[1], line.split()[3]
        ip, hex_port = address.split(":")
        if int(hex_port, 16) == port and state == "0A":  # LISTEN
            local.append(ip)
    return bool(local) and set(local) == {"0100007F"}


def test_view_recording_serves_the_web_viewer_on_loopback_and_frees_its_ports_on_ctrl_c(
    sphere_recording,
):
    try:
        view.rerun_executable()
    except ValueError:
        pytest.skip("rerun's viewer executable is not installed")
    web, grpc = view.free_port(), view.free_port()
    while grpc == web:
        grpc = view.free_port()
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    cmd = [sys.executable, "-m", "mjrft.app.cli", "view-recording", str(sphere_recording["path"])]
    proc = subprocess.Popen(
        [*cmd, "--port", str(web), "--grpc-port", str(grpc)],  # no display: the web viewer
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout], daemon=True).start()
    try:
        printed = []
        while not any("ssh -N" in x for x in printed):
            try:
                printed.append(lines.get(timeout=20))
            except queue.Empty:
                break
        if proc.poll() is not None and not printed:
            err = proc.stderr.read()
            if "web" in err.lower() and "viewer" in err.lower():
                pytest.skip(f"rerun's web viewer is not available: {err[-300:]}")
            pytest.fail(f"view-recording exited {proc.returncode}: {err[-2000:]}")
        text = "".join(printed)
        url = view.viewer_url(web, grpc)
        assert url in text and f"-L {web}:127.0.0.1:{web} -L {grpc}:127.0.0.1:{grpc}" in text
        with urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=10) as page:
            if page.status == 404:
                pytest.skip("rerun's web viewer assets are not available")
            assert page.status == 200 and b"<html" in page.read(4096).lower()
        if Path("/proc/net/tcp").exists():
            assert _listening_on_loopback_only(web) and _listening_on_loopback_only(grpc)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
        assert view.port_is_free(web) and view.port_is_free(grpc)  # the server is gone too
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_view_recording_help_and_errors(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["view-recording", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "--web" in out and "--port" in out and "127.0.0.1" in out
    assert cli.main(["view-recording", str(tmp_path / "missing.rrd"), "--web"]) == 2
    assert "no recording" in capsys.readouterr().err
    assert view.viewer_url(9090, 9876) == (
        "http://127.0.0.1:9090/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A9876%2Fproxy"
    )


# ------------------------------------------------------------------ headless, size, isolation
def test_recorder_is_headless_and_leaves_rerun_global_state_alone(tmp_path, monkeypatch):
    for var in ("DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(var, raising=False)
    before_global = rr.get_global_data_recording()
    children_before = _children()
    model = simulate.load_model(MODELS / "plate_rig.xml", n_triangles=TRIANGLES)
    fld = GranularField(model)
    viz.record(model, 0.02, tmp_path / "plate.rrd", fld=fld, every=5)
    assert rr.get_global_data_recording() is before_global
    assert _children() == children_before  # no viewer process spawned
    paths = entity_paths(tmp_path / "plate.rrd")
    assert {
        "/world/region",
        "/world/bodies/plate/rft_mesh",
        "/world/bodies/gantry_z/geoms",
    } <= paths
    (box,) = rows(tmp_path / "plate.rrd", "world/region")
    np.testing.assert_allclose(box["Boxes3D:half_sizes"][0], (fld.region[1] - fld.region[0]) / 2)


def _children() -> set[str]:
    out = set()
    for task in Path(f"/proc/{os.getpid()}/task").glob("*"):
        try:
            out |= set((task / "children").read_text().split())
        except OSError:
            pass
    return out


def test_recorder_rejects_bad_options(tmp_path):
    model = simulate.load_model(MODELS / "sphere_drop.xml", n_triangles=TRIANGLES)
    fld = GranularField(model)
    for kwargs, match in (
        ({"every": 0}, "every"),
        ({"max_arrows": -1}, "max_arrows"),
        ({"arrow_scale": 0.0}, "arrow_scale"),
        ({"stress_max": float("nan")}, "stress_max"),
    ):
        with pytest.raises(ValueError, match=match):
            viz.Recorder(model, fld, tmp_path / "x.rrd", **kwargs)
    with pytest.raises(ValueError, match="file path"):
        viz.Recorder(model, fld, None)


def test_default_ellipsoid_recording_stays_under_50_mb_for_10_s(tmp_path):
    """One simulated second at the defaults (full 4096 triangles), extrapolated to 10 s."""
    model = simulate.load_model(MODELS / "ellipsoid_pitch.xml")
    path = tmp_path / "one_second.rrd"
    viz.record(model, 1.0, path, record_every=10)
    per_second = path.stat().st_size
    frames = len(steps_of(path, "world/bodies/ellipsoid"))
    assert frames == 101  # 100 per simulated second at dt = 1 ms, plus the final state
    assert 10 * per_second < 40e6, f"{per_second / 1e6:.1f} MB per simulated second"


def test_importing_mjrft_does_not_import_rerun():
    code = (
        "import sys, mjrft, mjrft.field, mjrft.simulate, mjrft.app.report, mjrft.app.cli; "
        "mjrft.app.cli.build_parser(); print('rerun' in sys.modules); "
        "sys.exit(1 if 'rerun' in sys.modules else 0)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_stress_colors_scale():
    smax = 1.0e4
    c = viz.stress_colors(np.array([0.0, 1e-9, 0.5 * smax, smax, 10 * smax]), smax)
    assert c.dtype == np.uint32
    rgba = [(int(x) >> 24, (int(x) >> 16) & 255, (int(x) >> 8) & 255, int(x) & 255) for x in c]
    assert rgba[0] == (*viz.NO_FORCE_RGB, 255)  # no force: grey
    assert rgba[1] == (68, 1, 84, 255)  # viridis bottom
    assert rgba[3] == rgba[4] == (253, 231, 37, 255)  # top, clipped above
    assert rgba[2][1] > rgba[1][1] and rgba[2][2] > rgba[3][2]  # teal in the middle


def test_plot_paper_writes_a_labelled_png(tmp_path):
    model = simulate.load_model(MODELS / "sphere_drop.xml", n_triangles=TRIANGLES)
    fld = GranularField(model)
    _, rec = simulate.run(model, 0.05, fld=fld)
    path = report.plot_paper(rec, fld.surface_z, tmp_path / "summary.png", title="sphere")
    assert path.stat().st_size > 20_000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
