"""Solids of primitives (a sphere, a clipped primitive, subtractions that are not
through-holes): the model file, the general-solid mesher and its guarantees, checked
from the arrays alone."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hetmesh
from hetmesh.cli import main
from hetmesh.errors import GeometryError, ModelFileError
from hetmesh.io.model import load_model
from hetmesh.tet.api import mesh_model
from hetmesh.tet.implicit import CSGSolid
from hetmesh.tet.mesher import CHORD
from test_tet import check_tet_mesh

MATERIAL = """
[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""

#: a box with a blind bore from the top and a spherical pocket cut into one edge
BOX_BORE = """
[solid]
type = "box"
min = [0, 0, 0]
max = [1, 1, 1]

[[solid.subtract]]
type = "cylinder"
center = [0.5, 0.5]
radius = 0.25
from = 0.4
to = 2
name = "bore"

[[solid.subtract]]
type = "sphere"
center = [1, 1, 0]
radius = 0.3
name = "pocket"
""" + MATERIAL.format(formula="(1 - z)**2")


def write(tmp_path, text, name="m.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def boundary_triangles(tets):
    f = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]],
                        tets[:, [0, 1, 2]]])
    key = np.sort(f, axis=1)
    u, cnt = np.unique(key, axis=0, return_counts=True)
    return u[cnt == 1]


def tri_points(q):
    """Points of triangles ``(K, 3, 3)``: corners, edge midpoints and the centroid."""
    mids = 0.5 * (q + q[:, [1, 2, 0]])
    return np.concatenate([q, mids, q.mean(axis=1, keepdims=True)], axis=1)


def test_graded_sphere_meets_every_guarantee():
    """The example's octant of the hollow sphere: delta, volumes and conformity recomputed;
    every boundary triangle exactly on a symmetry plane or within the chord tolerance of a
    sphere; the volume of the shell up to the chords; the five faces named."""
    m = load_model(hetmesh.example_path("graded_sphere"))
    assert isinstance(m.solid, CSGSolid)
    assert set(m.solid.face_names) == {"outer", "inner", "xmin", "ymin", "zmin"}
    d0 = 0.3
    res = mesh_model(m, d0)
    assert res.info["placement"] == "general"
    f = lambda p: ((np.linalg.norm(p, axis=1) - 10) / 10) ** 2  # noqa: E731
    bnd = check_tet_mesh(res.points, res.tets, f, d0)
    chord = CHORD * m.solid.diameter
    q = res.points[bnd]
    plane = np.zeros(len(bnd), dtype=bool)
    for k in range(3):
        on = (q[:, :, k] == 0).all(axis=1)
        plane |= on
        # a symmetry plane's triangles cover its quarter annulus, up to the chords
        area = 0.5 * np.linalg.norm(np.cross(q[on, 1] - q[on, 0], q[on, 2] - q[on, 0]),
                                    axis=1).sum()
        assert abs(area - math.pi / 4 * (400 - 100)) <= chord * math.pi / 2 * 30
    r = np.linalg.norm(tri_points(q[~plane]), axis=2)
    off = np.minimum(np.abs(r - 10), np.abs(r - 20)).max(axis=1)
    assert off.max() <= chord * (1 + 1e-9)
    a, b, c, d = (res.points[res.tets[:, k]] for k in range(4))
    vol = (np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) / 6).sum()
    exact = math.pi / 6 * (20 ** 3 - 10 ** 3)
    assert abs(vol - exact) <= chord * math.pi / 2 * (400 + 100)
    # the face markers name the faces the triangles are on
    names = dict(enumerate(res.face_names, start=1))
    inner = res.faces[np.array([names[k] == "inner" for k in res.face_markers])]
    assert np.abs(np.linalg.norm(res.points[inner], axis=2) - 10).max() <= chord
    # economy: N_iso3 = 6 sqrt(2) int |grad f|^3 dV / d0^3 in closed form (|grad f| =
    # (r - 10)/50 over the octant of the shell); the mesh had 6.0 x at 0.3 while each size
    # round remeshed once, 3.3 x since
    # int_0^10 (s/50)^3 (s + 10)^2 ds with s = r - 10, over a solid angle of pi/2
    integral = math.pi / 2 * (10 ** 6 / 6 + 20 * 10 ** 5 / 5 + 100 * 10 ** 4 / 4) / 50 ** 3
    n_iso3 = 6 * math.sqrt(2) * integral / d0 ** 3
    assert len(res.tets) <= 4.0 * n_iso3


