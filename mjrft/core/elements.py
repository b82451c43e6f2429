"""Surface element sets: the triangles RFT integrates over, in a shape's own frame."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from mjrft.core import quadrature
from mjrft.core.patches import Surface


@dataclass(frozen=True, eq=False)
class ElementSet:
    """Triangulated surface as RFT elements, all arrays in the shape's own frame, SI units.

    Attributes:
      centroids: (n, 3) element positions [m]: triangle centroids, or for a primitive the area
        centroids of the curved patches (mjrft.core.patches).
      normals: (n, 3) outward unit normals.
      areas: (n,) triangle areas [m^2], all > 0.
      vertices: (m, 3) mesh vertices [m] (for drawing and volume checks).
      faces: (n, 3) int vertex indices, counter-clockwise seen from outside; row i is element i.
      corner_normals: (n, 3, 3) unit outward normals at each element's corners (row j: the
        corner faces[i, j]); the facet normal for a mesh, the analytic surface's for a
        primitive (mjrft.core.patches), whose ``normals`` and ``areas`` are then those of the
        curved patch the triangle stands for.
    """

    centroids: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    corner_normals: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        n = len(self.areas)
        if self.corner_normals is None:  # flat facets: the facet normal at every corner
            flat = np.repeat(np.asarray(self.normals)[:, None, :], 3, axis=1)
            object.__setattr__(self, "corner_normals", flat)
        shapes = {
            "centroids": (self.centroids.shape, (n, 3)),
            "normals": (self.normals.shape, (n, 3)),
            "areas": (self.areas.shape, (n,)),
            "faces": (self.faces.shape, (n, 3)),
            "corner_normals": (self.corner_normals.shape, (n, 3, 3)),
        }
        for name, (got, want) in shapes.items():
            if got != want:
                raise ValueError(f"ElementSet.{name} has shape {got}, expected {want}")
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3:
            raise ValueError(
                f"ElementSet.vertices has shape {self.vertices.shape}, expected (m, 3)"
            )
        for arr in (self.centroids, self.normals, self.areas, self.vertices, self.corner_normals):
            arr.setflags(write=False)
        self.faces.setflags(write=False)

    def __len__(self) -> int:
        return len(self.areas)

    @cached_property
    def quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        """(reach (n,) [m], patch (n, PATCH_SIZE)): the kernel's corner data
        (mjrft.core.quadrature), shape frame."""
        return quadrature.element_patches(self)

    @property
    def total_area(self) -> float:
        """Sum of element areas [m^2]."""
        return float(self.areas.sum())

    @property
    def volume(self) -> float:
        """Enclosed volume [m^3] by the divergence theorem (meaningful for closed surfaces)."""
        tri = self.vertices[self.faces]
        return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)

    @classmethod
    def from_triangles(
        cls, vertices: np.ndarray, faces: np.ndarray, surface: Surface | None = None
    ) -> ElementSet:
        """Build from a triangle mesh whose faces are wound counter-clockwise seen from outside.

        Args:
          vertices: (m, 3) vertex positions [m], shape frame.
          faces: (n, 3) vertex indices.
          surface: the analytic surface the vertices lie on (a primitive's), whose normals and
            patch areas the elements then carry; None: flat facets.
        Raises ValueError if any triangle is degenerate (zero area); drop those first.
        """
        vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        tri = vertices[faces]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        twice_area = np.linalg.norm(cross, axis=1)
        bad = np.flatnonzero(~(twice_area > 0))
        if bad.size:
            raise ValueError(
                f"{bad.size} degenerate triangle(s) (zero area), first at face index {bad[0]}; "
                "remove them before building an ElementSet"
            )
        if surface is None:
            return cls(
                centroids=tri.mean(axis=1),
                normals=cross / twice_area[:, None],
                areas=0.5 * twice_area,
                vertices=vertices,
                faces=faces,
            )
        p = surface.patches(vertices, faces)
        return cls(
            centroids=p.centroids,
            normals=p.normals,
            areas=p.areas,
            vertices=vertices,
            faces=faces,
            corner_normals=p.corner_normals,
        )

    def transformed(self, rotation: np.ndarray, translation: np.ndarray) -> ElementSet:
        """Same surface expressed in a parent frame: x_parent = rotation @ x + translation.

        Args:
          rotation: (3, 3) rotation matrix, shape frame -> parent frame.
          translation: (3,) position of the shape origin in the parent frame [m].
        """
        r = np.asarray(rotation, dtype=np.float64)
        t = np.asarray(translation, dtype=np.float64)
        return ElementSet(
            centroids=self.centroids @ r.T + t,
            normals=self.normals @ r.T,
            areas=self.areas.copy(),
            vertices=self.vertices @ r.T + t,
            faces=self.faces.copy(),
            corner_normals=self.corner_normals @ r.T,
        )
