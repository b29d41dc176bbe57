"""Boundary and interface curves: straight segments and circular arcs.

Every curve is parametrised by ``t`` in ``[0, 1]`` proportional to arclength. All methods take
whole arrays: ``point(t)`` returns ``t.shape + (2,)``, ``project(points)`` returns
``points.shape[:-1]``. :class:`CurveBatch` holds many curves as flat arrays, so that sampling,
distances and areas of thousands of curves need no Python loop over curves.

Examples
--------
>>> arc = Arc.through((42, 24), (21, 30), (0, 24))
>>> round(arc.radius, 6), tuple(round(c, 6) for c in arc.center)
(39.75, (21.0, -9.75))
>>> float(Segment((0, 0), (3, 4)).length)
5.0
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely

from hetmesh.errors import GeometryError

__all__ = [
    "Segment",
    "Arc",
    "Curve",
    "CurveBatch",
    "SizeLike",
    "segments_through",
    "fmt_point",
    "fmt_num",
    "sample_parameters",
    "tolerance",
]

TWO_PI = 2.0 * math.pi
EPS = float(np.finfo(float).eps)
REL_TOL = 1e-9  # relative geometric tolerance (times the length scale)

MAX_SAMPLES = 50_000_000  # most points sample_parameters places

SizeLike = float | Callable[[np.ndarray], np.ndarray]


# ----------------------------------------------------------------------------- formatting
def fmt_num(v: float) -> str:
    """A number as the user would write it (12 significant digits, no trailing zeros)."""
    return f"{float(v):.12g}"


def fmt_point(p: Sequence[float]) -> str:
    """A point as ``(x, y)``, e.g. ``(0, 24.5)``."""
    return f"({fmt_num(p[0])}, {fmt_num(p[1])})"


def _prefix(where: str) -> str:
    return f"{where}: " if where else ""


def _pair(value, what: str) -> tuple[float, float]:
    if type(value) is tuple and len(value) == 2 and all(type(v) is float for v in value):
        return value  # fast path
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise GeometryError(f"{what} must be a pair of numbers, got {value!r}") from None
    if a.shape != (2,):
        raise GeometryError(f"{what} must be a pair of numbers, got {value!r}")
    return (float(a[0]), float(a[1]))


def _points(points) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.shape[-1:] != (2,):
        raise GeometryError(f"points must have shape (..., 2), got {p.shape}")
    return p


def tolerance(scale: float, magnitude: float) -> float:
    """Relative tolerance: ``1e-9`` of the scale plus rounding of the coordinates' size."""
    return REL_TOL * scale + 64.0 * EPS * magnitude


