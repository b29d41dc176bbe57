"""The nodes of a Heterogeneous Feature Tree (paper Section 3.3, case studies 2-3).

Every node is evaluated on a whole ``(N, 2)`` array (no Python loop over points) and returns
an :class:`FeatureEval`: distance and its gradient (``None`` for a blend), composition ``(N, m)``
and its gradient ``(N, m, 2)``, and the owning subregion id ``(N,)``.

* **Leaves** (:class:`PointFeature`, :class:`CurveFeature`) carry a composition vector,
  constant or linear in arc length between a start and an end composition.
* **Parents** choose one child per point: :class:`NearestFeature` (the child holding the
  nearest point, a composite curve) or :class:`SelectFeature` (an ordered rule list, the
  "between circle A and circle C" of Fig. 7(c)). A parent of curves is itself a curve.
* **Blends** (:class:`BlendFeature`) mix two features, ``f = W M_1 + (1 - W) M_2``
  (Eqs. 19, 27), ``W`` a formula of named distances, per subregion (Eq. 20).

Gradients are exact (chain rule). ``grad d`` is the unit vector from the nearest feature
point; where ``d = 0`` it is the curve's *left* normal (zero at a point feature). Points
equidistant from two children take the first child: never NaN.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from ...errors import MaterialError, ModelFileError
from ...topology import unique
from ...tri.geometry import Arc, Segment
from ...tri.geometry.curves import TWO_PI
from . import enclose as _enc

__all__ = ["PointFeature", "CurveFeature", "NearestFeature", "SelectFeature", "FeatureEval",
           "inside_predicate"]


class FeatureEval:
    """One feature evaluated at N points (``dist``/``ddist`` are None for a blend)."""

    __slots__ = ("dist", "ddist", "comp", "dcomp", "region")

    def __init__(self, dist, ddist, comp, dcomp, region):
        self.dist, self.ddist, self.comp, self.dcomp, self.region = \
            dist, ddist, comp, dcomp, region


def _empty_eval(n: int, m: int, geometric: bool) -> FeatureEval:
    return FeatureEval(np.empty(n) if geometric else None, np.empty((n, 2)) if geometric else None,
                 np.empty((n, m)), np.empty((n, m, 2)), np.empty(n, dtype=np.int64))


# ------------------------------------------------------------------------------- leaves

class LeafFeature:
    """Base of leaf features: composition ``c0 + t (c1 - c0)``, ``t`` the nearest-point
    arc-length parameter in [0, 1]."""

    geometric = True
    n_regions = 1

    def __init__(self, fid: str, c0, c1=None):
        self.id = fid
        self.c0 = np.asarray(c0, dtype=float)
        self.c1 = self.c0 if c1 is None else np.asarray(c1, dtype=float)
        self.dc = self.c1 - self.c0
        self.children: tuple = ()

    def _geom(self, p, need_grad: bool):
        """``(t, q, dtdp, normal)``: parameter, nearest point, grad t, left normal."""
        raise NotImplementedError

    def distance(self, p, region=None):
        _, q, _, _ = self._geom(p, False)
        return np.hypot(p[:, 0] - q[:, 0], p[:, 1] - q[:, 1])

    def region(self, p):
        return np.zeros(len(p), dtype=np.int64)

    def evaluate(self, p, region=None) -> FeatureEval:
        t, q, dtdp, normal = self._geom(p, True)
        diff = p - q
        d = np.hypot(diff[:, 0], diff[:, 1])
        on = d == 0.0
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = diff / d[:, None]
        if on.any():
            unit[on] = normal[on]
        comp = self.c0 + t[:, None] * self.dc
        if np.any(self.dc):
            dcomp = self.dc[None, :, None] * dtdp[:, None, :]
        else:
            dcomp = np.zeros((len(p), len(self.c0), 2))
        return FeatureEval(d, unit, comp, dcomp, np.zeros(len(p), dtype=np.int64))

    def sample(self, n: int = 64) -> np.ndarray:
        """Points ``(K, 2)`` on the feature: its point, or ``n`` points along its curve."""
        raise NotImplementedError

    def enclose(self, box, region=None) -> _enc.Enclosure:
        """Intervals containing the distance and the composition at every point of each box
        ``(xlo, xhi, ylo, yhi)`` (see :mod:`.enclose`); ``region`` is ignored (a leaf has
        one subregion)."""
        raise NotImplementedError(f"feature {self.id!r}: no enclosure for "
                                  f"{type(self).__name__}")

    def region_path(self, r: int) -> list[str]:
        return [self.id]

    def region_name(self, r: int) -> str:
        return self.id

    def curves(self) -> list:
        return []


class PointFeature(LeafFeature):
    """A point with a constant composition."""

    def __init__(self, fid: str, at, composition):
        super().__init__(fid, composition)
        self.at = np.asarray(at, dtype=float).reshape(2)

    def sample(self, n: int = 64) -> np.ndarray:
        return self.at[None, :].copy()

    def enclose(self, box, region=None) -> _enc.Enclosure:
        return _enc.Enclosure(_enc.point_box(self.at, box),
                              _enc.constant_comp(self.c0, len(box[0])))

    def _geom(self, p, need_grad):
        n = len(p)
        q = np.broadcast_to(self.at, (n, 2))
        z = np.zeros((n, 2)) if need_grad else None
        return np.zeros(n), q, z, z


class CurveFeature(LeafFeature):
    """A :class:`~hetmesh.tri.geometry.Segment` or :class:`~hetmesh.tri.geometry.Arc` whose
    composition goes linearly in arc length from ``start`` to ``end`` (constant if
    ``end`` is None)."""

    def __init__(self, fid: str, curve, start, end=None):
        super().__init__(fid, start, end)
        self.curve = curve
        if isinstance(curve, Segment):
            self._p0 = np.array(curve.p0)
            self._d = np.array(curve.p1) - self._p0
            self._dd = float(self._d @ self._d)
        elif isinstance(curve, Arc):
            self._c = np.array(curve.center)
            self._sgn = 1.0 if curve.sweep >= 0 else -1.0
            self._s = abs(curve.sweep)
        else:
            raise MaterialError(f"feature {fid!r}: expected a Segment or an Arc, got {curve!r}")

    def curves(self) -> list:
        return [self.curve]

    def sample(self, n: int = 64) -> np.ndarray:
        return np.asarray(self.curve.point(np.linspace(0.0, 1.0, n)), dtype=float).reshape(-1, 2)

    def enclose(self, box, region=None) -> _enc.Enclosure:
        k = len(box[0])
        if isinstance(self.curve, Segment):
            dist, t = _enc.segment_box(self._p0, self._p0 + self._d, box)
        else:
            arc = self.curve
            dist, rho = _enc.circle_distance(self._c, arc.radius, box)
            if np.any(self.dc) or not arc.is_full:
                t, radial = _enc.arc_parameter(_enc.arc_angles(self._c, box, rho[0]),
                                               arc.theta0, arc.sweep)
                radial = radial | arc.is_full
            else:
                t, radial = None, np.ones(k, dtype=bool)
            if not radial.all():  # beyond the arc's ends: 1-Lipschitz about the centre
                c, r = _enc.centre_radius(box)
                dc = self.distance(c)
                llo, lhi = _enc.widen(dc - r, dc + r, _enc.magnitude(box, self._c)
                                      + arc.radius)
                dist = (np.where(radial, dist[0], np.maximum(dist[0], llo)),
                        np.where(radial, dist[1], lhi))
        if not np.any(self.dc):
            return _enc.Enclosure(dist, _enc.constant_comp(self.c0, k))
        return _enc.Enclosure(dist, _enc.linear_comp(self.c0, self.dc, t))

    def _geom(self, p, need_grad):
        if isinstance(self.curve, Segment):
            u = ((p[:, 0] - self._p0[0]) * self._d[0]
                 + (p[:, 1] - self._p0[1]) * self._d[1]) / self._dd
            t = np.clip(u, 0.0, 1.0)
            q = self._p0 + t[:, None] * self._d
            if not need_grad:
                return t, q, None, None
            inner = (u > 0.0) & (u < 1.0)
            dtdp = np.where(inner[:, None], self._d / self._dd, 0.0)
            nrm = np.array([-self._d[1], self._d[0]]) / math.sqrt(self._dd)
            return t, q, dtdp, np.broadcast_to(nrm, (len(p), 2))
        c, r, arc = self._c, self.curve.radius, self.curve
        dx, dy = p[:, 0] - c[0], p[:, 1] - c[1]
        a = np.mod((np.arctan2(dy, dx) - arc.theta0) * self._sgn, TWO_PI)
        s = self._s
        inner = a <= s
        t = np.where(inner, a / s, np.where(a - s < TWO_PI - a, 1.0, 0.0))
        ang = arc.theta0 + t * arc.sweep
        cs, sn = np.cos(ang), np.sin(ang)
        q = np.column_stack([c[0] + r * cs, c[1] + r * sn])
        if not need_grad:
            return t, q, None, None
        rho2 = dx * dx + dy * dy
        ok = inner & (rho2 > 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            k = np.where(ok, self._sgn / (s * np.where(ok, rho2, 1.0)), 0.0)
        dtdp = np.column_stack([-dy * k, dx * k])
        nrm = np.column_stack([-self._sgn * cs, -self._sgn * sn])
        return t, q, dtdp, nrm


# ------------------------------------------------------------------------------- parents

class _Parent:
    """Base of parents choosing one child per point (owner index per point)."""

    def __init__(self, fid: str, children: Sequence):
        self.id = fid
        self.children = tuple(children)
        self.geometric = all(c.geometric for c in self.children)
        self.offsets = np.cumsum([0] + [c.n_regions for c in self.children])
        self.n_regions = int(self.offsets[-1])

    def _owner(self, p) -> np.ndarray:
        raise NotImplementedError

    def _split(self, region):
        k = np.searchsorted(self.offsets[1:], region, side="right")
        return k, region - self.offsets[k]

    def _groups(self, owner):
        for k, child in enumerate(self.children):
            if len(self.children) == 1:
                yield k, child, slice(None)
                continue
            mask = owner == k
            if mask.any():
                yield k, child, (slice(None) if mask.all() else np.flatnonzero(mask))

    def region(self, p):
        owner = self._owner(p)
        out = np.empty(len(p), dtype=np.int64)
        for k, child, idx in self._groups(owner):
            out[idx] = child.region(p[idx]) + self.offsets[k]
        return out

    def distance(self, p, region=None):
        if region is None:
            owner, sub = self._owner(p), None
        else:
            owner, sub = self._split(np.asarray(region))
        out = np.empty(len(p))
        for _, child, idx in self._groups(owner):
            out[idx] = child.distance(p[idx], None if sub is None else sub[idx])
        return out

    def evaluate(self, p, region=None) -> FeatureEval:
        if region is None:
            owner, sub = self._owner(p), None
        else:
            owner, sub = self._split(np.asarray(region))
        groups = list(self._groups(owner))
        if len(groups) == 1 and isinstance(groups[0][2], slice):
            k, child, _ = groups[0]
            ev = child.evaluate(p, sub)
            if k:
                ev.region = ev.region + self.offsets[k]
            return ev
        out = _empty_eval(len(p), self._m, self.geometric)
        for k, child, idx in groups:
            ev = child.evaluate(p[idx], None if sub is None else sub[idx])
            if self.geometric:
                out.dist[idx], out.ddist[idx] = ev.dist, ev.ddist
            out.comp[idx], out.dcomp[idx] = ev.comp, ev.dcomp
            out.region[idx] = ev.region + self.offsets[k]
        return out

    @property
    def _m(self) -> int:
        return _width(self)

    def enclose(self, box, region=None) -> _enc.Enclosure:
        """Intervals containing the distance (None unless every child is geometric) and the
        composition at every point of each box ``(xlo, xhi, ylo, yhi)``: with ``region``,
        those of the forced child; without, of any child that may own a point of the box
        (see :mod:`.enclose`)."""
        if region is None:
            return self._enclose_free(box)
        k, sub = self._split(np.asarray(region))
        n = len(box[0])
        out = _enc.Enclosure((np.empty(n), np.empty(n)) if self.geometric else None,
                             (np.empty((n, self._m)), np.empty((n, self._m))))
        for j, child in enumerate(self.children):
            idx = np.flatnonzero(k == j)
            if not idx.size:
                continue
            e = child.enclose(tuple(b[idx] for b in box), sub[idx])
            if self.geometric:
                out.dist[0][idx], out.dist[1][idx] = e.dist
            out.comp[0][idx], out.comp[1][idx] = e.comp
        return out

    def _enclose_free(self, box) -> _enc.Enclosure:
        """Without a forced subregion: the hull over all children."""
        es = [c.enclose(box) for c in self.children]
        dist = _enc.hull([e.dist for e in es]) if self.geometric else None
        return _enc.Enclosure(dist, _enc.hull([e.comp for e in es]))

    def _child_of(self, r: int):
        k = int(np.searchsorted(self.offsets[1:], r, side="right"))
        return self.children[k], r - int(self.offsets[k])

    def region_path(self, r: int) -> list[str]:
        child, sub = self._child_of(r)
        return [self.id] + child.region_path(sub)

    def region_name(self, r: int) -> str:
        child, sub = self._child_of(r)
        return child.region_name(sub)

    def curves(self) -> list:
        return [c for child in self.children for c in child.curves()]


def _width(feature) -> int:
    while not isinstance(feature, LeafFeature):
        feature = feature.children[0]
    return len(feature.c0)


def _constant(feature) -> np.ndarray | None:
    """The composition of a feature that is the same at every point (a leaf with one
    composition, or a uniform :class:`NearestFeature`), else None."""
    if isinstance(feature, LeafFeature):
        return None if np.any(feature.dc) else feature.c0
    return getattr(feature, "constant", None)


class NearestFeature(_Parent):
    """A parent whose owning child is the one holding the nearest point (ties: the first
    child). Models a composite curve; its distance is the minimum of its children's.

    If every child carries one and the same constant composition (a stadium or a rounded
    rectangle made of segments and arcs, all at ``M_C``), the choice of child changes
    nothing in the material: the feature is then *uniform*, a single subregion (named by
    its own id), and no subregion boundary runs along the medial curves between its
    children (Sec. 3.3.1: a subregion is a part with one material distribution).
    """

    def __init__(self, fid: str, children: Sequence):
        super().__init__(fid, children)
        bad = [c.id for c in self.children if not c.geometric]
        if bad:
            raise ModelFileError(f"feature {fid!r}: child {bad[0]!r} is a blend, which has no "
                                 f"distance (a 'nearest' parent needs curves or points)")
        comps = [_constant(c) for c in self.children]
        self.constant = comps[0] if all(c is not None and np.array_equal(c, comps[0])
                                        for c in comps) else None
        if self.constant is not None:  # one subregion: every child maps to id 0
            self.offsets = np.zeros(len(self.children) + 1, dtype=np.int64)
            self.n_regions = 1

    @property
    def uniform(self) -> bool:
        """Whether all children carry the same constant composition (one subregion)."""
        return self.constant is not None

    def distance(self, p, region=None):
        return super().distance(p, None if self.uniform else region)

    def enclose(self, box, region=None) -> _enc.Enclosure:
        return super().enclose(box, None if self.uniform else region)

    def _enclose_free(self, box) -> _enc.Enclosure:
        """The distance is the children's minimum; a child may own a point of the box if
        its lower bound does not exceed the smallest upper bound."""
        es = [c.enclose(box) for c in self.children]
        dlo = np.minimum.reduce([e.dist[0] for e in es])
        dhi = np.minimum.reduce([e.dist[1] for e in es])
        if self.constant is not None:
            return _enc.Enclosure((dlo, dhi), _enc.constant_comp(self.constant, len(dlo)))
        lo = np.full(es[0].comp[0].shape, np.inf)
        hi = np.full(es[0].comp[1].shape, -np.inf)
        for e in es:
            may = (e.dist[0] <= dhi)[:, None]
            lo = np.where(may, np.minimum(lo, e.comp[0]), lo)
            hi = np.where(may, np.maximum(hi, e.comp[1]), hi)
        return _enc.Enclosure((dlo, dhi), (lo, hi))

    def evaluate(self, p, region=None) -> FeatureEval:
        return super().evaluate(p, None if self.uniform else region)

    def region_path(self, r: int) -> list[str]:
        return [self.id] if self.uniform else super().region_path(r)

    def region_name(self, r: int) -> str:
        return self.id if self.uniform else super().region_name(r)

    def _owner(self, p):
        if len(self.children) == 1:
            return np.zeros(len(p), dtype=np.int64)
        best = self.children[0].distance(p)
        owner = np.zeros(len(p), dtype=np.int64)
        for k, child in enumerate(self.children[1:], 1):
            d = child.distance(p)
            closer = d < best
            owner[closer] = k
            np.minimum(best, d, out=best)
        return owner


class SelectFeature(_Parent):
    """A parent whose owning child is given by rules ``(child index, predicate)``: the
    first rule whose ``predicate(points) -> bool (N,)`` holds wins, ``None`` always holds
    (a default). The rules are the paper's case-specific boundary feature (Sec. 3.3.1,
    Fig. 7(c): "between C_A and C_C -> C_C, between C_A and C_B -> C_B").

    Without a default the rules may leave points unowned. Such a point is never evaluated
    with owner -1: :meth:`owners` returns -1 there, and every evaluation raises
    :class:`~hetmesh.errors.MaterialError` naming the feature and the first such point
    (``parse_hft`` checks the domain's sample points when the model is loaded).
    """

    def __init__(self, fid: str, children: Sequence, rules: Sequence[tuple[int, Callable | None]]):
        super().__init__(fid, children)
        if not rules:
            raise ModelFileError(f"feature {fid!r}: a select needs at least one rule")
        self.rules = list(rules)

    def owners(self, p) -> np.ndarray:
        """Index of the owning child per point, -1 where no rule holds."""
        owner = np.full(len(p), -1, dtype=np.int64)
        for k, pred in self.rules:
            todo = owner < 0
            if pred is None:
                owner[todo] = k
                break
            hit = np.asarray(pred(p), dtype=bool) & todo
            owner[hit] = k
        return owner

    def _owner(self, p):
        owner = self.owners(p)
        free = np.flatnonzero(owner < 0)
        if free.size:
            x, y = p[free[0]]
            raise MaterialError(f"feature {self.id!r}: region rule leaves part of the domain "
                                f"unowned: no rule holds at ({x:.6g}, {y:.6g}) (add a default "
                                f"rule without a condition, or cover that point)")
        return owner


def inside_predicate(curves: Sequence, fid: str = "") -> Callable[[np.ndarray], np.ndarray]:
    """A vectorised ``inside(points) -> bool (N,)`` for closed chains of segments and arcs
    (in any order and orientation): crossing parity of the chord polygon, toggled inside
    each arc's circular segment (exact for arcs, no polygonal approximation). Points on
    the curves themselves may fall either way; points on an arc's chord (inside the shape,
    e.g. on the line joining a stadium's straight sides) are classified consistently by
    the two tests.

    >>> from hetmesh.tri.geometry import Arc, Segment
    >>> half = [Segment((-1, 0), (1, 0)), Arc.from_center((1, 0), (-1, 0), (0, 0))]
    >>> inside_predicate(half)(np.array([[0.0, 0.5], [0.0, -0.5], [0.0, 1.5]])).tolist()
    [True, False, False]
    """
    ends = []
    chords = []
    segs = []
    for c in curves:
        s, e = np.asarray(c.start, float), np.asarray(c.end, float)
        if isinstance(c, Arc):
            if c.is_full:
                segs.append((np.array(c.center), c.radius, None, None, None))
                continue
            mid = np.asarray(c.point(0.5), float)
            segs.append((np.array(c.center), c.radius, s, e - s, mid))
        chords.append((s, e))
        ends += [s, e]
    if ends:
        scale = max(1.0, float(np.ptp(np.array(ends), axis=0).max()))
        pts = np.round(np.array(ends) / (1e-9 * scale)).astype(np.int64)
        _, counts = unique(pts, axis=0, return_counts=True)
        if np.any(counts % 2):
            raise ModelFileError(f"feature {fid!r}: 'inside'/'outside' needs a closed curve, "
                                 f"but its curves do not form closed loops")

    def inside(p):
        x, y = p[:, 0], p[:, 1]
        odd = np.zeros(len(p), dtype=bool)
        for (a, b) in chords:
            if a[1] == b[1]:
                continue
            cond = (a[1] > y) != (b[1] > y)
            xi = a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
            odd ^= cond & (x < xi)
        for c, r, s, ch, mid in segs:
            inn = (x - c[0]) ** 2 + (y - c[1]) ** 2 < r * r
            if s is not None:
                side = ch[0] * (y - s[1]) - ch[1] * (x - s[0])
                ref = ch[0] * (mid[1] - s[1]) - ch[1] * (mid[0] - s[0])
                # On the chord (side == 0) decide as the crossing test above does for a
                # point on a polygon edge, i.e. as if the point were nudged to +x (to +y
                # for a horizontal chord): the chord is then counted exactly once.
                side = np.where(side == 0.0, -ch[1] if ch[1] != 0 else ch[0], side)
                inn &= side * ref > 0
            odd ^= inn
        return odd

    return inside


# ------------------------------------------------------------------------------- blend

def walk(feature, seen=None):
    """Every feature of the tree under ``feature`` once, parents before their children (a
    blend's distance features included); ``seen`` holds the ids already visited."""
    seen = set() if seen is None else seen
    if id(feature) in seen:
        return
    seen.add(id(feature))
    yield feature
    for c in feature.children:
        yield from walk(c, seen)
    for f in getattr(feature, "distances", {}).values():  # a blend's distance features
        yield from walk(f, seen)


def reached(feature, p):
    """``(feature, points)`` for every node that evaluating ``feature`` at ``p`` visits, with
    the points routed to it: a parent passes each child the points it owns, a blend passes
    all of its points to its two children and its distance features."""
    yield feature, p
    if isinstance(feature, _Parent):
        for _, child, idx in feature._groups(feature._owner(p)):
            yield from reached(child, p[idx])
    elif hasattr(feature, "distances"):  # a blend (hetmesh.material.hft.blend)
        for child in dict.fromkeys([feature.first, feature.second,
                                    *feature.distances.values()]):
            yield from reached(child, p)
