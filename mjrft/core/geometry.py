"""Shapes -> ElementSets: tessellated primitives and checked mesh files, shape frame, metres.

Every primitive is built on the same structured topology: the surface of an ``nx x ny x nz``
lattice of cells (a subdivided box), each quad split into two triangles in a "union jack"
pattern, and each lattice point mapped onto the shape's surface. The mapping is chosen per
shape so that triangles are roughly uniform and there are no poles:

* box: identity (uniform grid on every face);
* sphere / ellipsoid: equal-angle cube-sphere (``tan`` spacing, projected radially onto the unit
  sphere, then scaled by the semi-axes), lattice counts proportional to the semi-axes;
* cylinder: side faces -> tube (uniform azimuth, uniform z); top/bottom faces -> flat caps via the
  Shirley-Chiu concentric square-to-disc map (rings with 8k points, no central pole fan);
* capsule: two equal-angle cube-sphere hemispheres joined by a tube;
* paraboloid: a concentric-mapped tip patch, a lateral band uniform in meridian arc length, and
  a flat concentric disc cap.

Vertices are shared (watertight, consistently wound counter-clockwise seen from outside, so the
normals point outward), every vertex lies exactly on the analytic surface, and the maps are
smooth on each lattice face, so total area and enclosed volume converge to the analytic values
as O(h^2) ~ O(1 / n_triangles).

Resolution (all primitives): give at most one of ``n_triangles`` (target count; the nearest
achievable count is used, typically within +-25 %, never fewer than :data:`MIN_TRIANGLES`) or
``max_edge`` (every triangle edge <= ``max_edge`` [m], the coarsest such mesh in the family).
Neither -> ``n_triangles=DEFAULT_N_TRIANGLES`` (about 1000 for every shape, boxes included: RFT
evaluates depth per element, so a 2-triangle box face would be far too coarse).
"""

from __future__ import annotations

import logging
import math
import operator
import warnings
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from mjrft.core import patches
from mjrft.core.elements import ElementSet

__all__ = [
    "DEFAULT_N_TRIANGLES",
    "MAX_TRIANGLES",
    "MIN_TRIANGLES",
    "PRIMITIVE_KINDS",
    "SUPPORTED_MESH_EXTENSIONS",
    "MeshWarning",
    "box",
    "capsule",
    "cylinder",
    "ellipsoid",
    "from_mesh",
    "from_mesh_file",
    "paraboloid",
    "primitive",
    "sphere",
]

log = logging.getLogger(__name__)

DEFAULT_N_TRIANGLES = 1000
"""Target triangle count used when neither ``n_triangles`` nor ``max_edge`` is given."""

MIN_TRIANGLES = 12
"""No primitive has fewer triangles (box: one lattice cell per axis, 12; sphere, ellipsoid and
cylinder: two, so a lattice line runs along each mid-plane, 48; paraboloid 32; capsule 80).
Smaller n_triangles requests give the shape's minimum."""

MAX_TRIANGLES = 2_000_000
"""Refuse resolutions above this (memory: ~0.5 GB of element arrays and temporaries)."""

PRIMITIVE_KINDS = ("sphere", "ellipsoid", "capsule", "cylinder", "box")

#: Accuracy knob, per primitive type: n = max(TOLERANCE_FLOOR, ceil((C / tol) ** (1 / p)))
#: triangles for a relative RMS force tolerance tol, (C, p) = TOLERANCE_RULES[type]. Fitted in
#: benchmarks/pareto.py (benchmarks/RESULTS.md, "Speed vs accuracy"; docs/accuracy.md): p is
#: the smallest order fitted on the type's cases (clipped to [0.8, 1]; rounded down to two
#: decimals) and C twice the envelope of their measured errors from 200 triangles up (rounded
#: up to two digits); checked there and in tests/test_tolerance.py
#: on shapes and motions not used in the fit (tumbling about an oblique axis, grazing, slender,
#: flat and disc-like shapes). The cylinder keeps an earlier, more conservative fit: the re-fit's
#: (0.5, 0.86) asked 384 triangles at 0.3 %, where a held-out short cylinder (10 x 5 mm)
#: tumbling reached 0.316 %.
TOLERANCE_RULES = {
    "sphere": (0.87, 0.81),
    "ellipsoid": (3.9, 0.92),
    "capsule": (0.91, 0.8),
    "cylinder": (0.88, 0.92),
    "box": (0.36, 0.8),
}
#: The scene's default relative force tolerance per primitive geom when an MJCF gives neither
#: ``mjrft:triangles`` nor ``mjrft:tolerance`` (mjrft.field.scene): 1 % RMS force error, with
#: each primitive's count from its type's rule (200-656 triangles at the fitted shapes).
DEFAULT_TOLERANCE = 0.01
TOLERANCE_FLOOR = 200  # below ~200 triangles errors are not yet asymptotic (a slender tip)
#: Aspect ratio (longest over shortest extent, ``aspect_ratio``) of the shape each rule was
#: fitted on, for the types whose error grows with it: a slender ellipsoid's tips and a long
#: capsule's tube get few of the triangles, so grazing motions of a 5 x 10 x 30 mm ellipsoid
#: and a 3 x 25 mm capsule missed 1 % by 2x at the fitted rule; their count scales by
#: max(1, aspect / TOLERANCE_ASPECT[type]), floor included (grazing slim capsules missed 3 % at
#: the floor). Cylinders and boxes (discs, plates) did not need it.
TOLERANCE_ASPECT = {"ellipsoid": 1.875, "capsule": 3.0}


def aspect_ratio(kind: str, size: Sequence[float] | np.ndarray) -> float:
    """Longest over shortest extent of a primitive of MuJoCo type name kind and size [m]."""
    s = np.asarray(size, dtype=np.float64)
    if kind == "sphere":
        return 1.0
    if kind == "capsule":
        return float((s[0] + s[1]) / s[0])
    if kind == "cylinder":
        return float(max(s[0], s[1]) / min(s[0], s[1]))
    return float(s[:3].max() / s[:3].min())


