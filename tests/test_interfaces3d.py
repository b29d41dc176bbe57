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
metal = "where(x < 5, 0.1 + 0.06*y*z, 0.8 - 0.05*y*z)"
"""


def metal_extruded(p: np.ndarray, left: np.ndarray) -> np.ndarray:
    y, z = p[:, 1], p[:, 2]
    return np.where(left, 0.1 + 0.06 * y * z, 0.8 - 0.05 * y * z)


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
metal = "where(x**2 + y**2 < 625, 0.5 + 0.45*sin(6*atan2(y, x)), 0.3 + 0.02*z)"
"""


def metal_revolved(p: np.ndarray, inner: np.ndarray) -> np.ndarray:
    a = np.arctan2(p[:, 1], p[:, 0])
    return np.where(inner, 0.5 + 0.45 * np.sin(6 * a), 0.3 + 0.02 * p[:, 2])


def with_metal(text: str, formula: str) -> str:
    """``text`` with another metal formula."""
    return re.sub(r'^metal = ".*"$', f'metal = "{formula}"', text, flags=re.M)


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


def check(res, metal, side, on_surface, threshold: float = THRESHOLD):
    """Validity, conformity, delta per side and the interface surface, from the arrays:
    ``side(points) -> (N,)`` -1 / 0 (on the interface, or within the chord tolerance of a
    curved one) / 1, ``metal(points, first_side)`` the formula of each side,
    ``on_surface(points) -> bool`` the interface's surface."""
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
    regions = np.asarray(res.mesh.regions)
    cs = side(p[t].mean(axis=1))
    (r_first,), (r_second,) = np.unique(regions[cs < 0]), np.unique(regions[cs > 0])
    assert r_first != r_second and set(np.unique(regions)) == {r_first, r_second}
    first = regions == r_first
    assert not (s[first] > 0).any() and not (s[~first] < 0).any()
    # delta from the formulas, every corner with its tetrahedron's side
    f = metal(p[t].reshape(-1, 3), np.repeat(first, 4)).reshape(len(t), 4)
    delta = f.max(axis=1) - f.min(axis=1)
    assert delta.max() < threshold
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
    # the repair split seam triangles: seam points off the columns of the section's seam
    # vertices (a column has a point on the bottom, z = 0)
    v = np.unique(rec)
    y0 = set(res.points[v][res.points[v, 2] == 0.0, 1].tolist())
    assert any(y not in y0 for y in res.points[v, 1].tolist())


def test_revolution_keeps_the_bond_with_an_angle_dependent_composition(revolved):
    _, res = revolved
    assert res.info["placement"] == "revolved+repair"
    # the chord tolerance: 2e-3 x the diameter of the solid's bounds (+-30, +-30, 0..10)
    chord = 2e-3 * np.linalg.norm([60.0, 60.0, 10.0])

    def r(q):
        return np.hypot(q[:, 0], q[:, 1])

    rec = check(res, metal_revolved,
                lambda q: np.sign(np.where(np.abs(r(q) - 25) <= chord, 0.0, r(q) - 25)),
                lambda q: np.abs(r(q) - 25) <= chord)
    # the repair split bond triangles: midpoints of angular chords, inside the cylinder
    assert (np.abs(r(res.points[np.unique(rec)]) - 25.0) > 1e-9).any()
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
    text = with_metal(text, "where(x < 4, 0.1 + 0.06*y*z, 0.8 - 0.05*y*z)")
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


