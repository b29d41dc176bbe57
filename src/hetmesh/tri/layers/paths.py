"""Gradient paths: steepest ascent and descent from just inside every curve.

The paths cross the level curves at right angles, so they measure the heights of the bands
between rows (:func:`gradient_profiles`, for :mod:`~hetmesh.tri.layers.grading`) and they
find the level curves that cross no curve of the domain, closed ones around a hole or an
extremum (:func:`gradient_seeds`, for :mod:`~hetmesh.tri.layers.tracing`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..workset import Context, project_to_level
from .curves import crosses_interface, side_points
from .levels import Levels, crossed_levels
from .pieces import OUTSIDE, Pieces
from .records import Records
from .rowstep import LEVEL_TOL


@dataclass(frozen=True)
class PathStarts(Records):
    """Where gradient paths start: ``point`` (P, 2), ``direction`` (P,) +1 for ascent and
    -1 for descent, the ``piece`` (P,) they run in, and the ``curve`` (P,) they start next
    to."""

    point: np.ndarray
    direction: np.ndarray
    piece: np.ndarray
    curve: np.ndarray


def path_starts(ctx: Context, pieces: Pieces, most: int) -> list[PathStarts]:
    """Start points of gradient paths: 4..``most`` points per curve (about two per h_max),
    just off the curve on each side that lies in a piece (``direction`` left at 0)."""
    starts = []
    for k, c in enumerate(ctx.curves):
        n = int(np.clip(np.ceil(2 * c.length / ctx.h_max), 4, most))
        ts = (np.arange(n) + 0.5) / n
        for side in (1, -1):
            pc = pieces.at(k, ts, side)
            ok = pc != OUTSIDE
            if ok.any():
                starts.append(PathStarts(side_points(ctx, k, ts[ok], side),
                                         np.zeros(int(ok.sum())), pc[ok],
                                         np.full(int(ok.sum()), k)))
    return starts


def two_way_starts(ctx: Context, pieces: Pieces, most: int) -> PathStarts | None:
    """The gradient paths' starts inside the domain, each twice (all ascents, then all
    descents), or None if no curve has a piece beside it."""
    starts = path_starts(ctx, pieces, most)
    if not starts:
        return None
    st = PathStarts.concat(starts)
    st = st.take(ctx.inside(st.point))
    return PathStarts(np.vstack([st.point, st.point]), np.repeat([1.0, -1.0], len(st)),
                      np.concatenate([st.piece, st.piece]),
                      np.concatenate([st.curve, st.curve]))


@dataclass(frozen=True)
class WalkStep:
    """One step of the live gradient paths (:func:`gradient_walk`), one entry per path:
    ``path`` its index among the starts, ``x`` and ``f`` where it stands, ``grad_norm``
    |grad f| there, ``x_next`` and ``f_next`` where the step leads, ``ok`` whether the path
    goes on from there, ``length`` the step's length."""

    path: np.ndarray
    x: np.ndarray
    f: np.ndarray
    grad_norm: np.ndarray
    x_next: np.ndarray
    f_next: np.ndarray
    ok: np.ndarray
    length: np.ndarray


def gradient_walk(ctx: Context, x: np.ndarray, dirn: np.ndarray, step: float, cap: float,
                  max_steps: int) -> Iterator[WalkStep]:
    """Steepest ascent (``dirn`` +1) or descent (-1) from the points ``x``, in steps of
    min(step / |grad f|, cap), until f stops changing monotonically, the path leaves the
    domain or crosses an interface. Yields every step of the paths still live."""
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
        yield WalkStep(ids, x, f, gn, xn, fn, ok, ds)
        ids, x, f, dirn = ids[ok], xn[ok], fn[ok], dirn[ok]


