"""Level selection: the row levels of every piece."""

from __future__ import annotations

import numpy as np

from ...density import background_points
from ..workset import Context
from .curves import side_points
from .pieces import Pieces


def anchor_level(ctx: Context) -> float:
    """The level the rows count from: the extreme value of f that the boundary holds over
    the longer stretch (a boundary that is a level curve is a row).
    The fallback of pieces without a level curve on their border (:func:`piece_levels`)."""
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


KEY_STRIDE = 8.0  # level keys: piece * KEY_STRIDE + level (levels lie within (-2, 3))


def piece_levels(ctx: Context, pieces: Pieces, dprime: float):
    """The row levels of every piece, as sorted keys ``piece * KEY_STRIDE + level`` and levels.

    A piece counts its levels ``anchor -/+ k * dprime`` from the level curve on its border
    that carries the most row nodes (the largest integral of |grad f| along it: the rows
    next to it keep their full spacing where elements are smallest); without one, from the
    boundary's extreme value (:func:`anchor_level`). Levels closer than 0.02 dprime to another
    level curve of the border are dropped (they would run along it), and where the last
    level before another level curve leaves a gap under dprime / 4, the last two gaps are
    evened out instead of leaving a thin strip. A border along which f varies by less than
    dprime / 4 (nearly a level curve: fgm_plate's top edge, f 0.991-0.994) is evened
    against too (at its median value), but it is no anchor: a level 0.007 below it lay too
    close to the border for its row step to be kept, so the flat top was left to the fill
    and the repair loop (fgm_plate 0.1: 2,089 -> 1,828 elements, delta_avg/delta_0
    0.71 -> 0.79)."""
    a0 = anchor_level(ctx)
    ts = (np.arange(400) + 0.5) / 400
    holders = [[] for _ in range(pieces.n)]
    near = [[] for _ in range(pieces.n)]  # borders that are nearly level curves (evening only)
    vals = []
    for k, c in enumerate(ctx.curves):
        for side, ev in pieces.sides(k, ctx):
            pc = pieces.at(k, ts, side)
            f = ctx.f(side_points(ctx, k, ts, ev))
            vals.append(f)
            for p in np.unique(pc[pc >= 0]):
                m = pc == p
                if m.sum() < 0.9 * len(ts):
                    continue
                if np.ptp(f[m]) > 1e-7:
                    if np.ptp(f[m]) < 0.25 * dprime:
                        near[p].append(float(np.median(f[m])))
                    continue
                g = np.linalg.norm(ctx.grad_f(side_points(ctx, k, ts[m], ev)), axis=1)
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
        keys.append(p * KEY_STRIDE + L)
        levs.append(L)
        dps.append(np.full(len(L), dprime))  # each row's spacing in f (traced with it)
    if not keys:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    return np.concatenate(keys), np.concatenate(levs), np.concatenate(dps)
