"""Filling the flat zones that no row covers (circumcenter insertion).

Where |grad f| is small the row step reaches the maximum size and the levels lie far apart or
not at all (a plateau of f): the triangles of the rows and the curve nodes are larger than
the local size there, and their circumcenters are inserted, round by round, as free nodes.
"""

from __future__ import annotations

import numpy as np

from ...metrics import circumcircles, corner_columns
from ..workset import Context, WorkSet, add_free_points, thin_candidates_mask, triangulate
from .curves import curve_distances
from .rowstep import row_step_at


def fill_flat_zones(ws: WorkSet, ctx: Context, dprime: float, rounds: int = 30):
    """Fill flat zones: insert the circumcenters of the triangles whose circumradius
    exceeds 0.75 of the local row step, inside the domain, at least half a step from every
    curve and not too near a node (:func:`hetmesh.tri.workset.thin_candidates_mask`), for at
    most ``rounds`` rounds. Returns the triangles of the work set as filled."""
    for _ in range(rounds):
        tris = triangulate(ws, ctx)
        cc, R = circumcircles(ws.P, tris)
        cen = centroids(ws.P, tris)
        hloc = row_step_at(ctx, cen, dprime)
        big = R > 0.75 * hloc
        if not big.any():
            return tris
        cc, R = cc[big], R[big]
        ok = ctx.inside(cc)
        cc, R = cc[ok], R[ok]
        db, di = curve_distances(ctx, cc)
        hh = row_step_at(ctx, cc, dprime)
        ok = (db > 0.5 * hh) & (di > 0.5 * hh)
        cc, R = cc[ok], R[ok]
        cand = cc[thin_candidates_mask(ws, cc, 0.5 * R)]
        if len(cand) == 0:
            return tris
        add_free_points(ws, cand)
    return triangulate(ws, ctx)


def centroids(P: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Triangle centroids ``(M, 2)``, ``P[tris].mean(axis=1)``: the same numbers,
    ``((a + b) + c) / 3`` per coordinate, from coordinate columns."""
    (ax, ay), (bx, by), (cx, cy) = corner_columns(P, tris)
    return np.column_stack([(ax + bx + cx) / 3, (ay + by + cy) / 3])
