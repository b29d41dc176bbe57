"""Local updates of the constrained Delaunay triangulation (triangulate.patch) and the
depth/inside floods of the wrapper: the same triangles as a full rebuild."""

from __future__ import annotations

import numpy as np
import pytest

from hetmesh.mesh import edge_keys
from hetmesh.tri.cdt import constrained_delaunay, patch


def _loop(pts, start):
    k = len(pts)
    return start + np.column_stack([np.arange(k), (np.arange(k) + 1) % k])


def _model(seed):
    """Unit square (boundary), a round hole (boundary) and an open interface polyline,
    with random interior points: points, edges, boundary mask, inside test."""
    rng = np.random.default_rng(seed)
    s = np.arange(40) / 40
    sq = np.concatenate([np.c_[s, 0 * s], np.c_[1 + 0 * s, s], np.c_[1 - s, 1 + 0 * s],
                         np.c_[0 * s, 1 - s]])
    a = -np.linspace(0, 2 * np.pi, 48, endpoint=False)
    hole = np.c_[0.3 + 0.1 * np.cos(a), 0.3 + 0.1 * np.sin(a)]
    xs = np.linspace(0.55, 0.9, 12)
    iface = np.c_[xs, 0.7 + 0.05 * np.sin(9 * xs)]
    q = rng.random((3000, 2)) * 0.96 + 0.02
    to_iface = np.min(np.hypot(*(q[:, None] - iface[None]).transpose(2, 0, 1)), axis=1)
    far = (np.hypot(*(q - 0.3).T) > 0.115) & (to_iface > 0.01)
    q = q[far]
    P = np.vstack([sq, hole, iface, q])
    E = np.vstack([_loop(sq, 0), _loop(hole, len(sq)),
                   len(sq) + len(hole) + np.c_[np.arange(11), np.arange(1, 12)]])
    bnd = np.r_[np.ones(len(sq) + len(hole), bool), np.zeros(11, bool)]

    def inside(x):
        return ((x[:, 0] >= 0) & (x[:, 0] <= 1) & (x[:, 1] >= 0) & (x[:, 1] <= 1)
                & (np.hypot(x[:, 0] - 0.3, x[:, 1] - 0.3) > 0.1 - 1e-9))

    return P, E, bnd, inside, len(sq), len(sq) + len(hole)


def _split(P, E, bnd, row, point):
    """Split constraint edge ``row`` at ``point`` (as refine.split_constraint_edges)."""
    n = len(P)
    P = np.vstack([P, point])
    E = E.copy()
    b = E[row, 1]
    E[row, 1] = n
    E = np.vstack([E, [n, b]])
    return P, E, np.r_[bnd, bnd[row]]


def _same(a, b):
    ka = np.sort(np.sort(a, axis=1).view("i4,i4,i4"), axis=0)
    kb = np.sort(np.sort(b, axis=1).view("i4,i4,i4"), axis=0)
    return len(a) == len(b) and np.array_equal(ka, kb)


@pytest.mark.parametrize("seed", range(6))
def test_patch_equals_full_rebuild(seed):
    P, E, bnd, inside, n_sq, n_hole = _model(seed)
    T = constrained_delaunay(P, E, inside=inside, boundary_edges=E[bnd])
    rng = np.random.default_rng(100 + seed)
    # moves: interior points by a hair (no fold)
    P2 = P.copy()
    inner = np.arange(n_hole + 12, len(P))
    mv = rng.choice(inner, 12, replace=False)
    P2[mv] += rng.normal(0, 2e-4, (12, 2))
    # new interior points, a split square edge (on it), a split hole edge (on the circle:
    # off its chord) and a split interface edge
    new = rng.random((5, 2)) * 0.5 + 0.45
    gap = np.min(np.hypot(*(new[:, None] - P2[None]).transpose(2, 0, 1)), axis=1)
    P2 = np.vstack([P2, new[gap > 1e-3]])
    E2, b2 = E.copy(), bnd.copy()
    P2, E2, b2 = _split(P2, E2, b2, 3, 0.5 * (P2[E2[3, 0]] + P2[E2[3, 1]]))
    a = -(2 * np.pi) * (10.5 / 48)
    P2, E2, b2 = _split(P2, E2, b2, n_sq + 10, [0.3 + 0.1 * np.cos(a), 0.3 + 0.1 * np.sin(a)])
    P2, E2, b2 = _split(P2, E2, b2, len(bnd) - 4,
                        0.5 * (P2[E2[-4 + len(bnd), 0]] + P2[E2[-4 + len(bnd), 1]]))
    full = constrained_delaunay(P2, E2, inside=inside, boundary_edges=E2[b2])
    up = patch(P2, E2, b2, P, E, T)
    assert up is not None
    out, kept = up
    assert np.array_equal(out[:len(kept)], T[kept]) and _same(out, full)
    # every constraint edge is a mesh edge, every triangle counter-clockwise
    keys = edge_keys(np.r_[out[:, 0], out[:, 1], out[:, 2]], np.r_[out[:, 1], out[:, 2], out[:, 0]])
    assert np.isin(edge_keys(E2[:, 0], E2[:, 1]), keys).all()
    x, y = P2[:, 0], P2[:, 1]
    t0, t1, t2 = out.T
    assert ((x[t1] - x[t0]) * (y[t2] - y[t0]) - (y[t1] - y[t0]) * (x[t2] - x[t0]) > 0).all()


