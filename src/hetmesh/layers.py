"""Node placement on iso-composition curves ("layers"): MOR's start for two constituents.

Why: delta(T) of a small element is |grad f| times its extent along the gradient. A CVT spreads
that extent by ~1.4 between elements, so an isotropic CVT cannot go much below ~1.2 x N_iso
elements. Rows of nodes on the level curves f = c_k, c_k = anchor -/+ k * beta * delta_0,
with spacing 2 w / sqrt(3) along each row (w = beta * delta_0 / |grad f| the row distance),
make near-equilateral triangles whose vertices sit on two adjacent rows, so every such triangle
has delta(T) = beta * delta_0 exactly: the threshold is used to the full (about 0.75-0.9 x N_iso
elements). The rows are traced from where the level curves cross the boundary (predictor step
along the tangent, Newton corrector back onto the level); flat zones are filled by
circumcenter insertion to the maximum size; nodes then slide along their rows (conforming
Lloyd, :func:`hetmesh.refine.smooth`) and the shared repair loop of :mod:`hetmesh.adapt`
fixes whatever is left, so the guarantee does not depend on this placement.
"""

from __future__ import annotations

import logging

import numpy as np

from .geometry import pslg_from_parameters
from .metrics import circumcircles
from . import cvt
from .density import background_points, estimate_elements
from .refine import (FREE, Context, WorkSet, add_free_points, project_to_level, row_tangent,
                     slide_along_rows, smooth, thin_candidates_mask, triangulate,
                     workset_from_pslg)

__all__ = ["place_layers", "BETA"]

log = logging.getLogger(__name__)

STAGGER_ITERS = 8
BETA = 0.985  # row spacing in composition, as a fraction of delta_0


def _row_step(ctx: Context, gnorm: np.ndarray, dprime: float) -> np.ndarray:
    """Node spacing along a row, 2 w / sqrt(3) with w = delta' / |grad f| (capped at h_max)."""
    with np.errstate(divide="ignore"):
        s = 2.0 * dprime / (np.sqrt(3.0) * gnorm)
    return np.minimum(np.nan_to_num(s, nan=ctx.h_max, posinf=ctx.h_max), ctx.h_max)


def _row_step_at(ctx: Context, pts: np.ndarray, dprime: float) -> np.ndarray:
    return _row_step(ctx, np.linalg.norm(ctx.grad_f(pts), axis=1), dprime)


def _anchor(ctx: Context) -> tuple[float, float]:
    """The level the rows count from and their direction: the extreme value of f that the
    boundary holds over the longer stretch (a boundary that is a level curve is a row)."""
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
    return (fmax, -1.0) if at_max >= at_min else (fmin, 1.0)


