"""Jumps of a piecewise composition inside solids bounded by a triangulated surface
(``[solid] type = "surface"`` with ``where``): every tetrahedron in one phase, the interfaces
on their jump surfaces, their rims on both the jump and the input surface, delta per side,
the interfaces recorded as faces ``discontinuity[k]`` -- all checked here from the arrays
and the models' own geometry (the branch formulas, the box's planes, the sphere, the
bracket's faces and bore), not with hetmesh's verification. Plus determinism and the
one-line refusal of a jump nearly tangent to the surface."""

from __future__ import annotations

import hashlib

import meshio
import numpy as np
import pytest

import hetmesh
from hetmesh.cli import main
from hetmesh.io.model import load_model
from hetmesh.tet.api import mesh_model
from hetmesh.tet.quality import min_dihedral
from hetmesh.tet.surface_mesh import surface_problems


def box_surface(lo, hi, n: int = 2):
    """The surface of the box ``[lo, hi]``: every face an ``n x n`` grid of squares, two
    outward triangles each."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    V, F = [], []
    ex, ey, ez = np.diag(hi - lo)
    for o, a, b in ((lo, ey, ex), (lo + ez, ex, ey), (lo, ex, ez), (lo + ey, ez, ex),
                    (lo, ez, ey), (lo + ex, ey, ez)):
        base = len(V)
        V += [o + a * i / n + b * j / n for i in range(n + 1) for j in range(n + 1)]
        for i in range(n):
            for j in range(n):
                v0 = base + i * (n + 1) + j
                F += [[v0, v0 + n + 1, v0 + n + 2], [v0, v0 + n + 2, v0 + 1]]
    return np.array(V), np.array(F)


def cylinder_surface(r: float, h: float, n: int = 48):
    """A closed cylinder around the z axis from z = 0 to h: ``n`` facets around."""
    a = 2 * np.pi * np.arange(n) / n
    ring = np.c_[r * np.cos(a), r * np.sin(a)]
    V = np.r_[np.c_[ring, np.zeros(n)], np.c_[ring, np.full(n, h)], [[0, 0, 0], [0, 0, h]]]
    F = []
    for i in range(n):
        j = (i + 1) % n
        F += [[i, j, n + j], [i, n + j, n + i], [2 * n, j, i], [2 * n + 1, n + i, n + j]]
    return V, np.array(F)


MODEL = """
[model]
name = "{name}"

[solid]
type = "surface"
file = "{file}"

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""

CHORD_TOL = 0.005  # relative to the diameter


def model_file(tmp_path, name, surface, formula):
    stl = tmp_path / f"{name}.stl"
    meshio.write_points_cells(str(stl), *surface[:1], [("triangle", surface[1])])
    path = tmp_path / f"{name}.toml"
    path.write_text(MODEL.format(name=name, file=stl.name, formula=formula), encoding="utf-8")
    return path


def tet_faces(t):
    f = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]])
    return np.sort(f, axis=1), np.tile(np.arange(len(t)), 4)


def interfaces_and_boundary(t, region):
    """Triangles between tetrahedra of different regions, and the boundary triangles."""
    key, owner = tet_faces(t)
    order = np.lexsort(key.T[::-1])
    ks, ow = key[order], owner[order]
    same = (ks[1:] == ks[:-1]).all(axis=1)
    a, b = ow[:-1][same], ow[1:][same]
    inter = ks[:-1][same][region[a] != region[b]]
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    assert counts.max() <= 2  # conforming
    return inter, key[counts[inv.reshape(-1)] == 1]


def tri_points(q):
    """Corners, edge midpoints and centroid of triangles ``(K, 3, 3)``: ``(K, 7, 3)``."""
    mids = 0.5 * (q + q[:, [1, 2, 0]])
    return np.concatenate([q, mids, q.mean(axis=1, keepdims=True)], axis=1)


def volumes(p, t):
    a, b, c, d = (p[t[:, k]] for k in range(4))
    return np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) / 6.0


def branch_delta(p, t, region, branches):
    """delta of every tetrahedron with its corners evaluated in its own region's formula."""
    delta = np.full(len(t), np.nan)
    for k, f in branches.items():
        sel = region == k
        v = f(p[t[sel].ravel()]).reshape(-1, 4)
        delta[sel] = v.max(axis=1) - v.min(axis=1)
    assert np.isfinite(delta).all()
    return delta


