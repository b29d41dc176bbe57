"""Where the levels cross the curves, and the curve nodes between the crossings.

Every row that meets a curve ends on a node of it: the crossings are pinned curve nodes
(:func:`curve_crossings`), and the curve is divided between them at the local row step
(:func:`curve_params`), so the triangles along a curve are as high as the band next to it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import pslg_from_parameters
from ..workset import Context, WorkSet, workset_from_pslg
from .curves import side_points
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
            a, b = ts[seg], ts[seg + 1]
            fa = f[seg] - level
            for _ in range(40):  # bisection on t, vectorised
                m = 0.5 * (a + b)
                fm = ctx.f(side_points(ctx, k, m, ev)) - level
                left = np.sign(fm) == np.sign(fa)
                a = np.where(left, m, a)
                fa = np.where(left, fm, fa)
                b = np.where(left, b, m)
            parts.append(Crossings(curve=np.full(len(a), k), t=0.5 * (a + b), level=level,
                                   side=np.full(len(a), side), piece=pc[seg],
                                   dprime=levels.dprime[kk]))
    return Crossings.concat(parts) if parts else Crossings.empty()


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
