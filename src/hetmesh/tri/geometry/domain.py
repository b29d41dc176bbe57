"""Loops, interface paths and the domain they bound.

A :class:`Domain` is an outer :class:`Loop`, holes (loops strictly inside it, apart from each
other), interfaces (:class:`Path`, open or closed chains inside the domain, embedded in the
mesh) and named points (fixed mesh vertices). Tolerances are relative to the domain's diameter
and geometric work is done relative to a reference point, so coordinates offset by ``1e9``
behave like coordinates near the origin.

Examples
--------
>>> d = make_domain(Loop.polygon([(0, 0), (2, 0), (2, 1), (0, 1)], "outer"),
...                 holes=[Loop((Arc.circle((1, 0.5), 0.25),), "hole")])
>>> round(d.area, 12) == round(2 - math.pi / 16, 12), d.contains([[0.1, 0.1], [1, 0.5]]).tolist()
(True, [True, False])
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Mapping, NamedTuple, Sequence

import numpy as np
import shapely
from shapely.geometry import LinearRing, LineString, Polygon

from hetmesh.errors import GeometryError

from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .curves import (TWO_PI, Arc, Curve, CurveBatch, Segment, fmt_num, fmt_point,
                     sample_parameters, segments_through, tolerance)

__all__ = ["Loop", "Path", "CurveInfo", "Domain", "make_domain", "fixed_vertices"]

VALIDATION_CHORD = 1e-6  # chord tolerance of validation / containment samples, x diameter
CONTACT = 4 * VALIDATION_CHORD  # curves closer than this (x diameter) touch
POLYGON_CHORD = 1e-4  # default chord tolerance of Domain.polygon, x diameter


# ----------------------------------------------------------------------------- chains
def _as_curves(curves, name: str) -> tuple[Curve, ...]:
    curves = (curves,) if isinstance(curves, (Segment, Arc)) else tuple(curves)
    for i, c in enumerate(curves):
        if not isinstance(c, (Segment, Arc)):
            raise GeometryError(f"{name or 'chain'}: curve {i} is not a Segment or Arc: {c!r}")
    return curves


@dataclass(frozen=True)
class _Chain:
    curves: tuple[Curve, ...]
    name: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", str(self.name))
        object.__setattr__(self, "curves", _as_curves(self.curves, self.name))

    @property
    def length(self) -> float:
        return float(sum(c.length for c in self.curves))

    @property
    def vertices(self) -> np.ndarray:
        """Curve start points ``(K, 2)``."""
        return CurveBatch.from_curves(self.curves).p0

    def translated(self, offset):
        return replace(self, curves=tuple(c.translated(offset) for c in self.curves))

    def scaled(self, factor: float):
        return replace(self, curves=tuple(c.scaled(factor) for c in self.curves))


@dataclass(frozen=True)
class Loop(_Chain):
    """A closed chain of curves: ``curves[i].end == curves[i + 1].start`` (cyclically).

    Examples
    --------
    >>> Loop.polygon([(0, 0), (1, 0), (0, 1)], "tri").signed_area
    0.5
    """

    @classmethod
    def polygon(cls, vertices, name: str = "", *, where: str = "") -> Loop:
        """The closed polygon through ``vertices`` (a repeated closing vertex is dropped)."""
        return cls(segments_through(vertices, closed=True, name=name, where=where), name)

    @property
    def signed_area(self) -> float:
        """Exact signed area (positive if counter-clockwise)."""
        b = CurveBatch.from_curves(self.curves)
        return float(b.green_area(b.p0[0]).sum())


@dataclass(frozen=True)
class Path(_Chain):
    """An open or closed chain of curves: an interface embedded in the mesh."""

    @classmethod
    def polyline(cls, points, name: str = "", *, closed: bool = False, where: str = "") -> Path:
        """The polyline through ``points`` (back to the first point if ``closed``)."""
        return cls(segments_through(points, closed=closed, name=name, where=where), name)

    def is_closed(self, tol: float | None = None) -> bool:
        """Whether the last curve ends (within ``tol``) where the first starts."""
        b = CurveBatch.from_curves(self.curves)
        if tol is None:
            bb = b.bounds()
            tol = tolerance(float(np.hypot(*(bb[:, 2:].max(0) - bb[:, :2].min(0)))),
                       float(np.abs(bb).max()))
        return bool(np.hypot(*(b.p1[-1] - b.p0[0])) <= tol)


class CurveInfo(NamedTuple):
    """One curve of a domain, with its role and its edge marker (``1 +`` its index)."""

    curve: Curve
    kind: str  # 'outer' | 'hole' | 'interface'
    marker: int
    name: str
    owner: str


# ----------------------------------------------------------------------------- domain
def _chain(value, cls, name: str):
    if isinstance(value, cls):
        return value if value.name else replace(value, name=name)
    if isinstance(value, _Chain):
        return cls(value.curves, value.name or name)
    return cls(value, name)


@dataclass(frozen=True)
class Domain:
    """An outer loop with holes, interface paths and named points.

    Build it with :func:`make_domain`, which also validates it.

    Parameters
    ----------
    outer : Loop (or a sequence of curves)
    holes : sequence of Loop
    interfaces : sequence of Path
    points : mapping of name to ``(x, y)``
        Fixed mesh vertices inside the domain.
    """

    outer: Loop
    holes: tuple[Loop, ...] = ()
    interfaces: tuple[Path, ...] = ()
    points: Mapping[str, tuple[float, float]] = field(default_factory=dict, hash=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "outer", _chain(self.outer, Loop, "outer"))
        set_(self, "holes", tuple(_chain(h, Loop, f"hole[{i}]")
                                  for i, h in enumerate(_seq(self.holes))))
        set_(self, "interfaces", tuple(_chain(p, Path, f"interface[{i}]")
                                       for i, p in enumerate(_seq(self.interfaces))))
        pts = {}
        for k, v in dict(self.points or {}).items():
            a = np.asarray(v, dtype=np.float64)
            if a.shape != (2,):
                raise GeometryError(f"point '{k}' must be a pair of numbers, got {v!r}")
            pts[str(k)] = (float(a[0]), float(a[1]))
        set_(self, "points", pts)

    # -- structure
    @cached_property
    def chains(self) -> tuple[tuple[str, Loop | Path], ...]:
        """``(kind, chain)`` of the outer loop, the holes, then the interfaces.

        ``kind`` is ``"outer"``, ``"hole"`` or ``"interface"``; :attr:`curves` lists the
        chains' curves in this order.
        """
        return (("outer", self.outer),) + tuple(("hole", h) for h in self.holes) + \
            tuple(("interface", p) for p in self.interfaces)

    @cached_property
    def chain_starts(self) -> np.ndarray:
        """``(n_chains + 1,)`` start index of every chain's curves in :attr:`curves`."""
        return np.r_[0, np.cumsum([len(o.curves) for _, o in self.chains])]

    @cached_property
    def curves(self) -> tuple[CurveInfo, ...]:
        """Every curve: outer loop, then holes, then interfaces; marker = 1 + index."""
        out = []
        for kind, owner in self.chains:
            for i, c in enumerate(owner.curves):
                out.append(CurveInfo(c, kind, len(out) + 1, c.name or f"{owner.name}[{i}]",
                                     owner.name))
        return tuple(out)

    @cached_property
    def curve_batch(self) -> CurveBatch:
        """All curves (in :attr:`curves` order) as flat arrays."""
        return CurveBatch.from_curves([c for _, o in self.chains for c in o.curves])

    @cached_property
    def chain_closed(self) -> np.ndarray:
        """``(n_chains,)`` bool: whether the chain is closed (loops always)."""
        b, tol, s = self.curve_batch, self.tol, self.chain_starts
        return np.array([kind != "interface" or
                         bool(np.hypot(*(b.p1[s[k + 1] - 1] - b.p0[s[k]])) <= tol)
                         for k, (kind, _) in enumerate(self.chains)])

    # -- measures
    @cached_property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)``, exact for arcs."""
        bb = self.curve_batch.bounds()
        return (float(bb[:, 0].min()), float(bb[:, 1].min()),
                float(bb[:, 2].max()), float(bb[:, 3].max()))

    @property
    def diameter(self) -> float:
        """The diagonal of the bounding box: the length scale of all tolerances."""
        x0, y0, x1, y1 = self.bounds
        return math.hypot(x1 - x0, y1 - y0)

    @cached_property
    def _origin(self) -> np.ndarray:
        return self.curve_batch.p0[0].copy()

    @cached_property
    def tol(self) -> float:
        """The geometric tolerance: points closer than this are the same point."""
        return tolerance(self.diameter, float(np.abs(self.bounds).max()))

    @cached_property
    def area(self) -> float:
        """Exact area: outer loop minus holes (arcs contribute their circular segments)."""
        g = self.curve_batch.green_area(self._origin)
        s = self.chain_starts
        loops = [abs(float(g[s[k]:s[k + 1]].sum())) for k in range(1 + len(self.holes))]
        return loops[0] - sum(loops[1:])

    # -- sampled geometry (local coordinates, relative to _origin)
    def _sampled(self, chord_tol: float) -> list[np.ndarray]:
        """Per owner, sampled coordinates relative to the origin; closed chains repeat p[0]."""
        b = self.curve_batch
        o = self._origin
        local = replace(b, p0=b.p0 - o, p1=b.p1 - o, center=b.center - o)
        off, t = sample_parameters(local, np.inf, chord_tol)
        pts = local.points(np.repeat(np.arange(len(b)), np.diff(off)), t)
        keep = np.ones(len(t), dtype=bool)
        keep[off[1:] - 1] = False
        out = []
        for k in range(len(self.chains)):
            lo, hi = off[self.chain_starts[k]], off[self.chain_starts[k + 1]]
            p = pts[lo:hi][keep[lo:hi]]
            out.append(np.vstack([p, p[:1] if self.chain_closed[k] else pts[hi - 1:hi]]))
        return out

    def polygon(self, chord_tol: float | None = None) -> Polygon:
        """The domain as a shapely Polygon with holes, arcs sampled to ``chord_tol``."""
        tol = POLYGON_CHORD * self.diameter if chord_tol is None else chord_tol
        rings = [r + self._origin for r in self._sampled(tol)[:1 + len(self.holes)]]
        return Polygon(rings[0], rings[1:])

    @cached_property
    def _fine(self) -> list[np.ndarray]:
        return self._sampled(VALIDATION_CHORD * self.diameter)

    @cached_property
    def _local_polygon(self) -> Polygon:
        n = 1 + len(self.holes)
        poly = Polygon(self._fine[0], self._fine[1:n])
        shapely.prepare(poly)
        return poly

    def contains(self, points) -> np.ndarray:
        """Whether points lie strictly inside the domain (holes excluded) -> bool (N,)."""
        p = np.asarray(points, dtype=np.float64) - self._origin
        return shapely.contains_xy(self._local_polygon, p[..., 0], p[..., 1])

    def distance_to_boundary(self, points, *, interfaces: bool = True) -> np.ndarray:
        """Exact distance to the nearest curve (interfaces included unless disabled)."""
        b = self.curve_batch
        if not interfaces:
            b = _sub(b, 0, int(self.chain_starts[1 + len(self.holes)]))
        return b.distance(points)

    # -- fixed vertices
    @cached_property
    def junctions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
        """The fixed vertices of the domain's PSLG: see :func:`fixed_vertices`."""
        return fixed_vertices(self)

    @property
    def corners(self) -> np.ndarray:
        """Fixed points ``(K, 2)``: curve end points and named points, deduplicated."""
        return self.junctions[0].copy()

    def translated(self, offset) -> Domain:
        """The domain moved by ``offset``."""
        o = np.asarray(offset, dtype=np.float64)
        return Domain(self.outer.translated(o), tuple(h.translated(o) for h in self.holes),
                      tuple(p.translated(o) for p in self.interfaces),
                      {k: tuple(np.asarray(v) + o) for k, v in self.points.items()})

    def scaled(self, factor: float) -> Domain:
        """The domain with every coordinate multiplied by ``factor`` (> 0).

        With a power of two for ``factor`` the result is exact: the mesher works on the
        domain scaled to a diameter near 1, whatever the user's units.
        """
        f = float(factor)
        return Domain(self.outer.scaled(f), tuple(h.scaled(f) for h in self.holes),
                      tuple(p.scaled(f) for p in self.interfaces),
                      {k: tuple(np.asarray(v) * f) for k, v in self.points.items()})

    def validate(self, where: str = "") -> Domain:
        """Check the domain; raise :class:`GeometryError` naming the curve and the place.

        Returns the domain itself, so that ``Domain(...).validate()`` chains.
        """
        try:
            _validate(self)
        except GeometryError as e:
            raise GeometryError(f"{where}: {e}" if where else str(e)) from None
        return self


