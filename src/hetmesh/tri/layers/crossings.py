"""Where the levels cross the curves, and the curve nodes between the crossings.

Every row that meets a curve ends at a node of it: the crossings are pinned curve nodes
(:func:`curve_crossings`), and the curve is divided between them at the local row step
(:func:`curve_params`), so the triangles along a curve are as high as the band next to it.
Where the rows meet a curve square, one band after the other, the curve nodes lie half-way
between the levels instead (:func:`wall_pins`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...topology import unique
from ..geometry import pslg_from_parameters
from ..workset import Context, WorkSet, workset_from_pslg
from .curves import side_eps, side_points
from .levels import Levels, crossed_levels
from .pieces import OUTSIDE, Pieces
from .records import Records
from .rowstep import row_step_at


@dataclass(frozen=True)
class Crossings(Records):
    """Points where a level curve crosses a curve of the domain, seen from one piece.

    Attributes
    ----------
    curve : (C,) int, the curve crossed.
    t : (C,) float, the parameter of the crossing on that curve.
    level : (C,) float, the level crossing there.
    side : (C,) int, +1 / -1: the piece lies left / right of the curve (increasing t).
    piece : (C,) int, that piece.
    dprime : (C,) float, the spacing in f of the level's row (:class:`~.levels.Levels`).
    """

    curve: np.ndarray
    t: np.ndarray
    level: np.ndarray
    side: np.ndarray
    piece: np.ndarray
    dprime: np.ndarray

    @classmethod
    def empty(cls) -> Crossings:
        z = np.zeros(0)
        return cls(z.astype(np.int64), z, z, z.astype(np.int64), z.astype(np.int64), z)


def curve_crossings(ctx: Context, pieces: Pieces, levels: Levels, dprime: float) -> Crossings:
    """Where the levels cross every curve, from the side of each piece along it: the curve
    sampled (at least 8 samples per row crossing, from the largest |grad f| along it), then
    every change of the level index between two samples of one piece bisected on t."""
    parts = []
    for k, c in enumerate(ctx.curves):
        for side, ev in pieces.sides(k, ctx):
            n = 64
            ts = np.linspace(0, 1, n + 1)
            g = np.linalg.norm(ctx.grad_f(side_points(ctx, k, ts, ev)), axis=1).max()
            # resolve the rows: at least 8 samples per row crossing
            n = int(min(200_000, max(256, 8 * c.length * g / dprime)))
            ts = np.linspace(0, 1, n + 1)
            f = ctx.f(side_points(ctx, k, ts, ev))
            pc = pieces.at(k, ts, side)
            idx = levels.index_after(pc, f)
            i = np.flatnonzero((idx[1:] != idx[:-1]) & (pc[1:] == pc[:-1])
                               & (pc[1:] != OUTSIDE))
            if i.size == 0:
                continue
            seg, kk = crossed_levels(i, idx[i], idx[i + 1])
            level = levels.value[kk]
            t = bisect_on_t(lambda m, k=k, ev=ev, level=level:
                            ctx.f(side_points(ctx, k, m, ev)) - level,
                            ts[seg], ts[seg + 1], f[seg] - level)
            parts.append(Crossings(curve=np.full(len(t), k), t=t, level=level,
                                   side=np.full(len(t), side), piece=pc[seg],
                                   dprime=levels.dprime[kk]))
    return Crossings.concat(parts) if parts else Crossings.empty()


def bisect_on_t(g, a: np.ndarray, b: np.ndarray, ga: np.ndarray, steps: int = 40
                ) -> np.ndarray:
    """Roots of ``g`` (vectorised, ``t -> values``) in the brackets ``[a, b]``, ``ga`` its
    values at ``a`` (of the other sign than at ``b``): ``steps`` bisections, the mid-points
    of the last brackets."""
    for _ in range(steps):
        m = 0.5 * (a + b)
        gm = g(m)
        left = np.sign(gm) == np.sign(ga)
        a, ga, b = np.where(left, m, a), np.where(left, gm, ga), np.where(left, b, m)
    return 0.5 * (a + b)


@dataclass(frozen=True)
class CurveNodes:
    """The nodes of one curve: ``t`` its sorted parameters, from 0 to 1, and ``pinned``
    those of the level crossings (nodes that stay where they are)."""

    t: np.ndarray
    pinned: np.ndarray


def curve_params(ctx: Context, cid: np.ndarray, tt: np.ndarray, dprime: float,
                 chord_tol: float, spacing: np.ndarray | None = None) -> list[CurveNodes]:
    """The nodes of every curve: 0, the crossings ``tt`` of curve ``cid``, 1, and between
    them nodes at the local row step (within the chord tolerance's step cap, the per-curve
    ``spacing`` cap of :func:`~hetmesh.tri.layers.grading.grade_levels` and the minimum
    interval counts of :mod:`hetmesh.tri.geometry`). Crossings closer than 0.3 of the row
    step to a curve's end or to each other are dropped."""
    batch = ctx.domain.curve_batch
    chord_cap, nmin = batch.max_step(chord_tol), batch.min_intervals()
    cap = chord_cap
    if spacing is not None:
        cap = np.minimum(cap, spacing)
    out = []
    for k, c in enumerate(ctx.curves):
        t = np.sort(tt[cid == k])
        if len(t):  # drop crossings too close to the curve's ends or to each other
            s = row_step_at(ctx, c.point(t), dprime)
            ok = np.minimum(t, 1 - t) * c.length > 0.3 * s
            t, s = t[ok], s[ok]
        if len(t) > 1:
            keep = np.ones(len(t), bool)
            keep[1:] = np.diff(t) * c.length > 0.3 * np.minimum(s[1:], s[:-1])
            t = t[keep]
        full = np.concatenate([[0.0], t, [1.0]])
        a, b = full[:-1], full[1:]
        h = np.minimum(row_step_at(ctx, c.point(0.5 * (a + b)), dprime), cap[k])
        nseg = np.maximum(np.ceil((b - a) * c.length / (1.15 * h)), np.ceil(nmin[k] * (b - a)))
        # the chord tolerance is a bound, not a target: never a chord longer than its cap
        nseg = np.maximum(nseg, np.ceil((b - a) * c.length / chord_cap[k] * (1 - 1e-12)))
        nseg = np.maximum(nseg, 1).astype(np.int64)
        gap = np.repeat(np.arange(len(a)), nseg)
        step = np.arange(nseg.sum()) - np.repeat(np.cumsum(nseg) - nseg, nseg) + 1
        inner = a[gap] + step * ((b - a) / nseg)[gap]  # as np.linspace(a, b, nseg + 1)[1:]
        inner[np.cumsum(nseg) - 1] = b  # each gap ends exactly on its crossing (or 1)
        out.append(CurveNodes(np.concatenate([[0.0], inner]), t))
    return out


