"""Fitting a medium to plate data (mjrft.core.fit, ``mjrft fit``): synthetic plates whose forces
come from the RFT kernel (``mjrft.element_forces`` on one leading element per plate), with and
without noise, fitted back."""

import csv
import json

import numpy as np
import pytest

import mjrft
from mjrft.app import cli
from mjrft.core import law
from mjrft.core.fit import (
    FIRST_ORDER,
    FULL,
    FitError,
    PlateData,
    YawedPlateData,
    fit,
    fit_yawed,
    scaling,
)

DEPTH_RANGE = (0.01, 0.05)  # m
AREA = 4e-4  # m^2: a 2 x 2 cm plate
# A noiseless fit reproduces the generating coefficients to rounding of a least-squares solve.
EXACT_RTOL = 1e-9
# Nine coefficients each inside its 95 % interval happens in 63 % of noise draws only; three
# standard errors (99.7 % each, 97 % for all nine) make the test a test of the intervals.
SE_MULTIPLE = 3.0


def plates(material: mjrft.Material, beta_deg, gamma_deg, rng, noise: float = 0.0) -> PlateData:
    """One plate per (beta, gamma) pair at a random depth, its force from the kernel: the
    plate's leading face as one element (normal of attack angle beta, motion along gamma in the
    x-z plane, docs/design.md 2.4), plus Gaussian noise of `noise` [N] per component."""
    beta, gamma = np.radians(np.asarray(beta_deg, float)), np.radians(np.asarray(gamma_deg, float))
    n = np.stack([np.sin(beta), 0 * beta, -np.cos(beta)], axis=1)
    v = np.stack([np.cos(gamma), 0 * gamma, -np.sin(gamma)], axis=1)
    lead = np.sum(n * v, axis=1)
    keep = np.abs(lead) > 1e-6  # a plate moving edge-on has no leading face
    n[lead < 0] *= -1.0  # the other face leads (alpha has period pi in beta)
    depth = rng.uniform(*DEPTH_RANGE, len(beta))
    pos = np.stack([0 * beta, 0 * beta, -depth], axis=1)
    f = mjrft.element_forces(pos, n, np.full(len(beta), AREA), v, material, 0.0)
    f = f + rng.normal(0.0, noise, f.shape) if noise else f
    return PlateData(beta[keep], gamma[keep], depth[keep], np.full(keep.sum(), AREA),
                     f[keep, 0], f[keep, 2])  # fmt: skip


def grid(step: float = 15.0):
    b, g = np.meshgrid(np.arange(-90, 90, step), np.arange(-90, 90.1, step))
    return b.ravel(), g.ravel()


@pytest.mark.parametrize("preset", ["glass_beads", "poppy_seeds_lp", "poppy_seeds_cp"])
def test_a_presets_own_plates_fit_back_to_the_preset(preset):
    material = mjrft.Material.preset(preset)
    data = plates(material, *grid(), np.random.default_rng(0))
    result = fit(data, "first")
    truth = material.fourier.scaled(material.zeta).as_mapping()
    for name in FIRST_ORDER["z"] + FIRST_ORDER["x"]:
        expected = pytest.approx(
            truth.get(name, 0.0), rel=EXACT_RTOL, abs=EXACT_RTOL * material.zeta
        )
        assert result.coefficients[name] == expected
    assert result.material.zeta == pytest.approx(material.zeta, rel=EXACT_RTOL)
    assert max(result.rms.values()) < 1e-9


def test_noisy_plates_recover_the_coefficients_within_their_intervals():
    """Synthetic glass-bead plates with 2 % force noise: every coefficient within three standard
    errors of the truth, the intervals honest in size (the noise level is recovered), and the
    full set, given enough plates, agrees with the first-order one on the terms they share."""
    material = mjrft.Material.preset("glass_beads")
    rng = np.random.default_rng(7)
    noise = 0.02 * material.zeta * np.mean(DEPTH_RANGE) * AREA  # N
    data = plates(material, *grid(10.0), rng, noise=noise)
    result = fit(data, "first")
    truth = material.fourier.scaled(material.zeta).as_mapping()
    for name, value in result.coefficients.items():
        se = result.standard_errors[name]
        assert abs(value - truth.get(name, 0.0)) <= SE_MULTIPLE * se, (name, value, se)
        assert se < 0.05 * material.zeta
    assert result.rms["z"] == pytest.approx(noise, rel=0.1)
    full = fit(data, "full")
    assert set(full.coefficients) == set(FULL["z"] + FULL["x"])
    for name in ("A00", "B01", "C01"):
        close = pytest.approx(result.coefficients[name], abs=4 * full.standard_errors[name])
        assert full.coefficients[name] == close


