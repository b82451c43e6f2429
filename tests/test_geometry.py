"""Shape tessellation and mesh loading (mjrft.geometry) against analytic geometry.

Observed convergence orders (fit of log relative error vs log n_triangles, n ~ 250..16000;
printed by test_convergence_order with ``pytest -s``): error ~ n^p with

    shape        area p   volume p
    sphere       -1.02    -1.01
    ellipsoid    -0.99    -0.99
    capsule      -0.86    -0.86   (even azimuth counts: coarse steps at low counts)
    cylinder     -0.96    -0.95
    paraboloid   -1.01    -1.02

i.e. O(h^2) in the edge length h ~ n^-1/2, as expected for polyhedra inscribed in smooth surfaces.
"""

import math
import warnings

import numpy as np
import pytest
import trimesh
from scipy import integrate

from mjrft import geometry
from mjrft.core.elements import ElementSet
from mjrft.geometry import MeshWarning

# Float64 round-off on O(1)-scaled sums of up to ~1e4 terms, with headroom.
EXACT = 1e-12
# Convergence order: theory says p = -1 (O(h^2)); the triangle count moves in discrete, slightly
# uneven steps between resolutions (coarser since the mid-plane counts are kept even), which
# jitters the fitted slope: fitted over 13 targets a factor sqrt(2) apart to average that out.
SLOPE_TOL = 0.15
CONVERGENCE_TARGETS = np.round(250 * 2 ** np.arange(0.0, 6.01, 0.5)).astype(int)  # 250..16000
# n_triangles is honoured to within this fraction for targets >= 50 (step granularity of the
# structured lattices; measured worst case ~20 % over many shapes and aspect ratios).
COUNT_TOL = 0.25
# Relative error of area/volume allowed at ~16000 triangles (observed <= 1.2e-3).
FINE_REL_ERR = 3e-3

R = 0.05
AXES = (0.06, 0.04, 0.025)
CAP_R, CAP_H = 0.02, 0.05
PAR_R, PAR_L = 0.01, 0.03
HALF = (0.03, 0.02, 0.01)


def ellipsoid_area_quadrature(a, b, c):
    """Ellipsoid surface area by 2-D adaptive quadrature of |dr/dtheta x dr/dphi|."""

    def integrand(theta, phi):
        st, ct, sp, cp = math.sin(theta), math.cos(theta), math.sin(phi), math.cos(phi)
        dth = np.array([a * ct * cp, b * ct * sp, -c * st])
        dph = np.array([-a * st * sp, b * st * cp, 0.0])
        return float(np.linalg.norm(np.cross(dth, dph)))

    val, _ = integrate.dblquad(integrand, 0.0, 2.0 * math.pi, 0.0, math.pi, epsabs=0, epsrel=1e-11)
    return val


def paraboloid_area(radius, length):
    lateral = math.pi * radius / (6 * length**2) * ((radius**2 + 4 * length**2) ** 1.5 - radius**3)
    return lateral + math.pi * radius**2