def triangles_for_tolerance(
    tol: float, kind: str | None = None, size: Sequence[float] | np.ndarray | None = None
) -> int:
    """Triangle count for a primitive whose RFT force should be within relative RMS error tol.

    The error is measured as the RMS over a motion of |F - F_converged| over the peak
    |F_converged| (benchmarks/pareto.py). kind: the primitive type ('sphere', 'ellipsoid',
    'capsule', 'cylinder', 'box'); None: the largest count over the types. size: its MuJoCo
    size [m], for the types whose count grows with the aspect ratio (TOLERANCE_ASPECT); None:
    the fitted shape's. Raises ValueError unless 0 < tol < 1 and the count stays within
    MAX_TRIANGLES, or for an unknown kind.
    """
    try:
        t = float(tol)
    except (TypeError, ValueError):
        raise ValueError(f"tolerance must be a number in (0, 1), got {tol!r}") from None
    if not (0.0 < t < 1.0):
        raise ValueError(f"tolerance must be in (0, 1) (a relative force error), got {tol!r}")
    if kind is None:
        return max(triangles_for_tolerance(t, k) for k in TOLERANCE_RULES)
    if kind not in TOLERANCE_RULES:
        raise ValueError(
            f"no tolerance rule for {kind!r}; primitive types: {', '.join(TOLERANCE_RULES)} "
            "(meshes keep their own triangles)"
        )
    c, p = TOLERANCE_RULES[kind]
    scale = 1.0
    if size is not None and kind in TOLERANCE_ASPECT:
        scale = max(1.0, aspect_ratio(kind, size) / TOLERANCE_ASPECT[kind])
    # In log space: a tiny tolerance (1e-300) would overflow the power before the check below.
    log_n = (math.log(c) - math.log(t)) / p + math.log(scale)
    if log_n > math.log(MAX_TRIANGLES):
        smallest = max(cc / MAX_TRIANGLES**pp for cc, pp in TOLERANCE_RULES.values())
        raise ValueError(
            f"tolerance {t:g} needs about 1e{log_n / math.log(10):.1f} triangles for this "
            f"{kind}, more than MAX_TRIANGLES = {MAX_TRIANGLES}; the smallest supported "
            f"tolerance is about {smallest:.2g}"
        )
    return math.ceil(scale * max(TOLERANCE_FLOOR, (c / t) ** (1.0 / p)))


"""Kinds accepted by :func:`primitive` (MuJoCo geom type names)."""

SUPPORTED_MESH_EXTENSIONS = (".stl", ".obj", ".ply")
"""Mesh file extensions accepted by :func:`from_mesh_file` (case-insensitive)."""

# Faces with area below this fraction of the mesh's mean face area count as degenerate.
_DEGENERATE_REL_AREA = 1e-12
# Open meshes are re-oriented only if |signed volume about the vertex mean| exceeds this fraction
# of the bounding-box diagonal cubed (below it, e.g. a flat sheet, orientation is ambiguous).
_OPEN_MESH_REL_VOLUME = 1e-6

_QUARTER_PI = 0.25 * math.pi


class MeshWarning(UserWarning):
    """A mesh was usable but not clean: degenerate faces dropped, holes, winding repaired."""


# --------------------------------------------------------------------------------------------
# Parameter validation
# --------------------------------------------------------------------------------------------


def _positive(name: str, value: object) -> float:
    """Finite positive float, else ValueError naming the parameter."""
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite positive number, got {value!r}") from None
    if not (math.isfinite(x) and x > 0.0):
        raise ValueError(f"{name} must be a finite positive number, got {value!r}")
    return x


def _positive_vector(name: str, value: object, length: int) -> np.ndarray:
    """Finite positive float vector of the given length, else ValueError naming the parameter."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name} must be {length} finite positive numbers [m], got {value!r}"
        ) from None
    if arr.shape != (length,) or not np.all(np.isfinite(arr)) or not np.all(arr > 0.0):
        raise ValueError(f"{name} must be {length} finite positive numbers [m], got {value!r}")
    return arr


def _resolution(n_triangles: object, max_edge: object) -> tuple[int | None, float | None]:
    """Validate the resolution pair; returns (n_triangles, max_edge) with exactly one set."""
    if n_triangles is not None and max_edge is not None:
        raise ValueError(
            f"give at most one of n_triangles and max_edge, got n_triangles={n_triangles!r} "
            f"and max_edge={max_edge!r}"
        )
    if max_edge is not None:
        return None, _positive("max_edge", max_edge)
    if n_triangles is None:
        return DEFAULT_N_TRIANGLES, None
    n: int | None = None
    if not isinstance(n_triangles, bool):
        try:
            n = operator.index(n_triangles)  # type: ignore[arg-type]
        except TypeError:
            if isinstance(n_triangles, float) and n_triangles.is_integer():
                n = int(n_triangles)
    if n is None or n <= 0:
        raise ValueError(f"n_triangles must be a positive integer, got {n_triangles!r}")
    if n > MAX_TRIANGLES:
        raise ValueError(
            f"n_triangles={n} exceeds the supported maximum MAX_TRIANGLES={MAX_TRIANGLES}"
        )
    return n, None


# --------------------------------------------------------------------------------------------
# Lattice surface topology
# --------------------------------------------------------------------------------------------

Dims = tuple[int, int, int]


def _lattice_triangles(dims: Dims) -> int:
    nx, ny, nz = dims
    return 4 * (nx * ny + ny * nz + nz * nx)


def _grid_triangles(ids: np.ndarray) -> np.ndarray:
    """Triangles (2*p*q, 3) of a (p+1, q+1) vertex-id grid whose axes (u, v) have u x v outward.

    Quads are split along the diagonal pointing away from the grid centre ("union jack"), which
    keeps the pattern symmetric and aligns diagonals with the kinks of the concentric disc map.
    """
    p, q = ids.shape[0] - 1, ids.shape[1] - 1
    c0, c1 = ids[:-1, :-1], ids[1:, :-1]
    c2, c3 = ids[1:, 1:], ids[:-1, 1:]
    cu = (np.arange(p) + 0.5 - 0.5 * p)[:, None]
    cv = (np.arange(q) + 0.5 - 0.5 * q)[None, :]
    main = np.broadcast_to(cu * cv >= 0.0, c0.shape)  # split along c0-c2
    t1 = np.where(main[..., None], np.stack([c0, c1, c2], -1), np.stack([c0, c1, c3], -1))
    t2 = np.where(main[..., None], np.stack([c0, c2, c3], -1), np.stack([c1, c2, c3], -1))
    return np.concatenate([t1.reshape(-1, 3), t2.reshape(-1, 3)])


def _lattice_surface(dims: Dims) -> tuple[np.ndarray, np.ndarray]:
    """Boundary points (P, 3) int lattice indices and outward CCW faces (F, 3) of a cell box."""
    nx, ny, nz = dims
    i, j, k = np.meshgrid(
        np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij", sparse=True
    )
    on_surface = (i == 0) | (i == nx) | (j == 0) | (j == ny) | (k == 0) | (k == nz)
    ids = np.full((nx + 1, ny + 1, nz + 1), -1, dtype=np.int64)
    ids[on_surface] = np.arange(np.count_nonzero(on_surface))
    ijk = np.argwhere(on_surface)
    faces = np.concatenate(
        [
            _grid_triangles(ids[nx, :, :]),  # +x: (y, z)
            _grid_triangles(ids[0, :, :].T),  # -x: (z, y)
            _grid_triangles(ids[:, ny, :].T),  # +y: (z, x)
            _grid_triangles(ids[:, 0, :]),  # -y: (x, z)
            _grid_triangles(ids[:, :, nz]),  # +z: (x, y)
            _grid_triangles(ids[:, :, 0].T),  # -z: (y, x)
        ]
    )
    return ijk, faces


def _cells(s: float, length: float, phase: float) -> int:
    """Cell count for a span of ``length`` [m] at density ``s`` [cells/m], at least 1.

    The phase staggers when different counts increment, giving finer steps in triangle count.
    """
    return max(1, math.floor(s * length + phase))


# Phases for up to three independent counts (see _cells).
_PHASES = (0.5, 1.0 / 6.0, 5.0 / 6.0)
# Curved spans get at least _MIN_CURVED_CELLS cells (12 segments around a circle: 30 deg, area
# error ~1 %) as soon as that keeps cells no more than _MAX_ASPECT times finer than the uniform
# spacing; without this a slender cylinder at 1000 triangles would have a square cross-section.
_MIN_CURVED_CELLS = 3
_MAX_ASPECT = 4.0
# n_triangles: accept the nearest member of the uniform family if within this log-ratio (~10 %).
_COUNT_SLACK = math.log(1.1)


def _curved_cells(s: float, length: float, phase: float) -> int:
    """Cell count for a curved span (arc length [m]): uniform, boosted on slender shapes."""
    boosted = min(_cells(_MAX_ASPECT * s, length, phase), _MIN_CURVED_CELLS)
    return max(_cells(s, length, phase), boosted)


def _even_curved_cells(s: float, length: float, phase: float) -> int:
    """_curved_cells rounded up to even (see _Family.even)."""
    return _even(_curved_cells(s, length, phase))


Counts = tuple[int, ...]
_CountsFn = Callable[[float], Counts]  # density [cells/m] -> shape-specific cell counts
_LatticeFn = Callable[[Counts], Dims]  # cell counts -> lattice dims
_MapFn = Callable[[np.ndarray, Counts], np.ndarray]  # (P, 3) lattice indices -> (P, 3) points


def _even(count: int) -> int:
    """count rounded up to even: a lattice line then runs along the span's middle."""
    return count + (count & 1)


