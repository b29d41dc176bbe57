"""A quality pass for tetrahedral meshes that keeps every element's delta under delta_0:
Laplacian relocation of the interior vertices, a move kept only where it helps.

In a round, the free vertices (not on the boundary, not fixed) are coloured so that no two
of one colour share an edge (greedy, in the order of a hash of their ids: deterministic);
every vertex of a colour is offered the centroid of its neighbours, and the move is kept
where all its tetrahedra stay positive, their delta (over the four vertices, the moved one's
composition evaluated at its new place) stays under ``threshold``, their mean radius ratio
improves and their smallest dihedral angle does not fall (or stays above :data:`FLOOR`).
Only the vertices of a tetrahedron of radius ratio under :data:`POOR` are offered a move. A
tetrahedron has at most one vertex of a colour, so the moves of a colour are independent and
are decided together, on whole arrays.

>>> import numpy as np
>>> from hetmesh.material import AnalyticField
>>> from hetmesh.mesh import simplex_measures
>>> f = AnalyticField({"metal": "z / 2"}, ["ceramic", "metal"], dim=3)
>>> p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.02, 0.02, 0.02]])
>>> t = np.array([[4, 1, 2, 3], [0, 4, 2, 3], [0, 1, 4, 3], [0, 1, 2, 4]])
>>> bool((simplex_measures(p, t) > 0).all())
True
>>> q, c, n = smooth(p, t, f, 0.6)
>>> n, q[4].tolist()
(1, [0.25, 0.25, 0.25])
"""

from __future__ import annotations

import numpy as np

from ..mesh import simplex_measures
from ..metrics import tet_quality
from ..topology import unique
from .faces import boundary_faces
from .quality import min_dihedral
from .refine import unique_edges

__all__ = ["smooth"]

#: rounds of the pass (each visits every colour once)
ROUNDS = 4
#: the vertices offered a move: those of a tetrahedron of radius ratio under this
POOR = 0.6
#: a move may lower the smallest dihedral angle around the vertex down to this (degrees)
FLOOR = 25.0


def _colours(edges: np.ndarray, free: np.ndarray) -> np.ndarray:
    """A colour per free vertex (-1 for the others), no edge between two of one colour."""
    n = len(free)
    col = np.full(n, -1, dtype=np.int64)
    e = edges[free[edges[:, 0]] & free[edges[:, 1]]]
    prio = (np.arange(n, dtype=np.uint64) * np.uint64(2654435761)) % np.uint64(2 ** 32)
    left = free.copy()
    c = 0
    while left.any():
        # a vertex takes colour c if no uncoloured neighbour of higher priority is left
        live = left[e[:, 0]] & left[e[:, 1]]
        a, b = e[live, 0], e[live, 1]
        beaten = np.zeros(n, dtype=bool)
        hi_a = prio[a] > prio[b]
        beaten[b[hi_a]] = True
        beaten[a[~hi_a]] = True
        take = left & ~beaten
        col[take] = c
        left &= ~take
        # neighbours of the vertices just coloured wait for the next colour
        c += 1
    return col


def _neighbour_centroids(pts: np.ndarray, edges: np.ndarray, deg: np.ndarray,
                         vs: np.ndarray) -> np.ndarray:
    """The centroid of the edge neighbours of each vertex ``vs`` ``(K, 3)``.

    Summed over the edges that touch ``vs`` only, in the order of ``edges`` (the same
    numbers as sums over every edge: a vertex's sum sees the same terms in the same
    order), so that a colour of a few vertices costs no pass over every point."""
    n = len(pts)
    mine = np.zeros(n, dtype=bool)
    mine[vs] = True
    a = edges[mine[edges[:, 0]]]
    b = edges[mine[edges[:, 1]]]
    sums = np.column_stack([np.bincount(a[:, 0], weights=pts[a[:, 1], j], minlength=n)
                            + np.bincount(b[:, 1], weights=pts[b[:, 0], j], minlength=n)
                            for j in range(3)])
    return sums[vs] / np.maximum(deg[vs], 1)[:, None]


