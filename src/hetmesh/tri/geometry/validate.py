"""The checks of a domain (:meth:`Domain.validate`): structure, finite coordinates, scale,
curves, chains, loops, holes, interfaces and named points, in that order; the first failure
raises a :class:`GeometryError` naming the curve and the place.

The checks read a domain's public attributes only; this module does not import
:mod:`hetmesh.tri.geometry.domain`, which imports it.
"""

from __future__ import annotations

import math
import re

import numpy as np
import shapely
from shapely.geometry import LinearRing, LineString, Polygon

from hetmesh.errors import GeometryError

from .curves import TWO_PI, Segment, fmt_num, fmt_point

__all__ = ["validate_domain", "VALIDATION_CHORD", "CONTACT"]

VALIDATION_CHORD = 1e-6  # chord tolerance of validation / containment samples, x diameter
CONTACT = 4 * VALIDATION_CHORD  # curves closer than this (x diameter) touch
_LOC = re.compile(r"\[\s*(\S+)\s+([^\s\]]+)")


def validate_domain(d) -> None:
    """Run every check in order; the first failure raises."""
    for check in (_check_structure, _check_finite, _check_scale, _check_curves, _check_chains,
                  _check_loops, _check_holes, _check_interfaces, _check_points):
        check(d)


def _label(d, i: int) -> str:
    k = int(np.searchsorted(d.chain_starts, i, side="right") - 1)
    c = d.curves[i].curve
    own = f" ('{c.name}')" if c.name else ""
    return f"{d.chains[k][1].name}: curve {i - int(d.chain_starts[k])}{own}"


def _pt(d, local) -> str:
    """A local point (relative to the origin) in user coordinates, to the sampling accuracy."""
    step = 10.0 ** math.floor(math.log10(VALIDATION_CHORD * d.diameter))
    return fmt_point(np.round((np.asarray(local, dtype=np.float64) + d.origin) / step) * step)


def _rep(geom) -> np.ndarray:
    return np.array(geom.representative_point().coords[0])


def _check_structure(d) -> None:
    names = [o.name for _, o in d.chains]
    for n in names:
        if names.count(n) > 1:
            raise GeometryError(f"the name '{n}' is used by more than one loop or interface")
    for _, o in d.chains:
        if not o.curves:
            raise GeometryError(f"{o.name}: has no curves")


def _check_finite(d) -> None:
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


def _check_scale(d) -> None:
    lo, hi = SIZE_RANGE
    diam = d.diameter
    if not (lo <= diam <= hi):
        raise GeometryError(f"the domain's size (diameter {fmt_num(diam)}) is outside the range "
                            f"hetmesh supports, {lo:g} to {hi:g}: its area cannot be computed in "
                            "floating point; give the model in other units")


def _first(mask: np.ndarray) -> int | None:
    return int(np.flatnonzero(mask)[0]) if mask.any() else None


def _check_curves(d) -> None:
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


def _check_chains(d) -> None:
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


def _check_loops(d) -> None:
    b = d.curve_batch
    for k in range(1 + len(d.holes)):
        o = d.chains[k][1]
        i0, i1 = d.chain_starts[k], d.chain_starts[k + 1]
        if not b.is_arc[i0:i1].any() and i1 - i0 < 3:
            raise GeometryError(f"{o.name}: a polygonal loop needs at least 3 vertices, "
                                f"got {i1 - i0}")
        reason = shapely.is_valid_reason(Polygon(d.fine_rings[k]))
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


def _touch(ga, gb, d, shared: np.ndarray | None = None) -> np.ndarray | None:
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


def _check_holes(d) -> None:
    H = len(d.holes)
    if not H:
        return
    outer = Polygon(d.fine_rings[0])
    holes = [Polygon(r) for r in d.fine_rings[1:1 + H]]
    oname = d.outer.name
    for i, h in enumerate(holes):
        inter = h.exterior.intersection(outer.exterior)
        near = _rep(inter) if not inter.is_empty else _touch(h.exterior, outer.exterior, d)
        if near is not None:
            raise GeometryError(f"{d.holes[i].name}: not strictly inside {oname}: touches or "
                                f"crosses it near {_pt(d, near)}")
        if not shapely.contains_properly(outer, h):
            raise GeometryError(f"{d.holes[i].name}: not strictly inside {oname}: it lies "
                                f"outside, e.g. at {_pt(d, d.fine_rings[1 + i][0])}")
    a, c = shapely.STRtree(holes).query(holes, predicate="dwithin",
                                        distance=CONTACT * d.diameter)
    for i, j in zip(a[a < c], c[a < c]):
        inter = holes[i].intersection(holes[j])
        near = _rep(inter) if not inter.is_empty else _touch(holes[i], holes[j], d)
        if near is not None:
            raise GeometryError(f"{d.holes[i].name} and {d.holes[j].name} overlap or touch "
                                f"near {_pt(d, near)}")


def _junction_coords(d, k: int) -> np.ndarray:
    b = d.curve_batch
    i0, i1 = d.chain_starts[k], d.chain_starts[k + 1]
    return np.vstack([b.p0[i0:i1], b.p1[i1 - 1:i1]]) - d.origin


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


def _check_interfaces(d) -> None:
    P, base, tol = len(d.interfaces), 1 + len(d.holes), d.tol
    if not P:
        return
    outer = Polygon(d.fine_rings[0])
    holes = [Polygon(r) for r in d.fine_rings[1:base]]
    lines = [LineString(d.fine_rings[base + k]) for k in range(P)]
    junc = [_junction_coords(d, k) for k in range(len(d.chains))]
    for k, line in enumerate(lines):
        name, jk = d.interfaces[k].name, junc[base + k]
        if not line.is_simple:
            where = _pt(d, _self_touch(d.fine_rings[base + k], bool(d.chain_closed[base + k])))
            raise GeometryError(f"{name}: the interface intersects itself near {where}")
        ring = LinearRing(d.fine_rings[0])
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


def _check_points(d) -> None:
    if not d.points:
        return
    names = list(d.points)
    P = np.array([d.points[n] for n in names])
    clear = CONTACT * d.diameter
    ends = np.vstack([_junction_coords(d, k) for k in range(len(d.chains))]) + d.origin
    corner = np.hypot(P[:, None, 0] - ends[:, 0], P[:, None, 1] - ends[:, 1]).min(1) <= d.tol
    inside = d.contains(P) & (d.distance_to_boundary(P, interfaces=False) > clear)
    if (i := _first(~inside & ~corner)) is not None:
        raise GeometryError(f"point '{names[i]}' at {fmt_point(P[i])} is not inside the "
                            f"domain (it is outside, on its boundary or closer than "
                            f"{fmt_num(clear)} to it, and not a curve end point)")
    base = 1 + len(d.holes)
    for k, path in enumerate(d.interfaces):
        i0, i1 = d.chain_starts[base + k], d.chain_starts[base + k + 1]
        on = d.curve_batch.slice(i0, i1).distance(P) <= clear
        jk = _junction_coords(d, base + k) + d.origin
        at_end = np.hypot(P[:, None, 0] - jk[:, 0], P[:, None, 1] - jk[:, 1]).min(1) <= d.tol
        if (i := _first(on & ~at_end & ~corner)) is not None:
            raise GeometryError(f"point '{names[i]}' at {fmt_point(P[i])} lies on {path.name} "
                                f"but not at one of its curve end points")
