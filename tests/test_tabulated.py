"""Media given by Python callables in the engine: the table of their alphas (engine/law.h
EvaluateTabulated, mjrft.core.material.tabulate) against the callables themselves.

The engine samples alpha_x(beta, gamma), alpha_z(beta, gamma) and alpha_y(beta) once, at load,
on a grid of step h = pi / n, and interpolates bicubic Hermite; its error is at most
h^4 / 384 (M4_beta + M4_gamma) + h^5 / 120 (M5_beta + M5_gamma), M_k the largest |k-th
derivative| of an alpha along an angle (the second term from the fourth-order differences that
give the node slopes). Here:

* Li's generic medium and the poppy-seed presets written as callables, through the engine's
  element-force entry point (mjrft_forces), against the exact Fourier kernel on the same
  elements: every element within the a priori bound, and the error measured;
* the callables the repository ships (the docs' example, the test media of test_rft, the
  authors' MATLAB stand-in, which is not pi-periodic in beta) against their exact NumPy
  evaluation (mjrft.core.rft.numpy_forces), horizontal plates and the cut at gamma = +-pi
  included; cubic callables come back to round-off (the interpolation reproduces them);
* the dynamic term appended to a table, as to the other forms;
* plugin models with a medium given by callables step, and follow the same scene with the
  Fourier medium they transcribe;
* callables that give a non-finite value or a wrong shape on the table are refused by name at
  load; a table too coarse for its callables warns.

The engine library is the installed one (mjrft.core.engine), as the plugin's.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math

import mujoco
import numpy as np
import pytest

import mjrft
from mjrft.core import engine
from mjrft.core.material import (
    HARMONICS,
    TABLE_N,
    TABLE_TAG,
    MaterialWarning,
    tabulate,
)
from mjrft.core.rft import numpy_forces
from mjrft.field.scene import SceneError

P, D, I64 = ctypes.c_void_p, ctypes.c_double, ctypes.c_int64
LI = mjrft.LI_GENERIC
PRESETS = ("generic_1ncm3", "poppy_seeds_lp", "poppy_seeds_cp")
#: Cubic callables are reproduced up to round-off in the table's sums (about 20 terms of order 1).
ROUND_OFF = 1e-13
#: The a priori bound on the table's error (module docstring) is met with this margin: it neglects
#: the tensor product's cross term, h^8 / 384^2 M4_beta M4_gamma (below 1e-14 here).
BOUND_MARGIN = 1.01


@pytest.fixture(scope="module")
def lib():
    lib = engine.library()
    lib.mjrft_forces.restype = ctypes.c_int
    lib.mjrft_forces.argtypes = [P, P, P, P, I64, P, I64, D, D, D, P]
    return lib


def cpp_forces(lib, pos, n_hat, area, vel, material, co=None):
    """(n, 3) element forces [N] from the engine (its coefficients: the material's, or co)."""
    co = np.ascontiguousarray(material.kernel_coefficients if co is None else co)
    out = np.empty_like(pos)
    args = [np.ascontiguousarray(a) for a in (pos, n_hat, area, vel)]
    lib.mjrft_forces(*(P(a.ctypes.data) for a in args), len(pos), P(co.ctypes.data), len(co),
                     material.alpha_y0, material.zeta, 0.0, P(out.ctypes.data))  # fmt: skip
    return out


def elements(rng, n):
    """Submerged elements with unit normals and random velocities, world frame, with the
    degenerate frames: horizontal plates facing down and up (beta at and beyond 0 and pi),
    normals within the horizontal-plate band, vertical motion, and tilted bottom (top) faces
    moving backwards and down (up), which lead with gamma near pi (-pi)."""
    pos = rng.normal(scale=0.05, size=(n, 3))
    pos[:, 2] = -np.abs(pos[:, 2]) - 1e-3
    normal = rng.normal(size=(n, 3))
    normal[: n // 20] = [0.0, 0.0, -1.0]
    normal[n // 20 : n // 10] = [0.0, 0.0, 1.0]
    band = slice(n // 10, n // 5)  # |n_z| >= 1 - 1e-3: the frame comes from the velocity
    normal[band, 2] = np.sign(normal[band, 2]) * 60.0
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    vel = rng.normal(size=(n, 3))
    vel[n // 5 : n // 5 + n // 40, :2] = 0.0  # vertical motion
    ends = slice(n // 4, n // 4 + n // 10)  # n = (sin t u, -+cos t), v = -u -+ s z, s > tan t
    m = n // 10
    tilt, phi = rng.uniform(0.05, 0.3, m), rng.uniform(-np.pi, np.pi, m)
    up = np.where(np.arange(m) % 2 == 0, -1.0, 1.0)  # bottom faces, top faces
    u = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    normal[ends, :2] = np.sin(tilt)[:, None] * u
    normal[ends, 2] = up * np.cos(tilt)
    vel[ends, :2] = -u
    vel[ends, 2] = up * np.tan(tilt) * rng.uniform(1.1, 4.0, m)
    area = rng.uniform(1e-6, 1e-4, n)
    return pos, normal, area, vel


def as_callables(material: mjrft.Material) -> mjrft.Material:
    """A Fourier-form medium written as callables (its own alpha_x, alpha_z)."""
    f = material.fourier
    return mjrft.Material.from_callables(f.alpha_x, f.alpha_z, material.zeta, name="callables")


def fourier_bound(coeffs, h: float) -> float:
    """A priori table error of one alpha sum_{m,n} c cos(2 m beta + n gamma) + s sin(...):
    h^4 / 384 (M4_beta + M4_gamma) + h^5 / 120 (M5_beta + M5_gamma), M bounded by the sums of
    |coefficient| (2 m)^k and n^k."""
    c, s = coeffs
    m = np.array([2.0 * abs(mm) for mm, _ in HARMONICS])
    n = np.array([float(nn) for _, nn in HARMONICS])
    mag = np.abs(c) + np.abs(s)
    return h**4 / 384 * (mag @ m**4 + mag @ n**4) + h**5 / 120 * (mag @ m**5 + mag @ n**5)


def per_element_error(f, ref, area, pos, material, scale):
    """|f - ref| of each element over zeta depth area scale: the force error per unit alpha
    error (f1, f23 <= 1)."""
    return np.linalg.norm(f - ref, axis=1) / (material.zeta * -pos[:, 2] * area * scale)


@pytest.mark.parametrize("preset", PRESETS)
def test_a_fourier_medium_as_callables_is_the_fourier_kernel_within_the_bound(lib, preset):
    exact = mjrft.Material.preset(preset)
    tab = as_callables(exact)
    pos, normal, area, vel = elements(np.random.default_rng(3), 20000)
    f_exact = cpp_forces(lib, pos, normal, area, vel, exact)
    f_tab = cpp_forces(lib, pos, normal, area, vel, tab)
    fo, h = exact.fourier, math.pi / TABLE_N
    e_x, e_z = fourier_bound((fo.c, fo.d), h), fourier_bound((fo.a, fo.b), h)
    # |dF| <= zeta d A (f1 |d alpha_y| + f23 |(d alpha_x, d alpha_z)|), alpha_y constant: exact.
    err = per_element_error(f_tab, f_exact, area, pos, exact, 1.0)
    assert np.count_nonzero(f_exact.any(axis=1)) > 5000
    assert err.max() <= BOUND_MARGIN * math.hypot(e_x, e_z)
    # The table's own estimate (at its cells' centres) agrees, and Li's medium is within 1.2e-7
    # of its largest |alpha| (the figure docs/materials.md states).
    assert tab.table_error <= BOUND_MARGIN * max(e_x, e_z)
    scale = np.abs(f_exact).max()
    print(f"{preset}: max |dF| / max |F| = {np.abs(f_tab - f_exact).max() / scale:.2e}, per "
          f"element {err.max():.2e} <= bound {math.hypot(e_x, e_z):.2e}, table_error "
          f"{tab.table_error:.2e}")  # fmt: skip
    if preset == "generic_1ncm3":
        assert np.abs(f_tab - f_exact).max() <= 1.2e-7 * scale


def test_the_table_error_falls_as_h4(lib):
    exact = mjrft.Material.preset("generic_1ncm3")
    tab = as_callables(exact)
    pos, normal, area, vel = elements(np.random.default_rng(4), 20000)
    f_exact = cpp_forces(lib, pos, normal, area, vel, exact)
    scale = np.abs(f_exact).max()
    errors = {}
    for n in (16, 32, 64, 128):
        f = cpp_forces(lib, pos, normal, area, vel, tab.tabulated(n))
        errors[n] = np.abs(f - f_exact).max() / scale
    print({n: f"{e:.2e}" for n, e in errors.items()})
    for n in (16, 32, 64):
        assert 12.0 < errors[n] / errors[2 * n] < 20.0  # 2^4 = 16
    assert errors[TABLE_N] < 1e-6 < errors[16]


def _shipped():
    """The callables the repository ships, by name: (material, largest |alpha|)."""
    glass = mjrft.Material.preset("glass_beads")
    with pytest.warns(MaterialWarning):  # stand-ins, not dissipative everywhere
        test_rft = mjrft.Material.from_callables(
            lambda b, g: 0.3 * np.cos(g) + 0.1 * np.sin(2 * b) - 0.05 * np.sin(b + g),
            lambda b, g: 0.6 + 0.2 * np.cos(2 * b) + 0.4 * np.sin(g) + 0.1 * np.cos(b - g),
            2.0e5,
        )
        matlab = mjrft.Material.from_callables(
            lambda b, g: 0.25 * np.cos(g) * (1 - np.cos(2 * b)),
            lambda b, g: (0.6 * np.sin(g) + 0.4) * np.cos(b),
            3.3e5,
        )
    alpha_y = mjrft.Material.from_callables(
        lambda b, g: 0.25 * np.cos(g), lambda b, g: 0.5 + 0.5 * np.sin(g), 1e6,
        alpha_y=lambda b: 0.1 + 0.05 * np.cos(2 * b),
    )  # fmt: skip
    docs = mjrft.Material.from_callables(LI.alpha_x, LI.alpha_z, zeta=glass.zeta)
    return {
        "docs_li_generic": (docs, 1.1),
        "test_rft_callables": (test_rft, 1.4),
        "test_rft_alpha_y": (alpha_y, 1.0),
        "matlab_stand_in": (matlab, 1.0),
    }


@pytest.mark.parametrize("name", ["docs_li_generic", "test_rft_callables", "test_rft_alpha_y",
                                  "matlab_stand_in"])  # fmt: skip
def test_shipped_callables_match_their_numpy_evaluation(lib, name):
    material, scale = _shipped()[name]
    pos, normal, area, vel = elements(np.random.default_rng(5), 20000)
    f_tab = cpp_forces(lib, pos, normal, area, vel, material)
    f_exact = numpy_forces(pos, normal, area, vel, material, 0.0)
    assert np.array_equal(f_tab.any(axis=1), f_exact.any(axis=1))  # the same elements act
    err = per_element_error(f_tab, f_exact, area, pos, material, scale)
    print(f"{name}: per element {err.max():.2e}, max |dF| / max |F| "
          f"{np.abs(f_tab - f_exact).max() / np.abs(f_exact).max():.2e}, table_error "
          f"{material.table_error:.2e}")  # fmt: skip
    assert err.max() < 1e-6
    assert material.table_error < 1e-6


@pytest.mark.filterwarnings("ignore::mjrft.core.material.MaterialWarning")  # a stand-in
def test_cubic_callables_come_back_to_round_off(lib):
    # Not periodic in either angle: the table is not wrapped, and its ends (beta beyond [0, pi]
    # on horizontal plates, gamma at +-pi) are the callables' own values.
    cubic = mjrft.Material.from_callables(
        lambda b, g: 0.3 + 0.05 * b - 0.02 * g**2 + 0.01 * b**3 * g - 0.004 * g**3,
        lambda b, g: 0.7 - 0.1 * b**2 + 0.03 * b * g**3 + 0.02 * g,
        3e5,
        alpha_y=lambda b: 0.2 - 0.03 * b**3,
    )
    pos, normal, area, vel = elements(np.random.default_rng(6), 20000)
    f_tab = cpp_forces(lib, pos, normal, area, vel, cubic)
    f_exact = numpy_forces(pos, normal, area, vel, cubic, 0.0)
    assert per_element_error(f_tab, f_exact, area, pos, cubic, 1.0).max() < ROUND_OFF
    assert cubic.table_error < ROUND_OFF


def test_the_layout_the_engine_reads():
    tab = as_callables(mjrft.Material.preset("glass_beads")).tabulated(16)
    co = tab.kernel_coefficients
    h = math.pi / 16
    nb, ng = int(co[1]), int(co[2])
    kb = (nb - 17) // 2  # nodes beyond [0, pi] at each end
    assert co[0] == TABLE_TAG and co[5] == h and co[4] == -math.pi and co[3] == -kb * h
    assert ng == 33 and kb * h >= 0.0447 and len(co) == 8 + 8 * nb * ng + 2 * nb
    # Node (i, j): alpha_x, h d/dbeta, h d/dgamma, h^2 d2/dbeta dgamma, then alpha_z's; then
    # alpha_y and h d/dbeta per beta node.
    i, j = 5, 7
    node = co[8 + 8 * (i * ng + j) :][:8]
    b, g = co[3] + i * h, co[4] + j * h
    assert node[0] == pytest.approx(LI.alpha_x(b, g), abs=1e-15)
    assert node[4] == pytest.approx(LI.alpha_z(b, g), abs=1e-15)
    # Slopes by fourth-order differences: within h^6 / 30 max |d5 alpha| (h times the
    # difference's error), max |d5 alpha| <= 2^5 sum |coefficient|.
    d = 1e-6
    slope_g = h * (LI.alpha_x(b, g + d) - LI.alpha_x(b, g - d)) / (2 * d)
    slope_b = h * (LI.alpha_z(b + d, g) - LI.alpha_z(b - d, g)) / (2 * d)
    tol = h**5 / 30 * 32 * sum(np.abs(c).sum() for c in (LI.a, LI.b, LI.c, LI.d))
    assert node[2] == pytest.approx(slope_g, abs=tol)
    assert node[5] == pytest.approx(slope_b, abs=tol)
    assert abs(node[5] - slope_b) > 1e-3 * tol  # not exact: the differences are
    assert co[8 + 8 * nb * ng + 2 * i] == tab.alpha_y0 and co[8 + 8 * nb * ng + 2 * i + 1] == 0.0
    # The dynamic term is one more entry, as for the other forms.
    dyn = dataclasses.replace(tab, dynamic=1200.0)
    assert len(dyn.kernel_coefficients) == len(co) + 1 and dyn.kernel_coefficients[-1] == 1200.0


def test_the_dynamic_term_composes_with_a_table_as_with_the_fourier_form(lib):
    exact = mjrft.Material.preset("glass_beads")
    tab = as_callables(exact)
    pos, normal, area, vel = elements(np.random.default_rng(7), 20000)
    vel *= 3.0  # speeds where the inertial term matters
    f_exact = cpp_forces(lib, pos, normal, area, vel, exact)
    f_tab = cpp_forces(lib, pos, normal, area, vel, tab)
    rho = 1500.0
    d_exact = cpp_forces(lib, pos, normal, area, vel, exact.with_dynamic(rho)) - f_exact
    co = np.append(tab.kernel_coefficients, rho)  # as kernel_coefficients appends it
    d_tab = cpp_forces(lib, pos, normal, area, vel, tab, co) - f_tab
    assert np.abs(d_exact).max() > 1e-3 * np.abs(f_exact).max()
    # The same term on the same elements: only the subtraction's rounding differs.
    np.testing.assert_allclose(d_tab, d_exact, rtol=0, atol=1e-14 * np.abs(f_exact).max())


# A dense ellipsoid thrown spinning into the medium: every step acts, at every angle.
THROWN = """
<mujoco>
  <option timestep="0.001" integrator="{integrator}"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <tuple name="mjrft:intruders"><element objtype="geom" objname="shell" prm="200"/></tuple>
  </custom>
  <worldbody>
    <body name="crab" pos="0 0 0.004">
      <freejoint/>
      <geom name="shell" type="ellipsoid" size="0.008 0.006 0.012" density="8000"/>
    </body>
  </worldbody>
</mujoco>"""
THROW = (0.3, -0.1, -0.5, 4.0, -2.0, 6.0)
#: Over 200 steps the table's medium and the Fourier one it transcribes part by the force error
#: (about 1e-7 of the force) carried along the trajectory: the state (qpos, qvel) within this of
#: each component's largest magnitude (measured: 1.9e-7)...
STATE_RTOL = 1e-6
#: ...and the wrench within this of each component's largest (measured 2.3e-6: a component's
#: smallest values feel the differences of the states in the others).
WRENCH_RTOL = 1e-5


def _run(material, integrator, steps=200):
    model = mjrft.load_model(THROWN.format(integrator=integrator), material=material)
    data = mujoco.MjData(model)
    data.qvel[:] = THROW
    out = []
    for _ in range(steps):
        mujoco.mj_step(model, data)
        out.append(np.concatenate([data.qpos, data.qvel, data.xfrc_applied[1]]))
    return model, np.array(out)


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_a_plugin_model_with_callables_steps_as_the_fourier_medium(integrator):
    glass = mjrft.Material.preset("glass_beads")
    callables = as_callables(glass)
    model, a = _run(callables, integrator)
    _, b = _run(glass, integrator)
    assert mjrft.GranularField(model).material is callables
    assert np.all(np.isfinite(a)) and np.any(a[:, -6:] != 0.0)
    assert not np.array_equal(a, b)  # the table is not the Fourier kernel, but near it
    error = np.abs(a - b).max(axis=0) / np.abs(b).max(axis=0)
    assert np.all(error[:-6] < STATE_RTOL) and np.all(error[-6:] < WRENCH_RTOL)


def test_a_plugin_model_with_beta_dependent_alpha_y_steps():
    medium = _shipped()["test_rft_alpha_y"][0]
    constant = dataclasses.replace(medium, alpha_y_fn=None, alpha_y0=0.1)  # alpha_y(pi/4)
    _, a = _run(medium, "Euler", 60)
    _, b = _run(constant, "Euler", 60)
    assert np.all(np.isfinite(a)) and np.any(a[:, -6:] != 0.0)
    assert np.abs(a - b).max() > 1e-6 * np.abs(b).max()  # alpha_y(beta) acts


def _probe_safe_nan(b, g):
    # Finite on from_callables' probe grid, NaN at the table node beta = 3 pi / 64.
    return np.where(np.abs(b - 3 * np.pi / 64) < 1e-9, np.nan, 0.2 + 0.0 * b)


@pytest.mark.filterwarnings("ignore::mjrft.core.material.MaterialWarning")  # stand-ins
@pytest.mark.parametrize(
    ("alphas", "message"),
    [
        ({"alpha_x": _probe_safe_nan}, r"alpha_x\(beta, gamma\) returned a non-finite value "
         r"\(nan\) at angle\(s\) \(0\.1473, .*\) rad on the engine's table"),
        ({"alpha_z": lambda b, g: np.ones(3)}, r"alpha_z\(beta, gamma\) returned shape \(3,\) "
         r"for inputs of shape \(\d+,\) on the engine's table"),
        ({"alpha_y": lambda b: np.full(73 * 73, 0.1)}, r"alpha_y\(beta\) returned shape "
         r"\(5329,\) for inputs of shape \(\d+,\) on the engine's table"),
        ({"alpha_y": lambda b: np.where(np.abs(b - 5 * np.pi / 64) < 1e-9, np.inf, 0.1 + 0 * b)},
         r"alpha_y\(beta\) returned a non-finite value \(inf\) at angle\(s\) \(0\.2454\) rad "
         r"on the engine's table of 'bad' \(step pi/64\)"),
    ],
)  # fmt: skip
def test_bad_callables_are_refused_by_name_at_load(alphas, message):
    """Callables that pass from_callables' probe but not the table's nodes (beta = 3 pi / 64 is on
    neither the probe's grid nor the dissipation check's), or that changed since (a medium's
    callables replaced with dataclasses.replace, as docs/materials.md does alpha_y0)."""
    good = {"alpha_x": lambda b, g: 0.2 + 0.0 * b, "alpha_z": lambda b, g: 1.0 + 0.0 * g}
    kw = {**good, **{k: v for k, v in alphas.items() if k != "alpha_z"}}
    medium = mjrft.Material.from_callables(kw["alpha_x"], kw["alpha_z"], 3e5,
                                           alpha_y=kw.get("alpha_y"), name="bad")  # fmt: skip
    if "alpha_z" in alphas:
        medium = dataclasses.replace(medium, alpha_z_fn=alphas["alpha_z"])
    with pytest.raises(SceneError, match=f"material 'bad': {message}"):
        mjrft.load_model(THROWN.format(integrator="Euler"), material=medium)


@pytest.mark.filterwarnings("ignore:.*not a dissipative medium")
def test_a_table_too_coarse_for_its_callables_warns_and_bad_resolutions_are_refused():
    step = mjrft.Material.from_callables(
        lambda b, g: 0.2 + 0.0 * b, lambda b, g: np.where(g > 0.3, 1.0, 0.5), 3e5, name="step"
    )
    with pytest.warns(MaterialWarning, match=r"step: the engine's table \(step pi/64\) misses "
                      r"alpha_z by .* at its cells' centres"):  # fmt: skip
        step.kernel_coefficients  # noqa: B018
    smooth = as_callables(mjrft.Material.preset("glass_beads"))
    for n in (7, 257, 32.0, "64"):
        with pytest.raises(ValueError, match=r"tabulated\(n=.*\): expected an integer"):
            smooth.tabulated(n)
    with pytest.raises(ValueError, match="given by coefficients.*only media given by callables"):
        mjrft.Material.preset("glass_beads").tabulated(32)
    assert mjrft.Material.preset("glass_beads").table_error == 0.0
    _, error, worst = tabulate(smooth, 32)
    assert worst in ("alpha_x", "alpha_z") and 1e-7 < error < 1e-5