@pytest.mark.slow  # 10-28 s: the default step stays under 10 minutes
def test_partial_subtractions(tmp_path):
    """A blind bore and a pocket cut into an edge: planar faces exact, curved ones within
    the chord tolerance, the bore's bottom a disk at z = 0.4, same mesh twice."""
    m = load_model(write(tmp_path, BOX_BORE))
    assert m.solid.face_names == ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax", "bore",
                                  "bore.bottom", "pocket")
    d0 = 0.4
    res = mesh_model(m, d0)
    bnd = check_tet_mesh(res.points, res.tets, lambda p: (1 - p[:, 2]) ** 2, d0)
    q = res.points[bnd]
    chord = CHORD * m.solid.diameter
    planar = np.zeros(len(bnd), dtype=bool)
    for k in range(3):
        for v in (0.0, 1.0):
            planar |= (q[:, :, k] == v).all(axis=1)
    bottom = (q[:, :, 2] == 0.4).all(axis=1)
    assert (np.hypot(q[bottom, :, 0] - 0.5, q[bottom, :, 1] - 0.5) <= 0.25 + 1e-12).all()
    rest = tri_points(q[~planar & ~bottom])
    d_bore = np.abs(np.hypot(rest[..., 0] - 0.5, rest[..., 1] - 0.5) - 0.25)
    d_pocket = np.abs(np.linalg.norm(rest - [1, 1, 0], axis=2) - 0.3)
    assert np.minimum(d_bore, d_pocket).max(axis=1).max() <= chord * (1 + 1e-9)
    assert len(res.faces) == len(bnd)
    again = mesh_model(m, d0)
    assert again.points.tobytes() == res.points.tobytes()
    assert again.tets.tobytes() == res.tets.tobytes()


def test_csg_volume_and_faces():
    from hetmesh.tet.implicit import Box, Cylinder, Sphere
    s = CSGSolid(Box((0, 0, 0), (2, 2, 2)),
                 subtract=(Sphere((1, 1, 1), 0.5, ("ball",)),
                           Cylinder((1, 1), 0.2, 0, -1, 3, ("hole", "h.b", "h.t"))))
    # the hole crosses the ball: no closed form; the grid estimate is within 1 %
    assert s.exact_volume is None
    # the bore outside the ball: about its length 2 less the chord 2 sqrt(0.5^2 - 0.2^2)
    want = 8 - 4 / 3 * math.pi * 0.125 - math.pi * 0.04 * (2 - 2 * math.sqrt(0.21))
    assert s.face_names == ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax", "ball", "hole")
    assert abs(s.volume - want) < 0.02 * want
    ball = CSGSolid(Sphere((0, 0, 0), 1.0))
    assert ball.exact_volume == pytest.approx(4 / 3 * math.pi)


