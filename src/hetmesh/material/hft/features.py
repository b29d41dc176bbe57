"""Heterogeneous Feature Tree (HFT) material fields (paper Section 3.3, case studies 2-3).

A feature tree has three kinds of node, all evaluated on whole ``(N, 2)`` arrays (no Python
loop over points):

* **Leaf features** carry a composition vector: a point, a segment, an arc or a circle. On a
  curve the composition is constant or varies linearly with arc length from its start
  composition to its end composition. A leaf gives, at every point, its distance ``d``, the
  composition at its nearest point and the gradients of both.
* **Parent features** choose one child per point: ``nearest`` (alias ``composite``; the
  child holding the nearest point, as for the bottom composite curve of case study 3) or
  ``select`` (an ordered rule list; the first rule whose predicate holds wins, e.g. "inside
  interface A -> circle C, else circle B" for the ring of Fig. 7). A parent of curves is
  itself a curve: its distance is that of the chosen child.
* **Blend (region) features** mix two features through a weight
  ``f = W M_1 + (1 - W) M_2`` (Eqs. 19, 27), ``W`` a formula of named distances (``d_b``,
  ``d_int``, ...), optionally a different ``W`` per subregion (Eq. 20).

Subregions and discontinuities
------------------------------
Every feature has ``n_regions`` subregions: 1 for a leaf, the sum over its children for a
parent, ``n_1 * n_2`` for a blend (id ``r_1 * n_2 + r_2``). :meth:`HFTField.region` gives the
subregion owning each point and :attr:`HFTField.region_names` names them by their leaves
(``"BCD|MN"``). Inside one subregion the field is smooth; where ownership changes it may
jump (material discontinuities). ``composition(points, region=r)`` evaluates the smooth
field *of subregion* ``r`` at the points (the owning leaves are forced, their nearest-point
formulas extrapolated), so an element on a discontinuity can use its own subregion's values
at all its vertices.

Gradients
---------
Exact, by the chain rule. ``grad d`` is the unit vector from the nearest feature point to the
point. Where ``d = 0`` it is undefined; we use the curve's *left* normal (so orient boundary
curves with the material on their left, as counter-clockwise outer loops are) and the zero
vector at a point feature. The gradient of a curve's composition (linear in arc length ``s``)
is ``dM/ds * grad s``, with ``grad s`` the gradient of the nearest-point parameter: the unit
tangent for a segment, ``r/rho`` times the tangent for an arc (``rho`` the distance to the
centre), and zero where the nearest point is an end point (or at an arc's centre). The blend
gradient is ``(M_1 - M_2) sum_i dW/dd_i grad d_i + W grad M_1 + (1 - W) grad M_2``, with
``dW/dd_i`` from :meth:`hetmesh.expr.Expr.diff`. Points equidistant from two children take the
first child in the list: never NaN.

Model file schema (``[material] type = "hft"``)
-----------------------------------------------
.. code-block:: toml

    [material]
    type = "hft"
    constituents = ["ceramic", "metal"]
    root = "plate"                        # id of the root feature

    [[material.features]]                 # leaves: composition = [m numbers] (constant) or
    id = "AB"                             #   [[m numbers], [m numbers]] (start, end: linear
    kind = "segment"                      #   in arc length), every row summing to 1
    from = [0, 0]
    to = [7, 0]
    composition = [1, 0]

    [[material.features]]
    id = "BCD"
    kind = "arc"                          # from, to and either through = [x, y] or
    from = [7, 0]                         # center = [x, y] (+ direction = "ccw" | "cw")
    to = [23, 0]
    through = [15, 8]
    composition = [[1, 0], [0.75, 0.25]]

    # kind = "point": at = [x, y];  kind = "circle": center = [x, y], radius = r
    # (+ direction = "ccw" | "cw"; it fixes the left normal used where d = 0)

    [[material.features]]
    id = "bottom"
    kind = "nearest"                      # or "composite"
    children = ["AB", "BCD", "DE", "EFG", "GH"]

    [[material.features]]
    id = "boundary"
    kind = "select"                       # first matching rule wins; the last rule has no
    rules = [                             # condition (the default)
      { child = "C", inside = "A" },      # inside / outside = id of a closed curve feature
      { child = "B", where = "x > 100" }, # where = a condition in x, y (and parameters)
      { child = "B" },
    ]

    [[material.features]]
    id = "plate"
    kind = "blend"                        # f = W M_first + (1 - W) M_second
    first = "bottom"
    second = "top"
    distances = { d_b = "bottom", d_t = "top" }   # variable -> curve feature
    weight = "exp(-5*d_b/(d_b + d_t))"    # default W
    weights = [ { owner = "C", formula = "(d_b/(d_int + d_b))**3" } ]  # per subregion:
                                          # the first rule whose owner feature is on the
                                          # subregion's path wins, else `weight`

Formulas may use the model's ``[parameters]``. Errors (one line, naming the feature):
:class:`~hetmesh.errors.ModelFileError` for unknown keys or kinds, an unknown feature
reference, a cycle in the tree, a blend used as a curve; :class:`~hetmesh.errors.MaterialError`
for a composition of the wrong length or not summing to 1, and for a weight leaving [0, 1] on
the points of :func:`~hetmesh.material.sample_domain` where it applies.
"""

