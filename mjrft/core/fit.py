"""Fit a medium's 2D RFT coefficients (Li, Zhang & Goldman 2013) to plate intrusion data.

Each measurement is a small plate of area A at depth d, attack angle beta, moving in the x-z
plane along the intrusion angle gamma (the angles of docs/design.md 2.4, gamma in [-pi/2, pi/2]:
the horizontal part of the motion is along +x, gamma = pi/2 is straight down), with the world
force components F_x, F_z (z up) it felt. RFT says F_z = alpha_z d A and F_x = -alpha_x d A
(alpha_x > 0 resists the motion), and alpha is linear in the Fourier coefficients, so each
component is an ordinary least-squares problem in F (the noise is in the force, not in alpha):
F_z = d A sum_j a_j phi_j(beta, gamma), one column per coefficient, phi_j the Fourier term
(``mjrft.core.material.FourierCoefficients`` with that coefficient alone set to 1).

Two coefficient sets:

* ``FIRST_ORDER``: the nine terms of Li's generic set (A00 A10 B11 B01 B-11 / C11 C01 C-11 D10),
  the set ``mjrft:coefficients`` takes;
* ``FULL``: every term the data can tell apart, nine per component. cos(2 m beta + n gamma)
  with m = -1 and m = 1 coincide when n = 0, so the full set is A00 A10 B10 A01 B01 A-11 A11
  B-11 B11 (and C, D alike).

Confidence intervals are the normal-theory ones, coefficient +- z se, se from the residual
variance times (X^T X)^-1 (X the design matrix); Z95 for 95 %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mjrft.core.material import FourierCoefficients, Material

FIRST_ORDER = {
    "z": ("A00", "A10", "B11", "B01", "B-11"),
    "x": ("C11", "C01", "C-11", "D10"),
}
FULL = {
    "z": ("A00", "A10", "B10", "A01", "B01", "A-11", "A11", "B-11", "B11"),
    "x": ("C00", "C10", "D10", "C01", "D01", "C-11", "C11", "D-11", "D11"),
}
SETS = {"first": FIRST_ORDER, "full": FULL}
#: Two-sided 95 % quantile of the normal distribution.
Z95 = 1.959963984540054
#: Relative singular-value threshold below which the data do not determine a combination.
RANK_RTOL = 1e-9


class FitError(ValueError):
    """The data cannot determine the coefficients (or are malformed); the message says why."""


@dataclass(frozen=True)
class PlateData:
    """Plate measurements, (n,) arrays: beta, gamma [rad], depth [m], area [m^2], and the world
    force components fx, fz [N] (module docstring)."""

    beta: np.ndarray
    gamma: np.ndarray
    depth: np.ndarray
    area: np.ndarray
    fx: np.ndarray
    fz: np.ndarray


@dataclass(frozen=True)
class Fit:
    """A fitted medium: dimensional coefficients [N/m^3] by name, their standard errors, the
    residual RMS of each component [N], the coefficient set and the Material they make."""

    order: str
    coefficients: dict[str, float]
    standard_errors: dict[str, float]
    rms: dict[str, float]
    n: int
    material: Material

    def interval(self, name: str, z: float = Z95) -> tuple[float, float]:
        """(low, high) of coefficient `name` [N/m^3] at z standard errors (default 95 %)."""
        c, se = self.coefficients[name], self.standard_errors[name]
        return c - z * se, c + z * se


def basis(names: tuple[str, ...], component: str, beta, gamma) -> np.ndarray:
    """(n, len(names)) Fourier terms of alpha_`component` ('x' or 'z') at the angles [rad]."""
    cols = []
    for name in names:
        unit = FourierCoefficients.from_mapping({name: 1.0})
        cols.append(unit.alpha_z(beta, gamma) if component == "z" else unit.alpha_x(beta, gamma))
    return np.stack(cols, axis=1)


def fit(data: PlateData, order: str = "first", name: str = "fitted") -> Fit:
    """Least-squares coefficients of both components from plate data; raises FitError if the
    angles cannot determine them (naming what is missing) or the result would not resist every
    motion (naming where)."""
    _check(data)
    if order not in SETS:
        raise FitError(f"order must be one of {', '.join(SETS)}, got {order!r}")
    coefficients, errors, rms = {}, {}, {}
    for component, force in (("z", data.fz), ("x", -data.fx)):
        names = SETS[order][component]
        x = (data.depth * data.area)[:, None] * basis(names, component, data.beta, data.gamma)
        c, se, r = _least_squares(x, force, names, data)
        coefficients.update(c)
        errors.update(se)
        rms[component] = r
    try:
        material = Material.from_table(coefficients, unit=1.0, name=name)
    except ValueError as exc:
        raise FitError(f"the fitted coefficients do not make a medium: {exc}") from None
    return Fit(order, coefficients, errors, rms, len(data.beta), material)


def _least_squares(x, force, names, data):
    """Coefficients, standard errors by name and the residual RMS of one component."""
    n, p = x.shape
    if n <= p:
        raise FitError(f"{n} plates cannot determine {p} coefficients ({', '.join(names)})")
    u, s, vt = np.linalg.svd(x, full_matrices=False)
    weak = s < RANK_RTOL * s[0] if s[0] > 0 else np.ones(p, dtype=bool)
    if np.any(weak):
        # The undetermined combinations: the right singular vectors of the small values.
        null = np.abs(vt[weak]).max(axis=0)
        which = [nm for nm, v in zip(names, null, strict=True) if v > 1e-3]
        raise FitError(
            f"the angles cannot separate {', '.join(which)}: the data have beta "
            f"{_degrees(data.beta)} and gamma {_degrees(data.gamma)} [deg]; add plates at "
            "other attack angles beta (at least 3 distinct, mod 180) and intrusion angles gamma "
            "(at least 3 distinct, not only straight down)"
        )
    coef = vt.T @ ((u.T @ force) / s)
    resid = force - x @ coef
    sigma2 = float(resid @ resid) / (n - p)
    cov = (vt.T / s**2) @ vt * sigma2
    rms = math.sqrt(float(resid @ resid) / n)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return (
        dict(zip(names, coef.tolist(), strict=True)),
        dict(zip(names, se.tolist(), strict=True)),
        rms,
    )


def _degrees(angles: np.ndarray) -> str:
    values = np.unique(np.round(np.degrees(angles), 3))
    shown = ", ".join(f"{v:g}" for v in values[:12])
    return f"{{{shown}{', ...' if len(values) > 12 else ''}}}"


def _check(data: PlateData) -> None:
    arrays = {f: np.asarray(getattr(data, f), dtype=float) for f in PlateData.__dataclass_fields__}
    n = {a.shape for a in arrays.values()}
    if len(n) != 1 or len(next(iter(n))) != 1:
        raise FitError(f"plate data must be (n,) arrays of one length, got shapes {sorted(n)}")
    for f, a in arrays.items():
        if not np.all(np.isfinite(a)):
            raise FitError(f"plate data column {f} has non-finite values (row {_first(a)})")
    for f in ("depth", "area"):
        bad = np.flatnonzero(arrays[f] <= 0)
        if bad.size:
            raise FitError(f"plate data column {f} must be > 0 (row {bad[0]}: {arrays[f][bad[0]]})")


def _first(a: np.ndarray) -> int:
    return int(np.flatnonzero(~np.isfinite(a))[0])
