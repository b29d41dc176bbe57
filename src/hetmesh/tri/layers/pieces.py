"""The connected pieces of the domain between interface curves.

Interface curves may carry a jump of f: rows and gradient paths stay in one piece, and each
piece counts its levels from its own anchor (:func:`~hetmesh.tri.layers.levels.piece_levels`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ...topology import edge_keys
from ..workset import Context, WorkSet, edge_params, triangulate

#: the piece index of a point that lies in no piece (beyond the domain's side of a boundary)
OUTSIDE: Final = -1


@dataclass(frozen=True)
class CurveSides:
    """The pieces along one curve, run by run: the run of work-set edge ``i`` starts at
    parameter ``t0[i]`` (sorted) and has piece ``left[i]`` on its left and ``right[i]`` on
    its right (with respect to increasing t; :data:`OUTSIDE` where the domain is not)."""

    t0: np.ndarray
    left: np.ndarray
    right: np.ndarray


def directed_edge_key(u: np.ndarray, v: np.ndarray, n: int) -> np.ndarray:
    """The directed edge ``u -> v`` between nodes of ``n`` as one integer, ``u * n + v``
    (exact, and unequal to ``v -> u`` unless u = v)."""
    return u.astype(np.int64) * n + v


class Pieces:
    """The connected pieces of the domain between interface curves (from the CDT of the
    initial PSLG work set), and which piece lies on either side of every curve point.

    Attributes
    ----------
    n : the number of pieces; they are numbered 0 .. n - 1.
    """

    def __init__(self, ctx: Context, ws: WorkSet):
        tris = triangulate(ws, ctx)
        n = ws.n
        nt = len(tris)
        # directed edges of the counter-clockwise triangles: a triangle is left of its edges
        a = tris[:, [0, 1, 2]].ravel()
        b = tris[:, [1, 2, 0]].ravel()
        tid = np.repeat(np.arange(nt), 3)
        key = directed_edge_key(a, b, n)
        order = np.argsort(key)
        skey = key[order]

        def left_of(u, v):
            """The triangle left of every directed edge u -> v, and whether there is one."""
            q = directed_edge_key(u, v, n)
            pos = np.minimum(np.searchsorted(skey, q), len(skey) - 1)
            return tid[order[pos]], skey[pos] == q

        nb, has_nb = left_of(b, a)
        iface = ~ctx.boundary_curve[ws.ecurve]
        if iface.any():
            ik = edge_keys(ws.E[iface, 0], ws.E[iface, 1])
            cut = np.isin(edge_keys(a, b), ik)
        else:
            cut = np.zeros(len(a), bool)
        link = has_nb & ~cut
        if nt:
            g = coo_matrix((np.ones(int(link.sum())), (tid[link], nb[link])), shape=(nt, nt))
            self.n, lab = connected_components(g, directed=False)
        else:
            self.n, lab = 0, np.zeros(0, np.int64)
        lt, has_lt = left_of(ws.E[:, 0], ws.E[:, 1])
        rt, has_rt = left_of(ws.E[:, 1], ws.E[:, 0])
        pl = np.where(has_lt, lab[lt], OUTSIDE)
        pr = np.where(has_rt, lab[rt], OUTSIDE)
        et = edge_params(ws, ctx)
        up = et[:, 1] >= et[:, 0]  # E[:, 0] -> E[:, 1] runs along increasing t
        self._curves: list[CurveSides] = []
        for k in range(len(ctx.curves)):
            s = np.flatnonzero(ws.ecurve == k)
            t0 = np.minimum(et[s, 0], et[s, 1])
            o = np.argsort(t0, kind="stable")
            s = s[o]
            self._curves.append(CurveSides(t0[o], left=np.where(up[s], pl[s], pr[s]),
                                           right=np.where(up[s], pr[s], pl[s])))

    def at(self, k: int, t: np.ndarray, side: int) -> np.ndarray:
        """The piece left (``side`` +1) or right (-1) of curve ``k`` at parameters ``t``
        (:data:`OUTSIDE` where the domain is not there)."""
        cs = self._curves[k]
        if len(cs.t0) == 0:
            return np.full(len(t), OUTSIDE, np.int64)
        i = np.clip(np.searchsorted(cs.t0, t, side="right") - 1, 0, len(cs.t0) - 1)
        return (cs.left if side > 0 else cs.right)[i]

    def sides(self, k: int, ctx: Context) -> list[tuple[int, int]]:
        """The sides of curve ``k`` that face the domain: ``[(side, eval side)]``, ``side``
        +1 / -1 for left / right of increasing t; f is evaluated on a boundary curve itself
        (eval side 0, :func:`~hetmesh.tri.layers.curves.side_points`) and just off an
        interface on each side."""
        if ctx.boundary_curve[k]:
            mid = np.array([0.5])
            inner = 1 if self.at(k, mid, 1)[0] != OUTSIDE else -1
            return [(inner, 0)]
        return [(1, 1), (-1, -1)]
