"""Jumps on planes across a sweep's axis (a coating over a substrate, a laminate): the sweep
puts a layer of points on every such plane, so no tetrahedron crosses it; checked from the
arrays alone."""

from __future__ import annotations

import numpy as np
import pytest

from hetmesh.cli import main
from hetmesh.errors import MaterialError
from hetmesh.io.model import load_model
from hetmesh.material import AnalyticField
from hetmesh.tet.api import mesh_model
from hetmesh.tet.sweep_regions import MAX_CUTS, axial_cuts
from hetmesh.tet.uniform import uniform_model

#: a cylinder whose top half-unit is a coating of another material
COATED = """
[model]
name = "coated_cylinder"

[solid]
type = "cylinder"
center = [0, 0]
radius = 1
from = 0
to = 2

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(z < 1.5, 0.2 + 0.2*z*(x*x + y*y), 0.9)"
"""

#: the two branches of COATED's metal fraction: below the plane (region 1), above it (0)
COATED_BRANCH = {1: lambda p: 0.2 + 0.2 * p[:, 2] * (p[:, 0] ** 2 + p[:, 1] ** 2),
                 0: lambda p: np.full(len(p), 0.9)}

#: a plate with a hole in three layers, the top one with a jump across the section too
LAMINATE = """
[model]
name = "laminate"

[solid]
type = "extrusion"
length = 3

[domain.outer]
start = [0, 0]
path = [{ to = [10, 0] }, { to = [10, 4] }, { to = [0, 4] }, { to = [0, 0] }]

[[domain.holes]]
start = [8, 2]
path = [{ to = [8, 2], center = [7, 2] }]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(z < 1, 0.1 + 0.03*x, where(z < 2, 0.5 + 0.05*z, where(x < 5, 0.9, 0.8 - 0.01*x)))"
"""

#: a box with a coating: a sweep now, not a solid of primitives
BOX = """
[model]
name = "coated_box"

[solid]
type = "box"
min = [0, 0, 0]
max = [3, 2, 2]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(z < 1.5, 0.1 + 0.2*z, 0.9)"
"""


def write(tmp_path, text, name="m.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def faces_of(t):
    f = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]])
    return np.sort(f, axis=1)


def area(p, f):
    a, b, c = p[f[:, 0]], p[f[:, 1]], p[f[:, 2]]
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()


def check_planes(res, cuts, axis=2):
    """No tetrahedron has vertices on both sides of a plane; the recorded faces of each
    plane are exactly the mesh's faces on it, each in two tetrahedra, and cover the end
    face's area."""
    p, t = res.points, res.tets.astype(np.int64)
    a, b, c, d = (p[t[:, k]] for k in range(4))
    assert np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)).min() > 0
    z = p[t][..., axis]
    end = res.faces[res.face_markers == 1]
    for c in cuts:
        assert not ((z.min(axis=1) < c) & (z.max(axis=1) > c)).any()
        f = faces_of(t)
        on = (p[f][..., axis] == c).all(axis=1)
        keys, counts = np.unique(f[on], axis=0, return_counts=True)
        assert (counts == 2).all()
        name = [n for n in res.face_names if n.startswith("discontinuity[")]
        rec = np.concatenate([np.sort(res.faces[res.face_markers == res.face_names.index(n) + 1],
                                      axis=1) for n in name])
        rec = rec[(p[rec][..., axis] == c).all(axis=1)]
        assert len(rec) == len(keys)
        assert set(map(tuple, rec.tolist())) == set(map(tuple, keys.tolist()))
        assert area(p, rec) == pytest.approx(area(p, end), rel=1e-9)


@pytest.fixture(scope="module")
def coated(tmp_path_factory):
    path = write(tmp_path_factory.mktemp("coated"), COATED)
    return load_model(path), mesh_model(load_model(path), 0.2)


def test_a_coated_cylinder_is_cut_at_its_coating(coated):
    model, res = coated
    assert res.info["jump_planes"] == pytest.approx((1.5,), abs=1e-12)
    check_planes(res, res.info["jump_planes"])
    assert "discontinuity[0]" in res.face_names


def test_every_tetrahedron_is_in_its_own_material(coated):
    """The region of every tetrahedron from its centroid's height, and delta recomputed from
    the branch formulas: under 0.2 although the coating jumps by at least 0.3."""
    _, res = coated
    p, t = res.points, res.tets.astype(np.int64)
    region = np.asarray(res.info["regions"])
    own = (p[t].mean(axis=1)[:, 2] < 1.5).astype(int)
    assert (own == region).all()
    assert set(region.tolist()) == {0, 1}
    x = p[t.ravel()]
    r4 = np.repeat(region, 4)
    m = np.empty(len(x))
    for r, f in COATED_BRANCH.items():
        m[r4 == r] = f(x[r4 == r])
    m = m.reshape(-1, 4)
    assert (m.max(axis=1) - m.min(axis=1)).max() < 0.2