def _all_even(counts: Counts) -> bool:
    return all(c % 2 == 0 for c in counts)


class _Family:
    """A one-parameter family of lattice meshes of one shape, indexed by density s [cells/m].

    allowed(counts): which counts the resolution search may use (default: all). Curved shapes
    keep the counts across their mid-planes even, so a lattice line runs along each mid-plane: a
    translation along a principal axis then has its leading boundary (and a level waterline its
    wet boundary) along lattice lines instead of cutting a row of facets, whose all-or-nothing
    decision is a first-order error (docs/accuracy.md, "Convergence to an analytic force").
    """

    def __init__(
        self,
        shape: str,
        counts_fn: _CountsFn,
        lattice_fn: _LatticeFn,
        map_fn: _MapFn,
        allowed: Callable[[Counts], bool] | None = None,
        surface: patches.Surface | None = None,
    ) -> None:
        self.shape, self.counts, self.lattice, self._map = shape, counts_fn, lattice_fn, map_fn
        self.allowed = allowed if allowed is not None else (lambda counts: True)
        self.surface = surface  # None: flat faces (a box)

    def n_triangles(self, counts: Counts) -> int:
        return _lattice_triangles(self.lattice(counts))

    def mesh(self, counts: Counts) -> tuple[np.ndarray, np.ndarray]:
        ijk, faces = _lattice_surface(self.lattice(counts))
        return self._map(ijk, counts), faces


def _max_edge_length(vertices: np.ndarray, faces: np.ndarray) -> float:
    tri = vertices[faces]
    edges = tri - np.roll(tri, 1, axis=1)
    return float(np.sqrt(np.max(np.einsum("ijk,ijk->ij", edges, edges))))


def _build(family: _Family, n_triangles: object, max_edge: object) -> ElementSet:
    """Pick cell counts from the resolution request, map the lattice, wrap as an ElementSet."""
    target, edge = _resolution(n_triangles, max_edge)
    if target is not None:
        counts = _counts_for_n_triangles(family, target)
    else:
        assert edge is not None
        counts = _counts_for_max_edge(family, edge)
    vertices, faces = family.mesh(counts)
    log.debug("%s: cell counts %s -> %d triangles", family.shape, counts, len(faces))
    return ElementSet.from_triangles(vertices, faces, family.surface)


