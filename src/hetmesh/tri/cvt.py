"""Conforming centroidal Voronoi tessellation: the density-weighted Lloyd step.

One Lloyd iteration (paper Sec. 3.1.1, steps ii-iii) moves every generator to the
rho-centroid of its Voronoi cell, Eq. (3). The cell of vertex ``i`` in a Delaunay triangulation
is assembled from the pieces of its incident triangles: in triangle (i, j, k) with circumcenter
``o`` the part closer to ``i`` is the quadrilateral (x_i, m_ij, o, m_ki), split here into two
signed sub-triangles; integrals use one-point quadrature (rho at the triangle's centroid,
moments at the sub-triangle centroids). At the domain boundary the cell is cut at the
boundary edges' midpoints, which is the clipped cell.

Conforming CVT (Ju's CfCVDT, Du & Gunzburger): boundary and interface generators move only
along their own curve and keep their order on it; corners and named points stay fixed. Those
constraints are applied by :func:`slide_on_curves`; :func:`limit_to_star` keeps every move
inside the vertex's star so the mesh never folds.
"""

from __future__ import annotations

import numpy as np

from ..metrics import circumcenters, triangle_areas2
from ..parallel import block_map, blocks
from ..topology import index_columns, unique

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

    The per-triangle work is done by blocks of triangles (in threads), from x and y
    columns, into whole arrays that each sum takes in triangle order; a few triangles among
    many points (a local smoothing) sum their cells over the points they use only. The
    numbers are those of the row-wise computation over all points.
    """
    t = triangles
    n = len(points)
    m = len(t)
    x, y = np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1])
    # per triangle: the (clamped) circumcentre and the centroid, by blocks into full arrays
    ox, oy, cen = np.empty(m), np.empty(m), np.empty((m, 2))

    def centres(s):
        c0, c1, c2 = index_columns(t[s])
        ax, ay, bx, by, cx, cy = x[c0], y[c0], x[c1], y[c1], x[c2], y[c2]
        qx, qy, _ = circumcenters(ax, ay, bx, by, cx, cy)
        # obtuse: clamp the circumcenter to the midpoint of the longest edge
        la = (bx - cx) ** 2 + (by - cy) ** 2
        lb = (cx - ax) ** 2 + (cy - ay) ** 2
        lc = (ax - bx) ** 2 + (ay - by) ** 2
        for obtuse, (u, v) in ((la > lb + lc, (1, 2)), (lb > lc + la, (2, 0)),
                               (lc > la + lb, (0, 1))):
            px, py = (ax, bx, cx), (ay, by, cy)
            qx = np.where(obtuse, 0.5 * (px[u] + px[v]), qx)
            qy = np.where(obtuse, 0.5 * (py[u] + py[v]), qy)
        ox[s], oy[s] = qx, qy
        cen[s, 0] = (ax + bx + cx) / 3.0
        cen[s, 1] = (ay + by + cy) / 3.0

    block_map(centres, m)
    # density at the triangle centroid, one evaluation per triangle
    rt = np.ones(m) if rho is None else rho(cen)
    cen = None  # the centroids are no longer needed
    # the cells' sums over the points the triangles use (all points for a global step)
    if 3 * m < n:
        used, inv = unique(t, return_inverse=True)
        ids = inv.reshape(t.shape)
    else:
        used, ids = None, t
    k = n if used is None else len(used)
    mass = np.zeros(k)
    mx = np.zeros(k)
    my = np.zeros(k)
    # per corner c, its two sub-triangles (p, q, o): p/q the corner and the midpoint of
    # an edge at it, the "first" one on the edge (c, c+1), the other on (c-1, c); one pass
    # over the triangles gathers the corner and its neighbours once for both
    w = [np.empty(m) for _ in range(6)]
    for c, (u, v) in ((0, (1, 2)), (1, (2, 0)), (2, (0, 1))):

        def subs(s, c=c, u=u, v=v):
            cols = index_columns(t[s])
            ic, iu, iv = cols[c], cols[u], cols[v]
            cx_, cy_ = x[ic], y[ic]
            m1x, m1y = 0.5 * (cx_ + x[iu]), 0.5 * (cy_ + y[iu])
            m2x, m2y = 0.5 * (x[iv] + cx_), 0.5 * (y[iv] + cy_)
            o_x, o_y, r = ox[s], oy[s], rt[s]
            for j, (px, py, qx, qy) in enumerate(((cx_, cy_, m1x, m1y),
                                                  (m2x, m2y, cx_, cy_))):
                ar = 0.5 * np.abs((qx - px) * (o_y - py) - (qy - py) * (o_x - px))
                ws = ar * r
                w[3 * j][s] = ws
                w[3 * j + 1][s] = ws * ((px + qx + o_x) / 3.0)
                w[3 * j + 2][s] = ws * ((py + qy + o_y) / 3.0)

        block_map(subs, m)
        idx = ids[:, c]
        for j in (0, 1):  # the first sub-triangles' sums, then the others'
            mass += np.bincount(idx, w[3 * j], minlength=k)
            mx += np.bincount(idx, w[3 * j + 1], minlength=k)
            my += np.bincount(idx, w[3 * j + 2], minlength=k)
    w = None
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
    area is computed as for the whole mesh, so the result does not depend on that. The
    triangles are taken by blocks (in threads), and the points that do not move are copied
    (``targets`` there are not read).
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
    parts = None
    # x and y columns of the points and targets: the gathers below read contiguous arrays
    cols = (np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1]),
            np.ascontiguousarray(targets[:, 0]), np.ascontiguousarray(targets[:, 1]))
    cand = None  # the triangles a try looks at: all, then those the last one found
    for _ in range(halvings + 1):
        bad, found = _folds_alone(cols, t if cand is None else t[cand], step, live,
                                  min_area_ratio)
        if parts is None:  # the first try looks at every triangle with a moving corner
            parts = found
        bad &= step > 0
        if not bad.any():
            break
        step[bad] *= 0.5
        # the next try's live points (a subset of this one's) have their triangles among
        # those this try found
        live = bad
        rows = np.concatenate([r for r, _ in found])
        cand = rows if cand is None else cand[rows]
    else:
        step[bad] = 0.0
    new = p.copy()
    for b in blocks(len(idx)):
        i = idx[b]
        new[i] = p[i] + step[i, None] * (targets[i] - p[i])
    # joint check: adjacent movers may fold a triangle together
    parts = [(t[rows], min_area_ratio * 0.5 * a0) for rows, a0 in parts]
    for _ in range(4):
        fail = block_map(lambda b: [tb[triangle_areas2(new, tb) < lim]
                                    for tb, lim in parts[b]], len(parts), 1)
        fail = [f for group in fail for f in group if len(f)]
        if not fail:
            break
        hold = unique(np.concatenate(fail).ravel())
        new[hold] = p[hold]
    return new


def _folds_alone(cols, t, step, live, ratio):
    """The ``live`` points (mask) that would fold an incident triangle below ``ratio`` of
    its area if each alone moved by its ``step`` towards its target (the others held); and,
    per block of ``t``, the triangles with a live corner (ids, in order) and twice their
    signed areas. ``cols`` holds the points' and the targets' x and y columns."""
    x, y, gx, gy = cols

    def block(s):
        tt = t[s]
        lv = np.take(live, tt.ravel()).reshape(tt.shape)
        rows = np.flatnonzero(lv[:, 0] | lv[:, 1] | lv[:, 2])
        c = index_columns(tt[rows])
        lv = lv[rows]
        ax, ay, bx, by, cx, cy = (x[c[0]], y[c[0]], x[c[1]], y[c[1]], x[c[2]], y[c[2]])
        a0 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        lim = ratio * a0
        out = []
        for k, (vx, vy) in enumerate(((ax, ay), (bx, by), (cx, cy))):
            v = c[k]
            # the corner alone at its tried position (the same numbers as for all points)
            sv = step[v]
            px = vx + sv * (gx[v] - vx)
            py = vy + sv * (gy[v] - vy)
            if k == 0:
                ar = (bx - px) * (cy - py) - (by - py) * (cx - px)
            elif k == 1:
                ar = (px - ax) * (cy - ay) - (py - ay) * (cx - ax)
            else:
                ar = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
            out.append(v[lv[:, k] & (ar < lim)])
        return np.concatenate(out), rows + s.start, a0

    found = block_map(block, len(t))
    bad = np.zeros(len(x), bool)
    for f, _, _ in found:
        bad[f] = True
    return bad, [(rows, a0) for _, rows, a0 in found]


def slide_on_curves(targets: np.ndarray, vertex_curve: np.ndarray, vertex_t: np.ndarray,
                    curves, t_lo: np.ndarray, t_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Project curve vertices' targets onto their curve, keeping their order on it.

    ``t_lo``/``t_hi`` are the parameters of each vertex's neighbours along the curve; the new
    parameter is clipped to the middle 80 % of that interval. Returns ``(points, t)`` for all
    vertices (unchanged where ``vertex_curve < 0``).
    """
    pts = targets.copy()
    t_new = vertex_t.copy()
    for c in unique(vertex_curve[vertex_curve >= 0]):
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
