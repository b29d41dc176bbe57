"""Flips within phases (hetmesh.tet.flips): the replaced tetrahedra fill the same space, the
boundary and the interfaces between phases keep their triangles, no vertex moves, the caller's
check is obeyed, and the worst tetrahedra get better; checked here with numpy alone."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from hetmesh.tet.flips import flip_improve, ring_triangulations


def volumes(P, T):
    a, b, c = (P[T[:, k]] - P[T[:, 0]] for k in (1, 2, 3))
    return np.einsum("ij,ij->i", a, np.cross(b, c)) / 6


def min_dihedral(P, T):
    """The smallest dihedral angle per tetrahedron, degrees (the angle at each edge between
    the other two vertices, projected on the plane normal to it)."""
    x = P[T]
    out = np.full(len(T), 180.0)
    for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)):
        k, m = (v for v in range(4) if v not in (i, j))
        e = x[:, j] - x[:, i]
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        u, w = x[:, k] - x[:, i], x[:, m] - x[:, i]
        u -= (u * e).sum(1, keepdims=True) * e
        w -= (w * e).sum(1, keepdims=True) * e
        c = (u * w).sum(1) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1))
        out = np.minimum(out, np.degrees(np.arccos(np.clip(c, -1, 1))))
    return out


def surfaces(T, phase):
    """The sorted triangles on one tetrahedron (boundary) and between two of different
    phases (interfaces, with the two phases)."""
    f = np.sort(np.concatenate([T[:, [1, 2, 3]], T[:, [0, 2, 3]], T[:, [0, 1, 3]],
                                T[:, [0, 1, 2]]]), axis=1)
    owner = np.tile(np.arange(len(T)), 4)
    _, inv, cnt = np.unique(f, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    boundary = {tuple(r) for r in f[cnt[inv] == 1].tolist()}
    pairs: dict[tuple, list] = {}
    for row, o in zip(f[cnt[inv] == 2].tolist(), owner[cnt[inv] == 2].tolist()):
        pairs.setdefault(tuple(row), []).append(int(phase[o]))
    inter = {(k, min(v), max(v)) for k, v in pairs.items() if v[0] != v[1]}
    return boundary, inter


def random_mesh(seed=0, n=120):
    rng = np.random.default_rng(seed)
    P = np.concatenate([rng.random((n, 3)), np.array(np.meshgrid([0, 1], [0, 1], [0, 1]))
                        .reshape(3, -1).T.astype(float)])
    T = Delaunay(P).simplices.astype(np.int64)
    neg = volumes(P, T) < 0
    T[neg] = T[neg][:, [1, 0, 2, 3]]
    phase = (P[T].mean(axis=1)[:, 0] > 0.5).astype(np.int64)
    return P, T, phase


def always(tets, phase):
    return np.ones(len(tets), bool)


@pytest.mark.parametrize("n,count", [(3, 1), (4, 2), (5, 5), (6, 14), (7, 42)])
def test_every_triangulation_of_a_ring(n, count):
    tri = ring_triangulations(n)
    assert len(tri) == count and len(set(tri)) == count
    for t in tri:
        assert len(t) == n - 2
        # a triangulation of the polygon: every side once, every diagonal twice
        edges = [e for a, b, c in t for e in ((a, b), (b, c), (a, c))]
        sides = {(k, k + 1) for k in range(n - 1)} | {(0, n - 1)}
        for e in set(edges):
            assert edges.count(e) == (1 if e in sides else 2)


@pytest.mark.parametrize("seed", [0, 1])
def test_flips_keep_space_surfaces_and_phases(seed):
    P, T, phase = random_mesh(seed)
    before = min_dihedral(P, T)
    T2, phase2 = flip_improve(P, T, phase, always, bound=20.0)
    assert not np.array_equal(np.sort(T2, axis=0), np.sort(T, axis=0))  # something changed
    v = volumes(P, T2)
    assert (v > 0).all()
    for k in (0, 1):
        assert v[phase2 == k].sum() == pytest.approx(volumes(P, T)[phase == k].sum(),
                                                     rel=1e-12)
    assert surfaces(T2, phase2) == surfaces(T, phase)
    after = min_dihedral(P, T2)
    assert after.min() > before.min()
    assert (after < 20).sum() < (before < 20).sum()
    # vertices removed only inside the phases, never on the surfaces
    gone = np.setdiff1d(np.unique(T), np.unique(T2))
    on = np.unique(np.array([list(f) for f in surfaces(T, phase)[0]]
                            + [list(f[0]) for f in surfaces(T, phase)[1]]))
    assert not np.isin(gone, on).any()
    # the same input, the same tetrahedra
    T3, phase3 = flip_improve(P, T, phase, always, bound=20.0)
    np.testing.assert_array_equal(T2, T3)
    np.testing.assert_array_equal(phase2, phase3)


def test_the_callers_check_is_obeyed():
    P, T, phase = random_mesh(2)
    T2, phase2 = flip_improve(P, T, phase, lambda t, ph: np.zeros(len(t), bool))
    np.testing.assert_array_equal(T2, T)
    # a check that refuses tetrahedra with vertex 0: none of the new ones has it
    T3, _ = flip_improve(P, T, phase, lambda t, ph: ~(t == 0).any(axis=1))
    old = {tuple(sorted(r)) for r in T.tolist()}
    new = [r for r in T3.tolist() if tuple(sorted(r)) not in old]
    assert new and not any(0 in r for r in new)
