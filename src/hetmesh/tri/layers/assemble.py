"""Assembly of the row placement: the stages in order."""

from __future__ import annotations

import logging

import numpy as np

from ...density import estimate_elements
from ..workset import FREE, Context, WorkSet, add_free_points, smooth, thin_candidates_mask
from .crossings import curve_crossings, curve_params, pslg_workset, wall_pins
from .fill import fill_flat_zones
from .grading import grade_levels
from .levels import piece_levels
from .pieces import Pieces
from .rows import place_rows
from .rowstep import row_step_at
from .stagger import STAGGER_ITERS, stagger

log = logging.getLogger(__name__)


def place_layers(ctx: Context, rng, chord_tol: float, progress=None,
                 mid_levels: bool = True) -> WorkSet:
    """Place nodes on rows along the iso-composition curves (see :mod:`hetmesh.tri.layers`).

    ``rng`` and ``progress`` are accepted for the placements' common signature and unused
    (the placement is deterministic). Returns the work set: the curve nodes (the levels'
    crossings pinned, or the mid-levels between them where the rows meet a curve square,
    :func:`~.crossings.wall_pins`; ``mid_levels=False``: every crossing pinned) and the row
    nodes with their levels (``WorkSet.level``), filled, smoothed along the rows and
    staggered."""
    dprime = ctx.row_spacing * ctx.threshold
    # the pieces between interfaces come from the curves sampled without the crossings
    ws0 = pslg_workset(ctx, curve_params(ctx, np.zeros(0, np.int64), np.zeros(0), dprime,
                                         chord_tol))
    pieces = Pieces(ctx, ws0)
    levels = piece_levels(ctx, pieces, dprime)
    with ctx.timed("grade"):
        levels, spacing = grade_levels(ctx, pieces, levels, dprime, chord_tol)
    cross = curve_crossings(ctx, pieces, levels, dprime)
    pin_curve, pin_t = wall_pins(ctx, levels, cross) if mid_levels else (cross.curve, cross.t)
    ws = pslg_workset(ctx, curve_params(ctx, pin_curve, pin_t, dprime, chord_tol, spacing))
    budget = int(2 * estimate_elements(ctx.field, ctx.domain, ctx.threshold, ctx.h_max)) + 1000
    with ctx.timed("rows"):
        rows = place_rows(ctx, pieces, levels, cross, dprime, budget)
    if len(rows):
        # row nodes too near a curve node or a node of another row (seed rows, rows
        # meeting at a curve): thin them
        h = row_step_at(ctx, rows.point, levels.dprime_of(rows.level))
        keep = thin_candidates_mask(ws, rows.point, 0.4 * h)
        add_free_points(ws, rows.point[keep], level=rows.level[keep])
    log.info("layers: %d pieces, %d boundary nodes, %d row nodes", pieces.n,
             int((ws.vcurve != FREE).sum()), int(np.isfinite(ws.level).sum()))
    tris = fill_flat_zones(ws, ctx, dprime)
    tris = smooth(ws, ctx, tris, iters=4, retriangulate_every=2)
    stagger(ws, ctx, tris, dprime, iters=STAGGER_ITERS)
    return ws