def _crossings(ctx: Context, anchor: float, sign: float, dprime: float):
    """Where the level curves cross every curve: (curve id, t, level) arrays."""
    cid, tt, lv = [], [], []
    for k, c in enumerate(ctx.curves):
        n = 64
        ts = np.linspace(0, 1, n + 1)
        g = np.linalg.norm(ctx.grad_f(c.point(ts)), axis=1).max()
        # resolve the rows: at least 8 samples per row crossing
        n = int(min(200_000, max(256, 8 * c.length * g / dprime)))
        ts = np.linspace(0, 1, n + 1)
        f = ctx.f(c.point(ts))
        u = (f - anchor) * sign / dprime  # row coordinate: crossing of row k where u == k
        fl = np.floor(u + 1e-12)
        i = np.flatnonzero(fl[1:] != fl[:-1])
        if i.size == 0:
            continue
        lo = np.minimum(fl[i], fl[i + 1]) + 1
        hi = np.maximum(fl[i], fl[i + 1])
        cnt = (hi - lo + 1).astype(np.int64)
        seg = np.repeat(i, cnt)
        kk = np.repeat(lo, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
        keep = kk >= 1
        seg, kk = seg[keep], kk[keep]
        level = anchor + sign * kk * dprime
        a, b = ts[seg], ts[seg + 1]
        fa = f[seg] - level
        for _ in range(40):  # bisection on t, vectorised
            m = 0.5 * (a + b)
            fm = ctx.f(c.point(m)) - level
            left = np.sign(fm) == np.sign(fa)
            a = np.where(left, m, a)
            fa = np.where(left, fm, fa)
            b = np.where(left, b, m)
        cid.append(np.full(len(a), k))
        tt.append(0.5 * (a + b))
        lv.append(level)
    if not cid:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    return np.concatenate(cid), np.concatenate(tt), np.concatenate(lv)


def _curve_params(ctx: Context, cid, tt, dprime, chord_tol):
    """Per-curve sorted parameters: 0, crossings, 1, and between them nodes at the local row
    step (and the chord tolerance, and the minimum interval counts, of :mod:`geometry`)."""
    batch = ctx.domain.curve_batch
    cap, nmin = batch.max_step(chord_tol), batch.min_intervals()
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


def _trace_rows(ctx: Context, cid, tt, lv, dprime, budget: int):
    """Trace every level curve inwards from its boundary crossings; returns (points, levels)."""
    seeds = np.array([ctx.curves[c].point(np.array([t]))[0] for c, t in zip(cid, tt)]) \
        if len(cid) else np.zeros((0, 2))
    isb = ctx.boundary_curve[cid] if len(cid) else np.zeros(0, bool)
    seeds, lv = seeds[isb], lv[isb]
    if len(seeds) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    gr = ctx.grad_f(seeds)
    tau = row_tangent(gr)
    s = _row_step(ctx, np.linalg.norm(gr, axis=1), dprime)
    probe = seeds + 0.05 * s[:, None] * tau
    inward = ctx.inside(probe)
    x, lev = seeds[inward], lv[inward]
    out_p, out_l = [], []
    total = 0
    active = np.ones(len(x), bool)
    start = x.copy()
    travelled = np.zeros(len(x))
    for step in range(100_000):
        if not active.any() or total > budget:
            break
        xa, la = x[active], lev[active]
        g = ctx.grad_f(xa)
        gn = np.linalg.norm(g, axis=1)
        h = _row_step(ctx, gn, dprime)
        xm = xa + 0.5 * h[:, None] * row_tangent(g)  # midpoint predictor
        tm = row_tangent(ctx.grad_f(xm))
        xn = project_to_level(ctx, xa + h[:, None] * tm, la, iters=3)
        moved = np.linalg.norm(xn - xa, axis=1)
        inside = ctx.inside(xn)
        db, di = _distances(ctx, xn)
        ok = inside & (gn > 1e-12) & (moved > 0.2 * h) & (moved < 3 * h)
        # closed level curves: stop when back near the start
        travelled[active] += moved
        closed = (travelled[active] > 3 * h) & (np.linalg.norm(xn - start[active], axis=1) < 0.6 * h)
        keep_node = ok & (db > 0.55 * h) & (di > 0.55 * h) & ~closed
        out_p.append(xn[keep_node])
        out_l.append(la[keep_node])
        total += int(keep_node.sum())
        cont = ok & ~closed & ((db > 0.3 * h) | (step < 2))
        ia = np.flatnonzero(active)
        x[ia] = xn
        active[ia[~cont]] = False
    if not out_p:
        return np.zeros((0, 2)), np.zeros(0)
    return np.concatenate(out_p), np.concatenate(out_l)


def _fill(ws: WorkSet, ctx: Context, dprime: float, rounds: int = 30):
    """Fill flat zones: insert circumcenters of triangles larger than the local size."""
    for _ in range(rounds):
        tris = triangulate(ws, ctx)
        cc, R = circumcircles(ws.P, tris)
        cen = ws.P[tris].mean(axis=1)
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
    def facing(tris):
        """(apex, a, b) index arrays of the row-to-row triangles, and the movable apexes."""
        L = ws.level[tris]
        parts = []
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3
            la, lb, lc = L[:, a], L[:, b], L[:, k]
            ok = (np.isfinite(la) & np.isfinite(lc) & (la == lb)
                  & (np.abs(np.abs(lc - la) - dprime) < 1e-6 * dprime))
            parts.append(tris[ok][:, [k, a, b]])
        fac = np.concatenate(parts)
        # row ends next to the boundary keep their place: moving them squeezes boundary triangles
        near_bnd = np.zeros(ws.n, bool)
        near_bnd[tris[(ws.vcurve[tris] != FREE).any(axis=1)].ravel()] = True
        cnt = np.bincount(fac[:, 0], minlength=ws.n)
        mov = np.isfinite(ws.level) & ~ws.pinned & (cnt > 0) & ~near_bnd
        return fac, cnt, mov

    fac, cnt, mov = facing(tris)
    for it in range(iters):
        if not mov.any():
            break
        with ctx.timed("stagger"):
            mid = 0.5 * (ws.P[fac[:, 1]] + ws.P[fac[:, 2]])
            tx = np.bincount(fac[:, 0], mid[:, 0], minlength=ws.n)[mov]
            ty = np.bincount(fac[:, 0], mid[:, 1], minlength=ws.n)[mov]
            target = ws.P.copy()
            target[mov] = slide_along_rows(ctx, ws.P[mov], np.column_stack([tx, ty]) / cnt[mov, None],
                                           ws.level[mov], relax=relax, iters=2)
            ws.P = cvt.limit_to_star(ws.P, tris, target, mov, halvings=2)
        if (it + 1) % 4 == 0 or it == iters - 1:  # between rebuilds the star limit keeps it valid
            tris = triangulate(ws, ctx)
            fac, cnt, mov = facing(tris)
    return tris


def place_layers(ctx: Context, rng, chord_tol: float, progress=None) -> WorkSet:
    """Place nodes on rows along the iso-composition curves (see the module docstring)."""
    dprime = BETA * ctx.threshold
    anchor, sign = _anchor(ctx)
    cid, tt, lv = _crossings(ctx, anchor, sign, dprime)
    ws = _pslg_workset(ctx, _curve_params(ctx, cid, tt, dprime, chord_tol))
    budget = int(2 * estimate_elements(ctx.field, ctx.domain, ctx.threshold, ctx.h_max)) + 1000
    with ctx.timed("rows"):
        rows, rlev = _trace_rows(ctx, cid, tt, lv, dprime, budget)
    if len(rows):
        # rows of one level traced twice (from both ends) or crossing: thin them
        keep = thin_candidates_mask(ws, rows, 0.4 * _row_step_at(ctx, rows, dprime))
        add_free_points(ws, rows[keep], level=rlev[keep])
    log.info("layers: %d boundary nodes, %d row nodes", int((ws.vcurve != FREE).sum()),
             int(np.isfinite(ws.level).sum()))
    tris = _fill(ws, ctx, dprime)
    tris = smooth(ws, ctx, tris, iters=4, retriangulate_every=2)
    stagger(ws, ctx, tris, dprime, iters=STAGGER_ITERS)
    return ws
