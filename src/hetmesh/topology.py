"""Array helpers for the topology of simplicial meshes: edge keys, their sort, components,
a grid screen for points near a few queries. Plain arrays in, plain arrays out; used by
:class:`hetmesh.mesh.Mesh`, the kernels and the writers.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["edge_keys", "edge_order", "any_corner", "points_near", "component_labels",
           "SCREEN_CELLS"]


def edge_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One int64 per undirected edge (a, b): the smaller id in the high 32 bits.

    The one edge encoding of the package: sort, unique and membership tests on edges become
    1-D integer operations. Vertex ids must be below 2**31.
    """
    lo = np.minimum(a, b).astype(np.int64)
    hi = np.maximum(a, b).astype(np.int64)
    return (lo << 32) | hi


def any_corner(mask: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Triangles ``(M,)`` with a corner in the point ``mask``: ``mask[triangles].any(axis=1)``
    by two elementwise ors (a reduction over the short axis costs several times more)."""
    return mask[triangles[:, 0]] | mask[triangles[:, 1]] | mask[triangles[:, 2]]


#: cells per side of the grid of :func:`points_near`
SCREEN_CELLS = 2048


def points_near(points: np.ndarray, query: np.ndarray, reach: float) -> np.ndarray:
    """Ids of a subset of ``points`` that holds every point within ``reach`` of a query.

    A grid of at most :data:`SCREEN_CELLS` square cells per side over the queries' box, its
    cells no smaller than ``reach``, marks the cells next to each query; the points in
    marked cells are returned (a few queries among many points: one pass over the points
    instead of a k-d tree of all of them).
    """
    lo = query.min(axis=0) - reach
    hi = query.max(axis=0) + reach
    cell = max(1.001 * float(reach), float((hi - lo).max()) / SCREEN_CELLS, 1e-300)
    shape = np.minimum(np.ceil((hi - lo) / cell).astype(np.int64) + 1, SCREEN_CELLS + 2)
    mark = np.zeros((shape[0] + 2, shape[1] + 2), bool)
    qc = np.floor((query - lo) / cell).astype(np.int64) + 1
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            mark[np.clip(qc[:, 0] + dx, 0, shape[0] + 1),
                 np.clip(qc[:, 1] + dy, 0, shape[1] + 1)] = True
    # the grid's box first (four comparisons per point), then the cells of the points in it
    top = lo + (shape + 1) * cell
    x, y = points[:, 0], points[:, 1]
    box = np.flatnonzero((x >= lo[0]) & (x <= top[0]) & (y >= lo[1]) & (y <= top[1]))
    pc = np.floor((points[box] - lo) / cell)
    inb = (pc[:, 0] >= 0) & (pc[:, 0] < shape[0]) & (pc[:, 1] >= 0) & (pc[:, 1] < shape[1])
    sel = np.flatnonzero(inb)
    return box[sel[mark[pc[sel, 0].astype(np.int64) + 1, pc[sel, 1].astype(np.int64) + 1]]]


def edge_order(keys: np.ndarray) -> np.ndarray:
    """``np.argsort(keys, kind="stable")`` for edge keys that repeat at most twice (the
    sides of a triangulation: an interior edge is held by two triangles).

    numpy's default sort is two to three times faster than its stable one on int64; the
    only ties are pairs, put back in index order afterwards. Keys repeated more often (an
    overlap) take the stable sort itself.
    """
    order = np.argsort(keys)
    k = keys[order]
    same = np.flatnonzero(k[1:] == k[:-1])
    if len(same) == 0:
        return order
    if len(same) > 1 and (np.diff(same) == 1).any():
        return np.argsort(keys, kind="stable")
    a, b = order[same], order[same + 1]
    swap = a > b
    order[same[swap]] = b[swap]
    order[same[swap] + 1] = a[swap]
    return order


def component_labels(m: int, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Connected-component label of each of ``m`` triangles joined by the (src, dst) pairs,
    numbered in the order of each component's first triangle."""
    g = coo_matrix((np.ones(len(src)), (src, dst)), shape=(m, m))
    _, label = connected_components(g, directed=False)
    _, first, inv = np.unique(label, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inv]