def check_common(res, branches, threshold):
    """Positive volumes, every tetrahedron's delta per its region below ``threshold``, the
    interfaces recorded as ``discontinuity[0]``: ``(p, t, region, interfaces, boundary)``."""
    p, t = res.points, res.tets.astype(np.int64)
    assert volumes(p, t).min() > 0
    region = np.asarray(res.info["regions"], dtype=np.int64)
    assert set(np.unique(region).tolist()) == set(branches)
    assert branch_delta(p, t, region, branches).max() < threshold
    inter, bnd = interfaces_and_boundary(t, region)
    names = list(res.face_names)
    assert names[-1] == "discontinuity[0]"
    k = names.index("discontinuity[0]") + 1
    rec = np.sort(res.faces[res.face_markers == k], axis=1)
    assert {tuple(f) for f in rec.tolist()} == {tuple(f) for f in inter.tolist()}
    assert len(res.faces) == len(inter) + len(bnd)
    return p, t, region, inter, bnd


def rim_of(inter, bnd):
    return np.intersect1d(np.unique(inter), np.unique(bnd))


def on_box(x, lo, hi, tol):
    """Whether every point lies on a face of the box ``[lo, hi]`` (within ``tol``) and none
    outside."""
    inside = ((x >= np.asarray(lo) - tol) & (x <= np.asarray(hi) + tol)).all(axis=1)
    face = (np.abs(x - lo) <= tol).any(axis=1) | (np.abs(x - hi) <= tol).any(axis=1)
    return inside & face


# -- a plane jump in a box -------------------------------------------------------------------

PLANE = "where(z < 0.4, 0.2 + 0.3*x, 0.8 - 0.2*y)"
PLANE_BRANCH = {1: lambda q: 0.2 + 0.3 * q[:, 0], 0: lambda q: 0.8 - 0.2 * q[:, 1]}


@pytest.fixture(scope="module")
def plane(tmp_path_factory):
    path = model_file(tmp_path_factory.mktemp("plane"), "plane", box_surface([0, 0, 0],
                                                                              [2, 1, 1]), PLANE)
    model = load_model(path)
    return model, mesh_model(model, 0.25, chord_tol=CHORD_TOL)


def test_a_plane_jump_in_a_box_is_an_interface(plane):
    model, res = plane
    p, t, region, inter, bnd = check_common(res, PLANE_BRANCH, 0.25)
    cen = p[t].mean(axis=1)
    assert ((cen[:, 2] < 0.4).astype(int) == region).all()
    assert np.abs(p[np.unique(inter), 2] - 0.4).max() <= 1e-12  # a plane: exact
    assert on_box(p[np.unique(bnd)], [0, 0, 0], [2, 1, 1], 1e-12).all()
    rim = rim_of(inter, bnd)
    assert len(rim) >= 8  # the rectangle where the plane meets the box
    # the rim's corners: the box's vertical edges at z = 0.4
    for x, y in ((0, 0), (2, 0), (0, 1), (2, 1)):
        assert (np.linalg.norm(p[rim] - [x, y, 0.4], axis=1) <= 1e-12).any()
    assert np.isclose(volumes(p, t)[region == 1].sum(), 0.8, rtol=1e-12)
    assert res.face_names[0] == "surface"
    assert res.info["jump_conditions"] == ("z < 0.4",)


def test_the_interface_is_written_as_a_physical_group(plane, tmp_path):
    _, res = plane
    out = tmp_path / "plane.msh"
    res.mesh.write(out)
    m = meshio.read(out)
    assert {"discontinuity[0]", "surface", "region_0", "region_1"} <= set(m.field_data)
    tags = np.concatenate(m.cell_data["gmsh:physical"])
    k = list(res.face_names).index("discontinuity[0]") + 1
    assert (tags == m.field_data["discontinuity[0]"][0]).sum() == (res.face_markers == k).sum()


