"""Interfaces in sweeps whose composition varies along the sweep: an extrusion with a seam
and a z-dependent composition on each side, a revolution with a bond and an angle-dependent
one. Every claim is recomputed here from the arrays and the formulas (the independent
checks of tests/tet_checks.py and tests/test_tet.py), not by the mesher's own checks."""

from __future__ import annotations

import re

import meshio
import numpy as np
import pytest

import hetmesh
from hetmesh.io.export import write_mesh
from hetmesh.tet.api import mesh_model
from tet_checks import tet_quality

THRESHOLD = 0.2

EXTRUDED = """
[model]
name = "seamed_plate_z"

[solid]
type = "extrusion"
length = 3

[domain.outer]
start = [0, 0]
path = [{ to = [5, 0] }, { to = [10, 0] }, { to = [10, 4] }, { to = [5, 4] }, { to = [0, 4] },
        { to = [0, 0] }]

[[domain.interfaces]]
name = "seam"
start = [5, 0]
path = [{ to = [5, 4] }]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(x < 5, 0.1 + 0.03*x + 0.1*z, 0.9 - 0.04*x - 0.08*z)"
"""


def metal_extruded(p: np.ndarray, left: np.ndarray) -> np.ndarray:
    x, z = p[:, 0], p[:, 2]
    return np.where(left, 0.1 + 0.03 * x + 0.1 * z, 0.9 - 0.04 * x - 0.08 * z)


REVOLVED = """
[model]
name = "bonded_ring"

[solid]
type = "revolution"
angle = 90

[domain.outer]
start = [20, 0]
path = [{ to = [25, 0], name = "bottom" }, { to = [30, 0], name = "bottom" },
        { to = [30, 10], name = "outside" }, { to = [25, 10], name = "top" },
        { to = [20, 10], name = "top" }, { to = [20, 0], name = "inside" }]

[[domain.interfaces]]
name = "bond"
start = [25, 0]
path = [{ to = [25, 10] }]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(x**2 + y**2 < 625, 0.1 + 0.3*atan2(y, x), 0.9 - 0.3*atan2(y, x))"
"""


def metal_revolved(p: np.ndarray, inner: np.ndarray) -> np.ndarray:
    a = np.arctan2(p[:, 1], p[:, 0])
    return np.where(inner, 0.1 + 0.3 * a, 0.9 - 0.3 * a)


def faces_held(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(tets, np.int64)
    f = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]])
    return np.unique(np.sort(f, axis=1), axis=0, return_counts=True)


def as_set(tris) -> set:
    return {tuple(sorted(int(v) for v in f)) for f in np.asarray(tris)}


def coordinate_set(points, tris) -> set:
    """Triangles as sets of their corners' coordinates (rounded to 1e-9): the .msh nodes
    are numbered by the writer."""
    q = np.round(np.asarray(points)[np.asarray(tris, np.int64)], 9)
    return {tuple(sorted(map(tuple, t.tolist()))) for t in q}


def check(res, metal, side, on_surface):
    """Validity, conformity, delta per side and the interface surface, from the arrays:
    ``side(points) -> (N,)`` -1 / 0 (on the interface) / 1, ``metal(points, first_side)``
    the formula of each side, ``on_surface(points) -> bool`` the interface's surface."""
    p, t = np.asarray(res.points), np.asarray(res.tets, np.int64)
    a, b, c, d = (p[t[:, k]] for k in range(4))
    vol = np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) / 6.0
    assert vol.min() > 0
    assert np.bincount(t.ravel(), minlength=len(p)).min() > 0
    faces, held = faces_held(t)
    assert held.max() <= 2
    # no tetrahedron straddles the interface; each is labelled with its side's subregion
    s = side(p)[t]
    assert not ((s.max(axis=1) > 0) & (s.min(axis=1) < 0)).any()
    first = (s <= 0).all(axis=1)
    regions = np.asarray(res.mesh.regions)
    assert len(np.unique(regions[first])) == 1 and len(np.unique(regions[~first])) == 1
    assert regions[first][0] != regions[~first][0]
    cen = p[t].mean(axis=1)
    assert (side(cen)[first] < 0).all() and (side(cen)[~first] > 0).all()
    # delta from the formulas, every corner with its tetrahedron's side
    f = metal(p[t].reshape(-1, 3), np.repeat(first, 4)).reshape(len(t), 4)
    delta = f.max(axis=1) - f.min(axis=1)
    assert delta.max() < THRESHOLD
    np.testing.assert_allclose(delta, res.delta, rtol=0, atol=1e-12)
    # the recorded interface triangles: exactly the tetrahedron faces on the surface, each
    # between two tetrahedra
    mesh = res.mesh
    (m,) = [k for k, n in mesh.marker_names.items() if n in ("seam[0]", "bond[0]")]
    rec = mesh.facets[mesh.facet_markers == m]
    on = on_surface(p[faces].reshape(-1, 3)).reshape(-1, 3).all(axis=1)
    assert len(rec) and as_set(rec) == as_set(faces[on]) and (held[on] == 2).all()
    return rec


@pytest.fixture(scope="module")
def extruded(tmp_path_factory):
    path = tmp_path_factory.mktemp("ifc") / "seamed_plate_z.toml"
    path.write_text(EXTRUDED)
    model = hetmesh.load_model(path)
    return model, mesh_model(model, THRESHOLD)


@pytest.fixture(scope="module")
def revolved(tmp_path_factory):
    path = tmp_path_factory.mktemp("ifc") / "bonded_ring.toml"
    path.write_text(REVOLVED)
    model = hetmesh.load_model(path)
    return model, mesh_model(model, THRESHOLD)