def test_plates_at_one_intrusion_angle_are_refused_naming_what_is_missing():
    material = mjrft.Material.preset("glass_beads")
    beta = np.arange(-80, 90, 10.0)
    data = plates(material, beta, np.full(beta.shape, 90.0), np.random.default_rng(1))
    with pytest.raises(FitError, match=r"cannot separate .*gamma \{90\}"):
        fit(data, "first")


def test_a_fit_that_would_push_along_the_motion_is_refused():
    """Forces with the sign of F_z flipped make a 'medium' that accelerates a plate pushed
    down: the fit says so instead of returning it."""
    material = mjrft.Material.preset("glass_beads")
    data = plates(material, *grid(), np.random.default_rng(2))
    flipped = PlateData(data.beta, data.gamma, data.depth, data.area, data.fx, -data.fz)
    with pytest.raises(FitError, match="do not make a medium"):
        fit(flipped, "first")


def test_cli_fit_writes_the_mjcf_json_and_plot_and_the_mjcf_loads(tmp_path, capsys):
    material = mjrft.Material.preset("poppy_seeds_lp")
    data = plates(material, *grid(), np.random.default_rng(3))
    path = tmp_path / "plates.csv"
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["beta_deg", "gamma_deg", "depth_m", "area_m2", "fx_N", "fz_N", "note"])
        for row in zip(np.degrees(data.beta), np.degrees(data.gamma), data.depth, data.area,
                       data.fx, data.fz, strict=True):  # fmt: skip
            w.writerow([*(f"{x:.17g}" for x in row), "synthetic"])
    out = tmp_path / "fit"
    assert cli.main(["fit", str(path), "--out", str(out), "--order", "first"]) == 0
    assert "first-order set" in capsys.readouterr().out
    summary = json.loads((out / "fit.json").read_text())
    assert summary["plates"] == len(data.beta)
    assert (out / "residuals.png").stat().st_size > 10_000
    # The MJCF snippet makes the same medium when pasted into a scene.
    from mjrft.field import GranularField

    xml = f"""<mujoco><custom>{(out / "material.xml").read_text()}
      <tuple name="mjrft:intruders"><element objtype="geom" objname="g" prm="0"/></tuple>
      </custom><worldbody><body><freejoint/><geom name="g" size="0.01"/></body></worldbody>
      </mujoco>"""
    fld = GranularField(mjrft.load_model(xml))
    beta, gamma = np.radians([10.0, 40.0, -70.0]), np.radians([80.0, -20.0, 30.0])
    # 10 significant digits in the MJCF.
    np.testing.assert_allclose(
        fld.material.alpha(beta, gamma), material.alpha(beta, gamma), rtol=1e-8,
        atol=1e-8 * material.zeta,
    )  # fmt: skip


