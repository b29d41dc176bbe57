"""Grading between rows: intermediate levels in bands much higher than their neighbours.

Where |grad f| tends to 0 (a boundary where f ~ d^2 or d^3, an extremum) consecutive levels
lie far apart: the band between them is higher than its neighbours and than the maximum
element size, the rows on either side of it have node steps that do not match it, and
circumcenter filling plus repair make poor elements there. Here the band heights are
measured along gradient paths (:func:`~hetmesh.tri.layers.paths.gradient_profiles`), and the
bands that are too high get intermediate levels whose band heights grow by :data:`GRADE` per
unit length from both ends (:func:`grade_levels`).

The data, one frozen dataclass per concept: the paths' crossings of the levels
(:class:`PathCrossings`), the levels each piece really holds (:class:`PieceSpans`), the
events along every path (:class:`PathEvents`: a level crossed, a piece's end, a path's end
inside a band), the passages of paths through whole bands (:class:`Passages`) and the bands
with their median heights (:class:`Bands`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from enum import IntEnum

import numpy as np

from ...topology import unique
from ..workset import Context
from .levels import Levels, crossed_levels
from .paths import GradientPaths, gradient_profiles
from .pieces import Pieces
from .records import Records

log = logging.getLogger(__name__)

#: growth of the band height per unit length where high bands are subdivided
GRADE = 0.35

#: a piece's end band up to this many times the height wanted at its ends is left whole
MAX_RATIO = 1.5

#: a band above this many times the largest element's height (sqrt(3)/2 h_max) is subdivided
#: even between two levels
MAX_HEIGHT = 1.3


@dataclass(frozen=True)
class PathCrossings(Records):
    """Where the gradient paths cross the levels, one entry per crossing: the ``path``, the
    ``level`` index (into :class:`~hetmesh.tri.layers.levels.Levels`), and the ``arc``
    length and ``grad_norm`` |grad f| there, interpolated linearly between the samples."""

    path: np.ndarray
    level: np.ndarray
    arc: np.ndarray
    grad_norm: np.ndarray


def path_crossings(paths: GradientPaths, levels: Levels) -> PathCrossings:
    """Every crossing of a level between consecutive samples of one path."""
    pid, s, f, gn = paths.path, paths.arc, paths.f, paths.grad_norm
    kx = levels.index_after(paths.piece[pid], f)
    i = np.flatnonzero((pid[1:] == pid[:-1]) & (kx[1:] != kx[:-1]))
    ii, kk = crossed_levels(i, kx[i], kx[i + 1])
    u = np.clip((levels.value[kk] - f[ii]) / (f[ii + 1] - f[ii]), 0.0, 1.0)
    return PathCrossings(pid[ii], kk, s[ii] + u * (s[ii + 1] - s[ii]),
                         gn[ii] + u * (gn[ii + 1] - gn[ii]))


@dataclass(frozen=True)
class PieceSpans:
    """The levels a piece really holds, those its paths cross (the level list overshoots
    the piece's range of f): indices ``first`` .. ``last`` per piece, meaningful where
    ``holds``; and the range ``f_min`` .. ``f_max`` of f along its paths."""

    first: np.ndarray
    last: np.ndarray
    holds: np.ndarray
    f_min: np.ndarray
    f_max: np.ndarray


def piece_spans(paths: GradientPaths, cross: PathCrossings, n_pieces: int,
                n_levels: int) -> PieceSpans:
    """The levels each piece's paths cross, and the range of f along them."""
    first = np.full(n_pieces, n_levels, np.int64)  # the identities of min and max
    last = np.full(n_pieces, -1, np.int64)
    np.minimum.at(first, paths.piece[cross.path], cross.level)
    np.maximum.at(last, paths.piece[cross.path], cross.level)
    fmin = np.full(n_pieces, np.inf)
    fmax = np.full(n_pieces, -np.inf)
    np.minimum.at(fmin, paths.piece[paths.path], paths.f)
    np.maximum.at(fmax, paths.piece[paths.path], paths.f)
    return PieceSpans(first, last, last >= first, fmin, fmax)


class EventKind(IntEnum):
    """What happens at an event along a gradient path."""

    #: the path crosses a level
    LEVEL = 0
    #: the path starts or ends where f is near its piece's extreme: the band between the
    #: piece's last level and its end (a border that is a level curve, an extremum) ends here
    PIECE_END = 1
    #: the path starts or ends inside a band (a boundary transverse to the rows)
    OPEN_END = 2


@dataclass(frozen=True)
class PathEvents(Records):
    """The events along every path, in path order and along each path: the ``path``, the
    ``arc`` length, the ``kind`` (:class:`EventKind`) and, for a level crossed, the
    ``level`` index (0 for the other kinds)."""

    path: np.ndarray
    arc: np.ndarray
    kind: np.ndarray
    level: np.ndarray


def path_ends(paths: GradientPaths, levels: Levels, spans: PieceSpans, last_sample: bool):
    """The first (or last) sample of every path, as events: a piece end where f lies within
    15 % of the span between the piece's extreme and its nearest level, else an open end."""
    pid, f = paths.path, paths.f
    starts = np.flatnonzero(np.r_[True, pid[1:] != pid[:-1]])
    at = np.r_[starts[1:] - 1, len(pid) - 1] if last_sample else starts
    p = pid[at]
    pc = paths.piece[p]
    held = spans.holds[pc]
    lo_span = levels.value[np.where(held, spans.first[pc], 0)] - spans.f_min[pc]
    hi_span = spans.f_max[pc] - levels.value[np.where(held, spans.last[pc], 0)]
    at_end = held & ((f[at] - spans.f_min[pc] <= 0.15 * lo_span)
                     | (spans.f_max[pc] - f[at] <= 0.15 * hi_span))
    kind = np.where(at_end, EventKind.PIECE_END, EventKind.OPEN_END)
    return PathEvents(p, paths.arc[at], kind, np.zeros(len(at), np.int64))


def path_events(paths: GradientPaths, levels: Levels, cross: PathCrossings,
                spans: PieceSpans) -> PathEvents:
    """Every path's start, crossings and end, sorted by path and arc length."""
    ev = PathEvents.concat([
        path_ends(paths, levels, spans, last_sample=False),
        PathEvents(cross.path, cross.arc, np.full(len(cross), EventKind.LEVEL), cross.level),
        path_ends(paths, levels, spans, last_sample=True)])
    return ev.take(np.lexsort((ev.arc, ev.path)))


@dataclass(frozen=True)
class Passages(Records):
    """The passages of gradient paths through whole bands, one entry each: the ``path``,
    its ``piece``, the ``low`` level index of the band (the level below it; ``first - 1``
    for the band below a piece's first level) and the band's ``height`` along the path."""

    path: np.ndarray
    piece: np.ndarray
    low: np.ndarray
    height: np.ndarray


def passages(paths: GradientPaths, ev: PathEvents, spans: PieceSpans) -> Passages:
    """The stretches between consecutive events of a path that cross one band whole: from
    a level to the next, or between a piece's end and its first or last level."""
    same = ev.path[1:] == ev.path[:-1]
    a, b = ev.take(np.r_[same, False]), ev.take(np.r_[False, same])
    asc = paths.direction[a.path] > 0
    pc = paths.piece[a.path]
    first, last = spans.first[pc], spans.last[pc]
    # the band's low and high side (ascending: a, descending: b)
    lo_kind, hi_kind = np.where(asc, a.kind, b.kind), np.where(asc, b.kind, a.kind)
    lo_lvl, hi_lvl = np.where(asc, a.level, b.level), np.where(asc, b.level, a.level)
    lo_is, hi_is = lo_kind == EventKind.LEVEL, hi_kind == EventKind.LEVEL
    low = np.where(lo_is, lo_lvl, hi_lvl - 1)
    high = np.where(hi_is, hi_lvl, low + 1)
    whole = ((lo_is & hi_is) | (~lo_is & hi_is & (hi_lvl == first))
             | (lo_is & ~hi_is & (lo_lvl == last)))
    whole &= (a.kind != EventKind.OPEN_END) & (b.kind != EventKind.OPEN_END)
    whole &= (high - low == 1) & (low >= first - 1) & (high <= last + 1)
    return Passages(a.path[whole], pc[whole], low[whole], (b.arc - a.arc)[whole])


@dataclass(frozen=True)
class Bands(Records):
    """The bands that paths pass through whole, sorted by piece and low level: ``piece``,
    ``low`` (as in :class:`Passages`) and ``height``, the median of the passages' heights."""

    piece: np.ndarray
    low: np.ndarray
    height: np.ndarray


def collect_bands(ps: Passages) -> tuple[Bands, np.ndarray]:
    """The bands of the passages, and the band of every passage."""
    order = np.lexsort((ps.low, ps.piece))
    pc, lw = ps.piece[order], ps.low[order]
    new = np.r_[True, (pc[1:] != pc[:-1]) | (lw[1:] != lw[:-1])]
    band_of = np.empty(len(ps), np.int64)
    band_of[order] = np.cumsum(new) - 1
    nb = int(new.sum())
    height = np.array([np.median(ps.height[band_of == j]) for j in range(nb)])
    return Bands(pc[new], lw[new], height), band_of


@dataclass(frozen=True)
class Banding:
    """The bands that gradient paths pass through whole, and what grading asks of them.

    ``height_of`` maps ``(piece, low)`` to the band's median height; ``band_of`` gives the
    band (index into ``bands``) of every passage."""

    paths: GradientPaths
    levels: Levels
    spans: PieceSpans
    crossings: PathCrossings
    passages: Passages
    bands: Bands
    band_of: np.ndarray
    height_of: dict[tuple[int, int], float]

    def is_piece_end(self, j: int, upper: bool) -> bool:
        """Whether the upper (or lower) end of band ``j`` is its piece's end, not a level."""
        p, lw = int(self.bands.piece[j]), int(self.bands.low[j])
        return bool(lw + 1 > self.spans.last[p]) if upper else bool(lw < self.spans.first[p])

    def end_curves(self, j: int, upper: bool) -> np.ndarray:
        """The curves that the paths through band ``j`` start on at its upper (descending
        paths) or lower end (ascending paths), one entry per passage."""
        m = np.flatnonzero(self.band_of == j)
        d = self.paths.direction[self.passages.path[m]]
        m = m[(d < 0) if upper else (d > 0)]
        return self.paths.curve[self.passages.path[m]]

    def end_height(self, j: int, upper: bool, curve_step: np.ndarray, cap_h: float) -> float:
        """The band height wanted at one end of band ``j``: its neighbour's; at a piece's
        end, sqrt(3)/2 times the node spacing of the curve the paths start on there (a
        boundary with a chord limit), at most ``cap_h``."""
        p, lw = int(self.bands.piece[j]), int(self.bands.low[j])
        nbr = (p, lw + 1 if upper else lw - 1)
        if nbr in self.height_of and not self.is_piece_end(j, upper):
            return self.height_of[nbr]
        cur = self.end_curves(j, upper)
        st = float(np.median(curve_step[cur])) if len(cur) else np.inf
        return min(cap_h, np.sqrt(3.0) / 2.0 * st)


def banding(paths: GradientPaths, levels: Levels, n_pieces: int) -> Banding | None:
    """The bands of ``levels`` that ``paths`` pass through whole; None if there are none."""
    cross = path_crossings(paths, levels)
    if len(cross) == 0:
        return None
    spans = piece_spans(paths, cross, n_pieces, len(levels))
    ps = passages(paths, path_events(paths, levels, cross, spans), spans)
    if len(ps) == 0:
        return None
    bands, band_of = collect_bands(ps)
    height_of = {(int(p), int(lw)): h for p, lw, h in
                 zip(bands.piece, bands.low, bands.height.tolist())}
    return Banding(paths, levels, spans, cross, ps, bands, band_of, height_of)


def sub_band_bounds(H: float, ha: float, hb: float, cap_h: float) -> np.ndarray | None:
    """Where to subdivide a band of height ``H`` wanted ``ha`` high at its low end and
    ``hb`` at its upper end: sub-band heights follow sigma(t) = min(ha + GRADE t,
    hb + GRADE (H - t), cap_h), m = round(integral of dt / sigma) of them, the bounds where
    the integral reaches k / m of the whole. Returns the m - 1 inner bounds' distances
    from the low end, or None if the band stays whole (m < 2)."""
    t = np.linspace(0.0, H, 401)
    sig = np.minimum(np.minimum(ha + GRADE * t, hb + GRADE * (H - t)), cap_h)
    N = np.concatenate([[0.0], np.cumsum(0.5 * (1 / sig[1:] + 1 / sig[:-1]) * np.diff(t))])
    m = int(max(1, round(N[-1])))
    if m < 2:
        return None
    return np.interp((np.arange(1, m) / m) * N[-1], N, t)


@dataclass(frozen=True)
class Subdivision:
    """The intermediate levels of one band: their values ``f`` and row spacings ``dprime``
    in f (low to high), and the ``heights`` of the sub-bands (one more than the levels)."""

    f: np.ndarray
    dprime: np.ndarray
    heights: np.ndarray


def subdivide(b: Banding, j: int, pos: np.ndarray) -> Subdivision | None:
    """Intermediate levels of band ``j`` at distances ``pos`` from its low end, taken on its
    path of median height (f and |grad f| interpolated along it). A level's spacing in f
    makes its node step 2/sqrt(3) times the mean height of its two sub-bands (with
    dprime = |grad f| w, :func:`~hetmesh.tri.layers.rowstep.row_step`). None if the levels
    would not increase or a gradient vanishes there (rows need a gradient to follow)."""
    p, lw = int(b.bands.piece[j]), int(b.bands.low[j])
    H = b.bands.height[j]
    mm = np.flatnonzero(b.band_of == j)
    rep = b.passages.path[mm[np.argsort(b.passages.height[mm])[len(mm) // 2]]]
    sel = b.paths.path == rep
    ps, pf, pg = b.paths.arc[sel], b.paths.f[sel], b.paths.grad_norm[sel]
    # where the band starts on that path: the low level's crossing (or the path's end)
    asc = b.paths.direction[rep] > 0
    from_level = lw >= b.spans.first[p]
    if from_level:
        flo = b.levels.value[lw]
    else:
        flo = pf[0] if asc else pf[-1]
    if asc:
        sub_s = (np.interp(flo, pf, ps) if from_level else ps[0]) + pos
    else:  # descending path: f decreases along s
        sub_s = (np.interp(-flo, -pf, ps) if from_level else ps[-1]) - pos
    sub_f = np.interp(sub_s, ps, pf)
    sub_g = np.interp(sub_s, ps, pg)
    hs = np.diff(np.concatenate([[0.0], pos, [H]]))  # sub-band heights, low to high
    ok = (np.diff(np.concatenate([[flo], sub_f])) > 1e-12 * max(1.0, abs(flo)))
    ok &= np.isfinite(sub_g) & (sub_g > 1e-12)
    if not ok.all():
        return None
    return Subdivision(sub_f, sub_g * 0.5 * (hs[:-1] + hs[1:]), hs)


def grade_band(b: Banding, j: int, curve_step: np.ndarray, cap_h: float
               ) -> Subdivision | None:
    """The intermediate levels of band ``j``, or None where it stays whole: a band between
    two levels is split only above ``MAX_HEIGHT`` times the largest element's height (on
    a plate graded to a flat maximum, splitting bands 2.5 times their neighbours' height
    cost 20 % more elements), a band at a piece's end also above ``MAX_RATIO`` times the
    height wanted at its ends (:meth:`Banding.end_height`)."""
    H = b.bands.height[j]
    ha = b.end_height(j, False, curve_step, cap_h)
    hb = b.end_height(j, True, curve_step, cap_h)
    inner = not b.is_piece_end(j, False) and not b.is_piece_end(j, True)
    if (inner or H <= MAX_RATIO * min(ha, hb, cap_h)) and H <= cap_h * MAX_HEIGHT:
        return None
    pos = sub_band_bounds(H, ha, hb, cap_h)
    return None if pos is None else subdivide(b, j, pos)


def regraded_dprime(b: Banding, below: np.ndarray, above: np.ndarray,
                    dprime: float) -> np.ndarray:
    """The row spacings in f, changed for the rows next to a subdivided band and the rows
    next to a level that is not ``dprime`` away (evened out by
    :func:`~hetmesh.tri.layers.levels.piece_levels`): |grad f| along the row (the median at
    the paths' crossings) times the mean height of its two bands, where that differs from
    the row's spacing by more than 15 %. ``below`` and ``above`` are the heights of the
    sub-bands next to every row (nan: the band there is whole, its median height counts)."""
    lv, first, last = b.levels, b.spans.first, b.spans.last
    dps = lv.dprime.copy()
    for lvl in unique(b.crossings.level):
        p = int(lv.piece[lvl])
        nbl = [lv.value[k] for k in (lvl - 1, lvl + 1) if first[p] <= k <= last[p]]
        odd = any(abs(abs(v - lv.value[lvl]) - dprime) > 0.01 * dprime for v in nbl)
        if np.isnan(below[lvl]) and np.isnan(above[lvl]) and not odd:
            continue
        hh = [below[lvl] if not np.isnan(below[lvl]) else b.height_of.get((p, int(lvl) - 1)),
              above[lvl] if not np.isnan(above[lvl]) else b.height_of.get((p, int(lvl)))]
        hh = [h for h in hh if h is not None]
        if not hh:
            continue
        d = float(np.median(b.crossings.grad_norm[b.crossings.level == lvl])) * float(np.mean(hh))
        if np.isfinite(d) and d > 0.05 * dps[lvl] and abs(d / dps[lvl] - 1.0) > 0.15:
            dps[lvl] = d
    return dps


def grade_levels(ctx: Context, pieces: Pieces, levels: Levels, dprime: float,
                 chord_tol: float) -> tuple[Levels, np.ndarray]:
    """Subdivide the bands between rows that are much higher than their neighbours.

    The band heights are measured along gradient paths; a band at a piece's end (between
    its last level and a border that is a level curve, or an extremum) whose height H
    exceeds ``MAX_RATIO`` times the height wanted at its ends (the neighbouring band's
    height, or the boundary's own node spacing), and any band above ``MAX_HEIGHT`` x
    sqrt(3)/2 h_max, gets intermediate levels so that the band heights grow by ``GRADE``
    per unit length from both ends, up to sqrt(3)/2 h_max (:func:`grade_band`). Each new
    row and each row next to a subdivided band gets the spacing in f that makes its node
    step 2/sqrt(3) times the mean height of its two bands, and so does a row next to a
    level that is not dprime away (:func:`regraded_dprime`); a border level curve gets the
    node spacing of its sub-band. Returns the levels, new ones inserted in key order, and
    the node spacing cap of every curve (inf where none)."""
    spacing = np.full(len(ctx.curves), np.inf)
    paths = gradient_profiles(ctx, pieces, dprime)
    if paths is None or len(levels) == 0:
        return levels, spacing
    b = banding(paths, levels, pieces.n)
    if b is None:
        return levels, spacing
    cap_h = np.sqrt(3.0) / 2.0 * ctx.h_max
    cstep = ctx.domain.curve_batch.max_step(chord_tol)
    if log.isEnabledFor(logging.DEBUG):  # (piece, low level, height, wanted at both ends)
        log.debug("bands %s", [(int(b.bands.piece[j]), int(b.bands.low[j]),
                                round(float(b.bands.height[j]), 3),
                                round(b.end_height(j, False, cstep, cap_h), 3),
                                round(b.end_height(j, True, cstep, cap_h), 3))
                               for j in range(len(b.bands))])
    below = np.full(len(levels), np.nan)  # the sub-band heights next to every row
    above = np.full(len(levels), np.nan)
    new = []
    for j in range(len(b.bands)):
        sub = grade_band(b, j, cstep, cap_h)
        if sub is None:
            continue
        p, lw = int(b.bands.piece[j]), int(b.bands.low[j])
        new.append(Levels.of(np.full(len(sub.f), p, np.int64), sub.f, sub.dprime))
        # the rows bounding the band: their step follows the sub-band next to them
        first, last = b.spans.first[p], b.spans.last[p]
        if first <= lw <= last:
            above[lw] = sub.heights[0]
        if first <= lw + 1 <= last:
            below[lw + 1] = sub.heights[-1]
        for upper in (False, True):  # a piece's end: the border curve's node spacing
            if b.is_piece_end(j, upper):
                hend = 2.0 / np.sqrt(3.0) * (sub.heights[-1] if upper else sub.heights[0])
                for cur in unique(b.end_curves(j, upper)):
                    spacing[cur] = min(spacing[cur], hend)
    levels = replace(levels, dprime=regraded_dprime(b, below, above, dprime))
    if not new:
        return levels, spacing
    out = Levels.concat([levels] + new)
    log.info("layers: %d intermediate levels in %d flat bands", len(out) - len(levels),
             len(new))
    return out.take(np.argsort(out.key, kind="stable")), spacing
