"""Array helpers for the topology of simplicial meshes: edge keys, their sort, components,
a grid screen for points near a few queries. Plain arrays in, plain arrays out; used by
:class:`hetmesh.mesh.Mesh`, the kernels and the writers.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["unique", "edge_keys", "edge_order", "any_corner", "index_columns", "points_near",
           "component_labels", "drop_unused", "SCREEN_CELLS"]


def edge_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One int64 per undirected edge (a, b): the smaller id in the high 32 bits.

    The one edge encoding of the package: sort, unique and membership tests on edges become
    1-D integer operations. Vertex ids must be below 2**31.
    """
    lo = np.minimum(a, b).astype(np.int64)
    hi = np.maximum(a, b).astype(np.int64)
    return (lo << 32) | hi


def index_columns(cells: np.ndarray) -> tuple[np.ndarray, ...]:
    """The columns of ``cells (M, k)`` as contiguous ``intp`` arrays, one per corner.

    numpy gathers with an index array of its own integer type directly; a column of int32
    cells (strided, of another type) is converted at every gather, so code that gathers
    several arrays at a corner converts it once here (about 40 % less time for the x and
    y coordinates of a million triangles' corners)."""
    return tuple(cells[:, k].astype(np.intp) for k in range(cells.shape[1]))


def any_corner(mask: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Triangles ``(M,)`` with a corner in the point ``mask``: ``mask[triangles].any(axis=1)``
    by two elementwise ors of the gathered corners (a reduction over the short axis costs
    several times more), gathered in one pass over the flat cells."""
    g = np.take(mask, triangles.ravel()).reshape(triangles.shape)
    return g[:, 0] | g[:, 1] | g[:, 2]


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
    _, first, inv = unique(label, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inv]


def drop_unused(points: np.ndarray, cells: np.ndarray, *index_arrays, point_data=()):
    """The points that ``cells`` uses, with ``cells`` and every array of ``index_arrays``
    (boundary faces, say) renumbered to them and every array of ``point_data`` (one row
    per point) kept alike: ``(points, cells, *index_arrays, *point_data, used)``, ``used``
    the indices kept (all of them where every point is used: then nothing is copied).

    >>> p, c, used = drop_unused(np.zeros((4, 2)), np.array([[0, 2, 3]]))
    >>> len(p), c.tolist(), used.tolist()
    (3, [[0, 1, 2]], [0, 2, 3])
    """
    used = unique(cells)
    if len(used) == len(points):
        return (points, cells, *index_arrays, *point_data, used)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return (points[used], remap[cells], *(remap[a] for a in index_arrays),
            *(d[used] for d in point_data), used)


def unique(a, return_index: bool = False, return_inverse: bool = False,
           return_counts: bool = False, axis: int | None = None):
    """:func:`numpy.unique` (same results, same shapes) by sorting, for integer and boolean
    arrays flat or by rows (``axis=0`` of a 2-D array); anything else goes to numpy.

    Recent NumPy (2.4.6 here) finds the unique values of an integer array by hashing; on this
    project's arrays (edge and node keys) that is 20-80 x slower than sorting: 3.6 s against
    0.05 s for three million int64 keys (numpy 2.4.6), which made the 2D pipeline 2-3 x
    slower on a million elements.

    >>> unique(np.array([3, 1, 3, 2]), return_index=True, return_inverse=True,
    ...        return_counts=True)
    (array([1, 2, 3]), array([1, 3, 0]), array([2, 0, 2, 1]), array([1, 1, 2]))
    >>> unique(np.array([[1, 2], [1, 2], [0, 5]]), axis=0)
    array([[0, 5],
           [1, 2]])
    """
    a = np.asarray(a)
    rows = axis == 0 and a.ndim == 2
    if a.dtype.kind not in "iub" or not (axis is None or rows):
        return np.unique(a, return_index=return_index, return_inverse=return_inverse,
                         return_counts=return_counts, axis=axis)
    if rows:
        order = np.lexsort(a.T[::-1]) if a.shape[1] else np.arange(len(a))  # stable
        s = a[order]
        new = np.ones(len(s), bool)
        if len(s) > 1:
            new[1:] = (s[1:] != s[:-1]).any(axis=1)
        shape = (len(a),)
    else:
        flat = a.ravel()
        if return_index or return_inverse:
            # the first occurrences need a stable sort; the inverse and the counts do not
            # depend on the order among equal values (and introsort is faster)
            order = np.argsort(flat, kind="stable" if return_index else None)
            s = flat[order]
        else:
            order, s = None, np.sort(flat)
        new = np.ones(len(s), bool)
        if len(s) > 1:
            np.not_equal(s[1:], s[:-1], out=new[1:])
        shape = a.shape
    out = [s[new]]
    if return_index:
        out.append(order[new])
    if return_inverse:
        inv = np.empty(len(s), np.intp)
        inv[order] = np.cumsum(new) - 1
        out.append(inv.reshape(shape))
    if return_counts:
        out.append(np.diff(np.r_[np.flatnonzero(new), len(s)]))
    return out[0] if len(out) == 1 else tuple(out)