def test_cli_fit_names_a_bad_csv(tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text("beta_deg,gamma_deg,depth_m,area_m2,fx_N\n0,90,0.01,1e-4,0\n")
    assert cli.main(["fit", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "missing column(s) fz_N" in capsys.readouterr().err
    path.write_text("beta_deg,gamma_deg,depth_m,area_m2,fx_N,fz_N\n0,90,deep,1e-4,0,1\n")
    assert cli.main(["fit", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "row 2, column depth_m: 'deep'" in capsys.readouterr().err


def test_repeated_rows_are_refused_naming_them_and_replicates_are_fitted(tmp_path, capsys):
    """A file given twice would narrow every interval by 1/sqrt(2) with no new information."""
    material = mjrft.Material.preset("glass_beads")
    rng = np.random.default_rng(4)
    data = plates(material, *grid(), rng, noise=0.01)
    twice = PlateData(*(np.concatenate([a, a]) for a in vars(data).values()))
    n = len(data.beta)
    with pytest.raises(FitError, match=rf"plate data: {n} row\(s\) repeat .*\(row {n} = row 0, "):
        fit(twice, "first")
    path = tmp_path / "plates.csv"
    lines = ["beta_deg,gamma_deg,depth_m,area_m2,fx_N,fz_N"]
    lines += [",".join(f"{x:.17g}" for x in row) for row in zip(*vars(data).values(), strict=True)]
    path.write_text("\n".join(lines + lines[1:3]) + "\n")  # the first two plates pasted again
    assert cli.main(["fit", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{path}: 2 row(s) repeat an earlier row in every column (row {n + 2} = row 2, " in err
    # Replicates (the same plates measured again: their own forces) are data.
    fx, fz = (np.concatenate([f, f + rng.normal(0.0, 0.01, n)]) for f in (data.fx, data.fz))
    same = (np.concatenate([a, a]) for a in (data.beta, data.gamma, data.depth, data.area))
    replicate = PlateData(*same, fx, fz)
    assert fit(replicate, "first").n == 2 * n


# ---- yawed plates: alpha_y(beta), f1, f23 (mjrft.core.fit.fit_yawed) -------------------------


def yawed_plates(material, beta_deg, gamma_deg, psi_deg, rng, noise: float = 0.0):
    """As ``plates``, the motion turned by yaw psi towards +y (YawedPlateData's convention)."""
    beta, gamma, psi = (np.radians(np.asarray(a, float)) for a in (beta_deg, gamma_deg, psi_deg))
    n = np.stack([np.sin(beta), 0 * beta, -np.cos(beta)], axis=1)
    u = np.stack([np.cos(gamma), 0 * gamma, -np.sin(gamma)], axis=1)
    v = np.cos(psi)[:, None] * u + np.sin(psi)[:, None] * np.array([0.0, 1.0, 0.0])
    lead = np.sum(n * v, axis=1)
    keep = np.abs(lead) > 1e-3
    n[lead < 0] *= -1.0
    depth = rng.uniform(*DEPTH_RANGE, len(beta))
    pos = np.stack([0 * beta, 0 * beta, -depth], axis=1)
    f = mjrft.element_forces(pos, n, np.full(len(beta), AREA), v, material, 0.0)
    f = f + rng.normal(0.0, noise, f.shape) if noise else f
    area = np.full(keep.sum(), AREA)
    return YawedPlateData(beta[keep], gamma[keep], psi[keep], depth[keep], area,
                          f[keep, 0], f[keep, 1], f[keep, 2])  # fmt: skip


def yaw_grid():
    b, g, p = np.meshgrid(np.arange(-75, 90, 15), np.arange(-60, 90.1, 30), [-60, -30, 20, 45, 70])
    return b.ravel(), g.ravel(), p.ravel()


#: A start far from Treers et al.'s values (mjrft.core.law), so the fit has to find them.
FAR = {"f1_slope": 2.0, "f1_shift": 0.8, "f23_slope": 1.2, "f23_shift": 0.5}


def in_plane_fit(material):
    return fit(plates(material, *grid(), np.random.default_rng(0)), "first")


def test_yawed_plates_give_back_the_kernels_f1_f23_and_alpha_y():
    """Noiseless plates from the kernel (Treers et al.'s f1 and f23, the preset's constant
    alpha_y): the fit returns mjrft.core.law's slopes and shifts and alpha_y to 1e-6."""
    material = mjrft.Material.preset("glass_beads")
    data = yawed_plates(material, *yaw_grid(), np.random.default_rng(1))
    result = fit_yawed(data, in_plane_fit(material), start=FAR)
    truth = {"f1_slope": law.F1_SLOPE, "f1_shift": law.F1_SHIFT, "f23_slope": law.F23_SLOPE,
             "f23_shift": law.F23_SHIFT, "ay0": material.alpha_y0 * material.zeta,
             "ay_cos2b": 0.0, "ay_sin2b": 0.0}  # fmt: skip
    for name, value in truth.items():
        assert result.values[name] == pytest.approx(value, rel=1e-6, abs=1e-6 * material.zeta)
    assert max(result.rms.values()) < 1e-9


def test_noisy_yawed_plates_recover_the_parameters_within_their_intervals():
    material = mjrft.Material.preset("glass_beads")
    rng = np.random.default_rng(2)
    noise = 0.02 * material.zeta * np.mean(DEPTH_RANGE) * AREA
    data = yawed_plates(material, *yaw_grid(), rng, noise=noise)
    result = fit_yawed(data, in_plane_fit(material), start=FAR)
    truth = {"f1_slope": law.F1_SLOPE, "f1_shift": law.F1_SHIFT, "f23_slope": law.F23_SLOPE,
             "f23_shift": law.F23_SHIFT, "ay0": material.alpha_y0 * material.zeta}  # fmt: skip
    for name, value in truth.items():
        err = abs(result.values[name] - value)
        assert err <= SE_MULTIPLE * result.standard_errors[name], (name, result.values[name])
    # shapes other than the truth are told apart: the fitted f23 differs from a straight line
    u = np.linspace(0.1, 0.9, 9)
    f = scaling(u, result.values["f23_slope"], result.values["f23_shift"], inverse_tanh=True)
    assert np.abs(f - u).max() > 0.05


def test_yawed_plates_that_cannot_determine_f1_and_f23_are_refused():
    material = mjrft.Material.preset("glass_beads")
    b, g, p = yaw_grid()
    few = np.isin(np.abs(p), [20, 45])
    data = yawed_plates(material, b[few], g[few], p[few], np.random.default_rng(3))
    with pytest.raises(FitError, match=r"yawed plates at >= 3 distinct \|yaw\|"):
        fit_yawed(data, in_plane_fit(material))
    flat = yawed_plates(material, 0 * b + 30, g, p, np.random.default_rng(3))
    with pytest.raises(FitError, match="alpha_y\\(beta\\) needs yawed plates at >= 3 distinct"):
        fit_yawed(flat, in_plane_fit(material))


def test_cli_fit_fits_the_yawed_rows_of_a_csv(tmp_path, capsys):
    """A CSV with yaw_deg and fy_N: the yaw-0 rows give the in-plane set, the others f1, f23
    and alpha_y, reported in fit.json beside the kernel's values."""
    material = mjrft.Material.preset("glass_beads")
    flat = plates(material, *grid(), np.random.default_rng(4))
    yawed = yawed_plates(material, *yaw_grid(), np.random.default_rng(5))
    path = tmp_path / "plates.csv"
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["beta_deg", "gamma_deg", "yaw_deg", "depth_m", "area_m2", "fx_N", "fy_N",
                    "fz_N"])  # fmt: skip
        for d, psi, fy in ((flat, 0 * flat.beta, 0 * flat.fx), (yawed, yawed.psi, yawed.fy)):
            for row in zip(np.degrees(d.beta), np.degrees(d.gamma), np.degrees(psi), d.depth,
                           d.area, d.fx, fy, d.fz, strict=True):  # fmt: skip
                w.writerow([f"{x:.17g}" for x in row])
    out = tmp_path / "fit"
    assert cli.main(["fit", str(path), "--out", str(out), "--order", "first"]) == 0
    assert (
        "yawed plates: alpha_y(beta) and the scaling functions f1, f23" in capsys.readouterr().out
    )
    summary = json.loads((out / "fit.json").read_text())
    assert summary["plates"] == len(flat.beta)
    f23 = summary["yawed"]["values"]["f23_slope"]
    assert f23["value"] == pytest.approx(f23["kernel"], rel=1e-6)
    path.write_text("beta_deg,gamma_deg,yaw_deg,depth_m,area_m2,fx_N,fz_N\n0,90,0,0.01,1e-4,0,1\n")
    assert cli.main(["fit", str(path), "--out", str(out)]) == 2
    assert "column yaw_deg needs column fy_N" in capsys.readouterr().err