def test_the_verification_catches_a_rim_vertex_off_the_surface(plane):
    """hetmesh's own check of the mesh finds a rim vertex moved off the box (inward, the
    tetrahedra still positive)."""
    model, res = plane
    chord = CHORD_TOL * model.solid.diameter
    assert surface_problems(res, model.solid, model.material, chord) == []
    p, t = res.points, res.tets.astype(np.int64)
    region = np.asarray(res.info["regions"], dtype=np.int64)
    inter, bnd = interfaces_and_boundary(t, region)
    rim = rim_of(inter, bnd)
    # a rim vertex inside the face x = 0 (not on an edge of the box)
    v = int(rim[(np.abs(p[rim, 0]) <= 1e-12) & (p[rim, 1] > 0.1) & (p[rim, 1] < 0.9)][0])
    bad = res.points.copy()
    bad[v, 0] += 3 * chord
    assert volumes(bad, t).min() > 0
    broken = type(res)(bad, res.tets, res.faces, res.face_markers, res.face_names, res.delta,
                       res.threshold, res.info)
    problems = surface_problems(broken, model.solid, model.material, chord)
    assert any("rim" in s for s in problems), problems


@pytest.mark.slow  # 10-28 s: the default step stays under 10 minutes
def test_same_model_same_mesh(tmp_path):
    path = model_file(tmp_path, "det", box_surface([0, 0, 0], [1, 1, 1]), PLANE)
    h = []
    for _ in range(2):
        r = mesh_model(load_model(path), 0.3, chord_tol=0.01)
        h.append(hashlib.sha1(r.points.tobytes() + r.tets.astype(np.int64).tobytes()
                              + np.asarray(r.info["regions"], np.int64).tobytes()
                              + r.faces.astype(np.int64).tobytes()).hexdigest())
    assert h[0] == h[1]


# -- a curved jump: a ball around a corner of the box ------------------------------------------

BALL = "where(x**2 + y**2 + z**2 < 0.49, 0.3 + 0.2*z, 0.9 - 0.1*x)"
BALL_BRANCH = {1: lambda q: 0.3 + 0.2 * q[:, 2], 0: lambda q: 0.9 - 0.1 * q[:, 0]}


@pytest.mark.slow  # 10-28 s: the default step stays under 10 minutes
def test_a_ball_jump_meets_three_faces_of_a_box(tmp_path):
    """The sphere r = 0.7 around a corner of the unit box: its interface within the chord
    tolerance of the sphere (checked at 7 points per triangle), its rim (three quarter
    circles on the faces x = 0, y = 0, z = 0) on the faces exactly and on the sphere."""
    path = model_file(tmp_path, "ball", box_surface([0, 0, 0], [1, 1, 1]), BALL)
    model = load_model(path)
    res = mesh_model(model, 0.25, chord_tol=CHORD_TOL)
    chord = CHORD_TOL * model.solid.diameter
    p, t, region, inter, bnd = check_common(res, BALL_BRANCH, 0.25)
    r = np.linalg.norm(p[t].mean(axis=1), axis=1)
    own = (r ** 2 < 0.49).astype(int)
    assert (np.abs(r[own != region] - 0.7) <= chord).all()
    assert (own == region).mean() > 0.999
    rad = np.linalg.norm(tri_points(p[inter]), axis=2)
    assert np.abs(rad - 0.7).max() <= chord * (1 + 1e-9)
    assert on_box(p[np.unique(bnd)], [0, 0, 0], [1, 1, 1], 1e-12).all()
    rim = rim_of(inter, bnd)
    assert np.abs(np.linalg.norm(p[rim], axis=1) - 0.7).max() <= chord
    for axis in range(3):  # every quarter circle has rim vertices
        assert (np.abs(p[rim, axis]) <= 1e-12).sum() >= 6
    # the volume of the ball's octant, within the chord tolerance x its area
    inner = volumes(p, t)[region == 1].sum()
    assert abs(inner - np.pi * 0.7 ** 3 / 6) <= chord * np.pi * 0.7 ** 2 / 2
    assert min_dihedral(p, t).min() >= 5.0


