"""The tetrahedral mesher: invariants rechecked independently of hetmesh.tet's own checks."""

from __future__ import annotations

import numpy as np
import pytest

from hetmesh.errors import GeometryError, OptionError
from hetmesh.material import AnalyticField
from hetmesh.metrics import dihedral_angles, tet_quality
from hetmesh.tet import box, cylinder, generate_tets


def check_tet_mesh(points, tets, composition, threshold, *, box_bounds=None,
                   cylinder_axis_z=None, chord_tol=None):
    """Recompute every claim from the arrays alone (no hetmesh code).

    ``composition(points) -> (N,)`` evaluates the fraction directly. ``box_bounds`` =
    ``(lo, hi)`` for a box, ``cylinder_axis_z`` = ``(cx, cy, r, z0, z1)`` for a cylinder.
    Returns the boundary triangles.
    """
    p = np.asarray(points, float)
    t = np.asarray(tets, np.int64)
    assert t.ndim == 2 and t.shape[1] == 4 and len(t)
    # every point used, positive volumes (own determinant)
    assert np.bincount(t.ravel(), minlength=len(p)).min() > 0
    a, b, c, d = (p[t[:, k]] for k in range(4))
    m = np.stack([b - a, c - a, d - a], axis=1)
    vol = np.linalg.det(m) / 6.0
    assert vol.min() > 0, f"non-positive volume {vol.min()}"
    # conformity: every face in at most two tetrahedra; boundary = faces of one
    faces = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]])
    key = np.sort(faces, axis=1)
    uniq, cnt = np.unique(key, axis=0, return_counts=True)
    assert cnt.max() <= 2
    bnd = uniq[cnt == 1]
    q = p[bnd]
    area = 0.5 * np.linalg.norm(np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]), axis=1)
    if box_bounds is not None:
        lo, hi = (np.asarray(v, float) for v in box_bounds)
        size = hi - lo
        # each boundary triangle exactly on one face plane; each face covered exactly
        on = np.zeros(len(bnd), int)
        for k in range(3):
            for val in (lo[k], hi[k]):
                sel = (q[:, :, k] == val).all(axis=1)
                on += sel
                want = np.prod(np.delete(size, k))
                assert area[sel].sum() == pytest.approx(want, rel=1e-12, abs=1e-14)
        assert (on == 1).all()
        assert vol.sum() == pytest.approx(np.prod(size), rel=1e-12)
    if cylinder_axis_z is not None:
        cx, cy, r, z0, z1 = cylinder_axis_z
        rr = np.hypot(q[..., 0] - cx, q[..., 1] - cy)
        cap = (q[..., 2] == z0).all(axis=1) | (q[..., 2] == z1).all(axis=1)
        side = ~cap
        assert np.abs(rr[side] - r).max() <= 1e-9 * r   # vertices on the surface
        mid = 0.5 * (q + q[:, [1, 2, 0]])
        rm = np.hypot(mid[..., 0] - cx, mid[..., 1] - cy)[side]
        assert (r - rm).max() <= chord_tol * (1 + 1e-9)
        assert (rr[cap] <= r * (1 + 1e-12)).all()
        exact = np.pi * r * r * (z1 - z0)
        assert exact - 2 * np.pi * r * chord_tol * (z1 - z0) < vol.sum() <= exact * (1 + 1e-12)
    # delta over the four vertices, from the formula itself
    f = composition(p)
    fv = f[t]
    delta = fv.max(axis=1) - fv.min(axis=1)
    assert delta.max() < threshold
    return bnd


def cube_field():
    return AnalyticField({"metal": "(1 - z)**2"}, ["ceramic", "metal"], dim=3)


@pytest.mark.parametrize("d0", [0.2, 0.1])
def test_unit_cube(d0):
    res = generate_tets(box((0, 0, 0), (1, 1, 1)), cube_field(), d0)
    check_tet_mesh(res.points, res.tets, lambda p: (1 - p[:, 2]) ** 2, d0,
                   box_bounds=((0, 0, 0), (1, 1, 1)))
    # the face markers name the cube's faces
    names = {res.face_names[m - 1] for m in res.face_markers}
    assert names == {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"}
    assert np.degrees(0) < dihedral_angles(res.points, res.tets).min()
    assert tet_quality(res.points, res.tets).min() > 0


def test_deterministic():
    a = generate_tets(box((0, 0, 0), (1, 1, 1)), cube_field(), 0.2, seed=3)
    b = generate_tets(box((0, 0, 0), (1, 1, 1)), cube_field(), 0.2, seed=3)
    assert a.points.tobytes() == b.points.tobytes()
    assert a.tets.tobytes() == b.tets.tobytes()


def test_box_offset_and_three_constituents():
    f = AnalyticField({"a": "0.5*(x - 10)/2", "b": "0.4*(y + 3)/3"}, ["a", "b", "c"], dim=3)
    lo, hi = (10, -3, 5), (12, 0, 6)
    res = generate_tets(box(lo, hi), f, 0.15)
    comp = f.composition
    check_tet_mesh(res.points, res.tets, lambda p: comp(p)[:, 0], 0.15, box_bounds=(lo, hi))
    check_tet_mesh(res.points, res.tets, lambda p: comp(p)[:, 1], 0.15, box_bounds=(lo, hi))
    check_tet_mesh(res.points, res.tets, lambda p: comp(p)[:, 2], 0.15, box_bounds=(lo, hi))


def test_graded_cylinder_axial():
    f = AnalyticField({"metal": "z/2"}, ["ceramic", "metal"], dim=3)
    solid = cylinder((0, 0), 0.5, 0.0, 2.0)
    res = generate_tets(solid, f, 0.2, chord_tol=0.01)
    check_tet_mesh(res.points, res.tets, lambda p: p[:, 2] / 2, 0.2,
                   cylinder_axis_z=(0, 0, 0.5, 0, 2), chord_tol=0.01)


def test_graded_cylinder_radial():
    # levels are cylinders: the curved placement, repaired by edge bisection
    f = AnalyticField({"metal": "(x**2 + y**2)/0.25"}, ["ceramic", "metal"], dim=3)
    solid = cylinder((0, 0), 0.5, 0.0, 1.0)
    res = generate_tets(solid, f, 0.25, chord_tol=0.01)
    assert res.info["placement"] == "curved"
    check_tet_mesh(res.points, res.tets, lambda p: (p[:, 0] ** 2 + p[:, 1] ** 2) / 0.25, 0.25,
                   cylinder_axis_z=(0, 0, 0.5, 0, 1), chord_tol=0.01)


@pytest.mark.parametrize("make, match", [
    (lambda: box((0, 0, 0), (1, 0, 1)), "size along y must be positive"),
    (lambda: cylinder((0, 0), -1.0, 0, 1), "radius must be positive"),
    (lambda: cylinder((0, 0), 1.0, 1, 1), "length must be positive"),
])
def test_bad_solids(make, match):
    with pytest.raises(GeometryError, match=match):
        make()


def test_bad_threshold():
    with pytest.raises(OptionError):
        generate_tets(box((0, 0, 0), (1, 1, 1)), cube_field(), 0.0)
