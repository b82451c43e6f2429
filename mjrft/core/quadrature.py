"""Per-element data of the surface quadrature: each triangle's corners and corner normals.

The kernel (``mjrft.core.engine.body_wrench``) evaluates an element at its centroid with its
patch's normal and area, as a one-point rule, except where that rule is first order: where
the free surface crosses the triangle, or where the leading boundary n . v = 0 does. There it
integrates over the part of the triangle that is both submerged and leading, with depth and
n . v interpolated linearly from the corners (depth is exactly linear on a flat triangle
under a level surface, and n . v is to O(h^2)), and evaluates the force at that part's
depth-weighted centroid with the normal interpolated there (docs/accuracy.md, "Quadrature").

Which elements need it is decided in two steps, so that the others cost one comparison more
than a one-point rule. First two bounds per element: ``reach``, the largest distance from the
centroid to a corner (the depth of a corner differs from the centroid's by at most reach under
a level surface), and ``spread``, the largest distance between the element's normal and a
corner normal (0 for a flat facet); n . v differs from the centroid's by at most
spread |v| + |omega| reach over the element. The elements these bounds cannot clear are then
tested exactly, from their corner depths and corner n . v, and only those the surface or the
leading boundary crosses, or within the band (``UNEVEN_REACH``), are clipped.
"""

from __future__ import annotations

import numpy as np

#: Columns of the (n, PATCH_SIZE) table: corner offsets from the centroid (3 x 3) [m], corner
#: normals (3 x 3), spread; shape (body) frame.
PATCH_CORNER, PATCH_NORMAL, PATCH_SPREAD = 0, 9, 18
PATCH_SIZE = 19
#: Elements whose centroid is within UNEVEN_REACH * reach of the surface are clipped: under a
#: level surface a corner's depth differs from the centroid's by at most reach; on an uneven
#: one the surface's rise over reach horizontally adds to it, covered up to 45 deg slopes
#: (beyond, a straddling triangle may be evaluated at its centroid). One band for every
#: surface, so that a flat height field gives the flat surface's forces.
UNEVEN_REACH = 2.0


def patch_table(
    centroids: np.ndarray, corners: np.ndarray, normals: np.ndarray, corner_normals: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(reach (n,) [m], patch (n, PATCH_SIZE)) of elements, all in one frame.

    centroids (n, 3) element positions [m] (unused: offsets are from the triangles' own
    centroids), corners (n, 3, 3) [m] (the triangle's vertices), normals (n, 3) the
    elements' unit normals, corner_normals (n, 3, 3) unit normals at the corners.
    """
    # Offsets from the triangle's own centroid: a primitive's element sits at its curved patch's
    # centroid, and the kernel clips the triangle translated there (so a submerged patch and
    # its clipped triangle integrate the same depth).
    off = corners - corners.mean(axis=1, keepdims=True)
    reach = np.sqrt(np.max(np.einsum("ijk,ijk->ij", off, off), axis=1))
    dn = corner_normals - normals[:, None, :]
    patch = np.empty((len(centroids), PATCH_SIZE))
    patch[:, PATCH_CORNER : PATCH_CORNER + 9] = off.reshape(-1, 9)
    patch[:, PATCH_NORMAL : PATCH_NORMAL + 9] = corner_normals.reshape(-1, 9)
    patch[:, PATCH_SPREAD] = np.sqrt(np.max(np.einsum("ijk,ijk->ij", dn, dn), axis=1))
    return np.ascontiguousarray(reach), patch


def element_patches(elements) -> tuple[np.ndarray, np.ndarray]:
    """patch_table of an ElementSet (its own frame)."""
    return patch_table(
        elements.centroids, elements.vertices[elements.faces], elements.normals,
        elements.corner_normals,
    )  # fmt: skip
