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

Rows that repeat an earlier row in every column (angles, depth, area and forces) are refused,
naming them (``repeated_rows``): such a row is the same measurement counted again (a file
concatenated twice, rows pasted twice), and k copies would narrow every interval by 1/sqrt(k)
with no new information. Refusing, not dropping, because a copy means the data are not what their
author believes, which only the author can mend. Replicates, plates at the same angles, depth and
area with their own measured forces, are independent measurements and are fitted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mjrft.core.law import HORIZONTAL_PLATE_NZ
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


def _columns(data, label: str) -> dict[str, np.ndarray]:
    """The data's columns as float arrays, checked to be (n,) of one length and finite."""
    arrays = {f: np.asarray(getattr(data, f), dtype=float) for f in type(data).__dataclass_fields__}
    n = {a.shape for a in arrays.values()}
    if len(n) != 1 or len(next(iter(n))) != 1:
        raise FitError(f"{label} must be (n,) arrays of one length, got shapes {sorted(n)}")
    for f, a in arrays.items():
        if not np.all(np.isfinite(a)):
            raise FitError(f"{label} column {f} has non-finite values (row {_first(a)})")
    pairs = repeated_rows(np.stack(list(arrays.values()), axis=1))
    if pairs:
        raise FitError(repeats_message(pairs, label))
    return arrays


def repeated_rows(values: np.ndarray) -> list[tuple[int, int]]:
    """(row, earlier row) of every row of the (n, columns) `values` equal to an earlier one in
    every column (module docstring)."""
    first: dict[tuple[float, ...], int] = {}
    pairs = []
    for i, row in enumerate(np.asarray(values, dtype=float).tolist()):
        j = first.setdefault(tuple(row), i)
        if j != i:
            pairs.append((i, j))
    return pairs


def repeats_message(pairs: list[tuple[int, int]], label: str, offset: int = 0) -> str:
    """The refusal of the repeated `pairs` (``repeated_rows``) of `label`, rows numbered from
    `offset`."""
    shown = ", ".join(f"row {i + offset} = row {j + offset}" for i, j in pairs[:5])
    more = f" and {len(pairs) - 5} more" if len(pairs) > 5 else ""
    return (
        f"{label}: {len(pairs)} row(s) repeat an earlier row in every column ({shown}{more}): "
        "the same measurement counted twice narrows the 95 % intervals with no new information; "
        "remove the repeats (replicates with their own measured forces are kept)"
    )


def _check(data: PlateData) -> None:
    arrays = _columns(data, "plate data")
    for f in ("depth", "area"):
        bad = np.flatnonzero(arrays[f] <= 0)
        if bad.size:
            raise FitError(f"plate data column {f} must be > 0 (row {bad[0]}: {arrays[f][bad[0]]})")


def _first(a: np.ndarray) -> int:
    return int(np.flatnonzero(~np.isfinite(a))[0])


# --------------------------------------------------------------------------------------------
# Yawed plates: the out-of-plane coefficient alpha_y(beta) and the scaling functions f1, f23
# --------------------------------------------------------------------------------------------

#: alpha_y(beta) = sum of these terms' coefficients times 1, cos 2 beta, sin 2 beta.
ALPHA_Y_TERMS = ("ay0", "ay_cos2b", "ay_sin2b")
#: The shape parameters of f1 and f23 (mjrft.core.law): slope and shift each, the gain fixed by
#: f(1) = 1 (f(0) = 0 holds for any slope and shift).
SCALING_PARAMETERS = ("f1_slope", "f1_shift", "f23_slope", "f23_shift")
#: Gauss-Newton (Levenberg-damped) on the scaling parameters: iterations and the relative step
#: below which it has converged.
_GN_ITERATIONS, _GN_RTOL = 100, 1e-12


@dataclass(frozen=True)
class YawedPlateData:
    """Yawed plate measurements, (n,) arrays: the in-plane angles beta, gamma [rad] of
    ``PlateData``, the yaw psi [rad] (the motion turned out of the x-z plane towards +y:
    v = cos psi (cos gamma, 0, -sin gamma) + sin psi (0, 1, 0)), depth [m], area [m^2] and
    the world force components fx, fy, fz [N]."""

    beta: np.ndarray
    gamma: np.ndarray
    psi: np.ndarray
    depth: np.ndarray
    area: np.ndarray
    fx: np.ndarray
    fy: np.ndarray
    fz: np.ndarray


