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

An interface curve of the section (a seam, a material interface) is a chain of mesh edges;
the strip swept by each of its edges ``(a, b)`` is triangulated alike by the cells on either
side, so the interface's sweep is a surface of tetrahedron faces: those whose three vertices
lie in the columns of ``a`` and ``b`` (:func:`strip_faces`), each shared by two tetrahedra
(:func:`strip_problems`); :func:`swept_interfaces` gives them their faces' markers.

>>> p2 = np.array([[0, 0], [1, 0], [0, 1.0], [1, 1]]); t2 = np.array([[0, 1, 2], [1, 3, 2]])
>>> pts, tets, tri = column_tets(p2, t2, np.array([1, 1, 1, 1]), 0.0, 1.0)
>>> col = np.repeat(np.arange(4), 2)
>>> f, k = strip_faces(tets, col, np.array([[1, 2]]))
>>> len(f), k.tolist(), strip_problems(tets, f)
(2, [0, 0], [])

After an edge-bisection repair the points are no longer all in columns: a midpoint lies in
the strip of a section edge when both ends of its edge do (:func:`carriers`), and the strip's
faces are the tetrahedron faces whose three points lie in one interface edge's strip
(:func:`carried_strip_faces`): the repair splits strip triangles within the strip (a child
lies in its parent), and no tetrahedron lies in a strip (every one keeps a point off it).

>>> c = carriers(col, np.array([[2, 5]]), np.array([[1, 2]]))  # point 8: mid of 2 and 5
>>> c[[2, 5, 8]].tolist()
[[1, 1], [2, 2], [1, 2]]
"""

from __future__ import annotations

import numpy as np

from ..topology import edge_keys, unique
from .quality import TET_FACES

__all__ = ["column_tets", "layered_column_tets", "column_counts", "vertex_size",
           "section_interfaces", "strip_faces",
           "strip_problems", "face_multiplicity", "swept_interfaces", "carriers",
           "carried_strip_faces"]


def vertex_size(points2: np.ndarray, tris2: np.ndarray) -> np.ndarray:
    """The mean length of the edges at each vertex of a triangulation ``(N,)``."""
    e = np.concatenate([tris2[:, [0, 1]], tris2[:, [1, 2]], tris2[:, [2, 0]]])
    e = unique(np.sort(e, axis=1), axis=0)
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


def layered_column_tets(points2: np.ndarray, tris2: np.ndarray, counts: np.ndarray,
                        levels: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`column_tets` through the layers between consecutive ``levels (K + 1,)``, with
    ``counts (K, N)`` intervals per layer and column: every column has a point on every
    level, shared by the layers below and above it, so no tetrahedron crosses a level (the
    sweep's jump planes). ``(points (P, 3), tets (M, 4), tri (M,), column (P,))``,
    ``column`` the section vertex of every point; one layer gives :func:`column_tets`'s.

    >>> p2 = np.array([[0, 0], [1, 0], [0, 1.0]]); t2 = np.array([[0, 1, 2]])
    >>> p, t, tri, col = layered_column_tets(p2, t2, np.array([[1, 1, 1], [2, 1, 1]]),
    ...                                      np.array([0.0, 1.0, 3.0]))
    >>> len(p), len(t), sorted(set(p[:, 2].tolist()))
    (10, 7, [0.0, 1.0, 2.0, 3.0])
    """
    counts = np.atleast_2d(np.asarray(counts, dtype=np.int64))
    n = len(points2)
    pts, tets, tris, cols = [], [], [], []
    top, offset = None, 0
    for k in range(len(counts)):
        pl, tt, tri = column_tets(points2, tris2, counts[k], levels[k], levels[k + 1])
        start = np.concatenate([[0], np.cumsum(counts[k] + 1)])
        col = np.repeat(np.arange(n), counts[k] + 1)
        keep = np.ones(len(pl), dtype=bool)
        if top is not None:  # the bottom points are the layer below's top ones
            keep[start[:-1]] = False
        ids = np.empty(len(pl), dtype=np.int64)
        ids[keep] = offset + np.arange(int(keep.sum()))
        if top is not None:
            ids[start[:-1]] = top
        pts.append(pl[keep])
        cols.append(col[keep])
        tets.append(ids[tt])
        tris.append(tri)
        top = ids[start[1:] - 1]
        offset += int(keep.sum())
    return (np.concatenate(pts), np.concatenate(tets), np.concatenate(tris),
            np.concatenate(cols))