# ----------------------------------------------------------------------------- segment
@dataclass(frozen=True)
class Segment:
    """The straight segment from ``p0`` to ``p1``.

    Examples
    --------
    >>> s = Segment((0, 0), (2, 0))
    >>> s.point([0, 0.5]).tolist(), s.project([[1, 5], [-3, 0]]).tolist()
    ([[0.0, 0.0], [1.0, 0.0]], [0.5, 0.0])
    """

    p0: tuple[float, float]
    p1: tuple[float, float]
    name: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "p0", _pair(self.p0, "segment p0"))
        object.__setattr__(self, "p1", _pair(self.p1, "segment p1"))

    @property
    def start(self) -> np.ndarray:
        return np.array(self.p0)

    @property
    def end(self) -> np.ndarray:
        return np.array(self.p1)

    @property
    def length(self) -> float:
        return math.hypot(self.p1[0] - self.p0[0], self.p1[1] - self.p0[1])

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        (x0, y0), (x1, y1) = self.p0, self.p1
        return (min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1))

    def _d(self) -> np.ndarray:
        return np.array([self.p1[0] - self.p0[0], self.p1[1] - self.p0[1]])

    def point(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)[..., None]
        return np.array(self.p0) + t * self._d()

    def tangent(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        d = self._d()
        n = np.hypot(*d)
        return np.broadcast_to(d / n if n > 0 else d, t.shape + (2,)).copy()

    def project(self, points) -> np.ndarray:
        p = _points(points) - np.array(self.p0)
        d = self._d()
        dd = float(d @ d)
        if dd == 0.0:
            return np.zeros(p.shape[:-1])
        return np.clip((p @ d) / dd, 0.0, 1.0)

    def distance(self, points) -> np.ndarray:
        p = _points(points) - np.array(self.p0)
        q = self.project(points)[..., None] * self._d()
        return np.hypot(*np.moveaxis(p - q, -1, 0))

    def translated(self, offset) -> Segment:
        o = np.asarray(_pair(offset, "offset"))
        return Segment(np.array(self.p0) + o, np.array(self.p1) + o, self.name)

    def scaled(self, factor: float) -> Segment:
        """The segment with every coordinate multiplied by ``factor`` (> 0)."""
        f = float(factor)
        return Segment(np.array(self.p0) * f, np.array(self.p1) * f, self.name)

    def green_area(self, origin=(0.0, 0.0)) -> float:
        """``∫ (x dy - y dx) / 2`` along the segment, coordinates taken relative to ``origin``."""
        return float(CurveBatch.from_curves([self]).green_area(origin)[0])

    def sample_t(self, size: SizeLike, chord_tol: float | None = None) -> np.ndarray:
        """Increasing parameters from 0 to 1 spaced by the target edge length ``size``.

        See :func:`sample_parameters`; ``chord_tol`` is ignored for segments.
        """
        return sample_parameters([self], size, chord_tol)[1]


# ----------------------------------------------------------------------------- arc
@dataclass(frozen=True)
class Arc:
    """The circular arc ``center + radius (cos a, sin a)``, ``a`` from ``theta0`` to ``theta1``.

    The sweep ``theta1 - theta0`` is signed (counter-clockwise if positive) with
    ``|sweep| <= 2 pi``; a full circle has ``|sweep| = 2 pi`` and starts where it ends.

    Examples
    --------
    >>> c = Arc.circle((0, 0), 2)
    >>> round(c.length, 12) == round(4 * math.pi, 12), c.distance([[3, 0]]).tolist()
    (True, [1.0])
    """

    center: tuple[float, float]
    radius: float
    theta0: float
    theta1: float
    name: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _pair(self.center, "arc centre"))
        for f in ("radius", "theta0", "theta1"):
            try:
                object.__setattr__(self, f, float(getattr(self, f)))
            except (TypeError, ValueError):
                raise GeometryError(f"arc {f} must be a number, got {getattr(self, f)!r}") from None

    # -- constructors
    @classmethod
    def from_center(cls, start, end, center, ccw: bool = True, *, name: str | None = None,
                    where: str = "") -> Arc:
        """The arc around ``center`` from ``start`` to ``end`` (a full circle if they coincide).

        Raises
        ------
        GeometryError
            If ``start`` and ``end`` are not at the same distance from ``center``.
        """
        s, e, c = (np.array(_pair(v, w)) for v, w in
                   ((start, "arc start"), (end, "arc end"), (center, "arc centre")))
        r0, r1 = float(np.hypot(*(s - c))), float(np.hypot(*(e - c)))
        if not all(np.isfinite(np.r_[s, e, c])):
            raise GeometryError(f"{_prefix(where)}arc has a non-finite coordinate: start "
                                f"{fmt_point(s)}, end {fmt_point(e)}, centre {fmt_point(c)}")
        tol = tolerance(max(r0, r1), float(np.abs(np.r_[s, e, c]).max()))
        if r0 <= tol:
            raise GeometryError(f"{_prefix(where)}arc start point {fmt_point(s)} coincides "
                                f"with its centre")
        if abs(r0 - r1) > tol:
            raise GeometryError(f"{_prefix(where)}arc end point {fmt_point(e)} is not on its "
                                f"circle (centre {fmt_point(c)}, radius {fmt_num(r0)})")
        full = float(np.hypot(*(e - s))) <= tol
        return cls._from_angles(c, r0, s - c, e - c, ccw, full, name)

    @classmethod
    def through(cls, start, through, end, *, name: str | None = None, where: str = "") -> Arc:
        """The arc from ``start`` through ``through`` to ``end``.

        Raises
        ------
        GeometryError
            If the three points are collinear or two of them coincide.
        """
        s, m, e = (np.array(_pair(v, w)) for v, w in
                   ((start, "arc start"), (through, "arc through"), (end, "arc end")))
        a, b = m - s, e - s
        na, nb, nab = (float(np.hypot(*v)) for v in (a, b, e - m))
        cross = float(a[0] * b[1] - a[1] * b[0])
        pts = f"{fmt_point(s)}, {fmt_point(m)}, {fmt_point(e)}"
        if not np.isfinite(cross):
            raise GeometryError(f"{_prefix(where)}arc has a non-finite coordinate: {pts}")
        if min(na, nb, nab) <= tolerance(max(na, nb), float(np.abs(np.r_[s, m, e]).max())):
            raise GeometryError(f"{_prefix(where)}arc points {pts} are not distinct")
        if abs(cross) <= 1e-12 * na * nb:
            raise GeometryError(f"{_prefix(where)}arc points {pts} are collinear")
        d = 2.0 * cross
        u = np.array([b[1] * na**2 - a[1] * nb**2, a[0] * nb**2 - b[0] * na**2]) / d
        return cls._from_angles(s + u, float(np.hypot(*u)), -u, b - u, cross > 0, False, name)

    @classmethod
    def circle(cls, center, radius: float, *, ccw: bool = True, start_angle: float = 0.0,
               name: str | None = None) -> Arc:
        """The full circle, starting (and ending) at angle ``start_angle``."""
        sweep = TWO_PI if ccw else -TWO_PI
        return cls(center, radius, start_angle, start_angle + sweep, name)

    @classmethod
    def _from_angles(cls, c, r, ds, de, ccw, full, name) -> Arc:
        th0 = math.atan2(ds[1], ds[0])
        th1 = math.atan2(de[1], de[0])
        if full:
            sweep = TWO_PI
        else:
            sweep = (th1 - th0) % TWO_PI if ccw else (th0 - th1) % TWO_PI
        return cls(c, r, th0, th0 + (sweep if ccw else -sweep), name)

    # -- properties
    @property
    def sweep(self) -> float:
        return self.theta1 - self.theta0

    @property
    def ccw(self) -> bool:
        return self.sweep > 0

    @property
    def is_full(self) -> bool:
        return abs(self.sweep) >= TWO_PI * (1 - 1e-12)

    @property
    def length(self) -> float:
        return abs(self.radius * self.sweep)

    @property
    def start(self) -> np.ndarray:
        return self.point(0.0)

    @property
    def end(self) -> np.ndarray:
        return self.point(1.0)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return tuple(float(v) for v in CurveBatch.from_curves([self]).bounds()[0])

    # -- vectorised methods
    def _angle(self, t) -> np.ndarray:
        return self.theta0 + np.asarray(t, dtype=np.float64) * self.sweep

    def point(self, t) -> np.ndarray:
        a = self._angle(t)
        return np.stack([self.center[0] + self.radius * np.cos(a),
                         self.center[1] + self.radius * np.sin(a)], axis=-1)

    def tangent(self, t) -> np.ndarray:
        a = self._angle(t)
        s = 1.0 if self.sweep >= 0 else -1.0
        return np.stack([-s * np.sin(a), s * np.cos(a)], axis=-1)

    def project(self, points) -> np.ndarray:
        d = _points(points) - np.array(self.center)
        return _arc_project(d[..., 0], d[..., 1], self.theta0, self.sweep)

    def distance(self, points) -> np.ndarray:
        d = _points(points) - np.array(self.center)
        a = self._angle(self.project(points))
        return np.hypot(d[..., 0] - self.radius * np.cos(a), d[..., 1] - self.radius * np.sin(a))

    def translated(self, offset) -> Arc:
        o = _pair(offset, "offset")
        c = (self.center[0] + o[0], self.center[1] + o[1])
        return Arc(c, self.radius, self.theta0, self.theta1, self.name)

    def scaled(self, factor: float) -> Arc:
        """The arc with every coordinate multiplied by ``factor`` (> 0); same angles."""
        f = float(factor)
        return Arc((self.center[0] * f, self.center[1] * f), self.radius * f, self.theta0,
                   self.theta1, self.name)

    def green_area(self, origin=(0.0, 0.0)) -> float:
        """``∫ (x dy - y dx) / 2`` along the arc, coordinates taken relative to ``origin``."""
        return float(CurveBatch.from_curves([self]).green_area(origin)[0])

    def sample_t(self, size: SizeLike, chord_tol: float | None = None) -> np.ndarray:
        """Increasing parameters from 0 to 1 spaced by ``size`` and the chord tolerance.

        See :func:`sample_parameters`.
        """
        return sample_parameters([self], size, chord_tol)[1]


