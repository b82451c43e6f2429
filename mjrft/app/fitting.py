"""``mjrft fit``: plate intrusion data (CSV) -> a fitted medium, its MJCF, JSON and residual plot.

The CSV has a header row and one row per plate (docs/materials.md, "Fit your own medium"):
``beta_deg, gamma_deg, depth_m, area_m2, fx_N, fz_N`` (angles as in docs/design.md 2.4; the
plate moves in the x-z plane with its horizontal motion along +x; forces are world components on
the plate, z up). Optional yawed plates: with columns ``yaw_deg`` and ``fy_N`` (the motion
turned out of the x-z plane towards +y by the yaw, ``mjrft.core.fit.YawedPlateData``), the rows
at yaw 0 give the in-plane coefficients and the others the out-of-plane coefficient
alpha_y(beta) and the scaling functions f1, f23 (``fit_yawed``). Other columns are ignored.
A row that repeats an earlier one in every column read is refused, naming the file and the rows
(``mjrft.core.fit``'s docstring says why).
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import numpy as np

from mjrft.core.fit import (
    SETS,
    Fit,
    FitError,
    PlateData,
    YawedPlateData,
    YawFit,
    basis,
    fit,
    repeated_rows,
    repeats_message,
)
from mjrft.core.units import N_PER_CM3
from mjrft.field.scene import COEFFICIENT_ORDER

COLUMNS = ("beta_deg", "gamma_deg", "depth_m", "area_m2", "fx_N", "fz_N")
YAW_COLUMNS = ("yaw_deg", "fy_N")
DEG = np.pi / 180.0  # rad per degree: the CSV gives angles in degrees


def read_csv(path: str | os.PathLike) -> PlateData:
    """PlateData from a CSV of COLUMNS (its rows at yaw 0 if it has YAW_COLUMNS); raises
    FitError naming the file, row and column."""
    return read_plates(path)[0]


def read_plates(path: str | os.PathLike) -> tuple[PlateData, YawedPlateData | None]:
    """(the in-plane plates, the yawed plates or None) of one reading of the CSV: without
    YAW_COLUMNS every row is in-plane; with them, the rows at yaw 0 and the others."""
    values, yawed = _read(Path(path))
    flat = np.ones(len(values), dtype=bool) if yawed is None else yawed[:, 0] == 0.0
    beta_deg, gamma_deg, depth, area, fx, fz = values.T
    beta, gamma = beta_deg * DEG, gamma_deg * DEG
    plates = PlateData(beta[flat], gamma[flat], depth[flat], area[flat], fx[flat], fz[flat])
    if flat.all():
        return plates, None
    on = ~flat
    return plates, YawedPlateData(beta[on], gamma[on], yawed[on, 0] * DEG, depth[on], area[on],
                                  fx[on], yawed[on, 1], fz[on])  # fmt: skip


def _read(p: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """(rows x COLUMNS, rows x YAW_COLUMNS or None) of the CSV, as numbers."""
    try:
        with open(p, newline="") as fh:
            reader = csv.DictReader(fh)
            header = reader.fieldnames or []
            missing = [c for c in COLUMNS if c not in header]
            if missing:
                raise FitError(
                    f"{p}: missing column(s) {', '.join(missing)}; expected {', '.join(COLUMNS)}"
                )
            yaw = [c for c in YAW_COLUMNS if c in header]
            if len(yaw) == 1:
                other = next(c for c in YAW_COLUMNS if c not in header)
                raise FitError(f"{p}: column {yaw[0]} needs column {other} (yawed plates)")
            rows = list(reader)
    except OSError as exc:
        raise FitError(f"cannot read {p}: {exc.strerror}") from None
    columns = COLUMNS + (YAW_COLUMNS if yaw else ())
    values = np.empty((len(rows), len(columns)))
    for i, row in enumerate(rows):
        for j, c in enumerate(columns):
            try:
                values[i, j] = float(row[c])
            except (TypeError, ValueError):
                raise FitError(
                    f"{p}: row {i + 2}, column {c}: {row[c]!r} is not a number"
                ) from None
    pairs = repeated_rows(values)
    if pairs:
        raise FitError(repeats_message(pairs, str(p), offset=2))  # the CSV's line numbers
    n = len(COLUMNS)
    return values[:, :n], (values[:, n:] if yaw else None)


def choose(data: PlateData, order: str) -> Fit:
    """Fit with `order` ('first', 'full', or 'auto': the full set where the data determine it
    with at least three plates per coefficient, else the first-order set)."""
    if order != "auto":
        return fit(data, order)
    if len(data.beta) >= 3 * 9:
        try:
            return fit(data, "full")
        except FitError:
            pass
    return fit(data, "first")


def mjcf(result: Fit) -> str:
    """The fitted medium as MJCF ``<custom>`` elements (first-order set), else a comment saying
    how to build it in Python."""
    m = result.material
    if result.order == "first":
        generic = m.fourier.as_mapping()
        values = " ".join(f"{generic.get(k, 0.0):.10g}" for k in COEFFICIENT_ORDER)
        return (
            f'<numeric name="mjrft:zeta" data="{m.zeta:.10g}"/>\n'
            f'<numeric name="mjrft:coefficients" data="{values}"/>\n'
        )
    table = ", ".join(f'"{k}": {v:.6g}' for k, v in result.coefficients.items())
    return (
        "<!-- the full coefficient set has no MJCF form; in Python:\n"
        f"     Material.from_table({{{table}}}, unit=1.0)  (N/m^3) -->\n"
    )


def yaw_summary(result: YawFit) -> dict:
    """JSON-ready description of a yawed-plate fit: alpha_y(beta) terms [N/m^3] and the f1, f23
    shape parameters with 95 % intervals, and the kernel's values of the latter."""
    from mjrft.core import law

    kernel = {"f1_slope": law.F1_SLOPE, "f1_shift": law.F1_SHIFT, "f23_slope": law.F23_SLOPE,
              "f23_shift": law.F23_SHIFT}  # fmt: skip
    return {
        "plates": result.n,
        "alpha_y": "ay0 + ay_cos2b cos(2 beta) + ay_sin2b sin(2 beta) [N/m^3]",
        "values": {k: _entry(result, k, kernel.get(k)) for k in result.values},
        "residual_rms_N": result.rms,
        "note": "the compiled kernel uses Treers et al.'s f1 and f23 (mjrft.core.law) and a "
        "constant alpha_y; Material(alpha_y0=ay0 / zeta) takes the fitted constant",
    }


