"""Jumps of a piecewise composition inside solids of primitives: cut into the mesh, kept
through MMG's remeshing, recorded as interfaces; checked from the arrays alone."""

from __future__ import annotations

import hashlib

import meshio
import numpy as np
import pytest

from hetmesh.cli import main
from hetmesh.io.model import load_model
from hetmesh.tet.api import mesh_model

#: a ball with a core of radius 0.6 of another graded material
CORE = """
[model]
name = "core"

[solid]
type = "sphere"
center = [0, 0, 0]
radius = 1

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(x**2 + y**2 + z**2 < 0.36, 0.3 + 0.2*z, 0.9 - 0.1*z*z)"
"""

#: the two branches of CORE's metal fraction: the core's (region 1) and the shell's (0)
BRANCH = {1: lambda p: 0.3 + 0.2 * p[:, 2], 0: lambda p: 0.9 - 0.1 * p[:, 2] ** 2}

#: a ball cut by a plane jump, which meets the sphere along a circle
HALVES = CORE.replace("x**2 + y**2 + z**2 < 0.36", "x < 0.2")

#: a box with a bore through a wider spherical pocket: curved faces that meet
MEETING = """
[model]
name = "pocket"

[solid]
type = "box"
min = [0, 0, 0]
max = [2, 2, 2]

[[solid.subtract]]
type = "cylinder"
center = [1, 1]
radius = 0.4
from = -1
to = 3
name = "bore"

[[solid.subtract]]
type = "sphere"
center = [1, 1, 1]
radius = 0.6
name = "pocket"

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(z < 1, 0.2, 0.7)"
"""

CHORD_TOL = 0.01  # relative: coarse curved faces keep these meshes small


def write(tmp_path, text, name="m.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def tet_faces(t):
    f = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]])
    return np.sort(f, axis=1), np.tile(np.arange(len(t)), 4)


def interfaces(t, region):
    """Triangles shared by two tetrahedra of different regions, and every face's use count."""
    key, owner = tet_faces(t)
    order = np.lexsort(key.T[::-1])
    ks, ow = key[order], owner[order]
    same = (ks[1:] == ks[:-1]).all(axis=1)
    a, b = ow[:-1][same], ow[1:][same]
    differ = region[a] != region[b]
    _, counts = np.unique(key, axis=0, return_counts=True)
    return ks[:-1][same][differ], counts


def tri_points(q):
    mids = 0.5 * (q + q[:, [1, 2, 0]])
    return np.concatenate([q, mids, q.mean(axis=1, keepdims=True)], axis=1)


def check_arrays(p, t):
    a, b, c, d = (p[t[:, k]] for k in range(4))
    vol = np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) / 6.0
    assert vol.min() > 0
    assert np.bincount(t.ravel(), minlength=len(p)).min() > 0
    return vol


@pytest.fixture(scope="module")
def core(tmp_path_factory):
    path = write(tmp_path_factory.mktemp("core"), CORE)
    return load_model(path), mesh_model(load_model(path), 0.2, chord_tol=CHORD_TOL)


def test_no_tetrahedron_straddles_the_core(core):
    model, res = core
    p, t = res.points, res.tets.astype(np.int64)
    chord = CHORD_TOL * model.solid.diameter
    check_arrays(p, t)
    region = np.asarray(res.info["regions"])
    assert set(np.unique(region).tolist()) == {0, 1}
    r = np.linalg.norm(p[t].mean(axis=1), axis=1)
    own = (r ** 2 < 0.36).astype(int)
    # a centroid on the other side only within the chord tolerance of the core's sphere
    assert (np.abs(r[own != region] - 0.6) <= chord).all()
    assert (own == region).mean() > 0.999
    inter, counts = interfaces(t, region)
    assert counts.max() <= 2  # conforming
    assert len(inter) > 100
    rad = np.linalg.norm(tri_points(p[inter]), axis=2)
    assert np.abs(rad - 0.6).max() <= chord * (1 + 1e-9)
    # the core's surface is closed: every edge of the interface in two of its triangles
    e = np.sort(np.concatenate([inter[:, [0, 1]], inter[:, [1, 2]], inter[:, [0, 2]]]), axis=1)
    _, ec = np.unique(e, axis=0, return_counts=True)
    assert (ec == 2).all()


def test_delta_is_measured_in_each_tetrahedron_s_own_material(core):
    """delta recomputed from the branch formulas: the jump (0.3 + 0.2 z against 0.9 - 0.1
    z^2, at least 0.36 apart) is not inside any tetrahedron, so every one is below 0.2."""
    _, res = core
    p, t = res.points, res.tets.astype(np.int64)
    region = np.asarray(res.info["regions"])
    delta = np.empty(len(t))
    for k, f in BRANCH.items():
        sel = region == k
        v = f(p[t[sel].ravel()]).reshape(-1, 4)
        delta[sel] = v.max(axis=1) - v.min(axis=1)
    assert delta.max() < 0.2
    assert res.delta.max() < 0.2
    assert np.allclose(delta, res.delta, atol=1e-12)


