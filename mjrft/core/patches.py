"""The curved surface a primitive's flat triangles stand for: exact normals and patch areas.

A primitive's vertices lie on its analytic surface, so each flat triangle stands for the patch
of that surface its corners span. The element then carries, instead of the facet's values, the
surface normal at its corners and at its centroid's image on the surface, and the patch's
area (shape frame throughout). The facet normal of a chord triangle differs from the surface
normal at the centroid by O(h) (h the edge length); the surface normal there by O(h^2), which
is what makes the kernel's quadrature (``mjrft.core.engine``) second order (docs/accuracy.md).

Each shape is a few smooth pieces (``piece``: which one a face lies on, from its corners), each
with a ``normal`` and a ``project`` onto the surface (a bijection from the triangle's plane
near the patch, used only to measure the patch's area).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Patch area from the triangle's area A0 and the area A1 of its four midpoint sub-triangles
#: projected onto the surface: both err as c h^2, so (4 A1 - A0) / 3 errs as O(h^4).
_RICHARDSON = (4.0 / 3.0, -1.0 / 3.0)


#: Largest |n_corner - n_centre| for which the corners keep their own normals (0.5: 29 deg);
#: chosen on benchmarks/pareto.py's slender ellipsoid and root tip among 0.25, 0.5 and 0.8.
MAX_TURN = 0.5


class Patches(NamedTuple):
    """Normals and areas of the curved patches of a primitive's faces, shape frame."""

    centroids: np.ndarray  # (n, 3) area centroids of the curved patches [m] (off the surface)
    normals: np.ndarray  # (n, 3) unit surface normal at each centroid's image on the surface
    corner_normals: np.ndarray  # (n, 3, 3) unit surface normal at each face's corners
    areas: np.ndarray  # (n,) patch areas [m^2]


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


class Surface:
    """A smooth closed surface made of pieces; subclasses define the three maps below."""

    def piece(self, corners: np.ndarray) -> np.ndarray:
        """(n,) int piece of each face, from its corners (n, 3, 3) [m]."""
        return np.zeros(corners.shape[0], dtype=np.int64)

    def normal(self, p: np.ndarray, piece: np.ndarray) -> np.ndarray:
        """(..., 3) unit outward normals at surface points p (..., 3) of the given pieces."""
        raise NotImplementedError

    def project(self, p: np.ndarray, piece: np.ndarray) -> np.ndarray:
        """(..., 3) images on the surface of points p (..., 3) near the given pieces."""
        raise NotImplementedError

    def patches(self, vertices: np.ndarray, faces: np.ndarray) -> Patches:
        """Exact normals and patch areas of the faces (n, 3) of vertices (m, 3) on this surface."""
        tri = vertices[faces]
        piece = self.piece(tri)
        pc = piece[:, None]
        corner_normals = self.normal(tri, np.broadcast_to(pc, tri.shape[:2]))
        centre = self.project(tri.mean(axis=1), piece)
        mid = 0.5 * (tri + np.roll(tri, -1, axis=1))  # midpoints of edges 01, 12, 20
        mid = self.project(mid, np.broadcast_to(pc, mid.shape[:2]))
        corner = self.project(tri, np.broadcast_to(pc, tri.shape[:2]))
        subs = (
            (corner[:, 0], mid[:, 0], mid[:, 2]),
            (corner[:, 1], mid[:, 1], mid[:, 0]),
            (corner[:, 2], mid[:, 2], mid[:, 1]),
            (mid[:, 0], mid[:, 1], mid[:, 2]),
        )
        a_fine = [_area(*s) for s in subs]
        a_flat = _area(*tri.transpose(1, 0, 2))
        areas = _RICHARDSON[0] * sum(a_fine) + _RICHARDSON[1] * a_flat
        # The first moment the same way: the patch's area centroid, where its depth is its mean
        # depth under a level surface (depth is linear in z).
        moment = _RICHARDSON[0] * sum(
            a[:, None] * (s[0] + s[1] + s[2]) / 3.0 for a, s in zip(a_fine, subs, strict=True)
        )
        moment += _RICHARDSON[1] * a_flat[:, None] * tri.mean(axis=1)
        normals = self.normal(centre, piece)
        # Where the normal turns by more than MAX_TURN between the centre and a corner, n . v
        # is far from linear over the triangle: the corners then carry the element's normal, so
        # that only the surface and rotation can clip it (benchmarks/pareto.py: the slender
        # ellipsoid's tip and the root's apex at a few hundred triangles).
        turn = np.max(np.linalg.norm(corner_normals - normals[:, None, :], axis=2), axis=1)
        coarse = (turn > MAX_TURN)[:, None, None]
        corner_normals = np.where(coarse, normals[:, None, :], corner_normals)
        return Patches(
            moment / areas[:, None], normals, corner_normals, areas + self.rim(tri, piece)
        )

    def rim(self, corners: np.ndarray, piece: np.ndarray) -> np.ndarray:
        """(n,) surface area [m^2] between a face's rim chords and the rim curve the projection
        misses (a flat cap's circular segments); 0 where the projection covers it."""
        return np.zeros(corners.shape[0])