def _seq(value) -> tuple:
    if value is None:
        return ()
    if isinstance(value, (_Chain, Segment, Arc)):
        return (value,)
    return tuple(value)


def make_domain(outer, holes: Sequence = (), interfaces: Sequence = (),
                points: Mapping[str, Sequence[float]] | None = None, *,
                where: str = "") -> Domain:
    """Build and validate a :class:`Domain`.

    ``outer``, every hole and every interface may be a :class:`Loop` / :class:`Path` or a
    plain sequence of curves (named ``outer``, ``hole[i]``, ``interface[i]``). ``where``
    prefixes every error message (e.g. the model file's name).

    Raises
    ------
    GeometryError
        On any problem found by :meth:`Domain.validate`.
    """
    try:
        d = Domain(outer, holes, interfaces, points or {})
    except GeometryError as e:
        raise GeometryError(f"{where}: {e}" if where else str(e)) from None
    return d.validate(where)


def _sub(b: CurveBatch, i0: int, i1: int) -> CurveBatch:
    return CurveBatch(*(getattr(b, f)[i0:i1] for f in b.__dataclass_fields__))


# ----------------------------------------------------------------------------- validation
_LOC = re.compile(r"\[\s*(\S+)\s+([^\s\]]+)")


def _validate(d: Domain) -> None:
    """Run every check in order; the first failure raises."""
    for check in (_check_structure, _check_finite, _check_scale, _check_curves, _check_chains,
                  _check_loops, _check_holes, _check_interfaces, _check_points):
        check(d)


