"""Interval enclosures of feature-tree quantities over axis-aligned boxes.

The feature nodes' ``enclose(box, region)`` methods (:mod:`.features`) build on these: a
:data:`Box` is four ``(K,)`` arrays ``(xlo, xhi, ylo, yhi)``; an :class:`Enclosure` holds,
for each box, an interval containing the node's distance (geometric nodes) and one
containing each constituent's fraction at every point of the box. Every bound is rounded
outwards (:func:`widen`): a few units in the last place of the result plus
:data:`GEOMETRY_ULPS` units of the coordinates' magnitude, which covers the rounding of the
floating-point geometry (hypot, projections, arctan2).

Distances to a point or a segment over a box are exact (the distance is convex: its maximum
is at a corner, its minimum between two convex sets at a vertex of one of them, or 0 where
they meet); to an arc or a circle, the distance to the full circle ``|rho - R|`` is exact
(``rho``, the distance to the centre, ranges exactly over the box), and it is the arc's
distance where the box's angular range lies within the arc; elsewhere it is a lower bound,
combined with the 1-Lipschitz bound ``d(c) +- r`` (``c`` the box's centre, ``r`` its
half-diagonal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...expr import Interval

__all__ = ["ANGLE_PAD", "GEOMETRY_ULPS", "Box", "Enclosure", "arc_angles", "arc_parameter",
           "blend", "centre_radius", "circle_distance", "constant_comp", "hull", "linear_comp",
           "magnitude", "point_box", "segment_box", "widen"]

#: A batch of boxes ``(xlo, xhi, ylo, yhi)``, each a ``(K,)`` array.
Box = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]

_EPS = np.finfo(np.float64).eps
#: units in the last place of the coordinates' magnitude added to geometric bounds
GEOMETRY_ULPS = 64.0
#: radians added on both sides of an angular range (arctan2 and the reduction mod 2 pi are
#: accurate to a few 1e-16)
ANGLE_PAD = 1e-12
_TWO_PI = 2.0 * math.pi


@dataclass
class Enclosure:
    """Enclosures over ``K`` boxes: ``dist`` ``(lo, hi)`` ``(K,)`` (None for a blend) and
    ``comp`` ``(lo, hi)`` ``(K, m)``."""

    dist: Interval | None
    comp: Interval


def widen(lo: np.ndarray, hi: np.ndarray, scale: np.ndarray | float = 0.0) -> Interval:
    """``[lo, hi]`` widened by 4 ulp of themselves and :data:`GEOMETRY_ULPS` ulp of
    ``scale`` (the coordinates' magnitude); NaN bounds become infinite."""
    pad = GEOMETRY_ULPS * _EPS * np.asarray(scale, dtype=float)
    lo = lo - (np.abs(lo) * 4.0 * _EPS + pad + np.finfo(float).tiny)
    hi = hi + (np.abs(hi) * 4.0 * _EPS + pad + np.finfo(float).tiny)
    return np.where(np.isnan(lo), -np.inf, lo), np.where(np.isnan(hi), np.inf, hi)


def magnitude(box: Box, *points) -> np.ndarray:
    """The largest coordinate magnitude ``(K,)`` of the boxes and the given points."""
    m = np.maximum(np.maximum(np.abs(box[0]), np.abs(box[1])),
                   np.maximum(np.abs(box[2]), np.abs(box[3])))
    for p in points:
        m = np.maximum(m, float(np.abs(np.asarray(p, dtype=float)).max(initial=0.0)))
    return m


def centre_radius(box: Box) -> tuple[np.ndarray, np.ndarray]:
    """Centres ``(K, 2)`` and half-diagonals ``(K,)`` of the boxes (the half-diagonal
    rounded up)."""
    xlo, xhi, ylo, yhi = box
    c = np.column_stack([0.5 * (xlo + xhi), 0.5 * (ylo + yhi)])
    r = 0.5 * np.hypot(xhi - xlo, yhi - ylo)
    return c, r * (1.0 + 8.0 * _EPS)


def _corners(box: Box) -> list[tuple[np.ndarray, np.ndarray]]:
    xlo, xhi, ylo, yhi = box
    return [(xlo, ylo), (xhi, ylo), (xhi, yhi), (xlo, yhi)]


def point_box(p, box: Box) -> Interval:
    """The exact range ``(lo, hi)`` of the distance to the point ``p`` over each box."""
    px, py = float(p[0]), float(p[1])
    xlo, xhi, ylo, yhi = box
    nx = np.maximum(np.maximum(xlo - px, px - xhi), 0.0)
    ny = np.maximum(np.maximum(ylo - py, py - yhi), 0.0)
    fx = np.maximum(np.abs(xlo - px), np.abs(xhi - px))
    fy = np.maximum(np.abs(ylo - py), np.abs(yhi - py))
    return widen(np.hypot(nx, ny), np.hypot(fx, fy), magnitude(box, p))


def _point_segment(x, y, p0, d, dd):
    u = np.clip(((x - p0[0]) * d[0] + (y - p0[1]) * d[1]) / dd, 0.0, 1.0)
    return np.hypot(x - (p0[0] + u * d[0]), y - (p0[1] + u * d[1]))


def segment_box(p0, p1, box: Box) -> tuple[Interval, Interval]:
    """For the segment ``p0 -> p1``: the exact ranges over each box of the distance and of
    the nearest point's parameter ``t = clip(u, 0, 1)`` (``u`` the projection, affine)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    dd = float(d @ d)
    xlo, xhi, ylo, yhi = box
    # u is affine: its range over a box is at the corners picked by the signs of d
    ux = np.where(d[0] >= 0, xlo, xhi), np.where(d[0] >= 0, xhi, xlo)
    uy = np.where(d[1] >= 0, ylo, yhi), np.where(d[1] >= 0, yhi, ylo)
    ulo = ((ux[0] - p0[0]) * d[0] + (uy[0] - p0[1]) * d[1]) / dd
    uhi = ((ux[1] - p0[0]) * d[0] + (uy[1] - p0[1]) * d[1]) / dd
    mag = magnitude(box, p0, p1)
    ulo, uhi = widen(ulo, uhi, mag / math.sqrt(dd))
    t = (np.clip(ulo, 0.0, 1.0), np.clip(uhi, 0.0, 1.0))
    corner = [_point_segment(x, y, p0, d, dd) for x, y in _corners(box)]
    far = np.maximum.reduce(corner)
    near = np.minimum.reduce(corner)
    for q in (p0, p1):
        near = np.minimum(near, point_box(q, box)[0])
    # separating axes: x, y and the segment's normal; no separation -> they meet
    apart = (max(p0[0], p1[0]) < xlo) | (min(p0[0], p1[0]) > xhi) | \
            (max(p0[1], p1[1]) < ylo) | (min(p0[1], p1[1]) > yhi)
    nrm = np.array([-d[1], d[0]])
    proj = [(x - p0[0]) * nrm[0] + (y - p0[1]) * nrm[1] for x, y in _corners(box)]
    tol = GEOMETRY_ULPS * _EPS * mag * math.sqrt(dd)
    apart |= (np.minimum.reduce(proj) > tol) | (np.maximum.reduce(proj) < -tol)
    near = np.where(apart, near, 0.0)
    return widen(near, far, mag), t


def circle_distance(center, radius: float, box: Box) -> tuple[Interval, Interval]:
    """``(|rho - R| range, rho range)`` over each box, ``rho`` the distance to ``center``:
    the exact range of the distance to the full circle."""
    rlo, rhi = point_box(center, box)
    lo = np.maximum(np.maximum(rlo - radius, radius - rhi), 0.0)
    hi = np.maximum(rhi - radius, radius - rlo)
    return widen(lo, hi, magnitude(box, center) + radius), (rlo, rhi)


def arc_angles(center, box: Box, rho_lo: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The polar angle's range ``(lo, hi, known)`` over each box seen from ``center``:
    ``known`` where the box keeps away from the centre (``rho_lo > 0``, the range is then
    spanned by the corners and narrower than pi); ``lo <= hi`` unwrapped around the angle
    of the box's centre."""
    cx, cy = float(center[0]), float(center[1])
    xlo, xhi, ylo, yhi = box
    ref = np.arctan2(0.5 * (ylo + yhi) - cy, 0.5 * (xlo + xhi) - cx)
    rel = []
    for x, y in _corners(box):
        a = np.arctan2(y - cy, x - cx) - ref
        rel.append(np.mod(a + math.pi, _TWO_PI) - math.pi)
    lo = ref + np.minimum.reduce(rel) - ANGLE_PAD
    hi = ref + np.maximum.reduce(rel) + ANGLE_PAD
    # a box almost touching the centre spans almost pi: a corner's angle could round to
    # the other side of the cut at +-pi, so such boxes are left undecided
    known = (rho_lo > 0.0) & (np.maximum.reduce([np.abs(r) for r in rel]) < 3.0)
    return lo, hi, known


def _t_on(lo, hi, s, mid):
    """The range of the arc parameter over ``a`` in ``[lo, hi]`` within ``[0, 2 pi]``:
    ``t = a / s`` up to the sweep ``s``, 1 up to ``mid`` (the nearer end is the last), 0
    beyond."""
    has1 = lo <= s
    tlo = np.where(has1, np.maximum(lo, 0.0) / s, np.inf)
    thi = np.where(has1, np.minimum(hi, s) / s, -np.inf)
    one = (hi > s) & (lo < mid)
    zero = hi >= mid
    tlo = np.where(one, np.minimum(tlo, 1.0), tlo)
    thi = np.where(one, 1.0, thi)
    tlo = np.where(zero, 0.0, tlo)
    thi = np.where(zero, np.maximum(thi, 0.0), thi)
    return tlo, thi


def arc_parameter(theta: tuple[np.ndarray, np.ndarray, np.ndarray], theta0: float,
                  sweep: float) -> tuple[Interval, np.ndarray]:
    """For an arc from ``theta0`` sweeping ``sweep`` (signed): the range of its nearest
    point's parameter ``t`` over boxes of polar-angle range ``theta`` (:func:`arc_angles`),
    and where the whole range lies within the arc (the nearest point is then radial)."""
    lo, hi, known = theta
    sgn, s = (1.0, sweep) if sweep >= 0 else (-1.0, -sweep)
    alo = np.where(sgn > 0, lo - theta0, theta0 - hi)
    width = hi - lo
    a0 = np.mod(alo, _TWO_PI)
    a1 = a0 + width
    mid = 0.5 * (s + _TWO_PI)
    wraps = a1 >= _TWO_PI
    t1 = _t_on(a0, np.minimum(a1, _TWO_PI), s, mid)
    t2 = _t_on(np.zeros_like(a1), np.where(wraps, a1 - _TWO_PI, 0.0), s, mid)
    tlo = np.where(wraps, np.minimum(t1[0], t2[0]), t1[0])
    thi = np.where(wraps, np.maximum(t1[1], t2[1]), t1[1])
    tlo = np.where(known, np.clip(tlo - 1e-12, 0.0, 1.0), 0.0)
    thi = np.where(known, np.clip(thi + 1e-12, 0.0, 1.0), 1.0)
    inside = known & ~wraps & (a1 <= s)
    return (tlo, thi), inside


def linear_comp(c0: np.ndarray, dc: np.ndarray, t: Interval) -> Interval:
    """The range ``(K, m)`` of ``c0 + t dc`` for ``t`` in the intervals ``t`` ``(K,)``."""
    a = c0 + t[0][:, None] * dc
    b = c0 + t[1][:, None] * dc
    return widen(np.minimum(a, b), np.maximum(a, b), np.abs(c0) + np.abs(dc))


def constant_comp(c0: np.ndarray, k: int) -> Interval:
    """A constant composition over ``k`` boxes."""
    v = np.broadcast_to(np.asarray(c0, float), (k, len(c0)))
    return v.copy(), v.copy()


def hull(parts: list[Interval]) -> Interval:
    """The elementwise hull of intervals."""
    return (np.minimum.reduce([p[0] for p in parts]), np.maximum.reduce([p[1] for p in parts]))


def blend(w: Interval, m1: Interval, m2: Interval) -> Interval:
    """The range of ``W M_1 + (1 - W) M_2`` (``W`` ``(K,)``, ``M`` ``(K, m)``) over
    independent intervals: multilinear, so its extremes are at the corners."""
    vals, mags = [], []
    with np.errstate(invalid="ignore", over="ignore"):
        for W in (w[0][:, None], w[1][:, None]):
            for a in m1:
                for b in m2:
                    wa, wb = W * a, (1.0 - W) * b
                    vals.append(wa + wb)
                    mags.append(np.abs(wa) + np.abs(wb) + np.abs(W))
    v = np.stack(vals)
    bad = np.isnan(v).any(axis=0)
    lo, hi = widen(v.min(axis=0), v.max(axis=0), np.max(mags, axis=0))
    return np.where(bad, -np.inf, lo), np.where(bad, np.inf, hi)
