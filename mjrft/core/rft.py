"""The 3D granular RFT force kernel: pure functions over element arrays (world frame, SI).

Implements docs/design.md section 2 (Treers, Cao & Stuart, RA-L 2021, on Li et al., Science 2013).
Angles beta and gamma never exist here for Fourier-form media: their sines and cosines are
normalised vector components and the Fourier terms follow from angle-addition identities. User
callables receive explicit angles. Media given by coefficients (``Material.compiled``) are
evaluated by the C++ engine's kernel (``mjrft.core.engine``, engine/kernel.h), the one the MuJoCo
plugin runs; the NumPy evaluation here is its reference and serves media given as callables.
This module imports no mujoco and holds no state.
"""

from __future__ import annotations

import numpy as np

from mjrft.core import engine
from mjrft.core.law import HORIZONTAL_PLATE_NZ, LEADING_SLACK, f1, f23
from mjrft.core.material import HARMONICS, Material, as_material


def _unit_rows(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors and norms of the rows of x (n, 3), free of overflow/underflow for finite x.

    Rows of zero length give a zero vector and norm 0.
    """
    scale = np.abs(x).max(axis=1)
    safe = np.where(scale > 0.0, scale, 1.0)
    y = x / safe[:, None]
    r = np.sqrt(np.einsum("ij,ij->i", y, y))
    u = y / np.where(r > 0.0, r, 1.0)[:, None]
    return u, scale * r


def _as_rows(name: str, x: np.ndarray, n: int | None) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or (n is not None and a.shape[0] != n):
        want = "(n, 3)" if n is None else f"({n}, 3)"
        raise ValueError(f"element_forces: {name} has shape {a.shape}, expected {want}")
    return a


_INPUT_NAMES = {
    engine.BAD_POS: "pos",
    engine.BAD_NORMAL: "normal",
    engine.BAD_AREA: "area",
    engine.BAD_VEL: "vel",
}


def _shaped(pos, normal, area, vel, surface_z):
    """Float64 C arrays of checked shapes, and surface_z checked finite."""
    pos = np.ascontiguousarray(_as_rows("pos", pos, None))
    n = pos.shape[0]
    normal = np.ascontiguousarray(_as_rows("normal", normal, n))
    vel = np.ascontiguousarray(_as_rows("vel", vel, n))
    area = np.ascontiguousarray(area, dtype=np.float64)
    if area.shape != (n,):
        raise ValueError(f"element_forces: area has shape {area.shape}, expected ({n},)")
    surface_z = float(surface_z)
    if not np.isfinite(surface_z):
        raise ValueError(f"element_forces: surface_z must be finite, got {surface_z}")
    return pos, normal, area, vel, surface_z


def _raise_bad(code: int, i: int, pos, normal, area, vel) -> None:
    """ValueError naming element i's bad input (codes of engine.checked_unit_normals)."""
    if code in _INPUT_NAMES:
        name = _INPUT_NAMES[code]
        value = {"pos": pos, "normal": normal, "area": area, "vel": vel}[name][i]
        raise ValueError(f"element_forces: {name} of element {i} is not finite: {value}")
    if code == engine.NEGATIVE_AREA:
        raise ValueError(f"element_forces: area of element {i} is negative ({area[i]}); need >= 0")
    if code == engine.ZERO_NORMAL:
        raise ValueError(f"element_forces: normal of element {i} has zero length")


def element_forces(
    pos: np.ndarray,
    normal: np.ndarray,
    area: np.ndarray,
    vel: np.ndarray,
    material: Material | str,
    surface_z: float = 0.0,
) -> np.ndarray:
    """RFT force on each surface element, world frame.

    Args:
      pos: (n, 3) element centroids, world frame [m]; world z is up.
      normal: (n, 3) outward normals, world frame (any positive length).
      area: (n,) element areas [m^2], >= 0.
      vel: (n, 3) centroid velocities, world frame [m/s].
      material: the medium, or a preset's name (``mjrft.PRESETS``).
      surface_z: height of the free surface [m]; depth = surface_z - z.
    Returns:
      (n, 3) forces, world frame [N]. Zero for elements above the surface, trailing (n . v <= 0)
      or at rest. Finite for every finite input whose force magnitude is representable.
    Raises:
      ValueError on mismatched shapes, non-finite inputs, negative areas, zero-length normals or
      an unknown preset name; TypeError for a material that is neither.

    The checks cost about 1 ns per element (10 % of the evaluation); normals that are not unit
    cost a normalising pass more (about 5 ns). ``unit_normal_forces`` is the same evaluation
    without checks, for arrays you trust.
    """
    material = as_material(material)
    pos, normal, area, vel, surface_z = _shaped(pos, normal, area, vel, surface_z)
    bad, nonunit = engine.input_flags(pos, normal, area, vel)
    n_hat = normal
    if bad or nonunit:  # name the culprit, or normalise (unit normals skip this pass)
        n_hat, code, i = engine.checked_unit_normals(pos, normal, area, vel)
        _raise_bad(code, i, pos, normal, area, vel)
    return unit_normal_forces(pos, n_hat, area, vel, material, surface_z)


def unit_normal_forces(
    pos: np.ndarray,
    n_hat: np.ndarray,
    area: np.ndarray,
    vel: np.ndarray,
    material: Material,
    surface_z: float,
) -> np.ndarray:
    """``element_forces`` without input checks, for callers that guarantee them (the field).

    Args as ``element_forces``, but float64 arrays of matching shapes, all finite, areas >= 0
    and `n_hat` unit normals, world frame.
    """
    if material.compiled:
        out, _ = engine.forces(
            pos, n_hat, area, vel, material.kernel_coefficients, material.alpha_y0,
            material.zeta, surface_z,
        )  # fmt: skip
        return out
    return numpy_forces(pos, n_hat, area, vel, material, surface_z)


def quadrature_forces(rows: np.ndarray, material: Material) -> np.ndarray:
    """(n, 3) forces [N] at the quadrature points of ``engine.body_wrench``'s rows (n, ROW):
    point, unit normal, velocity, weight W = depth x area [m^3], world frame (W = 0: none)."""
    at = rows[:, :3].copy()
    at[:, 2] = -1.0  # depth 1 below a surface at 0: the weight stands for the area
    w = np.ascontiguousarray(rows[:, 9])
    f = unit_normal_forces(
        at, np.ascontiguousarray(rows[:, 3:6]), w, np.ascontiguousarray(rows[:, 6:9]), material,
        0.0,
    )  # fmt: skip
    f[w <= 0.0] = 0.0
    return f


def numpy_forces(
    pos: np.ndarray,
    n_hat: np.ndarray,
    area: np.ndarray,
    vel: np.ndarray,
    material: Material,
    surface_z: float,
) -> np.ndarray:
    """The vectorised NumPy evaluation (any material, callables included); args as
    ``unit_normal_forces``. The engine's kernel is tested against it."""
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    out = np.zeros_like(pos)
    depth = surface_z - pos[:, 2]
    v_hat, speed = _unit_rows(vel)
    # docs/design.md 2.1: only submerged, leading (n . v^ > LEADING_SLACK), moving elements
    # feel force.
    lead = np.einsum("ij,ij->i", n_hat, v_hat) > LEADING_SLACK
    active = (depth > 0.0) & (speed > 0.0) & lead
    idx = np.flatnonzero(active)
    if idx.size == 0:
        return out
    out[idx] = _active_forces(n_hat[idx], v_hat[idx], depth[idx] * area[idx], material)
    return out


def _frame(n_hat: np.ndarray, v_hat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal unit e2 (x, y) of docs/design.md 2.2 for each element; e1 = e2 x z =
    (e2y, -e2x, 0)."""
    nx, ny, nz = n_hat.T
    flat = np.abs(nz) >= HORIZONTAL_PLATE_NZ
    hx = np.where(flat, v_hat[:, 0], nx)
    hy = np.where(flat, v_hat[:, 1], ny)
    h = np.hypot(hx, hy)
    none = h == 0.0  # horizontal plate moving exactly vertically: world x
    hs = np.where(none, 1.0, h)
    return np.where(none, 1.0, hx / hs), np.where(none, 0.0, hy / hs)


def _active_forces(
    n_hat: np.ndarray, v_hat: np.ndarray, depth_area: np.ndarray, material: Material
) -> np.ndarray:
    """Forces [N] on submerged leading elements (unit normals/velocities, depth*area [m^3])."""
    e2x, e2y = _frame(n_hat, v_hat)
    # Components of v^ in the orthonormal frame (e1, e2, z): v^ = a e1 + b e2 + c z.
    a = v_hat[:, 0] * e2y - v_hat[:, 1] * e2x
    b = v_hat[:, 0] * e2x + v_hat[:, 1] * e2y
    c = v_hat[:, 2]
    vt = np.abs(a)
    vn = np.hypot(b, c)
    # Plate direction in the (e2, z) plane; beta = atan2(nz, n2) + pi/2 (docs/design.md 2.4).
    n2 = n_hat[:, 0] * e2x + n_hat[:, 1] * e2y
    nz = n_hat[:, 2]
    rn = np.hypot(n2, nz)
    cos_b, sin_b = -nz / rn, n2 / rn
    # gamma = -atan2(c, b); atan2(0, 0) = 0 gives gamma = 0 when v^ is along e1.
    moving_in_plane = vn > 0.0
    vns = np.where(moving_in_plane, vn, 1.0)
    cos_g = np.where(moving_in_plane, b / vns, 1.0)
    sin_g = np.where(moving_in_plane, -c / vns, 0.0)

    if material.fourier is not None:
        ax, az = _fourier_alphas(material, cos_b, sin_b, cos_g, sin_g)
        if material.alpha_y_fn is None:
            ay = material.alpha_y0
        else:
            ay = material.alpha_y_fn(np.arctan2(nz, n2) + 0.5 * np.pi)
    else:
        beta = np.arctan2(nz, n2) + 0.5 * np.pi
        gamma = -np.arctan2(c, b)
        ax, ay, az = material.alpha_generic(beta, gamma)

    # docs/design.md 2.8: F = zeta d dA [-f1 ay sign(v^.e1) e1 - f23 ax e2 + f23 az z].
    s = material.zeta * depth_area
    g1 = -s * f1(vt) * ay * np.sign(a)
    g23 = s * f23(vn)
    gx = -g23 * ax
    out = np.empty_like(n_hat)
    out[:, 0] = g1 * e2y + gx * e2x
    out[:, 1] = -g1 * e2x + gx * e2y
    out[:, 2] = g23 * az
    return out


def _fourier_alphas(
    material: Material, cos_b: np.ndarray, sin_b: np.ndarray, cos_g: np.ndarray, sin_g: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Generic alpha_x, alpha_z from angle sines/cosines via angle-addition identities."""
    c2b = cos_b * cos_b - sin_b * sin_b
    s2b = 2.0 * sin_b * cos_b
    cos_t = np.empty((len(cos_b), len(HARMONICS)))
    sin_t = np.empty_like(cos_t)
    for k, (m, n) in enumerate(HARMONICS):
        # cos/sin of 2 m beta (m in {-1, 0, 1}) then adding n gamma (n in {0, 1}).
        cm = np.ones_like(c2b) if m == 0 else c2b
        sm = np.zeros_like(s2b) if m == 0 else m * s2b
        if n == 0:
            cos_t[:, k], sin_t[:, k] = cm, sm
        else:
            cos_t[:, k] = cm * cos_g - sm * sin_g
            sin_t[:, k] = sm * cos_g + cm * sin_g
    co = material.fourier
    return cos_t @ co.c + sin_t @ co.d, cos_t @ co.a + sin_t @ co.b
