"""The rigs in models/ with the granular field: stability, consistency with the core, load cells."""

import csv
from pathlib import Path

import mujoco
import numpy as np
import pytest

from mjrft import simulate
from mjrft.app import cli, demos
from mjrft.body import trajectory_wrenches
from mjrft.field import GranularField

MODELS = Path(__file__).resolve().parents[1] / "models"
MODEL_FILES = sorted(MODELS.glob("*.xml"))
# Coarse meshes keep the suite fast; these tests are about dynamics, not resolution.
FAST_TRIANGLES = 600


def test_models_directory_has_the_rigs():
    names = {p.name for p in MODEL_FILES}
    assert {
        "plate_rig.xml",
        "ellipsoid_pitch.xml",
        "root_circumnutation.xml",
        "sphere_drop.xml",
    } <= names


def test_the_rigs_carry_the_prescribed_demos_bodies():
    """The rig-vs-prescribed comparison of `mjrft demo` needs the same bodies on both sides."""
    model = mujoco.MjModel.from_xml_path(str(MODELS / "ellipsoid_pitch.xml"))
    np.testing.assert_allclose(model.geom("ellipsoid").size, demos.ELLIPSOID_SEMI_AXES)
    model = mujoco.MjModel.from_xml_path(str(MODELS / "root_circumnutation.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    g = model.geom("root_tip")
    adr, n = model.mesh_vertadr[g.dataid[0]], model.mesh_vertnum[g.dataid[0]]
    world = (
        data.geom("root_tip").xpos
        + model.mesh_vert[adr : adr + n] @ data.geom("root_tip").xmat.reshape(3, 3).T
    )
    local = (world - data.body("root").xpos) @ data.body("root").xmat.reshape(3, 3)
    tol = 1e-8  # m: MuJoCo stores mesh vertices in single precision
    assert local[:, 2].min() == pytest.approx(-demos.ROOT_PIVOT_ABOVE_APEX, abs=tol)
    assert np.ptp(local[:, 2]) == pytest.approx(demos.ROOT_LENGTH, abs=tol)
    assert np.hypot(local[:, 0], local[:, 1]).max() == pytest.approx(demos.ROOT_RADIUS, abs=tol)


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("path", MODEL_FILES, ids=lambda p: p.stem)
def test_every_model_runs_one_second_with_the_field(path, integrator):
    model = simulate.load_model(path, n_triangles=FAST_TRIANGLES)
    simulate.configure(model, None, integrator)
    fld = GranularField(model)
    data, rec = simulate.run(model, 1.0, fld=fld, record_every=10)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    arr = rec.array()
    assert np.all(np.isfinite(arr))
    assert arr[-1, 0] == pytest.approx(1.0)
    force_cols = [i for i, c in enumerate(rec.columns) if "_rft_force_" in c]
    assert np.any(arr[:, force_cols] != 0), "the medium never acted"


def run_recording_states(model, fld, n_steps):
    """Step; record each pre-step state and the wrench the step's pass computed there."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    be = fld.bodies[0]
    b = be.body
    out = {k: [] for k in ("pos", "rot", "v", "w", "com", "wrench")}
    vel = np.zeros(6)
    for _ in range(n_steps):
        mujoco.mj_step(model, data)  # Euler: derived quantities stay at the pre-step state
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, b, vel, 0)
        out["pos"].append(data.xpos[b].copy())
        out["rot"].append(data.xmat[b].reshape(3, 3).copy())
        out["v"].append(vel[3:].copy())
        out["w"].append(vel[:3].copy())
        out["com"].append(data.xipos[b].copy())
        out["wrench"].append(fld.wrench_of(data)[b].copy())
    return b, {k: np.array(v) for k, v in out.items()}


@pytest.mark.parametrize("name", ["ellipsoid_pitch", "root_circumnutation"])
def test_replaying_the_trajectory_through_the_core_reproduces_the_field(name):
    model = simulate.load_model(MODELS / f"{name}.xml", n_triangles=FAST_TRIANGLES)
    fld = GranularField(model)
    n = 1500 if name == "ellipsoid_pitch" else 300  # the ellipsoid starts with its tip just in
    b, rec = run_recording_states(model, fld, n)
    replay = trajectory_wrenches(
        fld.body_element_set(b),
        rec["pos"],
        rec["rot"],
        rec["v"],
        rec["w"],
        fld.material,
        points=rec["com"],
        surface_z=fld.surface_z,
    )
    scale_f = np.abs(rec["wrench"][:, :3]).max()
    scale_m = np.abs(rec["wrench"][:, 3:]).max()
    assert scale_f > 0.05  # the body was really in the medium
    np.testing.assert_allclose(replay.force, rec["wrench"][:, :3], rtol=1e-9, atol=1e-9 * scale_f)
    np.testing.assert_allclose(replay.moment, rec["wrench"][:, 3:], rtol=1e-9, atol=1e-9 * scale_m)


def load_cell_error(name, duration):
    """RMS of (load cell in world frame - weight + RFT force), relative to the peak RFT force.

    MuJoCo's force sensor reads the force the parent exerts on the child body, in the site
    frame (tests/test_models_kinematics.py), so R f = m a - m g - F_rft for the intruder below
    it; m a is small for these slow rigs and is part of the tolerance.
    """
    model = simulate.load_model(MODELS / f"{name}.xml", n_triangles=FAST_TRIANGLES)
    fld = GranularField(model)
    b = int(fld.body_ids[0])
    s = next(
        i for i in range(model.nsensor) if model.sensor_type[i] == mujoco.mjtSensor.mjSENS_FORCE
    )
    site, adr = model.sensor_objid[s], model.sensor_adr[s]
    weight = model.body_subtreemass[b] * -model.opt.gravity
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    errs, rfts = [], []
    for _ in range(round(duration / model.opt.timestep)):
        mujoco.mj_step(model, data)  # Euler: sensors, site frames, wrench all pre-step
        world = data.site_xmat[site].reshape(3, 3) @ data.sensordata[adr : adr + 3]
        rfts.append(fld.wrench_of(data)[b, :3].copy())
        errs.append(world - weight + rfts[-1])
    err, rft = np.array(errs), np.array(rfts)
    peak = np.abs(rft).max()
    return np.sqrt(np.mean(np.sum(err**2, axis=1))) / peak, peak


@pytest.mark.parametrize(
    ("name", "duration"),
    [("plate_rig", 2.5), ("ellipsoid_pitch", 5.0), ("root_circumnutation", 3.0)],
)
def test_load_cell_minus_weight_matches_rft_force(name, duration):
    rel, peak = load_cell_error(name, duration)
    assert peak > 0.1
    assert rel < 0.02, f"{name}: load cell vs RFT force RMS error {rel:.2%} of peak {peak:.3f} N"


def test_linkage_pitches_9_degrees_at_0625_hz_in_the_medium():
    model = simulate.load_model(MODELS / "ellipsoid_pitch.xml", n_triangles=FAST_TRIANGLES)
    fld = GranularField(model)
    _, rec = simulate.run(model, 6.4, fld=fld, record_every=5)
    t, pitch = rec.column("time_s"), rec.column("sensor_pitch")
    rft_z = rec.column(f"{rec.body_names[0]}_rft_force_z_N")
    assert rft_z.max() > 1.0  # loaded by the medium
    late = t > 1.6  # after the first period
    amp = 0.5 * (pitch[late].max() - pitch[late].min())
    assert np.degrees(amp) == pytest.approx(9.0, rel=0.05)
    assert demos.dominant_frequency(t, pitch, detrend_degree=0) == pytest.approx(0.625, rel=0.05)


# ------------------------------------------------------------------ CLI
def test_cli_run_writes_csv_and_plots(tmp_path, capsys):
    out = tmp_path / "run"
    code = cli.main(
        [
            "run",
            str(MODELS / "sphere_drop.xml"),
            "--duration",
            "0.05",
            "--out",
            str(out),
            "--timestep",
            "0.0005",
            "--integrator",
            "rk4",
            "--all-figures",
        ]
    )
    assert code == 0
    rows = list(csv.reader(open(out / "timeseries.csv")))
    header = rows[0]
    assert header[0] == "time_s"
    assert any(c.endswith("_rft_force_z_N") for c in header)
    assert any(c.startswith("sensor_") for c in header)
    assert len(rows) - 1 == 101  # 100 steps of 0.5 ms, plus the final state
    assert float(rows[-1][0]) == pytest.approx(0.05)
    assert (out / "forces_vs_time.png").stat().st_size > 1000
    # (0.05 s: the sphere's CoM is still above the surface, so no force-vs-depth figure.)
    assert (out / "rft_summary.png").stat().st_size > 1000
    assert "completed at t = 0.05 s" in capsys.readouterr().out


def test_cli_keeps_results_when_interrupted(tmp_path, monkeypatch):
    calls = []

    class Interrupting:
        def __init__(self, label):
            pass

        def __call__(self, fraction):
            calls.append(fraction)
            if fraction >= 0.5:
                raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_Progress", Interrupting)
    out = tmp_path / "run"
    code = cli.main(
        ["run", str(MODELS / "sphere_drop.xml"), "--duration", "0.2", "--out", str(out)]
    )
    assert code == 130
    rows = list(csv.reader(open(out / "timeseries.csv")))
    assert 50 < len(rows) - 1 < 200  # about half of the 200 steps, nothing lost, nothing invented
    assert float(rows[-1][0]) <= 0.1 + 1e-9


def test_cli_keeps_results_when_the_run_fails(tmp_path, monkeypatch):
    original = simulate.record_row
    rows_seen = []

    def failing(*args, **kwargs):
        rows_seen.append(1)
        if len(rows_seen) > 20:
            raise FloatingPointError("synthetic failure mid-run")
        return original(*args, **kwargs)

    monkeypatch.setattr(simulate, "record_row", failing)
    out = tmp_path / "run"
    with pytest.raises(FloatingPointError, match="synthetic"):
        cli.main(["run", str(MODELS / "sphere_drop.xml"), "--duration", "0.1", "--out", str(out)])
    rows = list(csv.reader(open(out / "timeseries.csv")))
    assert len(rows) - 1 == 20  # everything computed before the failure, nothing else


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["run", "nope.xml", "--duration", "1", "--out", "x"], "nope.xml"),
        (["run", str(MODELS / "sphere_drop.xml"), "--duration", "-1", "--out", "x"], "positive"),
        (
            [
                "run",
                str(MODELS / "sphere_drop.xml"),
                "--duration",
                "1",
                "--out",
                "x",
                "--integrator",
                "leapfrog",
            ],
            "invalid choice",
        ),
    ],
)
def test_cli_bad_input(args, match, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        code = cli.main(args)
    except SystemExit as exc:  # argparse errors
        code = exc.code
    assert code == 2
    assert match in capsys.readouterr().err
