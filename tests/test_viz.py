"""Rerun recordings (mjrft.viz, `mjrft run --rrd`, `mjrft demo`) and the paper-style plots.

Recordings are read back with rerun's own reader (rerun.chunk.RrdReader, via viz.read_entity) and
compared with an independent re-simulation evaluated at exactly the logged states.
"""

import copy
import csv
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

from mjrft import simulate, viz  # noqa: E402
from mjrft.app import cli, report  # noqa: E402
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
    fld = GranularField(model, n_triangles=TRIANGLES)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    wanted, out = set(steps), {}
    last = max(steps)
    with fld.installed():
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
    """0.3 s of the root rig (in the medium from the start, 3120-triangle mesh) recorded every
    25 steps with at most 40 arrows per frame."""
    model = simulate.load_model(MODELS / "root_circumnutation.xml")
    simulate.configure(model, None, request.param)
    fld = GranularField(model, n_triangles=TRIANGLES)
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
    assert f"{r['rec'].arrow_scale:.4g} m per N" in legend["TextDocument:text"][0]


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
        np.testing.assert_allclose(vectors / rec.arrow_scale, st.force[k], atol=2e-6 * fmax)
        np.testing.assert_allclose(origins, st.pos[k], atol=1e-7)
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
    np.testing.assert_allclose(world[st.index], st.pos, atol=1e-6)


# ------------------------------------------------------------------ robustness
def test_recording_is_complete_when_the_run_raises(tmp_path):
    def failing_progress(fraction):  # called after each 2nd step of 200 (and its frame)
        if fraction >= 0.25:
            raise RuntimeError("synthetic failure mid-run")

    model = simulate.load_model(MODELS / "sphere_drop.xml")
    path = tmp_path / "failed.rrd"
    with pytest.raises(RuntimeError, match="synthetic"):
        viz.record(
            model,
            0.2,
            path,
            fld=GranularField(model, n_triangles=TRIANGLES),
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


# ------------------------------------------------------------------ CLI options and files
def test_cli_run_writes_the_recording_with_the_requested_decimation_and_scale(tmp_path, capsys):
    out = tmp_path / "run"
    rrd = out / "sphere.rrd"
    code = cli.main(
        ["run", str(MODELS / "sphere_drop.xml"), "--duration", "0.05", "--out", str(out)]
        + ["--rrd", str(rrd), "--rrd-every", "3", "--max-arrows", "100000"]
        + ["--arrow-scale", "0.25", "--stress-max", "5000"]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert f"recording: {rrd}" in printed and f"rerun {rrd}" in printed
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
        checked += fz[row["step"]] > 0.05
    assert checked >= 3
    for name in ("timeseries.csv", "forces_vs_time.png", "forces_vs_depth.png", report.PAPER_PNG):
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
    fld, rec = cli._demo_rig(cli.DEMO_RRD_RIG, 0.05, Material.preset("glass_beads"), 300, rrd)
    RrdReader(str(rrd)).store()
    assert steps_of(rrd, f"world/bodies/{fld.bodies[0].name}") == [0, 10, 20, 30, 40, 50]
    assert len(rec.rows) == 6
    assert cli.DEMO_RRD_RIG in {name for name, _ in cli.DEMO_RIGS}


# ------------------------------------------------------------------ headless, size, isolation
def test_recorder_is_headless_and_leaves_rerun_global_state_alone(tmp_path, monkeypatch):
    for var in ("DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(var, raising=False)
    before_global = rr.get_global_data_recording()
    children_before = _children()
    model = simulate.load_model(MODELS / "plate_rig.xml")
    fld = GranularField(model, n_triangles=TRIANGLES)
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
    model = simulate.load_model(MODELS / "sphere_drop.xml")
    fld = GranularField(model, n_triangles=TRIANGLES)
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
    model = simulate.load_model(MODELS / "sphere_drop.xml")
    fld = GranularField(model, n_triangles=TRIANGLES)
    _, rec = simulate.run(model, 0.05, fld=fld)
    path = report.plot_paper(rec, fld.surface_z, tmp_path / "summary.png", title="sphere")
    assert path.stat().st_size > 20_000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