from __future__ import annotations

import math
from typing import Callable, Mapping, Sequence

import numpy as np

from ...errors import GeometryError, MaterialError, ModelFileError
from ...expr import compile_expr
from ...geometry import Arc, Segment
from ..analytic import _Shiftable, check_constituents
from ..field import as_points, sample_domain

__all__ = ["HFTField", "PointFeature", "CurveFeature", "NearestFeature", "SelectFeature",
           "BlendFeature", "inside_predicate", "parse_hft"]

TWO_PI = 2.0 * math.pi


class _Eval:
    """One feature evaluated at N points (``dist``/``ddist`` are None for a blend)."""

    __slots__ = ("dist", "ddist", "comp", "dcomp", "region")

    def __init__(self, dist, ddist, comp, dcomp, region):
        self.dist, self.ddist, self.comp, self.dcomp, self.region = \
            dist, ddist, comp, dcomp, region


def _empty_eval(n: int, m: int, geometric: bool) -> _Eval:
    return _Eval(np.empty(n) if geometric else None, np.empty((n, 2)) if geometric else None,
                 np.empty((n, m)), np.empty((n, m, 2)), np.empty(n, dtype=np.int64))


# ------------------------------------------------------------------------------- leaves

class _Leaf:
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

    def evaluate(self, p, region=None) -> _Eval:
        t, q, dtdp, normal = self._geom(p, True)
        diff = p - q
        d = np.hypot(diff[:, 0], diff[:, 1])
        on = d == 0.0
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = diff / d[:, None]
        if on.any():
            unit[on] = normal[on]
        comp = self.c0 + t[:, None] * self.dc
        if np.any(self.dc) and dtdp is not None:
            dcomp = self.dc[None, :, None] * dtdp[:, None, :]
        else:
            dcomp = np.zeros((len(p), len(self.c0), 2))
        return _Eval(d, unit, comp, dcomp, np.zeros(len(p), dtype=np.int64))

    def region_path(self, r: int) -> list[str]:
        return [self.id]

    def region_name(self, r: int) -> str:
        return self.id

    def curves(self) -> list:
        return []


class PointFeature(_Leaf):
    """A point with a constant composition."""

    def __init__(self, fid: str, at, composition):
        super().__init__(fid, composition)
        self.at = np.asarray(at, dtype=float).reshape(2)

    def _geom(self, p, need_grad):
        n = len(p)
        q = np.broadcast_to(self.at, (n, 2))
        z = np.zeros((n, 2)) if need_grad else None
        return np.zeros(n), q, z, z


