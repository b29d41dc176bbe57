"""Sweeps with a spacing of their own in every column: the 2D mesh of a section turned into
tetrahedra through columns of points whose count follows the local triangle size.

Every vertex ``i`` of the section mesh becomes a column of ``n_i + 1`` points at the sweep
parameters ``s0 + (s1 - s0) k / n_i`` (``k = 0 .. n_i``). The prism-like cell over a
triangle ``(a, b, c)`` is filled by advancing a front: it starts as the bottom triangle
``(a_0, b_0, c_0)`` and, in the order of the next point's parameter (ties: the smaller vertex
id first), one corner at a time moves up its column; each move makes the tetrahedron of the
front and the corner's next point. The cell holds ``n_a + n_b + n_c`` tetrahedra. The two
cells on either side of a section edge ``(a, b)`` order the moves of ``a`` and ``b`` the same
way, so they triangulate the vertical strip between the two columns alike and the mesh
conforms. A tetrahedron ``(front, a_{k+1})`` has the volume ``area(abc) (s_{k+1} - s_k) / 3``
in the sweep coordinates: positive whatever the front's tilt.

With one count everywhere this is the classical cut of a prism into three tetrahedra; with
counts that follow the section's edge lengths a small triangle is no longer swept through
the layers a large one needs, nor a large one through the thin layers of a small one: the
cells stay about as tall as wide (the tetrahedra's shape), and the section's coarse regions
get fewer points (the count). Each tetrahedron's vertices are copies of one triangle's, so
its composition range is at most the triangle's when the composition does not change along
the sweep.

>>> import numpy as np
>>> p2 = np.array([[0, 0], [1, 0], [0, 1.0]]); t2 = np.array([[0, 1, 2]])
>>> pts, tets, tri = column_tets(p2, t2, np.array([1, 2, 1]), 0.0, 1.0)
>>> len(pts), len(tets), tri.tolist()
(7, 4, [0, 0, 0, 0])
"""

from __future__ import annotations

import numpy as np

__all__ = ["column_tets", "column_counts", "vertex_size"]


def vertex_size(points2: np.ndarray, tris2: np.ndarray) -> np.ndarray:
    """The mean length of the edges at each vertex of a triangulation ``(N,)``."""
    e = np.concatenate([tris2[:, [0, 1]], tris2[:, [1, 2]], tris2[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    ln = np.linalg.norm(points2[e[:, 0]] - points2[e[:, 1]], axis=1)
    n = len(points2)
    s = np.bincount(e.ravel(), weights=np.repeat(ln, 2), minlength=n)
    c = np.bincount(e.ravel(), minlength=n)
    return s / np.maximum(c, 1)


def column_counts(length: float, size: np.ndarray, *, ratio: float,
                  cap: float | None = None) -> np.ndarray:
    """Intervals per column ``(N,)`` (at least 1): ``length / (ratio size_i)`` rounded up,
    the spacing at most ``cap``."""
    h = ratio * np.asarray(size, dtype=float)
    if cap is not None:
        h = np.minimum(h, cap)
    return np.maximum(1, np.ceil(length / np.maximum(h, 1e-300) - 1e-9)).astype(np.int64)


def column_tets(points2: np.ndarray, tris2: np.ndarray, counts: np.ndarray, s0: float,
                s1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sweep a triangulation through columns of ``counts (N,)`` intervals from ``s0`` to
    ``s1``: ``(points (P, 3): section coordinates and sweep parameter, tets (M, 4) positively
    oriented in those coordinates, tri (M,) the section triangle of each)``.

    Column ``i``'s points are consecutive, from ``s0`` up (its first is ``sum(counts[:i] +
    1)``); a count of 0 makes a column of one point (at ``s0``), which never moves.
    """
    p2 = np.asarray(points2, dtype=float)
    t = np.asarray(tris2, dtype=np.int64).copy()
    n = np.asarray(counts, dtype=np.int64)
    d = p2[t[:, 1]] - p2[t[:, 0]]
    e = p2[t[:, 2]] - p2[t[:, 0]]
    cw = d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0] < 0
    t[cw, 1], t[cw, 2] = t[cw, 2], t[cw, 1].copy()
    start = np.concatenate([[0], np.cumsum(n + 1)])
    col = np.repeat(np.arange(len(n)), n + 1)
    k = np.arange(int(start[-1])) - start[col]
    frac = np.where(n[col] > 0, k / np.maximum(n[col], 1), 0.0)
    s = s0 + (s1 - s0) * frac
    s[(k == n[col]) & (n[col] > 0)] = s1
    pts = np.column_stack([p2[col], s])
    # the moves: corner j of triangle i to its level l = 1 .. n
    nc = n[t].ravel()  # (3 T,)
    rep = np.repeat(np.arange(len(nc)), nc)
    first = np.concatenate([[0], np.cumsum(nc)])[:-1]
    lvl = np.arange(len(rep)) - first[rep] + 1
    tri, corner = rep // 3, rep % 3
    vid = t.ravel()[rep]
    key = lvl / n[vid]  # exact ties for equal fractions (correctly rounded quotients)
    order = np.lexsort((vid, key, tri))
    tri, corner, vid, lvl = tri[order], corner[order], vid[order], lvl[order]
    onehot = np.zeros((len(tri), 3), dtype=np.int64)
    onehot[np.arange(len(tri)), corner] = 1
    cs = np.cumsum(onehot, axis=0)
    gstart = np.searchsorted(tri, np.arange(len(t)))
    base = np.vstack([np.zeros((1, 3), dtype=np.int64), cs])[gstart]  # (T, 3)
    before = cs - base[tri] - onehot  # the front's levels before each move
    front = start[t[tri]] + before  # (M, 3)
    new = start[vid] + lvl
    tets = np.column_stack([front, new])
    return pts, tets, tri
