"""The one wrapper around the constrained Delaunay kernel (pythoncdt).

Everything else in hetmesh sees plain arrays: ``points (N, 2)``, constraint ``edges (E, 2)``
in, counter-clockwise ``triangles (M, 3)`` out.

The kernel triangulates inside a super triangle of three extra vertices (ids 0-2 of its own
arrays, the points following at 3..N+2). Its own clean-up passes (``erase_super_triangle``,
``erase_outer_triangles_and_holes``) flood and compact all M triangles; here they are done on
the kernel's raw arrays instead: a triangle survives when it keeps no super vertex and, for a
domain without interfaces, lies at odd depth (inside the outer loop, outside every hole),
found from the few triangles that touch a boundary vertex (:func:`_odd_depth`). The kept
triangles come out in the kernel's order, so the result is the kernel's, bit for bit, at a
fraction of the cost (0.03 s instead of 0.2 s for a million triangles).
"""

from __future__ import annotations

import logging

import numpy as np
import pythoncdt as cdt
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, shortest_path
from scipy.spatial import cKDTree

from ..errors import MeshingError
from ..mesh import any_corner, component_labels, edge_keys, points_near
from ..metrics import triangle_areas2
from ..topology import unique

__all__ = ["constrained_delaunay", "patch"]

log = logging.getLogger(__name__)

#: the kernel's vertices before the points: the super triangle's
SUPER = 3


