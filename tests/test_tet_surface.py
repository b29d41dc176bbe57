"""Solids bounded by a triangulated surface (``[solid] type = "surface"``): the surface
checks, the example l_bracket meshed and checked from the arrays alone against the bracket's
own geometry, determinism, and bad inputs (one line, exit 2, nothing written).

The first volume is hetmesh's own fill (hetmesh.tet.surface_fill, tests/test_surface_fill.py);
nothing here needs Gmsh. ``need_gmsh`` (skip without Gmsh, fail under ``CI=true``) is kept for
the tests that use Gmsh as a peer."""

from __future__ import annotations

import importlib.util
import os
import re
import sys

import meshio
import numpy as np
import pytest

import hetmesh
from hetmesh.cli import main
from hetmesh.errors import GeometryError
from hetmesh.io.model import load_model
from hetmesh.tet.api import mesh_model
from hetmesh.tet.mesher import CHORD
from hetmesh.tet.surface import SurfaceSolid, ray_parity
from test_tet import check_tet_mesh

CI = os.environ.get("CI", "").lower() == "true"


def need_gmsh():
    try:
        import gmsh  # noqa: F401
    except Exception as exc:  # noqa: BLE001
        if CI:
            pytest.fail(f"gmsh is missing under CI=true ({exc}); install '.[test]'")
        pytest.skip(f"gmsh is not installed ({exc}): pip install '.[peers]'")