@dataclass(frozen=True)
class YawFit:
    """alpha_y(beta) [N/m^3] coefficients (``ALPHA_Y_TERMS``) and the f1 / f23 shape parameters
    (``SCALING_PARAMETERS``), their standard errors, residual RMS per component [N], plates."""

    values: dict[str, float]
    standard_errors: dict[str, float]
    rms: dict[str, float]
    n: int

    def interval(self, name: str, z: float = Z95) -> tuple[float, float]:
        """(low, high) of `name` at z standard errors (default 95 %)."""
        c, se = self.values[name], self.standard_errors[name]
        return c - z * se, c + z * se

    def alpha_y(self, beta) -> np.ndarray:
        """The fitted alpha_y [N/m^3] at attack angles beta [rad]."""
        b = np.asarray(beta, dtype=float)
        v = self.values
        return v["ay0"] + v["ay_cos2b"] * np.cos(2 * b) + v["ay_sin2b"] * np.sin(2 * b)


def scaling(u, slope: float, shift: float, inverse_tanh: bool) -> np.ndarray:
    """g(u) = (h(slope u - shift) + h(shift)) / (h(slope - shift) + h(shift)), h = tanh (f1)
    or atanh (f23): the form of mjrft.core.law's f1, f23 with the gain that makes g(1) = 1."""
    h = np.arctanh if inverse_tanh else np.tanh
    u = np.asarray(u, dtype=float)
    return (h(slope * u - shift) + h(shift)) / (h(slope - shift) + h(shift))


def fit_yawed(data: YawedPlateData, in_plane: Fit, start: dict[str, float] | None = None) -> YawFit:
    """alpha_y(beta) and f1, f23 from yawed plates (Treers et al. 2021, docs/design.md 2.8):
    F_x, F_z = f23(|cos psi|) times the in-plane fit's force at (beta, gamma), and F_y =
    -sign(psi) f1(|sin psi|) alpha_y(beta) d A. Nonlinear least squares (Levenberg-damped
    Gauss-Newton from `start`, by default mjrft.core.law's values; alpha_y solved linearly
    inside); plates within 2.6 deg of horizontal are left out. Raises FitError if the yaws or
    attack angles cannot determine the parameters."""
    from mjrft.core import law

    columns = _check_yawed(data)
    # A nearly horizontal plate (|n_z| = |cos beta|) takes its frame from the motion
    # (docs/design.md 2.2), not from the plate: left out.
    keep = np.abs(np.cos(columns["beta"])) < HORIZONTAL_PLATE_NZ
    data = YawedPlateData(**{f: a[keep] for f, a in columns.items()})
    s, c = np.abs(np.sin(data.psi)), np.abs(np.cos(data.psi))
    da = data.depth * data.area
    names_x, names_z = SETS[in_plane.order]["x"], SETS[in_plane.order]["z"]
    cx = np.array([in_plane.coefficients[k] for k in names_x])
    cz = np.array([in_plane.coefficients[k] for k in names_z])
    fx0 = -da * (basis(names_x, "x", data.beta, data.gamma) @ cx)
    fz0 = da * (basis(names_z, "z", data.beta, data.gamma) @ cz)
    cols = -np.sign(data.psi)[:, None] * (da[:, None] * _alpha_y_basis(data.beta))

    def f23_residual(p):
        g = scaling(c, p[0], p[1], inverse_tanh=True)
        return np.concatenate([data.fx - g * fx0, data.fz - g * fz0])

    def f1_residual(p):  # alpha_y projected out: linear in it for given f1
        x = scaling(s, p[0], p[1], inverse_tanh=False)[:, None] * cols
        coef = np.linalg.lstsq(x, data.fy, rcond=None)[0]
        return data.fy - x @ coef

    begin = {"f1_slope": law.F1_SLOPE, "f1_shift": law.F1_SHIFT, "f23_slope": law.F23_SLOPE,
             "f23_shift": law.F23_SHIFT} | (start or {})  # fmt: skip
    p23 = _gauss_newton(f23_residual, (begin["f23_slope"], begin["f23_shift"]), "f23")
    se23, r23 = _standard_errors(f23_residual, p23)
    p1 = _gauss_newton(f1_residual, (begin["f1_slope"], begin["f1_shift"]), "f1")
    x = scaling(s, p1[0], p1[1], inverse_tanh=False)[:, None] * cols
    ay, _, rms_y = _least_squares(x, data.fy, ALPHA_Y_TERMS, data)

    def fy_residual(q):  # alpha_y and f1 together, for their joint standard errors
        return data.fy - scaling(s, q[3], q[4], inverse_tanh=False) * (cols @ q[:3])

    se_joint, _ = _standard_errors(fy_residual, np.array([*ay.values(), *p1]))
    values = dict(ay) | dict(zip(SCALING_PARAMETERS, map(float, [*p1, *p23]), strict=True))
    errors = dict(zip(ALPHA_Y_TERMS + SCALING_PARAMETERS,
                      map(float, [*se_joint, *se23]), strict=True))  # fmt: skip
    n = len(data.psi)
    rx, rz = r23[:n], r23[n:]
    rms = {"x": math.sqrt(float(rx @ rx) / n), "y": rms_y, "z": math.sqrt(float(rz @ rz) / n)}
    return YawFit(values, errors, rms, n)


