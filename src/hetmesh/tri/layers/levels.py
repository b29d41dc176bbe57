"""Level selection: the row levels of every piece, counted from an anchor in steps of delta'.

The rows of the placement lie on the level curves f = c_k of the composition, c_k = anchor
-/+ k * delta' with delta' = beta * delta_0 (``Context.row_spacing`` times the threshold): two
adjacent rows differ by delta' in f, so a triangle with its vertices on two adjacent rows has
delta(T) = delta' < delta_0 (delta(T) as the paper's Eqs. 14-15 define it, from the vertices'
compositions).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ...density import background_points
from ...topology import unique
from ..workset import Context
from .curves import side_points
from .pieces import OUTSIDE, Pieces
from .records import Records

#: The levels of all pieces sort on one key, :func:`level_key` = ``piece * KEY_STRIDE +
#: level``. Levels lie within [-1.9, 2.9] (:func:`piece_levels` clamps them there), so the
#: pieces' ranges of keys do not overlap, and a search for ``level_key(p, f)`` among the keys
#: finds f's place among the levels of piece p.
KEY_STRIDE = 8.0


def level_key(piece, value):
    """The sort key of level ``value`` of piece ``piece``: ``piece * KEY_STRIDE + value``."""
    return piece * KEY_STRIDE + value


@dataclass(frozen=True)
class Levels(Records):
    """The row levels of all pieces, one entry per row level, sorted by :func:`level_key`.

    Attributes
    ----------
    piece : (K,) int, the piece the level belongs to.
    value : (K,) float, the level, a value of f.
    dprime : (K,) float, the row's spacing in f: its node step along the row is
        2 / sqrt(3) * dprime / |grad f| (:func:`~hetmesh.tri.layers.rowstep.row_step`).
        delta' for a level counted from the anchor; other values next to graded bands
        (:func:`~hetmesh.tri.layers.grading.grade_levels`).
    key : (K,) float, ``level_key(piece, value)``, ascending.
    """

    piece: np.ndarray
    value: np.ndarray
    dprime: np.ndarray
    key: np.ndarray

    @classmethod
    def of(cls, piece, value, dprime) -> Levels:
        """Levels from their pieces, values and spacings (given in key order)."""
        piece = np.asarray(piece, np.int64)
        value = np.asarray(value, float)
        return cls(piece, value, np.asarray(dprime, float), level_key(piece, value))

    @classmethod
    def empty(cls) -> Levels:
        return cls.of(np.zeros(0, np.int64), np.zeros(0), np.zeros(0))

    def index_after(self, piece, f):
        """How many levels sort before or at ``f`` of piece ``piece``: f lies between levels
        ``i - 1`` and ``i`` of the list (with ``i`` the result), a crossing of level j
        between two points changes the index from j to j + 1."""
        return np.searchsorted(self.key, level_key(piece, f), side="right")

    def index(self, piece, value):
        """The index in the list of every row level ``value`` of ``piece`` (adjacent rows of
        a piece have consecutive indices)."""
        return np.searchsorted(self.key, level_key(piece, value), side="left")

    def parity(self, piece, value):
        """0 or 1 for every row level ``value`` of ``piece``: its index in the list, modulo 2
        (adjacent rows of a piece alternate)."""
        return self.index(piece, value) % 2

    def dprime_of(self, rlev: np.ndarray) -> np.ndarray:
        """The spacing in f of the rows at levels ``rlev`` (the smallest of equal levels)."""
        o = np.lexsort((self.dprime, self.value))
        lv, dp = self.value[o], self.dprime[o]
        i = np.clip(np.searchsorted(lv, rlev, side="left"), 0, len(lv) - 1)
        return dp[i]


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


class BorderLevel(NamedTuple):
    """A level curve on the border of a piece: the integral of |grad f| along it (how many
    row nodes it carries), its length and its value of f."""

    weight: float
    length: float
    value: float


def border_levels(ctx: Context, pieces: Pieces, dprime: float):
    """What the borders of every piece hold: ``(holders, near, values)``; ``holders[p]`` the
    level curves on the border of piece p (:class:`BorderLevel`), ``near[p]`` the median f of
    the borders that are nearly level curves (f varies by less than ``dprime`` / 4 along
    them), ``values`` samples of f on all curves and inside the domain."""
    ts = (np.arange(400) + 0.5) / 400
    holders: list[list[BorderLevel]] = [[] for _ in range(pieces.n)]
    near: list[list[float]] = [[] for _ in range(pieces.n)]
    vals = []
    for k, c in enumerate(ctx.curves):
        for side, ev in pieces.sides(k, ctx):
            pc = pieces.at(k, ts, side)
            f = ctx.f(side_points(ctx, k, ts, ev))
            vals.append(f)
            for p in unique(pc[pc != OUTSIDE]):
                m = pc == p
                if m.sum() < 0.9 * len(ts):
                    continue
                if np.ptp(f[m]) > 1e-7:
                    if np.ptp(f[m]) < 0.25 * dprime:
                        near[p].append(float(np.median(f[m])))
                    continue
                g = np.linalg.norm(ctx.grad_f(side_points(ctx, k, ts[m], ev)), axis=1)
                holders[p].append(BorderLevel(float(g.sum() * c.length / len(ts)), c.length,
                                              float(f[m].mean())))
    vals.append(ctx.f(background_points(ctx.domain, 100)))
    return holders, near, np.concatenate(vals)


def even_out(L: np.ndarray, a: float, borders: np.ndarray, dprime: float) -> np.ndarray:
    """Levels ``L`` counted from ``a``, with the last level before every other border level
    ``v`` in ``borders`` moved half-way between its neighbour and v where it lies closer than
    ``dprime`` / 4 to v (no thin strip along the border). Changes and returns ``L``."""
    for v in borders[np.abs(borders - a) > 0.02 * dprime]:
        between = np.flatnonzero((L > min(a, v)) & (L < max(a, v)))
        if len(between) == 0:
            continue
        j = len(between)
        last, nxt = (between[-1], between[max(j - 2, 0)]) if v > a else \
            (between[0], between[min(1, j - 1)])
        if abs(v - L[last]) < 0.25 * dprime:
            prev = L[nxt] if len(between) > 1 else a
            L[last] = 0.5 * (prev + v)
    return L


def piece_levels(ctx: Context, pieces: Pieces, dprime: float) -> Levels:
    """The row levels of every piece, spacing ``dprime`` in f.

    A piece counts its levels ``anchor -/+ k * dprime`` from the level curve on its border
    that carries the most row nodes (the largest integral of |grad f| along it: the rows
    next to it keep their full spacing where elements are smallest); without one, from the
    boundary's extreme value (:func:`anchor_level`). Levels closer than 0.02 dprime to another
    level curve of the border are dropped (they would run along it), and where the last
    level before another level curve leaves a gap under dprime / 4, the last two gaps are
    evened out instead of leaving a thin strip (:func:`even_out`). A border along which f
    varies by less than dprime / 4 (nearly a level curve, such as the top edge of a plate
    graded to a flat maximum) is evened against too (at its median value), but it is no
    anchor: a level just below it would lie too close to the border for its row step to be
    kept, and the flat zone would be left to the fill and the repair loop."""
    a0 = anchor_level(ctx)
    holders, near, vals = border_levels(ctx, pieces, dprime)
    lo, hi = max(float(vals.min()) - dprime, -1.9), min(float(vals.max()) + dprime, 2.9)
    piece, levs = [], []
    for p in range(pieces.n):
        hs = sorted(holders[p], key=lambda h: (-h.weight, -h.length))
        if hs:
            a = hs[0].value
            if abs(a - a0) < 1e-7:
                a = a0  # the boundary's own value (bit-identical rows)
        else:
            a = a0
        kdn = np.arange(1, int(np.floor((a - lo) / dprime)) + 1)
        kup = np.arange(1, int(np.floor((hi - a) / dprime)) + 1)
        L = np.concatenate([a - kdn[::-1] * dprime, a + kup * dprime])
        hv = np.array([h.value for h in hs]) if hs else np.zeros(0)
        if len(hv):
            L = L[np.abs(L[:, None] - hv[None, :]).min(axis=1) > 0.02 * dprime]
        L = np.sort(even_out(L, a, np.concatenate([hv, near[p]]) if near[p] else hv, dprime))
        piece.append(np.full(len(L), p, np.int64))
        levs.append(L)
    if not levs:
        return Levels.empty()
    levs = np.concatenate(levs)
    return Levels.of(np.concatenate(piece), levs, np.full(len(levs), dprime))


def crossed_levels(i: np.ndarray, k0: np.ndarray, k1: np.ndarray):
    """The levels crossed between consecutive samples: sample ``i[j]`` has level index
    ``k0[j]`` (:meth:`Levels.index_after`) and the next one ``k1[j]``; every level between
    is crossed. Returns ``(sample, level index)`` of every crossing, the sample repeated."""
    lo = np.minimum(k0, k1)
    cnt = np.abs(k1 - k0)
    return np.repeat(i, cnt), np.repeat(lo, cnt) + (np.arange(cnt.sum())
                                                    - np.repeat(np.cumsum(cnt) - cnt, cnt))