# name -> (factory(**resolution), interior centre, exact area, exact volume)
CURVED = {
    "sphere": (
        lambda **kw: geometry.sphere(R, **kw),
        (0, 0, 0),
        4 * math.pi * R**2,
        4 / 3 * math.pi * R**3,
    ),
    "ellipsoid": (
        lambda **kw: geometry.ellipsoid(AXES, **kw),
        (0, 0, 0),
        None,  # quadrature reference, computed in the test
        4 / 3 * math.pi * math.prod(AXES),
    ),
    "capsule": (
        lambda **kw: geometry.capsule(CAP_R, CAP_H, **kw),
        (0, 0, 0),
        4 * math.pi * CAP_R**2 + 4 * math.pi * CAP_R * CAP_H,
        4 / 3 * math.pi * CAP_R**3 + 2 * math.pi * CAP_R**2 * CAP_H,
    ),
    "cylinder": (
        lambda **kw: geometry.cylinder(CAP_R, CAP_H, **kw),
        (0, 0, 0),
        2 * math.pi * CAP_R**2 + 4 * math.pi * CAP_R * CAP_H,
        2 * math.pi * CAP_R**2 * CAP_H,
    ),
    "paraboloid": (
        lambda **kw: geometry.paraboloid(PAR_R, PAR_L, **kw),
        (0, 0, 0.5 * PAR_L),
        paraboloid_area(PAR_R, PAR_L),
        math.pi * PAR_R**2 * PAR_L / 2,
    ),
}
ALL = {
    **CURVED,
    "box": (
        lambda **kw: geometry.box(HALF, **kw),
        (0, 0, 0),
        8 * (HALF[0] * HALF[1] + HALF[1] * HALF[2] + HALF[2] * HALF[0]),
        8 * math.prod(HALF),
    ),
}
# Slender / flat variants: the hard cases for count targeting and surface maps.
EXTREME = {
    "thin_cylinder": (lambda **kw: geometry.cylinder(0.002, 0.2, **kw), (0, 0, 0)),
    "disc_cylinder": (lambda **kw: geometry.cylinder(0.2, 0.002, **kw), (0, 0, 0)),
    "thin_capsule": (lambda **kw: geometry.capsule(0.002, 0.2, **kw), (0, 0, 0)),
    "flat_capsule": (lambda **kw: geometry.capsule(0.2, 0.001, **kw), (0, 0, 0)),
    "needle_paraboloid": (lambda **kw: geometry.paraboloid(0.001, 0.05, **kw), (0, 0, 0.025)),
    "flat_paraboloid": (lambda **kw: geometry.paraboloid(0.05, 0.002, **kw), (0, 0, 0.0015)),
    "pancake_ellipsoid": (lambda **kw: geometry.ellipsoid((0.1, 0.001, 0.05), **kw), (0, 0, 0)),
    "plank_box": (lambda **kw: geometry.box((0.5, 0.005, 0.05), **kw), (0, 0, 0)),
}
SHAPES = {**{k: v[:2] for k, v in ALL.items()}, **EXTREME}


def exact_area(name):
    if name == "ellipsoid":
        return ellipsoid_area_quadrature(*AXES)
    return ALL[name][2]


