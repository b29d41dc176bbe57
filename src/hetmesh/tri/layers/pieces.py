"""The connected pieces of the domain between interface curves."""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ...mesh import edge_keys
from ..workset import Context, WorkSet, edge_params, triangulate


class Pieces:
    """The connected pieces of the domain between interface curves (from the CDT of the
    initial PSLG work set), and which piece lies on either side of every curve point.

    Interface curves may carry a jump of f: rows and gradient paths stay in one piece, and
    each piece counts its levels from its own anchor (:func:`piece_levels`)."""

    def __init__(self, ctx: Context, ws: WorkSet):
        tris = triangulate(ws, ctx)
        n = ws.n
        nt = len(tris)
        # directed edges of the counter-clockwise triangles: a triangle is left of its edges
        a = tris[:, [0, 1, 2]].ravel()
        b = tris[:, [1, 2, 0]].ravel()
        tid = np.repeat(np.arange(nt), 3)
        key = a.astype(np.int64) * n + b
        order = np.argsort(key)
        skey = key[order]

        def left_of(u, v):  # the triangle left of the directed edge u -> v, or -1
            q = u.astype(np.int64) * n + v
            pos = np.minimum(np.searchsorted(skey, q), len(skey) - 1)
            return np.where(skey[pos] == q, tid[order[pos]], -1)

        nb = left_of(b, a)
        iface = ~ctx.boundary_curve[ws.ecurve]
        if iface.any():
            ik = edge_keys(ws.E[iface, 0], ws.E[iface, 1])
            cut = np.isin(edge_keys(a, b), ik)
        else:
            cut = np.zeros(len(a), bool)
        link = (nb >= 0) & ~cut
        if nt:
            g = coo_matrix((np.ones(int(link.sum())), (tid[link], nb[link])), shape=(nt, nt))
            self.n, lab = connected_components(g, directed=False)
        else:
            self.n, lab = 0, np.zeros(0, np.int64)
        lt = left_of(ws.E[:, 0], ws.E[:, 1])
        rt = left_of(ws.E[:, 1], ws.E[:, 0])
        pl = np.where(lt >= 0, lab[np.maximum(lt, 0)], -1)
        pr = np.where(rt >= 0, lab[np.maximum(rt, 0)], -1)
        et = edge_params(ws, ctx)
        up = et[:, 1] >= et[:, 0]  # E[:, 0] -> E[:, 1] runs along increasing t
        self._curves = []
        for k in range(len(ctx.curves)):
            s = np.flatnonzero(ws.ecurve == k)
            t0 = np.minimum(et[s, 0], et[s, 1])
            o = np.argsort(t0, kind="stable")
            s = s[o]
            left = np.where(up[s], pl[s], pr[s])
            right = np.where(up[s], pr[s], pl[s])
            self._curves.append((t0[o], left, right))

    def at(self, k: int, t: np.ndarray, side: int) -> np.ndarray:
        """Piece left (``side`` +1) or right (-1) of curve ``k`` at parameters ``t`` (-1: outside)."""
        t0, left, right = self._curves[k]
        if len(t0) == 0:
            return np.full(len(t), -1, np.int64)
        i = np.clip(np.searchsorted(t0, t, side="right") - 1, 0, len(t0) - 1)
        return (left if side > 0 else right)[i]

    def sides(self, k: int, ctx: Context):
        """The sides of curve ``k`` that face the domain: ``[(side, eval side)]``; f is
        evaluated on a boundary curve itself and just off an interface on each side."""
        if ctx.boundary_curve[k]:
            mid = np.array([0.5])
            inner = 1 if self.at(k, mid, 1)[0] >= 0 else -1
            return [(inner, 0)]
        return [(1, 1), (-1, -1)]