def _label(d: Domain, i: int) -> str:
    k = int(np.searchsorted(d.chain_starts, i, side="right") - 1)
    c = d.curves[i].curve
    own = f" ('{c.name}')" if c.name else ""
    return f"{d.chains[k][1].name}: curve {i - int(d.chain_starts[k])}{own}"


def _pt(d: Domain, local) -> str:
    """A local point (relative to the origin) in user coordinates, to the sampling accuracy."""
    step = 10.0 ** math.floor(math.log10(VALIDATION_CHORD * d.diameter))
    return fmt_point(np.round((np.asarray(local, dtype=np.float64) + d._origin) / step) * step)


def _rep(geom) -> np.ndarray:
    return np.array(geom.representative_point().coords[0])


def _check_structure(d: Domain) -> None:
    names = [o.name for _, o in d.chains]
    for n in names:
        if names.count(n) > 1:
            raise GeometryError(f"the name '{n}' is used by more than one loop or interface")
    for _, o in d.chains:
        if not o.curves:
            raise GeometryError(f"{o.name}: has no curves")


def _check_finite(d: Domain) -> None:
    b = d.curve_batch
    vals = np.c_[b.p0, b.p1, b.center, b.radius, b.theta0, b.sweep]
    bad = ~np.isfinite(vals).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        c = d.curves[i].curve
        if isinstance(c, Segment):
            raise GeometryError(f"{_label(d, i)} has a non-finite coordinate: from "
                                f"{fmt_point(c.p0)} to {fmt_point(c.p1)}")
        raise GeometryError(f"{_label(d, i)} has a non-finite value: arc centre "
                            f"{fmt_point(c.center)}, radius {fmt_num(c.radius)}, angles "
                            f"{fmt_num(c.theta0)} to {fmt_num(c.theta1)}")
    for k, v in d.points.items():
        if not np.isfinite(v).all():
            raise GeometryError(f"point '{k}' has a non-finite coordinate {fmt_point(v)}")