def _counts_for_n_triangles(family: _Family, target: int) -> Counts:
    """Counts whose triangle total is nearest to target (in ratio), never below the minimum."""
    lo = 0.0
    if family.n_triangles(family.counts(lo)) >= target:
        return family.counts(lo)
    hi = 1.0
    while family.n_triangles(family.counts(hi)) < target:
        hi *= 2.0
    for _ in range(200):  # the count is a non-decreasing step function of s: bisect the step
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if family.n_triangles(family.counts(mid)) >= target:
            hi = mid
        else:
            lo = mid
    below, above = family.counts(lo), family.counts(hi)

    def error(counts: Counts) -> float:
        return abs(math.log(family.n_triangles(counts) / target))

    best = below if error(below) < error(above) else above
    if error(best) <= _COUNT_SLACK:
        return best
    # The family jumps too far here (one count going 1 -> 2 doubles the total): re-balance one
    # count of either neighbour, within a factor 2 of its value (small counts up to 8), to land
    # closer to the target. Among those within the slack, the one whose coarsest count is the
    # finest wins (e.g. a slender capsule: more cells around rather than along).
    candidates = [best]
    for base in (below, above):
        for i, c in enumerate(base):
            for c_new in range(max(1, c // 2), max(2 * c + 2, 9)):
                candidates.append((*base[:i], c_new, *base[i + 1 :]))
    candidates = [c for c in candidates if family.allowed(c)]
    close = [c for c in candidates if error(c) <= _COUNT_SLACK]
    if close:
        return max(close, key=lambda c: (min(c), -error(c)))
    return min(candidates, key=error)


def _counts_for_max_edge(family: _Family, max_edge: float) -> Counts:
    """Coarsest counts found (bisection over density) whose longest triangle edge <= max_edge."""
    cache: dict[Counts, bool] = {}

    def ok(counts: Counts) -> bool:
        if counts not in cache:
            if family.n_triangles(counts) > MAX_TRIANGLES:
                raise ValueError(
                    f"{family.shape}: max_edge={max_edge!r} m would need more than "
                    f"MAX_TRIANGLES={MAX_TRIANGLES} triangles; use a larger max_edge"
                )
            cache[counts] = _max_edge_length(*family.mesh(counts)) <= max_edge
        return cache[counts]

    lo, hi = 0.0, 1.0 / max_edge
    if ok(family.counts(lo)):
        return family.counts(lo)
    while not ok(family.counts(hi)):
        lo, hi = hi, 2.0 * hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        c_mid = family.counts(mid)
        if c_mid == family.counts(hi):
            hi = mid
        elif c_mid == family.counts(lo):
            lo = mid
        elif ok(c_mid):
            hi = mid
        else:
            lo = mid
    return family.counts(hi)


# --------------------------------------------------------------------------------------------
# Surface maps (lattice index -> shape surface)
# --------------------------------------------------------------------------------------------


def _unit(ijk: np.ndarray, dims: Dims) -> np.ndarray:
    """Lattice indices -> linear coordinates in [-1, 1]^3 (boundary exactly +-1)."""
    return 2.0 * ijk / np.asarray(dims, dtype=np.float64) - 1.0


def _cube_sphere_dirs(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Equal-angle cube-sphere: cube surface coordinates in [-1, 1] -> unit vectors (P, 3)."""
    d = np.stack([np.tan(_QUARTER_PI * a), np.tan(_QUARTER_PI * b), np.tan(_QUARTER_PI * c)], -1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _concentric(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Shirley-Chiu concentric map of the square [-1, 1]^2 onto the unit disc, (P, 2).

    The square's boundary goes to the unit circle with uniform azimuth, matching the equal-angle
    cube-sphere's equator; ring k of a 2m x 2m grid becomes 8k evenly spaced points at radius k/m.
    """
    use_a = np.abs(a) >= np.abs(b)
    r = np.where(use_a, a, b)
    safe = np.where(r == 0.0, 1.0, r)
    phi = np.where(use_a, _QUARTER_PI * (b / safe), 2.0 * _QUARTER_PI - _QUARTER_PI * (a / safe))
    return np.stack([r * np.cos(phi), r * np.sin(phi)], -1)


def _ring_dirs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unit (x, y) directions of cube-sphere equator points (max(|a|, |b|) = 1), (P, 2)."""
    d = np.stack([np.tan(_QUARTER_PI * a), np.tan(_QUARTER_PI * b)], -1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


# --------------------------------------------------------------------------------------------
# Primitives
# --------------------------------------------------------------------------------------------


def sphere(
    radius: float, *, n_triangles: int | None = None, max_edge: float | None = None
) -> ElementSet:
    """Sphere centred at the shape origin, as an equal-angle cube-sphere.

    Args:
      radius: sphere radius [m] (MuJoCo size[0]).
      n_triangles: target triangle count (default DEFAULT_N_TRIANGLES); exclusive with max_edge.
      max_edge: longest allowed triangle edge [m]; exclusive with n_triangles.
    Returns:
      ElementSet in the shape frame [m]; vertices on the sphere, normals outward.
    """
    r = _positive("radius", radius)
    return _ellipsoid_impl("sphere", np.array([r, r, r]), n_triangles, max_edge)


def ellipsoid(
    semi_axes: Sequence[float] | np.ndarray,
    *,
    n_triangles: int | None = None,
    max_edge: float | None = None,
) -> ElementSet:
    """Ellipsoid centred at the shape origin, axis-aligned: (x/a)^2 + (y/b)^2 + (z/c)^2 = 1.

    Built as an equal-angle cube-sphere mapped through the semi-axes, with each axis' cell count
    proportional to the longest surface arc it subdivides, so triangles stay roughly uniform
    and the rims of flat or slender ellipsoids stay resolved.

    Args:
      semi_axes: (3,) semi-axes (a, b, c) along shape x, y, z [m] (MuJoCo size).
      n_triangles: target triangle count (default DEFAULT_N_TRIANGLES); exclusive with max_edge.
      max_edge: longest allowed triangle edge [m]; exclusive with n_triangles.
    Returns:
      ElementSet in the shape frame [m]; vertices on the ellipsoid, normals outward.
    """
    axes = _positive_vector("semi_axes", semi_axes, 3)
    return _ellipsoid_impl("ellipsoid", axes, n_triangles, max_edge)


def _ellipsoid_impl(
    shape: str, axes: np.ndarray, n_triangles: object, max_edge: object
) -> ElementSet:
    counts_fn = _per_axis_counts(_cube_sphere_spans(axes), _even_curved_cells)

    def map_fn(ijk: np.ndarray, counts: Counts) -> np.ndarray:
        u = _unit(ijk, _as_dims(counts))
        return _cube_sphere_dirs(u[:, 0], u[:, 1], u[:, 2]) * axes

    family = _Family(shape, counts_fn, _as_dims, map_fn, _all_even, patches.Ellipsoid(axes))
    return _build(family, n_triangles, max_edge)


def _cube_sphere_spans(axes: np.ndarray) -> np.ndarray:
    """Longest surface arc [m] each axis' cell count must subdivide on an ellipsoid cube-sphere.

    Count i subdivides the faces whose normal is another axis j; along the centre line of face j
    the surface is the ellipse (a_j cos t, a_i sin t), t in [-pi/4, pi/4]. Taking the longest
    such arc (not just pi/2 a_i) keeps the rims of flat or slender ellipsoids resolved.
    """
    t, w = np.polynomial.legendre.leggauss(32)
    t = _QUARTER_PI * t
    w = _QUARTER_PI * w
    spans = np.zeros(3)
    for i in range(3):
        for j in range(3):
            if i != j:
                speed = np.sqrt((axes[j] * np.sin(t)) ** 2 + (axes[i] * np.cos(t)) ** 2)
                spans[i] = max(spans[i], float(np.dot(w, speed)))
    return spans


def _per_axis_counts(spans: np.ndarray, cells: Callable[[float, float, float], int]) -> _CountsFn:
    """Counts function with one staggered cell count per axis, proportional to spans [m]."""
    lengths = [float(x) for x in spans]

    def counts_fn(s: float) -> Counts:
        return tuple(cells(s, length, ph) for length, ph in zip(lengths, _PHASES, strict=True))

    return counts_fn


def _as_dims(counts: Counts) -> Dims:
    nx, ny, nz = counts
    return (nx, ny, nz)


def box(
    half_sizes: Sequence[float] | np.ndarray,
    *,
    n_triangles: int | None = None,
    max_edge: float | None = None,
) -> ElementSet:
    """Axis-aligned box centred at the shape origin, each face a uniform grid of triangles.

    Args:
      half_sizes: (3,) half extents along shape x, y, z [m] (MuJoCo size).
      n_triangles: target triangle count (default DEFAULT_N_TRIANGLES, minimum 12 = 2 per face);
        exclusive with max_edge.
      max_edge: longest allowed triangle edge (the grid-cell diagonal) [m]; exclusive with
        n_triangles.
    Returns:
      ElementSet in the shape frame [m]; area and volume exact, normals outward.
    """
    half = _positive_vector("half_sizes", half_sizes, 3)

    def map_fn(ijk: np.ndarray, counts: Counts) -> np.ndarray:
        return _unit(ijk, _as_dims(counts)) * half

    family = _Family("box", _per_axis_counts(2.0 * half, _cells), _as_dims, map_fn)
    return _build(family, n_triangles, max_edge)


def cylinder(
    radius: float,
    half_length: float,
    *,
    n_triangles: int | None = None,
    max_edge: float | None = None,
) -> ElementSet:
    """Closed cylinder about shape z, centred at the origin, with flat end caps.

    Args:
      radius: radius [m] (MuJoCo size[0]).
      half_length: half the length along z [m] (MuJoCo size[1]); caps at z = +-half_length.
      n_triangles: target triangle count (default DEFAULT_N_TRIANGLES); exclusive with max_edge.
      max_edge: longest allowed triangle edge [m]; exclusive with n_triangles.
    Returns:
      ElementSet in the shape frame [m]; normals outward.
    """
    r = _positive("radius", radius)
    h = _positive("half_length", half_length)
    quarter = 0.5 * math.pi * r  # quarter circumference: one lattice side face

    def counts_fn(s: float) -> Counts:  # (azimuth cells per quarter turn, axial cells), even
        return (_even_curved_cells(s, quarter, _PHASES[0]), _even(_cells(s, 2.0 * h, _PHASES[1])))

    def lattice_fn(counts: Counts) -> Dims:
        n, m = counts
        return (n, n, m)

    def map_fn(ijk: np.ndarray, counts: Counts) -> np.ndarray:
        u = _unit(ijk, lattice_fn(counts))
        xy = r * _concentric(u[:, 0], u[:, 1])
        return np.column_stack([xy, h * u[:, 2]])

    family = _Family("cylinder", counts_fn, lattice_fn, map_fn, _all_even, patches.Cylinder(r, h))
    return _build(family, n_triangles, max_edge)


def capsule(
    radius: float,
    half_length: float,
    *,
    n_triangles: int | None = None,
    max_edge: float | None = None,
) -> ElementSet:
    """Capsule about shape z, centred at the origin: a cylinder capped by two hemispheres.

    Args:
      radius: radius of the cylinder and hemispheres [m] (MuJoCo size[0]).
      half_length: half length of the cylindrical part [m] (MuJoCo size[1]); hemisphere centres
        at z = +-half_length, total length 2 * (half_length + radius).
      n_triangles: target triangle count (default DEFAULT_N_TRIANGLES); exclusive with max_edge.
      max_edge: longest allowed triangle edge [m]; exclusive with n_triangles.
    Returns:
      ElementSet in the shape frame [m]; normals outward.
    """
    r = _positive("radius", radius)
    h = _positive("half_length", half_length)
    quarter = 0.5 * math.pi * r

    def counts_fn(s: float) -> Counts:
        # (azimuth cells per quarter turn, hemisphere band cells from the equator to the cube
        # edge at ~45 deg latitude: half the cube face, tube cells); azimuth and tube even, so
        # lattice lines run along the x, y and z mid-planes (_Family.even)
        n = _even_curved_cells(s, quarter, _PHASES[0])
        return (n, n // 2, _even(_cells(s, 2.0 * h, _PHASES[1])))

    def lattice_fn(counts: Counts) -> Dims:
        n, band, tube = counts
        return (n, n, 2 * band + tube)

    def map_fn(ijk: np.ndarray, counts: Counts) -> np.ndarray:
        _, band, tube = counts
        u = _unit(ijk, lattice_fn(counts))
        a, b, k = u[:, 0], u[:, 1], ijk[:, 2]
        # Hemisphere bands: latitude coordinate in [0, 1] from the equator to the cap face.
        top = (k - band - tube) / band
        bottom = (band - k) / band
        lat = np.where(k >= band + tube, top, np.where(k <= band, bottom, 0.0))
        d = _cube_sphere_dirs(a, b, lat)
        z_sign = np.where(k >= band + tube, 1.0, -1.0)
        out = np.empty((len(ijk), 3))
        out[:, :2] = r * d[:, :2]
        out[:, 2] = z_sign * (h + r * d[:, 2])
        in_tube = (k > band) & (k < band + tube)
        out[in_tube, :2] = r * _ring_dirs(a[in_tube], b[in_tube])
        out[in_tube, 2] = -h + 2.0 * h * (k[in_tube] - band) / tube
        return out

    def allowed(counts: Counts) -> bool:  # even azimuth and tube; bands follow the azimuth
        n, band, tube = counts
        return n % 2 == 0 and tube % 2 == 0 and band == n // 2

    family = _Family("capsule", counts_fn, lattice_fn, map_fn, allowed, patches.Capsule(r, h))
    return _build(family, n_triangles, max_edge)


def paraboloid(
    radius: float,
    length: float,
    *,
    n_triangles: int | None = None,
    max_edge: float | None = None,
) -> ElementSet:
    """Closed paraboloid of revolution about shape z, apex at the origin pointing down (-z).

    Lateral surface z = length * (r / radius)^2 for r in [0, radius], closed by a flat disc cap
    at z = length (root-tip-like shape). Analytic volume pi * radius^2 * length / 2.

    Args:
      radius: radius of the base disc [m].
      length: axial length from apex to base [m].
      n_triangles: target triangle count (default DEFAULT_N_TRIANGLES); exclusive with max_edge.
      max_edge: longest allowed triangle edge [m]; exclusive with n_triangles.
    Returns:
      ElementSet in the shape frame [m]; normals outward.
    """
    big_r = _positive("radius", radius)
    big_l = _positive("length", length)
    k = 2.0 * big_l / big_r**2  # dz/dr = k r

    def arc(r: np.ndarray) -> np.ndarray:  # meridian arc length from the apex [m]
        return 0.5 * (r * np.sqrt(1.0 + (k * r) ** 2) + np.arcsinh(k * r) / k)

    # Inverse of arc() by interpolation: it only sets the spacing (z is computed from r, so every
    # vertex is exactly on the surface). Quadratic spacing resolves sharp apices.
    r_table = big_r * np.linspace(0.0, 1.0, 4097) ** 2
    s_table = arc(r_table)
    meridian = float(s_table[-1])
    quarter = 0.5 * math.pi * big_r

    def counts_fn(s: float) -> Counts:
        # (half the azimuth cells per quarter turn: even counts put a vertex on the apex,
        #  meridian cells of the lateral band)
        # (as _curved_cells, boosted to at least 2 x 2 = 4 cells per quarter: 16 around)
        half = max(
            _cells(s, 0.5 * quarter, _PHASES[0]),
            min(_cells(_MAX_ASPECT * s, 0.5 * quarter, _PHASES[0]), 2),
        )
        return (half, _cells(s, meridian, _PHASES[1]))

    def lattice_fn(counts: Counts) -> Dims:
        half, m = counts
        return (2 * half, 2 * half, m)

    def map_fn(ijk: np.ndarray, counts: Counts) -> np.ndarray:
        half, m = counts
        u = _unit(ijk, lattice_fn(counts))
        disc = _concentric(u[:, 0], u[:, 1])  # tip patch / base cap: ring j of 8j points
        rho = np.linalg.norm(disc, axis=1)
        direction = disc / np.where(rho > 0.0, rho, 1.0)[:, None]
        kk = ijk[:, 2]
        # Meridian arc: the tip patch's `half` rings and the band's m rings share one uniform
        # spacing over the apex-to-rim arc.
        sigma_tip = meridian * half / (m + half)
        sigma = np.where(kk == 0, rho * sigma_tip, sigma_tip + (meridian - sigma_tip) * kk / m)
        r = np.interp(sigma, s_table, r_table)
        r[kk == m] = big_r
        xy = r[:, None] * direction
        z = big_l * (r / big_r) ** 2
        base = kk == m  # flat cap (its rim ring is r = radius as well)
        xy[base] = big_r * disc[base]
        z[base] = big_l
        return np.column_stack([xy, z])

    family = _Family(
        "paraboloid", counts_fn, lattice_fn, map_fn, surface=patches.Paraboloid(big_r, big_l)
    )
    return _build(family, n_triangles, max_edge)


def primitive(
    kind: str,
    size: Sequence[float] | np.ndarray,
    *,
    n_triangles: int | None = None,
    max_edge: float | None = None,
) -> ElementSet:
    """Tessellate a MuJoCo geom primitive from its type name and ``size`` vector.

    Args:
      kind: 'sphere' | 'ellipsoid' | 'capsule' | 'cylinder' | 'box' (case-insensitive).
      size: MuJoCo geom size [m]: sphere (radius,), ellipsoid semi-axes (3,),
        capsule/cylinder (radius, half_length), box half sizes (3,). Extra trailing entries
        (MuJoCo always stores 3) are ignored.
      n_triangles: target triangle count (default DEFAULT_N_TRIANGLES); exclusive with max_edge.
      max_edge: longest allowed triangle edge [m]; exclusive with n_triangles.
    Returns:
      ElementSet in the geom frame [m].
    """
    key = kind.lower() if isinstance(kind, str) else None
    needed = {"sphere": 1, "ellipsoid": 3, "capsule": 2, "cylinder": 2, "box": 3}
    if key not in needed:
        raise ValueError(
            f"unknown primitive kind {kind!r}; valid kinds: {', '.join(PRIMITIVE_KINDS)} "
            "(for meshes use from_mesh_file / from_mesh)"
        )
    try:
        s = np.atleast_1d(np.asarray(size, dtype=np.float64))
    except (TypeError, ValueError):
        raise ValueError(f"size for {key} must be numbers, got {size!r}") from None
    if s.ndim != 1 or s.size < needed[key]:
        raise ValueError(
            f"size for {key} needs at least {needed[key]} entries (MuJoCo convention), got {size!r}"
        )
    res = {"n_triangles": n_triangles, "max_edge": max_edge}
    if key == "sphere":
        return sphere(s[0], **res)
    if key == "ellipsoid":
        return ellipsoid(s[:3], **res)
    if key == "capsule":
        return capsule(s[0], s[1], **res)
    if key == "cylinder":
        return cylinder(s[0], s[1], **res)
    return box(s[:3], **res)


# --------------------------------------------------------------------------------------------
# Meshes
# --------------------------------------------------------------------------------------------


def from_mesh_file(path: str | Path, *, scale: float = 1.0) -> ElementSet:
    """Load a triangle mesh file (STL/OBJ/PLY) as a checked, outward-wound ElementSet.

    Checks and repairs as :func:`from_mesh` (errors and MeshWarnings name the file).

    Args:
      path: mesh file; extension one of SUPPORTED_MESH_EXTENSIONS.
      scale: uniform factor applied to the file's coordinates to get metres (e.g. 1e-3 for mm).
    Returns:
      ElementSet in the mesh's own frame [m].
    Raises:
      ValueError: missing/unreadable file, unsupported extension, bad scale, invalid mesh.
    """
    p = Path(path)
    supported = ", ".join(SUPPORTED_MESH_EXTENSIONS)
    factor = _positive("scale", scale)
    if p.suffix.lower() not in SUPPORTED_MESH_EXTENSIONS:
        raise ValueError(f"mesh file {str(p)!r}: unsupported extension; supported: {supported}")
    if not p.is_file():
        raise ValueError(
            f"mesh file {str(p)!r} does not exist or is not a file (supported: {supported})"
        )
    # Imported here: trimesh (with the scipy.spatial it loads) is half a second of every import
    # of mjrft, and only files on disk need it (MJCF meshes come from the compiled MjModel).
    import trimesh

    try:
        mesh = trimesh.load(str(p), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for malformed files
        raise ValueError(
            f"could not read mesh file {str(p)!r} ({type(exc).__name__}: {exc}); "
            f"supported: {supported}"
        ) from exc
    vertices = getattr(mesh, "vertices", None)
    faces = getattr(mesh, "faces", None)
    if vertices is None or faces is None or len(faces) == 0:
        raise ValueError(f"mesh file {str(p)!r} contains no triangles (supported: {supported})")
    vertices = np.asarray(vertices, dtype=np.float64) * factor
    return _checked_elements(vertices, np.asarray(faces), str(p), stacklevel=3)


def from_mesh(
    vertices: np.ndarray | Sequence[Sequence[float]],
    faces: np.ndarray | Sequence[Sequence[int]],
    *,
    name: str = "<array>",
) -> ElementSet:
    """Check and repair a triangle mesh given as arrays, returning an outward-wound ElementSet.

    Steps (problems named by ``name``): non-finite vertices or out-of-range/non-integer face
    indices -> ValueError; exactly coincident vertices are merged (STL stores none shared);
    degenerate faces (repeated vertex or area < 1e-12 of the mean) are dropped with a
    MeshWarning; holes/non-manifold edges -> MeshWarning (mesh still used); inconsistent winding
    is repaired (MeshWarning), or ValueError if the surface is not orientable; an inward
    (negative signed volume) mesh is flipped (MeshWarning).

    Args:
      vertices: (m, 3) vertex positions [m], shape frame.
      faces: (n, 3) vertex indices.
      name: label used in messages (e.g. the source file name).
    Returns:
      ElementSet in the given frame [m].
    """
    return _checked_elements(vertices, faces, name, stacklevel=3)


def _warn(message: str, stacklevel: int) -> None:
    warnings.warn(message, MeshWarning, stacklevel=stacklevel + 1)


def _checked_elements(vertices: object, faces: object, name: str, *, stacklevel: int) -> ElementSet:
    """The ElementSet of a mesh after the load-time checks and repairs, step by step."""
    where = f"mesh {name!r}"
    v, f = _parsed(vertices, faces, where)
    v, f = _cleaned(v, f, where, stacklevel + 1)
    topo, f = _consistently_wound(v, f, where, stacklevel + 1)
    f = _outward(v, f, topo, where, stacklevel + 1)
    return ElementSet.from_triangles(v, f)


def _parsed(vertices: object, faces: object, where: str) -> tuple[np.ndarray, np.ndarray]:
    """(m, 3) finite float64 vertices and (n, 3) int64 faces indexing them, or ValueError."""
    try:
        v = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: vertices must be an (m, 3) array of numbers") from None
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise ValueError(f"{where}: vertices must have shape (m, 3), got {v.shape}")
    bad_v = np.flatnonzero(~np.all(np.isfinite(v), axis=1))
    if bad_v.size:
        raise ValueError(
            f"{where}: {bad_v.size} vertex/vertices with non-finite coordinates "
            f"(first: index {bad_v[0]}, {v[bad_v[0]].tolist()})"
        )
    f_raw = np.asarray(faces)
    if f_raw.ndim != 2 or f_raw.shape[1] != 3 or len(f_raw) == 0:
        raise ValueError(f"{where}: faces must have shape (n, 3) with n >= 1, got {f_raw.shape}")
    if np.issubdtype(f_raw.dtype, np.integer):
        f = f_raw.astype(np.int64)
    elif (
        np.issubdtype(f_raw.dtype, np.floating)
        and np.all(np.isfinite(f_raw))
        and np.all(f_raw == np.round(f_raw))
    ):
        f = f_raw.astype(np.int64)
    else:
        raise ValueError(f"{where}: face indices must be integers, got dtype {f_raw.dtype}")
    bad_f = np.flatnonzero(np.any((f < 0) | (f >= len(v)), axis=1))
    if bad_f.size:
        raise ValueError(
            f"{where}: {bad_f.size} face(s) index vertices outside [0, {len(v)}) "
            f"(first: face {bad_f[0]} = {f[bad_f[0]].tolist()})"
        )

    return v, f


def _cleaned(v: np.ndarray, f: np.ndarray, where: str, stacklevel: int):
    """Coincident vertices merged, degenerate faces dropped (warned), unused vertices removed."""
    # Merge exactly coincident vertices (keeping first-occurrence order); +0.0 folds -0.0.
    _, first, inverse = np.unique(v + 0.0, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    v = v[first[order]]
    f = rank[inverse][f]

    # Degenerate faces.
    tri = v[f]
    twice_area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    degenerate = repeated | ~(twice_area > _DEGENERATE_REL_AREA * twice_area.mean())
    if np.all(degenerate):
        raise ValueError(f"{where}: all {len(f)} faces are degenerate (zero area)")
    if np.any(degenerate):
        _warn(
            f"{where}: dropped {int(degenerate.sum())} degenerate triangle(s) "
            f"(repeated vertex or area < {_DEGENERATE_REL_AREA:g} x mean)",
            stacklevel,
        )
        f = f[~degenerate]

    # Remove vertices no face uses.
    used = np.zeros(len(v), dtype=bool)
    used[f.ravel()] = True
    if not np.all(used):
        remap = np.cumsum(used) - 1
        v, f = v[used], remap[f]

    return v, f


def _consistently_wound(v: np.ndarray, f: np.ndarray, where: str, stacklevel: int):
    """(topology, faces): open meshes warned about, inconsistent winding repaired (warned)."""
    # Topology: edge multiplicities, winding consistency, orientation.
    topo = _edge_topology(f, len(v))
    if not topo.watertight:
        details = []
        if topo.n_boundary:
            details.append(f"{topo.n_boundary} boundary edge(s)")
        if topo.n_nonmanifold:
            details.append(f"{topo.n_nonmanifold} non-manifold edge(s)")
        _warn(
            f"{where} is not watertight ({', '.join(details)}); volume and outward orientation "
            "are approximate",
            stacklevel,
        )
    if not topo.consistent:
        flip = _consistent_flips(len(f), topo.pairs, topo.parity)
        if flip is None:
            raise ValueError(
                f"{where}: face winding cannot be made consistent (non-orientable surface, "
                "e.g. a Moebius strip or self-glued sheets)"
            )
        f = f.copy()
        f[flip] = f[flip][:, ::-1]
        _warn(
            f"{where}: inconsistent face winding repaired ({int(flip.sum())} of {len(f)} "
            "faces flipped)",
            stacklevel,
        )
        if not _edge_topology(f, len(v)).consistent:
            raise ValueError(f"{where}: face winding still inconsistent after repair")

    return topo, f


def _outward(v: np.ndarray, f: np.ndarray, topo, where: str, stacklevel: int) -> np.ndarray:
    """Faces wound outward (an inward mesh is flipped, warned); inverted components warned."""
    centre = v.mean(axis=0)
    tri = v[f] - centre
    six_vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    volume = six_vol.sum() / 6.0
    diagonal = float(np.linalg.norm(np.ptp(v, axis=0)))
    threshold = 0.0 if topo.watertight else _OPEN_MESH_REL_VOLUME * diagonal**3
    if volume < -threshold:
        f = f[:, ::-1].copy()
        six_vol = -six_vol
        _warn(
            f"{where}: faces were wound inward (negative signed volume {volume:.6g}); flipped "
            "all faces so normals point outward",
            stacklevel,
        )
    if topo.watertight:
        labels = _components(len(f), topo.pairs)
        if labels.max() > 0:
            comp_vol = np.bincount(np.unique(labels, return_inverse=True)[1], weights=six_vol)
            n_neg = int(np.count_nonzero(comp_vol < 0.0))
            if n_neg:
                _warn(
                    f"{where}: {n_neg} of {len(comp_vol)} closed components enclose negative "
                    "volume (an inner cavity or an inverted body); left as is",
                    stacklevel,
                )
    return f


class _Topology(NamedTuple):
    watertight: bool  # every edge shared by exactly two faces
    consistent: bool  # every such pair traverses its shared edge in opposite directions
    n_boundary: int  # edges used by one face
    n_nonmanifold: int  # edges used by three or more faces
    pairs: np.ndarray  # (e, 2) faces sharing a two-face edge
    parity: np.ndarray  # (e,) bool, True where the pair traverses the edge the same way


def _edge_topology(f: np.ndarray, n_vertices: int) -> _Topology:
    """Edge multiplicities and the face pairs across manifold edges (parity 1 = same direction)."""
    start = f.reshape(-1)
    end = np.roll(f, -1, axis=1).reshape(-1)
    face_of = np.repeat(np.arange(len(f)), 3)
    key = np.minimum(start, end) * np.int64(n_vertices) + np.maximum(start, end)
    order = np.argsort(key, kind="stable")
    key_sorted = key[order]
    uniq_start = np.flatnonzero(np.r_[True, key_sorted[1:] != key_sorted[:-1]])
    counts = np.diff(np.r_[uniq_start, len(key_sorted)])
    two = uniq_start[counts == 2]
    e1, e2 = order[two], order[two + 1]
    pairs = np.column_stack([face_of[e1], face_of[e2]])
    parity = start[e1] == start[e2]  # same direction -> one face must flip relative to other
    return _Topology(
        watertight=bool(np.all(counts == 2)),
        consistent=not bool(np.any(parity)),
        n_boundary=int(np.count_nonzero(counts == 1)),
        n_nonmanifold=int(np.count_nonzero(counts > 2)),
        pairs=pairs,
        parity=parity,
    )


def _consistent_flips(n_faces: int, pairs: np.ndarray, parity: np.ndarray) -> np.ndarray | None:
    """Faces to flip so adjacent faces agree; per component the smaller set. None if impossible."""
    both = np.concatenate([pairs, pairs[:, ::-1]])
    par = np.concatenate([parity, parity]).astype(np.int64)
    order = np.argsort(both[:, 0], kind="stable")
    # Plain lists: the breadth-first search below is scalar Python, much faster on lists.
    nbr, nbr_par = both[order, 1].tolist(), par[order].tolist()
    offsets = np.searchsorted(both[order, 0], np.arange(n_faces + 1)).tolist()
    flip = [-1] * n_faces
    comp = [-1] * n_faces
    n_comp = 0
    for root in range(n_faces):
        if flip[root] >= 0:
            continue
        flip[root] = 0
        comp[root] = n_comp
        queue = deque([root])
        while queue:
            face = queue.popleft()
            for idx in range(offsets[face], offsets[face + 1]):
                other, want = nbr[idx], flip[face] ^ nbr_par[idx]
                if flip[other] < 0:
                    flip[other] = want
                    comp[other] = n_comp
                    queue.append(other)
                elif flip[other] != want:
                    return None
        n_comp += 1
    flipped = np.array(flip, dtype=bool)
    labels = np.array(comp, dtype=np.int64)
    # Within each component flip the minority so the fewest faces change.
    n_flipped = np.bincount(labels, weights=flipped, minlength=n_comp)
    size = np.bincount(labels, minlength=n_comp)
    invert = n_flipped > 0.5 * size
    return flipped ^ invert[labels]


def _components(n_faces: int, pairs: np.ndarray) -> np.ndarray:
    """Connected-component labels (n_faces,) of faces joined across manifold edges."""
    labels = np.arange(n_faces)
    if len(pairs) == 0:
        return labels
    while True:
        a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
        low = np.minimum(a, b)
        new = labels.copy()
        np.minimum.at(new, a, low)
        np.minimum.at(new, b, low)
        while True:  # pointer jumping to the root label
            jumped = new[new]
            if np.array_equal(jumped, new):
                break
            new = jumped
        if np.array_equal(new, labels):
            return labels
        labels = new