MODEL = """
[solid]
type = "surface"
file = "{file}"

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""


def cube(lo=0.0, hi=1.0, inward=False, offset=(0.0, 0.0, 0.0)):
    """The surface of a cube: 8 points, 12 outward (or inward) triangles."""
    V = np.array([[x, y, z] for x in (lo, hi) for y in (lo, hi) for z in (lo, hi)], float)
    V += np.asarray(offset)
    # each face as two triangles, counter-clockwise seen from outside
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    F = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return V, (F[:, [0, 2, 1]] if inward else F)


def write_surface(path, V, F):
    meshio.write_points_cells(str(path), np.asarray(V, float), [("triangle", np.asarray(F))])
    return path


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# -- the surface and its checks ------------------------------------------------------------

def test_a_cube_in_every_format_reads_the_same(tmp_path):
    V, F = cube(0.0, 2.0)
    for ext in ("stl", "obj", "ply"):
        s = SurfaceSolid.read(write_surface(tmp_path / f"c.{ext}", V, F))
        assert s.volume == pytest.approx(8.0, rel=1e-12)
        assert s.face_names == ("surface",)
        assert s.contains([[1, 1, 1], [3, 1, 1]]).tolist() == [True, False]


def test_feature_angle_splits_the_faces_at_sharp_edges():
    V, F = cube()
    assert SurfaceSolid.from_arrays(V, F, "c").face_names == ("surface",)
    s = SurfaceSolid.from_arrays(V, F, "c", feature_angle=30)
    assert s.face_names == tuple(f"surface.{i}" for i in range(1, 7))
    assert np.bincount(s.patch).tolist() == [2] * 6
    assert SurfaceSolid.from_arrays(V, F, "c", feature_angle=95).face_names == ("surface",)


def test_an_inward_surface_is_turned_outward_and_a_cavity_kept():
    V, F = cube(inward=True)
    assert SurfaceSolid.from_arrays(V, F, "c").volume == pytest.approx(1.0)
    Vi, Fi = cube(0.25, 0.75, inward=True)
    s = SurfaceSolid.from_arrays(np.r_[V, Vi], np.r_[F[:, [0, 2, 1]], Fi + 8], "hollow")
    assert s.volume == pytest.approx(1 - 0.125)
    assert s.contains([[0.5, 0.5, 0.5], [0.1, 0.5, 0.5]], 0.0).tolist() == [False, True]


def test_inside_is_exact_through_vertices_and_edges():
    """The ray parity counts a ray through an edge or a vertex once: on a lattice through
    the example's points it agrees with the winding number wherever the point is off the
    surface."""
    s = SurfaceSolid.read(hetmesh.example_path("l_bracket").with_suffix(".stl"))
    g = np.stack(np.meshgrid(np.arange(-2, 42, 2.0), np.arange(-2, 22, 2.0),
                             np.arange(-2, 42, 2.0), indexing="ij"), -1).reshape(-1, 3)
    off = s.distance(g) > 1e-9
    inside = ray_parity(s.V, s.F, g[off])
    np.testing.assert_array_equal(inside, s.winding(g[off]) > 0.5)
    assert 0.2 < inside.mean() < 0.5


@pytest.mark.parametrize("case, message", [
    ("open", "not watertight: open (a hole in it)"),
    ("seam", "not watertight: not manifold"),
    ("flipped", "not consistently oriented"),
    ("crossing", "intersects itself"),
    ("flat", "encloses no volume"),
    ("degenerate", "has zero area"),
    ("few", "needs at least 4 triangles"),
    ("nested", "the shells do not nest: an outward shell lies inside the solid"),
    ("stray cavity", "a shell turned inward (a cavity) lies outside the solid"),
])
def test_bad_surfaces_are_refused(case, message):
    V, F = cube()
    if case == "open":
        F = F[1:]
    elif case == "seam":  # a second cube sharing an edge: that edge is in four triangles
        V2, F2 = cube(offset=(1, 1, 0))
        V = np.r_[V, V2]
        F = np.r_[F, F2 + 8]
        _, inv = np.unique(V, axis=0, return_inverse=True)
        V, F = V[np.unique(inv, return_index=True)[1]], inv.reshape(-1)[F]
    elif case == "flipped":
        F = F.copy()
        F[0] = F[0, [0, 2, 1]]
    elif case == "crossing":
        V2, F2 = cube(offset=(0.5, 0.3, 0.2))
        V, F = np.r_[V, V2], np.r_[F, F2 + 8]
    elif case == "flat":  # a tetrahedron squashed into a plane
        V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, 0]], float)
        F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    elif case == "degenerate":
        V = np.r_[V, [[0.5, 0, 0]]]
        F = np.r_[F, [[0, 4, 8]]]
    elif case == "few":
        F = F[:3]
    elif case in ("nested", "stray cavity"):
        Vi, Fi = cube(0.25, 0.75, inward=case != "nested",
                      offset=(0, 0, 0) if case == "nested" else (2, 0, 0))
        V, F = np.r_[V, Vi], np.r_[F, Fi + 8]
    with pytest.raises(GeometryError, match=f"^part.stl: .*{re.escape(message)}"):
        SurfaceSolid.from_arrays(V, F, "part.stl")


# -- the example ---------------------------------------------------------------------------

def bracket_distance(p):
    """Distance of ``p`` to the example's boundary, from the bracket's own dimensions (foot
    0 <= x <= 40, 0 <= z <= 10; web 0 <= x <= 10, 0 <= z <= 40; 0 <= y <= 20; holes of
    radius 5 along z at (27, 10) and along x at (10, 27)), for points near the boundary:
    the smallest distance to a face plane (within the face's extent) or a bore wall."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    r_foot = np.hypot(x - 27, y - 10)
    r_web = np.hypot(y - 10, z - 27)
    d = np.full(len(p), np.inf)
    inside_foot = (x <= 40) & (z <= 10)
    inside_web = (x <= 10) & (z <= 40)
    off_holes = (r_foot >= 5 - 0.05) & (r_web >= 5 - 0.05)
    planes = [(np.abs(y), inside_foot | inside_web), (np.abs(y - 20), inside_foot | inside_web),
              (np.abs(z), x <= 40), (np.abs(x), z <= 40), (np.abs(x - 40), z <= 10),
              (np.abs(z - 40), x <= 10), (np.abs(z - 10), x >= 10), (np.abs(x - 10), z >= 10)]
    for dist, where in planes:
        d = np.where(where & off_holes, np.minimum(d, dist), d)
    d = np.where(z <= 10, np.minimum(d, np.abs(r_foot - 5)), d)
    d = np.where(x <= 10, np.minimum(d, np.abs(r_web - 5)), d)
    return d


def test_l_bracket_meets_every_guarantee():
    """Delta, volumes and conformity recomputed from the arrays; every boundary triangle
    (corners, edge midpoints, centroid) within the chord tolerance of the bracket's faces
    (plus the 48-gon holes' own deviation from a circle); the volume of the faceted part;
    the ten faces between sharp edges, each on its own plane or bore; the same mesh
    twice."""
    m = load_model(hetmesh.example_path("l_bracket"))
    assert isinstance(m.solid, SurfaceSolid)
    assert m.solid.face_names == tuple(f"surface.{i}" for i in range(1, 11))
    d0 = 0.3
    res = mesh_model(m, d0)
    bnd = check_tet_mesh(res.points, res.tets, lambda p: ((p[:, 0] + p[:, 2]) / 50) ** 2, d0)
    q = res.points[bnd]
    pts = np.concatenate([q, 0.5 * (q + q[:, [1, 2, 0]]), q.mean(axis=1, keepdims=True)],
                         axis=1).reshape(-1, 3)
    chord = CHORD * np.sqrt(40 ** 2 + 20 ** 2 + 40 ** 2)
    sagitta = 5 * (1 - np.cos(np.pi / 48))
    assert bracket_distance(pts).max() <= chord + sagitta
    # the faceted bracket's volume: the L section x 20 minus two 48-gon bores of length 10
    bore = 0.5 * 48 * 25 * np.sin(2 * np.pi / 48) * 10
    exact = (40 * 10 + 10 * 30) * 20 - 2 * bore
    a, b, c, d = (res.points[res.tets[:, k]] for k in range(4))
    vol = np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)).sum() / 6
    assert abs(vol - exact) <= chord * m.solid.area
    # each named face on its part of the bracket (the order of the STL's faces)
    x, y, z = (res.points[res.faces][..., k] for k in range(3))
    on = {1: np.abs(y), 2: np.abs(y - 20), 3: np.abs(z), 4: np.abs(z - 10),
          5: np.abs(x - 40), 6: np.abs(x), 7: np.abs(x - 10), 8: np.abs(z - 40),
          9: np.abs(np.hypot(x - 27, y - 10) - 5), 10: np.abs(np.hypot(y - 10, z - 27) - 5)}
    assert sorted(set(res.face_markers.tolist())) == list(range(1, 11))
    for k, dist in on.items():
        assert dist[res.face_markers == k].max() <= chord + sagitta, res.face_names[k - 1]
    again = mesh_model(m, d0)
    assert again.points.tobytes() == res.points.tobytes()
    assert again.tets.tobytes() == res.tets.tobytes()


