"""Robustness testing: seeded random models and an independent check of a mesh.

hetmesh must mesh every valid model. This module makes many different valid models from a
seed, and checks a finished mesh with code that shares nothing with the pipeline's own
verification (:func:`hetmesh.tri.adapt.finish`), in the spirit of :mod:`numpy.testing`: it is
used by ``tests/test_robust.py`` and ``benchmarks/bench_robust.py``, and by anyone who
changes the mesher and wants to know what they broke.

- :func:`random_model` -- the model of one seed, as **model-file TOML** (docs/model-format.md),
  so that loading it exercises the whole load path (parser, geometry validation, formula
  compiler, material sampling).
- :func:`robust_suite` -- the fixed seeded set the benchmark and the tests run.
- :func:`independent_check` -- the problems of a :class:`hetmesh.Result`, as messages; an empty
  list means the mesh is what hetmesh promises.

Families (the material field; ``FAMILIES[seed % 7]``):

``gentle``
    linear, quadratic, bilinear or bowl-shaped gradings.
``tanh``
    a front ``0.5 + 0.5 A tanh((s - s0)/w)``, straight (random direction) or circular, of
    width ``w`` from 20 % down to 0.5 % of the domain's width.
``power``
    the power law ``((x - x0)/L)**p``, ``p`` in 0.5..8 along an axis or a random direction;
    with ``p < 1`` the gradient is infinite where ``x = x0`` touches the domain (a vertex or a
    whole edge).
``sfgm``
    the sigmoid power law (S-FGM): two power-law halves ``0.5 (2u)**p`` and
    ``1 - 0.5 (2 - 2u)**p`` meeting at ``u = 1/2``, ``u`` clipped to [0, 1] so that the
    material is flat (plateaus) beyond the graded band.
``gaussian``
    one to three (possibly anisotropic) Gaussian bumps or dips, 2 % to 30 % wide.
``sines``
    products of sines, 0.3 to 3 periods across the domain.
``kink``
    distance fields with kinks: the distance to a point inside the domain or to one of its
    corners (a cone), ``abs(s - c)`` (a crease along a line), or the smaller of two ramps.

Domains: star-shaped polygons (4-9 vertices, radius jitter, no corner sharper than 20
degrees), star polygons with some edges bent into circular arcs (outward or inward),
L- and U-shaped re-entrant outlines (sometimes with a concave fillet); a random size (0.01 to
1000) and position, some far from the origin (10^3 to 10^5 widths away); 0 to 3 circular
holes (some small) that touch neither each other nor the boundary; sometimes an interface
polyline inside the domain and a named point. Every composition stays in [0, 1] over the
domain's bounding box by construction. A generated model that does not load would be a bug
of this generator, so :func:`random_model` loads every model it makes (it tries another
geometry of the same seed if one does not).

Examples
--------
>>> from hetmesh.testing import random_model, independent_check
>>> rm = random_model(5)
>>> rm.family, rm.name
('sines', 'random-0005-sines')
>>> model = rm.load()                                         # doctest: +SKIP
>>> result = hetmesh.generate(model, rm.thresholds[0])        # doctest: +SKIP
>>> independent_check(result, model, rm.thresholds[0])        # doctest: +SKIP
[]
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["RandomModel", "random_model", "robust_suite", "independent_check", "estimate",
           "bump_toml", "FAMILIES", "ELEMENT_BUDGET", "MIN_CORNER_DEG"]

#: The material families, in the order ``random_model`` assigns them (``seed % 7``).
FAMILIES = ("gentle", "tanh", "power", "sfgm", "gaussian", "sines", "kink")

#: Thresholds are raised (never above 0.2) until the a-priori element estimate
#: (:func:`estimate`) is at most this many elements, so a suite run takes minutes, not hours.
ELEMENT_BUDGET = 40_000

#: No corner of a generated outer boundary is sharper than this (degrees).
MIN_CORNER_DEG = 20.0

THRESHOLD_RANGE = (0.02, 0.2)
_ATTEMPTS = 40


@dataclass(frozen=True)
class RandomModel:
    """One generated model.

    Attributes
    ----------
    seed : int
        :func:`random_model` ``(seed)`` makes it again, byte for byte.
    name : str
        ``random-<seed>-<family>``, also the ``[model] name`` of the TOML.
    toml : str
        The model file's text.
    family : str
        One of :data:`FAMILIES`.
    kind : tuple of str
        Tags of the domain and the field: ``star``, ``arcs``, ``lshape``, ``ushape``,
        ``fillet``, ``holes``, ``small-holes``, ``interface``, ``sharp-bend``, ``point``, ``far``,
        ``steep``, ``p<1``, ``edge-singular``, ``plateaus``, ``point-kink``, ``corner-kink``,
        ``line-kink``, ``ridge``, ...
    thresholds : tuple of float
        The thresholds delta_0 to run, in [0.02, 0.2], coarse first.
    """

    seed: int
    name: str
    toml: str
    family: str
    kind: tuple = ()
    thresholds: tuple = ()

    @property
    def hard(self) -> bool:
        """Whether a tag marks a known-difficult feature (steep front, p < 1, plateaus,
        kinks, small holes, sharp interface bends, corners below 40 degrees)."""
        return bool(set(self.kind) & HARD_TAGS)

    def write(self, path) -> Path:
        """Write the TOML to ``path``; returns the path."""
        p = Path(path)
        p.write_text(self.toml, encoding="utf-8")
        return p

    def load(self):
        """The model, read back through :func:`hetmesh.load_model` from a temporary file."""
        from .io.model import load_model

        with tempfile.TemporaryDirectory(prefix="hetmesh-random-") as tmp:
            return load_model(self.write(Path(tmp) / f"{self.name}.toml"))


HARD_TAGS = frozenset({"steep", "p<1", "edge-singular", "plateaus", "point-kink",
                       "corner-kink", "line-kink", "ridge", "small-holes", "sharp-bend",
                       "sharp-corner"})


# =============================================================================== generator
def random_model(seed: int, *, budget: int = ELEMENT_BUDGET) -> RandomModel:
    """The random model of ``seed`` (deterministic: same seed, same text).

    Parameters
    ----------
    seed : int
        Any non-negative integer. The family is ``FAMILIES[seed % 7]``; everything else
        (domain, holes, interface, field parameters, thresholds) comes from
        ``numpy.random.default_rng([seed, attempt])``.
    budget : int
        The thresholds are raised until the a-priori element estimate (:func:`estimate`) is
        at most ``budget`` (or 0.2 is reached).

    Returns
    -------
    RandomModel
        A model that loads (checked here by loading it).

    Raises
    ------
    RuntimeError
        If no attempt produced a loadable model (a bug of the generator).
    """
    from .errors import HetmeshError

    seed = int(seed)
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    family = FAMILIES[seed % len(FAMILIES)]
    errors = []
    for attempt in range(_ATTEMPTS):
        rng = np.random.default_rng([seed, attempt])
        try:
            geo = _geometry(rng)
            if geo is None:
                continue
            geo_model = _load_text(_toml(f"random-{seed:04d}-{family}", geo, "0.5", {}, ()),
                                   "geometry")
            field_txt, params, tags = _field(family, rng, geo, geo_model.domain)
            name = f"random-{seed:04d}-{family}"
            tags = tuple(geo.tags) + tuple(tags)
            text = _toml(name, geo, field_txt, params, tags)
            model = _load_text(text, name)
        except HetmeshError as exc:  # the generator's fault: try another geometry
            errors.append(f"attempt {attempt}: {str(exc).splitlines()[0]}")
            continue
        thresholds = _thresholds(rng, model, budget)
        return RandomModel(seed=seed, name=name, toml=text, family=family, kind=tags,
                           thresholds=thresholds)
    raise RuntimeError(f"random_model({seed}): no valid model in {_ATTEMPTS} attempts "
                       f"(a generator bug): " + "; ".join(errors[-3:]))


def robust_suite(n: int = 48, seed: int = 0, *, budget: int = ELEMENT_BUDGET) -> list:
    """The fixed seeded set: ``[random_model(seed + i) for i in range(n)]``.

    Consecutive seeds cycle through :data:`FAMILIES`, so with ``n >= 28`` every family
    appears at least 4 times (``n = 48``: 6 or 7 times).
    """
    return [random_model(seed + i, budget=budget) for i in range(int(n))]


def _load_text(text: str, name: str):
    from .io.model import load_model

    with tempfile.TemporaryDirectory(prefix="hetmesh-random-") as tmp:
        p = Path(tmp) / f"{name}.toml"
        p.write_text(text, encoding="utf-8")
        return load_model(p)


# ------------------------------------------------------------------------------ geometry
@dataclass
class _Geo:
    start: tuple
    path: list                      # [(to, kind, extra)], kind: "seg" | "through" | "center"
    holes: list = field(default_factory=list)        # [(center, radius)]
    interface: list | None = None   # polyline points
    point: tuple | None = None
    tags: list = field(default_factory=list)
    width: float = 1.0


def _f(v: float) -> str:
    """A TOML float that reads back as exactly ``v``."""
    v = float(v)
    if v == 0.0:
        return "0.0"
    return repr(v)


def _pt(p) -> str:
    return f"[{_f(p[0])}, {_f(p[1])}]"


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


def _sampled_outer(geo: _Geo, n: int = 129) -> tuple[np.ndarray, list[int]]:
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


def _geometry(rng) -> _Geo | None:
    """Outer loop, holes, interface and named point in unit scale, then scaled and moved;
    None if this draw is unusable (sharp corner, self-intersection)."""
    import shapely
    from shapely.geometry import LineString, Point, Polygon

    shape = rng.choice(["star", "arcs", "lshape"], p=[0.4, 0.3, 0.3])
    tags: list[str] = []
    if shape == "lshape":
        verts, path_kinds, ltags = _lshape(rng)
        tags += ltags
    else:
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
    # scale and position
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
    geo = _Geo(start=tuple(verts[0]), path=path, tags=tags, width=size)
    # the fillet's end must be as far from its centre as its start (to 1e-9): recompute it
    for i, (to, kind, extra) in enumerate(geo.path):
        if kind == "center":
            prev = np.asarray(geo.path[i - 1][0] if i else geo.start, float)
            c = np.asarray(extra[0], float)
            r0 = float(np.hypot(*(prev - c)))
            d = np.asarray(to, float) - c
            new_to = tuple(c + r0 * d / np.hypot(*d))
            geo.path[i] = (new_to, kind, extra)
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
    width = max(maxx - minx, maxy - miny)
    geo.width = width

    def random_inside(region, margin: float, tries: int = 200):
        for _ in range(tries):
            p = np.array([rng.uniform(minx, maxx), rng.uniform(miny, maxy)])
            if region.contains(Point(p)) and region.exterior.distance(Point(p)) > margin and \
                    all(h.distance(Point(p)) > margin for h in region.interiors):
                return p
        return None

    # holes
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
    if holes:
        geo.holes = [(tuple(c), float(r)) for c, r in holes]
        geo.tags.append("holes")
        if min(r for _, r in holes) < 0.025 * width:
            geo.tags.append("small-holes")
    region = Polygon(poly, [Point(c).buffer(r, 64).exterior.coords for c, r in holes])
    # interface polyline
    if rng.random() < 0.4:
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
    # a named point
    if rng.random() < 0.2:
        avoid = region if geo.interface is None else region.difference(
            LineString(geo.interface).buffer(0.03 * width))
        if avoid.geom_type == "Polygon":
            p = random_inside(avoid, 0.03 * width, tries=50)
            if p is not None:
                geo.point = tuple(p)
                geo.tags.append("point")
    return geo


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


# ------------------------------------------------------------------------------ material
def _field(family: str, rng, geo: _Geo, domain):
    """The formula of ``metal``, its parameters and tags; in [0, 1] over the bounding box."""
    x0, y0, x1, y1 = domain.bounds
    wx, wy = x1 - x0, y1 - y0
    D = max(wx, wy)
    xc, yc = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    params = {"xc": xc, "yc": yc, "D": D}
    tags: list[str] = []

    def inside_point():
        for _ in range(500):
            p = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
            if domain.contains(p[None])[0] and domain.distance_to_boundary(p[None])[0] > 0.01 * D:
                return p
        return np.array([xc, yc])

    def direction(axis_prob: float = 0.0):
        if rng.random() < axis_prob:
            th = rng.integers(0, 4) * 0.5 * math.pi
            c, s = round(math.cos(th)), round(math.sin(th))
        else:
            th = rng.uniform(0, 2 * math.pi)
            c, s = math.cos(th), math.sin(th)
        return float(c), float(s)

    def s_text(c: float, s: float) -> str:
        """The coordinate along (c, s), in domain widths, 0 at the box centre."""
        if s == 0.0:
            return f"(x - xc)/D" if c > 0 else f"(xc - x)/D"
        if c == 0.0:
            return f"(y - yc)/D" if s > 0 else f"(yc - y)/D"
        return f"((x - xc)*{_f(c)} + (y - yc)*{_f(s)})/D"

    def s_range(c: float, s: float) -> float:
        """Half the range of the s coordinate over the bounding box."""
        return (wx * abs(c) + wy * abs(s)) / (2.0 * D)

    def s_at(p, c, s):
        return ((p[0] - xc) * c + (p[1] - yc) * s) / D

    lo = float(rng.uniform(0.0, 0.3)) if rng.random() < 0.6 else 0.0
    hi = float(rng.uniform(0.7, 1.0)) if rng.random() < 0.6 else 1.0
    params.update(lo=lo, hi=hi)

    if family == "gentle":
        variant = rng.choice(["linear", "quadratic", "bilinear", "bowl"])
        tags.append(str(variant))
        if variant in ("linear", "quadratic"):
            c, s = direction(0.3)
            sm = s_range(c, s)
            params["sm"] = sm
            u = f"({s_text(c, s)} + sm)/(2*sm)"
            text = f"lo + (hi - lo)*{u}" if variant == "linear" else f"lo + (hi - lo)*{u}**2"
        elif variant == "bilinear":
            params.update(x0=x0, y0=y0, wx=wx, wy=wy)
            text = "lo + (hi - lo)*((x - x0)/wx)*((y - y0)/wy)"
        else:
            p = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
            d2 = max((cx - p[0]) ** 2 + (cy - p[1]) ** 2 for cx in (x0, x1) for cy in (y0, y1))
            params.update(px=float(p[0]), py=float(p[1]), d2=d2)
            text = "lo + (hi - lo)*((x - px)**2 + (y - py)**2)/d2"
    elif family == "tanh":
        w = 10.0 ** rng.uniform(math.log10(0.005), math.log10(0.2))
        A = float(rng.uniform(0.7, 1.0))
        params.update(w=w, A=A)
        if w < 0.02:
            tags.append("steep")
        if rng.random() < 0.3:
            q = inside_point()
            r0 = float(rng.uniform(0.1, 0.45))
            params.update(px=float(q[0]), py=float(q[1]), r0=r0)
            text = "0.5 + 0.5*A*tanh((sqrt((x - px)**2 + (y - py)**2)/D - r0)/w)"
            tags.append("circular-front")
        else:
            c, s = direction(0.2)
            s0 = s_at(inside_point(), c, s)
            params["s0"] = s0
            text = f"0.5 + 0.5*A*tanh(({s_text(c, s)} - s0)/w)"
    elif family == "power":
        p = float(rng.uniform(0.5, 1.0)) if rng.random() < 0.4 else \
            float(10.0 ** rng.uniform(0.0, math.log10(8.0)))
        params["p"] = p
        if p < 1:
            tags.append("p<1")
        c, s = direction(0.7)
        at_edge = rng.random() < 0.6
        if c in (1.0, -1.0) and s == 0.0 or s in (1.0, -1.0) and c == 0.0:
            along_x = s == 0.0
            lo_edge = (x0 if c > 0 else x1) if along_x else (y0 if s > 0 else y1)
            span = wx if along_x else wy
            off = 0.0 if at_edge else float(rng.uniform(0.01, 0.1)) * span
            sign = (c if along_x else s)
            origin = lo_edge - sign * off
            var = "x" if along_x else "y"
            params.update({f"{var}0": origin, "L": span + off})
            base = f"({var} - {var}0)/L" if sign > 0 else f"({var}0 - {var})/L"
        else:
            sm = s_range(c, s)
            off = 0.0 if at_edge else float(rng.uniform(0.01, 0.1)) * 2 * sm
            params.update(s1=-sm - off, L=2 * sm + off)
            base = f"({s_text(c, s)} - s1)/L"
        if at_edge and p < 1:
            tags.append("edge-singular")
        text = f"lo + (hi - lo)*max({base}, 0)**p"
    elif family == "sfgm":
        p = float(rng.uniform(0.5, 1.0)) if rng.random() < 0.3 else \
            float(10.0 ** rng.uniform(0.0, math.log10(8.0)))
        c, s = direction(0.4)
        sm = s_range(c, s)
        a = -sm + float(rng.uniform(0.0, 0.3)) * 2 * sm
        b = sm - float(rng.uniform(0.0, 0.3)) * 2 * sm
        if rng.random() < 0.3:  # no plateau
            a, b = -sm, sm
        params.update(p=p, a=a, bw=b - a)
        if p < 1:
            tags.append("p<1")
        if a > -sm or b < sm:
            tags.append("plateaus")
        u = f"clip(({s_text(c, s)} - a)/bw, 0, 1)"
        text = f"lo + (hi - lo)*where({u} < 0.5, 0.5*(2*{u})**p, 1 - 0.5*(2 - 2*{u})**p)"
    elif family == "gaussian":
        k = int(rng.integers(1, 4))
        amps = rng.dirichlet(np.ones(k)) * (hi - lo) * float(rng.uniform(0.7, 1.0))
        terms = []
        dip = rng.random() < 0.3
        for i in range(k):
            q = inside_point() if rng.random() < 0.8 else \
                np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
            sig = 10.0 ** rng.uniform(math.log10(0.02), math.log10(0.3))
            if sig < 0.05:
                tags.append("narrow")
            ratio = float(rng.uniform(1.0, 3.0)) if rng.random() < 0.5 else 1.0
            th = float(rng.uniform(0, math.pi))
            params.update({f"a{i}": float(amps[i]), f"cx{i}": float(q[0]), f"cy{i}": float(q[1]),
                           f"sa{i}": sig * D, f"sb{i}": sig * D / ratio})
            if ratio == 1.0:
                e = f"((x - cx{i})**2 + (y - cy{i})**2)/sa{i}**2"
            else:
                c, s = _f(math.cos(th)), _f(math.sin(th))
                e = (f"(((x - cx{i})*{c} + (y - cy{i})*{s})**2/sa{i}**2 + "
                     f"((y - cy{i})*{c} - (x - cx{i})*{s})**2/sb{i}**2)")
            terms.append(f"a{i}*exp(-0.5*{e})")
        tags.append("dip" if dip else "bump")
        text = (f"hi - ({' + '.join(terms)})" if dip else f"lo + {' + '.join(terms)}")
        tags[:] = list(dict.fromkeys(tags))
    elif family == "sines":
        k = 1 if rng.random() < 0.6 else 2
        amps = rng.dirichlet(np.ones(k)) * float(rng.uniform(0.5, 1.0))
        terms = []
        for i in range(k):
            kx, ky = (10.0 ** rng.uniform(math.log10(0.3), math.log10(3.0)) for _ in range(2))
            ph1, ph2 = (float(rng.uniform(0, 2 * math.pi)) for _ in range(2))
            params.update({f"a{i}": float(amps[i]), f"kx{i}": kx, f"ky{i}": ky,
                           f"ph{i}": ph1, f"ps{i}": ph2})
            terms.append(f"a{i}*sin(2*pi*kx{i}*(x - xc)/D + ph{i})*"
                         f"sin(2*pi*ky{i}*(y - yc)/D + ps{i})")
        text = f"0.5 + 0.5*({' + '.join(terms)})"
        tags.append("sines" if k == 1 else "sum-of-sines")
    else:  # kink
        variant = rng.choice(["point", "corner", "line", "ridge"])
        if variant in ("point", "corner"):
            if variant == "corner":
                verts = [np.asarray(geo.start, float)] + [np.asarray(t, float)
                                                          for t, _, _ in geo.path[:-1]]
                q = verts[int(rng.integers(0, len(verts)))]
                tags.append("corner-kink")
            else:
                q = inside_point()
                tags.append("point-kink")
            dmax = max(math.hypot(cx - q[0], cy - q[1]) for cx in (x0, x1) for cy in (y0, y1))
            params.update(px=float(q[0]), py=float(q[1]), dm=dmax)
            dist = "sqrt((x - px)**2 + (y - py)**2)/dm"
            text = f"lo + (hi - lo)*{dist}" if rng.random() < 0.5 else f"hi - (hi - lo)*{dist}"
        elif variant == "line":
            c, s = direction(0.3)
            sm = s_range(c, s)
            c0 = s_at(inside_point(), c, s)
            params.update(c0=c0, cm=max(abs(-sm - c0), abs(sm - c0)))
            text = f"lo + (hi - lo)*abs({s_text(c, s)} - c0)/cm"
            tags.append("line-kink")
        else:
            (c1, s1), (c2, s2) = direction(0.2), direction(0.2)
            m1, m2 = s_range(c1, s1), s_range(c2, s2)
            params.update(m1=m1, m2=m2)
            text = (f"lo + (hi - lo)*min(({s_text(c1, s1)} + m1)/(2*m1), "
                    f"({s_text(c2, s2)} + m2)/(2*m2))")
            tags.append("ridge")
    return text, params, tags


def _toml(name: str, geo: _Geo, formula: str, params: dict, tags) -> str:
    out = [f"# generated by hetmesh.testing.random_model: {', '.join(tags) or '-'}",
           "[model]", f'name = "{name}"', f'description = "random model ({", ".join(tags)})"',
           ""]
    used = {k: v for k, v in params.items() if _uses(formula, k)}
    if used:
        out.append("[parameters]")
        out += [f"{k} = {_f(v)}" for k, v in used.items()]
        out.append("")
    out += ["[domain.outer]", f"start = {_pt(geo.start)}", "path = ["]
    for to, kind, extra in geo.path:
        if kind == "seg":
            out.append(f"  {{ to = {_pt(to)} }},")
        elif kind == "through":
            out.append(f"  {{ to = {_pt(to)}, through = {_pt(extra)} }},")
        else:
            c, direction = extra
            out.append(f'  {{ to = {_pt(to)}, center = {_pt(c)}, direction = "{direction}" }},')
    out += ["]", ""]
    for c, r in geo.holes:
        out += ["[[domain.holes]]", f"circle = {{ center = {_pt(c)}, radius = {_f(r)} }}", ""]
    if geo.interface:
        pts = geo.interface
        out += ["[[domain.interfaces]]", f"start = {_pt(pts[0])}",
                "path = [" + ", ".join(f"{{ to = {_pt(p)} }}" for p in pts[1:]) + "]", ""]
    if geo.point is not None:
        out += ["[domain.points]", f"probe = {_pt(geo.point)}", ""]
    out += ["[material]", 'constituents = ["ceramic", "metal"]', "", "[material.composition]",
            f'metal = "{formula}"', ""]
    return "\n".join(out)


def _uses(formula: str, name: str) -> bool:
    import re

    return re.search(rf"\b{re.escape(name)}\b", formula) is not None


def estimate(model, threshold: float, n: int = 200) -> float:
    """A-priori element count of ``model`` at ``threshold``: equilateral triangles of side
    ``min(threshold / |grad f|, diameter / 8)`` tiling the domain (``|grad f|`` the largest
    over the constituents, on an ``n``-cell grid over the bounding box). This module's own,
    so that the thresholds :func:`random_model` picks do not move when hetmesh's estimator
    does."""
    dom = model.domain
    x0, y0, x1, y1 = dom.bounds
    step = max(x1 - x0, y1 - y0) / n
    xs = x0 + step * (np.arange(int(math.ceil((x1 - x0) / step))) + 0.5)
    ys = y0 + step * (np.arange(int(math.ceil((y1 - y0) / step))) + 0.5)
    X, Y = np.meshgrid(xs, ys)
    pts = np.column_stack([X.ravel(), Y.ravel()])
    pts = pts[dom.contains(pts)]
    if len(pts) == 0:
        return 0.0
    g = np.sqrt((np.asarray(model.material.gradient(pts)) ** 2).sum(axis=2)).max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.minimum(threshold / np.nan_to_num(g, nan=0.0, posinf=np.inf), dom.diameter / 8)
    return float(4.0 / math.sqrt(3.0) * np.mean(1.0 / h ** 2) * dom.area)


def _thresholds(rng, model, budget: int) -> tuple:
    lo, hi = THRESHOLD_RANGE
    coarse = 10.0 ** rng.uniform(math.log10(0.08), math.log10(hi))
    fine = 10.0 ** rng.uniform(math.log10(lo), math.log10(0.08))
    out = []
    for t in (coarse, fine):
        t = float(f"{t:.2g}")
        while t < hi:
            est = estimate(model, t)
            if np.isfinite(est) and est <= budget:
                break
            t = min(hi, float(f"{t * 1.25:.2g}"))
        if t not in out:
            out.append(t)
    return tuple(sorted(out, reverse=True))


# ========================================================================= independent check
def independent_check(result, model, threshold: float, *, min_angle: float | None = None,
                      min_quality: float | None = None) -> list[str]:
    """Problems of a meshing result, found without hetmesh's own verification.

    Parameters
    ----------
    result : hetmesh.Result
        From :func:`hetmesh.generate` (or :func:`hetmesh.uniform`).
    model : Model
        The model as given to the mesher (``result.model``, with material discontinuities
        embedded, is used for the curves when present).
    threshold : float
        delta_0.
    min_angle, min_quality : float, optional
        The angle (degrees) and quality floors; default: ``result.options``' values, else 30
        and 0.6.

    Returns
    -------
    list of str
        One line per problem; empty if the mesh is fine. Checked:

        * arrays: shapes, finite coordinates, indices in range, statistics matching the mesh;
        * every triangle counter-clockwise with positive area (not below 1e-12 of its longest
          edge squared), no repeated or unused points, every edge in one or two triangles and
          the two of an inner edge oriented oppositely (a manifold, consistently oriented);
        * every domain corner and named point a mesh node; every boundary and interface edge
          an edge of the mesh with both ends on its curve, and the edges of every curve
          covering it exactly once (their arcs add up to its length);
        * the mesh's boundary edges exactly the constraint edges of the outer loop and the
          holes; interface edges inside the mesh;
        * the area: mesh area plus the circular segments between the boundary chords and
          their arcs equals the domain's exact area, and the area of a shapely polygon of the
          domain (arcs sampled to 1e-7 of its diameter);
        * delta(T) < threshold at every element, from compositions recomputed at the vertices
          with ``model.material.composition`` (for a piecewise field every element in the
          subregion of its centroid, at all three vertices; the element's ``subregion``
          cell data is that subregion, and a vertex off every curve belongs to it); the
          reported ``delta`` cell data and ``stats.delta_max`` not below the recomputed
          values; the compositions written as point data equal to the recomputed ones;
        * every angle >= ``min_angle`` and q(T) >= ``min_quality``, except in triangles
          whose smallest angle sits at an input corner sharper than ``2 min_angle`` (the
          angle between the curves' tangents, on the domain's side) or whose shortest edge
          joins the two curves of such a corner at about equal distances from it.
    """
    out: list[str] = []
    try:
        _check(result, model, float(threshold), min_angle, min_quality, out)
    except Exception as exc:  # a malformed result must be a problem, not a crash
        out.append(f"check could not finish: {type(exc).__name__}: {exc}")
    return out


def _check(result, model, threshold, min_angle, min_quality, out):
    mesh = result.mesh
    opts = getattr(result, "options", None) or {}
    A = float(min_angle if min_angle is not None else opts.get("min_angle", 30.0))
    qfloor = float(min_quality if min_quality is not None else opts.get("min_quality", 0.6))
    meshed = getattr(result, "model", None) or model
    domain = meshed.domain
    P = np.asarray(mesh.points, float)
    T = np.asarray(mesh.triangles, np.int64)
    # -- arrays
    if P.ndim != 2 or P.shape[1:] != (2,) or T.ndim != 2 or T.shape[1:] != (3,) or len(T) == 0:
        out.append(f"bad array shapes: points {P.shape}, triangles {T.shape}")
        return
    if not np.isfinite(P).all():
        out.append("non-finite point coordinates")
        return
    if T.min() < 0 or T.max() >= len(P):
        out.append("triangle indices out of range")
        return
    st = result.stats
    if (st.n_points, st.n_elements) != (len(P), len(T)):
        out.append(f"stats say {st.n_points} points / {st.n_elements} elements, the mesh has "
                   f"{len(P)} / {len(T)}")
    diam = float(domain.diameter)
    mag = float(np.abs(P).max())
    tol = 1e-8 * diam + 256 * np.finfo(float).eps * mag
    # -- triangles: orientation, degeneracy
    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    # relative to the first vertex: keeps precision far from the origin
    ab, ac, bc = b - a, c - a, c - b
    area2 = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    L2 = np.stack([(bc ** 2).sum(1), (ac ** 2).sum(1), (ab ** 2).sum(1)], axis=1)
    if (m := int((area2 <= 0).sum())):
        out.append(f"{m} triangles are clockwise or have zero area "
                   f"(first #{int(np.argmax(area2 <= 0))})")
    if (m := int(((area2 > 0) & (area2 <= 1e-12 * L2.max(axis=1))).sum())):
        out.append(f"{m} triangles are degenerate (area below 1e-12 of the longest edge squared)")
    # -- points
    used = np.zeros(len(P), bool)
    used[T.ravel()] = True
    if (m := int((~used).sum())):
        out.append(f"{m} points are not used by any triangle")
    order = np.lexsort((P[:, 1], P[:, 0]))
    if len(P) > 1 and (m := int(np.all(P[order][1:] == P[order][:-1], axis=1).sum())):
        out.append(f"{m} repeated points")
    # -- edges: manifold and consistently oriented
    n = len(P)
    directed = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    dkey = directed[:, 0] * n + directed[:, 1]
    if len(np.unique(dkey)) != len(dkey):
        out.append("a directed edge appears twice (overlapping or inconsistently oriented "
                   "triangles)")
    ukey = np.minimum(directed[:, 0], directed[:, 1]) * n + np.maximum(directed[:, 0],
                                                                         directed[:, 1])
    keys, counts = np.unique(ukey, return_counts=True)
    if (m := int((counts > 2).sum())):
        out.append(f"{m} edges are shared by more than two triangles")
    boundary = set(keys[counts == 1].tolist())
    # -- constraint edges
    E = np.asarray(mesh.edges, np.int64).reshape(-1, 2)
    markers = np.asarray(mesh.edge_markers, np.int64)
    infos = domain.curves
    if len(E) and (E.min() < 0 or E.max() >= len(P)):
        out.append("constraint edge indices out of range")
        return
    if len(markers) and (markers.min() < 1 or markers.max() > len(infos)):
        out.append(f"edge markers outside 1..{len(infos)} (the model's curves)")
        return
    ekey = np.minimum(E[:, 0], E[:, 1]) * n + np.maximum(E[:, 0], E[:, 1])
    if (m := int((~np.isin(ekey, keys)).sum())):
        out.append(f"{m} boundary or interface edges are not edges of the mesh")
    kinds = np.array([ci.kind for ci in infos])
    on_bnd = kinds[markers - 1] != "interface" if len(markers) else np.zeros(0, bool)
    want = set(ekey[on_bnd].tolist())
    if (m := len(boundary - want)):
        out.append(f"{m} mesh boundary edges are not on the outer loop or a hole")
    if (m := len(want - boundary)):
        out.append(f"{m} edges of the outer loop or holes are not on the mesh's boundary")
    iface = set(ekey[~on_bnd].tolist())
    if (m := len(iface & boundary)):
        out.append(f"{m} interface edges are on the mesh's boundary")
    # ends on their curve; every curve covered exactly once
    off = 0.0
    for k, ci in enumerate(infos):
        sel = np.flatnonzero(markers == k + 1)
        curve = ci.curve
        if len(sel) == 0:
            out.append(f"curve {ci.name!r} has no mesh edges")
            continue
        ends = P[E[sel]].reshape(-1, 2)
        off = max(off, float(np.asarray(curve.distance(ends)).max()))
        chord = np.hypot(*(P[E[sel, 1]] - P[E[sel, 0]]).T)
        if hasattr(curve, "radius"):
            r = curve.radius
            covered = float((2 * r * np.arcsin(np.minimum(1.0, chord / (2 * r)))).sum())
        else:
            covered = float(chord.sum())
        slack = 1e-7 * curve.length + len(sel) * 256 * np.finfo(float).eps * mag
        if abs(covered - curve.length) > slack:
            out.append(f"the edges of curve {ci.name!r} cover {covered:.12g} of its length "
                       f"{curve.length:.12g}")
    if off > tol:
        out.append(f"boundary or interface nodes are off their curve by {off:.3g} "
                   f"({off / diam:.2g} of the diameter)")
    from scipy.spatial import cKDTree

    tree = cKDTree(P)
    fixed = np.asarray(domain.corners, float).reshape(-1, 2)
    if len(fixed):
        d, _ = tree.query(fixed)
        if (m := int((d > tol).sum())):
            out.append(f"{m} domain corners or named points are not mesh nodes")
    # -- area
    seg = 0.0
    bsel = np.flatnonzero(on_bnd)
    for k in np.unique(markers[bsel]) if len(bsel) else []:
        curve = infos[k - 1].curve
        if not hasattr(curve, "radius"):
            continue
        es = E[bsel[markers[bsel] == k]]
        pa, pb = P[es[:, 0]], P[es[:, 1]]
        chord = np.hypot(*(pb - pa).T)
        th = 2 * np.arcsin(np.minimum(1.0, chord / (2 * curve.radius)))
        cap = 0.5 * curve.radius ** 2 * (th - np.sin(th))
        # the triangle on each edge: is the arc's centre on its side (the mesh misses the cap)?
        third = _third_vertex(T, es, n)
        cen = np.asarray(curve.center, float)
        side_c = _side(pa, pb, cen)
        side_t = _side(pa, pb, P[third])
        seg += float(np.where(side_c * side_t > 0, cap, -cap).sum())
    mesh_area = 0.5 * float(area2.sum())
    exact = float(domain.area)
    if abs(mesh_area + seg - exact) > 1e-9 * exact + len(E) * 1e-13 * diam * diam + \
            len(T) * 64 * np.finfo(float).eps * float(np.abs(area2).max()):
        out.append(f"mesh area {mesh_area:.12g} (+ {seg:.3g} of arc caps) differs from the "
                   f"domain's {exact:.12g}")
    poly_area, poly_tol = _polygon_area(domain)
    if abs(mesh_area + seg - poly_area) > poly_tol + 1e-9 * exact:
        out.append(f"mesh area {mesh_area:.12g} (+ {seg:.3g} of arc caps) differs from the "
                   f"shapely polygon's {poly_area:.12g}")
    # -- delta
    fld = model.material
    piecewise = hasattr(fld, "region") and int(getattr(fld, "n_regions", 1) or 1) > 1
    if piecewise:
        own = np.asarray(fld.region(P[T].mean(axis=1)))
        sub = mesh.cell_data.get("subregion")
        if sub is None:
            out.append("no 'subregion' cell data for a piecewise field")
        elif (m := int((np.asarray(sub) != own).sum())):
            out.append(f"{m} elements carry a subregion other than their centroid's")
        comp = np.stack([np.asarray(fld.composition(P[T[:, k]], region=own)) for k in range(3)],
                        axis=1)
        curves = domain.curve_batch
        free = curves.distance(P) > 1e-9 * diam
        vreg = np.asarray(fld.region(P))
        bad = ~((vreg[T] == own[:, None]) | ~free[T])
        if (m := int(bad.any(axis=1).sum())):
            out.append(f"{m} elements have a vertex off every curve in another subregion "
                       f"(they cross a material discontinuity)")
    else:
        cv = np.asarray(fld.composition(P))
        comp = cv[T]  # (M, 3, m)
        names = list(fld.constituents)
        pd = mesh.point_data
        worst = max((float(np.abs(np.asarray(pd[nm]) - cv[:, j]).max())
                     for j, nm in enumerate(names) if nm in pd), default=0.0)
        if worst > 1e-6:
            out.append(f"the compositions written as point data differ from the model's by "
                       f"up to {worst:.3g}")
    delta = (comp.max(axis=1) - comp.min(axis=1)).max(axis=1)
    if not np.isfinite(delta).all():
        out.append(f"{int((~np.isfinite(delta)).sum())} elements have a non-finite delta")
    dmax = float(np.nanmax(delta))
    if dmax >= threshold:
        out.append(f"delta_max {dmax:.6g} >= threshold {threshold:g} "
                   f"({int((delta >= threshold).sum())} elements)")
    reported = mesh.cell_data.get("delta")
    # hetmesh evaluates in coordinates relative to the domain's centre: allow that rounding
    slack = 1e-9
    if reported is not None and (m := int((np.asarray(reported) < delta - slack).sum())):
        out.append(f"{m} elements report a delta below the recomputed one")
    if st.delta_max < dmax - slack:
        out.append(f"stats.delta_max {st.delta_max:.6g} is below the recomputed {dmax:.6g}")
    # -- angles and quality
    L = np.sqrt(L2)  # sides opposite vertices 0, 1, 2
    with np.errstate(invalid="ignore", divide="ignore"):
        la, lb, lc = L.T
        cosv = np.stack([(lb ** 2 + lc ** 2 - la ** 2) / (2 * lb * lc),
                         (lc ** 2 + la ** 2 - lb ** 2) / (2 * lc * la),
                         (la ** 2 + lb ** 2 - lc ** 2) / (2 * la * lb)], axis=1)
        ang = np.degrees(np.arccos(np.clip(np.nan_to_num(cosv, nan=1.0), -1, 1)))
        q = (lb + lc - la) * (lc + la - lb) * (la + lb - lc) / (la * lb * lc)
    q = np.nan_to_num(q, nan=0.0)
    if abs(st.q_min - q.min()) > 1e-5 or abs(st.q_avg - q.mean()) > 1e-5:
        out.append(f"stats q_min/q_avg {st.q_min:.6g}/{st.q_avg:.6g} differ from the mesh's "
                   f"{q.min():.6g}/{q.mean():.6g}")
    amin = ang.min(axis=1)
    bad = (amin < A - 1e-6) | (q < qfloor - 1e-9)
    if bad.any():
        exempt = _corner_exempt(P, T, E, markers, infos, fixed, tree, ang, L, A, tol,
                                np.flatnonzero(bad))
        bad_a = (amin < A - 1e-6) & ~exempt
        bad_q = (q < qfloor - 1e-9) & ~exempt
        if bad_a.any():
            out.append(f"{int(bad_a.sum())} triangles below the minimum angle {A:g} away from "
                       f"sharp input corners (smallest {amin[bad_a].min():.2f} degrees)")
        if bad_q.any():
            out.append(f"{int(bad_q.sum())} triangles below the quality floor {qfloor:g} away "
                       f"from sharp input corners (q_min {q[bad_q].min():.3f})")


def _side(pa, pb, p):
    p = np.broadcast_to(np.asarray(p, float), pa.shape)
    d = pb - pa
    return np.sign(d[:, 0] * (p[:, 1] - pa[:, 1]) - d[:, 1] * (p[:, 0] - pa[:, 0]))


def _third_vertex(T: np.ndarray, edges: np.ndarray, n: int) -> np.ndarray:
    """For boundary edges, the vertex of their (one) triangle not on them."""
    keys = []
    third = []
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        u, v = T[:, i], T[:, j]
        keys.append(np.minimum(u, v) * n + np.maximum(u, v))
        third.append(T[:, k])
    keys = np.concatenate(keys)
    third = np.concatenate(third)
    order = np.argsort(keys, kind="stable")
    ks = keys[order]
    q = np.minimum(edges[:, 0], edges[:, 1]) * n + np.maximum(edges[:, 0], edges[:, 1])
    pos = np.minimum(np.searchsorted(ks, q), len(ks) - 1)
    return third[order[pos]]


def _polygon_area(domain) -> tuple[float, float]:
    """Area of a shapely polygon of the domain (arcs sampled to 1e-7 of the diameter; the
    sampled vertices on the arcs) and the area that sampling may lose."""
    from shapely.geometry import Polygon

    chord = 1e-7 * domain.diameter
    rings = []
    loss = 0.0
    for loop in (domain.outer,) + tuple(domain.holes):
        pts = []
        for curve in loop.curves:
            if hasattr(curve, "radius"):
                r = curve.radius
                dth = 2 * math.acos(max(-1.0, 1 - chord / r)) if chord < r else math.pi / 2
                k = max(2, int(math.ceil(abs(curve.sweep) / dth)) + 1)
                k = min(k, 200_000)
                th = abs(curve.sweep) / (k - 1)
                loss += (k - 1) * 0.5 * r * r * (th - math.sin(th))
            else:
                k = 2
            pts.append(np.asarray(curve.point(np.linspace(0.0, 1.0, k)))[:-1])
        rings.append(np.vstack(pts))
    origin = rings[0][0]
    poly = Polygon(rings[0] - origin, [r - origin for r in rings[1:]])
    return float(poly.area), 1.01 * loss + 1e-12 * domain.diameter ** 2


def _corner_exempt(P, T, E, markers, infos, fixed, tree, ang, L, A, tol, cand) -> np.ndarray:
    """Triangles (among ``cand``) exempt from the angle and quality floors: the smallest
    angle at an input corner whose wedge is below 2A, or the shortest edge joining the two
    curves of such a corner at about the same distance from it."""
    out = np.zeros(len(T), bool)
    if len(fixed) == 0 or len(E) == 0:
        return out
    d, node = tree.query(fixed)
    apexes = np.unique(node[d <= tol])
    # wedges at every apex: sorted tangent directions of the incident curves
    wedges = {}
    for v in apexes:
        rows = np.flatnonzero((E[:, 0] == v) | (E[:, 1] == v))
        dirs, curves = [], []
        for r in rows:
            w = E[r, 1] if E[r, 0] == v else E[r, 0]
            curve = infos[markers[r] - 1].curve
            tv, tw = (float(np.asarray(curve.project(P[[x]]))[0]) for x in (v, w))
            step = tw - tv
            closed = float(np.hypot(*(np.asarray(curve.start) - np.asarray(curve.end)))) <= tol
            if closed and abs(step) > 0.5:
                step = -step
            tg = np.asarray(curve.tangent(np.array([tv])))[0] * (1.0 if step > 0 else -1.0)
            dirs.append(math.atan2(tg[1], tg[0]))
            curves.append(int(markers[r]))
        if len(dirs) < 2:
            continue
        order = np.argsort(dirs)
        th = np.asarray(dirs)[order]
        gaps = np.degrees(np.diff(np.r_[th, th[0] + 2 * math.pi]))
        wedges[int(v)] = (th, gaps, [curves[i] for i in order])
    if not wedges:
        return out
    on_curves: dict[int, set] = {}
    for (u, w), mk in zip(E.tolist(), markers.tolist()):
        on_curves.setdefault(u, set()).add(mk)
        on_curves.setdefault(w, set()).add(mk)
    for i in cand:
        t = T[i]
        k = int(np.argmin(ang[i]))
        v = int(t[k])
        if v in wedges:
            th, gaps, _ = wedges[v]
            other = P[t[(k + 1) % 3]] + P[t[(k + 2) % 3]] - 2 * P[v]
            bis = math.atan2(other[1], other[0])
            j = _gap_of(th, bis)
            if gaps[j] < 2 * A + 1e-9:
                out[i] = True
                continue
        # the shortest edge joins the two curves of a sharp wedge (a seditious edge)
        s = int(np.argmin(L[i]))
        a, b = int(t[(s + 1) % 3]), int(t[(s + 2) % 3])
        ca, cb = on_curves.get(a, set()), on_curves.get(b, set())
        if not ca or not cb:
            continue
        mid = 0.5 * (P[a] + P[b])
        for v, (th, gaps, curves) in wedges.items():
            da, db = P[a] - P[v], P[b] - P[v]
            na, nb = math.hypot(*da), math.hypot(*db)
            if na == 0 or nb == 0 or not (0.5 < na / nb < 2.0):
                continue
            if math.degrees(math.acos(max(-1.0, min(1.0, (da @ db) / (na * nb))))) >= 2 * A:
                continue
            j = _gap_of(th, math.atan2(*(mid - P[v])[::-1]))
            if gaps[j] >= 2 * A + 1e-9:
                continue
            c1, c2 = curves[j], curves[(j + 1) % len(curves)]
            if (c1 in ca and c2 in cb) or (c2 in ca and c1 in cb):
                out[i] = True
                break
    return out


def _gap_of(th: np.ndarray, angle: float) -> int:
    """Index j of the gap (th[j], th[j+1]) (cyclically) containing ``angle``."""
    rel = (angle - th[0]) % (2 * math.pi)
    return int(np.searchsorted(th - th[0], rel, side="right") - 1) % len(th)


def bump_toml(a: float, b: float, w: float) -> str:
    """Model text of the unit square with a narrow Gaussian bump of metal centred at (a, b),
    ``metal = exp(-((x - a)**2 + (y - b)**2)/w)``: a peak that vertex sampling can miss."""
    return f"""
[model]
name = "bump"
[domain.outer]
start = [0, 0]
path = [ {{ to = [1, 0] }}, {{ to = [1, 1] }}, {{ to = [0, 1] }}, {{ to = [0, 0] }} ]
[material]
constituents = ["ceramic", "metal"]
[material.composition]
metal = "exp(-((x - {a!r})**2 + (y - {b!r})**2)/{w!r})"
"""
