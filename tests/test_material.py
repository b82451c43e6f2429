"""Materials: presets, unit handling, table and callable construction, and their validation."""

import numpy as np
import pytest

import mjrft
from mjrft.core.material import POPPY_SEEDS_CP_N_PER_CM3, POPPY_SEEDS_LP_N_PER_CM3


def test_generic_units():
    si = mjrft.Material.generic(0.33e6)
    cm = mjrft.Material.generic(zeta_n_per_cm3=0.33)
    assert si.zeta == cm.zeta == pytest.approx(330_000.0)
    assert mjrft.Material.preset("glass_beads").zeta == pytest.approx(0.33 * mjrft.N_PER_CM3)


@pytest.mark.parametrize(
    ("name", "table"),
    [("poppy_seeds_lp", POPPY_SEEDS_LP_N_PER_CM3), ("poppy_seeds_cp", POPPY_SEEDS_CP_N_PER_CM3)],
)
def test_poppy_tables_reproduce_their_coefficients(name, table):
    m = mjrft.Material.preset(name)
    rng = np.random.default_rng(0)
    b, g = rng.uniform(-np.pi, np.pi, 200), rng.uniform(-np.pi, np.pi, 200)
    ax, _, az = m.alpha(b, g)
    # Direct evaluation of Li's Fourier form from the published table, in N/cm^3 -> N/m^3.
    t = table
    az_ref = (
        t["A00"] + t["A10"] * np.cos(2 * b) + t["B11"] * np.sin(2 * b + g) + t["B01"] * np.sin(g)
        + t["B-11"] * np.sin(-2 * b + g)
    ) * 1e6  # fmt: skip
    ax_ref = (
        t["C11"] * np.cos(2 * b + g) + t["C01"] * np.cos(g) + t["C-11"] * np.cos(-2 * b + g)
        + t["D10"] * np.sin(2 * b)
    ) * 1e6  # fmt: skip
    np.testing.assert_allclose(az, az_ref, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(ax, ax_ref, rtol=1e-12, atol=1e-9)
    # Generic-form normalisation: zeta is the table's alpha_z(0, pi/2).
    assert m.zeta == pytest.approx(
        (t["A00"] + t["A10"] + t["B11"] + t["B01"] + t["B-11"]) * 1e6, rel=1e-12
    )


def test_closely_packed_is_stronger_than_loosely_packed():
    lp, cp = mjrft.Material.preset("poppy_seeds_lp"), mjrft.Material.preset("poppy_seeds_cp")
    assert cp.alpha(0.0, np.pi / 2)[2] > lp.alpha(0.0, np.pi / 2)[2]


@pytest.mark.filterwarnings("ignore::mjrft.core.material.MaterialWarning")  # a stand-in model
def test_from_callables_default_alpha_y():
    m = mjrft.Material.from_callables(
        lambda b, g: 0.2 + 0 * b + 0.1 * np.cos(g), lambda b, g: 1 + 0 * b, 1e5
    )
    assert m.alpha_y0 == pytest.approx(0.3)
    _, ay, _ = m.alpha_generic(np.array([0.5]), np.array([0.2]))
    assert ay[0] == pytest.approx(0.3)


def ok(b, g):
    return np.cos(b) + np.sin(g)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: mjrft.Material.generic(-1.0), "zeta must be a finite number > 0"),
        (lambda: mjrft.Material.generic(0.0), "zeta must be a finite number > 0"),
        (lambda: mjrft.Material.generic(float("nan")), "zeta"),
        (lambda: mjrft.Material.generic(float("inf")), "zeta"),
        (lambda: mjrft.Material.generic("sand"), "zeta"),
        (lambda: mjrft.Material.generic(zeta_n_per_cm3=-0.3), "N/cm\\^3"),
        (lambda: mjrft.Material.generic(1.0, zeta_n_per_cm3=1.0), "exactly one"),
        (lambda: mjrft.Material.preset("sand"), "unknown material preset 'sand'.*glass_beads"),
        (lambda: mjrft.Material.from_callables(ok, ok, -5.0), "zeta"),
        (lambda: mjrft.Material.from_callables(42, ok, 3e5), "alpha_x.*callable"),
        (lambda: mjrft.Material.from_callables(ok, lambda b, g: 1.0, 3e5), "alpha_z.*shape"),
        (
            lambda: mjrft.Material.from_callables(
                ok, lambda b, g: np.where(g > 3, np.nan, 1 + 0 * b), 3e5
            ),
            "alpha_z.*non-finite",
        ),
        (
            lambda: mjrft.Material.from_callables(ok, ok, 3e5, alpha_y=lambda b: b[:3]),
            "alpha_y.*shape",
        ),
        (
            lambda: mjrft.Material.from_callables(lambda b, g: float(b), ok, 3e5),
            "alpha_x.*raised TypeError.*numpy.vectorize",
        ),
        (lambda: mjrft.Material.from_table({"A00": 1.0, "Q12": 2.0}), "'Q12'"),
        (lambda: mjrft.Material.from_table({"A00": 1.0, "A20": 2.0}), "'A20'"),
        (lambda: mjrft.Material.from_table({"A00": float("nan")}), "A00.*not finite"),
        (lambda: mjrft.Material.from_table({"A00": -1.0}), "must be > 0"),
    ],
)
def test_bad_material_input(make, match):
    with pytest.raises(ValueError, match=match):
        make()