def test_the_interface_is_recorded_as_a_face(core, tmp_path):
    _, res = core
    names = list(res.face_names)
    assert names[-1] == "discontinuity[0]" and "outer" in names
    k = names.index("discontinuity[0]") + 1
    rec = np.sort(res.faces[res.face_markers == k], axis=1)
    inter, _ = interfaces(res.tets.astype(np.int64), np.asarray(res.info["regions"]))
    assert {tuple(f) for f in rec.tolist()} == {tuple(f) for f in inter.tolist()}
    assert res.info["jump_conditions"] == ("x**2 + y**2 + z**2 < 0.36",)
    out = tmp_path / "core.msh"
    res.mesh.write(out)
    m = meshio.read(out)
    assert {"discontinuity[0]", "outer", "region_0", "region_1"} <= set(m.field_data)
    tags = np.concatenate(m.cell_data["gmsh:physical"])
    assert (tags == m.field_data["discontinuity[0]"][0]).sum() == len(rec)


def test_quality_targets_hold_with_the_jump(core):
    from hetmesh.tet.quality import min_dihedral

    _, res = core
    ang = min_dihedral(res.points, res.tets)
    assert ang.min() >= 10.0 and np.percentile(ang, 1) >= 20.0


def test_a_plane_jump_meets_the_curved_face(tmp_path):
    """x < 0.2 in a ball: the interface vertices on the sphere lie on both surfaces."""
    model = load_model(write(tmp_path, HALVES))
    res = mesh_model(model, 0.2, chord_tol=CHORD_TOL)
    p, t = res.points, res.tets.astype(np.int64)
    check_arrays(p, t)
    region = np.asarray(res.info["regions"])
    inter, _ = interfaces(t, region)
    ids = np.unique(inter)
    assert np.abs(p[ids, 0] - 0.2).max() <= 1e-9  # a plane: exact
    rim = ids[np.abs(np.linalg.norm(p[ids], axis=1) - 1) <= 1e-6]
    assert len(rim) > 10  # the circle where the plane meets the sphere
    cen = p[t].mean(axis=1)
    assert ((cen[:, 0] < 0.2).astype(int) == region).all()
    # the thin tetrahedra where the plane meets the sphere collapsed and flipped
    from hetmesh.tet.quality import min_dihedral

    assert min_dihedral(p, t).min() >= 10.0


def test_same_model_same_mesh(tmp_path):
    model = load_model(write(tmp_path, HALVES))
    h = []
    for _ in range(2):
        r = mesh_model(model, 0.3, chord_tol=0.02)
        h.append(hashlib.sha1(r.points.tobytes() + r.tets.astype(np.int64).tobytes()
                              + np.asarray(r.info["regions"], np.int64).tobytes()).hexdigest())
    assert h[0] == h[1]


def test_the_uniform_baseline_keeps_the_jump(tmp_path, capsys):
    path = write(tmp_path, CORE)
    out = tmp_path / "u.vtu"
    rc = main(["uniform", str(path), "--threshold", "0.2", "--chord-tol", str(CHORD_TOL),
               "--output", str(out)])
    assert rc == 0, capsys.readouterr().err
    m = meshio.read(out)
    sub = np.concatenate([np.asarray(a) for a, c in zip(m.cell_data["subregion"], m.cells)
                          if c.type == "tetra"])
    assert set(np.unique(sub).tolist()) == {0, 1}


def test_jumps_where_curved_faces_meet_fail_in_one_line(tmp_path, capsys):
    path = write(tmp_path, MEETING)
    out = tmp_path / "x.vtu"
    rc = main(["mesh", str(path), "--threshold", "0.2", "--output", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1
    assert "material.composition.metal: condition 'z < 1'" in err and "meet" in err


# (jumps in a solid from a surface file are embedded: tests/test_tet_surface_jumps.py)


#: a box cut by an inclined jump plane x + z = 2.5, which moves along its sweep axis (a
#: plane across the axis, such as a coating's z = 1, is embedded by the sweep instead:
#: tests/test_tet_jump_planes.py)
INCLINED = """
[model]
name = "inclined"

[solid]
type = "box"
min = [0, 0, 0]
max = [4, 2, 2]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(x + z < 2.5, 0.2 + 0.1*x, 0.8)"
"""


def test_a_box_whose_jump_changes_along_its_axis_is_cut_through(tmp_path):
    """The inclined jump plane crosses the box's sweep axis: the box is meshed as a solid of
    primitives, the plane exactly an interface, each side's delta recomputed."""
    model = load_model(write(tmp_path, INCLINED))
    res = mesh_model(model, 0.2)
    assert res.info["placement"] == "general"
    p, t = res.points, res.tets.astype(np.int64)
    vol = check_arrays(p, t)
    assert vol.sum() == pytest.approx(16.0, rel=1e-12)
    region = np.asarray(res.info["regions"])
    cen = p[t].mean(axis=1)
    assert ((cen[:, 0] + cen[:, 2] < 2.5).astype(int) == region).all()
    inter, _ = interfaces(t, region)
    assert np.abs(p[inter][..., 0] + p[inter][..., 2] - 2.5).max() < 1e-9
    area = 0.5 * np.linalg.norm(np.cross(p[inter[:, 1]] - p[inter[:, 0]],
                                         p[inter[:, 2]] - p[inter[:, 0]]), axis=1).sum()
    assert area == pytest.approx(2.0 * 8 ** 0.5, rel=1e-9)
    v = np.where(region[:, None] == 1, 0.2 + 0.1 * p[t][..., 0], 0.8)
    assert (v.max(axis=1) - v.min(axis=1)).max() < 0.2
