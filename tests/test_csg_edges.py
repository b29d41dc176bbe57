"""Solids of primitives whose curved faces meet (a bore through a sphere, a cylinder with a
spherical cavity at its end, two crossing bores): meshed, verified, the edges where two
curved faces meet within the chord tolerance of the exact intersection curve, checked from
the arrays alone with the curves' own formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

import hetmesh
from hetmesh.io.model import load_model
from hetmesh.tet.api import mesh_model
from hetmesh.tet.general import solid_problems, uniform_solid_at
from hetmesh.tet.quality import quality_summary
from hetmesh.tet.uniform import uniform_model
from test_tet import check_tet_mesh
from test_tet_flips import min_dihedral
from test_tet_solids import BOX_BORE, write

#: chord tolerance (relative to the diameter) and delta_0 of the tests: coarse, so that
#: each mesh takes seconds
CHORD_REL = 0.01
D0 = 0.4

MATERIAL = """
[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""

#: a ball of radius 1 with a bore of radius 0.3 along x right through it
BORE_SPHERE = """
[solid]
type = "sphere"
center = [0, 0, 0]
radius = 1

[[solid.subtract]]
type = "cylinder"
center = [0, 0]
radius = 0.3
axis = "x"
name = "bore"
""" + MATERIAL.format(formula="(x + 1)/2")

#: a cylinder (radius 1, z from 0 to 2) with a spherical cavity at its top end wider than
#: it: the cavity's sphere (radius 1.25 about (0, 0, 2)) meets the side at z = 1.25
CAVITY = """
[solid]
type = "cylinder"
center = [0, 0]
radius = 1
from = 0
to = 2

[[solid.subtract]]
type = "sphere"
center = [0, 0, 2]
radius = 1.25
name = "cavity"
""" + MATERIAL.format(formula="z/2")

#: a box with two crossing bores: radius 0.4 along x and 0.3 along y, both through the
#: centre line y = z = 1 and z = x = 1
CROSS = """
[solid]
type = "box"
min = [0, 0, 0]
max = [2, 2, 2]

[[solid.subtract]]
type = "cylinder"
center = [1, 1]
radius = 0.4
axis = "x"
name = "bx"

[[solid.subtract]]
type = "cylinder"
center = [1, 1]
radius = 0.3
axis = "y"
name = "by"
""" + MATERIAL.format(formula="z/2")


def _circle_distance(x, axis: int, at: float, radius: float):
    """Distance from points to the circle of ``radius`` about the coordinate axis
    ``axis`` in the plane ``x[axis] = at``."""
    others = [k for k in range(3) if k != axis]
    rho = np.hypot(x[:, others[0]], x[:, others[1]])
    return np.hypot(x[:, axis] - at, rho - radius)


def _cross_curve():
    """Points of the two closed curves where the bores of CROSS meet, 1e-6 apart at most:
    z = 1 + 0.3 cos(a), x = 1 + 0.3 sin(a) on the y bore, y = 1 +- sqrt(0.16 - (z - 1)^2)
    on the x bore."""
    a = np.linspace(0, 2 * math.pi, 2_000_001)
    z, x = 1 + 0.3 * np.cos(a), 1 + 0.3 * np.sin(a)
    w = np.sqrt(0.16 - (z - 1) ** 2)
    return np.concatenate([np.column_stack([x, 1 + w, z]), np.column_stack([x, 1 - w, z])])


#: name -> (model, composition, surfaces {face: |g|(points)}, the two curved faces that
#: meet, distance to their exact curve)
CASES = {
    "bore_sphere": (
        BORE_SPHERE, lambda p: (p[:, 0] + 1) / 2,
        {"outer": lambda p: np.abs(np.linalg.norm(p, axis=-1) - 1),
         "bore": lambda p: np.abs(np.hypot(p[..., 1], p[..., 2]) - 0.3)},
        ("outer", "bore"),
        lambda x: np.minimum(_circle_distance(x, 0, math.sqrt(0.91), 0.3),
                             _circle_distance(x, 0, -math.sqrt(0.91), 0.3))),
    "cavity": (
        CAVITY, lambda p: p[:, 2] / 2,
        {"side": lambda p: np.abs(np.hypot(p[..., 0], p[..., 1]) - 1),
         "cavity": lambda p: np.abs(np.linalg.norm(p - [0, 0, 2], axis=-1) - 1.25),
         "bottom": lambda p: np.abs(p[..., 2])},
        ("side", "cavity"),
        lambda x: _circle_distance(x, 2, 1.25, 1.0)),
    "cross": (
        CROSS, lambda p: p[:, 2] / 2,
        {"bx": lambda p: np.abs(np.hypot(p[..., 1] - 1, p[..., 2] - 1) - 0.4),
         "by": lambda p: np.abs(np.hypot(p[..., 2] - 1, p[..., 0] - 1) - 0.3)},
        ("bx", "by"),
        lambda x: cKDTree(_cross_curve()).query(x)[0]),
}


def _tri_points(q):
    mids = 0.5 * (q + q[:, [1, 2, 0]])
    return np.concatenate([q, mids, q.mean(axis=1, keepdims=True)], axis=1)


def test_meeting_faces_are_found(tmp_path):
    """The pairs of curved faces that meet, and none where they do not."""
    got = {}
    for name, (text, *_rest) in CASES.items():
        s = load_model(write(tmp_path, text, f"{name}.toml")).solid
        got[name] = {(s.face_names[i], s.face_names[j]) for i, j in s.curved_edges}
    assert got == {"bore_sphere": {("outer", "bore")}, "cavity": {("side", "cavity")},
                   "cross": {("bx", "by")}}
    assert load_model(write(tmp_path, BOX_BORE)).solid.curved_edges == ()
    assert load_model(hetmesh.example_path("graded_sphere")).solid.curved_edges == ()


#: the cavity runs in the default suite, the two larger ones only with -m slow
@pytest.mark.parametrize("name", [n if n == "cavity" else pytest.param(n, marks=pytest.mark.slow)
                                  for n in CASES])
def test_meeting_faces_mesh_with_a_sharp_edge(tmp_path, name):
    """Verified by the independent helper (volumes, conformity, delta); every boundary
    triangle within the chord tolerance of its own face's surface (the curved ones at
    corners, edge midpoints and centroid; planes exactly); every edge between the two
    curved faces within the chord tolerance of their exact curve (ends, quarter points,
    midpoint)."""
    text = CASES[name][0]
    m = load_model(write(tmp_path, text, f"{name}.toml"))
    res = mesh_model(m, D0, chord_tol=CHORD_REL)
    # the plain path's mesh is kept where it passes (the bore through the ball); the
    # cavity's cuts need the path for meeting faces (the crossing bores pass either way
    # at this threshold and tolerance)
    if name != "cross":
        assert res.info["meeting_path"] == (name == "cavity")
    q = quality_summary(res.points, res.tets)
    assert q["dihedral_min"] >= 10.0, q  # the plain path's mesh is kept only then
    if res.info["meeting_path"]:
        # the quality targets hold at the edge too: the vertices the projection could not
        # move are collapsed between the size rounds, the slivers left collapsed and flipped
        assert q["dihedral_p1"] >= 20.0, q
        assert q["radius_ratio_mean"] >= 0.75, q
    _check_faces_and_edge(res, m, name, D0)


def _check_faces_and_edge(res, m, name: str, d0: float):
    """The mesh of ``CASES[name]`` checked from the arrays: the independent helper (volumes,
    conformity, delta below ``d0``), every boundary triangle within the chord tolerance of
    its own face's surface (the curved ones at corners, edge midpoints and centroid; planes
    exactly), every edge between the two curved faces within the chord tolerance of their
    exact curve (ends, quarter points, midpoint)."""
    _text, comp, surfaces, (fa, fb), curve = CASES[name]
    bnd = check_tet_mesh(res.points, res.tets, comp, d0)
    assert len(bnd) == len(res.faces)
    chord = CHORD_REL * m.solid.diameter
    names = np.array(res.face_names)[res.face_markers - 1]
    q = res.points[res.faces]
    for face, g in surfaces.items():
        sel = names == face
        assert sel.any(), face
        dev = g(_tri_points(q[sel]))
        if face == "bottom":
            assert dev.max() == 0.0
        else:
            assert dev.max() <= chord * (1 + 1e-9), face
    # the edges between the two curved faces: in a triangle of each
    f = res.faces.astype(np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    lab = np.tile(names, 3)
    edges = {}
    for (a, b), nm in zip(map(tuple, e), lab):
        edges.setdefault((a, b), set()).add(nm)
    meet = np.array([k for k, v in edges.items() if v == {fa, fb}])
    assert len(meet) >= 10
    s = np.linspace(0, 1, 5)
    x0, x1 = res.points[meet[:, 0]], res.points[meet[:, 1]]
    pts = (x0[:, None] + s[None, :, None] * (x1 - x0)[:, None]).reshape(-1, 3)
    assert curve(pts).max() <= chord * (1 + 1e-9)


@pytest.mark.slow
def test_same_mesh_twice(tmp_path):
    m = load_model(write(tmp_path, CAVITY))
    a = mesh_model(m, D0, chord_tol=CHORD_REL)
    b = mesh_model(m, D0, chord_tol=CHORD_REL)
    assert a.points.tobytes() == b.points.tobytes()
    assert a.tets.tobytes() == b.tets.tobytes()


def _quality(points, tets):
    """The smallest dihedral angle (degrees; :func:`test_tet_flips.min_dihedral`) and the
    radius ratio ``3 r_in / R_circ`` of every tetrahedron, from numpy alone: ``r_in = 3 V /
    (sum of the face areas)``, the circumcentre solved from ``2 (x_k - x_0) . c = |x_k|^2 -
    |x_0|^2``."""
    x = np.asarray(points, float)[np.asarray(tets, np.int64)]
    e = x[:, 1:] - x[:, :1]
    vol = np.abs(np.linalg.det(e)) / 6
    area = sum(0.5 * np.linalg.norm(np.cross(x[:, b] - x[:, a], x[:, c] - x[:, a]), axis=1)
               for a, b, c in ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)))
    centre = np.linalg.solve(2 * e, (e * e).sum(axis=2)[..., None])[..., 0]  # from x_0
    ratio = 3 * (3 * vol / area) / np.linalg.norm(centre, axis=1)
    return min_dihedral(points, tets), ratio