def test_two_conditions_make_four_regions(tmp_path):
    """``where(z < 0.4, where(x < 0.55, ...), ...)``: two jump planes, cut everywhere (four
    regions, the conditions' truth values), the rim where both meet the box on both
    planes."""
    formula = "where(z < 0.4, where(x < 0.55, 0.2 + 0.1*y, 0.4), 0.8 - 0.2*y)"
    path = model_file(tmp_path, "two", box_surface([0, 0, 0], [1, 1, 1]), formula)
    model = load_model(path)
    res = mesh_model(model, 0.25, chord_tol=0.01)
    p, t = res.points, res.tets.astype(np.int64)
    assert volumes(p, t).min() > 0
    region = np.asarray(res.info["regions"], dtype=np.int64)
    field = model.material
    cen = p[t].mean(axis=1)
    assert (np.asarray(field.region(cen)) == region).all()
    assert len(np.unique(region)) == 4
    low = cen[:, 2] < 0.4
    sides = {(True, True): lambda q: 0.2 + 0.1 * q[:, 1],
             (True, False): lambda q: 0.4 + 0 * q[:, 0],
             (False, True): lambda q: 0.8 - 0.2 * q[:, 1],
             (False, False): lambda q: 0.8 - 0.2 * q[:, 1]}
    for (lz, lx), f in sides.items():
        sel = (low == lz) & ((cen[:, 0] < 0.55) == lx)
        v = f(p[t[sel].ravel()]).reshape(-1, 4)
        assert (v.max(axis=1) - v.min(axis=1)).max(initial=0.0) < 0.25
    inter, bnd = interfaces_and_boundary(t, region)
    ids = np.unique(inter)
    on_plane = (np.abs(p[ids, 2] - 0.4) <= 1e-12) | (np.abs(p[ids, 0] - 0.55) <= 1e-12)
    assert on_plane.all()
    # where both planes meet the faces y = 0 and y = 1: a point on all three
    for y in (0.0, 1.0):
        assert (np.linalg.norm(p - [0.55, y, 0.4], axis=1) <= 1e-12).any()


# -- the example bracket with a jump across its web and bore --------------------------------------

@pytest.mark.parametrize("z0, bore", [(25.0, True),
                                      pytest.param(10.0, False, marks=pytest.mark.slow)])
def test_a_jump_across_the_bracket_s_web(tmp_path, z0, bore):
    """examples/l_bracket.stl (feature faces) with ``where(z < z0, ...)``: at z0 = 25 the
    plane crosses the web and its bore (radius 5 around (y, z) = (10, 27), 48 facets); at
    z0 = 10 it crosses the web where it meets the foot and lies on the foot's top face (no
    crossing there). The interface lies on the plane, its rim on the web's planes or the
    bore's facets, the faces kept."""
    src = hetmesh.example_path("l_bracket")
    text = src.read_text(encoding="utf-8").replace(
        'file = "l_bracket.stl"', f'file = "{(src.parent / "l_bracket.stl").as_posix()}"')
    text = text.replace('metal = "((x + z)/50)**2"',
                        f'metal = "where(z < {z0:g}, 0.2 + 0.01*x, 0.8)"')
    path = tmp_path / "m.toml"
    path.write_text(text, encoding="utf-8")
    model = load_model(path)
    res = mesh_model(model, 0.25)
    branches = {1: lambda q: 0.2 + 0.01 * q[:, 0], 0: lambda q: 0.8 + 0 * q[:, 0]}
    p, t, region, inter, bnd = check_common(res, branches, 0.25)
    assert res.face_names[:10] == tuple(f"surface.{i}" for i in range(1, 11))
    cen = p[t].mean(axis=1)
    assert ((cen[:, 2] < z0).astype(int) == region).all()
    assert np.abs(p[np.unique(inter), 2] - z0).max() <= 1e-9
    # the interface is the web's section: 10 x 20 less the bore's
    tri = p[inter]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                axis=1).sum()
    cut = 2 * 10 * np.sqrt(25 - (z0 - 27) ** 2) if bore else 0.0
    assert abs(area - (200 - cut)) <= 0.05 * cut + 1e-6
    rim = p[rim_of(inter, bnd)]
    assert ((rim[:, 0] > -1e-9) & (rim[:, 0] < 10 + 1e-9)).all()  # in the web
    flat = (np.abs(rim[:, 0]) <= 1e-9) | (np.abs(rim[:, 0] - 10) <= 1e-9) \
        | (np.abs(rim[:, 1]) <= 1e-9) | (np.abs(rim[:, 1] - 20) <= 1e-9)
    dist = np.hypot(rim[:, 1] - 10, rim[:, 2] - 27)
    chord = 2e-3 * model.solid.diameter
    on_bore = np.abs(dist - 5) <= chord
    assert (flat | on_bore).all()
    # the two lines where the plane crosses the bore
    assert (on_bore.sum() >= 8) == bore
    # the rim's corners on the end y = 0, where the web's faces x = 0 and x = 10 meet it
    for x in (0.0, 10.0):
        assert (np.linalg.norm(rim - [x, 0.0, z0], axis=1) <= 1e-9).any()


