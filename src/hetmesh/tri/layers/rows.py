"""All the row nodes: rows traced from the crossings of the levels with the curves, then from
gradient-line seeds on the levels that cross no curve."""

from __future__ import annotations

import numpy as np

from ...topology import unique
from ..workset import Context, row_tangent
from .crossings import Crossings
from .curves import curve_distances, left_normal, side_points
from .levels import Levels
from .paths import RowSeeds, gradient_seeds
from .pieces import Pieces
from .respacing import even_nodes, respace_rows, row_polylines, start_phase
from .rowstep import row_step, row_step_at
from .tracing import RowNodes, near_own_row, trace_rows


def crossing_starts(ctx: Context, cross: Crossings, dprime: float):
    """The rows' start points at the crossings, and which of them start a row: those whose
    row tangent points into the domain (boundary) or into the crossing's side (interface).
    An interface crossing starts just off the curve, on its piece's side: f and its
    gradient may jump across, and on the curve they would be the other side's."""
    isb = ctx.boundary_curve[cross.curve]
    seeds = np.vstack([side_points(ctx, int(k), np.array([t]), 0 if b else int(d))
                       for k, t, d, b in zip(cross.curve, cross.t, cross.side, isb)])
    gr = ctx.grad_f(seeds)
    tau = row_tangent(gr)
    s = row_step(ctx, np.linalg.norm(gr, axis=1), dprime, ctx.h_at(seeds))
    inward = np.zeros(len(cross), bool)
    if isb.any():  # boundary: the row starts where its tangent points into the domain
        inward[isb] = ctx.inside(seeds[isb] + 0.05 * s[isb, None] * tau[isb])
    for k in unique(cross.curve[~isb]):  # interface: into the side it was found on
        m = np.flatnonzero((cross.curve == k) & ~isb)
        nrm = cross.side[m, None] * left_normal(ctx.curves[k], cross.t[m])
        inward[m] = (tau[m] * nrm).sum(1) > 0
    return RowSeeds(seeds, cross.level, cross.dprime, cross.piece), inward


def rows_from_crossings(ctx: Context, levels: Levels, cross: Crossings, dprime: float,
                        budget: int) -> RowNodes:
    """The rows traced inwards from the level crossings of the boundary and of both sides
    of every interface, re-spaced where they run from curve to curve (:func:`respace_rows`)."""
    if len(cross) == 0:
        return RowNodes.empty()
    starts, inward = crossing_starts(ctx, cross, dprime)
    ix = np.flatnonzero(inward)
    trace = trace_rows(ctx, starts.point[ix], starts.level[ix], np.ones(len(ix)),
                       starts.dprime[ix], budget)
    return respace_rows(ctx, starts, levels.index(starts.piece, starts.level), ix, trace)


def rows_from_seeds(ctx: Context, levels: Levels, seeds: RowSeeds, rows: list[RowNodes],
                    budget: int) -> list[RowNodes]:
    """The rows traced both ways from the gradient-line seeds on levels not traced yet, one
    seed per level and round, until every seed lies next to a row of its level; closed rows
    re-spaced from their seed, in phase with their neighbours (:func:`even_nodes`).
    Returns ``rows`` with the new rows appended."""
    rows = list(rows)
    for _ in range(64):
        if len(seeds) == 0 or sum(len(r) for r in rows) > budget:
            break
        known = RowNodes.concat(rows)
        new = ~near_own_row(known.point, known.level, seeds.point, seeds.level,
                            0.75 * row_step_at(ctx, seeds.point, seeds.dprime))
        seeds = seeds.take(new)
        if len(seeds) == 0:
            break
        # one seed per level: the first path's (seeds come in path order), so that the
        # seeds of nested closed rows lie on one gradient line and their phases agree
        _, first = unique(seeds.level, return_index=True)
        pick = np.zeros(len(seeds), bool)
        pick[first] = True
        s, seeds = seeds.take(pick), seeds.take(~pick)
        x, lv, d = s.point, s.level, s.dprime
        fwd = trace_rows(ctx, x, lv, np.ones(len(x)), d, budget)
        closed = fwd.closed
        back = trace_rows(ctx, x[~closed], lv[~closed], -np.ones(int((~closed).sum())),
                          d[~closed], budget)
        open_ = ~closed[fwd.start]
        rows += [RowNodes(x[~closed], lv[~closed]),
                 RowNodes(fwd.point[open_], fwd.level[open_]),
                 RowNodes(back.point, back.level)]
        if closed.any():
            o = np.argsort(fwd.start, kind="stable")
            loops = np.flatnonzero(closed)
            par = levels.parity(s.piece, lv)
            rows.append(even_nodes(ctx, row_polylines(x[loops], x[loops], fwd.point[o],
                                                      fwd.start[o], loops, closed),
                                   d[loops], lv[loops], start_phase(par[loops]), closed=True))
    return rows


def place_rows(ctx: Context, pieces: Pieces, levels: Levels, cross: Crossings, dprime: float,
               budget: int) -> RowNodes:
    """All row nodes: traced inwards from the level crossings of the curves
    (:func:`rows_from_crossings`), then from the gradient-line seeds on levels not traced
    yet (:func:`rows_from_seeds`), seeds closer than 0.55 of the row step to a curve
    dropped."""
    rows = [RowNodes.empty()]
    if len(cross):
        rows.append(rows_from_crossings(ctx, levels, cross, dprime, budget))
    with ctx.timed("seeds"):
        seeds = gradient_seeds(ctx, pieces, levels, dprime)
    if len(seeds):
        db, di = curve_distances(ctx, seeds.point)
        h = row_step_at(ctx, seeds.point, seeds.dprime)
        seeds = seeds.take((db > 0.55 * h) & (di > 0.55 * h))
    return RowNodes.concat(rows_from_seeds(ctx, levels, seeds, rows, budget))