def test_the_example_surface_is_what_its_script_writes(tmp_path):
    path = hetmesh.example_path("l_bracket").with_name("make_bracket_stl.py")
    spec = importlib.util.spec_from_file_location("make_bracket_stl", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--out", str(tmp_path / "b.stl")]) == 0
    want = hetmesh.example_path("l_bracket").with_suffix(".stl").read_bytes()
    assert (tmp_path / "b.stl").read_bytes() == want
    assert len(want) == 84 + 50 * 412


def test_a_hollow_cube_keeps_its_cavity(tmp_path):
    V, F = cube(0.0, 2.0)
    Vi, Fi = cube(0.5, 1.5, inward=True)
    write_surface(tmp_path / "hollow.stl", np.r_[V, Vi], np.r_[F, Fi + 8])
    (tmp_path / "m.toml").write_text(MODEL.format(file="hollow.stl", formula="z/2"))
    res = mesh_model(load_model(tmp_path / "m.toml"), 0.3)
    check_tet_mesh(res.points, res.tets, lambda p: p[:, 2] / 2, 0.3)
    a, b, c, d = (res.points[res.tets[:, k]] for k in range(4))
    vol = np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)).sum() / 6
    assert vol == pytest.approx(7.0, rel=1e-9)   # planar faces: kept exactly
    cen = res.points[res.tets].mean(axis=1)
    assert not ((np.abs(cen - 1.0) < 0.5).all(axis=1)).any()


# -- bad inputs through the command line ----------------------------------------------------

@pytest.mark.parametrize("case, message", [
    ("missing", "solid.file: nope.stl: no such surface file"),
    ("garbage", "solid.file: part.stl: cannot read the surface"),
    ("open", "part.stl: the surface is not watertight: open"),
    ("crossing", "part.stl: the surface intersects itself"),
    ("flat", "part.stl: the surface encloses no volume"),
    ("nofile", "missing key 'solid.file'"),
    ("angle", "solid.feature_angle: must be in (0, 180) degrees, got 180"),
])
def test_bad_surface_models_fail_in_one_line(case, message, tmp_path, capsys):
    V, F = cube()
    file = "part.stl"
    if case == "missing":
        file = "nope.stl"
    elif case == "garbage":
        (tmp_path / file).write_bytes(b"solid x\nfacet nonsense\n")
    elif case == "open":
        write_surface(tmp_path / file, V, F[1:])
    elif case == "crossing":
        V2, F2 = cube(offset=(0.5, 0.3, 0.2))
        write_surface(tmp_path / file, np.r_[V, V2], np.r_[F, F2 + 8])
    elif case == "flat":
        write_surface(tmp_path / file, [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, 0]],
                      [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    text = MODEL.format(file=file, formula="z")
    if case == "nofile":
        text = text.replace(f'file = "{file}"\n', "")
    if case == "angle":
        write_surface(tmp_path / file, V, F)
        text = text.replace(f'file = "{file}"\n', f'file = "{file}"\nfeature_angle = 180\n')
    model = tmp_path / "m.toml"
    model.write_text(text)
    out = tmp_path / "out.vtu"
    code, _, err = run(["mesh", model, "-d", "0.2", "-o", out], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"hetmesh: error: {model}: ") and message in lines[0], lines[0]
    assert not out.exists()


def test_without_gmsh_the_builtin_fill_meshes(tmp_path, capsys, monkeypatch):
    write_surface(tmp_path / "c.stl", *cube())
    (tmp_path / "m.toml").write_text(MODEL.format(file="c.stl", formula="z"))
    monkeypatch.setitem(sys.modules, "gmsh", None)  # import gmsh raises ImportError
    out = tmp_path / "out.vtu"
    code, _, err = run(["mesh", tmp_path / "m.toml", "-d", "0.2", "-o", out], capsys)
    assert code == 0, err
    m = meshio.read(out)
    check_tet_mesh(m.points, m.cells_dict["tetra"], lambda p: p[:, 2], 0.2)


def test_copying_the_example_out_copies_its_surface(tmp_path, capsys):
    code, out, _ = run(["examples", "l_bracket", "--out", tmp_path], capsys)
    assert code == 0 and "l_bracket.stl" in out
    want = hetmesh.example_path("l_bracket").with_suffix(".stl").read_bytes()
    assert (tmp_path / "l_bracket.stl").read_bytes() == want
    m = load_model(tmp_path / "l_bracket.toml")
    assert m.solid.volume == pytest.approx(load_model(hetmesh.example_path("l_bracket"))
                                           .solid.volume, rel=1e-15)