def _alpha_y_basis(beta: np.ndarray) -> np.ndarray:
    return np.stack([np.ones_like(beta), np.cos(2 * beta), np.sin(2 * beta)], axis=1)


def _gauss_newton(residual, start, label: str) -> np.ndarray:
    """The two shape parameters of `label` minimising |residual(p)|^2, from `start`."""
    p = np.array(start, dtype=float)
    r = residual(p)
    lam = 1e-3
    for _ in range(_GN_ITERATIONS):
        jac = _jacobian(residual, p, r)
        jtj, g = jac.T @ jac, jac.T @ r
        step = np.linalg.solve(jtj + lam * np.diag(np.diag(jtj)), -g)
        trial = p + step
        rt = residual(trial) if _valid(trial, label) else None
        if rt is not None and np.all(np.isfinite(rt)) and rt @ rt <= r @ r:
            p, r, lam = trial, rt, lam / 10.0
            if np.all(np.abs(step) <= _GN_RTOL * np.maximum(np.abs(p), 1.0)):
                break
        else:
            lam *= 10.0
            if lam > 1e12:
                break
    return p


def _standard_errors(residual, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(standard errors of p, residual at p): normal theory from the Jacobian at p, the
    residual variance over len(r) - len(p) degrees of freedom."""
    r = residual(p)
    jac = _jacobian(residual, p, r)
    cov = np.linalg.pinv(jac.T @ jac) * float(r @ r) / max(1, len(r) - len(p))
    return np.sqrt(np.maximum(np.diag(cov), 0.0)), r


def _valid(p: np.ndarray, label: str) -> bool:
    """f23's atanh needs |slope u - shift| < 1 on [0, 1]; both need a rising function."""
    if p[0] <= 0.0:
        return False
    return label != "f23" or (abs(p[1]) < 1.0 and abs(p[0] - p[1]) < 1.0)


def _jacobian(residual, p: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Central differences (the residuals are smooth in the shape parameters)."""
    jac = np.empty((len(r), len(p)))
    for k in range(len(p)):
        h = 1e-6 * max(1.0, abs(p[k]))
        up, down = p.copy(), p.copy()
        up[k] += h
        down[k] -= h
        jac[:, k] = (residual(up) - residual(down)) / (2 * h)
    return jac


def _check_yawed(data: YawedPlateData) -> dict[str, np.ndarray]:
    """The data's columns (``_columns``), checked to determine f1, f23 and alpha_y."""
    columns = _columns(data, "yawed plate data")
    if np.any(np.abs(data.psi) >= 0.5 * np.pi):
        bad = int(np.flatnonzero(np.abs(data.psi) >= 0.5 * np.pi)[0])
        raise FitError(f"yaw must be in (-90, 90) deg (row {bad}: {np.degrees(data.psi[bad]):g})")
    yaws = np.unique(np.round(np.abs(np.degrees(data.psi)), 3))
    inside = yaws[(yaws > 0) & (yaws < 90)]
    if inside.size < 3:
        raise FitError(
            f"f1 and f23 need yawed plates at >= 3 distinct |yaw| in (0, 90) deg; the data have "
            f"yaw {_degrees(data.psi)} [deg]"
        )
    tilt = np.abs(np.cos(data.beta)) < HORIZONTAL_PLATE_NZ
    if np.unique(np.round(np.degrees(data.beta[tilt]) % 180, 3)).size < 3:
        raise FitError(
            "alpha_y(beta) needs yawed plates at >= 3 distinct attack angles beta (mod 180 deg) "
            f"away from horizontal; the data have beta {_degrees(data.beta)} [deg]"
        )
    return columns