def test_a_laminate_keeps_its_planes_and_its_section_jump(tmp_path):
    """Two planes across the axis and a section curve (x = 5) that jumps in the top layer
    only: every tetrahedron's centroid is on its recorded side of each."""
    res = mesh_model(load_model(write(tmp_path, LAMINATE)), 0.1)
    cuts = res.info["jump_planes"]
    assert cuts == pytest.approx((1.0, 2.0), abs=1e-12)
    check_planes(res, cuts)
    c = res.points[res.tets.astype(np.int64)].mean(axis=1)
    layer = (c[:, 2] > 1).astype(int) + (c[:, 2] > 2)
    region = np.asarray(res.info["regions"])
    for k in range(3):  # one region per layer and side of x = 5, never shared
        for side in (c[:, 0] < 5, c[:, 0] > 5):
            r = region[(layer == k) & side]
            assert len(np.unique(r)) == 1
    assert len(np.unique(region)) == 6


def test_a_coated_box_is_swept(tmp_path):
    """A box whose coating is a plane across its axis stays a sweep (before, it went to the
    solids of primitives, whose cut of that plane did not finish: an internal error)."""
    res = mesh_model(load_model(write(tmp_path, BOX)), 0.1)
    assert res.info["placement"] == "swept+repair"
    check_planes(res, (1.5,))


def test_the_uniform_baseline_cuts_at_the_planes_too(tmp_path):
    model = load_model(write(tmp_path, COATED))
    res = uniform_model(model, 0.2)
    assert res.info["jump_planes"] == pytest.approx((1.5,), abs=1e-12)
    check_planes(res, res.info["jump_planes"])
    own = (res.points[res.tets.astype(np.int64)].mean(axis=1)[:, 2] < 1.5).astype(int)
    assert (own == np.asarray(res.info["regions"])).all()


def test_the_cuts_are_found_to_the_rounding_error():
    from hetmesh.tri.geometry import Domain, Loop

    sq = Domain(Loop.polygon([(0, 0), (2, 0), (2, 1), (0, 1)]))
    f = AnalyticField({"metal": "where(z < 0.3, 0.2, where(z > 2.5 - 0.1, 0.4, 0.6 + x/10))"},
                      ["ceramic", "metal"], dim=3)
    cuts = axial_cuts(f, sq, lambda q, s: np.column_stack([q, s]), 0.0, 3.0, "z")
    assert cuts == pytest.approx([0.3, 2.4], abs=1e-14)
    smooth = AnalyticField({"metal": "z / 3"}, ["ceramic", "metal"], dim=3)
    assert len(axial_cuts(smooth, sq, lambda q, s: np.column_stack([q, s]), 0, 3, "z")) == 0