# -- refused ----------------------------------------------------------------------------------

@pytest.mark.parametrize("surface, formula, condition, near", [
    # the plane x = 0.499 meets the cylinder r = 0.5 at under 4 degrees
    (cylinder_surface(0.5, 1.0), "where(x < 0.499, 0.2 + 0.1*z, 0.8)", "x < 0.499",
     "at 3.8 degrees to it near (0.49"),
    # the plane through the box's edge x = 1, z = 0 at 2.9 degrees to its face x = 1: a
    # thin wedge along the face
    (box_surface([0, 0, 0], [1, 1, 1]), "where(x + 0.05*z < 1, 0.2 + 0.1*z, 0.8)",
     "x + 0.05*z < 1", "meets the surface at 2.9 degrees near (1, "),
    # a ball poking 0.002 out of the bottom face of a cube of two triangles per face, in
    # a circle of radius 0.045 around (0.3, 0.3, 0) between the corners
    (box_surface([0, 0, 0], [1, 1, 1], 1),
     "where((x-0.3)**2 + (y-0.3)**2 + (z-0.5)**2 < 0.252004, 0.3 + 0.1*z, 0.8)",
     "(x - 0.3)**2 + (y - 0.3)**2 + (z - 0.5)**2 < 0.252004", "degrees to it near (0.3"),
    # a layer 0.02 thick along the bottom face, much thinner than the elements
    (box_surface([0, 0, 0], [1, 1, 1]), "where(z < 0.02, 0.2 + 0.1*x, 0.8)", "z < 0.02",
     "comes within 0.02 of the surface at 0.0 degrees to it near ("),
])
def test_a_jump_nearly_tangent_to_the_surface_fails_in_one_line(tmp_path, capsys, surface,
                                                                formula, condition, near):
    """Refused with one line naming the condition and a point (exit 2, nothing
    written)."""
    path = model_file(tmp_path, "tangent", surface, formula)
    out = tmp_path / "x.vtu"
    rc = main(["mesh", str(path), "--threshold", "0.25", "--output", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists() and len(err.splitlines()) == 1
    assert f"material.composition.metal: condition '{condition}'" in err
    assert "nearly tangent" in err and near in err, err


# -- the uniform baseline with the jumps ------------------------------------------------------

@pytest.mark.slow  # its size search remeshes every size tried (14-17 s on the loaded machine)
def test_the_uniform_baseline_keeps_the_jump(tmp_path):
    """``hetmesh uniform`` of the box with the plane jump: the size search meets delta_0 (it
    could not before: no size does across a jump), the plane z = 0.4 an interface, every
    centroid on its side, the rim on the box, delta per side as the branch formulas give
    it; verified as the adaptive mesh is."""
    from hetmesh.tet.uniform import uniform_model

    path = model_file(tmp_path, "uni", box_surface([0, 0, 0], [2, 1, 1]), PLANE)
    model = load_model(path)
    res = uniform_model(model, 0.25, chord_tol=CHORD_TOL)
    p, t, region, inter, bnd = check_common(res, PLANE_BRANCH, 0.25)
    assert np.allclose(branch_delta(p, t, region, PLANE_BRANCH), res.delta, atol=1e-12)
    assert ((p[t].mean(axis=1)[:, 2] < 0.4).astype(int) == region).all()
    assert np.abs(p[np.unique(inter), 2] - 0.4).max() <= 1e-12
    assert on_box(p[np.unique(bnd)], [0, 0, 0], [2, 1, 1], 1e-12).all()
    assert res.info["placement"] == "uniform remeshed"
    assert res.info["jump_conditions"] == ("z < 0.4",)