def constrained_delaunay(points: np.ndarray, edges: np.ndarray, inside=None,
                         boundary_edges: np.ndarray | None = None) -> np.ndarray:
    """Constrained Delaunay triangulation of ``points`` honouring ``edges``.

    Parameters
    ----------
    points : (N, 2) float array, no duplicates.
    edges : (E, 2) int array of constraint edges (boundary, holes and interfaces); they must
        not cross each other.
    inside : callable ``(K, 2) -> (K,) bool``, optional
        Tells which connected pieces of the triangulation (separated by ``boundary_edges``)
        lie inside the domain. Without it the convex hull is returned.
    boundary_edges : (B, 2) int array, optional
        The constraint edges that separate inside from outside (outer loop and holes; not
        interfaces). Defaults to ``edges``.

    Returns
    -------
    (M, 3) int32 triangles, counter-clockwise, indexing ``points``.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    e = np.ascontiguousarray(edges, dtype=np.uintc).reshape(-1, 2)
    t = cdt.Triangulation(cdt.VertexInsertionOrder.AUTO,
                          cdt.IntersectingConstraintEdges.NOT_ALLOWED, 0.0)
    be = None if boundary_edges is None else np.asarray(boundary_edges).reshape(-1, 2)
    # without interfaces, inside is the odd depth (outer loop + holes), as the kernel floods
    parity = inside is not None and (be is None or len(be) == len(e))
    try:
        t.insert_vertices(pts)
        if len(e):
            t.insert_edges(e)
    except Exception as exc:  # the kernel reports duplicate points or crossing constraints
        raise MeshingError(f"constrained Delaunay triangulation failed: {exc}") from exc
    if t.vertices_count() != len(pts) + SUPER:
        raise MeshingError("constrained Delaunay triangulation added or dropped vertices "
                           f"({t.vertices_count() - SUPER} != {len(pts)}): crossing "
                           "constraint edges?")
    raw = t.triangles_array(copy=False)
    v = raw["vertices"]
    nbr = raw["neighbors"]
    keep = None
    if parity:
        keep = _odd_depth(v, nbr, e, len(pts))
        if keep is None:  # not a nesting of closed loops: the kernel's own flood decides
            log.debug("depth flood inconsistent: erase_outer_triangles_and_holes")
            t.erase_outer_triangles_and_holes()
            return np.ascontiguousarray(t.triangles_array()["vertices"].astype(np.int32))
    else:
        keep = (v[:, 0] >= SUPER) & (v[:, 1] >= SUPER) & (v[:, 2] >= SUPER)
    # the kernel returns counter-clockwise triangles (checked in tests/test_triangulate.py)
    tris = (v[keep] - SUPER).astype(np.int32)
    if inside is None or parity or len(tris) == 0:
        return np.ascontiguousarray(tris)
    # the kernel's neighbours, renumbered to the kept triangles (-1: none or dropped)
    new = np.cumsum(keep) - 1
    valid = nbr < len(keep)
    nb = np.where(valid, new[np.minimum(nbr, len(keep) - 1)], -1)
    nb[valid] = np.where(keep[nbr[valid]], nb[valid], -1)
    inner = _inside_components(pts, tris, nb[keep], e if be is None else be, inside)
    return np.ascontiguousarray(tris[inner])


def _odd_depth(v: np.ndarray, nbr: np.ndarray, edges: np.ndarray, n: int) -> np.ndarray | None:
    """The kernel's triangles at odd depth (mask), or None where depth parity is ambiguous.

    ``v``, ``nbr`` are the kernel's raw vertex and neighbour arrays (super vertices 0-2,
    neighbour k across the edge (v_k, v_k+1), 2**32 - 1 for none), ``edges`` the constraint
    edges (all of them boundary: outer loop and holes), ``n`` the number of points.

    The depth of a triangle is the number of constraint edges crossed on the way from the
    super triangle. A triangle with no boundary vertex (nor super vertex) has no constraint
    edge among its sides, so it has the depth of its neighbours; all of them are taken as one
    region R, and only the triangles touching a boundary vertex (a thin band along the
    curves, plus the super triangle's fan) are flooded: pieces joined across non-constraint
    sides (and through R), then the parity of every piece by breadth-first search across
    the constraint sides from the super triangle's piece. Every constraint side must then
    join opposite parities; if not (R is not one region at one depth), None.
    """
    m = len(v)
    onb = np.zeros(n + SUPER, bool)
    onb[:SUPER] = True
    onb[edges.ravel().astype(np.int64) + SUPER] = True
    band = np.flatnonzero(any_corner(onb, v))
    nb_ = len(band)
    # the band's sides: constraint or not, and the neighbour (band id, R = nb_, none = -1)
    bv = v[band].astype(np.int64)
    bn = nbr[band].astype(np.int64)
    pos = np.full(m, nb_, np.int64)  # triangles off the band are R
    pos[band] = np.arange(nb_)
    ckeys = unique(edge_keys(edges[:, 0].astype(np.int64) + SUPER,
                                edges[:, 1].astype(np.int64) + SUPER))
    src, dst, cons = [], [], []
    for k in range(3):
        a, b = bv[:, k], bv[:, (k + 1) % 3]
        has = bn[:, k] < m
        kk = edge_keys(a, b)
        p = np.minimum(np.searchsorted(ckeys, kk), max(len(ckeys) - 1, 0))
        c = (ckeys[p] == kk) if len(ckeys) else np.zeros(nb_, bool)
        src.append(np.flatnonzero(has))
        dst.append(pos[bn[has, k]])
        cons.append(c[has])
    src, dst, cons = np.concatenate(src), np.concatenate(dst), np.concatenate(cons)
    # pieces of the band (+ R) joined across non-constraint sides
    free = ~cons
    g = coo_matrix((np.ones(int(free.sum())), (src[free], dst[free])), shape=(nb_ + 1, nb_ + 1))
    npc, piece = connected_components(g, directed=False)
    # parity across the constraint sides, from the super triangle's piece
    ps, pd = piece[src[cons]], piece[dst[cons]]
    if (ps == pd).any():
        return None
    start = piece[np.flatnonzero((bv < SUPER).any(axis=1))[:1]]
    if len(start) == 0:
        return None
    pg = coo_matrix((np.ones(len(ps)), (ps, pd)), shape=(npc, npc))
    dist = shortest_path(pg, directed=False, unweighted=True, indices=int(start[0]))
    reach = np.isfinite(dist)
    if not reach[piece[:nb_]].all():
        return None
    odd = np.zeros(npc, bool)
    odd[reach] = dist[reach] % 2 == 1
    if (odd[ps] == odd[pd]).any():
        return None
    keep = np.full(m, odd[piece[nb_]])  # R (unreachable only if it holds no triangle)
    keep[band] = odd[piece[:nb_]]
    return keep


def _inside_components(pts, tris, nbr, boundary_edges, inside) -> np.ndarray:
    """Flood the triangle adjacency graph without crossing boundary edges; keep the inside
    pieces (mask over ``tris``; ``nbr`` the neighbour across side k, -1 for none).

    Every piece is classified by ``inside`` at the centroid of its largest triangle (the
    first of equal ones). Boundary nodes sit on their curves up to rounding, so a straight
    boundary can bulge outwards by 1e-16 and the kernel then fills the bulge with slivers
    of zero area, whose centroids lie on the boundary and test inside or outside by chance;
    a piece of (numerically) zero area is such a bulge and never inside.

    As for the depth flood (:func:`_odd_depth`), only the triangles touching a boundary
    vertex are flooded, the others taken as one region; the result stands if every
    boundary edge then has exactly one kept side (none outside the hull), else the whole
    graph is flooded (:func:`inside_full_flood`).
    """
    area = 0.5 * np.abs(triangle_areas2(pts, tris))
    keep = inside_band_flood(pts, tris, nbr, boundary_edges, inside, area)
    if keep is None:
        keep = inside_full_flood(pts, tris, nbr, boundary_edges, inside, area)
    return keep


def _cut_keys(boundary_edges) -> np.ndarray:
    return unique(edge_keys(boundary_edges[:, 0], boundary_edges[:, 1]))


def _classify(pts, tris, label, n, area, inside) -> np.ndarray:
    """Whether each of the ``n`` pieces (``label`` per triangle) is inside: ``inside`` at
    the centroid of its largest triangle (the first of equal ones), and a piece of
    positive area."""
    total = np.bincount(label, area, minlength=n)
    big = np.full(n, -np.inf)
    np.maximum.at(big, label, area)
    top = np.flatnonzero(area == big[label])
    first = np.full(n, len(tris), np.int64)
    np.minimum.at(first, label[top], top)
    if (first == len(tris)).any():  # nan areas: sort (nan last), as before
        order = np.lexsort((-area, label))
        first = order[np.searchsorted(label[order], np.arange(n))]
    comp_inside = np.asarray(inside(pts[tris[first]].mean(axis=1)), dtype=bool)
    comp_inside &= total > 1e-12 * area.sum()
    return comp_inside


def inside_full_flood(pts, tris, nbr, boundary_edges, inside, area) -> np.ndarray:
    """:func:`_inside_components` over the whole adjacency graph."""
    m = len(tris)
    # the kernel's neighbour k lies across the edge (v_k, v_k+1)
    src = np.repeat(np.arange(m), 3)
    k = np.tile(np.arange(3), m)
    dst = nbr.ravel()
    ok = (dst >= 0) & (dst < m)
    src, k, dst = src[ok], k[ok], dst[ok]
    keys = edge_keys(tris[src, k], tris[src, (k + 1) % 3])
    bkeys = _cut_keys(boundary_edges)
    pos = np.minimum(np.searchsorted(bkeys, keys), len(bkeys) - 1)
    cut = bkeys[pos] == keys if len(bkeys) else np.zeros(len(keys), bool)
    label = component_labels(m, src[~cut], dst[~cut])
    return _classify(pts, tris, label, int(label.max()) + 1, area, inside)[label]


def inside_band_flood(pts, tris, nbr, boundary_edges, inside, area) -> np.ndarray | None:
    """:func:`_inside_components` flooding only the triangles that touch a boundary vertex
    (the others one region R, joined to the band through their shared sides); None if some
    boundary edge does not then have exactly one kept side."""
    m = len(tris)
    onb = np.zeros(len(pts), bool)
    onb[boundary_edges.ravel()] = True
    band = np.flatnonzero(any_corner(onb, tris))
    nb_ = len(band)
    if nb_ == 0 or nb_ == m:
        return None
    pos = np.full(m, nb_, np.int64)  # triangles off the band are R
    pos[band] = np.arange(nb_)
    bt = tris[band].astype(np.int64)
    bn = nbr[band].astype(np.int64)
    bkeys = _cut_keys(boundary_edges)
    src, dst, cut, side = [], [], [], []
    for k in range(3):
        has = bn[:, k] >= 0
        kk = edge_keys(bt[:, k], bt[:, (k + 1) % 3])
        p = np.minimum(np.searchsorted(bkeys, kk), max(len(bkeys) - 1, 0))
        c = (bkeys[p] == kk) if len(bkeys) else np.zeros(nb_, bool)
        src.append(np.flatnonzero(has))
        dst.append(pos[bn[has, k]])
        cut.append(c[has])
        side.append(np.flatnonzero(c & ~has))  # boundary edges on the hull
    src, dst, cut = np.concatenate(src), np.concatenate(dst), np.concatenate(cut)
    hull = np.concatenate(side)
    free = ~cut
    g = coo_matrix((np.ones(int(free.sum())), (src[free], dst[free])), shape=(nb_ + 1, nb_ + 1))
    npc, piece = connected_components(g, directed=False)
    label = np.full(m, piece[nb_], np.int64)
    label[band] = piece[:nb_]
    comp_inside = _classify(pts, tris, label, npc, area, inside)
    kept = comp_inside[piece]
    # every boundary edge: one kept side (the inside), the other dropped or outside the hull
    if (kept[src[cut]] == kept[dst[cut]]).any() or not kept[hull].all():
        return None
    return comp_inside[label]


# --------------------------------------------------------------------------- local updates
#: at most this share of the points changed (moved, added, ends of changed constraint
#: edges) for :func:`patch` to rebuild a window instead of the whole triangulation
PATCH_SHARE = 1e-2
#: rings of triangles around the changes in the first window; grown by one per retry
PATCH_RINGS = 2
PATCH_TRIES = 4


def patch(points: np.ndarray, edges: np.ndarray, boundary: np.ndarray, prev_points: np.ndarray,
          prev_edges: np.ndarray, prev_tris: np.ndarray):
    """The constrained Delaunay triangulation of ``points`` and ``edges`` by updating
    ``prev_tris``, that of ``prev_points`` and ``prev_edges``, in a window around what
    changed: ``(triangles, kept)``, the triangles being ``prev_tris[kept]`` (unchanged, in
    order) followed by the window's; None where a full rebuild is the way (too much
    changed, or the window does not close up).

    ``points`` extends ``prev_points`` (the first rows may have moved), ``edges`` extends
    ``prev_edges`` (rows may have been replaced, as when an edge is split); ``boundary``
    marks the current edges that bound the domain (outer loop and holes). Every point must
    lie inside the domain or on its boundary.

    The window R is the triangles touching a moved point, an end of a removed or added
    constraint edge, or the nearest old point of a new one (a Delaunay neighbour of it once
    inserted), grown by :data:`PATCH_RINGS` rings. Its points and the new ones are
    triangulated by the kernel with R's outline as constraints (a domain edge that was
    split replaced by its pieces) plus the constraint edges inside, and the triangles
    inside the outline (odd depth) replace R's. Accepted when the new triangles' outline is
    exactly R's, they use every window point, and every outline edge that is not a
    constraint is locally Delaunay with the triangle outside (then the whole triangulation
    is: edges away from R did not change); else R grows by a ring and the window is redone.

    The triangle set is the kernel's full rebuild's (up to the choice among cocircular
    points); the order differs (R's triangles out, the window's appended).
    """
    n0, n = len(prev_points), len(points)
    k0 = len(prev_edges)
    if n < n0 or len(edges) < k0 or len(prev_tris) == 0:
        return None
    same = prev_points == points[:n0]
    moved = np.flatnonzero(~(same[:, 0] & same[:, 1]))
    new = np.arange(n0, n)
    cur = edges[:k0]
    erow = np.flatnonzero((prev_edges[:, 0] != cur[:, 0]) | (prev_edges[:, 1] != cur[:, 1]))
    removed = prev_edges[erow]
    arow = np.r_[erow, np.arange(k0, len(edges))]
    added = edges[arow]
    touched = np.zeros(n, bool)
    touched[moved] = True
    touched[removed.ravel()] = True
    touched[added.ravel()] = True
    touched[new] = False
    if len(new):
        near = _nearest_index(prev_points, points[new])
        if near is None:
            return None
        touched[near] = True
    if int(touched.sum()) + len(new) > max(64.0, PATCH_SHARE * n):
        return None
    if not touched.any():
        return (prev_tris, np.arange(len(prev_tris))) if not len(new) else None
    inr = any_corner(touched, prev_tris)
    for _ in range(PATCH_RINGS):
        inr = _grow(prev_tris, inr, n0)
    ekeys = edge_keys(edges[:, 0], edges[:, 1])
    rkeys = edge_keys(removed[:, 0], removed[:, 1])
    akeys = edge_keys(added[:, 0], added[:, 1])
    for _ in range(PATCH_TRIES):
        out = _window(points, prev_tris, inr, new, ekeys, rkeys, akeys, boundary[arow])
        if out is not None:
            return out
        inr = _grow(prev_tris, inr, n0)
    return None


def _grow(tris: np.ndarray, inr: np.ndarray, n: int) -> np.ndarray:
    """The triangles ``inr`` (mask) and those sharing a corner with them (``n`` points)."""
    v = np.zeros(n, bool)
    v[tris[inr].ravel()] = True
    return any_corner(v, tris)


def _nearest_index(points: np.ndarray, query: np.ndarray) -> np.ndarray | None:
    """The nearest of ``points`` to every query (ids), from a few screened points: the
    screening reach starts at a 256th of the points' extent and doubles until every query
    has a point within it."""
    ext = float(np.ptp(points, axis=0).max()) if len(points) else 0.0
    reach = ext / 256.0
    for _ in range(12):
        if not reach > 0:
            return None
        sel = points_near(points, query, reach)
        if len(sel):
            d, j = cKDTree(points[sel]).query(query)
            if (d <= reach).all():
                return sel[j]
        reach *= 2.0
    return None


def _window(points, tris, inr, new, ekeys, rkeys, akeys, aboundary) -> np.ndarray | None:
    """One try of :func:`patch` with the window ``inr`` (mask over ``tris``)."""
    rt = tris[inr].astype(np.int64)
    wv = unique(np.concatenate([rt.ravel(), new]))
    # R's edges: inner ones twice, its outline once
    ha = rt[:, [0, 1, 2]].ravel()
    hb = rt[:, [1, 2, 0]].ravel()
    hk = edge_keys(ha, hb)
    uk, cnt = unique(hk, return_counts=True)
    outline = uk[cnt == 1]
    # the outline after the changes: removed domain edges out, their pieces in
    loop = np.union1d(np.setdiff1d(outline, rkeys), akeys[aboundary])
    # constraints: the outline and the current constraint edges among R's edges or added
    inner = ekeys[np.isin(ekeys, uk) | np.isin(ekeys, akeys)]
    cons = np.union1d(loop, inner)
    lo, hi = cons >> 32, cons & 0xFFFFFFFF
    if not (np.isin(lo, wv).all() and np.isin(hi, wv).all()):
        return None
    loc = lambda g: np.searchsorted(wv, g)  # noqa: E731
    e = np.column_stack([loc(lo), loc(hi)]).astype(np.uintc)
    le = np.column_stack([loc(loop >> 32), loc(loop & 0xFFFFFFFF)])
    pts = np.ascontiguousarray(points[wv], dtype=np.float64)
    t = cdt.Triangulation(cdt.VertexInsertionOrder.AUTO,
                          cdt.IntersectingConstraintEdges.NOT_ALLOWED, 0.0)
    try:
        t.insert_vertices(pts)
        t.insert_edges(e)
    except Exception:  # crossing constraints: the window does not fit the changes
        return None
    if t.vertices_count() != len(pts) + SUPER:
        return None
    raw = t.triangles_array()
    keep = _odd_depth(raw["vertices"], raw["neighbors"], le, len(pts))
    if keep is None:
        return None
    wt = raw["vertices"][keep].astype(np.int64) - SUPER
    if len(unique(wt)) != len(wv):  # a window point left out
        return None
    g = wv[wt]
    gk = edge_keys(g[:, [0, 1, 2]].ravel(), g[:, [1, 2, 0]].ravel())
    guk, gcnt = unique(gk, return_counts=True)
    if not np.array_equal(guk[gcnt == 1], loop) or (gcnt > 2).any():
        return None
    if not _outline_delaunay(points, tris, inr, g, loop, ekeys):
        return None
    kept = np.flatnonzero(~inr)
    return np.concatenate([tris[kept], g.astype(tris.dtype)]), kept


def _outline_delaunay(points, tris, inr, g, loop, ekeys) -> bool:
    """Whether every outline edge of the window that is not a constraint is locally
    Delaunay: the corner of the outside triangle across it is not strictly inside the
    circumcircle of the window triangle on it (up to rounding)."""
    free = np.setdiff1d(loop, ekeys)
    if len(free) == 0:
        return True
    # the window triangle on each free outline edge, and its opposite corner
    wa, wb, wc = (g[:, [0, 1, 2]].ravel(), g[:, [1, 2, 0]].ravel(), g[:, [2, 0, 1]].ravel())
    wk = edge_keys(wa, wb)
    iw = np.flatnonzero(np.isin(wk, free))
    # the outside triangles touching the outline
    v = np.zeros(len(points), bool)
    v[(free >> 32)] = True
    v[(free & 0xFFFFFFFF)] = True
    ot = tris[any_corner(v, tris) & ~inr].astype(np.int64)
    oa, ob, oc = (ot[:, [0, 1, 2]].ravel(), ot[:, [1, 2, 0]].ravel(), ot[:, [2, 0, 1]].ravel())
    ok_ = edge_keys(oa, ob)
    io = np.flatnonzero(np.isin(ok_, free))
    if len(io) != len(free) or len(iw) != len(free):
        return False
    iw = iw[np.argsort(wk[iw])]
    io = io[np.argsort(ok_[io])]
    p = points
    return bool(np.all(_incircle(p[wa[iw]], p[wb[iw]], p[wc[iw]], p[oc[io]]) <= 0))


def _incircle(a, b, c, d) -> np.ndarray:
    """Positive where ``d`` is strictly inside the circumcircle of the counter-clockwise
    triangles ``(a, b, c)`` beyond rounding; 0 for (near) cocircular points."""
    adx, ady = a[:, 0] - d[:, 0], a[:, 1] - d[:, 1]
    bdx, bdy = b[:, 0] - d[:, 0], b[:, 1] - d[:, 1]
    cdx, cdy = c[:, 0] - d[:, 0], c[:, 1] - d[:, 1]
    al, bl, cl = adx * adx + ady * ady, bdx * bdx + bdy * bdy, cdx * cdx + cdy * cdy
    det = (al * (bdx * cdy - cdx * bdy) + bl * (cdx * ady - adx * cdy)
           + cl * (adx * bdy - bdx * ady))
    perm = (al * (np.abs(bdx * cdy) + np.abs(cdx * bdy)) + bl * (np.abs(cdx * ady)
            + np.abs(adx * cdy)) + cl * (np.abs(adx * bdy) + np.abs(bdx * ady)))
    return np.where(np.abs(det) > 1e-12 * perm, det, 0.0)