class CurveFeature(_Leaf):
    """A :class:`~hetmesh.geometry.Segment` or :class:`~hetmesh.geometry.Arc` whose
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
                yield k, child, (slice(None) if mask.all() else mask)

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
        for k, child, idx in self._groups(owner):
            out[idx] = child.distance(p[idx], None if sub is None else sub[idx])
        return out

    def evaluate(self, p, region=None) -> _Eval:
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
    while not isinstance(feature, _Leaf):
        feature = feature.children[0]
    return len(feature.c0)


class NearestFeature(_Parent):
    """A parent whose owning child is the one holding the nearest point (ties: the first
    child). Models a composite curve; its distance is the minimum of its children's."""

    def __init__(self, fid: str, children: Sequence):
        super().__init__(fid, children)
        bad = [c.id for c in self.children if not c.geometric]
        if bad:
            raise ModelFileError(f"feature {fid!r}: child {bad[0]!r} is a blend, which has no "
                                 f"distance (a 'nearest' parent needs curves or points)")

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
    """A parent whose owning child is given by rules ``(child index, predicate)``; the
    first rule whose ``predicate(points) -> bool (N,)`` holds wins, ``None`` always holds
    (the last rule must be such a default)."""

    def __init__(self, fid: str, children: Sequence, rules: Sequence[tuple[int, Callable | None]]):
        super().__init__(fid, children)
        if not rules or rules[-1][1] is not None:
            raise ModelFileError(f"feature {fid!r}: the last rule must have no condition "
                                 f"(the default child)")
        self.rules = list(rules)

    def _owner(self, p):
        owner = np.full(len(p), -1, dtype=np.int64)
        for k, pred in self.rules:
            todo = owner < 0
            if pred is None:
                owner[todo] = k
                break
            hit = np.asarray(pred(p), dtype=bool) & todo
            owner[hit] = k
        return owner


def inside_predicate(curves: Sequence, fid: str = "") -> Callable[[np.ndarray], np.ndarray]:
    """A vectorised ``inside(points) -> bool (N,)`` for closed chains of segments and arcs
    (in any order and orientation): crossing parity of the chord polygon, toggled inside
    each arc's circular segment (exact for arcs, no polygonal approximation)."""
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
        _, counts = np.unique(pts, axis=0, return_counts=True)
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
                inn &= side * ref > 0
            odd ^= inn
        return odd

    return inside


# ------------------------------------------------------------------------------- blend