def test_patch_declines_large_changes():
    P, E, bnd, inside, _, n_hole = _model(0)
    T = constrained_delaunay(P, E, inside=inside, boundary_edges=E[bnd])
    P2 = P.copy()
    P2[n_hole + 12:] += 1e-6  # every interior point moved
    assert patch(P2, E, bnd, P, E, T) is None
    same, kept = patch(P, E, bnd, P, E, T)  # nothing changed
    assert same is T and np.array_equal(kept, np.arange(len(T)))


def test_band_flood_matches_full_flood():
    # the inside test of pieces separated by boundary edges, with an interface inside
    P, E, bnd, inside, _, _ = _model(3)
    import hetmesh.tri.cdt as tr
    t = constrained_delaunay(P, E, inside=inside, boundary_edges=E[bnd])
    area = np.ones(len(t))
    # the full flood and the band flood classify alike on the kernel's own triangles
    full = constrained_delaunay(P, E)  # convex hull
    nbr = np.full((len(full), 3), -1)
    keys = edge_keys(np.r_[full[:, 0], full[:, 1], full[:, 2]],
                     np.r_[full[:, 1], full[:, 2], full[:, 0]])
    order = np.argsort(keys, kind="stable")
    ks = keys[order]
    pair = np.flatnonzero(ks[1:] == ks[:-1])
    h1, h2 = order[pair], order[pair + 1]
    m = len(full)
    nbr[h1 % m, h1 // m] = h2 % m
    nbr[h2 % m, h2 // m] = h1 % m
    area = 0.5 * np.abs(tr.triangle_areas2(P, full))
    a = tr.inside_full_flood(P, full, nbr, E[bnd], inside, area)
    b = tr.inside_band_flood(P, full, nbr, E[bnd], inside, area)
    assert b is not None and np.array_equal(a, b)
    assert _same(full[a], t)


def test_refinement_through_local_updates(monkeypatch):
    """The repair rounds of a large mesh update the triangulation in windows and carry delta
    over for the triangles kept (``refine.evaluate(kept=...)``). Run here on a small mesh by
    lowering the size at which local updates start: it ends with a mesh that the
    independent check accepts, with the element count of the full rebuilds within 2 %
    (the triangles differ only in the choice among cocircular points). Regression: a
    parameter named like the helper it called made every mesh past 131,072 points fail with
    a TypeError."""
    import hetmesh
    from hetmesh.testing import independent_check
    from hetmesh.tri import workset

    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    full = hetmesh.generate(model, 0.05)
    monkeypatch.setattr(workset, "PATCH_MIN_POINTS", 100)
    calls = []
    real = workset.patch
    monkeypatch.setattr(workset, "patch", lambda *a: calls.append(1) or real(*a))
    local = hetmesh.generate(model, 0.05)
    assert calls  # the local updates ran
    assert independent_check(local, model, 0.05) == []
    assert abs(local.stats.n_elements - full.stats.n_elements) <= 0.02 * full.stats.n_elements