def section_interfaces(section, points2: np.ndarray, tris2: np.ndarray, edges2: np.ndarray,
                       tol: float, chord: float, only=None) -> tuple[np.ndarray, np.ndarray]:
    """The edges of a section's mesh that lie on its interface curves: ``(edges (E, 2),
    curve (E,))``, ``curve`` the index in ``section.curves``. ``edges2 (K, 2)`` are the
    mesh's constrained edges (its facets); an edge qualifies when it is inside the mesh (two
    triangles hold it), both ends lie within ``tol`` of one interface curve and its midpoint
    within ``chord + tol`` of it (a chord of an arc). Edges of embedded material
    discontinuities, on no curve of ``section``, are not among them. ``only``: the indices
    of the interface curves to look at (default: all)."""
    curves = [i for i, c in enumerate(section.curves) if c.kind == "interface"
              and (only is None or i in only)]
    e = np.sort(np.asarray(edges2, dtype=np.int64).reshape(-1, 2), axis=1)
    empty = (np.zeros((0, 2), np.int64), np.zeros(0, np.int64))
    if not curves or not len(e):
        return empty
    t = np.asarray(tris2, dtype=np.int64)
    all_e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    k_all, cnt = unique(edge_keys(all_e[:, 0], all_e[:, 1]), return_counts=True)
    inner = np.isin(edge_keys(e[:, 0], e[:, 1]), k_all[cnt == 2])
    e = e[inner]
    a, b = points2[e[:, 0]], points2[e[:, 1]]
    best = np.full(len(e), np.inf)
    arg = np.full(len(e), -1, dtype=np.int64)
    for i in curves:
        c = section.curves[i].curve
        d = np.maximum(c.distance(a), c.distance(b))
        better = d < best
        best[better], arg[better] = d[better], i
    ok = best <= tol
    mid = 0.5 * (a + b)
    for i in unique(arg[ok]):
        sel = ok & (arg == i)
        ok[sel] = section.curves[int(i)].curve.distance(mid[sel]) <= chord + tol
    return e[ok], arg[ok]


