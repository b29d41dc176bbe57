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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import NamedTuple

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from shapely.geometry import Polygon

from hetmesh.errors import GeometryError

from ...topology import unique
from .curves import Arc, Curve, CurveBatch, Segment, sample_parameters, segments_through, tolerance
from .validate import VALIDATION_CHORD, validate_domain

__all__ = ["Loop", "Path", "CurveInfo", "Domain", "make_domain", "fixed_vertices"]

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
    def origin(self) -> np.ndarray:
        """The reference point of the local coordinates the geometric work is done in (the
        first curve's start): coordinates far from the origin keep their precision."""
        return self.curve_batch.p0[0].copy()

    @cached_property
    def tol(self) -> float:
        """The geometric tolerance: points closer than this are the same point."""
        return tolerance(self.diameter, float(np.abs(self.bounds).max()))

    @cached_property
    def area(self) -> float:
        """Exact area: outer loop minus holes (arcs contribute their circular segments)."""
        g = self.curve_batch.green_area(self.origin)
        s = self.chain_starts
        loops = [abs(float(g[s[k]:s[k + 1]].sum())) for k in range(1 + len(self.holes))]
        return loops[0] - sum(loops[1:])

    # -- sampled geometry (local coordinates, relative to origin)
    def _sampled(self, chord_tol: float) -> list[np.ndarray]:
        """Per owner, sampled coordinates relative to the origin; closed chains repeat p[0]."""
        b = self.curve_batch
        o = self.origin
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
        rings = [r + self.origin for r in self._sampled(tol)[:1 + len(self.holes)]]
        return Polygon(rings[0], rings[1:])

    @cached_property
    def fine_rings(self) -> list[np.ndarray]:
        """Per chain, its points sampled to the validation chord, relative to :attr:`origin`
        (closed chains repeat their first point)."""
        return self._sampled(VALIDATION_CHORD * self.diameter)

    @cached_property
    def _local_polygon(self) -> Polygon:
        n = 1 + len(self.holes)
        poly = Polygon(self.fine_rings[0], self.fine_rings[1:n])
        shapely.prepare(poly)
        return poly

    def contains(self, points) -> np.ndarray:
        """Whether points lie strictly inside the domain (holes excluded) -> bool (N,)."""
        p = np.asarray(points, dtype=np.float64) - self.origin
        return shapely.contains_xy(self._local_polygon, p[..., 0], p[..., 1])

    def distance_to_boundary(self, points, *, interfaces: bool = True) -> np.ndarray:
        """Exact distance to the nearest curve (interfaces included unless disabled)."""
        b = self.curve_batch
        if not interfaces:
            b = b.slice(0, int(self.chain_starts[1 + len(self.holes)]))
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
            validate_domain(self)
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
    _, first = unique(labels, return_index=True)  # first vertex of every label
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    new = rank[labels]
    point_id = {q: int(new[k + i]) for i, q in enumerate(names)}
    return coords[first[order]], new[start_id], new[end_id], point_id