def edge_multiplicity(faces):
    """(undirected edges each used by exactly two faces, every directed edge used once)."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    _, undirected_counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    _, directed_counts = np.unique(directed, axis=0, return_counts=True)
    return bool(np.all(undirected_counts == 2)), bool(np.all(directed_counts == 1))


def all_edge_lengths(es):
    tri = es.vertices[es.faces]
    return np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).ravel()


# --------------------------------------------------------------------------------------------
# Primitives: structure
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(SHAPES))
@pytest.mark.parametrize("n", [12, 100, 1000])
def test_normals_unit_outward_and_mesh_closed(name, n):
    factory, centre = SHAPES[name]
    es = factory(n_triangles=n)
    assert isinstance(es, ElementSet)
    np.testing.assert_allclose(np.linalg.norm(es.normals, axis=1), 1.0, atol=EXACT)
    # Convex shapes: every outward normal points away from an interior point.
    assert np.all(np.einsum("ij,ij->i", es.normals, es.centroids - np.asarray(centre)) > 0)
    watertight, consistent = edge_multiplicity(np.asarray(es.faces))
    assert watertight and consistent
    assert es.volume > 0
    assert len(np.unique(es.faces)) == len(es.vertices)  # no stray vertices
    # No slivers: structured grids keep every triangle within a bounded area ratio of the mean.
    assert es.areas.min() > 1e-3 * es.areas.mean()


def test_vertices_lie_on_the_analytic_surfaces():
    v = geometry.sphere(R).vertices
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), R, rtol=EXACT)
    v = geometry.ellipsoid(AXES).vertices
    np.testing.assert_allclose(np.sum((v / AXES) ** 2, axis=1), 1.0, rtol=EXACT)
    v = geometry.box(HALF).vertices
    np.testing.assert_allclose(np.max(np.abs(v) / HALF, axis=1), 1.0, rtol=EXACT)

    v = geometry.cylinder(CAP_R, CAP_H).vertices
    rho = np.hypot(v[:, 0], v[:, 1])
    on_cap = np.isclose(np.abs(v[:, 2]), CAP_H, rtol=EXACT)
    assert np.all(rho <= CAP_R * (1 + EXACT))
    np.testing.assert_allclose(rho[~on_cap], CAP_R, rtol=EXACT)

    v = geometry.capsule(CAP_R, CAP_H).vertices
    axial = np.clip(v[:, 2], -CAP_H, CAP_H)
    dist = np.linalg.norm(v - np.column_stack([0 * axial, 0 * axial, axial]), axis=1)
    np.testing.assert_allclose(dist, CAP_R, rtol=EXACT)

    v = geometry.paraboloid(PAR_R, PAR_L).vertices
    rho2 = v[:, 0] ** 2 + v[:, 1] ** 2
    on_base = np.isclose(v[:, 2], PAR_L, rtol=EXACT)
    assert np.all(rho2 <= PAR_R**2 * (1 + EXACT))
    np.testing.assert_allclose(v[~on_base, 2], PAR_L * rho2[~on_base] / PAR_R**2, atol=EXACT)
    assert np.min(v[:, 2]) == pytest.approx(0.0, abs=EXACT)  # apex at the origin, pointing -z
    assert np.all(v[:, 2] >= -EXACT)


def test_box_is_exact_with_uniform_congruent_faces():
    for n in (12, 200, 2000):
        es = geometry.box(HALF, n_triangles=n)
        assert es.total_area == pytest.approx(ALL["box"][2], rel=EXACT)
        assert es.volume == pytest.approx(ALL["box"][3], rel=EXACT)
        # Uniform grid: one triangle size per pair of opposite faces.
        assert len(np.unique(np.round(es.areas / es.areas.max(), 9))) <= 3
    assert len(geometry.box(HALF, n_triangles=12)) == 12


# --------------------------------------------------------------------------------------------
# Primitives: convergence to analytic area and volume
# --------------------------------------------------------------------------------------------


def test_ellipsoid_area_reference_agrees_with_thomsen():
    # Knud Thomsen's approximation (p = 1.6075) is good to about 1 %: only a sanity check here.
    a, b, c = AXES
    p = 1.6075
    thomsen = 4 * math.pi * (((a * b) ** p + (a * c) ** p + (b * c) ** p) / 3) ** (1 / p)
    assert ellipsoid_area_quadrature(a, b, c) == pytest.approx(thomsen, rel=0.011)
    # Sphere limit of the quadrature is exact.
    assert ellipsoid_area_quadrature(R, R, R) == pytest.approx(4 * math.pi * R**2, rel=1e-9)


@pytest.mark.parametrize("name", list(CURVED))
def test_convergence_order(name):
    factory, _, _, volume = CURVED[name]
    area = exact_area(name)
    counts, err_area, err_vol, err_patch = [], [], [], []
    for n in CONVERGENCE_TARGETS:
        es = factory(n_triangles=int(n))
        counts.append(len(es))
        chords = ElementSet.from_triangles(es.vertices, es.faces)  # the inscribed polyhedron
        err_area.append(abs(chords.total_area / area - 1.0))
        err_vol.append(abs(es.volume / volume - 1.0))
        err_patch.append(abs(es.total_area / area - 1.0))  # the curved patches' areas
    # Inscribed polyhedra: errors shrink monotonically (between targets 4x apart; between
    # neighbours a step may refine only a flat span, e.g. a capsule's tube).
    assert np.all(np.diff(err_area[::4]) < 0) and np.all(np.diff(err_vol[::4]) < 0)
    slope_area = np.polyfit(np.log(counts), np.log(err_area), 1)[0]
    slope_vol = np.polyfit(np.log(counts), np.log(err_vol), 1)[0]
    print(f"{name}: area error ~ n^{slope_area:.3f}, volume error ~ n^{slope_vol:.3f}")
    assert slope_area == pytest.approx(-1.0, abs=SLOPE_TOL)
    assert slope_vol == pytest.approx(-1.0, abs=SLOPE_TOL)
    assert err_area[-1] < FINE_REL_ERR and err_vol[-1] < FINE_REL_ERR
    # The elements carry their patches' areas (mjrft.core.patches): O(h^4) = O(n^-2), or
    # rounding-level already; at every count far below the chords' error.
    assert all(p < 0.05 * a for p, a in zip(err_patch, err_area, strict=True))


# --------------------------------------------------------------------------------------------
# Resolution control
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(SHAPES))
def test_n_triangles_is_honoured(name):
    factory, _ = SHAPES[name]
    rng = np.random.default_rng(12345)
    targets = np.unique(np.round(np.exp(rng.uniform(np.log(50), np.log(5000), 25))).astype(int))
    for n in targets:
        got = len(factory(n_triangles=int(n)))
        assert abs(got / n - 1.0) <= COUNT_TOL, (name, n, got)


@pytest.mark.parametrize("name", list(SHAPES))
def test_minimum_and_default_resolution(name):
    factory, _ = SHAPES[name]
    smallest = factory(n_triangles=1)
    assert len(smallest) >= geometry.MIN_TRIANGLES
    assert len(smallest) <= 80  # capsule: 2 azimuth cells per quarter turn, 2 tube cells
    assert len(factory(n_triangles=1.0)) == len(smallest)  # integral float accepted
    default = len(factory())
    assert abs(default / geometry.DEFAULT_N_TRIANGLES - 1.0) <= COUNT_TOL


@pytest.mark.parametrize("name", list(SHAPES))
def test_max_edge_is_honoured(name):
    factory, _ = SHAPES[name]
    sizes = []
    for frac in (0.3, 0.1, 0.05):
        extent = np.ptp(factory(n_triangles=12).vertices, axis=0).max()
        max_edge = frac * extent
        es = factory(max_edge=max_edge)
        assert np.all(all_edge_lengths(es) <= max_edge)
        sizes.append(len(es))
    assert sizes[0] <= sizes[1] <= sizes[2]
    # Not wildly over-refined: halving max_edge costs about 4x the triangles.
    assert sizes[2] / sizes[1] < 8.0


def test_max_edge_exactly_at_a_mesh_edge_length():
    # max_edge equal to an achieved longest edge must be accepted (<=, not <).
    es = geometry.box((0.5, 0.5, 0.5), n_triangles=12)
    longest = all_edge_lengths(es).max()
    assert len(geometry.box((0.5, 0.5, 0.5), max_edge=longest)) == 12


def test_too_fine_resolution_is_refused():
    with pytest.raises(ValueError, match="max_edge"):
        geometry.sphere(1.0, max_edge=1e-4)
    with pytest.raises(ValueError, match="n_triangles"):
        geometry.sphere(1.0, n_triangles=geometry.MAX_TRIANGLES + 1)


# --------------------------------------------------------------------------------------------
# primitive() dispatcher
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kind", "size", "direct"),
    [
        ("sphere", (0.1, 0, 0), lambda: geometry.sphere(0.1, n_triangles=300)),
        ("ellipsoid", AXES, lambda: geometry.ellipsoid(AXES, n_triangles=300)),
        ("capsule", (0.02, 0.05, 0), lambda: geometry.capsule(0.02, 0.05, n_triangles=300)),
        ("cylinder", (0.02, 0.05), lambda: geometry.cylinder(0.02, 0.05, n_triangles=300)),
        ("box", HALF, lambda: geometry.box(HALF, n_triangles=300)),
        ("BOX", HALF, lambda: geometry.box(HALF, n_triangles=300)),
    ],
)
def test_primitive_matches_direct_constructors(kind, size, direct):
    got, want = geometry.primitive(kind, size, n_triangles=300), direct()
    np.testing.assert_array_equal(got.vertices, want.vertices)
    np.testing.assert_array_equal(got.faces, want.faces)


def test_primitive_rejects_unknown_kind_and_short_size():
    with pytest.raises(ValueError, match="sphere, ellipsoid, capsule, cylinder, box"):
        geometry.primitive("mesh", (1, 1, 1))
    with pytest.raises(ValueError, match="at least 2"):
        geometry.primitive("capsule", (0.1,))
    with pytest.raises(ValueError, match="max_edge"):
        geometry.primitive("box", HALF, max_edge=0.0)


# --------------------------------------------------------------------------------------------
# Bad parameters
# --------------------------------------------------------------------------------------------

BAD_PARAMETERS = [
    (geometry.sphere, (0.0,), {}, "radius"),
    (geometry.sphere, (-1.0,), {}, "radius"),
    (geometry.sphere, (math.nan,), {}, "radius"),
    (geometry.sphere, (math.inf,), {}, "radius"),
    (geometry.sphere, ("big",), {}, "radius"),
    (geometry.ellipsoid, ((1.0, 0.0, 1.0),), {}, "semi_axes"),
    (geometry.ellipsoid, ((1.0, 1.0),), {}, "semi_axes"),
    (geometry.capsule, (0.1, 0.0), {}, "half_length"),
    (geometry.capsule, (-0.1, 0.2), {}, "radius"),
    (geometry.cylinder, (0.1, math.nan), {}, "half_length"),
    (geometry.box, ((0.1, -0.1, 0.1),), {}, "half_sizes"),
    (geometry.box, ((0.1, 0.1, math.inf),), {}, "half_sizes"),
    (geometry.paraboloid, (0.01, 0.0), {}, "length"),
    (geometry.paraboloid, (0.0, 0.05), {}, "radius"),
    (geometry.sphere, (0.1,), {"n_triangles": 0}, "n_triangles"),
    (geometry.sphere, (0.1,), {"n_triangles": -10}, "n_triangles"),
    (geometry.sphere, (0.1,), {"n_triangles": 100.5}, "n_triangles"),
    (geometry.sphere, (0.1,), {"n_triangles": True}, "n_triangles"),
    (geometry.sphere, (0.1,), {"n_triangles": math.nan}, "n_triangles"),
    (geometry.box, (HALF,), {"max_edge": 0.0}, "max_edge"),
    (geometry.box, (HALF,), {"max_edge": -0.01}, "max_edge"),
    (geometry.capsule, (0.1, 0.1), {"max_edge": math.nan}, "max_edge"),
    (geometry.cylinder, (0.1, 0.1), {"max_edge": math.inf}, "max_edge"),
    (geometry.sphere, (0.1,), {"n_triangles": 100, "max_edge": 0.01}, "n_triangles and max_edge"),
]


@pytest.mark.parametrize(("fn", "args", "kwargs", "param"), BAD_PARAMETERS)
def test_bad_parameters_raise_value_error_naming_them(fn, args, kwargs, param):
    with pytest.raises(ValueError, match=param):
        fn(*args, **kwargs)


# --------------------------------------------------------------------------------------------
# Mesh files and arrays
# --------------------------------------------------------------------------------------------

BOX_EXTENTS = (0.2, 0.1, 0.05)


def box_mesh():
    mesh = trimesh.creation.box(extents=BOX_EXTENTS)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


BOX_AREA = 2 * (0.2 * 0.1 + 0.1 * 0.05 + 0.05 * 0.2)
BOX_VOLUME = 0.2 * 0.1 * 0.05
# STL and PLY store float32 coordinates: relative error ~1e-7.
FLOAT32 = 1e-6


def write(tmp_path, name, vertices, faces):
    path = tmp_path / name
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    return path


def load_strict(path, **kw):
    """Load, failing on any MeshWarning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", MeshWarning)
        return geometry.from_mesh_file(path, **kw)


