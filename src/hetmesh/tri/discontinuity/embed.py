"""Stages 2 and 4, clip and embed: traced polylines cut at the domain's boundary and
corners, fitted, and added to the domain as interface paths."""

from __future__ import annotations

import logging
import re
from dataclasses import replace

import numpy as np
import shapely

from ...errors import GeometryError, MaterialError
from ...material.field import has_subregions
from ..geometry import Arc, Path, Segment, make_domain
from .fit import fit_curves
from .regions import (
    DISCONTINUITY,
    FIT_TOL,
    GRID_CELLS,
    MAX_CROSSINGS_PER_CELL,
    Discontinuity,
    DomainRegions,
)
from .trace import Untraceable, trace_discontinuities

__all__ = ["embed_discontinuities", "embedded_count"]

log = logging.getLogger(__name__)


# ----------------------------------------------------------------------------- clipping
def _boundary_point(field, domain, q: np.ndarray, h: float, tol: float) -> np.ndarray:
    """The point of the domain's boundary (or interface) curves near ``q`` where the region
    changes: a curve end point (corner) if the change is there, else bisected on the curve."""
    corners = domain.corners
    curves = [ci.curve for ci in domain.curves]
    dist = np.array([float(c.distance(q[None])[0]) for c in curves])
    k = int(np.argmin(dist))
    c = curves[k]
    t = float(c.project(q[None])[0])
    dt = 3.0 * h / max(c.length, 1e-300)
    ta, tb = max(t - dt, 0.0), min(t + dt, 1.0)
    pa, pb = c.point(np.array([ta, tb]))
    ra, rb = field.region(np.array([pa, pb]))
    if ra != rb:
        for _ in range(60):
            tm = 0.5 * (ta + tb)
            if field.region(c.point(np.array([tm])))[0] == ra:
                ta = tm
            else:
                tb = tm
        at = c.point(np.array([0.5 * (ta + tb)]))[0]
    else:
        at = c.point(np.array([t]))[0]
    # a corner within reach wins: there the change is between two curves
    dc = np.hypot(*(corners - at).T)
    j = int(np.argmin(dc))
    if dc[j] <= 3.0 * h and ra == rb or dc[j] <= max(tol, 1e-9 * h):
        return corners[j].copy()
    return at