@dataclass(frozen=True)
class GradientPaths:
    """Gradient paths through every piece, as samples in path order.

    Per sample: ``path`` (S,) the path it lies on, ``arc`` (S,) the arc length from the
    path's start, ``f`` (S,) and ``grad_norm`` (S,) f and |grad f| there. Per path:
    ``piece`` (P,), ``curve`` (P,) the curve it starts next to, ``direction`` (P,) +1 for
    ascent, -1 for descent."""

    path: np.ndarray
    arc: np.ndarray
    f: np.ndarray
    grad_norm: np.ndarray
    piece: np.ndarray
    curve: np.ndarray
    direction: np.ndarray


def gradient_profiles(ctx: Context, pieces: Pieces, dprime: float) -> GradientPaths | None:
    """Gradient paths through every piece: steepest ascent and descent started just inside
    every curve, on each side, until f stops changing monotonically, the path leaves the
    domain or meets an interface (steps of dprime in f, at most 0.08 h_max long). None if
    no curve has a piece beside it."""
    start = two_way_starts(ctx, pieces, 32)
    if start is None:
        return None
    s = np.zeros(len(start))
    out = []
    max_steps = int(1.5 / dprime + 14 * ctx.domain.diameter / ctx.h_max + 100)
    for w in gradient_walk(ctx, start.point, start.direction, dprime, 0.08 * ctx.h_max,
                           max_steps):
        out.append((w.path, s[w.path], w.f, w.grad_norm))
        s[w.path[w.ok]] += w.length[w.ok]
    order = np.argsort(np.concatenate([o[0] for o in out]), kind="stable")
    path, arc, f, gn = (np.concatenate([o[j] for o in out])[order] for j in range(4))
    return GradientPaths(path, arc, f, gn, start.piece, start.curve, start.direction)


@dataclass(frozen=True)
class RowSeeds(Records):
    """Points to trace rows from: ``point`` (R, 2) on ``level`` (R,), the row's spacing in f
    ``dprime`` (R,) and its ``piece`` (R,)."""

    point: np.ndarray
    level: np.ndarray
    dprime: np.ndarray
    piece: np.ndarray

    @classmethod
    def empty(cls) -> RowSeeds:
        return cls(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0, np.int64))


def gradient_seeds(ctx: Context, pieces: Pieces, levels: Levels, dprime: float) -> RowSeeds:
    """Points on the levels found along gradient lines (steepest ascent and descent paths
    started just inside every curve, on each side, steps of dprime / 2 in f): they find the
    level curves that cross no curve at all (closed curves around a hole or an extremum).
    The seeds come in the order of the paths (stable)."""
    start = two_way_starts(ctx, pieces, 64)
    if start is None:
        return RowSeeds.empty()
    pc = start.piece
    kx = levels.index_after(pc, ctx.f(start.point))
    parts, path = [], []
    max_steps = int(4.0 / dprime + 8 * ctx.domain.diameter / ctx.h_max + 100)
    for w in gradient_walk(ctx, start.point, start.direction, 0.5 * dprime, 0.25 * ctx.h_max,
                           max_steps):
        kn = levels.index_after(pc[w.path], w.f_next)
        kc = kx[w.path]
        cr = np.flatnonzero(w.ok & (kn != kc))
        if cr.size:
            i, kk = crossed_levels(cr, kc[cr], kn[cr])
            L = levels.value[kk]
            u = (L - w.f[i]) / (w.f_next[i] - w.f[i])
            p = w.x[i] + u[:, None] * (w.x_next[i] - w.x[i])
            p, good = project_to_level(ctx, p, L, iters=3, tol=LEVEL_TOL * levels.dprime[kk])
            parts.append(RowSeeds(p[good], L[good], levels.dprime[kk][good],
                                  np.zeros(int(good.sum()), np.int64)))
            path.append(w.path[i][good])
        kx[w.path[w.ok]] = kn[w.ok]
    if not parts:
        return RowSeeds.empty()
    path = np.concatenate(path)
    o = np.argsort(path, kind="stable")
    seeds = RowSeeds.concat(parts).take(o)
    return RowSeeds(seeds.point, seeds.level, seeds.dprime, pc[path[o]])
