"""The mesh, in 2D and 3D: a small immutable dataclass (scikit-fem's ``Mesh`` is the model).

Conventions: points ``(N, d)`` float64 with d = 2 or 3, cells ``(M, d + 1)`` int32 --
triangles counter-clockwise, tetrahedra of positive volume (the layout of meshio, scipy and
matplotlib; scikit-fem's transposed ``(d, N)`` / ``(d + 1, M)`` only where it is called),
``regions`` ``(M,)`` int32, constrained facets ``(K, d)`` int32 (edges in 2D, triangles in
3D) with ``facet_markers`` ``(K,)``.
Transformations return new objects; derived topology is computed on first use and cached.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from .errors import MeshDataError
from .metrics import tet_volumes6, triangle_areas2
from .topology import any_corner, component_labels, edge_keys, edge_order, points_near, unique

__all__ = ["Mesh", "CELL_TYPES", "cell_faces", "face_table", "simplex_measures", "edge_keys",
           "edge_order", "any_corner", "points_near", "component_labels"]


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


#: the names of the cells and facets of a mesh of each dimension (meshio's cell types)
CELL_TYPES = {2: ("triangle", "line"), 3: ("tetra", "triangle")}


def cell_faces(cells: np.ndarray) -> np.ndarray:
    """The ``d + 1`` faces of every simplex in ``cells (M, d + 1)``: ``(d + 1, M, d)``, face
    ``k`` the one opposite vertex ``k``, its vertices in the cell's cyclic order (the sides
    ``(1, 2), (2, 0), (0, 1)`` of a triangle; for a positively oriented tetrahedron, faces
    whose order gives the outward normal by the right-hand rule).

    >>> cell_faces(np.array([[0, 1, 2]]))[:, 0].tolist()
    [[1, 2], [2, 0], [0, 1]]
    """
    if cells.shape[1] == 3:
        return np.stack([cells[:, [1, 2]], cells[:, [2, 0]], cells[:, [0, 1]]])
    return np.stack([cells[:, [1, 2, 3]], cells[:, [0, 3, 2]],
                     cells[:, [0, 1, 3]], cells[:, [0, 2, 1]]])


def face_table(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(order, first, count)`` of the faces ``(F, k)`` (rows of vertex ids in any order):
    ``faces[order]`` groups equal faces together (sorted by their sorted vertex ids),
    ``first`` the start of every group in that order and ``count`` its size. Faces of
    vertex ids below 2**21 are sorted as one int64 key each (a few times faster than rows).

    >>> order, first, count = face_table(np.array([[2, 1, 0], [0, 1, 2], [1, 2, 3]]))
    >>> count.tolist()
    [2, 1]
    """
    key = np.sort(faces, axis=1).astype(np.int64)
    n = int(key.max()) + 1 if key.size else 1
    if n ** key.shape[1] < 2 ** 62:
        packed = key[:, 0]
        for j in range(1, key.shape[1]):
            packed = packed * n + key[:, j]
        order = np.argsort(packed, kind="stable")
        k = packed[order]
        new = np.r_[True, k[1:] != k[:-1]] if len(k) else np.zeros(0, bool)
    else:
        order = np.lexsort(key.T[::-1])
        k = key[order]
        new = np.r_[True, np.any(k[1:] != k[:-1], axis=1)] if len(k) else np.zeros(0, bool)
    first = np.flatnonzero(new)
    return order, first, np.diff(np.r_[first, len(k)])


