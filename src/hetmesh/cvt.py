"""Conforming centroidal Voronoi tessellation: the density-weighted Lloyd step.

One Lloyd iteration (paper Sec. 3.1.1, steps ii-iii) moves every generator to the
rho-centroid of its Voronoi cell, Eq. (3). The cell of vertex ``i`` in a Delaunay triangulation
is assembled from the pieces of its incident triangles: in triangle (i, j, k) with circumcenter
``o`` the part closer to ``i`` is the quadrilateral (x_i, m_ij, o, m_ki), split here into two
signed sub-triangles; integrals use one-point quadrature (rho at the triangle's centroid, moments at the
sub-triangle centroids). At the
domain boundary the cell is cut at the boundary edges' midpoints, which is the clipped cell.

Conforming CVT (Ju's CfCVDT, Du & Gunzburger): boundary and interface generators move only
along their own curve and keep their order on it; corners and named points stay fixed. Those
constraints are applied by :func:`slide_on_curves`; :func:`limit_to_star` keeps every move
inside the vertex's star so the mesh never folds.
"""

from __future__ import annotations

import numpy as np

from .metrics import circumcircles, signed_area2

__all__ = ["cell_centroids", "limit_to_star", "slide_on_curves"]


def cell_centroids(points: np.ndarray, triangles: np.ndarray, rho) -> tuple[np.ndarray, np.ndarray]:
    """rho-weighted centroids of the (boundary-clipped) Voronoi cells, Eq. (3).

    Parameters
    ----------
    points : (N, 2), triangles : (M, 3) Delaunay, counter-clockwise.
    rho : callable ``(K, 2) -> (K,)`` density, or None for rho = 1.

    Returns
    -------
    centroids (N, 2), mass (N,) (the cell's integral of rho; 0 for unused points).

    Obtuse triangles have their circumcenter outside; it is clamped to the triangle's
    centroid side by taking the circumcenter of non-obtuse triangles and the midpoint of the
    longest edge for obtuse ones, which keeps every sub-triangle positive.
    """
    t = triangles
    a, b, c = points[t[:, 0]], points[t[:, 1]], points[t[:, 2]]
    o, _ = circumcircles(points, t)
    # obtuse: clamp the circumcenter to the midpoint of the longest edge
    la, lb, lc = ((b - c) ** 2).sum(1), ((c - a) ** 2).sum(1), ((a - b) ** 2).sum(1)
    mab, mbc, mca = 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)
    oa = la > lb + lc
    ob = lb > lc + la
    oc = lc > la + lb
    o = np.where(oa[:, None], mbc, o)
    o = np.where(ob[:, None], mca, o)
    o = np.where(oc[:, None], mab, o)
    # density at the triangle centroid, one evaluation per triangle
    rt = np.ones(len(t)) if rho is None else rho((a + b + c) / 3.0)
    n = len(points)
    mass = np.zeros(n)
    mom = np.zeros((n, 2))
    corners = ((a, mab, mca, t[:, 0]), (b, mbc, mab, t[:, 1]), (c, mca, mbc, t[:, 2]))
    for x, m1, m2, idx in corners:
        for p, q in ((x, m1), (m2, x)):
            # sub-triangle (p, q, o) with p/q = vertex and an edge midpoint
            ar = 0.5 * np.abs((q[:, 0] - p[:, 0]) * (o[:, 1] - p[:, 1])
                              - (q[:, 1] - p[:, 1]) * (o[:, 0] - p[:, 0]))
            cen = (p + q + o) / 3.0
            w = ar * rt
            mass += np.bincount(idx, w, minlength=n)
            mom[:, 0] += np.bincount(idx, w * cen[:, 0], minlength=n)
            mom[:, 1] += np.bincount(idx, w * cen[:, 1], minlength=n)
    ok = mass > 0
    cent = points.copy()
    cent[ok] = mom[ok] / mass[ok, None]
    return cent, mass


def limit_to_star(points: np.ndarray, triangles: np.ndarray, targets: np.ndarray,
                  moving: np.ndarray, halvings: int = 4, min_area_ratio: float = 0.1) -> np.ndarray:
    """Move ``moving`` points towards ``targets`` without folding any incident triangle.

    Each point is moved alone (the others held) and its step halved until every incident
    triangle keeps at least ``min_area_ratio`` of a positive area scale; points whose step
    cannot be made safe stay. Moving points are tested together afterwards and any pair of
    neighbours that fold a shared triangle are both held back.
    """
    new = points.copy()
    idx = np.flatnonzero(moving)
    if idx.size == 0:
        return new
    step = np.zeros(len(points))
    step[idx] = 1.0
    t = triangles
    p = points
    area0 = signed_area2(p[t[:, 0]], p[t[:, 1]], p[t[:, 2]])
    for _ in range(halvings + 1):
        cand = p + step[:, None] * (targets - p)
        bad = np.zeros(len(p), bool)
        for k in range(3):
            v = t[:, k]
            q = [p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]]
            q[k] = cand[v]
            ar = signed_area2(*q)
            fail = ar < min_area_ratio * area0
            bad[v[fail]] = True
        bad &= step > 0
        if not bad.any():
            break
        step[bad] *= 0.5
    else:
        step[bad] = 0.0
    new = p + step[:, None] * (targets - p)
    # joint check: adjacent movers may fold a triangle together
    for _ in range(4):
        ar = signed_area2(new[t[:, 0]], new[t[:, 1]], new[t[:, 2]])
        fail = ar < min_area_ratio * 0.5 * area0
        if not fail.any():
            break
        hold = np.unique(t[fail].ravel())
        new[hold] = p[hold]
    return new


def slide_on_curves(targets: np.ndarray, vertex_curve: np.ndarray, vertex_t: np.ndarray,
                    curves, t_lo: np.ndarray, t_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Project curve vertices' targets onto their curve, keeping their order on it.

    ``t_lo``/``t_hi`` are the parameters of each vertex's neighbours along the curve; the new
    parameter is clipped to the middle 80 % of that interval. Returns ``(points, t)`` for all
    vertices (unchanged where ``vertex_curve < 0``).
    """
    pts = targets.copy()
    t_new = vertex_t.copy()
    for c in np.unique(vertex_curve[vertex_curve >= 0]):
        sel = np.flatnonzero(vertex_curve == c)
        curve = curves[c]
        tt = curve.project(targets[sel])
        cur = vertex_t[sel]
        # closed curves: stay on the same side of the seam
        tt = np.where(tt - cur > 0.5, tt - 1.0, np.where(cur - tt > 0.5, tt + 1.0, tt))
        lo, hi = t_lo[sel], t_hi[sel]
        span = hi - lo
        tt = np.clip(tt, lo + 0.1 * span, hi - 0.1 * span)
        t_new[sel] = tt
        pts[sel] = curve.point(tt)
    return pts, t_new