def assert_outward_box(es, scale=1.0):
    assert es.total_area == pytest.approx(BOX_AREA * scale**2, rel=FLOAT32)
    assert es.volume == pytest.approx(BOX_VOLUME * scale**3, rel=FLOAT32)
    assert np.all(np.einsum("ij,ij->i", es.normals, es.centroids) > 0)


@pytest.mark.parametrize("ext", ["stl", "obj", "ply", "STL"])
def test_clean_mesh_file_loads_without_warnings(tmp_path, ext):
    path = write(tmp_path, f"box.{ext}", *box_mesh())
    es = load_strict(path)
    assert len(es) == 12
    assert_outward_box(es)
    assert_outward_box(load_strict(path, scale=1e-3), scale=1e-3)
    assert_outward_box(load_strict(str(path)))  # str paths too


def test_stl_triangle_soup_is_welded_watertight(tmp_path):
    v, f = box_mesh()
    soup_v, soup_f = v[f].reshape(-1, 3), np.arange(3 * len(f)).reshape(-1, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MeshWarning)
        es = geometry.from_mesh(soup_v, soup_f)
    assert len(es.vertices) == 8
    assert_outward_box(es)


@pytest.mark.parametrize("ext", ["stl", "obj"])
def test_all_faces_flipped_is_reoriented_with_warning(tmp_path, ext):
    v, f = box_mesh()
    path = write(tmp_path, f"inside_out.{ext}", v, f[:, ::-1])
    with pytest.warns(MeshWarning, match="inward") as record:
        es = geometry.from_mesh_file(path)
    assert str(path) in str(record[0].message)
    assert_outward_box(es)


