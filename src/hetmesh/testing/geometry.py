"""Random domains for :mod:`hetmesh.testing`: star polygons, arcs, L and U shapes, holes,
an interface and a named point, as the model file spells them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Geometry", "random_geometry", "toml_float", "toml_point", "MIN_CORNER_DEG"]

#: No corner of a generated outer boundary is sharper than this (degrees).
MIN_CORNER_DEG = 20.0


@dataclass
class Geometry:
    start: tuple
    path: list                      # [(to, kind, extra)], kind: "seg" | "through" | "center"
    holes: list = field(default_factory=list)        # [(center, radius)]
    interface: list | None = None   # polyline points
    point: tuple | None = None
    tags: list = field(default_factory=list)
    width: float = 1.0


def toml_float(v: float) -> str:
    """A TOML float that reads back as exactly ``v``."""
    v = float(v)
    if v == 0.0:
        return "0.0"
    return repr(v)


def toml_point(p) -> str:
    return f"[{toml_float(p[0])}, {toml_float(p[1])}]"


def _rot(points: np.ndarray, ang: float) -> np.ndarray:
    c, s = math.cos(ang), math.sin(ang)
    return points @ np.array([[c, s], [-s, c]])


def _circle_through(a, m, b):
    """Centre and radius of the circle through three points."""
    ax, ay = a
    bx, by = m
    cx, cy = b
    d = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    ux = ((ax * ax + ay * ay) * (by - cy) + (bx * bx + by * by) * (cy - ay)
          + (cx * cx + cy * cy) * (ay - by)) / d
    uy = ((ax * ax + ay * ay) * (cx - bx) + (bx * bx + by * by) * (ax - cx)
          + (cx * cx + cy * cy) * (bx - ax)) / d
    return np.array([ux, uy]), math.hypot(ax - ux, ay - uy)


def _arc_samples(a, b, c, ccw: bool, n: int) -> np.ndarray:
    a, b, c = (np.asarray(v, float) for v in (a, b, c))
    t0 = math.atan2(a[1] - c[1], a[0] - c[0])
    t1 = math.atan2(b[1] - c[1], b[0] - c[0])
    sweep = (t1 - t0) % (2 * math.pi) if ccw else -((t0 - t1) % (2 * math.pi))
    r = math.hypot(*(a - c))
    t = t0 + sweep * np.linspace(0.0, 1.0, n)
    return c + r * np.column_stack([np.cos(t), np.sin(t)])


def _sampled_outer(geo: Geometry, n: int = 129) -> tuple[np.ndarray, list[int]]:
    """The outer loop as a polyline (closing point not repeated) and the index of every
    path vertex in it."""
    pts = [np.asarray(geo.start, float)]
    idx = []
    cur = np.asarray(geo.start, float)
    for to, kind, extra in geo.path:
        to = np.asarray(to, float)
        if kind == "seg":
            seg = np.array([cur, to])
        elif kind == "through":
            c, _ = _circle_through(cur, extra, to)
            m = np.asarray(extra, float)
            cross = (m[0] - cur[0]) * (to[1] - cur[1]) - (m[1] - cur[1]) * (to[0] - cur[0])
            seg = _arc_samples(cur, to, c, ccw=cross > 0, n=n)
        else:
            c, direction = extra
            seg = _arc_samples(cur, to, c, ccw=direction == "ccw", n=n)
        pts.extend(seg[1:])
        idx.append(len(pts) - 1)
        cur = to
    poly = np.array(pts[:-1])  # the last point is the start again
    idx = [0] + idx[:-1]
    return poly, idx


def _corner_angles(poly: np.ndarray, idx: list[int]) -> np.ndarray:
    """Interior angles (degrees) at the path vertices of a counter-clockwise polyline."""
    n = len(poly)
    out = []
    for i in idx:
        a, b, c = poly[(i - 1) % n], poly[i], poly[(i + 1) % n]
        u, v = a - b, c - b
        ang = math.degrees(math.atan2(u[0] * v[1] - u[1] * v[0], u @ v))
        out.append(-ang % 360.0)
    return np.array(out)


def random_geometry(rng) -> Geometry | None:
    """Outer loop, holes, interface and named point in unit scale, then scaled and moved;
    None if this draw is unusable (sharp corner, self-intersection)."""
    import shapely
    from shapely.geometry import Point, Polygon

    geo = _placed(rng, *_outline(rng))
    poly, idx = _sampled_outer(geo)
    ring = shapely.LinearRing(poly)
    if not ring.is_simple:
        return None
    if Polygon(poly).exterior.is_ccw is False:
        return None
    corners = _corner_angles(poly, idx)
    if corners.min() < MIN_CORNER_DEG:
        return None
    if corners.min() < 40.0:
        geo.tags.append("sharp-corner")
    outer = Polygon(poly)
    minx, miny, maxx, maxy = outer.bounds
    geo.width = max(maxx - minx, maxy - miny)
    draw = _Inside(rng, outer.bounds)
    holes = _holes(rng, draw, outer, geo.width)
    if holes:
        geo.holes = [(tuple(c), float(r)) for c, r in holes]
        geo.tags.append("holes")
        if min(r for _, r in holes) < 0.025 * geo.width:
            geo.tags.append("small-holes")
    region = Polygon(poly, [Point(c).buffer(r, 64).exterior.coords for c, r in holes])
    if rng.random() < 0.4:
        _add_interface(rng, draw, region, geo)
    if rng.random() < 0.2:
        _add_point(draw, region, geo)
    return geo


def _outline(rng) -> tuple[np.ndarray, list, list[str]]:
    """The outer loop's vertices in unit scale, the kind of every edge (``("seg", None)``,
    ``("through", point)`` or ``("center", (centre, direction))``) and the shape's tags."""
    shape = rng.choice(["star", "arcs", "lshape"], p=[0.4, 0.3, 0.3])
    tags: list[str] = []
    if shape == "lshape":
        verts, path_kinds, ltags = _lshape(rng)
        return verts, path_kinds, tags + ltags
    n = int(rng.integers(4, 10 if shape == "star" else 9))
    step = 2 * math.pi / n
    ang = np.arange(n) * step + rng.uniform(0, 2 * math.pi) \
        + rng.uniform(-0.35, 0.35, n) * step
    jit = rng.uniform(0.0, 0.45)
    r = 0.5 * (1.0 + jit * rng.uniform(-1.0, 1.0, n))
    verts = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
    path_kinds = [("seg", None)] * n
    tags.append("star")
    if shape == "arcs":
        k = int(rng.integers(1, n + 1))
        which = rng.choice(n, size=k, replace=False)
        path_kinds = list(path_kinds)
        for i in which:
            a, b = verts[i], verts[(i + 1) % n]
            chord = b - a
            length = float(np.hypot(*chord))
            normal = np.array([chord[1], -chord[0]]) / length  # outward for ccw
            bulge = rng.uniform(0.08, 0.35) * (1 if rng.random() < 0.65 else -0.8)
            path_kinds[i] = ("through", 0.5 * (a + b) + bulge * length * normal)
        tags.append("arcs")
    return verts, path_kinds, tags


