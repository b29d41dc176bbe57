"""Row tracing: the level curves followed from their crossings and from gradient-line seeds."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..workset import Context, project_to_level, row_tangent
from .curves import crosses_interface, curve_distances, left_normal, side_points
from .levels import KEY_STRIDE
from .paths import gradient_seeds
from .pieces import Pieces
from .respacing import even_nodes, respace_rows, row_polylines
from .rowstep import row_step, row_step_at


def trace_rows(ctx: Context, x0: np.ndarray, lev: np.ndarray, dirn: np.ndarray,
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
        h = row_step_at(ctx, xa, dpr[ia], grad=g)
        xm = xa + 0.5 * h[:, None] * da * row_tangent(g)  # midpoint predictor
        tm = da * row_tangent(ctx.grad_f(xm))
        xn = project_to_level(ctx, xa + h[:, None] * tm, la, iters=3)
        moved = np.linalg.norm(xn - xa, axis=1)
        inside = ctx.inside(xn)
        db, di = curve_distances(ctx, xn)
        ok = inside & (gn > 1e-12) & (moved > 0.2 * h) & (moved < 3 * h)
        ok &= ~crosses_interface(ctx, xa, xn)
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
        # (:func:`respace_rows` checks): next to a curve, or a step from leaving its piece
        at_curve[ia] = ~cont & ~closed & (step >= 2)
        x[ia] = np.where(ok[:, None], xn, xa)
        active[ia[~cont]] = False
    at_curve &= ~active  # a trace cut short by the budget has no far end
    if not out_p:
        out = (np.zeros((0, 2)), np.zeros(0), closed_out)
        return out + (np.zeros(0, np.int64), x, at_curve) if ends else out
    out = (np.concatenate(out_p), np.concatenate(out_l), closed_out)
    return out + (np.concatenate(out_i), x, at_curve) if ends else out


def near_own_row(rows: np.ndarray, rlev: np.ndarray, pts: np.ndarray, lev: np.ndarray,
           radius: np.ndarray) -> np.ndarray:
    """Which points have a row node of their own level within ``radius``."""
    if len(rows) == 0 or len(pts) == 0:
        return np.zeros(len(pts), bool)
    k = min(8, len(rows))
    d, j = cKDTree(rows).query(pts, k=k)
    d, j = d.reshape(len(pts), k), j.reshape(len(pts), k)
    same = np.abs(rlev[j] - lev[:, None]) <= 1e-9 * np.maximum(1.0, np.abs(lev[:, None]))
    return ((d < radius[:, None]) & same).any(axis=1)


def place_rows(ctx: Context, pieces: Pieces, keys, levs, dps, cross, dprime: float,
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
        seeds = np.vstack([side_points(ctx, int(k), np.array([t]), 0 if b else int(d))
                           for k, t, d, b in zip(cid, tt, sd, isb)])
        gr = ctx.grad_f(seeds)
        tau = row_tangent(gr)
        s = row_step(ctx, np.linalg.norm(gr, axis=1), dprime, ctx.h_at(seeds))
        inward = np.zeros(len(cid), bool)
        if isb.any():  # boundary: the row starts where its tangent points into the domain
            inward[isb] = ctx.inside(seeds[isb] + 0.05 * s[isb, None] * tau[isb])
        for k in np.unique(cid[~isb]):  # interface: into the side the crossing was found on
            m = np.flatnonzero((cid == k) & ~isb)
            nrm = sd[m, None] * left_normal(ctx.curves[k], tt[m])
            inward[m] = (tau[m] * nrm).sum(1) > 0
        ix = np.flatnonzero(inward)
        p, l, _, tid, xend, at_curve = trace_rows(ctx, seeds[ix], lv[ix], np.ones(len(ix)),
                                                   cdp[ix], budget, ends=True)
        par = np.searchsorted(keys, pcs * KEY_STRIDE + lv, side="left") % 2  # level parity
        p, l = respace_rows(ctx, seeds, lv, pcs, cdp, par, ix, p, l, tid, xend, at_curve)
        rows.append(p)
        rlev.append(l)
    with ctx.timed("seeds"):
        sp, sl, sd_, spc = gradient_seeds(ctx, pieces, keys, levs, dps, dprime)
    if len(sp):
        db, di = curve_distances(ctx, sp)
        h = row_step_at(ctx, sp, sd_)
        far = (db > 0.55 * h) & (di > 0.55 * h)
        sp, sl, sd_, spc = sp[far], sl[far], sd_[far], spc[far]
    for _ in range(64):
        if len(sp) == 0 or sum(len(r) for r in rows) > budget:
            break
        R, RL = np.vstack(rows), np.concatenate(rlev)
        new = ~near_own_row(R, RL, sp, sl, 0.75 * row_step_at(ctx, sp, sd_))
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
        p1, l1, closed, tid, _, _ = trace_rows(ctx, x, l, np.ones(len(x)), d, budget,
                                                ends=True)
        p2, l2, _ = trace_rows(ctx, x[~closed], l[~closed], -np.ones(int((~closed).sum())),
                                d[~closed], budget)
        rows += [x[~closed], p1[~closed[tid]], p2]
        rlev += [l[~closed], l1[~closed[tid]], l2]
        if closed.any():  # closed rows: re-spaced from their seed, in phase (respace_rows)
            o = np.argsort(tid, kind="stable")
            loops = np.flatnonzero(closed)
            par = np.searchsorted(keys, pc * KEY_STRIDE + l, side="left") % 2
            xl, ll = even_nodes(ctx, row_polylines(x[loops], x[loops], p1[o], tid[o], loops, closed),
                                 d[loops], l[loops], np.where(par[loops] == 0, 1.0, 0.5),
                                 closed=True)
            rows.append(xl)
            rlev.append(ll)
    return np.vstack(rows), np.concatenate(rlev)