def test_some_faces_flipped_are_repaired_with_warning(tmp_path):
    v, f = box_mesh()
    f = f.copy()
    f[[1, 4, 7]] = f[[1, 4, 7], ::-1]
    path = write(tmp_path, "patchy.obj", v, f)
    with pytest.warns(MeshWarning, match="inconsistent face winding repaired") as record:
        es = geometry.from_mesh_file(path)
    assert str(path) in str(record[0].message)
    assert "3 of 12" in str(record[0].message)
    assert_outward_box(es)


def test_mostly_inward_patchy_mesh_ends_outward(tmp_path):
    v, f = box_mesh()
    f = f[:, ::-1].copy()
    f[[0, 5]] = f[[0, 5], ::-1]
    with pytest.warns(MeshWarning) as record:
        es = geometry.from_mesh(v, f, name="patchy_inward")
    messages = " | ".join(str(w.message) for w in record)
    assert "inconsistent" in messages and "inward" in messages and "patchy_inward" in messages
    assert_outward_box(es)


def test_open_mesh_warns_not_watertight(tmp_path):
    v, f = box_mesh()
    path = write(tmp_path, "open.ply", v, f[1:])
    with pytest.warns(MeshWarning, match="not watertight") as record:
        es = geometry.from_mesh_file(path)
    assert str(path) in str(record[0].message)
    assert len(es) == 11
    assert np.all(np.einsum("ij,ij->i", es.normals, es.centroids) > 0)