def _clip(field, domain, disc: Discontinuity, h: float, tol: float) -> list[np.ndarray]:
    """The parts of ``disc`` inside the domain, each ending exactly on the boundary."""
    p = disc.points
    inside = domain.contains(p) & (domain.distance_to_boundary(p, interfaces=False) > tol)
    if inside.all():
        return [p]
    out = []
    n = len(p)
    i = 0
    while i < n:
        if not inside[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and inside[j + 1]:
            j += 1
        part = [p[i:j + 1]]
        if i > 0:
            part.insert(0, _boundary_point(field, domain, p[i - 1], h, tol)[None])
        if j + 1 < n:
            part.append(_boundary_point(field, domain, p[j + 1], h, tol)[None])
        piece = np.vstack(part)
        if len(piece) >= 2:
            out.append(piece)
        i = j + 1
    if disc.closed and len(out) > 1 and inside[0] and inside[-1]:
        out[0] = np.vstack([out.pop()[:-1], out[0]])  # a loop cut once: join its ends
    return out


# ----------------------------------------------------------------------------- embedding
def _split_chain(chain, cuts: np.ndarray, tol: float):
    """``chain`` (Loop or Path) with its curves split at the points ``cuts`` lying on them."""
    curves = []
    for c in chain.curves:
        inner = _inner_cuts(c, cuts, tol)
        if len(inner) == 0:
            curves.append(c)
            continue
        if isinstance(c, Arc) and c.is_full:  # a circle cut once starts at the cut
            a0 = c.theta0 + float(np.min(c.project(inner))) * (c.theta1 - c.theta0)
            c = Arc(c.center, c.radius, a0, a0 + (c.theta1 - c.theta0), c.name)
            inner = _inner_cuts(c, inner, tol)
        ts = np.sort(np.asarray(c.project(inner), float)) if len(inner) else np.zeros(0)
        if len(ts) > 1:  # a point where two pieces end is one cut
            ts = ts[np.r_[True, np.diff(ts) * c.length > tol]]
        bounds = np.r_[0.0, ts, 1.0]
        curves.extend(_sub_curve(c, ta, tb) for ta, tb in zip(bounds[:-1], bounds[1:]))
    return replace(chain, curves=tuple(curves))


def _inner_cuts(c, cuts: np.ndarray, tol: float) -> np.ndarray:
    """The points of ``cuts`` on curve ``c`` (within ``tol``) that are not at its ends."""
    if len(cuts) == 0:
        return cuts
    on = cuts[c.distance(cuts) <= tol]
    ends = np.array([c.start, c.end])
    far = np.hypot(on[:, None, 0] - ends[:, 0], on[:, None, 1] - ends[:, 1]).min(axis=1) > tol
    return on[far]


def _sub_curve(c, ta: float, tb: float):
    if ta == 0.0 and tb == 1.0:
        return c
    if isinstance(c, Segment):
        pa = c.start if ta == 0.0 else c.point(np.array([ta]))[0]
        pb = c.end if tb == 1.0 else c.point(np.array([tb]))[0]
        return Segment(tuple(pa), tuple(pb), c.name)
    sweep = c.theta1 - c.theta0
    return Arc(c.center, c.radius, c.theta0 + ta * sweep, c.theta0 + tb * sweep, c.name)


def _split_at_interfaces(part: np.ndarray, domain) -> list[np.ndarray]:
    """``part`` cut where it crosses one of the domain's interface curves (interfaces may
    only meet at curve end points); each crossing point is put exactly on the interface."""
    curves = [ci.curve for ci in domain.curves if ci.kind == "interface"]
    if not curves:
        return [part]
    line = shapely.LineString(part)
    cuts = []  # (segment index, point)
    for c in curves:
        n = max(64, int(c.length / (1e-3 * domain.diameter)))
        hit = line.intersection(shapely.LineString(c.point(np.linspace(0.0, 1.0, n + 1))))
        for g in shapely.get_parts(hit):
            if g.geom_type != "Point":
                continue
            q = c.point(np.asarray(c.project(np.array([g.coords[0]])), float))[0]
            d = np.hypot(*(part - q).T)
            if min(d[0], d[-1]) <= 1e-9 * domain.diameter:
                continue  # the piece already ends there
            seg = _segment_of(part, q)
            cuts.append((seg, q))
    if not cuts:
        return [part]
    out, start, prev = [], 0, None
    for seg, q in sorted(cuts, key=lambda x: (x[0], float(np.hypot(*(x[1] - part[x[0]]))))):
        head = part[start:seg + 1] if prev is None else np.vstack([prev, part[start:seg + 1]])
        out.append(np.vstack([head, q]))
        start, prev = seg + 1, q
    out.append(np.vstack([prev, part[start:]]))
    return [o for o in out if len(o) >= 2]


def _split_at_corners(part: np.ndarray, domain, tol: float) -> list[np.ndarray]:
    """``part`` cut where it passes within ``tol`` of a fixed point of the domain (a curve
    end point, e.g. a re-entrant corner that a straight jump runs through, or a named
    point): each piece ends exactly there, so it meets the boundary, other curves and named
    points only at curve end points."""
    corners = np.asarray(domain.corners, dtype=float).reshape(-1, 2)
    if len(corners) == 0 or len(part) < 2:
        return [part]
    a, d = part[:-1], part[1:] - part[:-1]
    l2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    rel = corners[:, None, :] - a[None]
    t = np.clip(np.einsum("ksj,sj->ks", rel, d) / l2, 0.0, 1.0)
    dist = np.hypot(*(rel - t[..., None] * d).transpose(2, 0, 1))  # (corners, segments)
    near = np.min(np.hypot(*(corners[:, None, :] - part[[0, -1]][None]).transpose(2, 0, 1)),
                  axis=1)
    cuts = []
    for k in np.flatnonzero((dist.min(axis=1) <= tol) & (near > tol)):
        s = int(np.argmin(dist[k]))
        cuts.append((s, float(t[k, s]), corners[k]))
    if not cuts:
        return [part]
    out, head = [], part[:1]
    start = 1
    for s, _, c in sorted(cuts, key=lambda x: (x[0], x[1])):
        body = part[start:s + 1]
        body = body[np.hypot(*(body - c).T) > tol]
        out.append(np.vstack([head, body, c]))
        head, start = c[None], s + 1
    tail = part[start:]
    out.append(np.vstack([head, tail[np.hypot(*(tail - head[0]).T) > tol]]))
    return [o for o in out if len(o) >= 2]


def _segment_of(part: np.ndarray, q: np.ndarray) -> int:
    """Index ``i`` of the polyline segment ``part[i] -> part[i + 1]`` nearest to ``q``."""
    a, b = part[:-1], part[1:]
    d = b - a
    t = np.clip(np.einsum("ij,ij->i", q - a, d) / np.maximum(np.einsum("ij,ij->i", d, d),
                                                             1e-300), 0.0, 1.0)
    return int(np.argmin(np.hypot(*(a + t[:, None] * d - q).T)))


def _on_curves(domain, pts: np.ndarray, tol: float) -> bool:
    return bool(domain.curve_batch.distance(pts).max() <= tol)


def embed_discontinuities(model, *, tol: float | None = None, cells: int = GRID_CELLS):
    """The model with its material discontinuities added to the domain as interfaces.

    Returns ``model`` itself if its field has no subregions or no discontinuity lies inside
    the domain. ``tol`` is the fitting tolerance (default ``1e-5`` x the domain diameter).
    Raises :class:`MaterialError` if the subregions cannot be traced (more pieces than
    :data:`MAX_CROSSINGS_PER_CELL` x ``cells`` grid edges crossed inside the domain, or a
    piece narrower than the tracing grid) or if the traced curves cannot be embedded (two
    jumps closer than the geometric tolerance, one running along a boundary curve for a
    while): both are properties of the model. Messages start with the
    field's ``describe_jump(ra, rb)`` for the two subregions concerned if it has one (a
    formula field names its key and condition), else with the model's name, and give a
    coordinate.
    """
    field, domain = model.material, model.domain
    if not has_subregions(field) or embedded_count(domain) is not None:
        return model
    x0, y0, x1, y1 = domain.bounds
    offset = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
    dom = domain.translated(-offset)
    fl = field.shifted(offset)
    diam = dom.diameter
    tol = FIT_TOL * diam if tol is None else float(tol)
    h = max(x1 - x0, y1 - y0) * 1.04 / cells
    labels = DomainRegions(fl, dom)
    try:
        found = trace_discontinuities(labels, dom.bounds, cells=cells, tol=1e-3 * tol,
                                      inside=dom.contains,
                                      max_crossings=MAX_CROSSINGS_PER_CELL * cells)
    except Untraceable as exc:
        x, y = exc.point + offset  # the material's fault, not the mesher's
        raise MaterialError(f"{_jump_name(model, exc.pair)}: the jump near ({x:.6g}, "
                            f"{y:.6g}) cannot be embedded in the mesh: {exc.reason}") from None
    pieces, pairs = [], []
    for disc in found:
        for clipped in _clip(labels, dom, disc, h, 1e-9 * diam):
            for part in _split_at_corners(clipped, dom, tol):
                if _on_curves(dom, part, 10 * tol):
                    continue  # already an interface (or the boundary) of the domain
                split = _split_at_interfaces(part, dom)
                pieces += split
                pairs += [disc.regions] * len(split)
    if not pieces:
        return model
    ends = np.vstack([np.vstack([p[0], p[-1]]) for p in pieces])
    paths = []
    for k, part in enumerate(pieces):
        name = f"{DISCONTINUITY}[{k}]"
        try:
            paths.append(Path(tuple(c.translated(offset) for c in fit_curves(part, tol, name)),
                              name))
        except GeometryError as exc:
            raise MaterialError(f"{_jump_name(model, pairs[k])}: could not fit discontinuity "
                                f"{k}: {exc}") from None
    cut_tol = 1e-7 * diam
    cuts = ends + offset
    outer = _split_chain(domain.outer, cuts, cut_tol)
    holes = tuple(_split_chain(hl, cuts, cut_tol) for hl in domain.holes)
    inter = tuple(_split_chain(pt, cuts, cut_tol) for pt in domain.interfaces)
    try:
        new = make_domain(outer, holes, inter + tuple(paths), domain.points,
                          where=f"embedding {len(paths)} discontinuity curves")
    except GeometryError as exc:  # name the jump of the curve the message is about
        # the material's jumps come closer to each other or to the domain's curves than
        # any mesh can separate: a property of the model (exit code 2), not a failure
        hit = re.search(rf"{DISCONTINUITY}\[(\d+)\]", str(exc))
        k = int(hit.group(1)) if hit and int(hit.group(1)) < len(pairs) else 0
        raise MaterialError(f"{_jump_name(model, pairs[k])}: {exc}") from None
    log.info("%s: %d discontinuity curves embedded (%d arcs and segments)", model.name,
             len(paths), sum(len(p.curves) for p in paths))
    return replace(model, domain=new)


def _jump_name(model, pair) -> str:
    """What an error about the jump between subregions ``pair`` starts with: the field's
    own description (a formula field names its formula key and condition), else the model's
    name."""
    describe = getattr(model.material, "describe_jump", None)
    if callable(describe) and min(pair) >= 0:
        return describe(*pair)
    return model.name


def embedded_count(domain) -> int | None:
    """How many discontinuity paths ``domain`` holds (None if it holds none)."""
    n = sum(1 for p in domain.interfaces if p.name.startswith(DISCONTINUITY + "["))
    return n or None
