"""Spacing along rows: the nodes of a row re-placed evenly, in phase with its neighbours.

A row is traced at its own local step (:mod:`~hetmesh.tri.layers.tracing`); here the rows
that run from curve to curve, and the closed ones, get their nodes anew: a node count shared
by adjacent rows (a rung of a geometric ladder) and alternate rows starting a full and a half
spacing from their start, as in a staggered lattice (:func:`respace_rows`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..workset import Context, project_to_level
from .paths import RowSeeds
from .rowstep import LEVEL_TOL, row_step_at
from .tracing import RowNodes, Trace

#: ratio of the ladder of node counts of the rows that run from curve to curve
#: (:func:`respace_rows`)
LADDER = 1.1


def start_phase(parity: np.ndarray) -> np.ndarray:
    """Where a row's first node lies, in spacings from its start: 1 for rows of even level
    index, 1/2 for odd ones (:meth:`~hetmesh.tri.layers.levels.Levels.parity`)."""
    return np.where(parity == 0, 1.0, 0.5)


def respace_rows(ctx: Context, starts: RowSeeds, parity: np.ndarray, ix: np.ndarray,
                 trace: Trace) -> RowNodes:
    """Re-place the nodes of the rows that run from curve to curve, in phase with their
    neighbours.

    Why: a row traced from its start at its own step 2 w / sqrt(3) starts every row with a
    node one step from the wall, so adjacent rows are in phase at the wall (apex above a
    vertex, not above an edge's midpoint), and since the step changes from row to row the
    phase between two rows drifts along them: sheared bands along the walls and diagonal
    lines of dislocations. Here a row's nodes are spaced
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

    ``starts`` are the rows' start points at the crossings of the levels with the curves,
    ``parity`` the parity of their levels' indices (:func:`start_phase`), ``trace`` the rows
    traced from the starts ``ix``. Rows whose far end is not a crossing of their own level
    and piece keep their traced nodes. Returns all the rows' nodes."""
    p, lev, tid = trace.point, trace.level, trace.start
    xend, at_curve = trace.end, trace.at_curve
    seeds, lv, pcs, cdp = starts.point, starts.level, starts.piece, starts.dprime
    if len(p) == 0 or not at_curve.any():
        return RowNodes(p, lev)
    # the far end: the crossing of the same level and piece nearest to where the trace stopped
    h_end = row_step_at(ctx, xend, cdp[ix])
    tree = cKDTree(seeds)
    d, j = tree.query(xend, k=min(6, len(seeds)))
    d, j = d.reshape(len(ix), -1), j.reshape(len(ix), -1)
    same = (np.abs(lv[j] - lv[ix, None]) <= 1e-12 * np.maximum(1.0, np.abs(lv[ix, None])))
    same &= (pcs[j] == pcs[ix, None]) & (j != ix[:, None]) & (d < 1.5 * h_end[:, None])
    has = at_curve & same.any(axis=1)
    far = j[np.arange(len(ix)), np.argmax(same, axis=1)]
    order = np.argsort(tid, kind="stable")
    p, lev, tid = p[order], lev[order], tid[order]
    rows = np.flatnonzero(has)
    if len(rows) == 0:
        return RowNodes(p, lev)
    lines = row_polylines(seeds[ix[rows]], seeds[far[rows]], p, tid, rows, has)
    even = even_nodes(ctx, lines, cdp[ix[rows]], lv[ix[rows]], start_phase(parity[ix[rows]]),
                      closed=False)
    keep = ~has[tid]
    return RowNodes.concat([RowNodes(p[keep], lev[keep]), even])


@dataclass(frozen=True)
class Polylines:
    """Polylines one after the other: ``points`` (P, 2); polyline r is
    ``points[starts[r]:starts[r + 1]]``."""

    points: np.ndarray
    starts: np.ndarray


def row_polylines(first, last, p, tid, rows, has) -> Polylines:
    """Row polylines: ``first``, the traced nodes ``p`` of trace ``rows[r]`` in trace order
    (``tid`` sorted, ``has`` marking the traces kept), ``last``."""
    cnt = np.bincount(tid, minlength=len(has))[rows]
    starts = np.cumsum(np.r_[0, cnt + 2])
    pts = np.empty((starts[-1], 2))
    pts[starts[:-1]] = first
    pts[starts[1:] - 1] = last
    inner = np.flatnonzero(has[tid])
    r_of = np.searchsorted(rows, tid[inner])
    pos = starts[r_of] + 1 + (np.arange(len(inner)) - np.searchsorted(tid[inner], tid[inner]))
    pts[pos] = p[inner]
    return Polylines(pts, starts)


def even_nodes(ctx: Context, lines: Polylines, dprime, level, phi, closed: bool) -> RowNodes:
    """Nodes spaced evenly, in units of the local row step, along the polylines ``lines``
    (:func:`row_polylines`) of rows with spacing ``dprime`` in f at ``level``: n spacings per
    row, n its length in local steps rounded to a rung of the ladder (:data:`LADDER`), the
    first node ``phi`` (1 or 1/2) spacings from the start. An open row gets n - 1 nodes
    (phi = 1) or n (phi = 1/2) and ends ``phi`` spacings before its end; a closed row
    (first point = last) gets n, phi = 1 meaning a node on its start. Returns the nodes
    projected onto the levels and inside the domain."""
    pts, starts = lines.points, lines.starts
    nrow = len(starts) - 1
    row = np.repeat(np.arange(nrow), np.diff(starts))
    seg = np.flatnonzero(row[1:] == row[:-1])
    mid = 0.5 * (pts[seg] + pts[seg + 1])
    du = np.linalg.norm(pts[seg + 1] - pts[seg], axis=1) / row_step_at(ctx, mid, dprime[row[seg]])
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
    # one sorted key for all rows: row r's arc lengths, 0..U[r], become r * span + 0..U[r]
    span = 2.0 * (U.max() + 1)
    gk, tk = row * span + cu, rr * span + ut
    i = np.clip(np.searchsorted(gk, tk, side="right") - 1, starts[:-1][rr], starts[1:][rr] - 2)
    w = np.clip((tk - gk[i]) / np.maximum(gk[i + 1] - gk[i], 1e-300), 0.0, 1.0)
    x = pts[i] + w[:, None] * (pts[i + 1] - pts[i])
    lev = level[rr]
    x, ok = project_to_level(ctx, x, lev, iters=3, tol=LEVEL_TOL * dprime[rr])
    return RowNodes(x[ok], lev[ok])
