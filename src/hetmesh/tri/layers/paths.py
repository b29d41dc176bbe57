"""Gradient paths: steepest ascent and descent from just inside every curve."""

from __future__ import annotations

import numpy as np

from ..workset import Context, project_to_level
from .curves import crosses_interface, side_points
from .levels import KEY_STRIDE
from .pieces import Pieces
from .rowstep import LEVEL_TOL


def path_starts(ctx: Context, pieces: Pieces, most: int):
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
                starts.append(side_points(ctx, k, ts[ok], side))
                spc.append(pc[ok])
                scv.append(np.full(int(ok.sum()), k))
    return starts, spc, scv


def two_way_starts(ctx: Context, pieces: Pieces, most: int):
    """The gradient paths' starts inside the domain, each twice (ascent then descent):
    ``(points, direction +1/-1, piece, start curve)``, or None if there are none."""
    starts, spc, scv = path_starts(ctx, pieces, most)
    if not starts:
        return None
    x, pc, cv = np.vstack(starts), np.concatenate(spc), np.concatenate(scv)
    ok = ctx.inside(x)
    x, pc, cv = x[ok], pc[ok], cv[ok]
    dirn = np.repeat([1.0, -1.0], len(x))
    return np.vstack([x, x]), dirn, np.concatenate([pc, pc]), np.concatenate([cv, cv])


def gradient_walk(ctx: Context, x: np.ndarray, dirn: np.ndarray, step: float, cap: float,
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
        ok &= ~crosses_interface(ctx, x, xn)
        yield ids, x, f, gn, xn, fn, ok, ds
        ids, x, f, dirn = ids[ok], xn[ok], fn[ok], dirn[ok]


def gradient_profiles(ctx: Context, pieces: Pieces, dprime: float):
    """Gradient paths through every piece, as samples: steepest ascent and descent started
    just inside every curve, on each side, until f stops changing monotonically, the path
    leaves the domain or meets an interface. Returns (path id, arc length s, f, x, g) of the
    samples in path order and, per path, (piece, start curve, direction)."""
    start = two_way_starts(ctx, pieces, 32)
    if start is None:
        return None
    x, dirn, pc, cv = start
    npath = len(x)
    s = np.zeros(npath)
    out = []
    max_steps = int(1.5 / dprime + 14 * ctx.domain.diameter / ctx.h_max + 100)
    for ids, xs, f, gn, _, _, ok, ds in gradient_walk(ctx, x, dirn, dprime, 0.08 * ctx.h_max,
                                                        max_steps):
        out.append((ids, s[ids], f, xs, gn))
        s[ids[ok]] += ds[ok]
    P = np.concatenate([o[0] for o in out])
    order = np.argsort(P, kind="stable")
    cat = [np.concatenate([o[j] for o in out])[order] for j in range(5)]
    return cat, (pc, cv, dirn)


def gradient_seeds(ctx: Context, pieces: Pieces, keys, levs, dps, dprime: float):
    """Points on the levels found along gradient lines (steepest ascent and descent paths
    started just inside every curve, on each side): they find the level curves that cross
    no curve at all (closed curves around a hole or an extremum). Returns (points, levels,
    row spacings, pieces), in the order of the paths (stable)."""
    start = two_way_starts(ctx, pieces, 64)
    none = np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0, np.int64)
    if start is None:
        return none
    x, dirn, pc, _ = start
    kx = np.searchsorted(keys, pc * KEY_STRIDE + ctx.f(x), side="right")
    out_p, out_l, out_d, out_i = [], [], [], []
    max_steps = int(4.0 / dprime + 8 * ctx.domain.diameter / ctx.h_max + 100)
    for ids, xs, f, _, xn, fn, ok, _ in gradient_walk(ctx, x, dirn, 0.5 * dprime,
                                                        0.25 * ctx.h_max, max_steps):
        kn = np.searchsorted(keys, pc[ids] * KEY_STRIDE + fn, side="right")
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