#: the range of domain sizes (diameter) hetmesh meshes: areas and squared lengths of the
#: model's own coordinates must be representable in double precision (1e-308 to 1e308)
SIZE_RANGE = (1e-152, 1e152)


def _check_scale(d: Domain) -> None:
    lo, hi = SIZE_RANGE
    diam = d.diameter
    if not (lo <= diam <= hi):
        raise GeometryError(f"the domain's size (diameter {fmt_num(diam)}) is outside the range "
                            f"hetmesh supports, {lo:g} to {hi:g}: its area cannot be computed in "
                            "floating point; give the model in other units")


def _first(mask: np.ndarray) -> int | None:
    return int(np.flatnonzero(mask)[0]) if mask.any() else None


def _check_curves(d: Domain) -> None:
    b, tol = d.curve_batch, d.tol
    if (i := _first(~b.is_arc & (b.length <= tol))) is not None:
        raise GeometryError(f"{_label(d, i)} is a zero-length segment (duplicate consecutive "
                            f"points) at {fmt_point(b.p0[i])}")
    if (i := _first(b.is_arc & ~(b.radius > tol))) is not None:
        raise GeometryError(f"{_label(d, i)} is an arc with radius {fmt_num(b.radius[i])}; "
                            f"the radius must be positive")
    if (i := _first(b.is_arc & (b.length <= tol))) is not None:
        raise GeometryError(f"{_label(d, i)} is a zero-length arc at {fmt_point(b.p0[i])}")
    if (i := _first(b.is_arc & (np.abs(b.sweep) > TWO_PI * (1 + 1e-9)))) is not None:
        raise GeometryError(f"{_label(d, i)} is an arc sweeping "
                            f"{fmt_num(math.degrees(abs(b.sweep[i])))} degrees (more than 360)")