Curve = Segment | Arc


def _arc_project(dx, dy, theta0, sweep) -> np.ndarray:
    """Parameter of the closest arc point to offsets ``(dx, dy)`` from the centre."""
    sgn = np.where(np.asarray(sweep) >= 0, 1.0, -1.0)
    s = np.abs(sweep)
    a = np.mod((np.arctan2(dy, dx) - theta0) * sgn, TWO_PI)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(a <= s, a / s, np.where(a - s < TWO_PI - a, 1.0, 0.0))
    return np.clip(np.nan_to_num(t), 0.0, 1.0)


# ----------------------------------------------------------------------------- batches
@dataclass(frozen=True, eq=False)
class CurveBatch:
    """Many curves as flat arrays (``C`` curves); arc fields are 0 for segments.

    Attributes
    ----------
    is_arc : (C,) bool
    p0, p1 : (C, 2) start and end points (exact for segments, computed for arcs)
    center : (C, 2); radius, theta0, sweep, length : (C,)
    """

    is_arc: np.ndarray
    p0: np.ndarray
    p1: np.ndarray
    center: np.ndarray
    radius: np.ndarray
    theta0: np.ndarray
    sweep: np.ndarray
    length: np.ndarray

    def slice(self, i0: int, i1: int) -> CurveBatch:
        """The curves ``i0`` to ``i1 - 1`` as a batch."""
        return CurveBatch(*(getattr(self, f)[i0:i1] for f in self.__dataclass_fields__))

    @classmethod
    def from_curves(cls, curves: Sequence[Curve]) -> CurveBatch:
        curves = list(curves)
        is_arc = np.array([isinstance(c, Arc) for c in curves], dtype=bool)
        n = len(curves)
        p0, p1, center = np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2))
        radius, theta0, sweep = np.zeros(n), np.zeros(n), np.zeros(n)
        seg = np.flatnonzero(~is_arc)
        arc = np.flatnonzero(is_arc)
        if len(seg):
            p0[seg] = [curves[i].p0 for i in seg]
            p1[seg] = [curves[i].p1 for i in seg]
        if len(arc):
            center[arc] = [curves[i].center for i in arc]
            radius[arc] = [curves[i].radius for i in arc]
            theta0[arc] = [curves[i].theta0 for i in arc]
            sweep[arc] = [curves[i].theta1 - curves[i].theta0 for i in arc]
            for k, t in ((p0, 0.0), (p1, 1.0)):
                a = theta0[arc] + t * sweep[arc]
                k[arc] = center[arc] + radius[arc, None] * np.c_[np.cos(a), np.sin(a)]
        length = np.where(is_arc, np.abs(radius * sweep), np.hypot(*(p1 - p0).T))
        return cls(is_arc, p0, p1, center, radius, theta0, sweep, length)

    def __len__(self) -> int:
        return len(self.is_arc)

    def points(self, idx: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Points at parameters ``t`` (M,) of curves ``idx`` (M,) -> (M, 2)."""
        idx = np.asarray(idx, dtype=np.intp)
        t = np.asarray(t, dtype=np.float64)
        out = np.empty((len(idx), 2))
        arc = self.is_arc[idx]
        s, a = ~arc, arc
        i = idx[s]
        out[s] = self.p0[i] + t[s, None] * (self.p1[i] - self.p0[i])
        i = idx[a]
        ang = self.theta0[i] + t[a] * self.sweep[i]
        out[a] = self.center[i] + self.radius[i, None] * np.c_[np.cos(ang), np.sin(ang)]
        return out

    def tangents(self, idx: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Unit tangents at parameters ``t`` (M,) of curves ``idx`` (M,) -> (M, 2), in the
        direction of increasing t (as each curve's ``tangent``)."""
        idx = np.asarray(idx, dtype=np.intp)
        t = np.asarray(t, dtype=np.float64)
        out = np.empty((len(idx), 2))
        arc = self.is_arc[idx]
        i = idx[~arc]
        d = self.p1[i] - self.p0[i]
        n = np.hypot(d[:, 0], d[:, 1])[:, None]
        out[~arc] = np.where(n > 0, d / np.where(n > 0, n, 1.0), d)
        i = idx[arc]
        ang = self.theta0[i] + t[arc] * self.sweep[i]
        s = np.where(self.sweep[i] >= 0, 1.0, -1.0)
        out[arc] = np.c_[-s * np.sin(ang), s * np.cos(ang)]
        return out

    def bounds(self) -> np.ndarray:
        """Exact bounding boxes ``(C, 4)`` as ``xmin, ymin, xmax, ymax``."""
        lo = np.minimum(self.p0, self.p1)
        hi = np.maximum(self.p0, self.p1)
        sgn = np.where(self.sweep >= 0, 1.0, -1.0)
        for k, (ax, side) in enumerate(((0, 1), (1, 1), (0, -1), (1, -1))):
            rel = np.mod((k * math.pi / 2 - self.theta0) * sgn, TWO_PI)
            hit = self.is_arc & ((rel <= np.abs(self.sweep)) | self.is_full())
            v = self.center[:, ax] + side * self.radius
            if side > 0:
                hi[hit, ax] = np.maximum(hi[hit, ax], v[hit])
            else:
                lo[hit, ax] = np.minimum(lo[hit, ax], v[hit])
        return np.c_[lo, hi]

    def is_full(self) -> np.ndarray:
        return self.is_arc & (np.abs(self.sweep) >= TWO_PI * (1 - 1e-12))

    def green_area(self, origin=(0.0, 0.0)) -> np.ndarray:
        """``∫ (x dy - y dx) / 2`` along every curve, relative to ``origin`` -> (C,).

        Summed over a closed loop this is its signed area (exact for arcs).
        """
        o = np.asarray(origin, dtype=np.float64)
        a, b = self.p0 - o, self.p1 - o
        seg = 0.5 * (a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])
        c = self.center - o
        t0, t1 = self.theta0, self.theta0 + self.sweep
        r = self.radius
        arc = 0.5 * (r * r * self.sweep + r * (c[:, 0] * (np.sin(t1) - np.sin(t0))
                                               - c[:, 1] * (np.cos(t1) - np.cos(t0))))
        return np.where(self.is_arc, arc, seg)

    def max_step(self, chord_tol: float | None) -> np.ndarray:
        """Largest arclength step keeping the sagitta below ``chord_tol`` (inf for segments)."""
        step = np.full(len(self), np.inf)
        if chord_tol is None or not np.any(self.is_arc):
            return step
        r = np.where(self.is_arc, self.radius, 1.0)
        q = np.clip(1.0 - chord_tol / r, -1.0, 1.0)
        dtheta = np.minimum(2.0 * np.arccos(q), math.pi / 2)
        return np.where(self.is_arc, r * dtheta, step)

    def min_intervals(self) -> np.ndarray:
        """At least one interval, one per 90 degrees of arc and three for a full circle."""
        quarter = np.ceil(np.abs(self.sweep) / (math.pi / 2) * (1 - 1e-12))
        n = np.where(self.is_arc, np.maximum(quarter, 1), 1)
        return np.where(self.is_full(), np.maximum(n, 3), n).astype(np.int64)

    def distance(self, points, *, chunk: int = 1 << 22) -> np.ndarray:
        """Distance from every point to the nearest curve (exact) -> points.shape[:-1].

        Segments go through a shapely STRtree when there are many of them; arcs are
        compared with every point, in chunks of about ``chunk`` point-curve pairs.
        """
        p = _points(points)
        shape = p.shape[:-1]
        p = p.reshape(-1, 2)
        best = np.full(len(p), np.inf)
        seg = np.flatnonzero(~self.is_arc)
        arc = np.flatnonzero(self.is_arc)
        if len(seg) > 32 and len(p):
            origin, tree = self._segment_tree
            q = shapely.points(p - origin)
            (i, _), dist = tree.query_nearest(q, return_distance=True, all_matches=False)
            best[i] = dist
            seg = seg[:0]
        step = max(1, chunk // max(len(p), 1))
        for ids, kernel in ((seg, self._segment_distance), (arc, self._arc_distance)):
            for k in range(0, len(ids), step):
                best = np.minimum(best, kernel(p, ids[k:k + step]).min(axis=1))
        return best.reshape(shape)

    @cached_property
    def _segment_tree(self):
        seg = ~self.is_arc
        origin = self.p0[np.argmax(seg)].copy()
        lines = shapely.linestrings(np.stack([self.p0[seg], self.p1[seg]], axis=1) - origin)
        return origin, shapely.STRtree(lines)

    def _segment_distance(self, p: np.ndarray, ids: np.ndarray) -> np.ndarray:
        a = self.p0[ids]
        d = self.p1[ids] - a
        dd = np.einsum("ij,ij->i", d, d)
        px = p[:, None, 0] - a[None, :, 0]
        py = p[:, None, 1] - a[None, :, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.clip(np.nan_to_num((px * d[:, 0] + py * d[:, 1]) / dd), 0.0, 1.0)
        return np.hypot(px - t * d[:, 0], py - t * d[:, 1])

    def _arc_distance(self, p: np.ndarray, ids: np.ndarray) -> np.ndarray:
        dx = p[:, None, 0] - self.center[ids, 0]
        dy = p[:, None, 1] - self.center[ids, 1]
        t = _arc_project(dx, dy, self.theta0[ids], self.sweep[ids])
        a = self.theta0[ids] + t * self.sweep[ids]
        r = self.radius[ids]
        return np.hypot(dx - r * np.cos(a), dy - r * np.sin(a))


def segments_through(points, *, closed: bool, name: str = "",
                     where: str = "") -> tuple[Segment, ...]:
    """Segments joining consecutive ``points`` (and the last to the first if ``closed``).

    A repeated closing vertex of a closed chain is dropped. Raises :class:`GeometryError` on
    non-finite coordinates, duplicate consecutive points and too few vertices, naming ``name``.
    """
    name = name or ("loop" if closed else "path")
    pre = f"{where}: " if where else ""
    try:
        p = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise GeometryError(f"{pre}{name}: vertices must be pairs of numbers") from None
    if p.ndim != 2 or p.shape[1] != 2:
        raise GeometryError(f"{pre}{name}: vertices must have shape (K, 2), got {p.shape}")
    bad = ~np.isfinite(p).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise GeometryError(f"{pre}{name}: vertex {i} has a non-finite coordinate "
                            f"{fmt_point(p[i])}")
    if len(p):
        lo, hi = p.min(axis=0), p.max(axis=0)
        tol = tolerance(float(np.hypot(*(hi - lo))), float(np.abs(p).max()))
        if closed and len(p) > 1 and np.hypot(*(p[0] - p[-1])) <= tol:
            p = p[:-1]  # explicit closing vertex
        gap = np.hypot(*(p[1:] - p[:-1]).T) <= tol
        if gap.any():
            i = int(np.flatnonzero(gap)[0])
            raise GeometryError(f"{pre}{name}: duplicate consecutive points {fmt_point(p[i])} "
                                f"at vertices {i} and {i + 1}")
    need = 3 if closed else 2
    if len(p) < need:
        raise GeometryError(f"{pre}{name}: a polygon{'' if closed else 'al path'} needs at "
                            f"least {need} vertices, got {len(p)}")
    q = np.roll(p, -1, axis=0) if closed else p[1:]
    return tuple(Segment(a, b) for a, b in zip(map(tuple, p.tolist()), map(tuple, q.tolist())))


# ----------------------------------------------------------------------------- sampling
def _eval_size(size: Callable, pts: np.ndarray) -> np.ndarray:
    h = np.broadcast_to(np.asarray(size(pts), dtype=np.float64), (len(pts),))
    bad = ~(h > 0)  # also catches nan
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise GeometryError(f"size function returned {fmt_num(h[i])} at {fmt_point(pts[i])}; "
                            f"sizes must be positive")
    return h


def _check_count(n: np.ndarray) -> None:
    if n.sum() > MAX_SAMPLES:
        raise GeometryError(f"sampling the curves would need {int(n.sum())} points "
                            f"(more than {MAX_SAMPLES}); increase the size")


def sample_parameters(curves: Sequence[Curve] | CurveBatch, size: SizeLike,
                      chord_tol: float | None = None, *,
                      nearest: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Parameters of points spaced by the local target edge length along many curves.

    The count of intervals on a curve is ``ceil(∫ 1/h ds)`` (at least one; for arcs at least
    one per 90 degrees and three for a full circle), with ``h = min(size, max_step)`` where
    ``max_step`` keeps the sagitta of an arc's chords below ``chord_tol``; with ``nearest``
    the integral is rounded to the nearest count instead (the mean interval then follows
    ``size`` on short curves too, where rounding up shortens it by up to a half interval),
    but never so low that a step exceeds ``max_step``. Points sit at equal increments of that
    integral, computed on a fine sub-sampling (at least 4 per interval).

    Parameters
    ----------
    curves : sequence of Segment / Arc, or a CurveBatch
    size : float or callable ``(N, 2) -> (N,)``
        Target edge length (``inf`` means no limit).
    chord_tol : float, optional
        Largest distance between an arc and its chords.

    Returns
    -------
    offsets : (C + 1,) int64
        Curve ``i`` owns ``t[offsets[i]:offsets[i + 1]]``.
    t : (sum,) float64
        Increasing from exactly 0 to exactly 1 on every curve.

    Examples
    --------
    >>> from hetmesh.tri.geometry import Segment
    >>> off, t = sample_parameters([Segment((0, 0), (1, 0))], 0.25)
    >>> off.tolist(), t.tolist()
    ([0, 5], [0.0, 0.25, 0.5, 0.75, 1.0])
    """
    batch = curves if isinstance(curves, CurveBatch) else CurveBatch.from_curves(curves)
    if chord_tol is not None and not chord_tol > 0:
        raise GeometryError(f"chord tolerance must be positive, got {chord_tol!r}")
    C = len(batch)
    L = batch.length
    cap = batch.max_step(chord_tol)
    nmin = batch.min_intervals()
    if C == 0:
        return np.zeros(1, dtype=np.int64), np.zeros(0)
    if not callable(size):
        h = float(size)
        if not h > 0:
            raise GeometryError(f"size must be positive, got {size!r}")
        n = _count(L / np.minimum(h, cap), nmin, L / cap, nearest)
        _check_count(n)
        offsets = np.r_[0, np.cumsum(n + 1)]
        idx = np.repeat(np.arange(C), n + 1)
        k = np.arange(offsets[-1]) - offsets[idx]
        return offsets, k / n[idx]
    m = np.full(C, 16, dtype=np.int64)
    for _ in range(5):
        idx, t, first = _ragged(m)
        inv = 1.0 / np.minimum(_eval_size(size, batch.points(idx, t)), cap[idx])
        same = idx[1:] == idx[:-1]
        w = np.where(same, 0.5 * (inv[1:] + inv[:-1]) * (L / m)[idx[:-1]], 0.0)
        F = np.r_[0.0, np.cumsum(w)]
        total = F[first + m] - F[first]
        # the chord cap's share of the local step (0 where it never binds): the count
        # rounded to the nearest stretches every step by total / n, which must keep the
        # steps that the cap sets within it
        chords = total * np.maximum.reduceat(1.0 / (inv * cap[idx]), first) if nearest else 0
        n = _count(total, nmin, chords, nearest)
        _check_count(n)
        if np.all(m >= 4 * n):
            break
        m = np.maximum(m, 4 * n)
    # normalised cumulative integral G in [0, 1] per curve (tiny linear term: strictly increasing)
    Fl = F - F[first][idx]
    eps = np.where(total > 0, 1e-9 * total, 1.0)
    G = (Fl + eps[idx] * t) / (total + eps)[idx]
    G[first + m] = 1.0
    key = idx + G
    u = idx + t
    offsets = np.r_[0, np.cumsum(n + 1)]
    jdx = np.repeat(np.arange(C), n + 1)
    k = np.arange(offsets[-1]) - offsets[jdx]
    out = np.interp(jdx + k / n[jdx], key, u) - jdx
    out[offsets[:-1]] = 0.0
    out[offsets[1:] - 1] = 1.0
    return offsets, np.clip(out, 0.0, 1.0)


#: with ``nearest``, the steps that the chord cap sets stay this much below it
CHORD_SPARE = 1.01


def _count(total: np.ndarray, nmin: np.ndarray, chords, nearest: bool) -> np.ndarray:
    """Intervals per curve for the integral ``total`` of 1/h: rounded up, or with
    ``nearest`` to the nearest count but at least ``chords`` (the count whose steps keep
    the chord tolerance, with 1 % to spare; never above the count rounded up); and at least
    ``nmin``."""
    up = np.ceil(total * (1 - 1e-12))
    if nearest:
        up = np.minimum(up, np.maximum(np.floor(total + 0.5), np.ceil(CHORD_SPARE * chords)))
    return np.maximum(nmin, up).astype(np.int64)


def _ragged(m: np.ndarray):
    """Curve index, uniform parameter and first position of ``m + 1`` samples per curve."""
    first = np.r_[0, np.cumsum(m + 1)[:-1]]
    idx = np.repeat(np.arange(len(m)), m + 1)
    k = np.arange(int((m + 1).sum())) - first[idx]
    return idx, k / m[idx], first
