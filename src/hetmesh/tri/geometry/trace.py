"""Domains and phase boundaries traced from images.

A mask or a label image is a grid of pixels; its region boundaries run along pixel edges
(staircases). :func:`trace_labels` follows them and returns *chains*: polylines between
*junctions* (pixel corners where three or more regions meet, or where a region boundary meets
the image border), or closed loops, through the midpoints of the pixel edges (the contour
marching squares draws between the centres of unlike pixels, within sqrt(2)/4 of a pixel of
the staircase). Each chain is then simplified (greedy longest chords through its points
averaged over 5, ends kept) to within ``tol`` pixels of that contour's points, half a pixel
by default. Where the simplified
chains would cross or touch each other, the tolerance is halved until they do not.

Conventions (those of :class:`hetmesh.material.image.Image`): ``labels`` is ``(ny, nx)`` with
row 0 at the smallest y; pixel ``(j, i)`` has its centre at ``origin + (i, j) * spacing``.
Pixel corners where two diagonal pixels match and the other two do not (a checkerboard
*saddle*) are resolved by joining the diagonal of the smaller label (the outside, -1, first),
the chains passing a quarter pixel off the corner, so regions touching at a corner only are
separate and no curve touches itself.

:func:`mask_domain` and :func:`label_domain` build a :class:`~hetmesh.tri.geometry.Domain`: the
outer boundary and holes from the chains that border the outside, and, for labels, every chain
between two labels as an interface path named ``discontinuity[k]`` (so the mesh follows it and
no element straddles two phases). :func:`region_lookup` gives each point its phase from the
same simplified polygons, so the material field's subregions agree exactly with the embedded
curves. :func:`extent_domain` is the image's rectangle.

>>> import numpy as np
>>> j, i = np.mgrid[0:100, 0:100]
>>> disk = (i - 49.5) ** 2 + (j - 49.5) ** 2 < 40 ** 2        # radius 40 pixels
>>> d = mask_domain(disk, origin=(0.5, 0.5), spacing=(1.0, 1.0))
>>> bool(abs(float(d.area) - np.pi * 40 ** 2) < 2 * np.pi * 40 * 0.5)   # within 1/2 pixel
True
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import shapely

from ...errors import GeometryError
from .curves import Segment
from .domain import Domain, Loop, Path, make_domain

__all__ = ["Chain", "trace_labels", "simplify", "simplify_chains", "mask_domain",
           "label_domain", "extent_domain", "region_lookup", "largest_component",
           "OUTSIDE", "DEFAULT_TOL"]

log = logging.getLogger(__name__)

#: the label of the outside (the image border, zero pixels of a mask)
OUTSIDE = -1
#: default simplification tolerance, in pixels
DEFAULT_TOL = 0.5
SADDLE_OFFSET = 0.25  # pixels, along each axis


@dataclass(frozen=True)
class Chain:
    """A region boundary: ``points`` ``(K, 2)`` in pixel-corner index coordinates (corner
    ``(i, j)`` is the lower-left corner of pixel ``(j, i)``), ``left`` and ``right`` the
    labels on either side in the direction of travel, and the ids of its end corners
    (negative: a private id of a cut point of a closed boundary)."""

    points: np.ndarray
    left: int
    right: int
    start: int = -1
    end: int = -1


# ------------------------------------------------------------------------------ tracing
def _padded(labels: np.ndarray) -> np.ndarray:
    lab = np.asarray(labels)
    if lab.ndim != 2:
        raise GeometryError(f"a label image must be 2-D, got shape {lab.shape}")
    out = np.full((lab.shape[0] + 2, lab.shape[1] + 2), OUTSIDE, dtype=np.int64)
    out[1:-1, 1:-1] = lab
    return out


def trace_labels(labels: np.ndarray) -> list[Chain]:
    """Every boundary between different labels (and between a label and the outside, i.e.
    the border, or pixels labelled :data:`OUTSIDE`), as chains of pixel-corner points. The
    corners of the image are junctions, so the image's rectangle is traced exactly.

    Open chains run between junctions; a closed boundary is cut in two at its first point
    and the point farthest from it (so every chain has two distinct ends).
    """
    L = _padded(labels)
    nx = L.shape[1] - 2
    W = nx + 1  # corner id = cj * W + ci
    BL, BR, TL, TR = L[:-1, :-1], L[:-1, 1:], L[1:, :-1], L[1:, 1:]
    right = BR != TR       # edge corner -> corner + (1, 0)
    up = TL != TR          # edge corner -> corner + (0, 1)
    left = BL != TL
    down = BL != BR
    deg = right.astype(np.int8) + up + left + down
    d1, d2 = BL == TR, TL == BR  # diagonal pairs
    saddle = (deg == 4) & (d1 | d2)
    # join the diagonal of the smaller label: pair the edges around each isolated pixel
    join1 = saddle & d1 & (~d2 | (BL <= TL))  # BL-TR joined: TL and BR isolated
    junction = (deg == 3) | ((deg == 4) & ~saddle)
    junction[[0, 0, -1, -1], [0, -1, 0, -1]] |= deg[[0, 0, -1, -1], [0, -1, 0, -1]] > 0
    # edges: (corner a, corner b, left label, right label) in the direction a -> b
    cj, ci = np.nonzero(right[:, :-1])
    ea = [cj * W + ci]
    eb = [cj * W + ci + 1]
    el = [TR[cj, ci]]
    er = [BR[cj, ci]]
    cj, ci = np.nonzero(up[:-1, :])
    ea.append(cj * W + ci)
    eb.append((cj + 1) * W + ci)
    el.append(TL[cj, ci])
    er.append(TR[cj, ci])
    ea, eb = np.concatenate(ea), np.concatenate(eb)
    el, er = np.concatenate(el), np.concatenate(er)
    if not len(ea):
        return []
    return _chains(ea, eb, el, er, W, junction.ravel(), saddle.ravel(), join1.ravel())


def _chains(ea, eb, el, er, W, junction, saddle, join1) -> list[Chain]:
    """Walk the edge graph into chains (a Python walk over edges; arrays in, arrays out)."""
    n_e = len(ea)
    # incidence: every edge end; at a saddle, the end belongs to one of two split vertices
    ends = np.concatenate([ea, eb])
    other = np.concatenate([eb, ea])
    eid = np.concatenate([np.arange(n_e), np.arange(n_e)])
    # direction of the edge as seen from this end: 0 right, 1 up, 2 left, 3 down
    d = other - ends
    dirn = np.where(d == 1, 0, np.where(d == W, 1, np.where(d == -1, 2, 3)))
    sad = saddle[ends]
    j1 = join1[ends]
    # split vertex 1 collects the edges around the isolated pixel TL (join1) or BL (else)
    part = np.where(j1, np.isin(dirn, (1, 2)), np.isin(dirn, (2, 3))).astype(np.int64)
    vkey = 3 * ends + np.where(sad, 1 + part, 0)
    order = np.lexsort((eid, vkey))
    skey, sedge = vkey[order], eid[order]
    first = np.r_[True, skey[1:] != skey[:-1]]
    starts = np.flatnonzero(first)
    counts = np.diff(np.r_[starts, len(skey)])
    vid = np.cumsum(first) - 1  # vertex index of each sorted incidence
    nbr = [[] for _ in range(len(starts))]
    inc_v = np.empty(2 * n_e, np.int64)
    inc_v[order] = vid
    va, vb = inc_v[:n_e], inc_v[n_e:]
    for s, c in zip(starts.tolist(), counts.tolist()):
        nbr[vid[s]] = sedge[s:s + c].tolist()
    vcorner = skey[starts] // 3
    is_j = junction[vcorner].tolist()
    vsad = skey[starts] % 3 > 0
    vpart = skey[starts] % 3 - 1
    vj1 = join1[vcorner]
    # vertex positions in corner index coordinates, saddles a quarter pixel off the corner
    pos = np.column_stack([vcorner % W, vcorner // W]).astype(float)
    # moved into the isolated pixel: part 1 -> TL (join1) / BL, part 0 -> BR / TR
    off = np.where(vj1[:, None], np.where(vpart[:, None] == 1, [[-1, 1]], [[1, -1]]),
                   np.where(vpart[:, None] == 1, [[-1, -1]], [[1, 1]]))
    pos += np.where(vsad[:, None], SADDLE_OFFSET * off, 0.0)
    used = np.zeros(n_e, bool)
    va_l, vb_l = va.tolist(), vb.tolist()
    out: list[Chain] = []

    def walk(v0: int, e0: int) -> tuple[list[int], int, bool]:
        verts, v, e = [v0], v0, e0
        forward = va_l[e0] == v0
        while True:
            used[e] = True
            v = vb_l[e] if va_l[e] == v else va_l[e]
            verts.append(v)
            if is_j[v] or v == v0:
                return verts, v, forward
            a, b = nbr[v]
            e = b if a == e else a
            if used[e]:
                return verts, v, forward

    for v0 in [v for v, j in enumerate(is_j) if j]:
        for e0 in nbr[v0]:
            if used[e0]:
                continue
            verts, v1, fwd = walk(v0, e0)
            out.extend(_make(pos, verts, el[e0], er[e0], fwd, vcorner))
    for e0 in range(n_e):
        if not used[e0]:
            verts, _, fwd = walk(va_l[e0], e0)
            out.extend(_make(pos, verts, el[e0], er[e0], fwd, vcorner, closed=True))
    return out


def _make(pos, verts, left, right, forward, vcorner, closed=False) -> list[Chain]:
    """The marching-squares polyline of one walk: the midpoints of its pixel edges, from
    junction to junction (the junction corners kept as ends); a closed boundary (or one
    returning to its junction) is cut in two at the point farthest from its start."""
    lab_l, lab_r = (int(left), int(right)) if forward else (int(right), int(left))
    p = pos[verts]
    mids = 0.5 * (p[:-1] + p[1:])
    ids = [int(vcorner[verts[0]]), int(vcorner[verts[-1]])]
    if verts[0] != verts[-1]:
        return [Chain(np.vstack([p[:1], mids, p[-1:]]), lab_l, lab_r, ids[0], ids[1])]
    if closed:  # a ring of midpoints, cut at its first one
        ring = np.vstack([mids, mids[:1]])
        start = -2 - 4 * int(verts[0])
    else:
        ring = np.vstack([p[:1], mids, p[-1:]])
        start = ids[0]
    k = int(np.argmax(np.hypot(*(ring - ring[0]).T)))
    mid = -3 - 4 * int(verts[0])  # a private id for the cut point
    return [Chain(ring[:k + 1], lab_l, lab_r, start, mid),
            Chain(ring[k:], lab_l, lab_r, mid, start)]


# ------------------------------------------------------------------------ simplification
def simplify(points: np.ndarray, tol: float, *, windows: tuple = (1, 4, 5)) -> np.ndarray:
    """A polyline within ``tol`` of every one of ``points`` (ends kept): greedy longest
    chords (each found by doubling, then bisecting), through the points themselves or
    through their moving averages over 4 or 5 points (each averaged point then allowed
    ``tol`` minus how far the averaging moved it), whichever needs the fewest vertices.

    A digital line's edge midpoints zig-zag by up to 2/3 of a pixel with a period of a few
    pixels; Douglas-Peucker splits at the extremes of the zig-zag and then needs a vertex
    every pixel or two on most slopes. Greedy chords and averages over about one period
    run along its middle instead.

    >>> simplify(np.array([[0, 0], [1, 0.3], [2, 0], [3, 0.3], [4, 0]]), 0.5).tolist()
    [[0.0, 0.0], [4.0, 0.0]]
    """
    p = np.asarray(points, float)
    if len(p) <= 2 or tol <= 0:
        return p
    return min((_greedy(p, tol, w) for w in windows), key=len)


def _greedy(p: np.ndarray, tol: float, window: int) -> np.ndarray:
    n = len(p)
    q = _smoothed(p, window)
    allow = tol - np.hypot(*(q - p).T)
    if (allow < 0).any():  # cannot happen for tol > window / 4; keep the points there
        q = np.where((allow < 0)[:, None], p, q)
        allow = np.where(allow < 0, tol, allow)
    keep = [0]
    i = 0
    while i < n - 1:
        good, step = i + 1, 1
        while good < n - 1:
            k = min(i + 2 * step, n - 1)
            if _chord_ok(q, i, k, allow):
                good, step = k, 2 * step
                continue
            lo, hi = good, k
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if _chord_ok(q, i, mid, allow):
                    lo = mid
                else:
                    hi = mid
            good = lo
            break
        keep.append(good)
        i = good
    return q[keep]


def _smoothed(p: np.ndarray, window: int) -> np.ndarray:
    """Moving average of ``window`` points along the polyline (an even window averages
    the midpoints of consecutive points), ends fixed, windows shrinking near them."""
    n = len(p)
    if window < 2 or n < 3:
        return p.copy()
    if window % 2 == 0:  # average the segment midpoints over window - 1
        m = np.vstack([p[:1], 0.5 * (p[:-1] + p[1:]), p[-1:]])
        q = _smoothed(m, window - 1)
        return np.vstack([p[:1], 0.5 * (q[1:-2] + q[2:-1]), p[-1:]]) if n > 2 else p.copy()
    h = window // 2
    c = np.vstack([np.zeros((1, 2)), np.cumsum(p, axis=0)])
    idx = np.arange(n)
    half = np.minimum(np.minimum(idx, n - 1 - idx), h)
    return (c[idx + half + 1] - c[idx - half]) / (2 * half + 1)[:, None]


def _chord_ok(p: np.ndarray, i: int, k: int, tol: np.ndarray) -> bool:
    """Whether every point between ``p[i]`` and ``p[k]`` lies within its ``tol`` of that
    chord (of the segment, so that a chord cannot cut across a turn back)."""
    if k - i < 2:
        return True
    a, d = p[i], p[k] - p[i]
    q = p[i + 1:k] - a
    L2 = float(d @ d)
    t = np.clip(q @ d / L2, 0.0, 1.0) if L2 > 0 else np.zeros(len(q))
    r = q - t[:, None] * d
    return bool((np.einsum("ij,ij->i", r, r) <= tol[i + 1:k] ** 2).all())


def simplify_chains(chains: list[Chain], tol: float = DEFAULT_TOL) -> list[Chain]:
    """Every chain simplified to ``tol`` pixels; the tolerance is halved (down to none)
    until the simplified chains neither cross nor touch except at shared ends."""
    t = float(tol)
    while True:
        out = [Chain(_simplify_chain(c, t), c.left, c.right, c.start, c.end) for c in chains]
        if t <= 0 or _simple(out):
            if t < tol:
                log.info("boundary simplification tolerance lowered to %.3g pixels to keep "
                         "the curves apart", t)
            return out
        t = t / 2 if t > 1e-3 else 0.0


def _straight_run(p: np.ndarray) -> int:
    """Index of the last point of the straight run that ``p`` starts with."""
    if len(p) < 3:
        return len(p) - 1
    d = p[1] - p[0]
    q = p[1:] - p[0]
    ok = (np.abs(q[:, 0] * d[1] - q[:, 1] * d[0]) <= 1e-9) & (q @ d > 0)
    return int(np.argmin(ok)) if not ok.all() else len(p) - 1


def _simplify_chain(c: Chain, tol: float) -> np.ndarray:
    """:func:`simplify`, keeping at a junction end the end of the straight pixel-edge run
    that leaves it, so that curves meeting at a junction leave it at right angles (as the
    pixel edges do) instead of at the small angles their simplified chords could make."""
    p = c.points
    lo = _straight_run(p) if c.start >= 0 else 0
    hi = len(p) - 1 - (_straight_run(p[::-1]) if c.end >= 0 else 0)
    if hi <= lo:
        return simplify(p, tol)
    return np.vstack([p[:1] if lo else p[:0], simplify(p[lo:hi + 1], tol),
                      p[-1:] if hi < len(p) - 1 else p[:0]])


def _simple(chains: list[Chain]) -> bool:
    if not chains:
        return True
    lines = shapely.MultiLineString([c.points for c in chains])
    return bool(shapely.is_simple(lines))


# ---------------------------------------------------------------------------- rings
def label_rings(chains: list[Chain], inside) -> list[np.ndarray]:
    """Closed rings of the chains with an ``inside`` label (a predicate on labels) on one
    side and not the other, oriented with the inside on the left (counter-clockwise around
    an inside region, clockwise around a hole)."""
    pieces = {}
    for c in chains:
        li, ri = inside(c.left), inside(c.right)
        if li == ri:
            continue
        if li:
            pieces.setdefault(c.start, []).append((c.points, c.end))
        else:
            pieces.setdefault(c.end, []).append((c.points[::-1], c.start))
    rings = []
    while pieces:
        s = next(iter(pieces))
        parts, v = [], s
        while True:
            lst = pieces.get(v)
            if not lst:
                raise GeometryError("the traced boundary does not close (an internal "
                                    "inconsistency of the image tracing)")
            pts, nxt = lst.pop()
            if not lst:
                del pieces[v]
            parts.append(pts[:-1])
            v = nxt
            if v == s:
                break
        rings.append(np.vstack(parts))
    return rings


def _area(ring: np.ndarray) -> float:
    x, y = ring[:, 0], ring[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def pixel_to_xy(points: np.ndarray, origin, spacing) -> np.ndarray:
    """Traced points (pixel corner units, ``(0.5, 0.5)`` the first pixel's centre) to
    ``x, y`` given the first pixel centre ``origin`` and the pixel ``spacing``."""
    o, s = np.asarray(origin, float), np.asarray(spacing, float)
    return o + (points - 0.5) * s


def ring_polygons(rings: list[np.ndarray]) -> list[shapely.Polygon]:
    """Exterior (counter-clockwise) rings with their holes (clockwise rings inside them)."""
    ext = [r for r in rings if _area(r) > 0]
    holes = [r for r in rings if _area(r) < 0]
    polys = [shapely.Polygon(r) for r in ext]
    owned: list[list] = [[] for _ in ext]
    for h in holes:
        pt = shapely.Polygon(h).representative_point()
        cand = [k for k, pg in enumerate(polys) if pg.contains(pt)]
        if cand:
            k = min(cand, key=lambda k: polys[k].area)
            owned[k].append(h)
    return [shapely.Polygon(r, o) for r, o in zip(ext, owned)]


# ---------------------------------------------------------------------------- domains
def largest_component(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """The largest edge-connected (4-connected) region of non-zero pixels, and how many
    other regions were dropped."""
    from scipy import ndimage

    lab, n = ndimage.label(np.asarray(mask) != 0)
    if n == 0:
        return np.zeros(np.shape(mask), bool), 0
    sizes = np.bincount(lab.ravel())[1:]
    return lab == 1 + int(np.argmax(sizes)), n - 1


def _segments(points: np.ndarray, name: str) -> tuple[Segment, ...]:
    return tuple(Segment(tuple(a), tuple(b), name) for a, b in zip(points[:-1], points[1:]))


def _loop(ring: np.ndarray, name: str) -> Loop:
    closed = np.vstack([ring, ring[:1]])
    return Loop(_segments(closed, name), name)


def _domain_from(chains: list[Chain], origin, spacing, interfaces: bool,
                 where: str) -> tuple[Domain, list[Chain]]:
    rings = label_rings(chains, lambda lab: lab != OUTSIDE)
    if not rings:
        raise GeometryError(f"{where}: the mask has no non-zero pixels")
    outer = [r for r in rings if _area(r) > 0]
    if len(outer) != 1:  # the caller keeps one component
        raise GeometryError(f"{where}: the mask has {len(outer)} separate regions")
    holes = [r for r in rings if _area(r) < 0]
    xy = [pixel_to_xy(r, origin, spacing) for r in [outer[0]] + holes]
    paths = []
    inner = [c for c in chains if c.left != OUTSIDE and c.right != OUTSIDE]
    if interfaces:
        for k, c in enumerate(inner):
            name = f"discontinuity[{k}]"
            paths.append(Path(_segments(pixel_to_xy(c.points, origin, spacing), name), name))
    try:
        dom = make_domain(_loop(xy[0], "outer"),
                          tuple(_loop(h, f"hole[{k}]") for k, h in enumerate(xy[1:])),
                          tuple(paths), where=where)
    except GeometryError as exc:
        raise GeometryError(f"{where}: the traced boundary is not a valid domain: "
                            f"{exc}") from None
    return dom, inner


def mask_domain(mask: np.ndarray, origin, spacing, *, tol: float = DEFAULT_TOL,
                where: str = "mask") -> Domain:
    """The domain of the non-zero pixels of ``mask`` (its largest edge-connected region),
    holes where it is zero, boundaries traced and simplified to ``tol`` pixels."""
    keep, dropped = largest_component(mask)
    if not keep.any():
        raise GeometryError(f"{where}: the mask has no non-zero pixels")
    if dropped:
        log.warning("%s: %d separate regions of the mask dropped (the domain is its largest "
                    "connected region)", where, dropped)
    lab = np.where(keep, 1, OUTSIDE)
    chains = simplify_chains(trace_labels(lab), tol)
    return _domain_from(chains, origin, spacing, False, where)[0]


def label_domain(labels: np.ndarray, origin, spacing, *, tol: float = DEFAULT_TOL,
                 where: str = "labels"):
    """The domain of the pixels not labelled :data:`OUTSIDE` (the largest edge-connected
    region of them), with every boundary between two labels an interface
    ``discontinuity[k]``.

    Returns ``(domain, chains, labels)``: the simplified chains in pixel-corner coordinates
    and the labels with the dropped regions set to :data:`OUTSIDE` (for
    :func:`region_lookup`)."""
    lab = np.asarray(labels, np.int64)
    keep, dropped = largest_component(lab != OUTSIDE)
    if not keep.any():
        raise GeometryError(f"{where}: no pixel lies inside the domain")
    if dropped:
        log.warning("%s: %d separate regions dropped (the domain is the largest connected "
                    "region)", where, dropped)
    lab = np.where(keep, lab, OUTSIDE)
    chains = simplify_chains(trace_labels(lab), tol)
    dom, _ = _domain_from(chains, origin, spacing, True, where)
    return dom, chains, lab


def extent_domain(lower, upper) -> Domain:
    """The rectangle ``lower`` - ``upper`` (an image's extent), counter-clockwise."""
    (x0, y0), (x1, y1) = lower, upper
    pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    return make_domain(Loop.polygon(pts, "outer"))


def label_chains(labels: np.ndarray, tol: float = DEFAULT_TOL) -> list[Chain]:
    """The simplified chains of a label image covering its whole extent."""
    return simplify_chains(trace_labels(labels), tol)


def region_lookup(chains: list[Chain], labels: np.ndarray, phases: dict, origin, spacing,
                  tol: float = DEFAULT_TOL):
    """``region(points) -> (N,) int``: the phase of each point, from the polygons the
    (simplified) ``chains`` bound, so the phases agree exactly with the traced curves.

    ``phases`` maps a label to its phase index; ``tol`` is the simplification tolerance
    the chains were made with (pixels). A point whose neighbourhood of pixels (within
    ``tol + 1.5`` pixels) holds one label gets it directly (the traced curves stay within
    ``tol + 0.36`` pixels of the pixel edges); the others are tested against the
    polygons. Points outside every polygon (outside the domain) get the phase of the
    nearest pixel, or 0.
    """
    from scipy import ndimage

    lab = np.asarray(labels, np.int64)
    idx = np.full(lab.shape, -1, np.int64)
    for label, k in phases.items():
        idx[lab == label] = k
    size = 2 * int(np.ceil(tol + 1.0)) + 1
    mixed = ndimage.maximum_filter(idx, size, mode="nearest") != \
        ndimage.minimum_filter(idx, size, mode="nearest")
    polys = {}
    for label, k in phases.items():
        pg = ring_polygons([pixel_to_xy(r, origin, spacing) for r in label_rings(
            chains, lambda lab_, L=label: lab_ == L)])
        geom = shapely.MultiPolygon(pg) if pg else shapely.MultiPolygon()
        shapely.prepare(geom)
        polys[k] = geom
    o, s = np.asarray(origin, float), np.asarray(spacing, float)
    ny, nx = lab.shape

    def region(points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, float)
        ij = np.floor((p - o) / s + 0.5).astype(np.int64)
        i = np.clip(ij[:, 0], 0, nx - 1)
        j = np.clip(ij[:, 1], 0, ny - 1)
        out = idx[j, i].copy()
        exact = np.flatnonzero(mixed[j, i] | (out < 0))
        if len(exact):
            q = p[exact]
            res = np.full(len(exact), -1, np.int64)
            for k, geom in polys.items():
                left = res < 0
                if not left.any():
                    break
                hit = shapely.contains_xy(geom, q[left, 0], q[left, 1])
                res[np.flatnonzero(left)[hit]] = k
            for k, geom in polys.items():  # on a curve: the first phase touching it
                left = res < 0
                if not left.any():
                    break
                hit = shapely.intersects_xy(geom, q[left, 0], q[left, 1])
                res[np.flatnonzero(left)[hit]] = k
            res = np.where(res < 0, np.maximum(out[exact], 0), res)
            out[exact] = res
        return out

    return region
