"""The constrained Delaunay wrapper: orientation, constraints, inside detection."""

from __future__ import annotations

import numpy as np

from hetmesh.mesh import Mesh
from hetmesh.tri.cdt import constrained_delaunay


def _square_with_hole(n=400, seed=0):
    rng = np.random.default_rng(seed)
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    ang = np.linspace(0, 2 * np.pi, 17)[:-1]
    hole = 0.5 + 0.2 * np.column_stack([np.cos(ang), np.sin(ang)])
    pts = rng.random((n, 2)) * 0.98 + 0.01
    pts = pts[np.hypot(*(pts - 0.5).T) > 0.22]
    P = np.vstack([outer, hole, pts])
    e_out = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    e_hole = 4 + np.column_stack([np.arange(16), (np.arange(16) + 1) % 16])
    return P, np.vstack([e_out, e_hole])


def test_counter_clockwise_and_hole_removed():
    P, E = _square_with_hole()
    t = constrained_delaunay(P, E, inside=lambda q: np.hypot(*(q - 0.5).T) > 0.2)
    m = Mesh(P, t)
    assert (m.areas > 0).all()
    ring = 16 * 0.5 * np.sin(2 * np.pi / 16) * 0.2 ** 2
    assert m.area == np.float64(m.area) and abs(m.area - (1 - ring)) < 1e-12
    assert m.problems() == []


def test_interface_edges_kept_and_both_sides_meshed():
    P, E = _square_with_hole()
    # the same circle as an interface (inside kept): components flood, not parity
    t = constrained_delaunay(P, E, inside=lambda q: np.ones(len(q), bool), boundary_edges=E[:4])
    m = Mesh(P, t)
    assert abs(m.area - 1.0) < 1e-12
    sides = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    edges = {tuple(sorted(e)) for e in sides.tolist()}
    assert all(tuple(sorted(e)) in edges for e in E.tolist())