def _min_around(vs, start, inc_tet, values) -> np.ndarray:
    """The smallest of ``values`` (per tetrahedron) around each vertex of ``vs``."""
    cnt = start[vs + 1] - start[vs]
    owner = np.repeat(np.arange(len(vs)), cnt)
    first = np.concatenate([[0], np.cumsum(cnt)])[:-1]
    rows = inc_tet[start[vs][owner] + np.arange(len(owner)) - first[owner]]
    out = np.full(len(vs), np.inf)
    np.minimum.at(out, owner, values[rows])
    return out


def smooth(points: np.ndarray, tets: np.ndarray, field, threshold: float, *,
           comp: np.ndarray | None = None, fixed: np.ndarray | None = None,
           rounds: int = ROUNDS) -> tuple[np.ndarray, np.ndarray, int]:
    """Relocate the interior vertices where it improves the mean radius ratio around them,
    keeps the smallest dihedral angle (or above :data:`FLOOR`) and every delta under
    ``threshold``: ``(points, comp, moves)``; the connectivity is unchanged.

    ``points (N, 3)``, ``tets (M, 4)`` positively oriented, ``field`` with
    ``composition(points)``; ``comp (N, m)`` the vertex compositions if known; ``fixed
    (N,) bool`` vertices that must not move (the boundary's never do).
    """
    pts = np.array(points, dtype=np.float64)
    c = field.composition(pts) if comp is None else np.array(comp, dtype=np.float64)
    if c.ndim == 1:
        c = c[:, None]
    n = len(pts)
    faces, _ = boundary_faces(tets)
    free = np.ones(n, dtype=bool)
    free[unique(faces)] = False
    if fixed is not None:
        free &= ~fixed
    if not free.any():
        return pts, c, 0
    edges, _ = unique_edges(tets)
    col = _colours(edges, free)
    # incidence: (tet, local corner) of every vertex
    order = np.argsort(tets.ravel(), kind="stable")
    vert = tets.ravel()[order]
    inc_tet = order // 4
    start = np.searchsorted(vert, np.arange(n + 1))
    deg = np.bincount(edges.ravel(), minlength=n)
    q_tet = tet_quality(pts, tets)
    d_tet = min_dihedral(pts, tets)
    moves = 0
    for _ in range(rounds):
        moved_round = 0
        for k in range(int(col.max()) + 1):
            vs = np.flatnonzero(col == k)
            if len(vs):  # only the vertices of a poor tetrahedron
                vs = vs[_min_around(vs, start, inc_tet, q_tet) < POOR]
            if not len(vs):
                continue
            target = _neighbour_centroids(pts, edges, deg, vs)
            cnt = start[vs + 1] - start[vs]
            owner = np.repeat(np.arange(len(vs)), cnt)
            first = np.concatenate([[0], np.cumsum(cnt)])[:-1]
            rows = inc_tet[start[vs][owner] + np.arange(len(owner)) - first[owner]]
            old_q = q_tet[rows]
            # the trial positions and compositions in place (no copy of every point per
            # colour); the vertices whose move is refused get theirs back below
            saved_p, saved_c = pts[vs], c[vs]
            pts[vs] = target
            c[vs] = field.composition(target).reshape(len(vs), -1)
            new_q = tet_quality(pts, tets[rows])
            vol = simplex_measures(pts, tets[rows])
            cc = c[tets[rows]]
            delta = (cc.max(axis=1) - cc.min(axis=1)).max(axis=1)
            old_d = d_tet[rows]
            new_d = min_dihedral(pts, tets[rows])
            worst_old = np.full(len(vs), np.inf)
            worst_new = np.full(len(vs), np.inf)
            np.minimum.at(worst_old, owner, old_d)
            np.minimum.at(worst_new, owner, new_d)
            mean_old = np.bincount(owner, weights=old_q, minlength=len(vs))
            mean_new = np.bincount(owner, weights=new_q, minlength=len(vs))
            bad = np.zeros(len(vs), dtype=bool)
            bad[owner[(vol <= 0) | (delta >= threshold)]] = True
            ok = ~bad & (worst_new >= np.minimum(worst_old, FLOOR)) & (mean_new > mean_old + 1e-9)
            acc = vs[ok]
            keep = ok[owner]
            q_tet[rows[keep]] = new_q[keep]
            d_tet[rows[keep]] = new_d[keep]
            pts[vs[~ok]] = saved_p[~ok]
            c[vs[~ok]] = saved_c[~ok]
            moved_round += len(acc)
        moves += moved_round
        if not moved_round:
            break
    return pts, c, moves