class BlendFeature:
    """A region feature ``f = W M_first + (1 - W) M_second`` (Eqs. 19, 27).

    Parameters
    ----------
    fid : str
    first, second : features
    distances : mapping variable name -> geometric feature (e.g. ``{"d_b": bottom}``)
    weights : list of ``(formula text, owner feature id or None)``; for each subregion the
        first rule whose owner is on the subregion's path applies, ``None`` matches all.
    parameters : mapping, optional
        Constants of the formulas.
    """

    geometric = False

    def __init__(self, fid: str, first, second, distances: Mapping[str, object],
                 weights: Sequence[tuple[str, str | None]], parameters=None, where: str = ""):
        self.id = fid
        self.first, self.second = first, second
        self.children = (first, second)
        pre = f"{where}: " if where else ""
        for var, feat in distances.items():
            if not feat.geometric:
                raise ModelFileError(f"{pre}feature {fid!r}: distance {var!r} refers to blend "
                                     f"{feat.id!r}, which has no distance")
        self.distances = dict(distances)
        self.n2 = second.n_regions
        self.n_regions = first.n_regions * self.n2
        variables = tuple(self.distances)
        self.exprs = []
        for i, (text, _owner) in enumerate(weights):
            e = compile_expr(text, variables, parameters,
                             where=f"{pre}feature {fid!r}: weight {text!r}")
            self.exprs.append((e, {v: e.diff(v) for v in e.names}))
        table = []
        for r in range(self.n_regions):
            path = set(self.region_path(r))
            k = next((i for i, (_, owner) in enumerate(weights)
                      if owner is None or owner in path), None)
            if k is None:
                raise ModelFileError(f"{pre}feature {fid!r}: no weight for subregion "
                                     f"{self.region_name(r)!r} (add a default 'weight')")
            table.append(k)
        self.weight_of_region = np.array(table, dtype=np.int64)

    def region_path(self, r: int) -> list[str]:
        r1, r2 = divmod(r, self.n2)
        return [self.id] + self.first.region_path(r1) + self.second.region_path(r2)

    def region_name(self, r: int) -> str:
        r1, r2 = divmod(r, self.n2)
        return f"{self.first.region_name(r1)}|{self.second.region_name(r2)}"

    def region(self, p):
        return self.first.region(p) * self.n2 + self.second.region(p)

    def curves(self) -> list:
        return []

    def weight(self, p, region=None):
        """``(W (N,), grad W (N, 2), region (N,))`` at points ``p`` (global coordinates)."""
        return self._weight(p, *self._children(p, region))[:2]

    def _children(self, p, region):
        r1 = r2 = None
        if region is not None:
            r1, r2 = np.divmod(np.asarray(region, dtype=np.int64), self.n2)
        e1 = self.first.evaluate(p, r1)
        e2 = e1 if self.second is self.first else self.second.evaluate(p, r2)
        return e1, e2

    def _weight(self, p, e1, e2):
        cache = {id(self.first): e1, id(self.second): e2}
        dv, dg = {}, {}
        for var, feat in self.distances.items():
            ev = cache.get(id(feat))
            if ev is None:
                ev = cache[id(feat)] = feat.evaluate(p)
            dv[var], dg[var] = ev.dist, ev.ddist
        reg = e1.region * self.n2 + e2.region
        n = len(p)
        W = np.empty(n)
        dW = np.zeros((n, 2))
        widx = self.weight_of_region[reg] if len(self.exprs) > 1 else None
        for k, (e, de) in enumerate(self.exprs):
            if widx is None:
                idx = slice(None)
            else:
                idx = widx == k
                if not idx.any():
                    continue
            vals = {v: a[idx] for v, a in dv.items()}
            W[idx] = e(**vals)
            g = np.zeros((n if widx is None else int(np.count_nonzero(idx)), 2))
            for v, dexpr in de.items():
                g += dexpr(**vals)[:, None] * dg[v][idx]
            dW[idx] = g
        return W, dW, reg

    def evaluate(self, p, region=None) -> _Eval:
        e1, e2 = self._children(p, region)
        W, dW, reg = self._weight(p, e1, e2)
        delta = e1.comp - e2.comp
        comp = e2.comp + W[:, None] * delta
        dcomp = delta[:, :, None] * dW[:, None, :]
        dcomp += W[:, None, None] * e1.dcomp
        dcomp += (1.0 - W)[:, None, None] * e2.dcomp
        return _Eval(None, None, comp, dcomp, reg)


# ------------------------------------------------------------------------------- field

