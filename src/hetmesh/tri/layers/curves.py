"""The domain's curves as the rows see them: points just off a curve on one side, distances
to the boundary and interface curves, steps that cross an interface."""

from __future__ import annotations

import numpy as np

from ...metrics import signed_area2
from ..workset import Context


def left_normal(c, t: np.ndarray) -> np.ndarray:
    """The unit normals of curve ``c`` at parameters ``t``, to the left of increasing t."""
    tg = c.tangent(t)
    return np.column_stack([-tg[:, 1], tg[:, 0]])


def side_eps(ctx: Context) -> float:
    """How far off an interface f is evaluated for one side of it (f may jump across)."""
    return 1e-5 * ctx.domain.diameter


def side_points(ctx: Context, k: int, t: np.ndarray, side: int) -> np.ndarray:
    """Points of curve ``k`` at parameters ``t``; ``side`` +1/-1: just off it, to the left /
    right of the direction of increasing t; 0: on it."""
    c = ctx.curves[k]
    p = c.point(t)
    if side:
        p = p + (side * side_eps(ctx)) * left_normal(c, t)
    return p


def curve_distances(ctx: Context, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distance of every point to the nearest boundary curve and to the nearest
    interface curve (inf where there is none)."""
    db = np.full(len(pts), np.inf)
    di = np.full(len(pts), np.inf)
    for c, isb in zip(ctx.curves, ctx.boundary_curve):
        d = c.distance(pts)
        if isb:
            db = np.minimum(db, d)
        else:
            di = np.minimum(di, d)
    return db, di


def crosses_interface(ctx: Context, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
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
