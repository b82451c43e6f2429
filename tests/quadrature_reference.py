"""Slow, plainly written reference of the kernel's surface quadrature (mjrft.core.quadrature).

One element at a time in Python: the same one-point rule and the same clipping of the
submerged, leading part of a triangle as the engine's kernel (engine/kernel.cc, BodyWrench),
with the forces from the NumPy evaluation ``mjrft.core.rft.numpy_forces``. Any surface given as
a depth function.
"""

from __future__ import annotations

import numpy as np

from mjrft.core import quadrature
from mjrft.core.elements import ElementSet
from mjrft.core.law import LEADING_SLACK
from mjrft.core.rft import numpy_forces


def one_point(elements):
    """The chord facets of elements, evaluated by the one-point rule alone (facet normals and
    areas, nothing clipped): the quadrature mjrft.core.quadrature replaced, for comparisons."""
    facets = ElementSet.from_triangles(elements.vertices, elements.faces)
    n = len(facets)
    object.__setattr__(facets, "quadrature", (np.zeros(n), np.zeros((n, quadrature.PATCH_SIZE))))
    return facets


def clip(poly: list[np.ndarray], value: np.ndarray) -> list[np.ndarray]:
    """The part of a polygon (barycentric points, (3,) each) where the linear function with
    corner values value (3,) is >= 0 (Sutherland-Hodgman against one half-plane)."""
    out = []
    for a, b in zip(poly, poly[1:] + poly[:1], strict=True):
        fa, fb = a @ value, b @ value
        if fa >= 0.0:
            out.append(a)
        if (fa >= 0.0) != (fb >= 0.0):
            out.append(a + (b - a) * (fa / (fa - fb)))
    return out


def clipped_part(depth: np.ndarray, lead: np.ndarray, area: float):
    """(W, lam) of the part of a triangle with depth >= 0 and lead >= 0 (corner values (3,),
    both linear): W = integral of depth over it [m^3], lam its depth-weighted centroid in
    barycentric coordinates (None if W = 0)."""
    poly = clip(clip(list(np.eye(3)), depth), lead)
    w, m = 0.0, np.zeros(3)
    for k in range(1, len(poly) - 1):
        a, b, c = poly[0], poly[k], poly[k + 1]
        frac = abs((b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]))
        d = np.array([a @ depth, b @ depth, c @ depth])
        w += frac * area * d.sum() / 3.0
        m += frac * area / 12.0 * (d.sum() * (a + b + c) + d[0] * a + d[1] * b + d[2] * c)
    return (w, m / w) if w > 0.0 else (0.0, None)


def element_forces(
    centroids, normals, areas, reach, patch, rot, origin, omega, v_ref, p_ref, material,
    depth_of, region=None,
):  # fmt: skip
    """(forces (n, 3) [N], points (n, 3) [m]): each element's RFT force and where it acts
    (its centroid, or its clipped part's depth-weighted centroid), world frame.

    Elements (body frame) as ``mjrft.core.quadrature``; the body at rot (3, 3) body -> world
    and origin (3,), moving with omega (3,) and v_ref (3,) at the world point p_ref (3,);
    depth_of(points (k, 3)) -> (k,) resisting depths [m]; region (2, 3) world box or None.
    """
    rot = np.asarray(rot, float)
    omega, v_ref, p_ref = (np.asarray(x, float) for x in (omega, v_ref, p_ref))
    n_el = len(areas)
    c = np.asarray(centroids) @ rot.T + origin
    n = np.asarray(normals) @ rot.T
    v = v_ref + np.cross(omega, c - p_ref)
    depth_c = depth_of(c)
    band = quadrature.UNEVEN_REACH * reach
    wet = depth_c > -band
    if region is not None:
        wet &= np.all((c >= region[0]) & (c <= region[1]), axis=1)
    # Every wet element is clipped here, with no bound deciding which need it: one that nothing
    # clips, beyond the band, comes out as the one-point rule (to round-off), so the kernel's
    # bounds are checked, not copied.
    points, normal, vel, weight = c.copy(), n.copy(), v.copy(), np.zeros(n_el)
    for i in np.flatnonzero(wet):
        corners = c[i] + patch[i, :9].reshape(3, 3) @ rot.T
        cn = patch[i, 9:18].reshape(3, 3) @ rot.T
        vc = v_ref + np.cross(omega, corners - p_ref)
        d = depth_of(corners)
        # A corner leads iff n . v > LEADING_SLACK |v| (docs/design.md 2.1).
        lead = np.einsum("ij,ij->i", cn, vc) - LEADING_SLACK * np.linalg.norm(vc, axis=1)
        w, lam = clipped_part(d, lead, areas[i])
        if w > 0.0:
            x, nn = lam @ corners, lam @ cn
            # blended into the one-point rule's values, fully at the band's edge
            ramp = min(1.0, max(0.0, d.mean() / band[i])) if band[i] > 0 else 1.0
            if ramp > 0.0:
                whole = (d.sum() + d) / (4.0 * d.sum())  # the whole triangle's weighted centroid
                x = x + ramp * (c[i] - whole @ corners)
                nn = nn + ramp * (n[i] - whole @ cn)
                w += ramp * areas[i] * (depth_c[i] - d.mean())
            if w > 0.0:
                points[i] = x
                normal[i] = nn / np.linalg.norm(nn)
                vel[i] = v_ref + np.cross(omega, points[i] - p_ref)
                weight[i] = w
    pos = points.copy()
    pos[:, 2] = -1.0  # depth 1 below a surface at 0: the weight W stands for the area
    f = numpy_forces(pos, normal, weight, vel, material, 0.0)
    f[weight <= 0.0] = 0.0
    assert f.shape == (n_el, 3)
    return f, points


def body_wrench(elements, position, rotation, lin_vel, ang_vel, material, point, surface_z=0.0):
    """(force (3,) [N], moment (3,) [N m] about point) on a body, world frame; arguments as
    ``mjrft.body.body_wrench`` (rotation a (3, 3) matrix, lin_vel the origin's velocity)."""
    reach, patch = quadrature.element_patches(elements)
    f, x = element_forces(
        elements.centroids, elements.normals, elements.areas, reach, patch, rotation,
        np.asarray(position, float), ang_vel, lin_vel, position, material,
        lambda p: surface_z - p[..., 2],
    )  # fmt: skip
    return f.sum(axis=0), np.cross(x - np.asarray(point), f).sum(axis=0)