class HFTField(_Shiftable):
    """A material field given by a feature tree.

    Parameters
    ----------
    root : feature
        Normally a :class:`BlendFeature`.
    constituents : sequence of str

    Examples
    --------
    >>> from hetmesh.geometry import Segment
    >>> bot = CurveFeature("bot", Segment((0, 0), (1, 0)), [1.0, 0.0])
    >>> top = CurveFeature("top", Segment((1, 1), (0, 1)), [0.0, 1.0])
    >>> f = HFTField(BlendFeature("r", bot, top, {"d_b": bot, "d_t": top},
    ...                           [("d_t/(d_b + d_t)", None)]), ["ceramic", "metal"])
    >>> f.composition([[0.5, 0.25]]).tolist()
    [[0.75, 0.25]]
    >>> f.gradient([[0.5, 0.25]])[0, 0].tolist()
    [0.0, -1.0]
    """

    def __init__(self, root, constituents: Sequence[str]):
        self.root = root
        self.constituents = check_constituents(constituents)

    def __repr__(self) -> str:
        return f"HFTField(root={self.root.id!r}, constituents={list(self.constituents)})"

    @property
    def n_regions(self) -> int:
        return self.root.n_regions

    @property
    def region_names(self) -> list[str]:
        """Names of the subregions by id: their owning leaves joined by ``|``."""
        return [self.root.region_name(r) for r in range(self.root.n_regions)]

    def _region_arg(self, region, n):
        if region is None:
            return None
        r = np.asarray(region, dtype=np.int64)
        r = np.broadcast_to(r, (n,)) if r.ndim == 0 else r
        if r.shape != (n,) or (n and (r.min() < 0 or r.max() >= self.n_regions)):
            raise MaterialError(f"{self!r}: region must be {n} ids in [0, {self.n_regions}), "
                                f"got shape {r.shape}")
        return r

    def evaluate(self, points, region=None):
        """``(composition (N, m), gradient (N, m, 2), region (N,))`` in one pass.

        The last result is kept, keyed by the *contents* of the points and regions, so that
        ``composition(p)`` followed by ``gradient(p)`` (as the mesher calls them) evaluates
        the tree once; callers get copies.
        """
        p = self._global(points)
        r = self._region_arg(region, len(p))
        key = (p.shape, hash(p.tobytes()), None if r is None else hash(r.tobytes()))
        cached = getattr(self, "_cache", None)
        if cached is None or cached[0] != key:
            ev = self.root.evaluate(p, r)
            cached = self._cache = (key, ev.comp, ev.dcomp, ev.region)
        return cached[1].copy(), cached[2].copy(), cached[3].copy()

    def composition(self, points, region=None) -> np.ndarray:
        """Volume fractions ``(N, m)``; with ``region``, those of the given subregions."""
        return self.evaluate(points, region)[0]

    def gradient(self, points, region=None) -> np.ndarray:
        """Exact gradients ``(N, m, 2)``; with ``region``, those of the given subregions."""
        return self.evaluate(points, region)[1]

    def region(self, points) -> np.ndarray:
        """The subregion id ``(N,)`` owning each point (see :attr:`region_names`)."""
        return self.root.region(self._global(points))

    def check_weights(self, points, where: str = "") -> None:
        """Raise :class:`MaterialError` if a blend's W leaves [0, 1] at ``points``."""
        p = as_points(points)
        pre = f"{where}: " if where else ""
        for feat in _walk(self.root):
            if not isinstance(feat, BlendFeature):
                continue
            e1, e2 = feat._children(p, None)
            W, _, reg = feat._weight(p, e1, e2)
            widx = feat.weight_of_region[reg]
            excess = np.where(np.isfinite(W), np.maximum(W - 1.0, -W), np.inf)
            i = int(np.argmax(excess)) if len(W) else 0
            if len(W) and excess[i] > 1e-12:  # report the worst point
                text = feat.exprs[widx[i]][0].text
                raise MaterialError(f"{pre}feature {feat.id!r}: weight {text!r} is "
                                    f"{W[i]:.6g} at ({p[i, 0]:.6g}, {p[i, 1]:.6g}) in "
                                    f"subregion {feat.region_name(int(reg[i]))!r}, "
                                    f"outside [0, 1]")


def _walk(feature, seen=None):
    seen = set() if seen is None else seen
    if id(feature) in seen:
        return
    seen.add(id(feature))
    yield feature
    for c in feature.children:
        yield from _walk(c, seen)
    if isinstance(feature, BlendFeature):
        for f in feature.distances.values():
            yield from _walk(f, seen)


# ------------------------------------------------------------------------------- parser

_LEAF_KEYS = {
    "point": (("at", "composition"), ()),
    "segment": (("from", "to", "composition"), ()),
    "arc": (("from", "to", "composition"), ("through", "center", "direction")),
    "circle": (("center", "radius", "composition"), ("direction",)),
}
_KINDS = ("point", "segment", "arc", "circle", "nearest", "composite", "select", "blend")