def _area(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=-1)


#: A corner is on a rim circle of radius R if | rho - R | <= _ON_RIM R (vertices are placed on
#: it to round-off).
_ON_RIM = 1e-9


def _segments(corners: np.ndarray, radius: float, z: float) -> np.ndarray:
    """(n,) total area [m^2] of the circular segments cut off by each face's edges whose two
    ends lie on the circle rho = radius in the plane at height z (the rim of a disc)."""
    rho = np.linalg.norm(corners[..., :2], axis=-1)
    on = (np.abs(rho - radius) <= _ON_RIM * radius) & (
        np.abs(corners[..., 2] - z) <= _ON_RIM * radius
    )
    nxt = np.roll(corners, -1, axis=1)
    edge = on & np.roll(on, -1, axis=1)
    chord = np.linalg.norm(nxt[..., :2] - corners[..., :2], axis=-1)
    theta = 2.0 * np.arcsin(np.minimum(1.0, chord / (2.0 * radius)))
    return np.sum(np.where(edge, 0.5 * radius**2 * (theta - np.sin(theta)), 0.0), axis=1)


class Ellipsoid(Surface):
    """(x/a)^2 + (y/b)^2 + (z/c)^2 = 1 (spheres included); projection from the centre."""

    def __init__(self, axes: np.ndarray) -> None:
        self.axes = np.asarray(axes, dtype=np.float64)

    def normal(self, p, piece):
        return _unit(p / self.axes**2)

    def project(self, p, piece):
        return p / np.linalg.norm(p / self.axes, axis=-1, keepdims=True)


class Cylinder(Surface):
    """Tube of radius r about z, |z| <= h (piece 0), and flat caps z = +-h (pieces 1, 2)."""

    def __init__(self, radius: float, half_length: float) -> None:
        self.r, self.h = float(radius), float(half_length)

    def piece(self, corners):
        z = corners[..., 2]
        return np.where(
            np.all(z == self.h, axis=1), 1, np.where(np.all(z == -self.h, axis=1), 2, 0)
        )

    def normal(self, p, piece):
        side = p * [1.0, 1.0, 0.0]
        side = side / np.maximum(np.linalg.norm(side, axis=-1, keepdims=True), 1e-300)
        cap = np.zeros_like(p)
        cap[..., 2] = np.where(piece == 1, 1.0, -1.0)
        return np.where((piece == 0)[..., None], side, cap)

    def project(self, p, piece):
        rho = np.linalg.norm(p[..., :2], axis=-1, keepdims=True)
        side = np.concatenate([p[..., :2] * (self.r / np.maximum(rho, 1e-300)), p[..., 2:]], -1)
        return np.where((piece == 0)[..., None], side, p)

    def rim(self, corners, piece):
        top = _segments(corners, self.r, self.h)
        bottom = _segments(corners, self.r, -self.h)
        return np.where(piece == 1, top, np.where(piece == 2, bottom, 0.0))


class Capsule(Surface):
    """Points at distance r from the segment |z| <= h of the z axis (one C1 piece)."""

    def __init__(self, radius: float, half_length: float) -> None:
        self.r, self.h = float(radius), float(half_length)

    def _axis(self, p):
        a = np.zeros_like(p)
        a[..., 2] = np.clip(p[..., 2], -self.h, self.h)
        return a

    def normal(self, p, piece):
        return _unit(p - self._axis(p))

    def project(self, p, piece):
        a = self._axis(p)
        return a + self.r * _unit(p - a)


class Paraboloid(Surface):
    """z = L (rho / R)^2 for rho <= R (piece 0), apex down, and the flat cap z = L (piece 1)."""

    def __init__(self, radius: float, length: float) -> None:
        self.big_r, self.big_l = float(radius), float(length)

    def piece(self, corners):
        return np.all(corners[..., 2] == self.big_l, axis=1).astype(np.int64)

    def normal(self, p, piece):
        g = 2.0 * self.big_l / self.big_r**2  # the surface is z = g rho^2 / 2; outward is down
        lateral = _unit(np.concatenate([g * p[..., :2], -np.ones_like(p[..., 2:])], axis=-1))
        cap = np.zeros_like(p)
        cap[..., 2] = 1.0
        return np.where((piece == 0)[..., None], lateral, cap)

    def project(self, p, piece):
        rho2 = np.sum(p[..., :2] ** 2, axis=-1, keepdims=True)
        lateral = np.concatenate([p[..., :2], self.big_l * rho2 / self.big_r**2], axis=-1)
        return np.where((piece == 0)[..., None], lateral, p)

    def rim(self, corners, piece):
        # The vertical projection of a lateral face's rim chord stays inside rho = R; the strip
        # it misses is the chord's segment times the surface's area factor at the rim.
        seg = _segments(corners, self.big_r, self.big_l)
        slope = 2.0 * self.big_l / self.big_r
        return np.where(piece == 1, seg, seg * np.sqrt(1.0 + slope**2))