def _entry(result: YawFit, name: str, kernel: float | None) -> dict:
    entry = {"value": result.values[name], "standard_error": result.standard_errors[name],
             "ci95": list(result.interval(name))}  # fmt: skip
    return entry | ({"kernel": kernel} if kernel is not None else {})


def summary(result: Fit) -> dict:
    """JSON-ready description: coefficients [N/m^3 and N/cm^3] with 95 % intervals, RMS."""
    return {
        "order": result.order,
        "plates": result.n,
        "zeta_N_per_m3": result.material.zeta,
        "coefficients_N_per_m3": {
            k: {
                "value": v,
                "standard_error": result.standard_errors[k],
                "ci95": list(result.interval(k)),
            }
            for k, v in result.coefficients.items()
        },
        "coefficients_N_per_cm3": {k: v / N_PER_CM3 for k, v in result.coefficients.items()},
        "residual_rms_N": result.rms,
    }


def plot_residuals(data: PlateData, result: Fit, path: Path) -> Path:
    """PNG: measured against fitted force of each component, and the residuals against beta."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(9, 7), constrained_layout=True)
    scale = data.depth * data.area
    for row, (component, measured, sign) in enumerate((("z", data.fz, 1.0), ("x", data.fx, -1.0))):
        names = SETS[result.order][component]
        coef = np.array([result.coefficients[k] for k in names])
        model = sign * scale * (basis(names, component, data.beta, data.gamma) @ coef)
        ax = axes[row, 0]
        ax.plot(model, measured, ".", ms=4)
        lim = [min(model.min(), measured.min()), max(model.max(), measured.max())]
        ax.plot(lim, lim, "k-", lw=0.8)
        ax.set(xlabel=f"fitted F_{component} [N]", ylabel=f"measured F_{component} [N]",
               title=f"F_{component}: RMS residual {result.rms[component]:.3g} N")  # fmt: skip
        ax = axes[row, 1]
        ax.scatter(np.degrees(data.beta), measured - model, c=np.degrees(data.gamma), s=8)
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set(xlabel="attack angle beta [deg] (colour: gamma)",
               ylabel=f"residual F_{component} [N]")  # fmt: skip
    fig.suptitle(f"mjrft fit: {result.n} plates, {result.order}-order set, "
                 f"zeta = {result.material.zeta / N_PER_CM3:.4g} N/cm^3")  # fmt: skip
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_outputs(
    data: PlateData, result: Fit, out: Path, yawed: YawFit | None = None
) -> list[Path]:
    """material.xml, fit.json (with the yawed-plate fit, if given) and residuals.png in out."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "material.xml").write_text(mjcf(result))
    record = summary(result) | ({"yawed": yaw_summary(yawed)} if yawed is not None else {})
    (out / "fit.json").write_text(json.dumps(record, indent=2) + "\n")
    return [
        out / "material.xml",
        out / "fit.json",
        plot_residuals(data, result, out / "residuals.png"),
    ]