def test_open_inward_mesh_is_flipped(tmp_path):
    v, f = box_mesh()
    with pytest.warns(MeshWarning) as record:
        es = geometry.from_mesh(v, f[1:, ::-1], name="open_inward")
    assert any("inward" in str(w.message) for w in record)
    assert np.all(np.einsum("ij,ij->i", es.normals, es.centroids) > 0)


def test_degenerate_triangles_are_dropped_with_count(tmp_path):
    v, f = box_mesh()
    # A repeated-index face, and a zero-area face on three collinear points (a new midpoint).
    v2 = np.vstack([v, 0.5 * (v[f[0, 0]] + v[f[0, 1]])])
    collinear = [f[0, 0], f[0, 1], len(v)]
    f2 = np.vstack([f, [[0, 0, 1]], [collinear]])
    with pytest.warns(MeshWarning, match="dropped 2 degenerate") as record:
        es = geometry.from_mesh(v2, f2, name="slivers")
    assert "slivers" in str(record[0].message)
    assert len(es) == 12
    assert_outward_box(es)

    path = write(tmp_path, "degenerate.stl", v, np.vstack([f, [[0, 0, 1], [2, 3, 3]]]))
    with pytest.warns(MeshWarning, match="dropped 2 degenerate") as record:
        es = geometry.from_mesh_file(path)
    assert str(path) in str(record[0].message)
    assert_outward_box(es)