def test_extrusion_keeps_the_seam_with_a_z_dependent_composition(extruded):
    _, res = extruded
    assert res.info["placement"] == "swept+repair"
    rec = check(res, metal_extruded,
                lambda q: np.sign(np.where(q[:, 0] == 5.0, 0.0, q[:, 0] - 5.0)),
                lambda q: q[:, 0] == 5.0)
    q = res.points[rec]
    area = 0.5 * np.linalg.norm(np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]), axis=1)
    assert area.sum() == pytest.approx(4.0 * 3.0, rel=1e-12)  # the plane x = 5, 4 x 3
    # the repair split the seam's triangles (the sweep alone has only column points)
    assert len(res.points) > res.info["section_triangles"]


def test_revolution_keeps_the_bond_with_an_angle_dependent_composition(revolved):
    _, res = revolved
    assert res.info["placement"] == "revolved+repair"
    # the chord tolerance: 2e-3 x the diameter of the solid's bounds (+-30, +-30, 0..10)
    chord = 2e-3 * np.linalg.norm([60.0, 60.0, 10.0])

    def r(q):
        return np.hypot(q[:, 0], q[:, 1])

    rec = check(res, metal_revolved,
                lambda q: np.sign(np.where(np.abs(r(q) - 25) <= 1e-9 * 25, 0.0, r(q) - 25)),
                lambda q: np.abs(r(q) - 25) <= chord)
    # the bond's triangles lie on the cylinder r = 25 within the chord tolerance, edge
    # midpoints too, and none leaves 0 <= z <= 10
    q = res.points[rec]
    mids = 0.5 * (q + q[:, [1, 2, 0]])
    assert np.abs(r(q.reshape(-1, 3)) - 25.0).max() <= chord
    assert np.abs(r(mids.reshape(-1, 3)) - 25.0).max() <= chord
    assert q[..., 2].min() >= 0.0 and q[..., 2].max() <= 10.0


@pytest.mark.parametrize("fixture", ["extruded", "revolved"])
def test_the_interface_is_named_in_msh_and_inp(request, tmp_path, fixture):
    _, res = request.getfixturevalue(fixture)
    mesh = res.mesh
    name = "seam[0]" if fixture == "extruded" else "bond[0]"
    (m,) = [k for k, n in mesh.marker_names.items() if n == name]
    want = mesh.facets[mesh.facet_markers == m]
    path = write_mesh(mesh, tmp_path / "m.msh")
    mm = meshio.read(path)
    tag, dim = mm.field_data[name]
    assert dim == 2
    tris = np.concatenate([c.data for c, ph in zip(mm.cells, mm.cell_data["gmsh:physical"])
                           if c.type == "triangle" and (ph == tag).all()])
    assert coordinate_set(mm.points, tris) == coordinate_set(mesh.points, want)
    assert sorted(k for k, (_, d) in mm.field_data.items() if d == 3) == ["region_0",
                                                                         "region_1"]
    text = write_mesh(mesh, tmp_path / "m.inp").read_text()
    surfaces = re.findall(r"^\*SURFACE, NAME=(\w+)", text, flags=re.M)
    assert any(s.startswith(name.split("[")[0].upper()) or s.startswith(name.split("[")[0])
               for s in surfaces), surfaces
    nsets = re.findall(r"^\*NSET, NSET=(\w+)", text, flags=re.M)
    assert any(s.lower().startswith(name.split("[")[0]) for s in nsets), nsets


def test_quality(extruded, revolved):
    for _, res in (extruded, revolved):
        ang, rr = tet_quality(np.asarray(res.points), np.asarray(res.tets, np.int64))
        assert ang.min() > 1.0 and rr.mean() > 0.5


def test_a_piecewise_composition_without_interfaces_records_its_discontinuity(tmp_path):
    path = tmp_path / "jump.toml"
    text = EXTRUDED.replace('[[domain.interfaces]]\nname = "seam"\nstart = [5, 0]\n'
                            'path = [{ to = [5, 4] }]\n', "")
    text = text.replace("x < 5", "x < 4")
    path.write_text(text)
    res = mesh_model(hetmesh.load_model(path), THRESHOLD)
    assert res.face_names[-1] == "discontinuity[0]"
    rec = res.faces[res.face_markers == len(res.face_names)]
    faces, held = faces_held(res.tets)
    on = (np.abs(res.points[faces][..., 0] - 4.0) <= 1e-6).all(axis=1)
    assert len(rec) and as_set(rec) == as_set(faces[on]) and (held[on] == 2).all()


def test_swept_discontinuities_are_faces_after_the_existing_ones():
    model = hetmesh.load_model(hetmesh.example_path("fgm_plate_3d"))
    res = mesh_model(model, 0.3)
    names = res.face_names
    k = len(model.solid.face_names)
    assert names[:k] == tuple(model.solid.face_names)
    assert names[k:] and all(n.startswith("discontinuity[") for n in names[k:])
    disc = res.face_markers > k
    # the boundary first, then the discontinuities, each face of two tetrahedra
    assert not disc[:np.argmax(disc)].any() and disc[np.argmax(disc):].all()
    faces, held = faces_held(res.tets)
    key = {f: h for f, h in zip(map(tuple, faces.tolist()), held.tolist())}
    assert all(key[tuple(sorted(f))] == 2 for f in res.faces[disc].tolist())


def test_deterministic(tmp_path):
    path = tmp_path / "bonded_ring.toml"
    path.write_text(REVOLVED)
    model = hetmesh.load_model(path)
    a, b = mesh_model(model, 0.3), mesh_model(model, 0.3)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.tets, b.tets)
    assert np.array_equal(a.faces, b.faces) and np.array_equal(a.face_markers, b.face_markers)
