"""A size field from the geometry: elements grow gradually away from small boundary features.

The material sets the element size h = delta' / |grad f| (Eqs. 4, 7), capped at ``h_max``.
The geometry sets a second bound. A curved boundary or interface is sampled finer than the
material asks for wherever its chords must stay within the chord tolerance (a sagitta
s = L^2 / (8 R) <= tol allows chords of L = sqrt(8 R tol)), and so is a short polygon edge. A
placement sized by the material alone then puts elements of size ``h_max`` next to boundary
edges several times shorter, and the ring of elements along such a curve is badly shaped
(q 0.7-0.85 where the interior has 0.95+). A geometric mesher (Gmsh's ``MeshSizeFromPoints``
and its size extension from the boundary, CGAL's ``edge_size`` with a gradation) grades from
the boundary instead.

:class:`BoundarySize` is that bound: every PSLG vertex ``b_i`` sampled with the material-free
size ``h_max`` carries the length ``h_i`` of its shorter adjacent edge, and

    h_geo(x) = min_i ( h_i + GRADE * |x - b_i| ),

a cone per vertex, so h_geo grows by at most ``GRADE`` per unit length (Lipschitz). Only the
vertices with ``h_i`` clearly below ``h_max`` take part; a domain without small features
(straight edges of length at least ``h_max``) has none, and its placements are unchanged.
The minimum is taken over the ``K`` nearest such vertices (a KD-tree), which is exact
wherever the nearest features are the smallest, and never below the true minimum.

The placements use ``min(h_max, h_geo(x))`` wherever they used ``h_max``
(:meth:`hetmesh.tri.workset.Context.h_at`). It bounds sizes, never delta: the delta-driven
refinement still has the last word.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["BoundarySize", "boundary_size", "GRADE"]

#: growth of the geometric size per unit distance from the boundary (Gmsh's default
#: ``MeshSizeExtendFromBoundary`` front grows by about this much; 0.3-0.5 is usual)
GRADE = 0.35
#: vertices with ``h_i`` below this fraction of ``h_max`` take part
ACTIVE = 0.9
#: nearest vertices searched per query point
K = 8


class BoundarySize:
    """``h_geo(x) = min_i (h_i + grade |x - b_i|)`` over the active boundary vertices."""

    def __init__(self, vertices: np.ndarray, sizes: np.ndarray, h_max: float,
                 grade: float = GRADE):
        self.vertices = np.asarray(vertices, float)
        self.sizes = np.asarray(sizes, float)
        self.h_max = float(h_max)
        self.grade = float(grade)
        self._tree = cKDTree(self.vertices)
        self._k = min(K, len(self.vertices))
        # beyond this distance every cone is above h_max
        self._reach = (self.h_max - float(self.sizes.min())) / self.grade

    def __call__(self, pts: np.ndarray) -> np.ndarray:
        """``min(h_max, h_geo)`` at ``pts`` ``(N, 2)``."""
        pts = np.asarray(pts, float)
        d, i = self._tree.query(pts, k=self._k, distance_upper_bound=self._reach)
        if self._k == 1:
            d, i = d[:, None], i[:, None]
        hit = np.isfinite(d)
        h = np.where(hit, self.sizes[np.minimum(i, len(self.sizes) - 1)] + self.grade * d,
                     np.inf)
        return np.minimum(h.min(axis=1), self.h_max)


def vertex_sizes(vertices: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Length of every vertex's shortest adjacent edge ``(N,)`` (inf for isolated vertices)."""
    lengths = np.hypot(*(vertices[edges[:, 0]] - vertices[edges[:, 1]]).T)
    h = np.full(len(vertices), np.inf)
    np.minimum.at(h, edges[:, 0], lengths)
    np.minimum.at(h, edges[:, 1], lengths)
    return h


def boundary_size(vertices: np.ndarray, edges: np.ndarray, h_max: float,
                  grade: float = GRADE) -> BoundarySize | None:
    """The geometric size bound of a PSLG sampled at the material-free size ``h_max``, or
    None when no vertex has an adjacent edge shorter than ``ACTIVE * h_max``.

    >>> v = np.array([[0, 0], [1, 0], [1, 0.05], [0, 0.05]], float)
    >>> e = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    >>> bs = boundary_size(v, e, h_max=1.0)
    >>> bs(np.array([[1.0, 0.0], [0.5, 0.5]])).round(3)   # 0.05 + GRADE x distance
    array([0.05 , 0.285])
    """
    h = vertex_sizes(vertices, edges)
    keep = h < ACTIVE * h_max
    if not keep.any():
        return None
    return BoundarySize(vertices[keep], h[keep], h_max, grade)
