"""Flips of tetrahedral meshes that keep every phase's region: the tetrahedra whose smallest
dihedral angle is below a bound are replaced, with their neighbours, by other tetrahedra on
the same vertices wherever that raises the smallest angle.

Two operations, both inside one phase:

* *face flip* (2-3): two tetrahedra of one phase sharing a face become three around the
  edge joining their opposite vertices;
* *edge removal* (n - 2(n-2), n = 3..:data:`MAX_RING`): the n tetrahedra around an edge
  whose ring of opposite edges closes (an edge inside the phase: no boundary or interface
  triangle contains it) become the 2(n - 2) tetrahedra joining the edge's two ends to a
  triangulation of the ring (every triangulation is tried; n = 3 is the 3-2 flip, n = 4 the
  4-4 flip).

A replacement is taken only if its tetrahedra have positive volumes and exactly the outer
faces, oriented, of the tetrahedra they replace (so they fill the same polyhedron), pass
the caller's check (delta below delta_0), and their smallest dihedral angle is larger
than that of the tetrahedra they replace. The faces of the boundary and of the interfaces
between phases are outer faces of every replaced set: the surfaces, the vertices and the
phase of every point stay as they were.

>>> import numpy as np
>>> from hetmesh.tet.quality import min_dihedral
>>> p = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.85, 0], [0.5, 0.3, 0.05], [0.5, 0.3, -0.05]])
>>> t = np.array([[0, 2, 1, 4], [0, 1, 2, 3]])  # two flat tetrahedra on face (0, 1, 2)
>>> t2, ph = flip_improve(p, t, np.zeros(2, np.int64), lambda tets, phase: np.ones(len(tets),
...                       bool))
>>> t2.tolist()  # three around the edge (3, 4)
[[0, 1, 4, 3], [1, 2, 4, 3], [2, 0, 4, 3]]
>>> min_dihedral(p, t).round(1).tolist(), min_dihedral(p, t2).round(1).tolist()
([9.5, 9.5], [18.9, 20.3, 20.3])
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np

from ..metrics import delta_vertices, tet_volumes6
from ..topology import drop_unused
from .quality import min_dihedral

__all__ = ["flip_improve", "flip_slivers", "ring_triangulations", "MAX_RING"]

#: the largest ring of an edge that is removed
MAX_RING = 7
_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], np.int64)
_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], np.int64)


@cache
def ring_triangulations(n: int) -> tuple[tuple[tuple[int, int, int], ...], ...]:
    """Every triangulation of a convex polygon with vertices ``0 .. n-1``, each a tuple of
    ``n - 2`` triangles ``(i, j, k)``, ``i < j < k``."""

    def of(lo: int, hi: int) -> list[list[tuple[int, int, int]]]:
        # the triangulations of the polygon lo, lo+1, ..., hi (its side (lo, hi) closing it)
        if hi - lo < 2:
            return [[]]
        out = []
        for m in range(lo + 1, hi):
            for a in of(lo, m):
                for b in of(m, hi):
                    out.append(a + b + [(lo, m, hi)])
        return out

    return tuple(tuple(tr) for tr in of(0, n - 1))


def _oriented_faces(t: np.ndarray) -> set[tuple[int, int, int]]:
    """The faces of tetrahedra ``t`` not shared between two of them, each oriented outward
    and rotated to start at its smallest vertex."""
    f = t[:, _FACES].reshape(-1, 3)
    out: dict[tuple, tuple] = {}
    for a, b, c in f.tolist():
        key = tuple(sorted((a, b, c)))
        if key in out:
            del out[key]
        else:
            r = min(range(3), key=lambda k: (a, b, c)[k])
            out[key] = ((a, b, c) * 2)[r:r + 3]
    return set(out.values())


class _Index:
    """Faces and edges of the tetrahedra ``t`` for look-ups: the tetrahedra on a face or
    around an edge."""

    def __init__(self, t: np.ndarray, n_points: int):
        self.n = np.int64(n_points)
        f = np.sort(t[:, _FACES], axis=2).reshape(-1, 3)
        fk = (f[:, 0] * self.n + f[:, 1]) * self.n + f[:, 2]
        self.f_order = np.argsort(fk, kind="stable")
        self.f_keys = fk[self.f_order]
        e = np.sort(t[:, _EDGES], axis=2).reshape(-1, 2)
        ek = e[:, 0] * self.n + e[:, 1]
        self.e_order = np.argsort(ek, kind="stable")
        self.e_keys = ek[self.e_order]

    def on_face(self, a: int, b: int, c: int) -> np.ndarray:
        a, b, c = sorted((a, b, c))
        k = (a * self.n + b) * self.n + c
        lo, hi = np.searchsorted(self.f_keys, [k, k + 1])
        return self.f_order[lo:hi] // 4

    def around_edge(self, a: int, b: int) -> np.ndarray:
        a, b = min(a, b), max(a, b)
        k = a * self.n + b
        lo, hi = np.searchsorted(self.e_keys, [k, k + 1])
        return self.e_order[lo:hi] // 6


def _ring(t: np.ndarray, tets: np.ndarray, a: int, b: int) -> list[int] | None:
    """The vertices around edge ``(a, b)`` in order, if the tetrahedra ``tets`` around it
    close a ring; else None."""
    nxt: dict[int, list[int]] = {}
    for row in t[tets].tolist():
        x, y = (v for v in row if v != a and v != b)
        nxt.setdefault(x, []).append(y)
        nxt.setdefault(y, []).append(x)
    if any(len(v) != 2 for v in nxt.values()):
        return None
    start = next(iter(nxt))
    ring, prev, cur = [start], None, start
    while True:
        n0, n1 = nxt[cur]
        step = n1 if n0 == prev else n0
        if step == start:
            break
        ring.append(step)
        prev, cur = cur, step
    return ring if len(ring) == len(tets) else None


def _surface_points(t: np.ndarray, phase: np.ndarray, index: _Index, n_points: int
                    ) -> np.ndarray:
    """Whether each point lies on a boundary face (a face of one tetrahedron) or on an
    interface (a face of two tetrahedra of different phases)."""
    keys = index.f_keys
    first = np.r_[True, keys[1:] != keys[:-1]]
    start = np.flatnonzero(first)
    count = np.diff(np.r_[start, len(keys)])
    owner = index.f_order // 4
    a = owner[start]
    b = owner[np.minimum(start + 1, len(keys) - 1)]
    surf = (count == 1) | (phase[a] != phase[b])
    rows = index.f_order[start[surf]]
    faces = t[rows // 4][np.arange(len(rows))[:, None], _FACES[rows % 4]]
    out = np.zeros(n_points, bool)
    out[faces.ravel()] = True
    return out


@cache
def _ring_rows(n: int) -> np.ndarray:
    """``(C, 2 (n - 2), 4)``: for every triangulation of a ring of ``n`` vertices
    (:func:`ring_triangulations`), its triangles joined to the edge's ends, as positions
    in ``ring + [a, b]``."""
    return np.array([[[x, y, z, end] for x, y, z in tri for end in (n, n + 1)]
                     for tri in ring_triangulations(n)], np.int64)


def _candidates(t: np.ndarray, phase: np.ndarray, index: _Index, k: int,
                surface: np.ndarray, star_of: Callable[[int], np.ndarray]):
    """The replacements of tetrahedron ``k`` in groups ``(old tetrahedra, new (C, K, 4))``,
    C ways of replacing the same old ones: face flips with its neighbours, removals of its
    edges, and collapses of its vertices inside its phase (``surface`` False) onto its
    other vertices; all within its phase."""
    tv = t[k].tolist()
    for f in _FACES.tolist():
        a, b, c = (tv[i] for i in f)
        on = index.on_face(a, b, c)
        if len(on) != 2:
            continue
        o = int(on[0] if on[1] == k else on[1])
        if phase[o] != phase[k]:
            continue
        d = next(v for v in tv if v not in (a, b, c))
        e = next(v for v in t[o].tolist() if v not in (a, b, c))
        new = np.array([[[a, b, d, e], [b, c, d, e], [c, a, d, e]]], np.int64)
        yield np.array([k, o]), new
    for i, j in _EDGES.tolist():
        a, b = tv[i], tv[j]
        around = index.around_edge(a, b)
        if not 3 <= len(around) <= MAX_RING or (phase[around] != phase[k]).any():
            continue
        ring = _ring(t, around, a, b)
        if ring is None:
            continue
        yield around, np.array(ring + [a, b], np.int64)[_ring_rows(len(ring))]
    for m in tv:
        if surface[m]:
            continue
        star = star_of(m)
        if (phase[star] != phase[k]).any():
            continue
        rows = t[star]
        for v in tv:
            if v == m:
                continue
            keep = ~(rows == v).any(axis=1)
            yield star, np.where(rows[keep] == m, v, rows[keep])[None]


def flip_slivers(p: np.ndarray, t: np.ndarray, faces: np.ndarray, comp: np.ndarray,
                 threshold: float, bound: float):
    """:func:`flip_improve` of the tetrahedra under ``bound`` degrees of a one-phase mesh,
    every new tetrahedron's delta over the vertex compositions ``comp`` below ``threshold``
    (the boundary triangles ``faces`` stay), the vertices no longer used dropped:
    ``(points, tets, faces, comp)``."""
    t, _ = flip_improve(p, t, np.zeros(len(t), dtype=np.int64),
                        lambda tets, phase: delta_vertices(comp, tets) < threshold,
                        bound=bound)
    return drop_unused(p, t, faces, point_data=(comp,))[:4]


def flip_improve(p: np.ndarray, t: np.ndarray, phase: np.ndarray,
                 ok: Callable[[np.ndarray, np.ndarray], np.ndarray], *,
                 bound: float = 20.0, passes: int = 8,
                 measure: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Face flips, edge removals and collapses of inner vertices (see the module
    docstring) of the tetrahedra whose quality ``measure(points, tets)`` (default: the
    smallest dihedral angle, degrees; larger is better) is below ``bound``, the worst
    first, in up to ``passes`` passes (in each, a tetrahedron takes part in one
    replacement at most; of a tetrahedron's replacements, the one whose worst tetrahedron
    is best, if better than the worst of those it replaces; after the first pass, only the
    tetrahedra sharing a vertex with a replaced one or with one whose replacement another
    took the place of are tried again). ``ok(tets, phase)`` is the
    caller's check of candidate tetrahedra (True: acceptable). ``(tets, phase)``: the new
    tetrahedra, all positive, in a deterministic order; points of removed vertices are no
    longer referenced."""
    measure = min_dihedral if measure is None else measure
    t = np.asarray(t, np.int64)
    phase = np.asarray(phase, np.int64)
    dirty = np.ones(len(p), bool)  # the tetrahedra to try: those with a dirty vertex
    for _ in range(passes):
        dm = measure(p, t)
        bad = np.flatnonzero((dm < bound) & dirty[t].any(axis=1))
        if not len(bad):
            break
        bad = bad[np.argsort(dm[bad], kind="stable")]
        index = _Index(t, len(p))
        surface = _surface_points(t, phase, index, len(p))
        v_order = np.argsort(t.ravel(), kind="stable")
        v_keys = t.ravel()[v_order]

        def star_of(m: int, v_keys=v_keys, v_order=v_order) -> np.ndarray:
            lo, hi = np.searchsorted(v_keys, [m, m + 1])
            return v_order[lo:hi] // 4

        owner, olds, news = [], [], []
        for k in bad.tolist():
            for old, group in _candidates(t, phase, index, k, surface, star_of):
                owner.append(k)
                olds.append(old)
                news.append(group)
        if not news:
            break
        # every candidate: its group, its rows in ``rows``
        n_c = np.array([len(g) for g in news])
        n_k = np.array([g.shape[1] for g in news])
        group = np.repeat(np.arange(len(news)), n_c)
        sizes = n_k[group]
        offsets = np.r_[0, np.cumsum(sizes)]
        cand = np.repeat(np.arange(len(group)), sizes)
        rows = np.concatenate([g.reshape(-1, 4) for g in news])
        v = tet_volumes6(p, rows)
        flip = v < 0
        rows[flip] = rows[flip][:, [1, 0, 2, 3]]
        flat = np.abs(v) <= 1e-12 * np.abs(v).max()
        score = measure(p, rows)
        score[flat] = -np.inf
        cmin = np.full(len(group), np.inf)
        np.minimum.at(cmin, cand, score)
        before = np.array([dm[o].min() for o in olds])
        good = cmin > before[group]
        if not good.any():
            break
        owner_a = np.asarray(owner)
        sel = good[cand]
        fine = np.ones(len(group), bool)
        np.logical_and.at(fine, cand[sel], ok(rows[sel], phase[owner_a[group[cand[sel]]]]))
        take = np.flatnonzero(good & fine)
        # per tetrahedron, the best candidate first; tetrahedra worst first
        rank = np.empty(len(t), np.int64)
        rank[bad] = np.arange(len(bad))
        take = take[np.lexsort((take, -cmin[take], rank[owner_a[group[take]]]))]
        busy = np.zeros(len(t), bool)
        drop, add, add_phase = [], [], []
        # next pass: the tetrahedra around the replaced ones and those that were blocked
        dirty = np.zeros(len(p), bool)
        for c in take.tolist():
            old = olds[group[c]]
            if busy[old].any():
                dirty[t[owner_a[group[c]]]] = True
                continue
            new = rows[offsets[c]:offsets[c + 1]]
            if _oriented_faces(new) != _oriented_faces(t[old]):
                continue
            busy[old] = True
            dirty[t[old].ravel()] = True
            drop.append(old)
            add.append(new)
            add_phase.append(int(phase[owner_a[group[c]]]))
        if not drop:
            break
        keep = np.ones(len(t), bool)
        keep[np.concatenate(drop)] = False
        t = np.concatenate([t[keep]] + add)
        phase = np.concatenate([phase[keep]] + [np.full(len(a), f, np.int64)
                                                for a, f in zip(add, add_phase)])
    return t, phase