def _check_chains(d: Domain) -> None:
    b, tol = d.curve_batch, d.tol
    for k, (kind, o) in enumerate(d.chains):
        i0, i1 = d.chain_starts[k], d.chain_starts[k + 1]
        p0, p1 = b.p0[i0:i1], b.p1[i0:i1]
        if (j := _first(np.hypot(*(p0[1:] - p1[:-1]).T) > tol)) is not None:
            raise GeometryError(f"{o.name}: curve {j + 1} starts at {fmt_point(p0[j + 1])} "
                                f"but curve {j} ends at {fmt_point(p1[j])}")
        if kind != "interface" and np.hypot(*(p0[0] - p1[-1])) > tol:
            raise GeometryError(f"{o.name}: curve 0 starts at {fmt_point(p0[0])} but curve "
                                f"{len(p0) - 1} ends at {fmt_point(p1[-1])} "
                                f"(the loop is not closed)")


def _check_loops(d: Domain) -> None:
    b = d.curve_batch
    for k in range(1 + len(d.holes)):
        o = d.chains[k][1]
        i0, i1 = d.chain_starts[k], d.chain_starts[k + 1]
        if not b.is_arc[i0:i1].any() and i1 - i0 < 3:
            raise GeometryError(f"{o.name}: a polygonal loop needs at least 3 vertices, "
                                f"got {i1 - i0}")
        reason = shapely.is_valid_reason(Polygon(d._fine[k]))
        if reason != "Valid Geometry":
            m = _LOC.search(reason)
            try:
                where = _pt(d, [float(m.group(1)), float(m.group(2))])
            except (AttributeError, ValueError):
                where = fmt_point(b.p0[i0])
            raise GeometryError(f"{o.name}: the boundary intersects itself near {where}")
        area = abs(float(b.green_area(b.p0[i0])[i0:i1].sum()))
        if area <= d.tol * d.diameter:
            raise GeometryError(f"{o.name}: the loop encloses no area (near "
                                f"{fmt_point(b.p0[i0])})")


def _touch(ga, gb, d: Domain, shared: np.ndarray | None = None) -> np.ndarray | None:
    """A local point where ``ga`` and ``gb`` come closer than the contact tolerance.

    Samples sit within ``VALIDATION_CHORD * diameter`` of the true curves, so curves closer
    than ``CONTACT * diameter`` count as touching (tangent circles included). Parts of ``ga``
    near ``shared`` points (curve ends both chains may share) are left out.
    """
    tol = CONTACT * d.diameter
    if shared is not None and len(shared):
        ga = ga.difference(shapely.buffer(shapely.multipoints(shared), 1000 * tol))
    if ga.is_empty or not shapely.dwithin(ga, gb, tol):
        return None
    return np.asarray(shapely.shortest_line(ga, gb).coords).mean(axis=0)