def parse_hft(ctx, table: dict, domain, parameters: dict) -> HFTField:
    """The ``[material]`` parser of ``type = "hft"`` (see the module docstring)."""
    from ...io.model import _describe  # local: io.model imports this module

    t = ctx.table(table, "material", required=("type", "constituents", "root", "features"))
    cons = t["constituents"]
    if not isinstance(cons, list) or not all(isinstance(c, str) for c in cons):
        raise ctx.fail("material.constituents", f"expected an array of names, got "
                                                f"{_describe(cons)}")
    try:
        cons = check_constituents(cons)
    except MaterialError as exc:
        raise ctx.fail("material.constituents", str(exc).split(": ", 1)[-1]) from None
    m = len(cons)
    feats = t["features"]
    if not isinstance(feats, list) or not feats:
        raise ctx.fail("material.features", f"expected an array of tables "
                                             f"([[material.features]]), got {_describe(feats)}")
    raw: dict[str, tuple[str, dict]] = {}
    for i, item in enumerate(feats):
        key = f"material.features[{i}]"
        if not isinstance(item, Mapping):
            raise ctx.fail(key, f"expected a table, got {_describe(item)}")
        fid = item.get("id")
        if not isinstance(fid, str) or not fid.strip():
            raise ctx.fail(f"{key}.id", f"expected a non-empty feature id, got "
                                        f"{_describe(fid) if 'id' in item else 'nothing'}")
        if fid in raw:
            raise ctx.fail(f"{key}.id", f"feature {fid!r} is defined twice")
        kind = item.get("kind")
        if kind not in _KINDS:
            raise ctx.fail(f"material.features.{fid}.kind",
                           f"unknown kind {kind!r} (expected one of: {', '.join(_KINDS)})")
        raw[fid] = (f"material.features.{fid}", dict(item))
    root_id = t["root"]
    if not isinstance(root_id, str) or root_id not in raw:
        raise ctx.fail("material.root", f"unknown feature {root_id!r} (features: "
                                        f"{', '.join(raw)})")

    built: dict[str, object] = {}
    state: dict[str, int] = {}  # 1 = in progress, 2 = done

    def ref(fid: str, name, what: str, stack: list[str]):
        if not isinstance(name, str):
            raise ctx.fail(f"material.features.{fid}", f"{what}: expected a feature id, got "
                                               f"{_describe(name)}")
        if name not in raw:
            raise ctx.fail(f"material.features.{fid}", f"{what}: unknown feature {name!r}")
        return build(name, stack + [fid])

    def comp_vec(fid, v, what):
        ok = isinstance(v, list) and all(isinstance(c, (int, float)) and not isinstance(c, bool)
                                         and math.isfinite(c) for c in v)
        if not ok:
            raise ctx.fail(f"material.features.{fid}", f"{what}: expected an array of numbers, got "
                                               f"{_describe(v)}", MaterialError)
        if len(v) != m:
            raise ctx.fail(f"material.features.{fid}", f"{what} has {len(v)} values but there are "
                                               f"{m} constituents ({', '.join(cons)})",
                           MaterialError)
        a = np.array(v, dtype=float)
        if a.min() < 0 or a.max() > 1 or abs(a.sum() - 1.0) > 1e-9:
            shown = _describe(v).split(" (")[0]
            raise ctx.fail(f"material.features.{fid}", f"{what} {shown} is not a composition "
                                                       f"(values in [0, 1] summing to 1)",
                           MaterialError)
        return a

    def compositions(fid, v, pair_ok: bool):
        if isinstance(v, list) and v and all(isinstance(r, list) for r in v):
            if not pair_ok or len(v) != 2:
                raise ctx.fail(f"material.features.{fid}", "composition: expected [m numbers]" +
                               (" or [[start], [end]]" if pair_ok else ""), MaterialError)
            return comp_vec(fid, v[0], "start composition"), \
                comp_vec(fid, v[1], "end composition")
        return comp_vec(fid, v, "composition"), None

    def build(fid: str, stack: list[str]):
        if state.get(fid) == 2:
            return built[fid]
        if state.get(fid) == 1:
            cyc = stack[stack.index(fid):] + [fid]
            raise ctx.fail(f"material.features.{fid}", f"cycle in the feature tree: "
                                               f"{' -> '.join(cyc)}")
        state[fid] = 1
        key, item = raw[fid]
        kind = item["kind"]
        here = f"{ctx.pre}{key}"
        if kind in _LEAF_KEYS:
            req, opt = _LEAF_KEYS[kind]
            ctx.table(item, key, required=("id", "kind") + req, optional=opt)
            c0, c1 = compositions(fid, item["composition"], kind != "point")
            try:
                if kind == "point":
                    feat = PointFeature(fid, ctx.point(item["at"], f"{key}.at"), c0)
                elif kind == "segment":
                    a, b = ctx.point(item["from"], f"{key}.from"), ctx.point(item["to"],
                                                                          f"{key}.to")
                    if a == b:
                        raise ctx.fail(key, "zero-length segment", ModelFileError)
                    feat = CurveFeature(fid, Segment(a, b, fid), c0, c1)
                elif kind == "circle":
                    c = ctx.point(item["center"], f"{key}.center")
                    r = ctx.number(item["radius"], f"{key}.radius", positive=True)
                    direction = ctx.string(item, key, "direction", default="ccw")
                    if direction not in ("ccw", "cw"):
                        raise ctx.fail(f"{key}.direction", f"expected \"ccw\" or \"cw\", "
                                                           f"got {direction!r}")
                    feat = CurveFeature(fid, Arc.circle(c, r, ccw=direction == "ccw",
                                                        name=fid), c0, c1)
                else:
                    a, b = ctx.point(item["from"], f"{key}.from"), ctx.point(item["to"],
                                                                          f"{key}.to")
                    if ("through" in item) == ("center" in item):
                        raise ctx.fail(key, "an arc needs exactly one of 'through' and "
                                            "'center'")
                    if "through" in item:
                        if "direction" in item:
                            raise ctx.fail(f"{key}.direction", "only an arc given by "
                                                               "'center' has a direction")
                        arc = Arc.through(a, ctx.point(item["through"], f"{key}.through"), b,
                                          name=fid, where=here)
                    else:
                        direction = ctx.string(item, key, "direction", default="ccw")
                        if direction not in ("ccw", "cw"):
                            raise ctx.fail(f"{key}.direction", f"expected \"ccw\" or \"cw\", "
                                                               f"got {direction!r}")
                        arc = Arc.from_center(a, b, ctx.point(item["center"], f"{key}.center"),
                                              ccw=direction == "ccw", name=fid, where=here)
                    feat = CurveFeature(fid, arc, c0, c1)
            except GeometryError as exc:
                raise ctx.wrap(key, exc) from None
        elif kind in ("nearest", "composite"):
            ctx.table(item, key, required=("id", "kind", "children"))
            kids = item["children"]
            if not isinstance(kids, list) or not kids:
                raise ctx.fail(f"{key}.children", f"expected a non-empty array of feature "
                                                  f"ids, got {_describe(kids)}")
            children = [ref(fid, k, "children", stack) for k in kids]
            try:
                feat = NearestFeature(fid, children)
            except ModelFileError as exc:
                raise ctx.wrap("", exc) from None
        elif kind == "select":
            ctx.table(item, key, required=("id", "kind", "rules"))
            rules_in = item["rules"]
            if not isinstance(rules_in, list) or not rules_in:
                raise ctx.fail(f"{key}.rules", f"expected a non-empty array of "
                                               f"{{ child = ..., inside | outside | where }} "
                                               f"tables, got {_describe(rules_in)}")
            children, index, rules = [], {}, []
            for j, rt in enumerate(rules_in):
                rk = f"{key}.rules[{j}]"
                rt = ctx.table(rt, rk, required=("child",),
                               optional=("inside", "outside", "where"))
                conds = [k for k in ("inside", "outside", "where") if k in rt]
                if len(conds) > 1:
                    raise ctx.fail(rk, "give at most one of 'inside', 'outside' and 'where'")
                child = ref(fid, rt["child"], f"rules[{j}].child", stack)
                if id(child) not in index:
                    index[id(child)] = len(children)
                    children.append(child)
                pred = None
                if conds and conds[0] in ("inside", "outside"):
                    target = ref(fid, rt[conds[0]], f"rules[{j}].{conds[0]}", stack)
                    curves = target.curves() if target.geometric else []
                    if not curves:
                        raise ctx.fail(rk, f"{conds[0]}: feature {target.id!r} is not a "
                                           f"closed curve")
                    try:
                        ins = inside_predicate(curves, target.id)
                    except ModelFileError as exc:
                        raise ctx.wrap("", exc) from None
                    pred = ins if conds[0] == "inside" else (lambda p, _f=ins: ~_f(p))
                elif conds:
                    text = rt["where"]
                    if not isinstance(text, str):
                        raise ctx.fail(f"{rk}.where", f"expected a condition string, got "
                                                      f"{_describe(text)}")
                    e = compile_expr(f"where({text}, 1, 0)", ("x", "y"), parameters,
                                     where=f"{here}: rules[{j}].where {text!r}")
                    pred = (lambda p, _e=e: _e(x=p[:, 0], y=p[:, 1]) > 0.5)
                rules.append((index[id(child)], pred))
            if rules[-1][1] is not None:
                raise ctx.fail(f"{key}.rules", "the last rule must have no condition "
                                               "(the default child)")
            feat = SelectFeature(fid, children, rules)
        else:  # blend
            ctx.table(item, key, required=("id", "kind", "first", "second", "distances"),
                      optional=("weight", "weights"))
            first = ref(fid, item["first"], "first", stack)
            second = ref(fid, item["second"], "second", stack)
            dist_in = item["distances"]
            if not isinstance(dist_in, Mapping) or not dist_in:
                raise ctx.fail(f"{key}.distances", f"expected a table variable = feature id, "
                                                   f"got {_describe(dist_in)}")
            distances = {}
            for var, target in dist_in.items():
                if not (var.isascii() and var.isidentifier()) or var in ("x", "y") \
                        or var in parameters:
                    raise ctx.fail(f"{key}.distances.{var}", f"{var!r} is not a usable "
                                                             f"variable name")
                distances[var] = ref(fid, target, f"distances.{var}", stack)
            weights = []
            if not isinstance(item.get("weights", []), list):
                raise ctx.fail(f"{key}.weights", f"expected an array of {{ owner, formula }} "
                                                 f"tables, got {_describe(item['weights'])}")
            for j, wt in enumerate(item.get("weights", [])):
                wk = f"{key}.weights[{j}]"
                wt = ctx.table(wt, wk, required=("owner", "formula"))
                owner = wt["owner"]
                if not isinstance(owner, str) or owner not in raw:
                    raise ctx.fail(key, f"weights[{j}].owner: unknown feature "
                                                       f"{owner!r}")
                formula = wt["formula"]
                if not isinstance(formula, str):
                    raise ctx.fail(f"{wk}.formula", f"expected a formula string, got "
                                                    f"{_describe(formula)}")
                weights.append((formula, owner))
            if "weight" in item:
                if not isinstance(item["weight"], str):
                    raise ctx.fail(f"{key}.weight", f"expected a formula string, got "
                                                    f"{_describe(item['weight'])}")
                weights.append((item["weight"], None))
            if not weights:
                raise ctx.fail(key, "a blend needs 'weight' and/or 'weights'")
            try:
                feat = BlendFeature(fid, first, second, distances, weights, parameters,
                                    where=ctx.where)
            except ModelFileError as exc:
                raise ctx.wrap("", exc) from None
        state[fid] = 2
        built[fid] = feat
        return feat

    root = build(root_id, [])
    for fid in raw:  # every feature is checked, also those the root does not reach
        build(fid, [])
    field = HFTField(root, cons)
    if domain is not None:
        field.check_weights(sample_domain(domain, 60), ctx.where)
    return field