def strip_faces(tets: np.ndarray, column: np.ndarray, edges: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """The faces of ``tets`` on the strips swept by the section edges ``edges (E, 2)``: the
    triangles whose three vertices lie in the columns of one edge's two ends (``column
    (N,)``: the section vertex of every point). ``(faces (F, 3), edge (F,))``, every face
    once, in the order of its first tetrahedron and oriented as a face of it."""
    f = np.asarray(tets, dtype=np.int64)[:, TET_FACES].reshape(-1, 3)
    e = np.sort(np.asarray(edges, dtype=np.int64).reshape(-1, 2), axis=1)
    if not len(e) or not len(f):
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    c = np.sort(np.asarray(column, dtype=np.int64)[f], axis=1)
    two = (c[:, 0] != c[:, 2]) & ((c[:, 1] == c[:, 0]) | (c[:, 1] == c[:, 2]))
    n = np.int64(max(int(c.max()), int(e.max())) + 1)
    ekey = e[:, 0] * n + e[:, 1]
    order = np.argsort(ekey, kind="stable")
    pos = np.minimum(np.searchsorted(ekey[order], c[:, 0] * n + c[:, 2]), len(e) - 1)
    rows = np.flatnonzero(two & (ekey[order][pos] == c[:, 0] * n + c[:, 2]))
    _, first = unique(np.sort(f[rows], axis=1), axis=0, return_index=True)
    keep = rows[np.sort(first)]
    return f[keep], order[pos[keep]]


def face_multiplicity(tets: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Of how many tetrahedra each triangle of ``faces (F, 3)`` is a face ``(F,)``: 1 on
    the boundary, 2 inside the mesh."""
    if not len(faces):
        return np.zeros(0, dtype=np.int64)
    f = np.sort(np.asarray(tets, dtype=np.int64)[:, TET_FACES].reshape(-1, 3), axis=1)
    g = np.sort(np.asarray(faces, dtype=np.int64), axis=1)
    n = np.int64(max(int(f.max()), int(g.max())) + 1)
    fk = np.sort((f[:, 0] * n + f[:, 1]) * n + f[:, 2])
    gk = (g[:, 0] * n + g[:, 1]) * n + g[:, 2]
    return np.searchsorted(fk, gk, side="right") - np.searchsorted(fk, gk)


def strip_problems(tets: np.ndarray, faces: np.ndarray) -> list[str]:
    """One line if some interface triangles ``faces (F, 3)`` are not faces of exactly two
    tetrahedra (an interface inside the mesh separates two of them), else nothing."""
    if not len(faces):
        return []
    held = face_multiplicity(tets, faces)
    bad = held != 2
    if not bad.any():
        return []
    i = int(np.flatnonzero(bad)[0])
    return [f"{int(bad.sum())} interface triangles are not faces of two tetrahedra (e.g. "
            f"triangle {faces[i].tolist()} is a face of {int(held[i])})"]


def swept_interfaces(section, points2: np.ndarray, tris2: np.ndarray, edges2: np.ndarray,
                     tets: np.ndarray, column: np.ndarray, tol: float, chord: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The interface triangles of a mesh swept from a section's mesh (``points2``,
    ``tris2``, constrained edges ``edges2``; ``column (N,)`` the section vertex of every
    point of ``tets``) and their face markers, ``3 +`` the curve's index in
    ``section.curves`` (the markers of a swept solid's faces: two ends or caps, then one
    per section curve): ``(faces (F, 3), markers (F,))``. ``tol`` and ``chord`` as in
    :func:`section_interfaces`."""
    e2, curve = section_interfaces(section, points2, tris2, edges2, tol, chord)
    faces, k = strip_faces(tets, column, e2)
    return faces, 3 + curve[k]


def _edge_lookup(edges: np.ndarray, n: int):
    e = np.sort(np.asarray(edges, dtype=np.int64).reshape(-1, 2), axis=1)
    key = e[:, 0] * n + e[:, 1]
    order = np.argsort(key, kind="stable")
    return key[order], order


def _carried_by(vals: np.ndarray, skey: np.ndarray, order: np.ndarray, n: int):
    """For rows of carrier values ``vals (K, q)``: ``(lo, hi, edge)`` where every value is
    ``lo`` or ``hi`` (``edge``: the index of the interface edge ``(lo, hi)``, -1 if there is
    none or a value is -1)."""
    lo, hi = vals.min(axis=1), vals.max(axis=1)
    two = ((vals == lo[:, None]) | (vals == hi[:, None])).all(axis=1) & (lo >= 0)
    edge = np.full(len(vals), -1, dtype=np.int64)
    if len(skey):
        k = lo * n + hi
        pos = np.minimum(np.searchsorted(skey, k), len(skey) - 1)
        hit = two & (lo < hi) & (skey[pos] == k)
        edge[hit] = order[pos[hit]]
    return lo, hi, two, edge


def carriers(column: np.ndarray, ends: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Where every point of a repaired sweep lies with respect to the interface strips:
    ``(P, 2)`` sorted section vertices, ``(a, a)`` for a point of column ``a``, ``(a, b)``
    for a point inside the strip of the interface edge ``(a, b)`` (one of ``edges (E, 2)``),
    ``(-1, -1)`` elsewhere. ``column (N,)``: the section vertex of the sweep's points;
    ``ends (P - N, 2)``: the edge whose midpoint every later point is
    (:class:`hetmesh.tet.refine.RepairTrace`)."""
    col = np.asarray(column, dtype=np.int64)
    ends = np.asarray(ends, dtype=np.int64).reshape(-1, 2)
    out = np.full((len(col) + len(ends), 2), -1, dtype=np.int64)
    out[:len(col)] = col[:, None]
    n = int(max(col.max(initial=0), np.asarray(edges).max(initial=0))) + 1
    skey, order = _edge_lookup(edges, n)
    known, k = len(col), 0
    while k < len(ends):  # the midpoints of one pass depend on earlier points only
        later = np.flatnonzero(ends[k:].max(axis=1) >= known)
        stop = k + (int(later[0]) if len(later) else len(ends) - k)
        vals = np.concatenate([out[ends[k:stop, 0]], out[ends[k:stop, 1]]], axis=1)
        lo, hi, two, edge = _carried_by(vals, skey, order, n)
        one = two & (lo == hi)
        rows = known + np.arange(stop - k)
        out[rows[one]] = lo[one, None]
        on = edge >= 0
        out[rows[on], 0], out[rows[on], 1] = lo[on], hi[on]
        known += stop - k
        k = stop
    return out


def carried_strip_faces(tets: np.ndarray, carrier: np.ndarray, edges: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
    """The faces of ``tets`` inside the strips of ``edges (E, 2)``: the triangles whose three
    points' :func:`carriers` lie in one edge's two columns. ``(faces (F, 3), edge (F,))``,
    every face once, in the order of its first tetrahedron and oriented as a face of it (as
    :func:`strip_faces`, which it equals on an unrepaired sweep)."""
    f = np.asarray(tets, dtype=np.int64)[:, TET_FACES].reshape(-1, 3)
    if not len(edges) or not len(f):
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    c = np.asarray(carrier, dtype=np.int64)
    n = int(max(c.max(), np.asarray(edges).max())) + 1
    skey, order = _edge_lookup(edges, n)
    vals = c[f].reshape(len(f), 6)
    _, _, _, edge = _carried_by(vals, skey, order, n)
    rows = np.flatnonzero(edge >= 0)
    _, first = unique(np.sort(f[rows], axis=1), axis=0, return_index=True)
    keep = rows[np.sort(first)]
    return f[keep], edge[keep]
