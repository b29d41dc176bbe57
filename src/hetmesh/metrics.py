"""Element quality and material variation: Eqs. (1) and (14)-(18) of the paper, in 2D and 3D.

All functions work on whole arrays: ``points (N, d)`` and simplices ``(M, d + 1)``
(triangles, tetrahedra). The material variation delta(T) (Eqs. 14-15) and its dense sampling
are the same in every dimension; the quality is Eq. (17) for triangles and the radius ratio
``3 r_in / R_circ`` (1 for the regular tetrahedron) for tetrahedra, where the angle of the
statistics is the smallest dihedral angle.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .material.field import thread_safe
from .parallel import block_concat, block_map
from .topology import index_columns

__all__ = [
    "quality",
    "min_angle",
    "tet_volumes6",
    "tet_quality",
    "dihedral_angles",
    "quality_and_angle",
    "triangle_angles",
    "signed_area2",
    "triangle_areas2",
    "delta_vertices",
    "delta_dense",
    "lattice_barycentric",
    "MeshStats",
    "statistics",
    "side_lengths",
    "circumcircles",
    "circumcenters",
    "corner_columns",
]


def side_lengths(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Lengths ``(M, 3)`` of the sides opposite vertices 0, 1, 2."""
    x, y = _columns(points)
    return block_concat(lambda s: np.column_stack(_sides(x, y, triangles[s])), len(triangles))


def _columns(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The x and y coordinates of ``points (N, 2)``, each contiguous."""
    return np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1])


def _sides(x, y, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Side lengths ``(a, b, c)`` opposite vertices 0, 1, 2 of triangles ``t``."""
    c0, c1, c2 = index_columns(t)
    x0, y0, x1, y1, x2, y2 = x[c0], y[c0], x[c1], y[c1], x[c2], y[c2]
    return np.hypot(x2 - x1, y2 - y1), np.hypot(x0 - x2, y0 - y2), np.hypot(x1 - x0, y1 - y0)


def corner_columns(points: np.ndarray, triangles: np.ndarray):
    """The corners' coordinates ``((x0, y0), (x1, y1), (x2, y2))``, each ``(M,)``
    contiguous: gathered from coordinate columns, which is faster than from ``(N, 2)``
    rows and gives the same numbers."""
    x, y = _columns(points)
    return tuple((x[c], y[c]) for c in index_columns(triangles))


def circumcircles(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Circumcenters ``(M, 2)`` and circumradii ``(M,)`` of the triangles."""
    x, y = _columns(points)

    def block(s):
        t = triangles[s]
        c0, c1, c2 = index_columns(t)
        ox, oy, r = circumcenters(x[c0], y[c0], x[c1], y[c1], x[c2], y[c2])
        return np.column_stack([ox, oy]), r

    return block_concat(block, len(triangles))


def circumcenters(ax, ay, bx, by, cx, cy):
    """Circumcentres ``(ox, oy)`` and circumradii of the triangles with corners ``(ax, ay)``,
    ``(bx, by)``, ``(cx, cy)`` (arrays)."""
    bax, bay, cax, cay = bx - ax, by - ay, cx - ax, cy - ay
    d = 2.0 * (bax * cay - bay * cax)
    d = np.where(np.abs(d) < 1e-300, 1e-300, d)
    bl, cl = bax ** 2 + bay ** 2, cax ** 2 + cay ** 2
    ux = (cay * bl - bay * cl) / d
    uy = (bax * cl - cax * bl) / d
    return ax + ux, ay + uy, np.hypot(ux, uy)


def _quality(s: np.ndarray) -> np.ndarray:
    return _quality3(*s.T)


def _quality3(a, b, c) -> np.ndarray:
    """q (Eq. 17) from the side lengths."""
    num = (b + c - a) * (c + a - b) * (a + b - c)
    den = a * b * c
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
    return np.clip(q, 0.0, 1.0)


def _cosines(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cosines of the angles at vertices 0, 1, 2 (law of cosines), unclipped."""
    return _cosines3(*s.T)


def _cosines3(a, b, c) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a2, b2, c2 = a * a, b * b, c * c
    with np.errstate(invalid="ignore", divide="ignore"):
        return ((b2 + c2 - a2) / (2 * b * c), (c2 + a2 - b2) / (2 * c * a),
                (a2 + b2 - c2) / (2 * a * b))


def _degrees(cos: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.nan_to_num(cos, nan=1.0), -1, 1)))


