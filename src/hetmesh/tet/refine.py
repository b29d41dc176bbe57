"""Conforming refinement of tetrahedral meshes: bisection of the edges with the largest
composition jump, many at a time.

In one pass every violating tetrahedron proposes its edge with the largest composition jump;
of the proposed edges, those that are the best proposal (largest jump, then smallest edge id)
in every tetrahedron containing them are split at their midpoints together. A tetrahedron then
holds at most one split edge and becomes two; every tetrahedron around a split edge is split,
so the mesh stays conforming, and orientations are kept.

>>> import numpy as np
>>> p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
>>> t = np.array([[0, 1, 2, 3]])
>>> p2, t2 = bisect_edges(p, t, np.array([[0, 1]]))
>>> len(p2), len(t2), p2[-1].tolist()
(5, 2, [0.5, 0.0, 0.0])
"""

from __future__ import annotations

import numpy as np

from ..errors import MeshingError
from ..metrics import delta_vertices
from ..refinement import check_budget, check_progress
from ..topology import unique
from .quality import TET_EDGES

#: repair passes before giving up
MAX_PASSES = 60

__all__ = ["unique_edges", "bisect_edges", "select_edges", "repair"]


def unique_edges(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(edges (E, 2) sorted pairs, tet_edge (M, 6) edge ids)`` of a tetrahedral mesh."""
    e = np.sort(tets[:, TET_EDGES].reshape(-1, 2), axis=1).astype(np.int64)
    n = int(e.max()) + 1 if len(e) else 1
    key = e[:, 0] * n + e[:, 1]
    uk, inv = unique(key, return_inverse=True)
    edges = np.column_stack([uk // n, uk % n])
    return edges, inv.reshape(-1, 6)


def select_edges(tets: np.ndarray, comp: np.ndarray, bad: np.ndarray
                 ) -> np.ndarray:
    """Edges ``(K, 2)`` to bisect together: one per violating tetrahedron ``bad (M,) bool``
    at most, none two in a tetrahedron."""
    edges, te = unique_edges(tets)
    c = comp if comp.ndim == 2 else comp[:, None]
    jump = np.abs(c[edges[:, 0]] - c[edges[:, 1]]).max(axis=1)
    rows = np.flatnonzero(bad)
    if not len(rows):
        return np.empty((0, 2), dtype=np.int64)
    local = jump[te[rows]]  # (B, 6)
    best = te[rows, np.argmax(local, axis=1)]
    cand = unique(best)
    # priority: larger jump first, then smaller id (rank of (-jump, id))
    order = np.lexsort((cand, -jump[cand]))
    prio = np.full(len(edges), -1, dtype=np.int64)
    prio[cand[order]] = len(cand) - np.arange(len(cand))
    tp = prio[te]  # (M, 6)
    tmax = tp.max(axis=1)
    # an edge wins if it has the top priority in every tetrahedron holding it
    lose = np.zeros(len(edges), dtype=bool)
    holds = tp >= 0
    mt, kt = np.nonzero(holds)
    lost = tp[mt, kt] < tmax[mt]
    lose[te[mt[lost], kt[lost]]] = True
    win = cand[~lose[cand]]
    return edges[win]


def bisect_edges(points: np.ndarray, tets: np.ndarray, split: np.ndarray,
                 new_points: np.ndarray | None = None, *, with_parents: bool = False):
    """Split the edges ``split (K, 2)`` (no two in one tetrahedron) at their midpoints (or at
    ``new_points (K, 3)``), and every tetrahedron around them in two: ``(points, tets)``,
    with ``with_parents`` also the index in ``tets`` of every new tetrahedron's parent (to
    carry per-element data such as subregions)."""
    if not len(split):
        return (points, tets, np.arange(len(tets))) if with_parents else (points, tets)
    n = len(points)
    s = np.sort(split, axis=1).astype(np.int64)
    mid = 0.5 * (points[s[:, 0]] + points[s[:, 1]]) if new_points is None else new_points
    pts = np.concatenate([points, mid])
    edges, te = unique_edges(tets)
    nn = int(max(edges.max(), s.max())) + 1
    key = edges[:, 0] * nn + edges[:, 1]
    skey = s[:, 0] * nn + s[:, 1]
    pos = np.searchsorted(key, skey)
    new_id = np.full(len(edges), -1, dtype=np.int64)
    new_id[pos] = n + np.arange(len(s))
    tn = new_id[te]  # (M, 6)
    hit = tn >= 0
    if (hit.sum(axis=1) > 1).any():
        raise ValueError("bisect_edges: two split edges in one tetrahedron")
    rows = np.flatnonzero(hit.any(axis=1))
    k = np.argmax(hit[rows], axis=1)
    m = tn[rows, k]
    i, j = TET_EDGES[k, 0], TET_EDGES[k, 1]
    a = tets[rows].astype(np.int64).copy()
    b = a.copy()
    a[np.arange(len(rows)), j] = m  # keeps vertex i
    b[np.arange(len(rows)), i] = m  # keeps vertex j
    keep = np.ones(len(tets), dtype=bool)
    keep[rows] = False
    out = np.concatenate([tets[keep].astype(np.int64), a, b])
    if with_parents:
        return pts, out, np.concatenate([np.flatnonzero(keep), rows, rows])
    return pts, out


def repair(points: np.ndarray, tets: np.ndarray, field, threshold: float, *,
           comp: np.ndarray | None = None, max_elements: int | None = None):
    """Bisect largest-jump edges of the tetrahedra with delta >= ``threshold`` until there
    are none: ``(points, tets, comp, delta, passes)``. :class:`BudgetError` past
    ``max_elements``, :class:`MeshingError` after :data:`MAX_PASSES` passes."""
    comp = field.composition(points) if comp is None else comp
    delta = delta_vertices(comp, tets)
    passes = 0
    while (delta >= threshold).any():
        if passes >= MAX_PASSES:
            raise MeshingError(f"delta repair did not converge in {MAX_PASSES} passes "
                               f"({int((delta >= threshold).sum())} tetrahedra left)")
        if max_elements is not None:
            check_budget(len(tets), max_elements)
        split = select_edges(tets, comp, delta >= threshold)
        n0 = len(points)
        points, tets = bisect_edges(points, tets, split)
        check_progress(n0, len(points), passes, int((delta >= threshold).sum()), 0, threshold)
        comp = np.concatenate([comp, field.composition(points[n0:])])
        delta = delta_vertices(comp, tets)
        passes += 1
    return points, tets, comp, delta, passes
