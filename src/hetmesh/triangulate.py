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

from .errors import MeshingError
from .mesh import any_corner, component_labels, edge_keys
from .metrics import triangle_areas2

__all__ = ["constrained_delaunay"]

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
        keep = (v >= SUPER).all(axis=1)
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
    ckeys = np.unique(edge_keys(edges[:, 0].astype(np.int64) + SUPER,
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
    """Flood the triangle adjacency graph without crossing boundary edges; keep the inside pieces."""
    m = len(tris)
    # the kernel's neighbour k lies across the edge (v_k, v_k+1)
    src = np.repeat(np.arange(m), 3)
    k = np.tile(np.arange(3), m)
    dst = nbr.ravel()
    ok = (dst >= 0) & (dst < m)
    src, k, dst = src[ok], k[ok], dst[ok]
    keys = edge_keys(tris[src, k], tris[src, (k + 1) % 3])
    bkeys = np.unique(edge_keys(boundary_edges[:, 0], boundary_edges[:, 1]))
    pos = np.minimum(np.searchsorted(bkeys, keys), len(bkeys) - 1)
    cut = bkeys[pos] == keys if len(bkeys) else np.zeros(len(keys), bool)
    label = component_labels(m, src[~cut], dst[~cut])
    # one representative triangle per piece: its largest. Boundary nodes sit on their curves
    # up to rounding, so a straight boundary can bulge outwards by 1e-16 and the kernel then
    # fills the bulge with slivers of zero area, whose centroids lie on the boundary and
    # test inside or outside by chance; a piece of (numerically) zero area is such a bulge
    # and never inside
    area = 0.5 * np.abs(triangle_areas2(pts, tris))
    n = int(label.max()) + 1
    total = np.bincount(label, area, minlength=n)
    order = np.lexsort((-area, label))
    first = order[np.searchsorted(label[order], np.arange(n))]
    comp_inside = np.asarray(inside(pts[tris[first]].mean(axis=1)), dtype=bool)
    comp_inside &= total > 1e-12 * area.sum()
    return comp_inside[label]