def pslg_workset(ctx: Context, nodes: list[CurveNodes]) -> WorkSet:
    """The work set of the PSLG with the nodes of every curve (curve ends shared)."""
    ts = [n.t for n in nodes]
    offsets = np.r_[0, np.cumsum([len(x) for x in ts])]
    pslg = pslg_from_parameters(ctx.domain, offsets, np.concatenate(ts))
    return workset_from_pslg(pslg, [n.pinned for n in nodes])


#: a crossing is square to its curve where the curve's tangent and the gradient of f (the
#: normal of the level) are within this cosine of each other (about 10 degrees)
SQUARE_COS = 0.985


def curve_points(ctx: Context, curve: np.ndarray, t: np.ndarray, ev: np.ndarray
                 ) -> np.ndarray:
    """The points at parameters ``t`` of curves ``curve``: on the curve (``ev`` 0) or just
    off it, to the left (+1) or right (-1) of increasing t (as :func:`~.curves.side_points`,
    for many curves at once)."""
    batch = ctx.domain.curve_batch
    tg = batch.tangents(curve, t)
    off = (ev * side_eps(ctx))[:, None] * np.column_stack([-tg[:, 1], tg[:, 0]])
    return batch.points(curve, t) + off


def wall_pins(ctx: Context, levels: Levels, cross: Crossings) -> tuple[np.ndarray, np.ndarray]:
    """The pinned curve nodes, ``(curve, t)``: the crossings, except where the rows meet a
    curve square (within :data:`SQUARE_COS`) one band after the other; there the curve
    nodes lie half-way between the levels.

    Why: rows of alternate phases (:func:`~.respacing.start_phase`) end a full and a half
    spacing from a curve that they meet at a right angle. With a node at every crossing,
    the triangle on each curve edge has its two curve nodes on adjacent levels and its apex
    on one of them: a right triangle, q <= 0.83 (about 0.78 after smoothing: unit_square's
    side walls). With curve nodes half-way between the levels, the curve edge spans one band
    from mid-level to mid-level and the triangle on it has its apex on the level between:
    near-equilateral, the rows' ends staying where they are.

    A gap between two consecutive crossings of one curve side, of adjacent levels of one
    piece, or between a curve's end and a crossing a full band (within 10 %) from it in f,
    is *square* when the curve is square to the levels at both (within :data:`SQUARE_COS`)
    and the gap is one curve interval (shorter than 1.15 local row steps, as
    :func:`curve_params` divides it). A crossing whose gaps on both sides are square is
    dropped, and every square gap next to a dropped crossing gets a node at the mean of the
    f of its two ends (bisection on t). Runs of one square gap between two crossings are
    left as they are (a node in the middle would halve the band on the curve); curve ends
    stay nodes. Returns the crossings unchanged where no gap is square (bit-identical
    meshes)."""
    if len(cross) == 0:
        return cross.curve, cross.t
    # the crossings, and both ends of every curve side they lie on (f there as their level)
    grp = unique(np.column_stack([cross.curve, cross.side]), axis=0)
    ge = np.repeat(grp, 2, axis=0)
    te = np.tile([0.0, 1.0], len(grp))
    eve = np.where(ctx.boundary_curve[ge[:, 0]], 0, ge[:, 1])
    fe = ctx.f(curve_points(ctx, ge[:, 0], te, eve))
    o = np.lexsort((np.r_[cross.t, te], np.r_[cross.side, ge[:, 1]],
                    np.r_[cross.curve, ge[:, 0]]))
    nc = len(cross)
    end = o >= nc
    c, side = np.r_[cross.curve, ge[:, 0]][o], np.r_[cross.side, ge[:, 1]][o]
    t, lv = np.r_[cross.t, te][o], np.r_[cross.level, fe][o]
    pc = np.r_[cross.piece, np.full(len(te), -1)][o]
    dp = np.r_[cross.dprime, np.full(len(te), np.inf)][o]
    ix = np.where(end, -10, levels.index(np.maximum(pc, 0), lv))
    ev = np.where(ctx.boundary_curve[c], 0, side)
    g = ctx.grad_f(curve_points(ctx, c, t, ev))
    gn = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
    square = np.abs((gn * ctx.domain.curve_batch.tangents(c, t)).sum(1)) > SQUARE_COS
    # consecutive crossings of adjacent levels, or a curve end a full band from a crossing
    step_f = np.minimum(dp[1:], dp[:-1])
    df = np.abs(lv[1:] - lv[:-1])
    adjacent = np.where(end[1:] | end[:-1], np.abs(df - step_f) < 0.1 * step_f,
                        (np.abs(ix[1:] - ix[:-1]) == 1) & (pc[1:] == pc[:-1]))
    a = np.flatnonzero((c[1:] == c[:-1]) & (side[1:] == side[:-1]) & ~(end[1:] & end[:-1])
                       & adjacent & square[1:] & square[:-1])
    if len(a):
        length = np.array([ctx.curves[k].length for k in c[a]])
        mid = curve_points(ctx, c[a], 0.5 * (t[a] + t[a + 1]), ev[a])
        step = row_step_at(ctx, mid, step_f[a])
        a = a[(t[a + 1] - t[a]) * length < 1.15 * step]
    gaps = np.bincount(a, minlength=len(c)) + np.bincount(a + 1, minlength=len(c))
    drop = (gaps == 2) & ~end
    a = a[drop[a] | drop[a + 1]]
    if len(a) == 0:
        return cross.curve, cross.t
    keep = ~drop & ~end
    # the mid-levels, all gaps at once
    target = 0.5 * (lv[a] + lv[a + 1])
    mid_t = bisect_on_t(lambda m: ctx.f(curve_points(ctx, c[a], m, ev[a])) - target,
                        t[a], t[a + 1], lv[a] - target)
    return np.concatenate([c[keep], c[a]]), np.concatenate([t[keep], mid_t])
