"""Node placement on iso-composition curves ("layers"): MOR's start for two constituents.

Why: delta(T) of a small element is |grad f| times its extent along the gradient. A CVT spreads
that extent by ~1.4 between elements, so an isotropic CVT cannot go much below ~1.2 x N_iso
elements. Rows of nodes on the level curves f = c_k, c_k = anchor -/+ k * beta * delta_0,
with spacing 2 w / sqrt(3) along each row (w = beta * delta_0 / |grad f| the row distance),
make near-equilateral triangles whose vertices sit on two adjacent rows, so every such triangle
has delta(T) = beta * delta_0 exactly: the threshold is used to the full (about 0.75-0.9 x N_iso
elements). The rows are traced from where the level curves cross the boundary (predictor step
along the tangent, Newton corrector back onto the level); a row that runs from curve to curve
then gets its nodes re-spaced so that it is in phase with its neighbours (a node count shared
by adjacent rows, alternate rows starting a full and a half spacing from the curve,
:func:`_respace_rows`; closed rows likewise from their seeds). Where |grad f| -> 0 at a border
or an extremum the last band of rows is much higher than its neighbours: it gets
intermediate levels, graded from both ends, and the rows next to it a node step that
matches their bands (:func:`_grade_levels`); what no level covers is filled by
circumcenter insertion to the maximum size; nodes then slide along their rows (conforming
Lloyd, :func:`hetmesh.tri.workset.smooth`) and the shared repair loop of :mod:`hetmesh.tri.adapt`
fixes whatever is left, so the guarantee does not depend on this placement.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .geometry import pslg_from_parameters
from ..mesh import any_corner, edge_keys
from ..metrics import circumcircles, corner_columns, signed_area2
from . import cvt
from ..density import background_points, estimate_elements
from ..parallel import BLOCK, block_concat, block_map, blocks
from .workset import (FREE, Context, WorkSet, add_free_points, edge_params, project_to_level,
                     row_tangent,
                     slide_along_rows, smooth, thin_candidates_mask, triangulate,
                     workset_from_pslg)

__all__ = ["place_layers"]

log = logging.getLogger(__name__)

STAGGER_ITERS = 8

#: a node projected onto its level is kept if |f - level| <= LEVEL_TOL x the row spacing in f
LEVEL_TOL = 0.05


def _row_step(ctx: Context, gnorm: np.ndarray, dprime: float, h_cap=None) -> np.ndarray:
    """Node spacing along a row, 2 w / sqrt(3) with w = delta' / |grad f|, between h_min and
    ``h_cap`` (default h_max; where |grad f| is infinite, nan or zero too)."""
    h_cap = ctx.h_max if h_cap is None else h_cap
    with np.errstate(divide="ignore", invalid="ignore"):
        s = 2.0 * dprime / (np.sqrt(3.0) * gnorm)
    s = np.nan_to_num(s, nan=ctx.h_max, posinf=ctx.h_max)
    return np.clip(s, ctx.h_min, h_cap)


def _row_step_at(ctx: Context, pts: np.ndarray, dprime, grad: np.ndarray | None = None
                 ) -> np.ndarray:
    """:func:`_row_step` at ``pts`` (``grad``: grad f there, if known), for the gradient
    capped by the context (:meth:`Context.cap_at`); pointwise, so by blocks of points."""
    if len(pts) > BLOCK:
        dp = np.broadcast_to(dprime, (len(pts),))
        return block_concat(lambda s: _row_step_at(ctx, pts[s], dp[s],
                                                   None if grad is None else grad[s]),
                            len(pts), serial=True)
    gr = ctx.grad_f(pts) if grad is None else grad
    gn = np.minimum(np.nan_to_num(np.linalg.norm(gr, axis=1), nan=np.inf), ctx.cap_at(pts))
    return _row_step(ctx, gn, dprime, ctx.h_at(pts))


def _anchor(ctx: Context) -> float:
    """The level the rows count from: the extreme value of f that the boundary holds over
    the longer stretch (a boundary that is a level curve is a row).
    The fallback of pieces without a level curve on their border (:func:`_piece_levels`)."""
    dom = ctx.domain
    ts = np.linspace(0, 1, 401)
    bpts, blen = [], []
    for c, isb in zip(ctx.curves, ctx.boundary_curve):
        if isb:
            bpts.append(c.point(ts))
            blen.append(np.full(len(ts), c.length / len(ts)))
    bpts = np.concatenate(bpts)
    blen = np.concatenate(blen)
    ipts = background_points(dom, 200)
    f_all = ctx.f(np.vstack([bpts, ipts]))
    fmin, fmax = float(f_all.min()), float(f_all.max())
    fb = ctx.f(bpts)
    tol = 1e-9
    at_max = blen[np.abs(fb - fmax) < tol].sum()
    at_min = blen[np.abs(fb - fmin) < tol].sum()
    return fmax if at_max >= at_min else fmin


def _left_normal(c, t: np.ndarray) -> np.ndarray:
    tg = c.tangent(t)
    return np.column_stack([-tg[:, 1], tg[:, 0]])


def _side_eps(ctx: Context) -> float:
    """How far off an interface f is evaluated for one side of it (f may jump across)."""
    return 1e-5 * ctx.domain.diameter


def _side_points(ctx: Context, k: int, t: np.ndarray, side: int) -> np.ndarray:
    """Points of curve ``k`` at parameters ``t``; ``side`` +1/-1: just off it, to the left /
    right of the direction of increasing t; 0: on it."""
    c = ctx.curves[k]
    p = c.point(t)
    if side:
        p = p + (side * _side_eps(ctx)) * _left_normal(c, t)
    return p


class _Pieces:
    """The connected pieces of the domain between interface curves (from the CDT of the
    initial PSLG work set), and which piece lies on either side of every curve point.

    Interface curves may carry a jump of f: rows and gradient paths stay in one piece, and
    each piece counts its levels from its own anchor (:func:`_piece_levels`)."""

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


_STRIDE = 8.0  # level keys: piece * _STRIDE + level (levels lie within (-2, 3))


def _piece_levels(ctx: Context, pieces: _Pieces, dprime: float):
    """The row levels of every piece, as sorted keys ``piece * _STRIDE + level`` and levels.

    A piece counts its levels ``anchor -/+ k * dprime`` from the level curve on its border
    that carries the most row nodes (the largest integral of |grad f| along it: the rows
    next to it keep their full spacing where elements are smallest); without one, from the
    boundary's extreme value (:func:`_anchor`). Levels closer than 0.02 dprime to another
    level curve of the border are dropped (they would run along it), and where the last
    level before another level curve leaves a gap under dprime / 4, the last two gaps are
    evened out instead of leaving a thin strip. A border along which f varies by less than
    dprime / 4 (nearly a level curve: fgm_plate's top edge, f 0.991-0.994) is evened
    against too (at its median value), but it is no anchor: a level 0.007 below it lay too
    close to the border for its row step to be kept, so the flat top was left to the fill
    and the repair loop (fgm_plate 0.1: 2,089 -> 1,828 elements, delta_avg/delta_0
    0.71 -> 0.79)."""
    a0 = _anchor(ctx)
    ts = (np.arange(400) + 0.5) / 400
    holders = [[] for _ in range(pieces.n)]
    near = [[] for _ in range(pieces.n)]  # borders that are nearly level curves (evening only)
    vals = []
    for k, c in enumerate(ctx.curves):
        for side, ev in pieces.sides(k, ctx):
            pc = pieces.at(k, ts, side)
            f = ctx.f(_side_points(ctx, k, ts, ev))
            vals.append(f)
            for p in np.unique(pc[pc >= 0]):
                m = pc == p
                if m.sum() < 0.9 * len(ts):
                    continue
                if np.ptp(f[m]) > 1e-7:
                    if np.ptp(f[m]) < 0.25 * dprime:
                        near[p].append(float(np.median(f[m])))
                    continue
                g = np.linalg.norm(ctx.grad_f(_side_points(ctx, k, ts[m], ev)), axis=1)
                holders[p].append((float(g.sum() * c.length / len(ts)), c.length, float(f[m].mean())))
    vals.append(ctx.f(background_points(ctx.domain, 100)))
    vals = np.concatenate(vals)
    lo, hi = max(float(vals.min()) - dprime, -1.9), min(float(vals.max()) + dprime, 2.9)
    keys, levs, dps = [], [], []
    for p in range(pieces.n):
        hs = sorted(holders[p], key=lambda h: (-h[0], -h[1]))
        if hs:
            a = hs[0][2]
            if abs(a - a0) < 1e-7:
                a = a0  # the boundary's own value (bit-identical rows)
        else:
            a = a0
        kdn = np.arange(1, int(np.floor((a - lo) / dprime)) + 1)
        kup = np.arange(1, int(np.floor((hi - a) / dprime)) + 1)
        L = np.concatenate([a - kdn[::-1] * dprime, a + kup * dprime])
        hv = np.array([h[2] for h in hs]) if hs else np.zeros(0)
        if len(hv):
            L = L[np.abs(L[:, None] - hv[None, :]).min(axis=1) > 0.02 * dprime]
        ev = np.concatenate([hv, near[p]]) if near[p] else hv
        for v in ev[np.abs(ev - a) > 0.02 * dprime]:
            between = np.flatnonzero((L > min(a, v)) & (L < max(a, v)))
            if len(between) == 0:
                continue
            j = len(between)
            last, nxt = (between[-1], between[max(j - 2, 0)]) if v > a else \
                (between[0], between[min(1, j - 1)])
            if abs(v - L[last]) < 0.25 * dprime:
                prev = L[nxt] if len(between) > 1 else a
                L[last] = 0.5 * (prev + v)
        L = np.sort(L)
        keys.append(p * _STRIDE + L)
        levs.append(L)
        dps.append(np.full(len(L), dprime))  # each row's spacing in f (traced with it)
    if not keys:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    return np.concatenate(keys), np.concatenate(levs), np.concatenate(dps)


GRADE = 0.35  # growth of the band height per unit length where flat zones are subdivided
_MAX_RATIO = 1.5  # a piece's end band up to this many times the height wanted is left whole


def _path_starts(ctx: Context, pieces: _Pieces, most: int):
    """Start points of gradient paths: 4..``most`` points per curve (about two per h_max),
    just off the curve on each side that lies in a piece. Returns lists of point arrays,
    their pieces and their curves."""
    starts, spc, scv = [], [], []
    for k, c in enumerate(ctx.curves):
        n = int(np.clip(np.ceil(2 * c.length / ctx.h_max), 4, most))
        ts = (np.arange(n) + 0.5) / n
        for side in (1, -1):
            pc = pieces.at(k, ts, side)
            ok = pc >= 0
            if ok.any():
                starts.append(_side_points(ctx, k, ts[ok], side))
                spc.append(pc[ok])
                scv.append(np.full(int(ok.sum()), k))
    return starts, spc, scv


def _two_way_starts(ctx: Context, pieces: _Pieces, most: int):
    """The gradient paths' starts inside the domain, each twice (ascent then descent):
    ``(points, direction +1/-1, piece, start curve)``, or None if there are none."""
    starts, spc, scv = _path_starts(ctx, pieces, most)
    if not starts:
        return None
    x, pc, cv = np.vstack(starts), np.concatenate(spc), np.concatenate(scv)
    ok = ctx.inside(x)
    x, pc, cv = x[ok], pc[ok], cv[ok]
    dirn = np.repeat([1.0, -1.0], len(x))
    return np.vstack([x, x]), dirn, np.concatenate([pc, pc]), np.concatenate([cv, cv])


def _gradient_walk(ctx: Context, x: np.ndarray, dirn: np.ndarray, step: float, cap: float,
                   max_steps: int):
    """Steepest ascent (``dirn`` +1) or descent (-1) from the points ``x``, in steps of
    min(step / |grad f|, cap), until f stops changing monotonically, the path leaves the
    domain or crosses an interface. Yields, per step, for the live paths: ``(ids, x, f,
    |grad f|, next x, next f, ok, step length)``, ``ok`` telling which paths go on."""
    ids = np.arange(len(x))
    f = ctx.f(x)
    for _ in range(max_steps):
        if len(x) == 0:
            return
        g = ctx.grad_f(x)
        gn = np.linalg.norm(g, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ds = np.minimum(step / gn, cap)
            xn = x + (dirn * ds / gn)[:, None] * g
        good = gn > 1e-14
        xn = np.where(good[:, None], xn, x)
        fn = ctx.f(xn)
        ok = good & ctx.inside(xn) & (dirn * (fn - f) > 0)
        ok &= ~_crosses_interface(ctx, x, xn)
        yield ids, x, f, gn, xn, fn, ok, ds
        ids, x, f, dirn = ids[ok], xn[ok], fn[ok], dirn[ok]


def _profiles(ctx: Context, pieces: _Pieces, dprime: float):
    """Gradient paths through every piece, as samples: steepest ascent and descent started
    just inside every curve, on each side, until f stops changing monotonically, the path
    leaves the domain or meets an interface. Returns (path id, arc length s, f, x, g) of the
    samples in path order and, per path, (piece, start curve, direction)."""
    start = _two_way_starts(ctx, pieces, 32)
    if start is None:
        return None
    x, dirn, pc, cv = start
    npath = len(x)
    s = np.zeros(npath)
    out = []
    max_steps = int(1.5 / dprime + 14 * ctx.domain.diameter / ctx.h_max + 100)
    for ids, xs, f, gn, _, _, ok, ds in _gradient_walk(ctx, x, dirn, dprime, 0.08 * ctx.h_max,
                                                        max_steps):
        out.append((ids, s[ids], f, xs, gn))
        s[ids[ok]] += ds[ok]
    P = np.concatenate([o[0] for o in out])
    order = np.argsort(P, kind="stable")
    cat = [np.concatenate([o[j] for o in out])[order] for j in range(5)]
    return cat, (pc, cv, dirn)


def _grade_levels(ctx: Context, pieces: _Pieces, keys, levs, dps, dprime: float,
                  chord_tol: float):
    """Subdivide the bands between rows that are much higher than their neighbours.

    Where |grad f| tends to 0 (a boundary where f ~ d^2 or d^3, an extremum) consecutive
    levels lie far apart: the band between them is higher than its neighbours and than the
    maximum element size, the rows on either side of it have node steps that do not match
    it, and circumcenter filling plus repair made poor elements there. Here the band
    heights are measured along gradient paths; a band at a piece's end (between its last
    level and a border that is a level curve, or an extremum) whose height H exceeds
    ``_MAX_RATIO`` times the height wanted at its ends (the neighbouring band's height, or
    the boundary's own node spacing), and any band above 1.3 x sqrt(3)/2 h_max, gets
    intermediate levels so that the band heights grow
    by ``GRADE`` per unit length from both ends, up to sqrt(3)/2 h_max. The intermediate
    levels are taken on the path of median height; each new row and each row next to a
    subdivided band gets the spacing in f (``dps``) that makes its node step 2/sqrt(3) times
    the mean height of its two bands, and so does a row next to a level that is not dprime
    away (evened out by :func:`_piece_levels`); a border level curve gets the node spacing of
    its sub-band (curve spacing caps). hft_ring at 0.1: q_avg of the placement 0.91 -> 0.94,
    repair insertions 614 -> 77. Returns (keys, levs, dps, curve spacing caps)."""
    ncurve = len(ctx.curves)
    spacing = np.full(ncurve, np.inf)
    prof = _profiles(ctx, pieces, dprime)
    if prof is None or len(keys) == 0:
        return keys, levs, dps, spacing
    (pid, s, f, x, gn), (ppc, pcv, pdir) = prof
    nk = len(keys)
    piece_of = np.floor((keys + 2.0) / _STRIDE).astype(np.int64)  # levels lie in (-2, 3)
    kx = np.searchsorted(keys, ppc[pid] * _STRIDE + f, side="right")
    # crossings between consecutive samples of one path
    i = np.flatnonzero((pid[1:] == pid[:-1]) & (kx[1:] != kx[:-1]))
    lo = np.minimum(kx[i], kx[i + 1])
    cnt = np.abs(kx[i + 1] - kx[i])
    ii = np.repeat(i, cnt)
    kk = np.repeat(lo, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    u = np.clip((levs[kk] - f[ii]) / (f[ii + 1] - f[ii]), 0.0, 1.0)
    cs = s[ii] + u * (s[ii + 1] - s[ii])
    cg = gn[ii] + u * (gn[ii + 1] - gn[ii])
    cpid = pid[ii]
    # the levels a piece really holds: those its paths cross (the level list overshoots)
    if len(kk) == 0:
        return keys, levs, dps, spacing
    first = np.full(pieces.n, nk, np.int64)
    last = np.full(pieces.n, -1, np.int64)
    np.minimum.at(first, ppc[cpid], kk)
    np.maximum.at(last, ppc[cpid], kk)
    # events per path: start (-1), crossings (level index), end (-2); in path order
    starts = np.flatnonzero(np.r_[True, pid[1:] != pid[:-1]])
    ends = np.r_[starts[1:] - 1, len(pid) - 1]
    ep = np.concatenate([pid[starts], cpid, pid[ends]])
    es = np.concatenate([s[starts], cs, s[ends]])
    ek = np.concatenate([np.full(len(starts), -1), kk, np.full(len(ends), -2)])
    eg = np.concatenate([gn[starts], cg, gn[ends]])
    ef = np.concatenate([f[starts], levs[kk], f[ends]])
    o = np.lexsort((es, ep))
    ep, es, ek, eg, ef = ep[o], es[o], ek[o], eg[o], ef[o]
    # a path start or end is a piece end only where f is near the piece's extreme (not where
    # a path meets a boundary transverse to the rows)
    fmin = np.full(pieces.n, np.inf)
    fmax = np.full(pieces.n, -np.inf)
    np.minimum.at(fmin, ppc[pid], f)
    np.maximum.at(fmax, ppc[pid], f)
    pe = ppc[ep]
    lo_span = levs[np.minimum(first[pe], nk - 1)] - fmin[pe]
    hi_span = fmax[pe] - levs[np.maximum(last[pe], 0)]
    at_end = (ek < 0) & ((ef - fmin[pe] <= 0.15 * lo_span) | (fmax[pe] - ef <= 0.15 * hi_span))
    ek = np.where((ek < 0) & ~at_end, -3, ek)  # -3: a path end inside a band
    # consecutive events of a path: a band between levels (or a level and the path's end)
    same = ep[1:] == ep[:-1]
    a, b = ek[:-1][same], ek[1:][same]
    H = (es[1:] - es[:-1])[same]
    bp = ep[:-1][same]
    asc = pdir[bp] > 0
    pcb = ppc[bp]
    # a band id: 2 j + 1 between level j and j + 1 (j = first - 1 / last: the piece's ends)
    lvl_a = np.where(a >= 0, a, -1)
    lvl_b = np.where(b >= 0, b, -1)
    # the level index on the low side of the band (ascending: a, descending: b)
    low = np.where(asc, lvl_a, lvl_b)
    high = np.where(asc, lvl_b, lvl_a)
    low = np.where(low >= 0, low, np.where(high >= 0, high - 1, -10))
    high = np.where(high >= 0, high, low + 1)
    full = ((a >= 0) & (b >= 0)) | ((low == first[pcb] - 1) & (high >= 0)) | \
        ((high == last[pcb] + 1) & (low >= 0))
    full &= (a != -3) & (b != -3) & (high - low == 1) & (low >= first[pcb] - 1) & (high <= last[pcb] + 1)
    if not full.any():
        return keys, levs, dps, spacing
    band = (pcb * (nk + 2) + low + 1)[full]
    Hf, bpf = H[full], bp[full]
    ubands, inv = np.unique(band, return_inverse=True)
    nb = len(ubands)
    medH = np.array([np.median(Hf[inv == j]) for j in range(nb)])
    b_piece = ubands // (nk + 2)
    b_low = ubands % (nk + 2) - 1
    Hmap = dict(zip(ubands.tolist(), medH.tolist()))
    cap_h = np.sqrt(3.0) / 2.0 * ctx.h_max
    cstep = ctx.domain.curve_batch.max_step(chord_tol)

    def end_size(j, upper):
        """The band height wanted at one end of band j: its neighbour's, or the curve's
        spacing at a piece end (a boundary with a chord limit), or free (cap)."""
        p, lw = int(b_piece[j]), int(b_low[j])
        nbr = p * (nk + 2) + (lw + 2 if upper else lw)
        if nbr in Hmap and (lw + 1 <= last[p] if upper else lw >= first[p]):
            return Hmap[nbr]
        # a piece end: the curve the paths that start there start on
        m = np.flatnonzero(inv == j)
        m = m[(pdir[bpf[m]] < 0) if upper else (pdir[bpf[m]] > 0)]
        cur = pcv[bpf[m]]
        st = float(np.median(cstep[cur])) if len(cur) else np.inf
        return min(cap_h, np.sqrt(3.0) / 2.0 * st)

    if log.isEnabledFor(logging.DEBUG):  # (piece, low level, height, wanted at both ends)
        log.debug("bands %s", [(int(b_piece[j]), int(b_low[j]), round(float(medH[j]), 3),
                                round(end_size(j, False), 3), round(end_size(j, True), 3))
                               for j in range(nb)])
    new_l, new_d, new_k = [], [], []
    row_d = {}
    for j in range(nb):
        Hj = medH[j]
        ha, hb = end_size(j, False), end_size(j, True)
        p_, lw = int(b_piece[j]), int(b_low[j])
        inner = first[p_] <= lw and lw + 1 <= last[p_]
        # a band between two levels is split only above the largest element's size (on
        # fgm_plate splitting bands 2.5 x their neighbours' height cost 20 % more elements)
        if (inner or Hj <= _MAX_RATIO * min(ha, hb, cap_h)) and Hj <= cap_h * 1.3:
            continue
        # sizes grow by GRADE from both ends: sigma(t) = min(ha + G t, hb + G (H - t), cap)
        t = np.linspace(0.0, Hj, 401)
        sig = np.minimum(np.minimum(ha + GRADE * t, hb + GRADE * (Hj - t)), cap_h)
        N = np.concatenate([[0.0], np.cumsum(0.5 * (1 / sig[1:] + 1 / sig[:-1]) * np.diff(t))])
        m = int(max(1, round(N[-1])))
        if m < 2:
            continue
        pos = np.interp((np.arange(1, m) / m) * N[-1], N, t)  # sub-band boundaries
        # the path of median height: f and |grad f| along it
        mm = np.flatnonzero(inv == j)
        rep = bpf[mm[np.argsort(Hf[mm])[len(mm) // 2]]]
        sel = pid == rep
        ps, pf, pg = s[sel], f[sel], gn[sel]
        # where the band starts on that path: the low level's crossing (or the path start)
        asc_r = pdir[rep] > 0
        if lw >= first[p_]:
            flo = levs[lw]
        else:
            flo = pf[0] if asc_r else pf[-1]
        if asc_r:
            sub_s = (np.interp(flo, pf, ps) if lw >= first[p_] else ps[0]) + pos
        else:  # descending path: f decreases along s
            sub_s = (np.interp(-flo, -pf, ps) if lw >= first[p_] else ps[-1]) - pos
        sub_f = np.interp(sub_s, ps, pf)
        sub_g = np.interp(sub_s, ps, pg)
        hs = np.diff(np.concatenate([[0.0], pos, [Hj]]))  # sub-band heights, low to high
        ok = (np.diff(np.concatenate([[flo], sub_f])) > 1e-12 * max(1.0, abs(flo)))
        ok &= np.isfinite(sub_g) & (sub_g > 1e-12)  # rows need a gradient to follow
        if not ok.all():
            continue
        new_l.append(sub_f)
        new_d.append(sub_g * 0.5 * (hs[:-1] + hs[1:]))
        new_k.append(p_ * _STRIDE + sub_f)
        # the rows bounding the band: their step follows the sub-band next to them
        for lvl, side, h_in in ((lw, 1, hs[0]), (lw + 1, 0, hs[-1])):
            if first[p_] <= lvl <= last[p_]:
                row_d.setdefault(lvl, {})[side] = h_in
        for upper in (False, True):  # a piece end: the border curve's node spacing
            if (lw + 1 > last[p_]) if upper else (lw < first[p_]):
                m_ = np.flatnonzero(inv == j)
                m_ = m_[(pdir[bpf[m_]] < 0) if upper else (pdir[bpf[m_]] > 0)]
                hend = 2.0 / np.sqrt(3.0) * (hs[-1] if upper else hs[0])
                for cur in np.unique(pcv[bpf[m_]]):
                    spacing[cur] = min(spacing[cur], hend)
    # the step of a row next to a subdivided band, or next to a level that is not dprime
    # away in f (evened out by _piece_levels), from the heights of its two bands, where
    # that differs from dprime / |grad f| by more than 15 %
    dps = dps.copy()
    for lvl in np.unique(kk):
        p = int(piece_of[lvl])
        nbl = [levs[j] for j in (lvl - 1, lvl + 1) if first[p] <= j <= last[p]]
        odd = any(abs(abs(v - levs[lvl]) - dprime) > 0.01 * dprime for v in nbl)
        if lvl not in row_d and not odd:
            continue
        sides = row_d.get(lvl, {})
        hh = [sides.get(side, Hmap.get(p * (nk + 2) + lvl + side)) for side in (0, 1)]
        hh = [h for h in hh if h is not None]
        if not hh:
            continue
        d = float(np.median(eg[ek == lvl])) * float(np.mean(hh))
        if np.isfinite(d) and d > 0.05 * dps[lvl] and abs(d / dps[lvl] - 1.0) > 0.15:
            dps[lvl] = d
    if not new_l:
        return keys, levs, dps, spacing
    keys = np.concatenate([keys] + new_k)
    levs = np.concatenate([levs] + new_l)
    dps = np.concatenate([dps] + new_d)
    o = np.argsort(keys, kind="stable")
    log.info("layers: %d intermediate levels in %d flat bands", len(o) - nk, len(new_l))
    return keys[o], levs[o], dps[o], spacing


def _crossings(ctx: Context, pieces: _Pieces, keys, levs, dps, dprime: float):
    """Where the level curves cross every curve, from the side of each piece along it:
    (curve id, t, level, side, piece, row spacing) arrays."""
    cid, tt, lv, sd, pc_out, dp_out = [], [], [], [], [], []
    for k, c in enumerate(ctx.curves):
        for side, ev in pieces.sides(k, ctx):
            n = 64
            ts = np.linspace(0, 1, n + 1)
            g = np.linalg.norm(ctx.grad_f(_side_points(ctx, k, ts, ev)), axis=1).max()
            # resolve the rows: at least 8 samples per row crossing
            n = int(min(200_000, max(256, 8 * c.length * g / dprime)))
            ts = np.linspace(0, 1, n + 1)
            f = ctx.f(_side_points(ctx, k, ts, ev))
            pc = pieces.at(k, ts, side)
            idx = np.searchsorted(keys, pc * _STRIDE + f, side="right")
            i = np.flatnonzero((idx[1:] != idx[:-1]) & (pc[1:] == pc[:-1]) & (pc[1:] >= 0))
            if i.size == 0:
                continue
            lo = np.minimum(idx[i], idx[i + 1])
            cnt = np.abs(idx[i + 1] - idx[i]).astype(np.int64)
            seg = np.repeat(i, cnt)
            kk = np.repeat(lo, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
            level = levs[kk]
            a, b = ts[seg], ts[seg + 1]
            fa = f[seg] - level
            for _ in range(40):  # bisection on t, vectorised
                m = 0.5 * (a + b)
                fm = ctx.f(_side_points(ctx, k, m, ev)) - level
                left = np.sign(fm) == np.sign(fa)
                a = np.where(left, m, a)
                fa = np.where(left, fm, fa)
                b = np.where(left, b, m)
            cid.append(np.full(len(a), k))
            tt.append(0.5 * (a + b))
            lv.append(level)
            sd.append(np.full(len(a), side))
            pc_out.append(pc[seg])
            dp_out.append(dps[kk])
    if not cid:
        z = np.zeros(0)
        return z.astype(np.int64), z, z, z.astype(np.int64), z.astype(np.int64), z
    return (np.concatenate(cid), np.concatenate(tt), np.concatenate(lv), np.concatenate(sd),
            np.concatenate(pc_out), np.concatenate(dp_out))


def _curve_params(ctx: Context, cid, tt, dprime, chord_tol, spacing=None):
    """Per-curve sorted parameters: 0, crossings, 1, and between them nodes at the local row
    step (and the chord tolerance, the per-curve ``spacing`` cap of :func:`_grade_levels`,
    and the minimum interval counts, of :mod:`geometry`)."""
    batch = ctx.domain.curve_batch
    chord_cap, nmin = batch.max_step(chord_tol), batch.min_intervals()
    cap = chord_cap
    if spacing is not None:
        cap = np.minimum(cap, spacing)
    out = []
    for k, c in enumerate(ctx.curves):
        t = np.sort(tt[cid == k])
        if len(t):  # drop crossings too close to the curve's ends or to each other
            s = _row_step_at(ctx, c.point(t), dprime)
            ok = np.minimum(t, 1 - t) * c.length > 0.3 * s
            t, s = t[ok], s[ok]
        if len(t) > 1:
            keep = np.ones(len(t), bool)
            keep[1:] = np.diff(t) * c.length > 0.3 * np.minimum(s[1:], s[:-1])
            t = t[keep]
        full = np.concatenate([[0.0], t, [1.0]])
        a, b = full[:-1], full[1:]
        h = np.minimum(_row_step_at(ctx, c.point(0.5 * (a + b)), dprime), cap[k])
        nseg = np.maximum(np.ceil((b - a) * c.length / (1.15 * h)), np.ceil(nmin[k] * (b - a)))
        # the chord tolerance is a bound, not a target: never a chord longer than its cap
        nseg = np.maximum(nseg, np.ceil((b - a) * c.length / chord_cap[k] * (1 - 1e-12)))
        nseg = np.maximum(nseg, 1).astype(np.int64)
        gap = np.repeat(np.arange(len(a)), nseg)
        step = np.arange(nseg.sum()) - np.repeat(np.cumsum(nseg) - nseg, nseg) + 1
        inner = a[gap] + step * ((b - a) / nseg)[gap]  # as np.linspace(a, b, nseg + 1)[1:]
        inner[np.cumsum(nseg) - 1] = b  # each gap ends exactly on its crossing (or 1)
        out.append((np.concatenate([[0.0], inner]), t))
    return out


def _pslg_workset(ctx: Context, params) -> WorkSet:
    """The work set for per-curve ``(parameters, pinned parameters)`` (curve ends shared)."""
    ts = [p[0] for p in params]
    offsets = np.r_[0, np.cumsum([len(x) for x in ts])]
    pslg = pslg_from_parameters(ctx.domain, offsets, np.concatenate(ts))
    return workset_from_pslg(pslg, [p[1] for p in params])


def _distances(ctx: Context, pts: np.ndarray):
    db = np.full(len(pts), np.inf)
    di = np.full(len(pts), np.inf)
    for c, isb in zip(ctx.curves, ctx.boundary_curve):
        d = c.distance(pts)
        if isb:
            db = np.minimum(db, d)
        else:
            di = np.minimum(di, d)
    return db, di


def _crosses_interface(ctx: Context, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    """Whether the steps ``xa -> xb`` cross an interface curve (rows and paths stop there)."""
    out = np.zeros(len(xa), bool)
    if len(xa) == 0 or ctx.boundary_curve.all():
        return out
    ln = np.linalg.norm(xb - xa, axis=1)
    for c, isb in zip(ctx.curves, ctx.boundary_curve):
        if isb:
            continue
        near = np.flatnonzero(c.distance(xb) <= ln * (1 + 1e-9))
        if near.size == 0:
            continue
        a, b = xa[near], xb[near]
        if hasattr(c, "radius"):  # circular arc: segment-circle intersections on the arc
            d = b - a
            m = a - np.asarray(c.center)
            A = (d * d).sum(1)
            B = 2 * (m * d).sum(1)
            C = (m * m).sum(1) - c.radius ** 2
            disc = B * B - 4 * A * C
            hit = np.zeros(len(near), bool)
            ok = (disc >= 0) & (A > 0)
            sq = np.sqrt(np.where(ok, disc, 0.0))
            for sgn in (-1.0, 1.0):
                u = (-B + sgn * sq) / np.where(A > 0, 2 * A, 1.0)
                on = ok & (u >= 0) & (u <= 1)
                y = a + u[:, None] * d
                hit |= on & (c.distance(y) < 1e-9 * c.radius + 1e-12)
        elif hasattr(c, "p0"):  # segment: proper segment-segment intersection
            p0 = np.broadcast_to(np.asarray(c.p0, float), a.shape)
            p1 = np.broadcast_to(np.asarray(c.p1, float), a.shape)
            hit = ((np.sign(signed_area2(p0, p1, a)) != np.sign(signed_area2(p0, p1, b)))
                   & (np.sign(signed_area2(a, b, p0)) != np.sign(signed_area2(a, b, p1))))
        else:  # any other curve: the side of the nearest curve point changes
            tb = c.project(b)
            pb, tg = c.point(tb), c.tangent(tb)
            sa = np.sign(tg[:, 0] * (a - pb)[:, 1] - tg[:, 1] * (a - pb)[:, 0])
            sb = np.sign(tg[:, 0] * (b - pb)[:, 1] - tg[:, 1] * (b - pb)[:, 0])
            hit = sa * sb < 0
        out[near] |= hit
    return out


def _trace_rows(ctx: Context, x0: np.ndarray, lev: np.ndarray, dirn: np.ndarray,
                dprime: np.ndarray, budget: int, ends: bool = False):
    """Trace the level curves f = ``lev`` from the points ``x0`` along ``dirn`` times their
    tangent (predictor-corrector) until they reach a boundary or interface curve, leave the
    domain, or close (back near their start); ``dprime`` is each row's spacing in f.
    Returns (points, levels, closed per start); the starts themselves are not returned.
    With ``ends``, also the trace of every point and, per start, where the trace stopped
    and whether it stopped next to a curve (the row's far end)."""
    closed_out = np.zeros(len(x0), bool)
    if len(x0) == 0:
        z = (np.zeros((0, 2)), np.zeros(0), closed_out)
        return z + (np.zeros(0, np.int64), np.zeros((0, 2)), closed_out.copy()) if ends else z
    x, lev, dirn = x0.copy(), lev.copy(), np.asarray(dirn, float)
    dpr = np.broadcast_to(np.asarray(dprime, float), lev.shape)
    out_p, out_l, out_i = [], [], []
    at_curve = np.zeros(len(x), bool)
    total = 0
    active = np.ones(len(x), bool)
    start = x.copy()
    back = x.copy()  # the previous point of every trace: a trace that turns back stops
    travelled = np.zeros(len(x))
    for step in range(100_000):
        if not active.any() or total > budget:
            break
        ia = np.flatnonzero(active)
        xa, la, da = x[ia], lev[ia], dirn[ia, None]
        g = ctx.grad_f(xa)
        gn = np.linalg.norm(g, axis=1)
        h = _row_step_at(ctx, xa, dpr[ia], grad=g)
        xm = xa + 0.5 * h[:, None] * da * row_tangent(g)  # midpoint predictor
        tm = da * row_tangent(ctx.grad_f(xm))
        xn = project_to_level(ctx, xa + h[:, None] * tm, la, iters=3)
        moved = np.linalg.norm(xn - xa, axis=1)
        inside = ctx.inside(xn)
        db, di = _distances(ctx, xn)
        ok = inside & (gn > 1e-12) & (moved > 0.2 * h) & (moved < 3 * h)
        ok &= ~_crosses_interface(ctx, xa, xn)
        ok &= (step == 0) | (np.linalg.norm(xn - back[ia], axis=1) > 0.3 * h)
        back[ia] = xa
        # closed level curves: stop when back near the start
        travelled[ia] += moved
        closed = (travelled[ia] > 3 * h) & (np.linalg.norm(xn - start[ia], axis=1) < 0.6 * h)
        closed_out[ia[closed]] = True
        keep_node = ok & (db > 0.55 * h) & (di > 0.55 * h) & ~closed
        out_p.append(xn[keep_node])
        out_l.append(la[keep_node])
        out_i.append(ia[keep_node])
        total += int(keep_node.sum())
        near = (db <= 0.3 * h) | (di <= 0.3 * h)
        cont = ok & ~closed & (~near | (step < 2))
        # where an open trace stops is its far end, if a crossing of its level lies there
        # (:func:`_respace_rows` checks): next to a curve, or a step from leaving its piece
        at_curve[ia] = ~cont & ~closed & (step >= 2)
        x[ia] = np.where(ok[:, None], xn, xa)
        active[ia[~cont]] = False
    at_curve &= ~active  # a trace cut short by the budget has no far end
    if not out_p:
        out = (np.zeros((0, 2)), np.zeros(0), closed_out)
        return out + (np.zeros(0, np.int64), x, at_curve) if ends else out
    out = (np.concatenate(out_p), np.concatenate(out_l), closed_out)
    return out + (np.concatenate(out_i), x, at_curve) if ends else out


def _gradient_seeds(ctx: Context, pieces: _Pieces, keys, levs, dps, dprime: float):
    """Points on the levels found along gradient lines (steepest ascent and descent paths
    started just inside every curve, on each side): they find the level curves that cross
    no curve at all (closed curves around a hole or an extremum). Returns (points, levels,
    row spacings, pieces), in the order of the paths (stable)."""
    start = _two_way_starts(ctx, pieces, 64)
    none = np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0, np.int64)
    if start is None:
        return none
    x, dirn, pc, _ = start
    kx = np.searchsorted(keys, pc * _STRIDE + ctx.f(x), side="right")
    out_p, out_l, out_d, out_i = [], [], [], []
    max_steps = int(4.0 / dprime + 8 * ctx.domain.diameter / ctx.h_max + 100)
    for ids, xs, f, _, xn, fn, ok, _ in _gradient_walk(ctx, x, dirn, 0.5 * dprime,
                                                        0.25 * ctx.h_max, max_steps):
        kn = np.searchsorted(keys, pc[ids] * _STRIDE + fn, side="right")
        kc = kx[ids]
        cr = np.flatnonzero(ok & (kn != kc))
        if cr.size:
            lo = np.minimum(kc[cr], kn[cr])
            cnt = np.abs(kn[cr] - kc[cr])
            i = np.repeat(cr, cnt)
            kk = np.repeat(lo, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
            L = levs[kk]
            u = (L - f[i]) / (fn[i] - f[i])
            p = xs[i] + u[:, None] * (xn[i] - xs[i])
            p, good = project_to_level(ctx, p, L, iters=3, tol=LEVEL_TOL * dps[kk])
            out_p.append(p[good])
            out_l.append(L[good])
            out_d.append(dps[kk][good])
            out_i.append(ids[i][good])
        kx[ids[ok]] = kn[ok]
    if not out_p:
        return none
    o = np.argsort(np.concatenate(out_i), kind="stable")
    path = np.concatenate(out_i)[o]
    return np.vstack(out_p)[o], np.concatenate(out_l)[o], np.concatenate(out_d)[o], pc[path]


def _known(rows: np.ndarray, rlev: np.ndarray, pts: np.ndarray, lev: np.ndarray,
           radius: np.ndarray) -> np.ndarray:
    """Which points have a row node of their own level within ``radius``."""
    if len(rows) == 0 or len(pts) == 0:
        return np.zeros(len(pts), bool)
    k = min(8, len(rows))
    d, j = cKDTree(rows).query(pts, k=k)
    d, j = d.reshape(len(pts), k), j.reshape(len(pts), k)
    same = np.abs(rlev[j] - lev[:, None]) <= 1e-9 * np.maximum(1.0, np.abs(lev[:, None]))
    return ((d < radius[:, None]) & same).any(axis=1)


def _place_rows(ctx: Context, pieces: _Pieces, keys, levs, dps, cross, dprime: float,
                budget: int):
    """All row nodes: traced inwards from the level crossings of the boundary and of both
    sides of every interface, then from the gradient-line seeds on levels not traced yet
    (one seed per level and round, until every seed lies next to a row of its level)."""
    cid, tt, lv, sd, pcs, cdp = cross
    rows, rlev = [np.zeros((0, 2))], [np.zeros(0)]
    if len(cid):
        isb = ctx.boundary_curve[cid]
        # an interface crossing starts just off the curve, on its piece's side: f and its
        # gradient may jump across (on the curve they are the other side's for about half of
        # fgm_plate's crossings, whose rows then were never traced)
        seeds = np.vstack([_side_points(ctx, int(k), np.array([t]), 0 if b else int(d))
                           for k, t, d, b in zip(cid, tt, sd, isb)])
        gr = ctx.grad_f(seeds)
        tau = row_tangent(gr)
        s = _row_step(ctx, np.linalg.norm(gr, axis=1), dprime, ctx.h_at(seeds))
        inward = np.zeros(len(cid), bool)
        if isb.any():  # boundary: the row starts where its tangent points into the domain
            inward[isb] = ctx.inside(seeds[isb] + 0.05 * s[isb, None] * tau[isb])
        for k in np.unique(cid[~isb]):  # interface: into the side the crossing was found on
            m = np.flatnonzero((cid == k) & ~isb)
            nrm = sd[m, None] * _left_normal(ctx.curves[k], tt[m])
            inward[m] = (tau[m] * nrm).sum(1) > 0
        ix = np.flatnonzero(inward)
        p, l, _, tid, xend, at_curve = _trace_rows(ctx, seeds[ix], lv[ix], np.ones(len(ix)),
                                                   cdp[ix], budget, ends=True)
        par = np.searchsorted(keys, pcs * _STRIDE + lv, side="left") % 2  # level parity
        p, l = _respace_rows(ctx, seeds, lv, pcs, cdp, par, ix, p, l, tid, xend, at_curve)
        rows.append(p)
        rlev.append(l)
    with ctx.timed("seeds"):
        sp, sl, sd_, spc = _gradient_seeds(ctx, pieces, keys, levs, dps, dprime)
    if len(sp):
        db, di = _distances(ctx, sp)
        h = _row_step_at(ctx, sp, sd_)
        far = (db > 0.55 * h) & (di > 0.55 * h)
        sp, sl, sd_, spc = sp[far], sl[far], sd_[far], spc[far]
    for _ in range(64):
        if len(sp) == 0 or sum(len(r) for r in rows) > budget:
            break
        R, RL = np.vstack(rows), np.concatenate(rlev)
        new = ~_known(R, RL, sp, sl, 0.75 * _row_step_at(ctx, sp, sd_))
        sp, sl, sd_, spc = sp[new], sl[new], sd_[new], spc[new]
        if len(sp) == 0:
            break
        # one seed per level: the first path's (seeds come in path order), so that the
        # seeds of nested closed rows lie on one gradient line and their phases agree
        _, first = np.unique(sl, return_index=True)
        pick = np.zeros(len(sp), bool)
        pick[first] = True
        x, l, d, pc = sp[pick], sl[pick], sd_[pick], spc[pick]
        sp, sl, sd_, spc = sp[~pick], sl[~pick], sd_[~pick], spc[~pick]
        p1, l1, closed, tid, _, _ = _trace_rows(ctx, x, l, np.ones(len(x)), d, budget,
                                                ends=True)
        p2, l2, _ = _trace_rows(ctx, x[~closed], l[~closed], -np.ones(int((~closed).sum())),
                                d[~closed], budget)
        rows += [x[~closed], p1[~closed[tid]], p2]
        rlev += [l[~closed], l1[~closed[tid]], l2]
        if closed.any():  # closed rows: re-spaced from their seed, in phase (_respace_rows)
            o = np.argsort(tid, kind="stable")
            loops = np.flatnonzero(closed)
            par = np.searchsorted(keys, pc * _STRIDE + l, side="left") % 2
            xl, ll = _even_nodes(ctx, _polylines(x[loops], x[loops], p1[o], tid[o], loops, closed),
                                 d[loops], l[loops], np.where(par[loops] == 0, 1.0, 0.5),
                                 closed=True)
            rows.append(xl)
            rlev.append(ll)
    return np.vstack(rows), np.concatenate(rlev)


#: ratio of the ladder of node counts of the rows that run from curve to curve (:func:`_respace_rows`)
LADDER = 1.1


def _respace_rows(ctx: Context, seeds, lv, pcs, cdp, par, ix, p, l, tid, xend, at_curve):
    """Re-place the nodes of the rows that run from curve to curve, in phase with their
    neighbours.

    Why: a row traced from its start at its own step 2 w / sqrt(3) starts every row with a
    node one step from the wall, so adjacent rows are in phase at the wall (apex above a
    vertex, not above an edge's midpoint), and since the step changes from row to row the
    phase between two rows drifts along them: sheared bands along the walls and diagonal
    lines of dislocations (power_plate 0.03: q_avg 0.950). Here a row's nodes are spaced
    evenly in units of its local step, with

    * the row's length in spacings, n, taken from its length in local steps U rounded to
      a rung of a geometric ladder (ratio :data:`LADDER`, so the spacing is within 5 % of
      the local step): adjacent rows on the same rung have the same n, their nodes sit at
      the same fractions of their lengths and the phase between them does not drift (an
      isosceles triangle 5 % wider than equilateral loses 0.0014 of q, an apex half a step
      off loses 0.18). Between parallel rows of equal length (the plates) that is a shared
      spacing; between nested arcs (round a hole) it is shared angles, the spacing
      growing with the radius until the next rung;
    * rows of even level index starting a full spacing from the curve at both ends and odd
      rows a half spacing: n - 1 and n nodes, as in a staggered lattice.

    ``ix`` are the starts traced (into the crossing arrays); ``p, l, tid`` the traced
    nodes, their levels and traces; ``xend, at_curve`` where each trace stopped and
    whether next to a curve. Rows whose far end is not a crossing of their own level and
    piece keep their traced nodes. Returns the new (points, levels)."""
    if len(p) == 0 or not at_curve.any():
        return p, l
    # the far end: the crossing of the same level and piece nearest to where the trace stopped
    h_end = _row_step_at(ctx, xend, cdp[ix])
    tree = cKDTree(seeds)
    d, j = tree.query(xend, k=min(6, len(seeds)))
    d, j = d.reshape(len(ix), -1), j.reshape(len(ix), -1)
    same = (np.abs(lv[j] - lv[ix, None]) <= 1e-12 * np.maximum(1.0, np.abs(lv[ix, None])))
    same &= (pcs[j] == pcs[ix, None]) & (j != ix[:, None]) & (d < 1.5 * h_end[:, None])
    has = at_curve & same.any(axis=1)
    far = j[np.arange(len(ix)), np.argmax(same, axis=1)]
    order = np.argsort(tid, kind="stable")
    p, l, tid = p[order], l[order], tid[order]
    rows = np.flatnonzero(has)
    if len(rows) == 0:
        return p, l
    lines = _polylines(seeds[ix[rows]], seeds[far[rows]], p, tid, rows, has)
    x, lev = _even_nodes(ctx, lines, cdp[ix[rows]], lv[ix[rows]],
                         np.where(par[ix[rows]] == 0, 1.0, 0.5), closed=False)
    keep = ~has[tid]
    return np.concatenate([p[keep], x]), np.concatenate([l[keep], lev])


def _polylines(first, last, p, tid, rows, has):
    """Row polylines ``(points, start offsets)``: ``first``, the traced nodes ``p`` of trace
    ``rows[r]`` in trace order (``tid`` sorted, ``has`` marking the traces kept), ``last``."""
    cnt = np.bincount(tid, minlength=len(has))[rows]
    starts = np.cumsum(np.r_[0, cnt + 2])
    pts = np.empty((starts[-1], 2))
    pts[starts[:-1]] = first
    pts[starts[1:] - 1] = last
    inner = np.flatnonzero(has[tid])
    r_of = np.searchsorted(rows, tid[inner])
    pos = starts[r_of] + 1 + (np.arange(len(inner)) - np.searchsorted(tid[inner], tid[inner]))
    pts[pos] = p[inner]
    return pts, starts


def _even_nodes(ctx: Context, lines, dprime, level, phi, closed: bool):
    """Nodes spaced evenly, in units of the local row step, along the polylines ``lines``
    (:func:`_polylines`) of rows with spacing ``dprime`` in f at ``level``: n spacings per
    row, n its length in local steps rounded to a rung of the ladder (:data:`LADDER`), the
    first node ``phi`` (1 or 1/2) spacings from the start. An open row gets n - 1 nodes
    (phi = 1) or n (phi = 1/2) and ends ``phi`` spacings before its end; a closed row
    (first point = last) gets n, phi = 1 meaning a node on its start. Returns (points,
    levels), projected onto the levels and inside the domain."""
    pts, starts = lines
    nrow = len(starts) - 1
    row = np.repeat(np.arange(nrow), np.diff(starts))
    seg = np.flatnonzero(row[1:] == row[:-1])
    mid = 0.5 * (pts[seg] + pts[seg + 1])
    du = np.linalg.norm(pts[seg + 1] - pts[seg], axis=1) / _row_step_at(ctx, mid, dprime[row[seg]])
    U = np.bincount(row[seg], du, minlength=nrow)
    n = np.maximum(np.round(LADDER ** np.round(np.log(np.maximum(U, 1.0)) / np.log(LADDER))), 1)
    a = U / n
    m = (n - ((phi == 1.0) & ~closed)).astype(np.int64)
    # targets in step units from each row's start, then points along its polyline
    rr = np.repeat(np.arange(nrow), m)
    jj = np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m)
    ut = a[rr] * (np.where(closed, phi % 1.0, phi)[rr] + jj)
    cu = np.zeros(len(pts))
    cu[seg + 1] = du
    cu = np.cumsum(cu)
    cu -= cu[starts[:-1]][row]
    span = 2.0 * (U.max() + 1)  # rows apart in one sorted key
    gk, tk = row * span + cu, rr * span + ut
    i = np.clip(np.searchsorted(gk, tk, side="right") - 1, starts[:-1][rr], starts[1:][rr] - 2)
    w = np.clip((tk - gk[i]) / np.maximum(gk[i + 1] - gk[i], 1e-300), 0.0, 1.0)
    x = pts[i] + w[:, None] * (pts[i + 1] - pts[i])
    lev = level[rr]
    x, ok = project_to_level(ctx, x, lev, iters=3, tol=LEVEL_TOL * dprime[rr])
    return x[ok], lev[ok]


def _level_dps(levs: np.ndarray, dps: np.ndarray, rlev: np.ndarray) -> np.ndarray:
    """The spacing in f of the rows at levels ``rlev`` (the smallest of equal levels)."""
    o = np.lexsort((dps, levs))
    lv, dp = levs[o], dps[o]
    i = np.clip(np.searchsorted(lv, rlev, side="left"), 0, len(lv) - 1)
    return dp[i]


def _fill(ws: WorkSet, ctx: Context, dprime: float, rounds: int = 30):
    """Fill flat zones: insert circumcenters of triangles larger than the local size."""
    for _ in range(rounds):
        tris = triangulate(ws, ctx)
        cc, R = circumcircles(ws.P, tris)
        cen = _centroids(ws.P, tris)
        hloc = _row_step_at(ctx, cen, dprime)
        big = R > 0.75 * hloc
        if not big.any():
            return tris
        cc, R = cc[big], R[big]
        ok = ctx.inside(cc)
        cc, R = cc[ok], R[ok]
        db, di = _distances(ctx, cc)
        hh = _row_step_at(ctx, cc, dprime)
        ok = (db > 0.5 * hh) & (di > 0.5 * hh)
        cc, R = cc[ok], R[ok]
        cand = cc[thin_candidates_mask(ws, cc, 0.5 * R)]
        if len(cand) == 0:
            return tris
        add_free_points(ws, cand)
    return triangulate(ws, ctx)


def _centroids(P: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Triangle centroids ``(M, 2)``, ``P[tris].mean(axis=1)``: the same numbers,
    ``((a + b) + c) / 3`` per coordinate, from coordinate columns."""
    (ax, ay), (bx, by), (cx, cy) = corner_columns(P, tris)
    return np.column_stack([(ax + bx + cx) / 3, (ay + by + cy) / 3])


def _midpoints(P: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
    lv_all = np.unique(ws.level[np.isfinite(ws.level)])
    # index of every node's level among all the levels carried (intermediate levels)
    lvi = np.searchsorted(lv_all, np.nan_to_num(ws.level, nan=np.inf))

    def facing(tris):
        """(apex, a, b) index arrays of the row-to-row triangles, and the movable apexes."""
        parts = []
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3
            # a row edge (a, b: one level) and an apex on another level
            r = np.flatnonzero(ws.level[tris[:, a]] == ws.level[tris[:, b]])
            ta, tc = tris[r, a], tris[r, k]
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
            mx, my = _midpoints(ws.P, fac[:, 1], fac[:, 2])
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


def place_layers(ctx: Context, rng, chord_tol: float, progress=None) -> WorkSet:
    """Place nodes on rows along the iso-composition curves (see the module docstring)."""
    dprime = ctx.row_spacing * ctx.threshold
    # the pieces between interfaces come from the curves sampled without the crossings
    ws0 = _pslg_workset(ctx, _curve_params(ctx, np.zeros(0, np.int64), np.zeros(0), dprime,
                                           chord_tol))
    pieces = _Pieces(ctx, ws0)
    keys, levs, dps = _piece_levels(ctx, pieces, dprime)
    with ctx.timed("grade"):
        keys, levs, dps, spacing = _grade_levels(ctx, pieces, keys, levs, dps, dprime, chord_tol)
    cross = _crossings(ctx, pieces, keys, levs, dps, dprime)
    ws = _pslg_workset(ctx, _curve_params(ctx, cross[0], cross[1], dprime, chord_tol, spacing))
    budget = int(2 * estimate_elements(ctx.field, ctx.domain, ctx.threshold, ctx.h_max)) + 1000
    with ctx.timed("rows"):
        rows, rlev = _place_rows(ctx, pieces, keys, levs, dps, cross, dprime, budget)
    if len(rows):
        # row nodes too near a curve node or a node of another row (seed rows, rows
        # meeting at a curve): thin them
        keep = thin_candidates_mask(ws, rows, 0.4 * _row_step_at(ctx, rows, _level_dps(levs, dps, rlev)))
        add_free_points(ws, rows[keep], level=rlev[keep])
    log.info("layers: %d pieces, %d boundary nodes, %d row nodes", pieces.n,
             int((ws.vcurve != FREE).sum()), int(np.isfinite(ws.level).sum()))
    tris = _fill(ws, ctx, dprime)
    tris = smooth(ws, ctx, tris, iters=4, retriangulate_every=2)
    stagger(ws, ctx, tris, dprime, iters=STAGGER_ITERS)
    return ws
