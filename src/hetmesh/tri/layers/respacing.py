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

from ...topology import unique
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


def respace_rows(ctx: Context, starts: RowSeeds, index: np.ndarray, ix: np.ndarray,
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
    * every row's first node placed so that its nodes sit above the midpoints of the row
      before it (:func:`chain_phases`): where the wall meets the rows at a right angle,
      rows of even and odd level index start a full and a half spacing from it, as in a
      staggered lattice; where the wall is slanted, the start moves by the slant, so the
      lattice is not sheared across the whole piece (a slant of 70 degrees sheared every
      triangle's apex by a third of a spacing, q ~0.94 instead of ~1).

    ``starts`` are the rows' start points at the crossings of the levels with the curves,
    ``index`` the indices of their levels in the list of levels (``Levels.index``: adjacent
    rows of a piece have consecutive indices), ``trace`` the rows
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
    r_ix = ix[rows]
    units = row_units(ctx, lines, cdp[r_ix])
    phi = chain_phases(ctx, lines, units, index[r_ix], pcs[r_ix], cdp[r_ix],
                       start_phase(index[r_ix] % 2))
    even = even_nodes(ctx, lines, cdp[r_ix], lv[r_ix], phi, closed=False, units=units)
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


@dataclass(frozen=True)
class RowUnits:
    """Polylines measured in local row steps: ``cu`` (P,) the arc length of every point from
    its polyline's start; per polyline its length ``U``, its number of spacings ``n`` (a rung
    of the ladder, :data:`LADDER`) and its spacing ``a = U / n``; lengths in steps."""

    cu: np.ndarray
    U: np.ndarray
    n: np.ndarray
    a: np.ndarray


def row_units(ctx: Context, lines: Polylines, dprime) -> RowUnits:
    """:class:`RowUnits` of the polylines ``lines`` of rows with spacing ``dprime`` in f."""
    pts, starts = lines.points, lines.starts
    nrow = len(starts) - 1
    row = np.repeat(np.arange(nrow), np.diff(starts))
    seg = np.flatnonzero(row[1:] == row[:-1])
    mid = 0.5 * (pts[seg] + pts[seg + 1])
    du = np.linalg.norm(pts[seg + 1] - pts[seg], axis=1) / row_step_at(ctx, mid, dprime[row[seg]])
    U = np.bincount(row[seg], du, minlength=nrow)
    n = np.maximum(np.round(LADDER ** np.round(np.log(np.maximum(U, 1.0)) / np.log(LADDER))), 1)
    cu = np.zeros(len(pts))
    cu[seg + 1] = du
    cu = np.cumsum(cu)
    cu -= cu[starts[:-1]][row]
    return RowUnits(cu, U, n, U / n)


#: rows of fewer spacings keep the symmetric phase of their level's parity, and pass no phase
#: on: on short rows the walls, not the neighbours, shape the triangles
CHAIN_MIN_SPACINGS = 8

#: a phase within this many spacings of a multiple of 1/2 is taken as that multiple (rows
#: meeting a wall at a right angle keep the exact staggered lattice)
PHASE_SNAP = 0.02


def wrap_phase(phi: np.ndarray) -> np.ndarray:
    """Phases (in spacings) brought into [1/2, 3/2): the first node of an open row lies half
    a spacing to one and a half spacings from its start."""
    t = np.mod(phi - 0.5, 1.0)
    t = np.where(t > 1.0 - PHASE_SNAP, 0.0, t) + 0.5
    half = np.round(2.0 * t) / 2.0
    return np.where(np.abs(t - half) < PHASE_SNAP, half, t)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)


def chain_phases(ctx: Context, lines: Polylines, units: RowUnits, index: np.ndarray,
                 piece: np.ndarray, dprime: np.ndarray, phi0: np.ndarray) -> np.ndarray:
    """The phase of every open row (where its first node lies, in spacings from its start)
    that puts its nodes above the midpoints of the row before it.

    A row's predecessor is the row of the previous level of its piece (``index`` - 1)
    that passes within two steps of the row's start, on the same rung of the ladder (the
    same number of spacings n, at least :data:`CHAIN_MIN_SPACINGS`): rows of different n
    drift out of phase along their length anyway, and there the symmetric placement by
    parity is the better one (between nested arcs it is exact). With u the arc position (in
    the predecessor's spacings) of the start's foot on the predecessor, counted the way the
    row runs, and phi' the predecessor's phase counted the same way, the row's nodes at
    (phi + j) spacings lie above the predecessor's midpoints at (phi' + 1/2 + j') when
    phi = phi' + 1/2 - u (modulo 1, :func:`wrap_phase`). Rows without a predecessor keep
    ``phi0`` (by their level's parity). The phases are set level by level, in the order of
    ``index``."""
    pts, starts = lines.points, lines.starts
    nrow = len(starts) - 1
    row = np.repeat(np.arange(nrow), np.diff(starts))
    first = starts[:-1]
    S = pts[first]
    tS = _unit(pts[first + 1] - S)
    step_S = row_step_at(ctx, S, dprime)
    k = min(16, len(pts))
    d, j = cKDTree(pts).query(S, k=k)
    d, j = d.reshape(nrow, k), j.reshape(nrow, k)
    cand = row[j]
    long_ = units.n >= CHAIN_MIN_SPACINGS
    ok = ((index[cand] == index[:, None] - 1) & (piece[cand] == piece[:, None])
          & (d < 2.0 * step_S[:, None]) & long_[cand] & long_[:, None]
          & (units.n[cand] == units.n[:, None]))
    has = ok.any(axis=1)
    rr = np.flatnonzero(has)
    q = j[rr, np.argmax(ok[rr], axis=1)]  # the predecessor's polyline point nearest the start
    pr = row[q]
    # the foot of the start on the segment before or after q (the nearer one)
    lo = np.maximum(q - 1, starts[pr])
    hi = np.minimum(q + 1, starts[pr + 1] - 1)
    cu = units.cu

    def foot(a, b):
        """Distance to, and arc position of, the foot on segment (a, b): beyond the
        predecessor's ends the foot lies on its end segments extended (a start that
        projects before the predecessor's start has a negative position)."""
        ab = pts[b] - pts[a]
        t = ((S[rr] - pts[a]) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-300)
        t = np.clip(t, np.where(a == starts[pr], -np.inf, 0.0),
                    np.where(b == starts[pr + 1] - 1, np.inf, 1.0))
        x = pts[a] + t[:, None] * ab
        return np.linalg.norm(S[rr] - x, axis=1), cu[a] + t * (cu[b] - cu[a]), ab

    d0, u0, ab0 = foot(lo, q)
    d1, u1, ab1 = foot(q, hi)
    near0 = d0 <= d1
    u = np.where(near0, u0, u1)
    seg = np.where(near0[:, None], ab0, ab1)
    same = (seg * tS[rr]).sum(1) >= 0  # the predecessor runs the row's way
    a_p = units.a[pr]
    u_sp = np.where(same, u, units.U[pr] - u) / a_p  # in the predecessor's spacings
    phi = np.asarray(phi0, float).copy()
    lvl_of = index[rr]
    for lvl in unique(lvl_of):
        m = np.flatnonzero(lvl_of == lvl)
        r, p = rr[m], pr[m]
        prev = np.where(same[m], phi[p], np.mod(units.n[p] - phi[p], 1.0))
        phi[r] = wrap_phase(prev + 0.5 - u_sp[m])
    return phi


def even_nodes(ctx: Context, lines: Polylines, dprime, level, phi, closed: bool,
               units: RowUnits | None = None) -> RowNodes:
    """Nodes spaced evenly, in units of the local row step, along the polylines ``lines``
    (:func:`row_polylines`) of rows with spacing ``dprime`` in f at ``level``: n spacings per
    row, n its length in local steps rounded to a rung of the ladder (:data:`LADDER`), the
    first node ``phi`` spacings from the start (:func:`chain_phases`). An open row gets the
    nodes at (phi + j) spacings that lie at least half a spacing before its end (n - 1 for
    phi = 1, n for phi = 1/2); a closed row (first point = last) gets n, phi = 1 meaning a
    node on its start. ``units``: the lines' :func:`row_units`, if known. Returns the nodes
    projected onto the levels and inside the domain."""
    pts, starts = lines.points, lines.starts
    nrow = len(starts) - 1
    row = np.repeat(np.arange(nrow), np.diff(starts))
    u = row_units(ctx, lines, dprime) if units is None else units
    U, n, a, cu = u.U, u.n, u.a, u.cu
    phi = np.broadcast_to(np.asarray(phi, float), (nrow,))
    if closed:
        m = n.astype(np.int64)
        phase = phi % 1.0
    else:
        m = np.maximum(np.floor(n - 0.5 - phi + 1e-9) + 1, 0).astype(np.int64)
        phase = phi
    # targets in step units from each row's start, then points along its polyline
    rr = np.repeat(np.arange(nrow), m)
    jj = np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m)
    ut = a[rr] * (phase[rr] + jj)
    # one sorted key for all rows: row r's arc lengths, 0..U[r], become r * span + 0..U[r]
    span = 2.0 * (U.max() + 1)
    gk, tk = row * span + cu, rr * span + ut
    i = np.clip(np.searchsorted(gk, tk, side="right") - 1, starts[:-1][rr], starts[1:][rr] - 2)
    w = np.clip((tk - gk[i]) / np.maximum(gk[i + 1] - gk[i], 1e-300), 0.0, 1.0)
    x = pts[i] + w[:, None] * (pts[i + 1] - pts[i])
    lev = level[rr]
    x, ok = project_to_level(ctx, x, lev, iters=3, tol=LEVEL_TOL * dprime[rr])
    return RowNodes(x[ok], lev[ok])
