"""The one wrapper around the constrained Delaunay kernel (pythoncdt).

Everything else in hetmesh sees plain arrays: ``points (N, 2)``, constraint ``edges (E, 2)``
in, counter-clockwise ``triangles (M, 3)`` out.
"""

from __future__ import annotations

import logging

import numpy as np
import pythoncdt as cdt

from .errors import MeshingError
from .mesh import component_labels, edge_keys
from .metrics import signed_area2

__all__ = ["constrained_delaunay"]

log = logging.getLogger(__name__)


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
    # without interfaces, the kernel's own even-odd depth flood is exact (outer loop + holes)
    parity = inside is not None and (be is None or len(be) == len(e))
    try:
        t.insert_vertices(pts)
        if len(e):
            t.insert_edges(e)
        if parity:
            t.erase_outer_triangles_and_holes()
        else:
            t.erase_super_triangle()
    except Exception as exc:  # the kernel reports duplicate points or crossing constraints
        raise MeshingError(f"constrained Delaunay triangulation failed: {exc}") from exc
    if t.vertices_count() != len(pts):
        raise MeshingError("constrained Delaunay triangulation added or dropped vertices "
                           f"({t.vertices_count()} != {len(pts)}): crossing constraint edges?")
    tri = t.triangles_array()
    tris = tri["vertices"].astype(np.int32)
    # the kernel returns counter-clockwise triangles (checked in tests/test_triangulate.py)
    if inside is None or parity or len(tris) == 0:
        return np.ascontiguousarray(tris)
    nbr = tri["neighbors"].astype(np.int64)
    keep = _inside_components(pts, tris, nbr, e if be is None else be, inside)
    return np.ascontiguousarray(tris[keep])


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
    area = 0.5 * np.abs(signed_area2(pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]))
    n = int(label.max()) + 1
    total = np.bincount(label, area, minlength=n)
    order = np.lexsort((-area, label))
    first = order[np.searchsorted(label[order], np.arange(n))]
    comp_inside = np.asarray(inside(pts[tris[first]].mean(axis=1)), dtype=bool)
    comp_inside &= total > 1e-12 * area.sum()
    return comp_inside[label]
