"""The dimension-generic core: Mesh, metrics, material fields and density in 2D and 3D."""

from __future__ import annotations

import numpy as np
import pytest

from hetmesh.density import density
from hetmesh.errors import MaterialError, MeshDataError
from hetmesh.material import AnalyticField, CallableField, PiecewiseField, field_dim
from hetmesh.mesh import Mesh, cell_faces
from hetmesh.metrics import (
    delta_dense,
    delta_vertices,
    dihedral_angles,
    quality,
    quality_and_angle,
    statistics,
    tet_quality,
    tet_volumes6,
)

REGULAR = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)


def cube_mesh(n: int = 3, seed: int = 0) -> Mesh:
    """The unit cube in n^3 cells of six Kuhn tetrahedra each, inner nodes jittered."""
    g = np.linspace(0.0, 1.0, n + 1)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    inner = ((p > 0) & (p < 1)).all(axis=1)
    p[inner] += np.random.default_rng(seed).uniform(-0.1, 0.1, (inner.sum(), 3)) / n
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    corner = idx[:-1, :-1, :-1].ravel()
    step = np.array([(n + 1) ** 2, n + 1, 1])
    tets = []
    for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        a = corner
        b = a + step[perm[0]]
        c = b + step[perm[1]]
        d = c + step[perm[2]]
        tets.append(np.column_stack([a, b, c, d]))
    return Mesh(p, np.concatenate(tets))


def test_tet_mesh_is_oriented_measured_and_valid():
    m = cube_mesh()
    assert m.dim == 3 and m.cell_type == "tetra" and m.facet_type == "triangle"
    assert (m.measures > 0).all()
    assert m.measure == pytest.approx(1.0, rel=1e-12)
    assert (tet_volumes6(m.points, m.cells) > 0).all()
    assert m.problems() == []
    # boundary: 6 faces x 2 n^2 triangles, outward normals
    b = m.boundary_facets
    assert len(b) == 6 * 2 * 9
    p = m.points
    normal = np.cross(p[b[:, 1]] - p[b[:, 0]], p[b[:, 2]] - p[b[:, 0]])
    out = p[b].mean(axis=1) - 0.5
    assert (np.einsum("ij,ij->i", normal, out) > 0).all()


def test_tet_mesh_problems_are_found():
    m = cube_mesh()
    notch = Mesh(m.points, m.cells[1:])   # a corner tet removed: the surface stays closed
    assert notch.problems() == []
    twice = Mesh(m.points, np.r_[m.cells, m.cells[:1]])
    assert any("more than two tetrahedra" in s for s in twice.problems())
    flat = Mesh(np.r_[m.points, [[0.5, 0.5, 2.0]]], m.cells)
    assert flat.problems() == ["1 point is not used by any tetrahedron"]
    with pytest.raises(MeshDataError, match=r"shape \(M, 4\)"):
        Mesh(m.points, m.cells[:, :3])


def test_open_boundary_is_reported():
    # two tets sharing a face plus one touching only at an edge: a pinched surface
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1],
                  [1, 1, 0.5], [1, 1, -0.5]], float)
    t = np.array([[0, 1, 2, 3], [0, 2, 1, 4], [1, 2, 5, 6]])
    m = Mesh(p, t)
    assert any("closed surface" in s for s in m.problems())


def test_cell_faces_cover_every_vertex_pair():
    f = cell_faces(np.array([[0, 1, 2, 3]]))[:, 0]
    assert sorted(map(sorted, f.tolist())) == [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]


def test_tet_quality_and_dihedrals():
    t = np.array([[0, 1, 2, 3]])
    assert tet_quality(REGULAR, t)[0] == pytest.approx(1.0, abs=1e-12)
    assert np.allclose(dihedral_angles(REGULAR, t), np.degrees(np.arccos(1 / 3)))
    corner = np.eye(4, 3, k=-1)
    assert tet_quality(corner, t)[0] == pytest.approx(np.sqrt(3) - 1, rel=1e-12)
    assert sorted(dihedral_angles(corner, t)[0].round(6)) == pytest.approx(
        [54.735610] * 3 + [90.0] * 3, abs=1e-6)
    # a sliver: four nearly coplanar points, good edge lengths, quality near 0
    sliver = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.5, 1e-3], [0.5, -0.5, 1e-3]], float)
    assert tet_quality(sliver, t)[0] < 0.01
    assert dihedral_angles(sliver, t).min() < 1.0
    q, a = quality_and_angle(REGULAR, t)
    assert q[0] == pytest.approx(1.0) and a[0] == pytest.approx(70.528779, abs=1e-6)
    assert quality(REGULAR, t)[0] == pytest.approx(1.0)


