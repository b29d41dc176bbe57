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

from .mesh import any_corner
from .metrics import circumcircles, corner_columns, triangle_areas2
from .parallel import block_concat

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

    Coordinates are handled as separate x and y columns, and a few triangles among many
    points (a local smoothing) sum their cells over the points they use only; the numbers
    are those of the row-wise computation over all points.
    """
    t = triangles
    n = len(points)
    (ax, ay), (bx, by), (cx, cy) = corner_columns(points, t)
    o, _ = circumcircles(points, t)
    ox, oy = o[:, 0], o[:, 1]
    # obtuse: clamp the circumcenter to the midpoint of the longest edge
    la = (bx - cx) ** 2 + (by - cy) ** 2
    lb = (cx - ax) ** 2 + (cy - ay) ** 2
    lc = (ax - bx) ** 2 + (ay - by) ** 2
    mab = (0.5 * (ax + bx), 0.5 * (ay + by))
    mbc = (0.5 * (bx + cx), 0.5 * (by + cy))
    mca = (0.5 * (cx + ax), 0.5 * (cy + ay))
    for obtuse, m in ((la > lb + lc, mbc), (lb > lc + la, mca), (lc > la + lb, mab)):
        ox = np.where(obtuse, m[0], ox)
        oy = np.where(obtuse, m[1], oy)
    # density at the triangle centroid, one evaluation per triangle
    rt = np.ones(len(t)) if rho is None else rho(
        np.column_stack([(ax + bx + cx) / 3.0, (ay + by + cy) / 3.0]))
    # the cells' sums over the points the triangles use (all points for a global step)
    if 3 * len(t) < n:
        used, inv = np.unique(t, return_inverse=True)
        ids = inv.reshape(t.shape)
    else:
        used, ids = None, t
    k = n if used is None else len(used)
    mass = np.zeros(k)
    mx = np.zeros(k)
    my = np.zeros(k)
    corners = (((ax, ay), mab, mca, ids[:, 0]), ((bx, by), mbc, mab, ids[:, 1]),
               ((cx, cy), mca, mbc, ids[:, 2]))
    for x, m1, m2, idx in corners:
        for (px, py), (qx, qy) in ((x, m1), (m2, x)):
            # sub-triangle (p, q, o) with p/q = vertex and an edge midpoint
            ar = 0.5 * np.abs((qx - px) * (oy - py) - (qy - py) * (ox - px))
            w = ar * rt
            mass += np.bincount(idx, w, minlength=k)
            mx += np.bincount(idx, w * ((px + qx + ox) / 3.0), minlength=k)
            my += np.bincount(idx, w * ((py + qy + oy) / 3.0), minlength=k)
    if used is not None:
        full = np.zeros((3, n))
        full[:, used] = (mass, mx, my)
        mass, mx, my = full
    ok = mass > 0
    cent = points.copy()
    cent[ok, 0] = mx[ok] / mass[ok]
    cent[ok, 1] = my[ok] / mass[ok]
    return cent, mass


def limit_to_star(points: np.ndarray, triangles: np.ndarray, targets: np.ndarray,
                  moving: np.ndarray, halvings: int = 4, min_area_ratio: float = 0.1) -> np.ndarray:
    """Move ``moving`` points towards ``targets`` without folding any incident triangle.

    Each point is moved alone (the others held) and its step halved until every incident
    triangle keeps at least ``min_area_ratio`` of a positive area scale; points whose step
    cannot be made safe stay. Moving points are tested together afterwards and any pair of
    neighbours that fold a shared triangle are both held back.

    Only the corners of moving points are tested, and after the first try only those of the
    points whose step was just halved (the others keep their step, and their verdict); every
    area is computed as for the whole mesh, so the result does not depend on that.
    """
    p = points
    moving = np.asarray(moving, bool)
    idx = np.flatnonzero(moving)
    if idx.size == 0:
        return p.copy()
    t = triangles
    step = np.zeros(len(p))
    step[idx] = 1.0
    live = moving
    bad = np.zeros(len(p), bool)
    for _ in range(halvings + 1):
        bad = _folds_alone(p, t, targets, step, live, min_area_ratio)
        bad &= step > 0
        if not bad.any():
            break
        step[bad] *= 0.5
        live = bad
    else:
        step[bad] = 0.0
    new = p + step[:, None] * (targets - p)
    # joint check: adjacent movers may fold a triangle together
    tri = t[any_corner(moving, t)]
    lim = min_area_ratio * 0.5 * triangle_areas2(p, tri)
    for _ in range(4):
        fail = triangle_areas2(new, tri) < lim
        if not fail.any():
            break
        hold = np.unique(tri[fail].ravel())
        new[hold] = p[hold]
    return new


def _folds_alone(p, t, targets, step, live, ratio) -> np.ndarray:
    """The ``live`` points (mask) that would fold an incident triangle below ``ratio`` of
    its area if each alone moved by its ``step`` towards its target (the others held)."""
    x = np.ascontiguousarray(p[:, 0])
    y = np.ascontiguousarray(p[:, 1])
    # every point's tried position (the same numbers per point as per corner)
    qx = x + step * (targets[:, 0] - x)
    qy = y + step * (targets[:, 1] - y)

    def block(s):
        tt = t[s]
        lv = [live[tt[:, k]] for k in range(3)]
        rows = np.flatnonzero(lv[0] | lv[1] | lv[2])
        c = [tt[rows, k] for k in range(3)]
        ax, ay, bx, by, cx, cy = x[c[0]], y[c[0]], x[c[1]], y[c[1]], x[c[2]], y[c[2]]
        lim = ratio * ((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))
        out = []
        for k in range(3):
            px, py = qx[c[k]], qy[c[k]]
            if k == 0:
                ar = (bx - px) * (cy - py) - (by - py) * (cx - px)
            elif k == 1:
                ar = (px - ax) * (cy - ay) - (py - ay) * (cx - ax)
            else:
                ar = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
            out.append(c[k][lv[k][rows] & (ar < lim)])
        return np.concatenate(out)

    bad = np.zeros(len(p), bool)
    bad[block_concat(block, len(t))] = True
    return bad


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