def test_an_axisymmetric_jump_in_a_revolution_is_embedded_and_recorded(tmp_path):
    """A formula jump at r = 25 (the same at every angle, no interface in the domain): the
    profile's mesh embeds it, the sweep keeps it, and it is the face discontinuity[0]."""
    text = REVOLVED.replace('[[domain.interfaces]]\nname = "bond"\nstart = [25, 0]\n'
                            'path = [{ to = [25, 10] }]\n', "")
    text = with_metal(text, "where(x**2 + y**2 < 625, 0.2, 0.6 + 0.01*z)")
    path = tmp_path / "ring_jump.toml"
    path.write_text(text)
    res = mesh_model(hetmesh.load_model(path), THRESHOLD)
    assert res.info["placement"] == "revolved" and res.face_names[-1] == "discontinuity[0]"
    p, t = res.points, np.asarray(res.tets, np.int64)
    r = np.hypot(p[:, 0], p[:, 1])
    s = np.sign(np.where(np.abs(r - 25) <= 1e-6 * 25, 0.0, r - 25))[t]
    assert not ((s.max(axis=1) > 0) & (s.min(axis=1) < 0)).any()
    rec = res.faces[res.face_markers == len(res.face_names)]
    faces, held = faces_held(t)
    on = (np.abs(r[faces] - 25) <= 1e-6 * 25).all(axis=1)
    assert len(rec) and as_set(rec) == as_set(faces[on]) and (held[on] == 2).all()
    inner = (s <= 0).all(axis=1)
    metal = np.where(inner[:, None], 0.2, 0.6 + 0.01 * p[t][..., 2])
    assert (metal.max(axis=1) - metal.min(axis=1)).max() < THRESHOLD


def test_a_seam_in_a_smooth_z_dependent_composition_stays_a_plane(tmp_path):
    """No jump (one subregion): the seam x = 5 is kept through the repair and the quality
    pass all the same, and delta is over the vertices."""
    path = tmp_path / "seam_smooth.toml"
    path.write_text(with_metal(EXTRUDED, "x*z/30"))
    res = mesh_model(hetmesh.load_model(path), THRESHOLD)
    assert res.info["placement"] == "swept+repair" and "regions" not in res.info
    p, t = res.points, np.asarray(res.tets, np.int64)
    rec = res.faces[res.face_markers == res.face_names.index("seam[0]") + 1]
    faces, held = faces_held(t)
    on = (p[faces][..., 0] == 5.0).all(axis=1)
    assert len(rec) and as_set(rec) == as_set(faces[on]) and (held[on] == 2).all()
    q = p[rec]
    area = 0.5 * np.linalg.norm(np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]), axis=1)
    assert area.sum() == pytest.approx(12.0, rel=1e-12)
    f = (p[:, 0] * p[:, 2] / 30)[t]
    assert (f.max(axis=1) - f.min(axis=1)).max() < THRESHOLD
    s = np.sign(np.where(p[:, 0] == 5.0, 0.0, p[:, 0] - 5.0))[t]
    assert not ((s.max(axis=1) > 0) & (s.min(axis=1) < 0)).any()


def test_a_repaired_revolution_keeps_its_curved_faces(tmp_path):
    """Where the repair splits angular chords on the cylinders r = 20 and r = 30, the
    midpoints lie inside them by up to their sagitta: those boundary triangles still belong
    to their faces, within the chord tolerance."""
    text = re.sub(r"\[\[domain\.interfaces\]\].*?\n\n", "", REVOLVED, flags=re.S)
    path = tmp_path / "ring_sin.toml"
    path.write_text(with_metal(text, "0.5 + 0.45*sin(12*atan2(y, x))"))
    res = mesh_model(hetmesh.load_model(path), 0.3)
    assert res.info["placement"] == "revolved+repair" and res.info["repair_passes"] > 0
    p, t = res.points, np.asarray(res.tets, np.int64)
    a, b, c, d = (p[t[:, k]] for k in range(4))
    assert (np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) > 0).all()
    f = 0.5 + 0.45 * np.sin(12 * np.arctan2(p[:, 1], p[:, 0]))
    assert (f[t].max(axis=1) - f[t].min(axis=1)).max() < 0.3
    faces, held = faces_held(t)
    bnd = faces[held == 1]
    assert as_set(bnd) == as_set(res.faces) and (res.face_markers >= 1).all()
    chord = 2e-3 * np.linalg.norm([60.0, 60.0, 10.0])
    r = np.hypot(p[:, 0], p[:, 1])
    for name, dist in (("outside", np.abs(r - 30)), ("inside", np.abs(r - 20))):
        sel = res.faces[res.face_markers == res.face_names.index(name) + 1]
        assert len(sel) and dist[sel].max() <= chord
    # some split: boundary points strictly inside the outer cylinder
    outer = res.faces[res.face_markers == res.face_names.index("outside") + 1]
    assert (np.abs(r[np.unique(outer)] - 30) > 1e-9).any()


