"""Row tracing: a level curve followed from a point on it, node by node."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..workset import Context, project_to_level, row_tangent
from .curves import crosses_interface, curve_distances
from .records import Records
from .rowstep import row_step_at


@dataclass(frozen=True)
class Trace:
    """The rows traced from R starts (:func:`trace_rows`).

    Per node traced (the starts themselves are not among them): ``point`` (N, 2),
    ``level`` (N,), ``start`` (N,) the index of the start it was traced from, in tracing
    order. Per start: ``closed`` (R,) whether the row closed on itself, ``end`` (R, 2)
    where the trace stopped, ``at_curve`` (R,) whether it stopped next to a curve or a step
    from leaving its piece (the row's far end, if a crossing of its level lies there)."""

    point: np.ndarray
    level: np.ndarray
    start: np.ndarray
    closed: np.ndarray
    end: np.ndarray
    at_curve: np.ndarray


@dataclass(frozen=True)
class RowNodes(Records):
    """Row nodes: ``point`` (N, 2) and the ``level`` (N,) each lies on."""

    point: np.ndarray
    level: np.ndarray

    @classmethod
    def empty(cls) -> RowNodes:
        return cls(np.zeros((0, 2)), np.zeros(0))


def trace_rows(ctx: Context, x0: np.ndarray, lev: np.ndarray, dirn: np.ndarray,
               dprime: np.ndarray, budget: int) -> Trace:
    """Trace the level curves f = ``lev`` from the points ``x0`` along ``dirn`` times their
    tangent until they reach a boundary or interface curve, leave the domain, or close
    (back near their start); ``dprime`` is each row's spacing in f, and the step along the
    row its node step (:func:`~hetmesh.tri.layers.rowstep.row_step_at`). A step is a
    midpoint predictor along the tangent and a Newton corrector back onto the level
    (:func:`hetmesh.tri.workset.project_to_level`). Nodes closer than 0.55 of the step to a
    curve are not kept; tracing stops once ``budget`` nodes are."""
    closed_out = np.zeros(len(x0), bool)
    if len(x0) == 0:
        return Trace(np.zeros((0, 2)), np.zeros(0), np.zeros(0, np.int64), closed_out,
                     np.zeros((0, 2)), closed_out.copy())
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
        # (:func:`~hetmesh.tri.layers.respacing.respace_rows` checks): next to a curve, or a
        # step from leaving its piece
        at_curve[ia] = ~cont & ~closed & (step >= 2)
        x[ia] = np.where(ok[:, None], xn, xa)
        active[ia[~cont]] = False
    at_curve &= ~active  # a trace cut short by the budget has no far end
    if not out_p:
        return Trace(np.zeros((0, 2)), np.zeros(0), np.zeros(0, np.int64), closed_out, x,
                     at_curve)
    return Trace(np.concatenate(out_p), np.concatenate(out_l), np.concatenate(out_i),
                 closed_out, x, at_curve)


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