@pytest.mark.parametrize("formula, message", [
    ("where(z < 1 + 0.1*x, 0.2, 0.6)", "the subregion changes with z near"),
    ("where(sin(120*z) < 0, 0.2, 0.6)", f"at most {MAX_CUTS} planes"),
    ("where(z < 1, where(x < 1, 0.2, 0.3), where(y < 0.5, 0.6, 0.7))", None),
], ids=["inclined", "too-many-planes", "different-section-jumps"])
def test_jumps_that_are_not_planes_across_the_axis_are_refused(formula, message):
    """An inclined jump, a jump on more planes than the limit: one line naming the condition.
    Conditions on x or y only and on z only always give every layer the same section jumps
    (a formula's subregions are all its conditions' truth values), so the third is meshed."""
    from hetmesh.tri.geometry import Domain, Loop

    sq = Domain(Loop.polygon([(0, 0), (2, 0), (2, 1), (0, 1)]))
    f = AnalyticField({"metal": formula}, ["ceramic", "metal"], dim=3)
    place = lambda q, s: np.column_stack([q, s])  # noqa: E731
    if message is None:
        assert axial_cuts(f, sq, place, 0.0, 2.0, "z") == pytest.approx([1.0], abs=1e-14)
        return
    with pytest.raises(MaterialError, match="condition") as exc:
        axial_cuts(f, sq, place, 0.0, 2.0, "z")
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_an_inclined_jump_in_a_cylinder_fails_in_one_line(tmp_path, capsys):
    path = write(tmp_path, COATED.replace("z < 1.5", "z < 1 + 0.2*x"))
    out = tmp_path / "m.vtu"
    code = main(["mesh", str(path), "--threshold", "0.2", "--output", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err
    assert "material.composition.metal: condition 'z < 1 + 0.2*x'" in err
    assert "the subregion changes with z near" in err
    assert not out.exists()


#: a ring (r from 20 to 30, z from 0 to 10), turned through ``angle`` degrees
RING = """
[model]
name = "ring"

[solid]
type = "revolution"
angle = {angle}

[domain.outer]
start = [20, 0]
path = [{{ to = [30, 0] }}, {{ to = [30, 10] }}, {{ to = [20, 10] }}, {{ to = [20, 0] }}]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""

#: a solid disc of radius 10 (the profile on the axis), two halves of different materials
DISC = """
[model]
name = "disc"

[solid]
type = "revolution"
angle = 360

[domain.outer]
start = [0, 0]
path = [{ to = [10, 0] }, { to = [10, 4] }, { to = [0, 4] }, { to = [0, 0] }]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(y > 0, 0.2 + 0.01*z, 0.6 + 0.02*x)"
"""


def check_half_planes(res, angles, profile_area):
    """No tetrahedron has vertices off the axis on both sides of a half-plane (within 1e-9
    of the diameter); the recorded faces of each are exactly the mesh's faces on it, each in
    two tetrahedra, and cover the profile's area."""
    p, t = res.points, res.tets.astype(np.int64)
    a, b, c, d = (p[t[:, k]] for k in range(4))
    assert np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)).min() > 0
    tol = 1e-9 * np.ptp(p, axis=0).max()
    f = faces_of(t)
    name = [n for n in res.face_names if n.startswith("discontinuity[")]
    rec = np.concatenate([np.sort(res.faces[res.face_markers == res.face_names.index(n) + 1],
                                  axis=1) for n in name])
    for th in angles:
        n, e = np.array([-np.sin(th), np.cos(th), 0]), np.array([np.cos(th), np.sin(th), 0])
        side = p @ n
        ahead = p @ e > tol
        s = np.where(ahead[t], side[t], 0.0)  # a vertex behind the axis is on no side
        assert not ((s.min(axis=1) < -tol) & (s.max(axis=1) > tol)).any()
        on = (np.abs(side) <= tol) & (p @ e >= -tol)
        keys, counts = np.unique(f[on[f].all(axis=1)], axis=0, return_counts=True)
        assert (counts == 2).all()
        mine = rec[on[rec].all(axis=1)]
        assert set(map(tuple, mine.tolist())) == set(map(tuple, keys.tolist()))
        assert area(p, mine) == pytest.approx(profile_area, rel=1e-6)


def test_a_ring_with_a_sector_of_another_material_is_cut_at_its_half_plane(tmp_path):
    """A quarter ring whose sector past 0.5 rad is of another material: its half-plane is
    an embedded surface, every tetrahedron on its own side."""
    model = load_model(write(tmp_path, RING.format(
        angle=90, formula="where(atan2(y, x) < 0.5, 0.2 + 0.01*z, 0.6)")))
    res = mesh_model(model, 0.2)
    assert res.info["placement"] == "revolved+repair"
    assert res.info["jump_planes"] == pytest.approx((0.5,), abs=1e-12)
    check_half_planes(res, (0.5,), 100.0)
    c = res.points[res.tets.astype(np.int64)].mean(axis=1)
    own = (np.arctan2(c[:, 1], c[:, 0]) < 0.5).astype(int)
    assert (own == np.asarray(res.info["regions"])).all()


@pytest.mark.parametrize("text, angles, profile_area", [
    (RING.format(angle=360, formula="where(y > 0, 0.2 + 0.01*z, 0.6 + 0.005*x)"),
     (0.0, np.pi), 100.0),
    (DISC, (0.0, np.pi), 40.0),
], ids=["ring", "disc"])
def test_a_full_turn_in_two_halves_is_cut_at_angle_0_and_pi(tmp_path, text, angles,
                                                             profile_area):
    """The jump y = 0 of a full turn lies on the half-planes at 0 (where the turn closes)
    and pi; on a disc both meet at the axis. The uniform baseline cuts there too."""
    model = load_model(write(tmp_path, text))
    for res in (mesh_model(model, 0.2), uniform_model(model, 0.2)):
        assert res.info["jump_planes"] == pytest.approx(angles, abs=1e-12)
        check_half_planes(res, angles, profile_area)
        c = res.points[res.tets.astype(np.int64)].mean(axis=1)
        assert ((c[:, 1] > 0).astype(int) == np.asarray(res.info["regions"])).all()


def test_a_layer_thinner_than_the_section_s_elements_is_warned_of(tmp_path, capsys):
    """A coating 0.01 thick on a section meshed at about 0.4: the mesh is written (valid,
    verified) with one warning naming the layer, since its tetrahedra are flat."""
    path = write(tmp_path, BOX.replace("z < 1.5", "z < 1.99"))
    out = tmp_path / "m.vtu"
    code = main(["mesh", str(path), "--threshold", "0.3", "--output", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 0 and out.exists()
    warn = [line for line in err if line.startswith("hetmesh: warning:")]
    assert len(warn) == 1 and "between the jumps at z = 1.99 and 2 is 0.01 thick" in warn[0]