def test_delta_on_tets_matches_a_brute_force_reduction():
    m = cube_mesh(4, seed=3)
    rng = np.random.default_rng(5)
    comp = rng.random((m.n_points, 3))
    comp /= comp.sum(axis=1, keepdims=True)
    v = comp[m.cells]
    brute = (v.max(axis=1) - v.min(axis=1)).max(axis=1)
    assert np.array_equal(delta_vertices(comp, m.cells), brute)
    stats = statistics(m.points, m.cells, brute)
    assert stats.n_elements == m.n_elements and 0 < stats.angle_min < 90


def test_dense_delta_on_tets_sees_an_inner_peak():
    f = AnalyticField({"metal": "exp(-100*((x-0.25)**2 + (y-0.25)**2 + (z-0.25)**2))"},
                      ["ceramic", "metal"], dim=3)
    p = np.eye(4, 3, k=-1)
    t = np.array([[0, 1, 2, 3]])
    vert = delta_vertices(f.composition(p), t)[0]
    dense = delta_dense(f, p, t)[0]
    assert dense > vert + 0.5   # the peak sits at the order-4 lattice point (1/4, 1/4, 1/4)


def test_analytic_field_in_3d():
    f = AnalyticField({"metal": "(1 - z)**2 + 0.1*x*y"}, ["ceramic", "metal"], dim=3)
    assert f.dim == 3 and field_dim(f) == 3
    p = np.array([[0.5, 0.2, 0.25], [0.1, 0.9, 0.0]])
    c = f.composition(p)
    assert c[:, 1] == pytest.approx((1 - p[:, 2]) ** 2 + 0.1 * p[:, 0] * p[:, 1])
    g = f.gradient(p)
    assert g.shape == (2, 2, 3)
    assert g[:, 1] == pytest.approx(np.column_stack([0.1 * p[:, 1], 0.1 * p[:, 0],
                                                     -2 * (1 - p[:, 2])]))
    assert g[:, 0] == pytest.approx(-g[:, 1])
    s = f.shifted([0.0, 0.0, 0.5])
    assert s.composition(p) == pytest.approx(f.composition(p + [0, 0, 0.5]))
    # a kink: the finite-difference fallback works along z too
    k = AnalyticField({"metal": "sqrt(z)"}, ["ceramic", "metal"], dim=3)
    assert np.isfinite(k.gradient([[0.3, 0.3, 0.0]])).all()
    with pytest.raises(MaterialError, match=r"shape \(N, 3\)"):
        f.composition([[0.0, 0.0]])


def test_formula_in_a_missing_variable_is_named():
    with pytest.raises(MaterialError, match="z"):
        AnalyticField({"metal": "z"}, ["ceramic", "metal"])
    with pytest.raises(MaterialError, match="dim must be 2 or 3"):
        AnalyticField({"metal": "x"}, ["ceramic", "metal"], dim=4)


def test_piecewise_protocol():
    smooth = AnalyticField({"metal": "x"}, ["ceramic", "metal"])
    jump = AnalyticField({"metal": "where(z < 0.5, 0.2, 0.8)"}, ["ceramic", "metal"], dim=3)
    assert not isinstance(smooth, PiecewiseField)
    assert isinstance(jump, PiecewiseField)
    assert jump.region([[0, 0, 0.25], [0, 0, 0.75]]).tolist() == [1, 0]
    assert field_dim(CallableField(lambda x, y: x, ["a", "b"])) == 2


def test_density_takes_the_dimension():
    g = np.array([0.0, 2.0])
    assert density(g, 1.0, 0.5).tolist() == [0.5 ** 4, 16.0]
    assert density(g, 1.0, 0.5, dim=3).tolist() == [0.5 ** 5, 32.0]


def test_tet_mesh_written_and_read_through_meshio(tmp_path):
    import meshio

    m = cube_mesh()
    m = Mesh(m.points, m.cells, facets=m.boundary_facets,
             facet_markers=np.ones(len(m.boundary_facets), int),
             point_data={"metal": (1 - m.points[:, 2]) ** 2})
    m.write(tmp_path / "c.vtu")
    back = meshio.read(tmp_path / "c.vtu")
    assert np.array_equal(back.cells_dict["tetra"], m.cells)
    assert np.array_equal(back.cells_dict["triangle"], m.facets)
    assert np.allclose(back.point_data["metal"], m.point_data["metal"])


def test_formats_that_take_2d_only_say_so(tmp_path, monkeypatch):
    import dataclasses

    from hetmesh.errors import OutputError
    from hetmesh.io import export

    # every packaged format takes tetrahedra now: a 2D-only one stands in for a future writer
    only2d = dataclasses.replace(export.FILE_FORMATS["gmsh22"], dims=(2,))
    monkeypatch.setitem(export.FILE_FORMATS, "gmsh22", only2d)
    with pytest.raises(OutputError, match=r"takes 2D meshes, this one is 3D \(formats for 3D"):
        cube_mesh().write(tmp_path / "c.msh", file_format="gmsh22")
    assert not (tmp_path / "c.msh").exists()