def _check_holes(d: Domain) -> None:
    H = len(d.holes)
    if not H:
        return
    outer = Polygon(d._fine[0])
    holes = [Polygon(r) for r in d._fine[1:1 + H]]
    oname = d.outer.name
    for i, h in enumerate(holes):
        inter = h.exterior.intersection(outer.exterior)
        near = _rep(inter) if not inter.is_empty else _touch(h.exterior, outer.exterior, d)
        if near is not None:
            raise GeometryError(f"{d.holes[i].name}: not strictly inside {oname}: touches or "
                                f"crosses it near {_pt(d, near)}")
        if not shapely.contains_properly(outer, h):
            raise GeometryError(f"{d.holes[i].name}: not strictly inside {oname}: it lies "
                                f"outside, e.g. at {_pt(d, d._fine[1 + i][0])}")
    a, c = shapely.STRtree(holes).query(holes, predicate="dwithin",
                                        distance=CONTACT * d.diameter)
    for i, j in zip(a[a < c], c[a < c]):
        inter = holes[i].intersection(holes[j])
        near = _rep(inter) if not inter.is_empty else _touch(holes[i], holes[j], d)
        if near is not None:
            raise GeometryError(f"{d.holes[i].name} and {d.holes[j].name} overlap or touch "
                                f"near {_pt(d, near)}")


def _junction_coords(d: Domain, k: int) -> np.ndarray:
    b = d.curve_batch
    i0, i1 = d.chain_starts[k], d.chain_starts[k + 1]
    return np.vstack([b.p0[i0:i1], b.p1[i1 - 1:i1]]) - d._origin


def _bad_contact(inter, ja: np.ndarray, jb: np.ndarray, tol: float) -> np.ndarray | None:
    """A point of ``inter`` that is not a curve end point of both chains, or None."""
    if inter.is_empty:
        return None
    for g in shapely.get_parts(inter):
        if g.geom_type != "Point":
            sub = _bad_contact(g, ja, jb, tol) if hasattr(g, "geoms") else _rep(g)
            if sub is not None:
                return sub
            continue
        p = np.array(g.coords[0])
        if np.hypot(*(ja - p).T).min() > tol or np.hypot(*(jb - p).T).min() > tol:
            return p
    return None


def _self_touch(coords: np.ndarray, closed: bool) -> np.ndarray:
    """A point where a polyline touches or crosses itself (its first vertex if none)."""
    segs = shapely.linestrings(np.stack([coords[:-1], coords[1:]], axis=1))
    a, c = shapely.STRtree(segs).query(segs, predicate="intersects")
    keep = a < c
    a, c = a[keep], c[keep]
    adj = (c - a == 1) | (closed & (a == 0) & (c == len(segs) - 1))
    inter = shapely.intersection(segs[a], segs[c])
    bad = ~adj | (shapely.get_type_id(inter) != 0)
    return _rep(inter[_first(bad)]) if bad.any() else coords[0]


def _check_interfaces(d: Domain) -> None:
    P, base, tol = len(d.interfaces), 1 + len(d.holes), d.tol
    if not P:
        return
    outer = Polygon(d._fine[0])
    holes = [Polygon(r) for r in d._fine[1:base]]
    lines = [LineString(d._fine[base + k]) for k in range(P)]
    junc = [_junction_coords(d, k) for k in range(len(d.chains))]
    for k, line in enumerate(lines):
        name, jk = d.interfaces[k].name, junc[base + k]
        if not line.is_simple:
            where = _pt(d, _self_touch(d._fine[base + k], bool(d.chain_closed[base + k])))
            raise GeometryError(f"{name}: the interface intersects itself near {where}")
        ring = LinearRing(d._fine[0])
        bad = _bad_contact(line.intersection(ring), jk, junc[0], tol)
        bad = bad if bad is not None else _touch(line, ring, d, _shared(jk, junc[0], tol))
        if bad is not None:
            raise GeometryError(f"{name}: touches or crosses the boundary {d.outer.name} near "
                                f"{_pt(d, bad)} (an interface may not leave the domain)")
        if not shapely.covers(outer.buffer(tol), line):  # ends computed from angles
            raise GeometryError(f"{name}: lies outside the domain near "
                                f"{_pt(d, _rep(line.difference(outer)))}")
        for i, h in enumerate(holes):
            jh = junc[1 + i]
            bad = _bad_contact(line.intersection(h), jk, jh, tol)
            bad = bad if bad is not None else _touch(line, h.exterior, d, _shared(jk, jh, tol))
            if bad is not None:
                raise GeometryError(f"{name}: touches, crosses or enters {d.holes[i].name} "
                                    f"near {_pt(d, bad)}")
    a, c = shapely.STRtree(lines).query(lines, predicate="dwithin",
                                        distance=CONTACT * d.diameter)
    for i, j in zip(a[a < c], c[a < c]):
        ji, jj = junc[base + i], junc[base + j]
        bad = _bad_contact(lines[i].intersection(lines[j]), ji, jj, tol)
        bad = bad if bad is not None else _touch(lines[i], lines[j], d, _shared(ji, jj, tol))
        if bad is not None:
            raise GeometryError(f"{d.interfaces[i].name} and {d.interfaces[j].name} cross or "
                                f"touch near {_pt(d, bad)} (interfaces may only meet at curve "
                                f"end points)")


