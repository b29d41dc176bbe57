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

from dataclasses import dataclass

import numpy as np

from ..errors import MeshingError
from ..metrics import delta_vertices
from ..refinement import check_budget, check_progress
from ..topology import unique
from .quality import TET_EDGES

#: repair passes before giving up
MAX_PASSES = 60

__all__ = ["unique_edges", "bisect_edges", "select_edges", "repair", "RepairTrace",
           "corner_compositions"]


def unique_edges(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(edges (E, 2) sorted pairs, tet_edge (M, 6) edge ids)`` of a tetrahedral mesh."""
    e = np.sort(tets[:, TET_EDGES].reshape(-1, 2), axis=1).astype(np.int64)
    n = int(e.max()) + 1 if len(e) else 1
    key = e[:, 0] * n + e[:, 1]
    uk, inv = unique(key, return_inverse=True)
    edges = np.column_stack([uk // n, uk % n])
    return edges, inv.reshape(-1, 6)


def select_edges(tets: np.ndarray, comp: np.ndarray, bad: np.ndarray, *,
                 corners: np.ndarray | None = None, hashed: bool = False) -> np.ndarray:
    """Edges ``(K, 2)`` to bisect together: one per violating tetrahedron ``bad (M,) bool``
    at most, none two in a tetrahedron. An edge's jump is the range of ``comp`` over its
    ends or, with ``corners (M, 4, m)`` (every tetrahedron's own corner compositions, e.g.
    each in its subregion), the largest range over the tetrahedra holding it. An edge is
    taken where its jump leads in every tetrahedron holding it; equal jumps go to the
    smaller edge id or, ``hashed``, to the larger hash of it (where all jumps are equal on a
    structured grid, the ids leave a single leader per round, a hash many)."""
    edges, te = unique_edges(tets)
    if corners is None:
        c = comp if comp.ndim == 2 else comp[:, None]
        jump = np.abs(c[edges[:, 0]] - c[edges[:, 1]]).max(axis=1)
    else:
        tj = np.abs(corners[:, TET_EDGES[:, 0]] - corners[:, TET_EDGES[:, 1]]).max(axis=2)
        jump = np.zeros(len(edges))
        np.maximum.at(jump, te.ravel(), tj.ravel())
    rows = np.flatnonzero(bad)
    if not len(rows):
        return np.empty((0, 2), dtype=np.int64)
    local = jump[te[rows]]  # (B, 6)
    best = te[rows, np.argmax(local, axis=1)]
    cand = unique(best)
    # priority: larger jump first, then smaller id (rank of (-jump, id))
    tie = (cand.astype(np.uint64) * np.uint64(2654435761)) % np.uint64(2 ** 32) \
        if hashed else cand
    order = np.lexsort((tie, -jump[cand]))
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


@dataclass(frozen=True)
class RepairTrace:
    """What :func:`repair` did, for carrying data to the refined mesh.

    ``parent (M,)``: the index in the input tetrahedra of every output tetrahedron (each
    lies in its parent); ``ends (P, 2)``: the two points of the edge whose midpoint every
    new point is (new point ``k`` is point ``n_input + k``; its ends come before it)."""

    parent: np.ndarray
    ends: np.ndarray


def corner_compositions(field, points: np.ndarray, tets: np.ndarray, regions: np.ndarray
                        ) -> np.ndarray:
    """``(M, 4, m)``: every tetrahedron's four corners evaluated in its subregion
    ``regions (M,)`` (a vertex on a discontinuity takes each side's value in that side's
    tetrahedra)."""
    t = np.asarray(tets, dtype=np.int64)
    c = field.composition(points[t.ravel()], region=np.repeat(np.asarray(regions), 4))
    return np.asarray(c, dtype=np.float64).reshape(len(t), 4, -1)


def _corner_delta(cc: np.ndarray) -> np.ndarray:
    return (cc.max(axis=1) - cc.min(axis=1)).max(axis=1)


def repair(points: np.ndarray, tets: np.ndarray, field, threshold: float, *,
           comp: np.ndarray | None = None, max_elements: int | None = None,
           regions: np.ndarray | None = None, trace: bool = False):
    """Bisect largest-jump edges of the tetrahedra with delta >= ``threshold`` until there
    are none: ``(points, tets, comp, delta, passes)``. :class:`BudgetError` past
    ``max_elements``, :class:`MeshingError` after :data:`MAX_PASSES` passes.

    With ``regions (M,)`` (the subregion of every tetrahedron of a piecewise field, none
    straddling a discontinuity) every tetrahedron's corners are evaluated in its subregion
    and the children keep their parent's: ``comp`` is then ``(M', 4, m)``, the corner
    compositions of the output tetrahedra (a point has no single composition on a
    discontinuity), and the output tetrahedra's subregions are ``regions[trace.parent]``.
    With ``trace`` (or ``regions``) a :class:`RepairTrace` is returned last."""
    if regions is not None or trace:
        return _repair_traced(points, tets, field, threshold, comp, max_elements, regions)
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


def _repair_traced(points, tets, field, threshold, comp, max_elements, regions):
    """:func:`repair` with a :class:`RepairTrace` (and corner compositions per subregion
    with ``regions``): the same edges are chosen and split, the parents composed over the
    passes."""
    tets = np.asarray(tets, dtype=np.int64)
    parent = np.arange(len(tets))
    ends = [np.zeros((0, 2), dtype=np.int64)]
    if regions is None:
        comp = field.composition(points) if comp is None else comp
        cc = None
        delta = delta_vertices(comp, tets)
    else:
        regions = np.asarray(regions)
        cc = corner_compositions(field, points, tets, regions)
        delta = _corner_delta(cc)
    passes = 0
    while (delta >= threshold).any():
        if passes >= MAX_PASSES:
            raise MeshingError(f"delta repair did not converge in {MAX_PASSES} passes "
                               f"({int((delta >= threshold).sum())} tetrahedra left)")
        if max_elements is not None:
            check_budget(len(tets), max_elements)
        split = select_edges(tets, comp, delta >= threshold, corners=cc)
        n0 = len(points)
        points, tets, par = bisect_edges(points, tets, split, with_parents=True)
        check_progress(n0, len(points), passes, int((delta >= threshold).sum()), 0, threshold)
        if len(split):
            ends.append(np.sort(split, axis=1).astype(np.int64))
        parent = parent[par]
        if cc is None:
            comp = np.concatenate([comp, field.composition(points[n0:])])
            delta = delta_vertices(comp, tets)
        else:
            cc = cc[par]
            new = tets >= n0  # the midpoints, evaluated in their tetrahedron's subregion
            rows, k = np.nonzero(new)
            if len(rows):
                cc[rows, k] = field.composition(points[tets[rows, k]],
                                                region=regions[parent[rows]])
            delta = _corner_delta(cc)
        passes += 1
    out = cc if cc is not None else comp
    return points, tets, out, delta, passes, RepairTrace(parent, np.concatenate(ends))
