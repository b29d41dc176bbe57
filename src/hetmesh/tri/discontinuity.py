"""Material discontinuities of piecewise fields: found, fitted and embedded (Sec. 3.3).

A heterogeneous feature tree (:mod:`hetmesh.material.hft`) divides the domain into
subregions, each with its own smooth material distribution (Secs. 3.3.1-3.3.3). Where the
owning subregion changes -- the medial curves between the sub-features of a composite curve,
the boundary of a ``select`` rule -- the composition may jump. An element straddling such a
curve is not homogeneous however small it is, so the curves must be mesh edges. A formula
field with jumps (``where``, ``sign``; :class:`~hetmesh.material.AnalyticField`) has
subregions too: the patterns of truth values of its conditions.

The paper derives those curves by hand per model. Here they are found for any such field
(anything with ``region(points)`` and ``n_regions > 1``):

1. **Trace.** The subregion id is sampled on a grid over the domain's bounding box; every
   grid edge whose ends differ is bisected to the switch point (to ~1e-12 of the diameter),
   the crossings are linked cell by cell (marching squares; a cell with three or more
   subregions holds a junction, located by nested refinement) and chained into polylines.
2. **Clip.** Polylines are cut at the domain boundary, where the end point is located *on
   the boundary curve* by bisecting the subregion along it (or snapped to a corner), and
   at the corners they run through (a straight jump through a re-entrant corner).
   Pieces lying on an existing interface (a ``select`` rule "inside A" where A is an
   interface of the domain) are dropped: they are embedded already.
3. **Fit.** Each polyline becomes a chain of circular arcs and segments within ``tol`` of the
   crossings (greedy, longest piece first), so the mesher can place nodes freely along it.
4. **Embed.** Boundary curves are split where a discontinuity ends on them, and each chain is
   added to the domain as an interface path named ``discontinuity[k]``.

:func:`embed_discontinuities` does all four on a model; :func:`crossing_elements` checks a mesh
against the claim that no element interior crosses a discontinuity.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass, replace

import numpy as np
import shapely

from ..material.field import element_subregions, has_subregions
from ..errors import GeometryError, MaterialError, MeshingError
from .geometry import Arc, Path, Segment, make_domain

__all__ = ["Discontinuity", "DISCONTINUITY", "trace_discontinuities",
           "fit_curves", "embed_discontinuities", "embedded_count", "crossing_elements"]

log = logging.getLogger(__name__)

#: name prefix of the interface paths holding discontinuities
DISCONTINUITY = "discontinuity"
GRID_CELLS = 400          # grid cells along the longer side of the bounding box
FIT_TOL = 1e-5            # default fitting tolerance, relative to the domain diameter
BISECT = 48               # bisection steps for a crossing (2^-48 of a grid edge)
#: most grid edges inside the domain that discontinuities may cross, per grid cell along
#: the longer side (about as many curves spanning the domain): more pieces than this are
#: not embedded (:func:`embed_discontinuities` raises MaterialError)
MAX_CROSSINGS_PER_CELL = 100


@dataclass(frozen=True)
class Discontinuity:
    """One discontinuity curve: sampled points (``(K, 2)``, ordered), the two subregion ids
    it separates, and whether it is closed."""

    points: np.ndarray
    regions: tuple[int, int]
    closed: bool = False


# ----------------------------------------------------------------------------- tracing
class _DomainRegions:
    """``region(points)`` of a field, -1 outside ``domain`` where the field owns no
    subregion (a ``select`` without a default may leave the outside unowned; that is not an
    error there, and the -1 boundary lies on the domain's boundary, which is clipped away)."""

    def __init__(self, field, domain):
        self.field, self.domain = field, domain

    def region(self, points):
        try:
            return np.asarray(self.field.region(points), dtype=np.int64)
        except MaterialError:
            out = np.full(len(points), -1, dtype=np.int64)
            inside = self.domain.contains(points)
            out[inside] = self.field.region(points[inside])
            return out


def _bisect(field, a: np.ndarray, b: np.ndarray, la: np.ndarray, steps: int = BISECT):
    """Switch points on segments ``a -> b`` (arrays ``(K, 2)``) where the region leaves
    ``la``; returns the points (the last point still in ``la`` and its neighbour agree to
    2^-steps of the segment)."""
    lo, hi = a.copy(), b.copy()
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        same = field.region(mid) == la
        lo = np.where(same[:, None], mid, lo)
        hi = np.where(same[:, None], hi, mid)
    return 0.5 * (lo + hi)


def _crossings(field, xs: np.ndarray, ys: np.ndarray, lab: np.ndarray):
    """Switch points on the edges of the grid ``xs`` x ``ys`` with labels ``lab``
    ``(len(ys), len(xs))``: ``(points (K, 2), sorted label pairs (K, 2), horizontal ids,
    vertical ids)``, the ids ``-1`` on edges without a switch."""
    ny, nx = len(ys) - 1, len(xs) - 1
    hid = np.full((ny + 1, nx), -1, np.int64)
    vid = np.full((ny, nx + 1), -1, np.int64)
    pts, pair, count = [], [], 0
    for ids, la, lb, (aj, ai), (bj, bi) in (
            (hid, lab[:, :-1], lab[:, 1:], (0, 0), (0, 1)),
            (vid, lab[:-1, :], lab[1:, :], (0, 0), (1, 0))):
        jj, ii = np.nonzero(la != lb)
        if len(jj) == 0:
            continue
        pa = np.column_stack([xs[ii + ai], ys[jj + aj]])
        pb = np.column_stack([xs[ii + bi], ys[jj + bj]])
        ids[jj, ii] = count + np.arange(len(jj))
        count += len(jj)
        pts.append(_bisect(field, pa, pb, la[jj, ii]))
        pair.append(np.sort(np.column_stack([la[jj, ii], lb[jj, ii]]), axis=1))
    if not pts:
        return np.zeros((0, 2)), np.zeros((0, 2), np.int64), hid, vid
    return np.concatenate(pts), np.concatenate(pair), hid, vid


class _Untraceable(MeshingError):
    """The subregions cannot be traced: ``point`` (a coordinate of the trouble), ``pair``
    (the two subregions meeting there) and ``reason`` (the rest of a message)."""

    def __init__(self, point, pair, reason: str):
        super().__init__(reason)
        self.point, self.pair, self.reason = np.asarray(point, float), pair, reason


def _check_resolved(field, xs: np.ndarray, ys: np.ndarray, lab: np.ndarray, inside,
                    max_crossings: int | None) -> None:
    """Raise :class:`_Untraceable` if, on the part of the grid inside the domain
    (``inside(points) -> bool``), the subregion boundaries cross more than
    ``max_crossings`` grid edges, or a cell's centre lies in another subregion than its
    four corners (a piece narrower than the grid, which the tracing would miss)."""
    gx, gy = np.meshgrid(xs, ys)
    ins = np.asarray(inside(np.column_stack([gx.ravel(), gy.ravel()])),
                     dtype=bool).reshape(lab.shape)
    h = float(xs[1] - xs[0])
    if max_crossings is not None:
        hor = (lab[:, :-1] != lab[:, 1:]) & (ins[:, :-1] | ins[:, 1:])
        ver = (lab[:-1] != lab[1:]) & (ins[:-1] | ins[1:])
        n = int(hor.sum() + ver.sum())
        if n > max_crossings:  # name the first crossed edge (a horizontal one if any)
            dj, di = (0, 1) if hor.any() else (1, 0)
            j, i = np.argwhere(hor if hor.any() else ver)[0]
            pair = (int(lab[j, i]), int(lab[j + dj, i + di]))
            at = (xs[i] + 0.5 * h * di, ys[j] + 0.5 * h * dj)
            raise _Untraceable(at, pair, f"its curves cross {n:,} edges of the "
                               f"{len(xs) - 1} x {len(ys) - 1} tracing grid inside the domain "
                               f"(at most {max_crossings:,}): too many pieces to mesh")
    c00 = lab[:-1, :-1]
    same = ((c00 == lab[:-1, 1:]) & (c00 == lab[1:, :-1]) & (c00 == lab[1:, 1:])
            & ins[:-1, :-1] & ins[:-1, 1:] & ins[1:, :-1] & ins[1:, 1:])
    jj, ii = np.nonzero(same)
    if not len(jj):
        return
    centre = np.column_stack([xs[ii] + 0.5 * h, ys[jj] + 0.5 * h])
    cen = np.asarray(field.region(centre), dtype=np.int64)
    odd = np.flatnonzero(cen != c00[jj, ii])
    if len(odd):
        k = odd[0]
        raise _Untraceable(centre[k], (int(c00[jj[k], ii[k]]), int(cen[k])),
                           f"a piece narrower than the tracing grid's spacing {h:.3g} lies "
                           f"there, which the grid cannot follow")


def _labels(field, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    return np.asarray(field.region(np.column_stack([gx.ravel(), gy.ravel()])),
                      dtype=np.int64).reshape(len(ys), len(xs))


def _junction(field, center: np.ndarray, size: float, tol: float) -> np.ndarray:
    """The point where three or more subregions meet, near ``center``.

    In a shrinking window: the switch points of a 16 x 16 grid, a straight line fitted to
    those of every pair of subregions, and their least-squares intersection. Near the
    junction the curves are straight to second order, so each window (a quarter of the
    last) gains about two digits.
    """
    c = np.asarray(center, dtype=float)
    w = float(size)
    while w > tol:
        s = np.linspace(-0.5 * w, 0.5 * w, 17)
        xs, ys = c[0] + s, c[1] + s
        pts, pairs, _, _ = _crossings(field, xs, ys, _labels(field, xs, ys))
        A, rhs = np.zeros((2, 2)), np.zeros(2)
        for pr in np.unique(pairs, axis=0):
            q = pts[(pairs == pr).all(axis=1)]
            if len(q) < 2:
                continue
            m = q.mean(axis=0)
            _, _, vt = np.linalg.svd(q - m)
            n = vt[1]  # the line's normal
            A += np.outer(n, n)
            rhs += np.outer(n, n) @ m
        if np.linalg.cond(A) < 1e8:
            x = np.linalg.solve(A, rhs)
            c = np.clip(x, c - 0.5 * w, c + 0.5 * w)
        w /= 4.0
    return c


def trace_discontinuities(field, bounds, *, cells: int = GRID_CELLS,
                          tol: float | None = None, inside=None,
                          max_crossings: int | None = None) -> list[Discontinuity]:
    """Every curve in the box ``bounds = (x0, y0, x1, y1)`` where ``field.region`` changes,
    as ordered polylines (see the module docstring, step 1).

    The grid resolves features larger than the box's longer side / ``cells``; a subregion
    thinner than a grid cell everywhere can be missed. With ``inside`` (a callable
    ``points -> bool``, the domain), that is checked first on the grid cells inside: a
    cell whose centre lies in another subregion than its corners, or more than
    ``max_crossings`` grid edges crossed, raise an exception (a
    :class:`~hetmesh.errors.MeshingError` with the attributes ``point``, ``pair`` and
    ``reason``; :func:`embed_discontinuities` turns it into a
    :class:`~hetmesh.errors.MaterialError` naming the jump).
    """
    x0, y0, x1, y1 = (float(v) for v in bounds)
    span = max(x1 - x0, y1 - y0)
    pad = 0.02 * span
    h = (span + 2 * pad) / cells
    nx = int(math.ceil((x1 - x0 + 2 * pad) / h))
    ny = int(math.ceil((y1 - y0 + 2 * pad) / h))
    xs = x0 - pad + h * np.arange(nx + 1)
    ys = y0 - pad + h * np.arange(ny + 1)
    lab = _labels(field, xs, ys)
    if inside is not None:
        _check_resolved(field, xs, ys, lab, inside, max_crossings)
    tol = 1e-9 * span if tol is None else tol

    P, pairs, hid, vid = _crossings(field, xs, ys, lab)
    if len(P) == 0:
        return []

    # link crossings cell by cell
    c00, c10, c01, c11 = lab[:-1, :-1], lab[:-1, 1:], lab[1:, :-1], lab[1:, 1:]
    nlab = (1 + (c10 != c00) + ((c01 != c00) & (c01 != c10))
            + ((c11 != c00) & (c11 != c10) & (c11 != c01)))
    links: list[tuple[int, int]] = []
    junction_cells = np.argwhere(nlab >= 3)
    jnodes: dict[tuple[int, int], int] = {}
    extra: list[np.ndarray] = []
    groups = _group_cells(junction_cells)
    for group in groups:
        gj, gi = group[:, 0], group[:, 1]
        # one junction per group of touching junction cells, refined in its bounding square
        size = h * (max(gj.max() - gj.min(), gi.max() - gi.min()) + 1)
        corner = np.array([xs[gi.min()], ys[gj.min()]])
        J = _junction(field, corner + 0.5 * size, 2.0 * size, tol)
        k = len(P) + len(extra)
        extra.append(J)
        for j, i in group:
            jnodes[(int(j), int(i))] = k
    for j, i in np.argwhere(nlab >= 2):
        edges = [hid[j, i], vid[j, i + 1], hid[j + 1, i], vid[j, i]]  # bottom right top left
        cr = [e for e in edges if e >= 0]
        key = (int(j), int(i))
        if key in jnodes:
            J = jnodes[key]
            for e, (dj, di) in zip(edges, ((-1, 0), (0, 1), (1, 0), (0, -1))):
                if e >= 0 and jnodes.get((int(j) + dj, int(i) + di)) != J:
                    links.append((int(e), J))
            continue
        if len(cr) == 2:
            links.append((int(cr[0]), int(cr[1])))
        elif len(cr) == 4:  # saddle: the centre decides which corners are connected
            cen = field.region(np.array([[xs[i] + 0.5 * h, ys[j] + 0.5 * h]]))[0]
            b, r, t, l = (int(e) for e in edges)
            links += [(b, r), (t, l)] if cen == c00[j, i] else [(b, l), (t, r)]
    if extra:
        P = np.vstack([P, np.array(extra)])
        pairs = np.vstack([pairs, np.full((len(extra), 2), -1)])
    return [Discontinuity(P[c], _pair_of(pairs[c]), closed) for c, closed in
            _chains(len(P), links)]


def _group_cells(cells: np.ndarray) -> list[np.ndarray]:
    """Groups of junction cells touching by an edge or a corner."""
    left = {tuple(c) for c in cells.tolist()}
    out = []
    while left:
        stack = [left.pop()]
        group = []
        while stack:
            j, i = stack.pop()
            group.append((j, i))
            for dj in (-1, 0, 1):
                for di in (-1, 0, 1):
                    n = (j + dj, i + di)
                    if n in left:
                        left.remove(n)
                        stack.append(n)
        out.append(np.array(sorted(group)))
    return sorted(out, key=lambda g: tuple(g[0]))


def _pair_of(pairs: np.ndarray) -> tuple[int, int]:
    ok = pairs[pairs[:, 0] >= 0]
    if len(ok) == 0:
        return (-1, -1)
    vals, counts = np.unique(ok, axis=0, return_counts=True)
    a, b = vals[np.argmax(counts)]
    return int(a), int(b)


def _chains(n: int, links: list[tuple[int, int]]) -> list[tuple[list[int], bool]]:
    """Maximal paths of the link graph between nodes of degree != 2, then the cycles."""
    adj: list[list[int]] = [[] for _ in range(n)]
    for a, b in links:
        if a != b:
            adj[a].append(b)
            adj[b].append(a)
    used: set[tuple[int, int]] = set()
    out = []

    def walk(start, nxt):
        path = [start, nxt]
        used.add((min(start, nxt), max(start, nxt)))
        prev, cur = start, nxt
        while len(adj[cur]) == 2:
            a, b = adj[cur]
            step = b if a == prev else a
            key = (min(cur, step), max(cur, step))
            if key in used:
                break
            used.add(key)
            path.append(step)
            prev, cur = cur, step
        return path

    for v in range(n):
        if len(adj[v]) != 2:
            for w in adj[v]:
                if (min(v, w), max(v, w)) not in used:
                    out.append((walk(v, w), False))
    for v in range(n):
        for w in adj[v]:
            if (min(v, w), max(v, w)) not in used:
                path = walk(v, w)
                out.append((path, path[0] == path[-1]))
    return out


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


# ----------------------------------------------------------------------------- fitting
def _circle3(a, b, c):
    """Centre and radius of the circle through three points, or None if collinear."""
    ab, ac = b - a, c - a
    d = 2.0 * (ab[0] * ac[1] - ab[1] * ac[0])
    if abs(d) <= 1e-12 * (ab @ ab + ac @ ac):
        return None
    u = np.array([ac[1] * (ab @ ab) - ab[1] * (ac @ ac), ab[0] * (ac @ ac) - ac[0] * (ab @ ab)]) / d
    return a + u, float(np.hypot(*u))


def _deviation(p: np.ndarray, i: int, j: int):
    """How far points ``p[i..j]`` are from the arc (or segment) through ``p[i]``,
    ``p[(i+j)//2]``, ``p[j]``; returns ``(deviation, centre or None)``."""
    a, m, b = p[i], p[(i + j) // 2], p[j]
    q = p[i:j + 1]
    circ = _circle3(a, m, b) if j - i >= 2 else None
    if circ is None or circ[1] > 1e6 * np.hypot(*(b - a)):
        d = b - a
        L = float(np.hypot(*d))
        dev = np.abs((q[:, 0] - a[0]) * d[1] - (q[:, 1] - a[1]) * d[0]) / L
        return float(dev.max()), None
    c, r = circ
    dev = np.abs(np.hypot(q[:, 0] - c[0], q[:, 1] - c[1]) - r)
    return float(dev.max()), c


def fit_curves(points: np.ndarray, tol: float, name: str = DISCONTINUITY) -> list:
    """Arcs and segments through ``points`` (ordered; ends kept exactly), each piece within
    ``tol`` of the points it replaces; greedy, each piece as long as the tolerance allows."""
    p = np.asarray(points, dtype=float)
    n = len(p)
    if n > 3 and np.array_equal(p[0], p[-1]):  # a closed curve: two open halves
        return fit_curves(p[:n // 2 + 1], tol, name) + fit_curves(p[n // 2:], tol, name)
    out = []
    i = 0
    while i < n - 1:
        step, j = 1, i + 1
        while j < n - 1:  # grow geometrically, then bisect back to the longest fitting piece
            k = min(i + 2 * step, n - 1)
            if _deviation(p, i, k)[0] > tol:
                lo, hi = j, k
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    if _deviation(p, i, mid)[0] <= tol:
                        lo = mid
                    else:
                        hi = mid
                j = lo
                break
            j, step = k, 2 * step
        _, c = _deviation(p, i, j)
        out.append(Segment(tuple(p[i]), tuple(p[j]), name) if c is None
                   else Arc.through(tuple(p[i]), tuple(p[(i + j) // 2]), tuple(p[j]), name=name))
        i = j
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
    labels = _DomainRegions(fl, dom)
    try:
        found = trace_discontinuities(labels, dom.bounds, cells=cells, tol=1e-3 * tol,
                                      inside=dom.contains,
                                      max_crossings=MAX_CROSSINGS_PER_CELL * cells)
    except _Untraceable as exc:
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


# ----------------------------------------------------------------------------- checking
def crossing_elements(field, points: np.ndarray, triangles: np.ndarray, curves, *,
                      order: int = 4, tol: float = 0.0,
                      regions: np.ndarray | None = None) -> np.ndarray:
    """Elements whose interior crosses a subregion boundary (bool ``(M,)``).

    Every element is sampled on its order-``order`` lattice (pulled a hair inside); a sample
    owned by another subregion than the element's centroid is a crossing unless it lies within
    the element's chord error of the embedded curves ``curves`` (a :class:`CurveBatch`): an
    edge on a curved discontinuity is its chord, and the sliver between chord and curve,
    of width the sagitta, belongs to the neighbour. ``tol`` adds the fitting tolerance.
    ``regions``: the elements' subregions if already known (:func:`element_subregions`).
    """
    from ..metrics import lattice_barycentric

    own = element_subregions(field, points, triangles) if regions is None else regions
    lam = lattice_barycentric(order)
    lam = 0.999 * lam + 0.001 / 3.0
    xy = np.einsum("kv,cvd->ckd", lam, points[triangles])  # (M, K, 2)
    reg = field.region(xy.reshape(-1, 2)).reshape(len(triangles), -1)
    bad = reg != own[:, None]
    if not bad.any():
        return np.zeros(len(triangles), bool)
    e, k = np.nonzero(bad)
    near = curves.distance(xy[e, k])
    tri = triangles[e]
    nxt = np.roll(tri, -1, axis=1)
    lens = np.hypot(*(points[tri] - points[nxt]).transpose(2, 0, 1))  # (n, 3)
    scale = float(lens.max())
    on = curves.distance(points) <= 1e-9 * scale
    mids = 0.5 * (points[tri] + points[nxt]).reshape(-1, 2)
    sag = np.where(on[tri] & on[nxt], curves.distance(mids).reshape(-1, 3), 0.0).max(axis=1)
    allowed = sag + tol + 1e-9 * scale
    out = np.zeros(len(triangles), bool)
    out[e[near > allowed]] = True
    return out