@dataclass(frozen=True, eq=False)
class Mesh:
    """A conforming simplicial mesh (triangles in 2D, tetrahedra in 3D) with optional
    per-point and per-cell data.

    The dimension is that of the points: ``points (N, d)`` and ``cells (M, d + 1)``, with
    ``d`` 2 or 3. The 2D names stay as aliases: :attr:`triangles` (the cells),
    :attr:`edges` and :attr:`edge_markers` (the facets and their markers).

    Parameters
    ----------
    points : (N, d) array of float
    cells : (M, d + 1) array of int; re-oriented on construction (counter-clockwise
        triangles, tetrahedra of positive volume).
    regions : (M,) array of int, optional
        Region (subdomain) id of every cell; zeros by default.
    facets : (K, d) array of int, optional
        Boundary and interface facets (edges in 2D, triangles in 3D), exported as facet
        cells.
    facet_markers : (K,) array of int, optional
        The marker (curve or surface id + 1) of every facet.
    point_data, cell_data : mapping of name to array
        Exported alongside the mesh (composition, delta, quality, ...).
    marker_names : mapping of marker to name
        Names of the facet markers (curve or surface names), exported where the format
        allows; markers sharing a name are exported as one group.
    named_points : mapping of name to node index
        Named nodes (supports, probes), exported as node sets / physical points.

    Examples
    --------
    >>> m = Mesh([[0, 0], [1, 0], [0, 1]], [[0, 2, 1]])
    >>> m.triangles.tolist(), m.dim   # re-oriented counter-clockwise
    ([[0, 1, 2]], 2)
    >>> t = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1, 3]])
    >>> t.cells.tolist(), t.dim, round(t.measure, 12)   # positive volume
    ([[0, 1, 2, 3]], 3, 0.166666666667)
    """

    points: np.ndarray
    cells: np.ndarray
    regions: np.ndarray | None = None
    facets: np.ndarray | None = None
    facet_markers: np.ndarray | None = None
    point_data: Mapping[str, np.ndarray] = field(default_factory=dict)
    cell_data: Mapping[str, np.ndarray] = field(default_factory=dict)
    marker_names: Mapping[int, str] = field(default_factory=dict)
    named_points: Mapping[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] not in (2, 3):
            raise MeshDataError(f"points must have shape (N, 2) or (N, 3), got {p.shape}")
        d = p.shape[1]
        t = np.asarray(self.cells)
        if t.size == 0:
            t = t.reshape(0, d + 1)
        if t.ndim != 2 or t.shape[1] != d + 1:
            raise MeshDataError(f"cells of {d}D points must have shape (M, {d + 1}), got {t.shape}")
        t = t.astype(np.int32)
        if t.size and (t.min() < 0 or t.max() >= len(p)):
            raise MeshDataError(f"cells index points outside 0..{len(p) - 1}")
        t = _oriented(p, t)
        reg = (np.zeros(len(t), np.int32) if self.regions is None
               else np.asarray(self.regions, np.int32))
        if reg.shape != (len(t),):
            raise MeshDataError(f"len(cells) = {len(t)}, but regions has shape {reg.shape}")
        e = (np.zeros((0, d), np.int32) if self.facets is None
             else np.asarray(self.facets, np.int32).reshape(-1, d))
        em = (np.ones(len(e), np.int32) if self.facet_markers is None
              else np.asarray(self.facet_markers, np.int32))
        if em.shape != (len(e),):
            raise MeshDataError(f"len(facets) = {len(e)}, but facet_markers has shape {em.shape}")
        pd = {}
        for k, v in dict(self.point_data).items():
            v = np.asarray(v)
            if len(v) != len(p):
                raise MeshDataError(f"len(points) = {len(p)}, but "
                                    f"len(point_data[{k!r}]) = {len(v)}")
            pd[k] = _frozen(v)
        cd = {}
        for k, v in dict(self.cell_data).items():
            v = np.asarray(v)
            if len(v) != len(t):
                raise MeshDataError(f"len(cells) = {len(t)}, but len(cell_data[{k!r}]) = {len(v)}")
            cd[k] = _frozen(v)
        set_ = object.__setattr__
        set_(self, "points", _frozen(p))
        set_(self, "cells", _frozen(t))
        set_(self, "regions", _frozen(reg))
        set_(self, "facets", _frozen(e))
        set_(self, "facet_markers", _frozen(em))
        set_(self, "point_data", pd)
        set_(self, "cell_data", cd)
        set_(self, "marker_names", {int(k): str(v) for k, v in dict(self.marker_names).items()})
        named = {str(k): int(v) for k, v in dict(self.named_points).items()}
        if any(not 0 <= v < len(p) for v in named.values()):
            raise MeshDataError(f"named_points index points outside 0..{len(p) - 1}")
        set_(self, "named_points", named)

    # -- sizes -------------------------------------------------------------
    @property
    def dim(self) -> int:
        """The dimension of the points, 2 or 3."""
        return int(self.points.shape[1])

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_elements(self) -> int:
        return len(self.cells)

    @property
    def cell_type(self) -> str:
        """meshio's name of the cells: ``"triangle"`` or ``"tetra"``."""
        return CELL_TYPES[self.dim][0]

    @property
    def facet_type(self) -> str:
        """meshio's name of the facets: ``"line"`` or ``"triangle"``."""
        return CELL_TYPES[self.dim][1]

    # -- the 2D names --------------------------------------------------------
    @property
    def triangles(self) -> np.ndarray:
        """The cells of a 2D mesh (the 2D name of :attr:`cells`)."""
        return self.cells

    @property
    def edges(self) -> np.ndarray:
        """The facets of a 2D mesh (the 2D name of :attr:`facets`)."""
        return self.facets

    @property
    def edge_markers(self) -> np.ndarray:
        """The facet markers (the 2D name of :attr:`facet_markers`)."""
        return self.facet_markers

    # -- derived, cached ---------------------------------------------------
    @cached_property
    def measures(self) -> np.ndarray:
        """Area (2D) or volume (3D) of every cell, shape (M,)."""
        return simplex_measures(self.points, self.cells)

    @property
    def areas(self) -> np.ndarray:
        """Area of every triangle (the 2D name of :attr:`measures`)."""
        return self.measures

    @cached_property
    def measure(self) -> float:
        """The total area (2D) or volume (3D)."""
        return float(self.measures.sum())

    @property
    def area(self) -> float:
        """The total area (the 2D name of :attr:`measure`)."""
        return self.measure

    @cached_property
    def edge_table(self) -> tuple[np.ndarray, np.ndarray]:
        """``(keys (3M,), owner (3M,))`` of a 2D mesh: the edge key (:func:`edge_keys`) of
        every side of every triangle, sorted, and the triangle it belongs to. Interior edges
        appear twice in a row. The one sort that edge queries on this mesh share."""
        self._require_2d("edge_table")
        t = self.cells
        keys = edge_keys(np.concatenate([t[:, 0], t[:, 1], t[:, 2]]),
                         np.concatenate([t[:, 1], t[:, 2], t[:, 0]]))
        order = edge_order(keys)
        return keys[order], np.tile(np.arange(len(t)), 3)[order]

    @cached_property
    def unique_edges(self) -> tuple[np.ndarray, np.ndarray]:
        """``(edges (E, 2) sorted, count (E,))`` of a 2D mesh: every edge and how many
        triangles hold it."""
        keys, _ = self.edge_table
        new = np.r_[True, keys[1:] != keys[:-1]]
        k = keys[new]
        c = np.diff(np.r_[np.flatnonzero(new), len(keys)])
        u = np.column_stack([k >> 32, k & 0xFFFFFFFF]).astype(np.int32)
        return u, c

    @cached_property
    def unique_faces(self) -> tuple[np.ndarray, np.ndarray]:
        """``(faces (F, d), count (F,))``: every face of the cells (edges in 2D, triangles in
        3D), its vertices in the order of its first cell, and how many cells hold it."""
        if self.dim == 2:
            return self.unique_edges
        faces = cell_faces(self.cells).reshape(-1, 3)
        order, first, count = face_table(faces)
        return faces[order[first]], count

    def has_edges(self, edges: np.ndarray) -> np.ndarray:
        """Whether each of ``edges (K, 2)`` is an edge of the 2D mesh, ``(K,)`` bool."""
        keys, _ = self.edge_table
        q = edge_keys(edges[:, 0], edges[:, 1])
        pos = np.minimum(np.searchsorted(keys, q), max(len(keys) - 1, 0))
        return keys[pos] == q if len(keys) else np.zeros(len(q), bool)

    def pieces(self, cut_edges: np.ndarray) -> np.ndarray:
        """Pieces of the 2D mesh separated by ``cut_edges``: an id ``(M,)`` per triangle.

        Two triangles are in one piece when a chain of shared edges, none of them in
        ``cut_edges``, joins them; with the interface edges as cuts these are the regions
        between closed interfaces, exactly as meshed. Ids follow each piece's first triangle.
        """
        keys, owner = self.edge_table
        pair = np.flatnonzero(keys[1:] == keys[:-1])  # interior edges: two owners in a row
        cut = np.isin(keys[pair], edge_keys(cut_edges[:, 0], cut_edges[:, 1]))
        pair = pair[~cut]
        return component_labels(len(self.cells), owner[pair],
                                owner[pair + 1]).astype(np.int32)

    @cached_property
    def boundary_facets(self) -> np.ndarray:
        """Faces that belong to exactly one cell, shape (B, d): in 2D each edge as
        ``(low id, high id)``, in 3D each triangle as in its tetrahedron (outward normal by
        the right-hand rule)."""
        u, c = self.unique_faces
        return u[c == 1]

    @property
    def boundary_edges(self) -> np.ndarray:
        """Edges that belong to exactly one triangle, shape (B, 2) (2D)."""
        self._require_2d("boundary_edges")
        return self.boundary_facets

    def _require_2d(self, what: str) -> None:
        if self.dim != 2:
            raise MeshDataError(f"Mesh.{what} is defined for 2D meshes; this mesh is {self.dim}D")

    # -- transformations ---------------------------------------------------
    def with_data(self, point_data: Mapping | None = None,
                  cell_data: Mapping | None = None) -> Mesh:
        """A copy with point/cell data added (or replaced)."""
        pd = dict(self.point_data)
        pd.update(point_data or {})
        cd = dict(self.cell_data)
        cd.update(cell_data or {})
        return dataclasses.replace(self, point_data=pd, cell_data=cd)

    def with_regions(self, regions: np.ndarray) -> Mesh:
        return dataclasses.replace(self, regions=regions)

    # -- checks ------------------------------------------------------------
    def problems(self, *, rel_tol: float = 1e-12) -> list[str]:
        """Everything that makes this not a valid conforming mesh (empty if valid).

        Checks: no degenerate or inverted cells, no repeated or unused points, every face
        held by one or two cells, and a closed boundary: in 2D each boundary vertex in
        exactly two boundary edges (no hanging node, no pinched fan), in 3D each edge of the
        boundary surface in exactly two boundary triangles.

        A cell is degenerate when its measure is at most ``rel_tol`` times the mesh's extent
        to the power d: the extent of the points the cells use, so a stray unused point far
        away (itself reported) does not make every cell degenerate.

        >>> Mesh([[0, 0], [1, 0], [0, 1], [-7e13, -6543]], [[0, 1, 2]]).problems()
        ['1 point is not used by any triangle']
        """
        out: list[str] = []
        p, t, d = self.points, self.cells, self.dim
        what = CELL_TYPES[d][0].replace("tetra", "tetrahedra").replace("triangle", "triangles")
        one = what[:-1] if d == 2 else "tetrahedron"
        if len(t) == 0:
            return [f"the mesh has no {what}"]
        used = np.zeros(len(p), bool)
        used[t.ravel()] = True
        pu = p[used]
        finite = np.isfinite(pu).all(axis=1)
        extent = np.ptp(pu[finite], axis=0).max() if finite.any() else 0.0
        scale = max(float(extent), 1e-300)
        a = self.measures
        bad = np.flatnonzero(~(a > rel_tol * scale ** d))  # nan measures too
        if bad.size:
            out.append(f"{bad.size} degenerate or inverted {what} (first #{bad[0]})")
        if np.any(~np.isfinite(p)):
            out.append("non-finite point coordinates")
        if not used.all():
            n = int((~used).sum())
            out.append(f"{n} point{' is' if n == 1 else 's are'} not used by any {one}")
        if _has_repeats(p):
            out.append("repeated points")
        u, c = self.unique_faces
        if np.any(c > 2):
            side = "edges" if d == 2 else "faces"
            out.append(f"{int((c > 2).sum())} {side} are shared by more than two {what} (overlap)")
        be = u[c == 1]
        if d == 2:
            deg = np.bincount(be.ravel(), minlength=len(p))
            if np.any((deg != 0) & (deg != 2)):
                out.append("the boundary is not a set of simple closed loops (hanging node "
                           "or pinched vertex)")
        elif len(be):
            _, _, n_held = face_table(cell_faces(be).reshape(-1, 2))
            if np.any(n_held != 2):
                out.append("the boundary is not a closed surface (an edge of it is held by "
                           "one or more than two boundary triangles)")
        return out

    def is_valid(self) -> bool:
        return not self.problems()

    # -- output ------------------------------------------------------------
    def write(self, path: str | Path, **kwargs) -> Path:
        """Write the mesh; the format follows the extension (see
        :func:`hetmesh.io.export.write_mesh`)."""
        from .io.export import write_mesh

        return write_mesh(self, path, **kwargs)


def simplex_measures(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Signed area (2D) or volume (3D) of every simplex, ``(M,)``: positive for
    counter-clockwise triangles and for tetrahedra whose first three vertices turn
    counter-clockwise seen from the fourth's opposite side."""
    if points.shape[1] == 2:
        return 0.5 * triangle_areas2(points, cells)
    return tet_volumes6(points, cells) / 6.0


def _oriented(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``t`` with every negatively oriented cell's vertices 1 and 2 swapped."""
    a = triangle_areas2(p, t) if p.shape[1] == 2 else tet_volumes6(p, t)
    if np.any(a < 0):
        t = t.copy()
        flip = a < 0
        t[flip, 1], t[flip, 2] = t[flip, 2].copy(), t[flip, 1].copy()
    return t


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
    q = p[unique(np.concatenate([order[tie], order[tie + 1]]))]
    qs = q[np.lexsort((q[:, 1], q[:, 0]))]
    return bool(np.any(np.all(qs[1:] == qs[:-1], axis=1)))
