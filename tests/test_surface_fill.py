"""The builtin fill of a closed triangulated surface (hetmesh.tet.surface_fill), with Gmsh
made unimportable: surfaces built here (a tetrahedron, a cube with a cubic cavity, a thin
wedge, an icosphere, Schönhardt's twisted prism, a torus) and examples/l_bracket.stl, each
checked from the arrays alone: positive volumes, every inner face in two tetrahedra, the
boundary covering the input exactly (the same area, every boundary triangle in the plane of
the input triangle under its centroid, the same enclosed volume), the same mesh twice. Then
l_bracket and the hollow cube meshed to the material (MMG, verified) without Gmsh."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import hetmesh
from hetmesh.errors import MeshingError
from hetmesh.io.model import load_model
from hetmesh.testing import torus_surface
from hetmesh.tet import surface_fill
from hetmesh.tet.api import mesh_model
from hetmesh.tet.surface import SurfaceSolid
from hetmesh.tet.surface_fill import fill_surface
from hetmesh.tet.surface_mesh import initial_volume
from test_tet import check_tet_mesh
from test_tet_surface import MODEL, cube, write_surface


@pytest.fixture(autouse=True)
def no_gmsh(monkeypatch):
    """``import gmsh`` raises ImportError in every test here."""
    monkeypatch.setitem(sys.modules, "gmsh", None)


def icosphere(levels: int):
    """The unit icosphere: the icosahedron's triangles split in four ``levels`` times, the
    new points pushed onto the sphere."""
    g = (1 + 5 ** 0.5) / 2
    V = np.array([[-1, g, 0], [1, g, 0], [-1, -g, 0], [1, -g, 0], [0, -1, g], [0, 1, g],
                  [0, -1, -g], [0, 1, -g], [g, 0, -1], [g, 0, 1], [-g, 0, -1], [-g, 0, 1]])
    F = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9],
                  [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2],
                  [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
                  [8, 6, 7], [9, 8, 1]])
    V = V / np.linalg.norm(V, axis=1)[:, None]
    for _ in range(levels):
        e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        ue, inv = np.unique(e, axis=0, return_inverse=True)
        mid = V[ue].mean(axis=1)
        m = len(V) + inv.reshape(3, -1).T
        V = np.r_[V, mid / np.linalg.norm(mid, axis=1)[:, None]]
        a, b, c = F.T
        # m[:, 0] the midpoint of a-b, m[:, 1] of b-c, m[:, 2] of c-a
        F = np.concatenate([np.c_[a, m[:, 0], m[:, 2]], np.c_[m[:, 0], b, m[:, 1]],
                            np.c_[m[:, 2], m[:, 1], c], m])
    return V, F


def hollow_cube():
    V, F = cube(0.0, 2.0)
    Vi, Fi = cube(0.5, 1.5, inward=True)
    return np.r_[V, Vi], np.r_[F, Fi + 8]


def wedge(degrees=1.0):
    """A prism over a triangle with an angle of ``degrees`` at the edge x = y = 0."""
    s = np.tan(np.radians(degrees))
    V = np.array([[0, 0, 0], [1, 0, 0], [1, s, 0], [0, 0, 1], [1, 0, 1], [1, s, 1]], float)
    F = np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4],
                  [2, 0, 3], [2, 3, 5]])
    return V, F


def schonhardt():
    """Schönhardt's twisted triangular prism: no tetrahedralisation without new points."""
    a = 2 * np.pi * np.arange(3) / 3
    V = np.r_[np.c_[np.cos(a), np.sin(a), np.zeros(3)],
              np.c_[np.cos(a + 0.5), np.sin(a + 0.5), np.ones(3)]]
    F = np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4],
                  [2, 0, 3], [2, 3, 5]])
    return V, F


def l_bracket():
    s = load_model(hetmesh.example_path("l_bracket")).solid
    return s.V, s.F


SURFACES = {"tetrahedron": lambda: (np.eye(4, 3, -1), np.array([[0, 2, 1], [0, 1, 3],
                                                                   [0, 3, 2], [1, 2, 3]])),
            "hollow_cube": hollow_cube, "wedge": wedge, "icosphere": lambda: icosphere(3),
            "schonhardt": schonhardt, "torus": torus_surface, "l_bracket": l_bracket}