def test_second_body_inverted_is_reported(tmp_path):
    v, f = box_mesh()
    small = 0.1 * v + np.array([1.0, 0.0, 0.0])
    vv = np.vstack([v, small])
    ff = np.vstack([f, f[:, ::-1] + len(v)])
    with pytest.warns(MeshWarning, match="negative volume"):
        geometry.from_mesh(vv, ff, name="two_bodies")


def test_non_orientable_mesh_raises():
    # Moebius strip: 12 quads around a loop with a half twist.
    k = 12
    t = np.linspace(0.0, 2 * math.pi, k, endpoint=False)
    verts = []
    for ti in t:
        for s in (-0.1, 0.1):
            verts.append(
                [
                    (1 + s * math.cos(ti / 2)) * math.cos(ti),
                    (1 + s * math.cos(ti / 2)) * math.sin(ti),
                    s * math.sin(ti / 2),
                ]
            )
    faces = []
    for i in range(k):
        a, b = 2 * i, 2 * i + 1
        if i < k - 1:
            c, d = 2 * i + 2, 2 * i + 3
        else:  # the half twist swaps the strip's sides
            c, d = 1, 0
        faces += [[a, c, d], [a, d, b]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MeshWarning)  # it is also open
        with pytest.raises(ValueError, match=r"moebius_strip.*cannot be made consistent"):
            geometry.from_mesh(np.array(verts), np.array(faces), name="moebius_strip")


def test_missing_and_unsupported_files_raise_naming_path(tmp_path):
    missing = tmp_path / "nope.stl"
    with pytest.raises(ValueError, match=r"nope.stl") as info:
        geometry.from_mesh_file(missing)
    assert ".obj" in str(info.value)
    with pytest.raises(ValueError, match=r"\.stl, \.obj, \.ply"):
        geometry.from_mesh_file(tmp_path / "mesh.dae")
    garbage = tmp_path / "garbage.ply"
    garbage.write_bytes(b"definitely not a ply file\x00\x01")
    with pytest.raises(ValueError, match=r"garbage.ply"):
        geometry.from_mesh_file(garbage)
    with pytest.raises(ValueError, match="scale"):
        geometry.from_mesh_file(write(tmp_path, "ok.stl", *box_mesh()), scale=0.0)


def test_non_finite_vertices_and_bad_indices_raise_naming_source(tmp_path):
    v, f = box_mesh()
    v_bad = v.copy()
    v_bad[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"bracket.*non-finite"):
        geometry.from_mesh(v_bad, f, name="bracket")
    obj = tmp_path / "nan.obj"
    obj.write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match=r"nan.obj.*non-finite"):
        geometry.from_mesh_file(obj)
    with pytest.raises(ValueError, match=r"plate.*outside"):
        geometry.from_mesh(v, np.vstack([f, [[0, 1, 8]]]), name="plate")
    with pytest.raises(ValueError, match=r"plate.*outside"):
        geometry.from_mesh(v, np.vstack([f, [[0, 1, -1]]]), name="plate")
    with pytest.raises(ValueError, match=r"plate.*integers"):
        geometry.from_mesh(v, f + 0.5, name="plate")
    with pytest.raises(ValueError, match=r"plate.*\(m, 3\)"):
        geometry.from_mesh(v[:, :2], f, name="plate")


def test_from_mesh_of_a_primitive_round_trips_silently():
    es = geometry.capsule(CAP_R, CAP_H, n_triangles=800)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MeshWarning)
        again = geometry.from_mesh(es.vertices, es.faces)
    np.testing.assert_array_equal(again.faces, es.faces)
    # a mesh is its flat facets: the primitive's chord triangles, not its curved patches
    np.testing.assert_allclose(
        again.normals, ElementSet.from_triangles(es.vertices, es.faces).normals
    )