def _shared(ja: np.ndarray, jb: np.ndarray, tol: float) -> np.ndarray:
    """The points of ``ja`` that are also (within ``tol``) points of ``jb``."""
    dist = np.hypot(ja[:, None, 0] - jb[:, 0], ja[:, None, 1] - jb[:, 1]).min(axis=1)
    return ja[dist <= tol]


def _check_points(d: Domain) -> None:
    if not d.points:
        return
    names = list(d.points)
    P = np.array([d.points[n] for n in names])
    clear = CONTACT * d.diameter
    ends = np.vstack([_junction_coords(d, k) for k in range(len(d.chains))]) + d._origin
    corner = np.hypot(P[:, None, 0] - ends[:, 0], P[:, None, 1] - ends[:, 1]).min(1) <= d.tol
    inside = d.contains(P) & (d.distance_to_boundary(P, interfaces=False) > clear)
    if (i := _first(~inside & ~corner)) is not None:
        raise GeometryError(f"point '{names[i]}' at {fmt_point(P[i])} is not inside the "
                            f"domain (it is outside, on its boundary or closer than "
                            f"{fmt_num(clear)} to it, and not a curve end point)")
    base = 1 + len(d.holes)
    for k, path in enumerate(d.interfaces):
        i0, i1 = d.chain_starts[base + k], d.chain_starts[base + k + 1]
        on = _sub(d.curve_batch, i0, i1).distance(P) <= clear
        jk = _junction_coords(d, base + k) + d._origin
        at_end = np.hypot(P[:, None, 0] - jk[:, 0], P[:, None, 1] - jk[:, 1]).min(1) <= d.tol
        if (i := _first(on & ~at_end & ~corner)) is not None:
            raise GeometryError(f"point '{names[i]}' at {fmt_point(P[i])} lies on {path.name} "
                                f"but not at one of its curve end points")


def fixed_vertices(domain: Domain) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    """The fixed vertices of a domain's PSLG, merged within the domain's tolerance.

    Cached as :attr:`Domain.junctions`.

    Returns ``coords (K, 2)``, ``start_id (C,)``, ``end_id (C,)`` (fixed vertex of every
    curve's ends) and ``point_id`` (named point -> fixed vertex). Between two curves the
    vertex is a segment's exact end point where there is one.
    """
    b = domain.curve_batch
    coords, start_id, end_id = [], np.empty(len(b), np.int64), np.empty(len(b), np.int64)
    k = 0
    for j in range(len(domain.chains)):
        i0, i1 = domain.chain_starts[j], domain.chain_starts[j + 1]
        n = i1 - i0
        seg, p0, p1 = ~b.is_arc[i0:i1], b.p0[i0:i1], b.p1[i0:i1]
        prev = np.arange(n) - 1
        J = np.where(seg[prev, None], p1[prev], p0)
        if not domain.chain_closed[j]:
            J[0] = p0[0]
            J = np.vstack([J, p1[-1:]])
        ids = k + np.arange(len(J))
        start_id[i0:i1] = ids[:n]
        end_id[i0:i1] = np.roll(ids, -1) if domain.chain_closed[j] else ids[1:]
        coords.append(J)
        k += len(J)
    names = list(domain.points)
    coords.append(np.array([domain.points[q] for q in names]).reshape(-1, 2))
    coords = np.vstack(coords)
    pairs = cKDTree(coords).query_pairs(domain.tol, output_type="ndarray")
    m = len(coords)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    _, labels = connected_components(graph, directed=False)
    _, first = np.unique(labels, return_index=True)  # first vertex of every label
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    new = rank[labels]
    point_id = {q: int(new[k + i]) for i, q in enumerate(names)}
    return coords[first[order]], new[start_id], new[end_id], point_id