def check_fill(V, F, p, t):
    """The fill's claims from the arrays alone (numpy, no hetmesh code)."""
    V, F, p, t = (np.asarray(x) for x in (V, F, p, t))
    assert np.array_equal(p[:len(V)], V)                     # the input points kept
    a, b, c, d = (p[t[:, k]] for k in range(4))
    vol = np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) / 6
    assert vol.min() > 0
    faces = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 3, 2]], t[:, [0, 1, 3]],
                            t[:, [0, 2, 1]]])
    _, first, cnt = np.unique(np.sort(faces, axis=1), axis=0, return_index=True,
                              return_counts=True)
    assert cnt.max() <= 2
    bnd = faces[first[cnt == 1]]                             # outward for positive tets
    q = p[bnd]
    cross = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    T = V[F]
    n_in = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    area_in = 0.5 * np.linalg.norm(n_in, axis=1).sum()
    scale = np.ptp(V, axis=0).max()
    assert 0.5 * np.linalg.norm(cross, axis=1).sum() == pytest.approx(area_in, rel=1e-12)
    # each boundary triangle: its centroid on an input triangle (barycentric coordinates
    # in [0, 1] and in its plane), its corners in that plane, its normal the same way
    cen = q.mean(axis=1)
    unit = n_in / np.linalg.norm(n_in, axis=1)[:, None]
    for k in range(len(bnd)):
        h = np.einsum("ij,ij->i", cen[k] - T[:, 0], unit)
        e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
        r = cen[k] - T[:, 0] - h[:, None] * unit
        d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
        r1, r2 = (r * e1).sum(1), (r * e2).sum(1)
        den = d11 * d22 - d12 ** 2
        s, u = (d22 * r1 - d12 * r2) / den, (d11 * r2 - d12 * r1) / den
        on = (np.abs(h) <= 1e-12 * scale) & (s >= -1e-12) & (u >= -1e-12) \
            & (s + u <= 1 + 1e-12)
        assert on.any(), f"boundary triangle {k} is on no input triangle"
        j = int(np.flatnonzero(on)[0])
        assert np.abs((q[k] - T[j, 0]) @ unit[j]).max() <= 1e-12 * scale
        assert cross[k] @ unit[j] > 0
    enclosed = np.einsum("ij,ij->i", T[:, 0], np.cross(T[:, 1], T[:, 2])).sum() / 6
    assert vol.sum() == pytest.approx(enclosed, rel=1e-12)


@pytest.mark.parametrize("name", list(SURFACES))
def test_the_fill_covers_the_surface_exactly(name):
    V, F = SURFACES[name]()
    s = SurfaceSolid.from_arrays(V, F, f"{name}.stl")
    p, t, tri, parent = fill_surface(s.V, s.F, s.source)
    check_fill(s.V, s.F, p, t)
    assert len(tri) == len(parent) and parent.max() < len(s.F)
    again = fill_surface(s.V, s.F, s.source)
    assert again[0].tobytes() == p.tobytes() and again[1].tobytes() == t.tobytes()


def test_schonhardt_needs_new_points_and_they_stay_on_its_faces():
    s = SurfaceSolid.from_arrays(*schonhardt(), "s.stl")
    p, t, _, _ = fill_surface(s.V, s.F)
    assert len(p) > 6   # no tetrahedralisation of its six corners alone


def test_a_fill_that_does_not_converge_is_a_meshing_error(monkeypatch):
    s = SurfaceSolid.from_arrays(*schonhardt(), "s.stl")
    monkeypatch.setattr(surface_fill, "MAX_ROUNDS", 0)
    with pytest.raises(MeshingError, match=r"s.stl did not converge: after 0 rounds"):
        fill_surface(s.V, s.F, "s.stl")


def test_the_initial_volume_is_the_fill():
    s = SurfaceSolid.from_arrays(*hollow_cube(), "h.stl")
    p, t = initial_volume(s)
    check_fill(s.V, s.F, p, t)
    q, u, _, _ = fill_surface(s.V, s.F, "h.stl")
    assert np.array_equal(p, q) and np.array_equal(t, u)


def test_l_bracket_meshes_without_gmsh():
    m = load_model(hetmesh.example_path("l_bracket"))
    res = mesh_model(m, 0.3)     # verified (surface_problems) inside
    assert res.info["fill"] == "builtin"
    check_tet_mesh(res.points, res.tets, lambda p: ((p[:, 0] + p[:, 2]) / 50) ** 2, 0.3)
    again = mesh_model(m, 0.3)
    assert again.points.tobytes() == res.points.tobytes()
    assert again.tets.tobytes() == res.tets.tobytes()


def test_a_hollow_cube_meshes_without_gmsh(tmp_path):
    write_surface(tmp_path / "hollow.stl", *hollow_cube())
    (tmp_path / "m.toml").write_text(MODEL.format(file="hollow.stl", formula="z/2"))
    res = mesh_model(load_model(tmp_path / "m.toml"), 0.3)
    check_tet_mesh(res.points, res.tets, lambda p: p[:, 2] / 2, 0.3)
    a, b, c, d = (res.points[res.tets[:, k]] for k in range(4))
    vol = np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)).sum() / 6
    assert vol == pytest.approx(7.0, rel=1e-9)
    cen = res.points[res.tets].mean(axis=1)
    assert not ((np.abs(cen - 1.0) < 0.5).all(axis=1)).any()