def _min_angle(s: np.ndarray) -> np.ndarray:
    return _min_angle3(*s.T)


def _min_angle3(a, b, c) -> np.ndarray:
    # the smallest angle has the largest cosine: one arccos per triangle
    c0, c1, c2 = _cosines3(a, b, c)
    return _degrees(np.maximum(np.maximum(c0, c1), c2))


def quality(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """q(T) = 2 r/R = (b+c-a)(c+a-b)(a+b-c)/(abc), Eq. (17); 1 for an equilateral triangle.

    >>> quality(np.array([[0, 0], [1, 0], [0.5, 3 ** 0.5 / 2]]), np.array([[0, 1, 2]])).round(12)
    array([1.])

    Tetrahedra ``(M, 4)`` take :func:`tet_quality`, the radius ratio.
    """
    if triangles.shape[1] == 4:
        return tet_quality(points, triangles)
    x, y = _columns(points)
    return block_concat(lambda s: _quality3(*_sides(x, y, triangles[s])), len(triangles))


def triangle_angles(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Interior angles ``(M, 3)`` in degrees, at the triangles' vertices 0, 1, 2."""
    return _degrees(np.stack(_cosines(side_lengths(points, triangles)), axis=1))


def quality_and_angle(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(quality, min_angle)`` of every triangle from one computation of the side lengths
    (by blocks of triangles, in threads); for tetrahedra ``(radius ratio, smallest dihedral
    angle)``."""
    if triangles.shape[1] == 4:
        return tet_quality(points, triangles), dihedral_angles(points, triangles).min(axis=1)
    x, y = _columns(points)

    def block(s):
        a, b, c = _sides(x, y, triangles[s])
        return _quality3(a, b, c), _min_angle3(a, b, c)

    return block_concat(block, len(triangles))


def min_angle(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Smallest interior angle of every triangle, in degrees."""
    x, y = _columns(points)
    return block_concat(lambda s: _min_angle3(*_sides(x, y, triangles[s])), len(triangles))


def _tet_frame(points: np.ndarray, tets: np.ndarray):
    """The edge vectors ``a, b, c`` (each ``(M, 3)``) from vertex 0 to vertices 1, 2, 3."""
    p0 = points[tets[:, 0]]
    return points[tets[:, 1]] - p0, points[tets[:, 2]] - p0, points[tets[:, 3]] - p0


def tet_volumes6(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Six times the signed volume ``(M,)`` of every tetrahedron, ``a . (b x c)`` with
    ``a, b, c`` the edges from vertex 0; positive when ``a, b, c`` form a right-handed
    frame (vertices 1, 2, 3 turn counter-clockwise seen from outside that face).

    >>> tet_volumes6(np.eye(4, 3, k=-1), np.array([[0, 1, 2, 3]])).tolist()
    [1.0]
    """
    def block(s):
        a, b, c = _tet_frame(points, tets[s])
        return np.einsum("ij,ij->i", a, np.cross(b, c))

    return block_concat(block, len(tets))


def _face_normals(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Normals ``(4, M, 3)`` (length twice the face's area) of the faces opposite vertices
    0..3: outward for positively oriented tetrahedra, all inward for negative ones."""
    p = [points[tets[:, k]] for k in range(4)]
    return np.stack([np.cross(p[2] - p[1], p[3] - p[1]), np.cross(p[3] - p[0], p[2] - p[0]),
                     np.cross(p[1] - p[0], p[3] - p[0]), np.cross(p[2] - p[0], p[1] - p[0])])


def tet_quality(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The radius ratio ``3 r_in / R_circ`` of every tetrahedron: 1 for the regular one, 0
    for a flat one (a sliver included, which Eq. (17)'s 2D analogue by edge lengths misses).

    ``r_in = 3 V / (A_0 + A_1 + A_2 + A_3)`` (V the volume, A_k the face areas) and
    ``R_circ = |a|^2 (b x c) + |b|^2 (c x a) + |c|^2 (a x b)| / (2 |a . (b x c)|)``.

    >>> regular = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    >>> tet_quality(regular, np.array([[0, 1, 2, 3]])).round(12).tolist()
    [1.0]
    """
    def block(s):
        t = tets[s]
        a, b, c = _tet_frame(points, t)
        bc, ca, ab = np.cross(b, c), np.cross(c, a), np.cross(a, b)
        v6 = np.abs(np.einsum("ij,ij->i", a, bc))
        o = ((a * a).sum(1)[:, None] * bc + (b * b).sum(1)[:, None] * ca
             + (c * c).sum(1)[:, None] * ab)
        area2 = np.linalg.norm(_face_normals(points, t), axis=2).sum(axis=0)  # 2 x total area
        with np.errstate(invalid="ignore", divide="ignore"):
            # 3 r_in / R = 3 (v6 / area2) / (|o| / (2 v6)) = 6 v6^2 / (area2 |o|)
            q = np.where(v6 > 0, 6.0 * v6 * v6 / (area2 * np.linalg.norm(o, axis=1)), 0.0)
        return np.clip(np.nan_to_num(q, nan=0.0), 0.0, 1.0)

    return block_concat(block, len(tets))


#: the vertex pairs of a tetrahedron's six edges, in the column order of :func:`dihedral_angles`
TET_EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))


def dihedral_angles(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Interior dihedral angles ``(M, 6)`` in degrees at the edges :data:`TET_EDGES`.

    The angle at edge (i, j) is between the two faces holding it, those opposite the other
    two vertices k, l: ``pi - angle(n_k, n_l)`` of their outward normals.

    >>> regular = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    >>> dihedral_angles(regular, np.array([[0, 1, 2, 3]])).round(6).tolist()[0][:2]
    [70.528779, 70.528779]
    """
    def block(s):
        t = tets[s]
        n = _face_normals(points, t)
        n /= np.maximum(np.linalg.norm(n, axis=2, keepdims=True), 1e-300)
        out = np.empty((len(t), 6))
        for e, (i, j) in enumerate(TET_EDGES):
            k, l_ = (v for v in range(4) if v not in (i, j))
            out[:, e] = -np.einsum("ij,ij->i", n[k], n[l_])
        return _degrees(out)

    return block_concat(block, len(tets))


def signed_area2(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Twice the signed area of triangles (a, b, c) given as ``(M, 2)`` corner arrays;
    positive when counter-clockwise."""
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def triangle_areas2(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Twice the signed area ``(M,)`` of every triangle: :func:`signed_area2` of its
    corners (the same numbers), from coordinate columns, by blocks of triangles."""
    x, y = _columns(points)

    def block(s):
        t = triangles[s]
        c0, c1, c2 = index_columns(t)
        ax, ay, bx, by, cx, cy = x[c0], y[c0], x[c1], y[c1], x[c2], y[c2]
        return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)

    return block_concat(block, len(triangles))


def delta_vertices(composition: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """delta(T) from the vertex compositions, Eqs. (14)-(15) with the max-norm.

    ``composition`` is ``(N, m)`` (or ``(N,)`` for one fraction); ``triangles`` any
    simplices ``(M, d + 1)``. The largest max-norm difference over vertex pairs equals the
    largest per-constituent range over the vertices. Computed a constituent at a time from
    its corner values (elementwise maxima and minima: the same numbers as a reduction over
    the ``(M, d + 1, m)`` gather, at a tenth of its cost), by blocks of elements.

    >>> delta_vertices(np.array([0.0, 0.2, 0.5, 0.1]), np.array([[0, 1, 2, 3]])).tolist()
    [0.5]
    """
    c = composition if composition.ndim == 2 else composition[:, None]
    cols = [np.ascontiguousarray(c[:, j]) for j in range(c.shape[1])]
    nv = triangles.shape[1]

    def block(s):
        t = triangles[s]
        out = np.zeros(len(t)) if not cols else None
        for cj in cols:
            lo, b = cj[t[:, 0]], cj[t[:, 1]]
            hi = np.maximum(lo, b)
            np.minimum(lo, b, out=lo)
            for k in range(2, nv):
                d = cj[t[:, k]]
                np.maximum(hi, d, out=hi)
                np.minimum(lo, d, out=lo)
            hi -= lo
            out = hi if out is None else np.maximum(out, hi, out=out)
        return out

    return block_concat(block, len(triangles))


def lattice_barycentric(order: int, dim: int = 2) -> np.ndarray:
    """Barycentric coordinates ``(K, dim + 1)`` of the order-``order`` lattice of a simplex.

    Includes the vertices; ``K = (order + 1)(order + 2)/2`` for a triangle,
    ``(order + 1)(order + 2)(order + 3)/6`` for a tetrahedron.

    >>> len(lattice_barycentric(4)), len(lattice_barycentric(4, dim=3))
    (15, 35)
    """
    if dim == 2:
        i, j = np.meshgrid(np.arange(order + 1), np.arange(order + 1), indexing="ij")
        keep = i + j <= order
        i, j = i[keep], j[keep]
        return np.stack([order - i - j, i, j], axis=1).astype(float) / order
    i, j, k = np.meshgrid(*[np.arange(order + 1)] * 3, indexing="ij")
    keep = i + j + k <= order
    i, j, k = i[keep], j[keep], k[keep]
    return np.stack([order - i - j - k, i, j, k], axis=1).astype(float) / order


def delta_dense(field, points: np.ndarray, triangles: np.ndarray, order: int = 4,
                chunk: int = 200_000, regions: np.ndarray | None = None) -> np.ndarray:
    """delta(T) from the order-``order`` lattice of sample points in every element
    (:func:`lattice_barycentric`: 15 points in a triangle, 35 in a tetrahedron at order 4).

    Catches composition peaks inside an element that vertex sampling (the paper's) misses.
    ``field`` provides ``composition((N, d)) -> (N, m)``. Sample points are pulled a hair
    towards the centroid so that a field with discontinuities along element edges is sampled
    on the element's own side. If ``regions`` is given and the field accepts a ``region``
    keyword, compositions are evaluated for each element's own region.
    """
    dim = points.shape[1]
    lam = lattice_barycentric(order, dim)
    lam = 0.999999 * lam + 0.000001 / (dim + 1.0)
    out = np.empty(len(triangles))
    cols = [np.ascontiguousarray(points[:, d]) for d in range(dim)]

    def block(s):
        t = triangles[s]
        xy = _lattice_points(cols, t, lam)  # (K, n, d): lattice point k of every element
        if regions is not None:
            comp = field.composition(xy.reshape(-1, dim),
                                     region=np.tile(regions[s], len(lam)))
        else:
            comp = field.composition(xy.reshape(-1, dim))
        xy = None
        out[s] = _sample_range(comp.reshape(len(lam), len(t), -1))

    # chunks of elements; in parallel threads when the field allows it (the same numbers)
    block_map(block, len(triangles), size=chunk, serial=not thread_safe(field))
    return out


def _lattice_points(cols, t, lam) -> np.ndarray:
    """The points ``(K, n, d)`` at barycentric coordinates ``lam (K, d + 1)`` in the
    simplices ``t`` (lattice point first: every array below is contiguous): ``(l0 a + l1 b)
    + l2 c (+ l3 e)`` per coordinate, as ``np.einsum("kv,cvd->ckd", ...)`` sums them (the
    same numbers), from the coordinate columns ``cols``; by blocks of simplices (in
    threads)."""
    out = np.empty((len(lam), len(t), len(cols)))
    tcols = index_columns(t)

    def block(s):
        for d, z in enumerate(cols):
            corners = [z[c[s]] for c in tcols]
            for k, weights in enumerate(lam):
                acc = weights[0] * corners[0]
                for w, zc in zip(weights[1:], corners[1:]):
                    acc = acc + w * zc
                out[k, s, d] = acc

    block_map(block, len(t))
    return out


def _sample_range(comp: np.ndarray) -> np.ndarray:
    """``(comp.max(axis=0) - comp.min(axis=0)).max(axis=1)`` of ``comp (K, n, m)`` (the
    compositions at the K lattice points of n elements), the same numbers, by elementwise
    passes over the contiguous ``(n, m)`` slices of K, then over m."""
    hi = comp[0].copy()
    lo = hi.copy()
    for k in range(1, comp.shape[0]):
        np.maximum(hi, comp[k], out=hi)
        np.minimum(lo, comp[k], out=lo)
    hi -= lo
    out = hi[:, 0].copy()
    for j in range(1, hi.shape[1]):
        np.maximum(out, hi[:, j], out=out)
    return out


@dataclass(frozen=True)
class MeshStats:
    """The paper's mesh statistics (Tables 1, 3, 5): Eqs. (1), (16), (18), plus min angle.

    ``delta_min``, ``delta_avg`` and ``delta_max`` are delta(T) as the mesh was made (or
    checked) for: with the chosen sampling, ``"vertices"`` (the paper's Eqs. 14-15, the
    composition at the three vertices) or ``"dense"`` (also a lattice inside every element).
    ``delta_max_dense`` is the largest delta(T) over the order-4 lattice of every element
    (:func:`delta_dense`: 15 points, vertices included), whatever the sampling: what a reader
    of "delta_max < delta_0" as a property of the whole element wants to know, from samples
    (a lower bound on the element's true variation, not a certificate); ``None`` where not
    computed. ``delta_max_vertices`` is the vertex-sampled delta_max whatever the sampling,
    and ``delta_max_certified`` an upper bound on every element's variation over the whole
    element (:func:`hetmesh.certify.certified_delta`), where computed (``None`` otherwise).
    """

    n_points: int
    n_elements: int
    q_min: float
    q_avg: float
    delta_min: float
    delta_avg: float
    delta_max: float
    angle_min: float
    delta_max_dense: float | None = None
    delta_max_vertices: float | None = None
    delta_max_certified: float | None = None

    def as_dict(self) -> dict:
        return asdict(self)


def statistics(points: np.ndarray, triangles: np.ndarray, delta: np.ndarray, *,
               quality: np.ndarray | None = None, angle: np.ndarray | None = None,
               dense: np.ndarray | None = None) -> MeshStats:
    """Statistics of a mesh given the per-element delta (and, if known, q and min angle);
    ``dense``, the per-element delta from :func:`delta_dense`, gives ``delta_max_dense``."""
    if quality is None or angle is None:
        quality, angle = quality_and_angle(points, triangles)
    return MeshStats(
        n_points=int(len(points)),
        n_elements=int(len(triangles)),
        q_min=float(quality.min()),
        q_avg=float(quality.mean()),
        delta_min=float(delta.min()),
        delta_avg=float(delta.mean()),
        delta_max=float(delta.max()),
        angle_min=float(angle.min()),
        delta_max_dense=None if dense is None else float(dense.max()),
    )
