"""The triangle mesh: a small immutable dataclass (scikit-fem's ``Mesh`` is the model).

Conventions: points ``(N, 2)`` float64, triangles ``(M, 3)`` int32 counter-clockwise (the
layout of meshio, scipy and matplotlib; scikit-fem's transposed ``(2, N)`` / ``(3, M)`` only
where it is called), ``regions`` ``(M,)`` int32, constrained edges ``(K, 2)`` int32 with
``edge_markers`` ``(K,)``.
Transformations return new objects; derived topology is computed on first use and cached.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Mapping

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .errors import MeshDataError
from .metrics import triangle_areas2

__all__ = ["Mesh", "edge_keys", "edge_order", "any_corner", "points_near", "component_labels"]


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


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Mesh:
    """A conforming triangulation with optional per-point and per-cell data.

    Parameters
    ----------
    points : (N, 2) array of float
    triangles : (M, 3) array of int; re-oriented counter-clockwise on construction.
    regions : (M,) array of int, optional
        Region (subdomain) id of every triangle; zeros by default.
    edges : (K, 2) array of int, optional
        Boundary and interface edges, exported as line cells.
    edge_markers : (K,) array of int, optional
        The marker (curve id + 1) of every edge in ``edges``.
    point_data, cell_data : mapping of name to array
        Exported alongside the mesh (composition, delta, quality, ...).
    marker_names : mapping of marker to name
        Names of the edge markers (curve names), exported where the format allows; markers
        sharing a name are exported as one group.
    named_points : mapping of name to node index
        Named nodes (supports, probes), exported as node sets / physical points.

    Examples
    --------
    >>> m = Mesh([[0, 0], [1, 0], [0, 1]], [[0, 2, 1]])
    >>> m.triangles.tolist()   # re-oriented counter-clockwise
    [[0, 1, 2]]
    """

    points: np.ndarray
    triangles: np.ndarray
    regions: np.ndarray | None = None
    edges: np.ndarray | None = None
    edge_markers: np.ndarray | None = None
    point_data: Mapping[str, np.ndarray] = field(default_factory=dict)
    cell_data: Mapping[str, np.ndarray] = field(default_factory=dict)
    marker_names: Mapping[int, str] = field(default_factory=dict)
    named_points: Mapping[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=np.float64)
        t = np.asarray(self.triangles)
        if p.ndim != 2 or p.shape[1] != 2:
            raise MeshDataError(f"points must have shape (N, 2), got {p.shape}")
        if t.size == 0:
            t = t.reshape(0, 3)
        if t.ndim != 2 or t.shape[1] != 3:
            raise MeshDataError(f"triangles must have shape (M, 3), got {t.shape}")
        t = t.astype(np.int32)
        if t.size and (t.min() < 0 or t.max() >= len(p)):
            raise MeshDataError(f"triangles index points outside 0..{len(p) - 1}")
        # counter-clockwise orientation
        a = triangle_areas2(p, t)
        if np.any(a < 0):
            t = t.copy()
            flip = a < 0
            t[flip, 1], t[flip, 2] = t[flip, 2].copy(), t[flip, 1].copy()
        reg = np.zeros(len(t), np.int32) if self.regions is None else np.asarray(self.regions, np.int32)
        if reg.shape != (len(t),):
            raise MeshDataError(f"len(triangles) = {len(t)}, but regions has shape {reg.shape}")
        e = np.zeros((0, 2), np.int32) if self.edges is None else np.asarray(self.edges, np.int32).reshape(-1, 2)
        em = np.ones(len(e), np.int32) if self.edge_markers is None else np.asarray(self.edge_markers, np.int32)
        if em.shape != (len(e),):
            raise MeshDataError(f"len(edges) = {len(e)}, but edge_markers has shape {em.shape}")
        pd = {}
        for k, v in dict(self.point_data).items():
            v = np.asarray(v)
            if len(v) != len(p):
                raise MeshDataError(f"len(points) = {len(p)}, but len(point_data[{k!r}]) = {len(v)}")
            pd[k] = _frozen(v)
        cd = {}
        for k, v in dict(self.cell_data).items():
            v = np.asarray(v)
            if len(v) != len(t):
                raise MeshDataError(f"len(triangles) = {len(t)}, but len(cell_data[{k!r}]) = {len(v)}")
            cd[k] = _frozen(v)
        set_ = object.__setattr__
        set_(self, "points", _frozen(p))
        set_(self, "triangles", _frozen(t))
        set_(self, "regions", _frozen(reg))
        set_(self, "edges", _frozen(e))
        set_(self, "edge_markers", _frozen(em))
        set_(self, "point_data", pd)
        set_(self, "cell_data", cd)
        set_(self, "marker_names", {int(k): str(v) for k, v in dict(self.marker_names).items()})
        named = {str(k): int(v) for k, v in dict(self.named_points).items()}
        if any(not 0 <= v < len(p) for v in named.values()):
            raise MeshDataError(f"named_points index points outside 0..{len(p) - 1}")
        set_(self, "named_points", named)

    # -- sizes -------------------------------------------------------------
    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_elements(self) -> int:
        return len(self.triangles)

    # -- derived, cached ---------------------------------------------------
    @cached_property
    def areas(self) -> np.ndarray:
        """Area of every triangle, shape (M,)."""
        return 0.5 * triangle_areas2(self.points, self.triangles)

    @cached_property
    def area(self) -> float:
        return float(self.areas.sum())

    @cached_property
    def edge_table(self) -> tuple[np.ndarray, np.ndarray]:
        """``(keys (3M,), owner (3M,))``: the edge key (:func:`edge_keys`) of every side of
        every triangle, sorted, and the triangle it belongs to. Interior edges appear twice in
        a row. The one sort that edge queries on this mesh share."""
        t = self.triangles
        keys = edge_keys(np.concatenate([t[:, 0], t[:, 1], t[:, 2]]),
                         np.concatenate([t[:, 1], t[:, 2], t[:, 0]]))
        order = edge_order(keys)
        return keys[order], np.tile(np.arange(len(t)), 3)[order]

    @cached_property
    def unique_edges(self) -> tuple[np.ndarray, np.ndarray]:
        """``(edges (E, 2) sorted, count (E,))``: every edge and how many triangles hold it."""
        keys, _ = self.edge_table
        new = np.r_[True, keys[1:] != keys[:-1]]
        k = keys[new]
        c = np.diff(np.r_[np.flatnonzero(new), len(keys)])
        u = np.column_stack([k >> 32, k & 0xFFFFFFFF]).astype(np.int32)
        return u, c

    def has_edges(self, edges: np.ndarray) -> np.ndarray:
        """Whether each of ``edges (K, 2)`` is an edge of the mesh, ``(K,)`` bool."""
        keys, _ = self.edge_table
        q = edge_keys(edges[:, 0], edges[:, 1])
        pos = np.minimum(np.searchsorted(keys, q), max(len(keys) - 1, 0))
        return keys[pos] == q if len(keys) else np.zeros(len(q), bool)

    def pieces(self, cut_edges: np.ndarray) -> np.ndarray:
        """Pieces of the mesh separated by ``cut_edges``: an id ``(M,)`` per triangle.

        Two triangles are in one piece when a chain of shared edges, none of them in
        ``cut_edges``, joins them; with the interface edges as cuts these are the regions
        between closed interfaces, exactly as meshed. Ids follow each piece's first triangle.
        """
        keys, owner = self.edge_table
        pair = np.flatnonzero(keys[1:] == keys[:-1])  # interior edges: two owners in a row
        cut = np.isin(keys[pair], edge_keys(cut_edges[:, 0], cut_edges[:, 1]))
        pair = pair[~cut]
        return component_labels(len(self.triangles), owner[pair],
                                owner[pair + 1]).astype(np.int32)

    @cached_property
    def boundary_edges(self) -> np.ndarray:
        """Edges that belong to exactly one triangle, shape (B, 2)."""
        u, c = self.unique_edges
        return u[c == 1]

    # -- transformations ---------------------------------------------------
    def with_data(self, point_data: Mapping | None = None, cell_data: Mapping | None = None) -> "Mesh":
        """A copy with point/cell data added (or replaced)."""
        pd = dict(self.point_data)
        pd.update(point_data or {})
        cd = dict(self.cell_data)
        cd.update(cell_data or {})
        return dataclasses.replace(self, point_data=pd, cell_data=cd)

    def with_regions(self, regions: np.ndarray) -> "Mesh":
        return dataclasses.replace(self, regions=regions)

    # -- checks ------------------------------------------------------------
    def problems(self, *, rel_tol: float = 1e-12) -> list[str]:
        """Everything that makes this not a valid conforming triangulation (empty if valid).

        Checks: no degenerate or inverted triangles, no repeated or unused points, every edge
        held by one or two triangles, and boundary edges forming closed loops (each boundary
        vertex in exactly two boundary edges, so no hanging node and no pinched fan).

        A triangle is degenerate when its area is at most ``rel_tol`` times the square of the
        mesh's extent: that of the points the triangles use, so a stray unused point far
        away (itself reported) does not make every triangle degenerate.

        >>> Mesh([[0, 0], [1, 0], [0, 1], [-7e13, -6543]], [[0, 1, 2]]).problems()
        ['1 point is not used by any triangle']
        """
        out: list[str] = []
        p, t = self.points, self.triangles
        if len(t) == 0:
            return ["the mesh has no triangles"]
        used = np.zeros(len(p), bool)
        used[t.ravel()] = True
        pu = p[used]
        finite = np.isfinite(pu[:, 0]) & np.isfinite(pu[:, 1])
        extent = np.ptp(pu[finite], axis=0).max() if finite.any() else 0.0
        scale = max(float(extent), 1e-300)
        a = self.areas
        bad = np.flatnonzero(~(a > rel_tol * scale * scale))  # nan areas too
        if bad.size:
            out.append(f"{bad.size} degenerate or inverted triangles (first #{bad[0]})")
        if np.any(~np.isfinite(p)):
            out.append("non-finite point coordinates")
        if not used.all():
            n = int((~used).sum())
            out.append(f"{n} point{' is' if n == 1 else 's are'} not used by any triangle")
        if _has_repeats(p):
            out.append("repeated points")
        u, c = self.unique_edges
        if np.any(c > 2):
            out.append(f"{int((c > 2).sum())} edges are shared by more than two triangles (overlap)")
        be = u[c == 1]
        deg = np.bincount(be.ravel(), minlength=len(p))
        if np.any((deg != 0) & (deg != 2)):
            out.append("the boundary is not a set of simple closed loops (hanging node or pinched vertex)")
        return out

    def is_valid(self) -> bool:
        return not self.problems()

    # -- output ------------------------------------------------------------
    def write(self, path: str | Path, **kwargs) -> Path:
        """Write the mesh; the format follows the extension (see :func:`hetmesh.io.export.write_mesh`)."""
        from .io.export import write_mesh

        return write_mesh(self, path, **kwargs)



def _has_repeats(p: np.ndarray) -> bool:
    """Whether two rows of ``p (N, 2)`` are equal: points sharing an x coordinate (few)
    are compared in full."""
    if len(p) < 2:
        return False
    order = np.argsort(p[:, 0])
    x = p[order, 0]
    tie = np.flatnonzero(x[1:] == x[:-1])
    if len(tie) == 0:
        return False
    q = p[np.unique(np.concatenate([order[tie], order[tie + 1]]))]
    qs = q[np.lexsort((q[:, 1], q[:, 0]))]
    return bool(np.any(np.all(qs[1:] == qs[:-1], axis=1)))