def _placed(rng, verts: np.ndarray, path_kinds: list, tags: list[str]) -> Geometry:
    """The outline scaled to a random size and moved to a random place (some far away)."""
    size = 10.0 ** rng.uniform(-2.0, 3.0)
    if rng.random() < 0.25:
        far = size * 10.0 ** rng.uniform(3.0, 5.0)
        phi = rng.uniform(0, 2 * math.pi)
        centre = far * np.array([math.cos(phi), math.sin(phi)])
        tags.append("far")
    else:
        centre = size * rng.uniform(-2.0, 2.0, 2)
    verts = centre + size * verts
    path = []
    n = len(verts)
    for i in range(n):
        kind, extra = path_kinds[i]
        to = tuple(verts[(i + 1) % n])
        if kind == "through":
            path.append((to, "through", tuple(centre + size * np.asarray(extra))))
        elif kind == "center":
            c, direction = extra
            path.append((to, "center", (tuple(centre + size * np.asarray(c)), direction)))
        else:
            path.append((to, "seg", None))
    geo = Geometry(start=tuple(verts[0]), path=path, tags=tags, width=size)
    # the fillet's end must be as far from its centre as its start (to 1e-9): recompute it
    for i, (to, kind, extra) in enumerate(geo.path):
        if kind == "center":
            prev = np.asarray(geo.path[i - 1][0] if i else geo.start, float)
            c = np.asarray(extra[0], float)
            r0 = float(np.hypot(*(prev - c)))
            d = np.asarray(to, float) - c
            new_to = tuple(c + r0 * d / np.hypot(*d))
            geo.path[i] = (new_to, kind, extra)
    return geo


class _Inside:
    """Random points of the outline's bounding box inside a region, off its boundary."""

    def __init__(self, rng, bounds):
        self.rng = rng
        self.minx, self.miny, self.maxx, self.maxy = bounds

    def __call__(self, region, margin: float, tries: int = 200):
        from shapely.geometry import Point

        rng = self.rng
        for _ in range(tries):
            p = np.array([rng.uniform(self.minx, self.maxx), rng.uniform(self.miny, self.maxy)])
            if region.contains(Point(p)) and region.exterior.distance(Point(p)) > margin and \
                    all(h.distance(Point(p)) > margin for h in region.interiors):
                return p
        return None