def _check_targets(points, tets):
    """The quality targets: smallest dihedral angle >= 10 degrees, its 1st percentile >= 20,
    mean radius ratio >= 0.75."""
    dih, ratio = _quality(points, tets)
    assert dih.min() >= 10.0, dih.min()
    assert np.percentile(dih, 1.0) >= 20.0, np.percentile(dih, 1.0)
    assert ratio.mean() >= 0.75, ratio.mean()


def test_uniform_mesh_where_curved_faces_meet(tmp_path):
    """The uniform baseline's mesh of the cavity at one size takes the adaptive mesher's path
    for meeting faces (the vertices left short collapsed between the rounds, the slivers
    collapsed and flipped at the end): verified, the faces and the edge within the chord
    tolerance, and the quality targets met (checked from the arrays). Before, it took the
    cuts and the projection of that path alone: smallest dihedral angle 0.1 degrees."""
    m = load_model(write(tmp_path, CAVITY, "cavity.toml"))
    chord = CHORD_REL * m.solid.diameter
    res = uniform_solid_at(m.solid, m.material, 0.3, D0, chord_tol=chord)
    assert solid_problems(res, m.solid, m.material, chord) == []
    _check_faces_and_edge(res, m, "cavity", D0)
    _check_targets(res.points, res.tets)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cross", "bore_sphere"])
def test_uniform_search_where_curved_faces_meet(tmp_path, name):
    """``hetmesh uniform``'s search on the crossing bores and the bore through the ball: the
    coarsest passing mesh is verified (the ball's within the volume the chords allow: 1.6 %
    under the grid estimate) and meets the quality targets (checked from the arrays)."""
    m = load_model(write(tmp_path, CASES[name][0], f"{name}.toml"))
    res = uniform_model(m, D0, chord_tol=CHORD_REL)
    assert res.info["placement"] == "uniform remeshed"
    _check_faces_and_edge(res, m, name, D0)
    _check_targets(res.points, res.tets)