def metal_seamed_z(p: np.ndarray, left: np.ndarray) -> np.ndarray:
    """examples/seamed_plate_z.toml's formula, each side's."""
    x, z = p[:, 0], p[:, 2]
    return np.where(left, 0.1 + 0.03 * x + 0.1 * z, 0.9 - 0.04 * x - 0.08 * z)


@pytest.fixture(scope="module")
def seamed_example():
    model = hetmesh.load_model(hetmesh.example_path("seamed_plate_z"))
    return model, mesh_model(model, 0.1)


def test_seamed_plate_z_meets_the_quality_targets_at_0_1(seamed_example):
    """The MMG pass after the repair (hetmesh.tet.sweep_mmg): minimum dihedral >= 10,
    1st percentile >= 20, mean radius ratio >= 0.75, with the seam a plane of faces, every
    tetrahedron on one side, delta per side under 0.1 and the box's faces exact."""
    _, res = seamed_example
    check(res, metal_seamed_z, lambda q: np.sign(np.where(q[:, 0] == 5.0, 0.0, q[:, 0] - 5.0)),
          lambda q: q[:, 0] == 5.0, threshold=0.1)
    p, t = np.asarray(res.points), np.asarray(res.tets, np.int64)
    ang, rr = tet_quality(p, t)
    assert ang.min() >= 10 and np.percentile(ang, 1) >= 20 and rr.mean() >= 0.75
    # every boundary vertex exactly on a plane of the box [0, 10] x [0, 4] x [0, 3]
    faces, held = faces_held(t)
    b = p[np.unique(faces[held == 1])]
    on = (b[:, 0] == 0) | (b[:, 0] == 10) | (b[:, 1] == 0) | (b[:, 1] == 4) | \
        (b[:, 2] == 0) | (b[:, 2] == 3)
    assert on.all()
    assert res.info["placement"] == "swept+repair" and res.info["mmg_rounds"] >= 1


def test_seamed_plate_z_is_deterministic(seamed_example):
    model, a = seamed_example
    b = mesh_model(model, 0.1)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.tets, b.tets)
    assert np.array_equal(a.faces, b.faces) and np.array_equal(a.face_markers, b.face_markers)


@pytest.mark.slow
def test_the_bonded_ring_meets_the_quality_targets_at_0_1(tmp_path):
    """The repaired revolution missed the targets at 0.1 (8.2 / 14.5 / 0.588); the MMG pass
    meets them, the bond still a surface of faces within the chord tolerance of r = 25,
    every tetrahedron on one side, delta per side under 0.1."""
    path = tmp_path / "bonded_ring.toml"
    path.write_text(REVOLVED)
    res = mesh_model(hetmesh.load_model(path), 0.1)
    assert res.info["placement"] == "revolved+repair" and res.info["mmg_rounds"] >= 1
    chord = 2e-3 * np.linalg.norm([60.0, 60.0, 10.0])

    def r(q):
        return np.hypot(q[:, 0], q[:, 1])

    check(res, metal_revolved,
          lambda q: np.sign(np.where(np.abs(r(q) - 25) <= chord, 0.0, r(q) - 25)),
          lambda q: np.abs(r(q) - 25) <= chord, threshold=0.1)
    ang, rr = tet_quality(np.asarray(res.points), np.asarray(res.tets, np.int64))
    assert ang.min() >= 10 and np.percentile(ang, 1) >= 20 and rr.mean() >= 0.75
