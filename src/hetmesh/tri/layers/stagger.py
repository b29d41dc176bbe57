"""Staggering adjacent rows: every apex above the midpoint of the edge it faces.

The last step of the placement. A triangle with two nodes on one row and its apex on the
next is equilateral, q(T) = 1 (the paper, Eq. 17), when the apex sits above the midpoint of
the other two; rows traced independently have a random phase between them.
"""

from __future__ import annotations

import numpy as np

from ...parallel import block_map, blocks
from ...topology import any_corner, index_columns, unique
from .. import cvt
from ..workset import FREE, Context, WorkSet, slide_along_rows, triangulate

#: the stagger iterations of :func:`~hetmesh.tri.layers.assemble.place_layers`
STAGGER_ITERS = 8


def midpoints(P: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The midpoints of the segments ``(P[a], P[b])``, as x and y columns (``0.5 * (P[a] +
    P[b])``, the same numbers), by blocks."""
    mx, my = np.empty(len(a)), np.empty(len(a))

    def block(s):
        ia, ib = a[s], b[s]
        mx[s] = 0.5 * (P[ia, 0] + P[ib, 0])
        my[s] = 0.5 * (P[ia, 1] + P[ib, 1])

    block_map(block, len(a))
    return mx, my


def stagger(ws: WorkSet, ctx: Context, tris: np.ndarray, dprime: float, iters: int = 6,
            relax: float = 0.8) -> np.ndarray:
    """Stagger neighbouring rows: each row node slides towards the midpoint of the two nodes
    of the adjacent row that it faces.

    In a triangle with two nodes a, b on one row and its apex c on the next row, the
    triangle is equilateral when c sits above the midpoint of ab. With independent rows the
    phase between rows is random, which caps q_avg at ~0.939 (the mean of q over a uniform
    apex offset); the conforming Lloyd step does not correct it. Here every apex collects the
    midpoints it faces (usually two: one from the row below, one from the row above) and
    moves along its row towards their mean, then back onto its level (Newton); moves are
    limited to the vertex's star. Returns the new triangles.
    """
    lv_all = unique(ws.level[np.isfinite(ws.level)])
    # index of every node's level among all the levels carried (intermediate levels)
    lvi = np.searchsorted(lv_all, np.nan_to_num(ws.level, nan=np.inf))

    def facing(tris):
        """(apex, a, b) index arrays of the row-to-row triangles, and the movable apexes."""
        parts = []
        cols = index_columns(tris)
        lev = [ws.level[c] for c in cols]
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3
            # a row edge (a, b: one level) and an apex on another level
            r = np.flatnonzero(lev[a] == lev[b])
            ta, tc = cols[a][r], cols[k][r]
            la, lc = ws.level[ta], ws.level[tc]
            gap = np.abs(lc - la)
            ok = (np.isfinite(la) & np.isfinite(lc)
                  & ((np.abs(gap - dprime) < 1e-6 * dprime)
                     | ((gap < dprime) & (np.abs(lvi[tc] - lvi[ta]) == 1))))
            parts.append(tris[r[ok]][:, [k, a, b]])
        fac = np.concatenate(parts)
        # row ends next to the boundary keep their place: moving them squeezes boundary triangles
        near_bnd = np.zeros(ws.n, bool)
        near_bnd[tris[any_corner(ws.vcurve != FREE, tris)].ravel()] = True
        cnt = np.bincount(fac[:, 0], minlength=ws.n)
        mov = np.isfinite(ws.level) & ~ws.pinned & (cnt > 0) & ~near_bnd
        return fac, cnt, mov

    fac, cnt, mov = facing(tris)
    for it in range(iters):
        if not mov.any():
            break
        with ctx.timed("stagger"):
            mx, my = midpoints(ws.P, fac[:, 1], fac[:, 2])
            im = np.flatnonzero(mov)
            tx = np.bincount(fac[:, 0], mx, minlength=ws.n)[im]
            ty = np.bincount(fac[:, 0], my, minlength=ws.n)[im]
            target = ws.P.copy()
            for b in blocks(len(im)):  # by blocks of row nodes: no arrays over all of them
                i = im[b]
                target[i] = slide_along_rows(ctx, ws.P[i],
                                             np.column_stack([tx[b], ty[b]]) / cnt[i, None],
                                             ws.level[i], relax=relax, iters=2)
            ws.P = cvt.limit_to_star(ws.P, tris, target, mov, halvings=2)
        if (it + 1) % 4 == 0 or it == iters - 1:  # between rebuilds the star limit keeps it valid
            tris = triangulate(ws, ctx)
            fac, cnt, mov = facing(tris)
    return tris