def _holes(rng, random_inside: _Inside, outer, width: float) -> list:
    """0 to 3 circular holes ``[(centre, radius)]`` apart from each other and the boundary."""
    n_holes = int(rng.choice([0, 0, 1, 1, 2, 3]))
    holes: list = []
    for _ in range(n_holes):
        for _try in range(60):
            r = width * 10.0 ** rng.uniform(math.log10(0.008), math.log10(0.12))
            gap = max(0.5 * r, 0.02 * width)
            c = random_inside(outer, r + gap, tries=20)
            if c is None:
                continue
            if all(math.hypot(*(c - hc)) > r + hr + max(gap, 0.5 * hr) for hc, hr in holes):
                holes.append((c, r))
                break
    return holes


def _add_interface(rng, random_inside: _Inside, region, geo: Geometry) -> None:
    """An interface polyline of 1 to 4 segments inside ``region``, if one is found."""
    from shapely.geometry import LineString

    width = geo.width
    margin = 0.02 * width
    for _try in range(40):
        p0 = random_inside(region, 3 * margin, tries=20)
        if p0 is None:
            continue
        k = int(rng.integers(1, 5))
        pts = [p0]
        heading = rng.uniform(0, 2 * math.pi)
        sharp = False
        for j in range(k):
            if j:
                turn = rng.uniform(-2.6, 2.6) if rng.random() < 0.3 else rng.uniform(-1, 1)
                sharp |= abs(turn) > math.radians(150)
                heading += turn
            step = width * rng.uniform(0.08, 0.35)
            pts.append(pts[-1] + step * np.array([math.cos(heading), math.sin(heading)]))
        line = LineString(pts)
        if line.is_simple and region.buffer(-margin).contains(line):
            geo.interface = [tuple(p) for p in pts]
            geo.tags.append("interface")
            if sharp:
                geo.tags.append("sharp-bend")
            break


def _add_point(random_inside: _Inside, region, geo: Geometry) -> None:
    """A named point inside ``region``, off the interface, if one is found."""
    from shapely.geometry import LineString

    avoid = region if geo.interface is None else region.difference(
        LineString(geo.interface).buffer(0.03 * geo.width))
    if avoid.geom_type == "Polygon":
        p = random_inside(avoid, 0.03 * geo.width, tries=50)
        if p is not None:
            geo.point = tuple(p)
            geo.tags.append("point")


def _lshape(rng):
    """An L (optionally with a concave fillet at the re-entrant corner) or a U, in unit
    scale around the origin, rotated by 0 or a random angle."""
    w, h = 1.0, float(rng.uniform(0.5, 1.6))
    tags = []
    kinds = None
    if rng.random() < 0.6:
        a, b = rng.uniform(0.3, 0.7), rng.uniform(0.3, 0.7)
        if rng.random() < 0.35:
            rf = float(rng.uniform(0.1, 0.4)) * min(w * (1 - a), h * (1 - b), w * a, h * b)
            verts = np.array([[0, 0], [w, 0], [w, h * b], [w * a + rf, h * b],
                              [w * a, h * b + rf], [w * a, h], [0, h]], float)
            centre = np.array([w * a + rf, h * b + rf])
            kinds = [("seg", None)] * 7
            kinds[3] = ("center", (centre, "cw"))
            tags.append("fillet")
        else:
            verts = np.array([[0, 0], [w, 0], [w, h * b], [w * a, h * b], [w * a, h], [0, h]],
                             float)
        tags.append("lshape")
    else:
        a1 = rng.uniform(0.15, 0.45)
        a2 = rng.uniform(a1 + 0.15, 0.85)
        b = rng.uniform(0.2, 0.75)
        verts = np.array([[0, 0], [w, 0], [w, h], [w * a2, h], [w * a2, h * b], [w * a1, h * b],
                          [w * a1, h], [0, h]], float)
        tags.append("ushape")
    if kinds is None:
        kinds = [("seg", None)] * len(verts)
    centre0 = 0.5 * np.array([w, h])
    scale = 1.0 / max(w, h)
    rot = 0.0 if rng.random() < 0.5 else float(rng.uniform(0, 2 * math.pi))
    verts = _rot((verts - centre0) * scale, rot)
    kinds = [(k, None) if k != "center" else
             (k, (_rot(((e[0] - centre0) * scale)[None], rot)[0], e[1])) for k, e in kinds]
    if rng.random() < 0.2 and "fillet" not in tags:  # an outward bulge on the first edge
        a, bb = verts[0], verts[1]
        chord = bb - a
        length = float(np.hypot(*chord))
        normal = np.array([chord[1], -chord[0]]) / length
        kinds[0] = ("through", 0.5 * (a + bb) + rng.uniform(0.05, 0.25) * length * normal)
        tags.append("arcs")
    return verts, kinds, tags