@pytest.mark.parametrize("snippet, cls, contains", [
    ('[solid]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 0\n', GeometryError,
     "solid.radius: a primitive's size must be positive"),
    ('[solid]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1\ninner_radius = 1\n',
     GeometryError, "solid.inner_radius"),
    ('[solid]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1\n'
     'clip = { min = [2, 2, 2], max = [3, 3, 3] }\n', GeometryError, "solid.clip"),
    ('[solid]\ntype = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n[[solid.subtract]]\n'
     'type = "sphere"\ncenter = [0.5, 0.5, 0.5]\nradius = 2\n', GeometryError,
     "solid.subtract: the subtraction leaves nothing"),
    ('[solid]\ntype = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n[[solid.subtract]]\n'
     'type = "sphere"\ncenter = [0.5, 0.5, 0.5]\nradius = -1\n', GeometryError,
     "solid.subtract[0].radius: a primitive's size must be positive"),
    ('[solid]\ntype = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n[[solid.subtract]]\n'
     'type = "cylinder"\ncenter = [0.5, 0.5]\nradius = 0.1\nfrom = 0.5\nto = 0.5\n',
     GeometryError, "solid.subtract[0]: a primitive's size must be positive"),
    ('[solid]\ntype = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n[[solid.subtract]]\n'
     'type = "sphere"\ncenter = [0, 0, 0]\nradius = 0.2\nname = "a"\n[[solid.subtract]]\n'
     'type = "sphere"\ncenter = [1, 1, 1]\nradius = 0.2\nname = "a"\n', ModelFileError,
     "two faces are named 'a'"),
    ('[solid]\ntype = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n[[solid.subtract]]\n'
     'type = "torus"\n', ModelFileError, "solid.subtract[0].type"),
    ('[solid]\ntype = "sphere"\ncenter = [0, 0]\nradius = 1\n', ModelFileError,
     "solid.center"),
])
def test_bad_primitive_solids(tmp_path, snippet, cls, contains):
    p = write(tmp_path, snippet + MATERIAL.format(formula="z*z"))
    with pytest.raises(cls, match=contains.replace("[", r"\[").replace("]", r"\]")) as e:
        load_model(p)
    assert str(e.value).startswith(str(p)) and "\n" not in str(e.value)


def test_formula_in_w_is_refused_for_a_sphere(tmp_path):
    p = write(tmp_path, '[solid]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1\n'
              + MATERIAL.format(formula="w"))
    with pytest.raises(hetmesh.errors.FormulaError, match="unknown name 'w'"):
        load_model(p)


def test_cli_bad_sphere_exits_2_and_writes_nothing(tmp_path, capsys):
    p = write(tmp_path, '[solid]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = -2\n'
              + MATERIAL.format(formula="z*z"))
    out = tmp_path / "s.vtu"
    code = main(["mesh", str(p), "--threshold", "0.3", "--output", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert "solid.radius" in err and len(err.strip().splitlines()) == 1


def test_a_through_hole_keeps_the_swept_mesher(tmp_path):
    """Subtractions that are through-holes along the axis stay prisms (their meshes are
    unchanged); the same cylinder stopping inside goes to the general mesher."""
    from hetmesh.tet.solid import Prism
    base = '[solid]\ntype = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n[[solid.subtract]]\n' \
           'type = "cylinder"\ncenter = [0.5, 0.5]\nradius = 0.2\n'
    m = load_model(write(tmp_path, base + MATERIAL.format(formula="z*z")))
    assert isinstance(m.solid, Prism)
    m = load_model(write(tmp_path, base + "from = 0.5\nto = 1.5\n"
                         + MATERIAL.format(formula="z*z")))
    assert isinstance(m.solid, CSGSolid)
    assert m.solid.face_names[-2:] == ("solid_subtract[0]", "solid_subtract[0].bottom")


@pytest.mark.slow
def test_graded_sphere_solves_to_the_exact_radial_solution(tmp_path):
    """The example meshed at delta_0 = 0.1, written, read back and analysed with quadratic
    tetrahedra: radial and hoop stresses at R1..R3 within 1 % of the exact graded sphere."""
    import hetmesh.fea as fea
    from hetmesh.fea import verification
    from hetmesh.io.read import read_mesh
    model = hetmesh.load_model(hetmesh.example_path("graded_sphere"))
    r = hetmesh.generate(model, 0.1)
    back = read_mesh(r.mesh.write(tmp_path / "sphere.vtu"))
    res = fea.solve(back, model)
    ref = verification.reference("sphere")
    for name, q in verification.case_probes("sphere").items():
        sr, st = verification.radial_hoop("sphere", res.probes[name])
        rr = math.sqrt(sum(c * c for c in q))
        assert abs(sr - ref.sigma_r(rr)) < 0.01 * abs(ref.sigma_r(rr)), name
        assert abs(st - ref.sigma_t(rr)) < 0.01 * abs(ref.sigma_t(rr)), name
