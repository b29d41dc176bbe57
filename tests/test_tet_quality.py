"""Sweeps through columns of their own spacing (hetmesh.tet.columns): conformity, positive
volumes, exact caps and sides, every tetrahedron within one section triangle's columns."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from hetmesh.tet.columns import column_counts, column_tets, vertex_size
from hetmesh.tet.extrude import prism_tets


def _section(seed=3, n=60):
    """A Delaunay triangulation of the unit square with a dense corner (sizes ~10x apart)."""
    rng = np.random.default_rng(seed)
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    inner = rng.random((n, 2)) ** 3  # crowded near (0, 0)
    p = np.concatenate([corners, inner])
    return p, Delaunay(p).simplices.astype(np.int64)


def _volumes(pts, tets):
    a, b, c, d = (pts[tets[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6.0


def _faces(tets):
    f = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]],
                        tets[:, [0, 1, 2]]])
    return np.unique(np.sort(f, axis=1), axis=0, return_counts=True)


def _area(p2, t2):
    d, e = p2[t2[:, 1]] - p2[t2[:, 0]], p2[t2[:, 2]] - p2[t2[:, 0]]
    return 0.5 * np.abs(d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_columns_conform_and_fill_the_prism(seed):
    p2, t2 = _section(seed)
    rng = np.random.default_rng(seed)
    counts = rng.integers(1, 6, len(p2))
    pts, tets, tri = column_tets(p2, t2, counts, 0.5, 2.0)
    assert len(tets) == counts[t2].sum()
    assert len(pts) == (counts + 1).sum()
    vol = _volumes(pts, tets)
    assert (vol > 0).all()
    assert np.isclose(vol.sum(), _area(p2, t2).sum() * 1.5, rtol=1e-12)
    # every tetrahedron's vertices lie on its triangle's columns
    col = np.repeat(np.arange(len(p2)), counts + 1)
    assert np.array_equal(np.sort(pts[:, :2], axis=0), np.sort(p2[col], axis=0))
    own = (col[tets][:, :, None] == t2[tri][:, None, :]).any(axis=2)
    assert own.all()
    # conforming: every face in one or two tetrahedra; the single ones on the caps or the
    # sides of the section's boundary edges
    faces, cnt = _faces(tets)
    assert cnt.max() == 2
    bnd = faces[cnt == 1]
    s = pts[bnd, 2]
    caps = (s == 0.5).all(axis=1) | (s == 2.0).all(axis=1)
    e = np.sort(np.concatenate([t2[:, [0, 1]], t2[:, [1, 2]], t2[:, [2, 0]]]), axis=1)
    ue, ce = np.unique(e, axis=0, return_counts=True)
    outer = {tuple(x) for x in ue[ce == 1]}
    side_cols = np.sort(col[bnd[~caps]], axis=1)
    for c in side_cols:  # two distinct columns of one boundary edge
        pair = tuple(np.unique(c))
        assert len(pair) == 2 and pair in outer
    # the caps are the section's triangles, the sides add up to perimeter x length
    assert caps.sum() == 2 * len(t2)
    q = pts[bnd[~caps]]
    side = 0.5 * np.linalg.norm(np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]), axis=1)
    perim = sum(np.linalg.norm(p2[a] - p2[b]) for a, b in outer)
    assert np.isclose(side.sum(), perim * 1.5, rtol=1e-12)


def test_one_count_everywhere_is_the_prism_cut():
    p2, t2 = _section(5)
    pts, tets, _ = column_tets(p2, t2, np.full(len(p2), 4), 0.0, 1.0)
    pl, tp, _ = prism_tets(p2, t2, np.linspace(0, 1, 5))
    assert len(tets) == len(tp)
    assert np.isclose(_volumes(pts, tets).sum(), np.abs(_volumes(pl, tp)).sum(), rtol=1e-12)


def test_columns_are_deterministic_and_axis_columns_stay_single():
    p2, t2 = _section(7)
    counts = column_counts(1.0, vertex_size(p2, t2), ratio=1.25)
    a = column_tets(p2, t2, counts, 0.0, 1.0)
    b = column_tets(p2, t2, counts, 0.0, 1.0)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    # the section's sizes span about a factor of ten: so do the columns' counts
    assert counts.max() >= 4 * counts.min()
    # a column of count 0 is one point, never moved: its triangles' cells are the moves of
    # their other corners
    c0 = counts.copy()
    c0[0] = 0
    pts, tets, tri = column_tets(p2, t2, c0, 0.0, 1.0)
    assert len(tets) == c0[t2].sum()
    assert (np.count_nonzero(tets == 0, axis=1) <= 1).all()
    assert (np.abs(_volumes(pts, tets)) > 0).all()


def test_column_counts():
    c = column_counts(10.0, np.array([1.0, 4.0, 100.0]), ratio=1.25, cap=2.0)
    assert c.tolist() == [8, 5, 5]


def test_smoothing_keeps_delta_boundary_and_connectivity():
    from hetmesh.material import AnalyticField
    from hetmesh.metrics import delta_vertices, tet_quality
    from hetmesh.tet.faces import boundary_faces
    from hetmesh.tet.quality import min_dihedral
    from hetmesh.tet.refine import repair
    from hetmesh.tet.smooth import smooth

    field = AnalyticField({"metal": "(x + z) / 2"}, ["ceramic", "metal"], dim=3)
    g = np.linspace(0, 1, 7)
    p2 = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    p2[7:-7] += np.random.default_rng(1).uniform(-0.03, 0.03, (len(p2) - 14, 2))
    t2 = Delaunay(p2).simplices.astype(np.int64)
    pts, tets, _ = column_tets(p2, t2, column_counts(1.0, vertex_size(p2, t2), ratio=1.25),
                               0.0, 1.0)
    pts, tets, comp, delta, _ = repair(pts, tets, field, 0.1)
    assert delta.max() < 0.1
    p, c, moves = smooth(pts, tets, field, 0.1, comp=comp)
    assert moves > 0
    again = smooth(pts, tets, field, 0.1, comp=comp)
    assert np.array_equal(again[0], p) and again[2] == moves
    bnd = np.unique(boundary_faces(tets)[0])
    assert np.array_equal(p[bnd], pts[bnd])
    assert (_volumes(p, tets) > 0).all()
    assert np.allclose(c, field.composition(p))
    assert delta_vertices(field.composition(p), tets).max() < 0.1
    assert min_dihedral(p, tets).min() >= min(min_dihedral(pts, tets).min(), 25.0) - 1e-9
    assert tet_quality(p, tets).mean() > tet_quality(pts, tets).mean()
