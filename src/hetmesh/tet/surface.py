"""Solids bounded by a closed triangulated surface (STL, OBJ, PLY, ... through meshio):
reading, the checks the surface must pass, and the queries the mesher and its verification
need (inside, distance).

Checks, each failure a one-line :class:`~hetmesh.errors.GeometryError` naming the file and a
place: at least four triangles, none of zero area; every edge in exactly two triangles (a
closed, manifold surface: an edge in one triangle is a hole in it, in three or more a
non-manifold seam); the two triangles on an edge traverse it in opposite directions
(consistently oriented; a surface whose triangles all turn inward is turned outward); no
edge of a triangle crosses another triangle that shares no vertex with it (no
self-intersection: candidate pairs from overlapping bounding boxes); a positive enclosed
volume. Several closed shells are allowed (a shell inside another bounds a cavity).

>>> import numpy as np
>>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
>>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
>>> s = SurfaceSolid.from_arrays(V, F, "tet.stl")
>>> s.face_names, round(s.volume, 12)
(('surface',), 0.166666666667)
>>> s.contains([[0.1, 0.1, 0.1], [1.0, 1.0, 1.0]]).tolist()
[True, False]
>>> SurfaceSolid.from_arrays(V, F[:3], "open.stl")
Traceback (most recent call last):
...
hetmesh.errors.GeometryError: open.stl: a closed surface needs at least 4 triangles, got 3
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from ..errors import GeometryError
from ..topology import component_labels, unique

__all__ = ["SurfaceSolid", "read_surface", "check_surface", "ray_parity", "distance_within",
           "distance_to_triangles", "closest_on_triangles", "SURFACE_FACE"]

#: the name of the one face of a surface solid (boundary conditions, physical groups)
SURFACE_FACE = "surface"


def _xyz(p) -> str:
    return f"({p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g})"


def read_surface(path, name: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(n, 3)`` and triangles ``(m, 3)`` of a triangulated surface file (a format
    meshio reads: STL, OBJ, PLY, OFF, ...), coincident points merged (STL repeats them).
    Errors start with ``name`` (default: the path)."""
    import meshio
    path = Path(path)
    name = str(path) if name is None else name
    if not path.is_file():
        where = "" if name.endswith(str(path)) else f" ({path})"
        raise GeometryError(f"{name}: no such surface file{where}")
    try:
        with warnings.catch_warnings():  # meshio sizes an ASCII STL as if binary first
            warnings.simplefilter("ignore", RuntimeWarning)
            m = meshio.read(path)
    except Exception as exc:  # noqa: BLE001  (meshio raises many kinds on bad files)
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise GeometryError(f"{name}: cannot read the surface: {msg}") from None
    tris = [np.asarray(c.data) for c in m.cells if c.type == "triangle"]
    if not tris or not sum(len(t) for t in tris):
        raise GeometryError(f"{name}: no triangles in the file")
    F = np.concatenate(tris).astype(np.int64)
    V = np.asarray(m.points, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] != 3 or not np.isfinite(V).all():
        raise GeometryError(f"{name}: the points must be finite (x, y, z)")
    if F.min() < 0 or F.max() >= len(V):
        raise GeometryError(f"{name}: a triangle refers to a point that is not in the file")
    U, inv = unique(V, axis=0, return_inverse=True)
    return U, inv.reshape(-1)[F]


def _edges(F: np.ndarray) -> np.ndarray:
    """Directed edges ``(3m, 2)`` of the triangles: all first edges, then seconds, thirds."""
    return np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])


def signed_volume(V: np.ndarray, F: np.ndarray) -> float:
    """The volume a closed oriented surface encloses (positive when it turns outward)."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def check_surface(V: np.ndarray, F: np.ndarray, name: str) -> np.ndarray:
    """The triangles, turned outward; :class:`GeometryError` (starting with ``name``) unless
    the surface is closed, manifold, consistently oriented, free of self-intersections and
    encloses a positive volume (module docstring)."""
    if len(F) < 4:
        raise GeometryError(f"{name}: a closed surface needs at least 4 triangles, got "
                            f"{len(F)}")
    scale = float(np.ptp(V, axis=0).max())
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]),
                                axis=1)
    flat = (area <= 1e-12 * scale ** 2) | (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) \
        | (F[:, 0] == F[:, 2])
    if flat.any():
        i = int(np.flatnonzero(flat)[0])
        raise GeometryError(f"{name}: triangle {i} has zero area (at "
                            f"{_xyz(V[F[i]].mean(axis=0))})")
    e = _edges(F)
    n = len(V)
    und = np.sort(e, axis=1)
    uk, cnt = unique(und[:, 0] * n + und[:, 1], return_counts=True)
    if (cnt != 2).any():
        j = int(np.argmax(cnt != 2))
        a, b, c = V[uk[j] // n], V[uk[j] % n], int(cnt[j])
        what = "open (a hole in it)" if c == 1 else "not manifold"
        raise GeometryError(f"{name}: the surface is not watertight: {what}: the edge from "
                            f"{_xyz(a)} to {_xyz(b)} is in {c} triangle{'s' * (c != 1)}, "
                            f"not 2")
    ud, dcnt = unique(e[:, 0] * n + e[:, 1], return_counts=True)
    if (dcnt > 1).any():
        j = int(np.argmax(dcnt > 1))
        raise GeometryError(f"{name}: the surface is not consistently oriented: two "
                            f"triangles run along the edge from {_xyz(V[ud[j] // n])} to "
                            f"{_xyz(V[ud[j] % n])} in the same direction")
    _check_self_intersection(V, F, name)
    vol = signed_volume(V, F)
    if abs(vol) <= 1e-9 * scale ** 3:
        raise GeometryError(f"{name}: the surface encloses no volume ({vol:.3g})")
    if vol < 0:
        F = F[:, [0, 2, 1]]
    try:
        volumes_of_shells(V, F)
    except GeometryError as exc:
        raise GeometryError(f"{name}: {exc}") from None
    return F


def _shell_labels(V, F) -> tuple[np.ndarray, np.ndarray]:
    """``(label (m,), volume (k,))``: the closed shells (triangles connected through shared
    points) and the signed volume each encloses."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    m = len(F)
    g = coo_matrix((np.ones(3 * m), (np.repeat(np.arange(m), 3), F.ravel())),
                   shape=(m, len(V))).tocsr()
    k, lab = connected_components(g @ g.T, directed=False)
    return lab, np.array([signed_volume(V, F[lab == i]) for i in range(k)])


def volumes_of_shells(V, F) -> list[tuple[int, list[int]]]:
    """The regions the outward surface ``V``, ``F`` bounds: ``(outer shell, [cavity
    shells])`` per region, shells numbered as :func:`_shell_labels` does; a cavity (a shell
    turned inward) belongs to the smallest outward shell around it. :class:`GeometryError`
    (without a name) unless the shells nest consistently: the other shells' winding numbers
    add up to 0 at an outward shell (it lies outside the solid they bound) and to 1 at a
    cavity (inside it)."""
    lab, vol = _shell_labels(V, F)
    k = len(vol)
    if k == 1:
        return [(0, [])]
    probes = np.array([V[F[lab == i][0, 0]] for i in range(k)])
    w = np.array([_winding(V, F[lab == j], probes) for j in range(k)])  # (shell, probe)
    for i in range(k):
        total = float(w[:, i].sum() - w[i, i])
        want = 0.0 if vol[i] > 0 else 1.0
        if abs(total - want) > 0.5:
            what = ("an outward shell lies inside the solid" if vol[i] > 0 else
                    "a shell turned inward (a cavity) lies outside the solid")
            raise GeometryError(f"the shells do not nest: {what} (at {_xyz(probes[i])})")
    outer = [int(i) for i in np.argsort(vol) if vol[i] > 0]  # smallest first
    regions = {i: [] for i in outer}
    for j in np.flatnonzero(vol < 0):
        host = next(i for i in outer if w[i, j] > 0.5)
        regions[host].append(int(j))
    return [(i, regions[i]) for i in sorted(regions)]


def feature_patches(V: np.ndarray, F: np.ndarray, angle: float) -> np.ndarray:
    """The patch of each triangle ``(m,)``: triangles joined across the edges where their
    normals are at most ``angle`` degrees apart (the others are sharp edges), numbered in
    the order of their first triangle."""
    nrm = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    e = np.sort(_edges(F), axis=1)
    tri = np.tile(np.arange(len(F)), 3)
    order = np.argsort(e[:, 0] * len(V) + e[:, 1], kind="stable")
    a, b = tri[order[0::2]], tri[order[1::2]]  # every edge in exactly two triangles
    smooth = np.einsum("ij,ij->i", nrm[a], nrm[b]) >= np.cos(np.radians(angle))
    return component_labels(len(F), a[smooth], b[smooth])


def _orient3d(a, b, c, d):
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a))


def _candidate_pairs(lo: np.ndarray, hi: np.ndarray, block: int = 2_000_000):
    """Pairs ``(i, j)`` of boxes ``[lo, hi]`` that overlap: a sweep along the axis on which
    the boxes are shortest relative to the whole extent (fewest overlaps)."""
    span = np.maximum(hi.max(axis=0) - lo.min(axis=0), 1e-300)
    a = int(np.argmin((hi - lo).mean(axis=0) / span))
    order = np.argsort(lo[:, a], kind="stable")
    xs = lo[order, a]
    stop = np.searchsorted(xs, hi[order, a], side="right")
    counts = stop - np.arange(len(order)) - 1
    start = 0
    while start < len(order):
        end = start + 1
        total = counts[start]
        while end < len(order) and total + counts[end] <= block:
            total += counts[end]
            end += 1
        a = np.repeat(np.arange(start, end), counts[start:end])
        offs = np.arange(len(a)) - np.repeat(np.cumsum(counts[start:end]) - counts[start:end],
                                             counts[start:end])
        b = a + 1 + offs
        i, j = order[a], order[b]
        ok = ((lo[i] <= hi[j]) & (lo[j] <= hi[i])).all(axis=1)
        yield i[ok], j[ok]
        start = end


def _check_self_intersection(V, F, name: str) -> None:
    """No edge of a triangle crosses another triangle that shares no vertex with it."""
    tri = V[F]
    scale = float(np.ptp(V, axis=0).max())
    pad = 1e-12 * scale
    eps = 1e-12 * scale ** 3
    for i, j in _candidate_pairs(tri.min(axis=1) - pad, tri.max(axis=1) + pad):
        share = (F[i][:, :, None] == F[j][:, None, :]).any(axis=(1, 2))
        i, j = i[~share], j[~share]
        for s, t in ((i, j), (j, i)):
            A, B, C = V[F[t, 0]], V[F[t, 1]], V[F[t, 2]]
            for k in range(3):
                P, Q = V[F[s, k]], V[F[s, (k + 1) % 3]]
                dp, dq = _orient3d(A, B, C, P), _orient3d(A, B, C, Q)
                cross = ((dp > eps) & (dq < -eps)) | ((dp < -eps) & (dq > eps))
                s1, s2, s3 = _orient3d(P, Q, A, B), _orient3d(P, Q, B, C), \
                    _orient3d(P, Q, C, A)
                inside = ((s1 > eps) & (s2 > eps) & (s3 > eps)) | \
                    ((s1 < -eps) & (s2 < -eps) & (s3 < -eps))
                hit = cross & inside
                if hit.any():
                    m = int(np.flatnonzero(hit)[0])
                    raise GeometryError(
                        f"{name}: the surface intersects itself: triangles {int(s[m])} and "
                        f"{int(t[m])} cross near {_xyz(0.5 * (P[m] + Q[m]))}")


def _winding(V, F, P) -> np.ndarray:
    """Generalised winding number of the surface at points ``P`` (1 inside, 0 outside)."""
    P = np.asarray(P, dtype=float).reshape(-1, 3)
    out = np.zeros(len(P))
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    block = max(1, 4_000_000 // max(len(F), 1))
    for s in range(0, len(P), block):
        q = P[s:s + block, None, :]
        a, b, c = A[None] - q, B[None] - q, C[None] - q
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        num = np.einsum("kij,kij->ki", a, np.cross(b, c))
        den = la * lb * lc + np.einsum("kij,kij->ki", a, b) * lc \
            + np.einsum("kij,kij->ki", b, c) * la + np.einsum("kij,kij->ki", c, a) * lb
        out[s:s + block] = np.arctan2(num, den).sum(axis=1) / (2 * np.pi)
    return out


def _side(ax, ay, bx, by, px, py) -> np.ndarray:
    """Sign (+1, -1) of the point ``p`` to the left of the directed edge ``a -> b`` (2D), its
    ties broken by a symbolic shift of ``p`` by ``(eps, eps^2)`` (simulation of
    simplicity): never 0, and opposite for the edge ``b -> a``."""
    e = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    tie = np.where(by != ay, -(by - ay), bx - ax)
    return np.where(e != 0, np.sign(e), np.sign(tie))


def ray_parity(V, F, P) -> np.ndarray:
    """Whether each point ``P (k, 3)`` is inside the closed surface: the parity of the
    triangles crossed by the ray from it along +z. The triangles' projections are binned
    on a grid in (x, y); a ray through an edge or a vertex counts one triangle, the ties
    broken consistently (:func:`_side`), so the count is exact for a closed surface."""
    P = np.asarray(P, dtype=float).reshape(-1, 3)
    tri = V[F]
    x0, y0 = tri[:, :, 0], tri[:, :, 1]
    area = (x0[:, 1] - x0[:, 0]) * (y0[:, 2] - y0[:, 0]) \
        - (x0[:, 2] - x0[:, 0]) * (y0[:, 1] - y0[:, 0])
    keep = np.flatnonzero(area != 0)  # vertical triangles: no ray crosses them
    tri, area = tri[keep], area[keep]
    lo, hi = tri[:, :, :2].min(axis=1), tri[:, :, :2].max(axis=1)
    blo, bhi = lo.min(axis=0), hi.max(axis=0)
    g = max(1, int(np.sqrt(len(tri))))
    step = np.where(bhi > blo, (bhi - blo) / g, 1.0)
    c0 = np.clip(((lo - blo) / step).astype(np.int64), 0, g - 1)
    c1 = np.clip(((hi - blo) / step).astype(np.int64), 0, g - 1)
    nx = c1[:, 0] - c0[:, 0] + 1
    ny = c1[:, 1] - c0[:, 1] + 1
    cnt = nx * ny
    t_of = np.repeat(np.arange(len(tri)), cnt)
    k = np.arange(len(t_of)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    cell = (c0[t_of, 0] + k // ny[t_of]) * g + c0[t_of, 1] + k % ny[t_of]
    order = np.argsort(cell, kind="stable")
    cell, t_of = cell[order], t_of[order]
    start = np.searchsorted(cell, np.arange(g * g))
    end = np.searchsorted(cell, np.arange(g * g), side="right")
    inside = np.zeros(len(P), dtype=bool)
    q = (P[:, :2] - blo) / step
    pc = np.clip(np.floor(q).astype(np.int64), 0, g - 1)
    out = ((P[:, :2] < blo) | (P[:, :2] > bhi)).any(axis=1)
    pcell = np.where(out, -1, pc[:, 0] * g + pc[:, 1])
    ids = np.flatnonzero(pcell >= 0)
    n = end[pcell[ids]] - start[pcell[ids]]
    chunk = 4_000_000
    pos = 0
    while pos < len(ids):
        csum = np.cumsum(n[pos:])
        stop = pos + max(1, int(np.searchsorted(csum, chunk, side="right")))
        r = np.repeat(ids[pos:stop], n[pos:stop])
        off = np.arange(len(r)) - np.repeat(np.cumsum(n[pos:stop]) - n[pos:stop], n[pos:stop])
        t = t_of[np.repeat(start[pcell[ids[pos:stop]]], n[pos:stop]) + off]
        T = tri[t]
        px, py = P[r, 0], P[r, 1]
        s = [_side(T[:, a, 0], T[:, a, 1], T[:, b, 0], T[:, b, 1], px, py)
             for a, b in ((0, 1), (1, 2), (2, 0))]
        sg = np.sign(area[t])
        hit = (s[0] == sg) & (s[1] == sg) & (s[2] == sg)
        r, t, T = r[hit], t[hit], T[hit]
        # the triangle's height above the point (barycentric in the projection)
        ax, ay = T[:, 0, 0], T[:, 0, 1]
        l1 = ((P[r, 0] - ax) * (T[:, 2, 1] - ay) - (T[:, 2, 0] - ax) * (P[r, 1] - ay)) \
            / area[t]
        l2 = ((T[:, 1, 0] - ax) * (P[r, 1] - ay) - (P[r, 0] - ax) * (T[:, 1, 1] - ay)) \
            / area[t]
        z = T[:, 0, 2] + l1 * (T[:, 1, 2] - T[:, 0, 2]) + l2 * (T[:, 2, 2] - T[:, 0, 2])
        above = z > P[r, 2]
        np.logical_xor.at(inside, r[above], True)
        pos = stop
    return inside


def closest_on_triangles(P, A, B, C) -> np.ndarray:
    """The closest point of triangle ``(A[i], B[i], C[i])`` to ``P[i]``, row by row (Voronoi
    regions of the vertices, edges and face; Ericson, Real-Time Collision Detection 5.1.5)."""
    ab, ac = B - A, C - A
    ap, bp, cp = P - A, P - B, P - C
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        out = A + ab * (vb / den)[:, None] + ac * (vc / den)[:, None]
        t_ab = np.clip(d1 / (d1 - d3), 0, 1)
        t_ac = np.clip(d2 / (d2 - d6), 0, 1)
        t_bc = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0, 1)
    out = np.where(((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))[:, None],
                   B + (C - B) * t_bc[:, None], out)
    out = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[:, None], A + ac * t_ac[:, None], out)
    out = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[:, None], A + ab * t_ab[:, None], out)
    out = np.where(((d6 >= 0) & (d5 <= d6))[:, None], C, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[:, None], B, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[:, None], A, out)
    return out


def distance_to_triangles(V: np.ndarray, F: np.ndarray, P) -> np.ndarray:
    """The distance of each point ``P (k, 3)`` to the triangles ``F`` of ``V``: exact, the
    triangles whose bounding box is farther than the best distance so far skipped (the
    candidates are taken nearest box first, in blocks)."""
    P = np.asarray(P, dtype=float).reshape(-1, 3)
    tri = V[F]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    out = np.empty(len(P))
    chunk = max(1, 2_000_000 // max(len(F), 1))
    for s in range(0, len(P), chunk):
        q = P[s:s + chunk]
        gap = np.maximum(np.maximum(lo[None] - q[:, None], q[:, None] - hi[None]), 0.0)
        box = np.linalg.norm(gap, axis=2)                        # (k, m) lower bounds
        order = np.argsort(box, axis=1, kind="stable")
        best = np.full(len(q), np.inf)
        rows = np.arange(len(q))
        for c in range(0, len(F), 8):
            cols = order[:, c:c + 8]
            live = box[rows[:, None], cols[:, :1]][:, 0] < best
            if not live.any():
                break
            r = rows[live]
            cc = cols[live]
            k = cc.shape[1]
            Q = np.repeat(q[r], k, axis=0)
            T = F[cc.ravel()]
            cp = closest_on_triangles(Q, V[T[:, 0]], V[T[:, 1]], V[T[:, 2]])
            d = np.linalg.norm(cp - Q, axis=1).reshape(len(r), k).min(axis=1)
            best[r] = np.minimum(best[r], d)
        out[s:s + chunk] = best
    return out


def distance_within(V: np.ndarray, F: np.ndarray, P, tol: float, *,
                    nearest: bool = False):
    """The distance of each point ``P (k, 3)`` to the triangles ``F`` of ``V`` where it is
    at most ``tol`` (exact), ``inf`` elsewhere; with ``nearest``, also the index of the
    nearest triangle (-1 where none is that close). Only the triangles whose bounding box
    widened by ``tol`` holds the point can be that close: the boxes are binned on a grid
    over the points' and triangles' extent, and each point meets the triangles of its
    cell."""
    P = np.asarray(P, dtype=float).reshape(-1, 3)
    out = np.full(len(P), np.inf)
    near = np.full(len(P), -1, dtype=np.int64)
    if not len(P) or not len(F):
        return (out, near) if nearest else out
    tri = V[F]
    lo, hi = tri.min(axis=1) - tol, tri.max(axis=1) + tol
    blo = np.minimum(lo.min(axis=0), P.min(axis=0))
    bhi = np.maximum(hi.max(axis=0), P.max(axis=0))
    g = int(np.clip(round(2 * len(F) ** (1 / 3)), 1, 64))
    step = np.where(bhi > blo, (bhi - blo) / g, 1.0)
    c0 = np.clip(((lo - blo) / step).astype(np.int64), 0, g - 1)
    c1 = np.clip(((hi - blo) / step).astype(np.int64), 0, g - 1)
    n3 = c1 - c0 + 1
    cnt = n3.prod(axis=1)
    t_of = np.repeat(np.arange(len(F)), cnt)
    k = np.arange(len(t_of)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    nyz = n3[t_of, 1] * n3[t_of, 2]
    i = c0[t_of, 0] + k // nyz
    j = c0[t_of, 1] + (k % nyz) // n3[t_of, 2]
    m = c0[t_of, 2] + k % n3[t_of, 2]
    cell = (i * g + j) * g + m
    order = np.argsort(cell, kind="stable")
    cell, t_of = cell[order], t_of[order]
    start = np.searchsorted(cell, np.arange(g ** 3))
    end = np.searchsorted(cell, np.arange(g ** 3), side="right")
    pc = np.clip(((P - blo) / step).astype(np.int64), 0, g - 1)
    pcell = (pc[:, 0] * g + pc[:, 1]) * g + pc[:, 2]
    n = end[pcell] - start[pcell]
    pos = 0
    csum = np.cumsum(n)
    while pos < len(P):
        base = csum[pos - 1] if pos else 0
        stop = max(pos + 1, int(np.searchsorted(csum, base + 2_000_000, side="right")))
        r = np.repeat(np.arange(pos, stop), n[pos:stop])
        off = np.arange(len(r)) - np.repeat(np.cumsum(n[pos:stop]) - n[pos:stop], n[pos:stop])
        t = t_of[np.repeat(start[pcell[pos:stop]], n[pos:stop]) + off]
        T = F[t]
        d = np.linalg.norm(closest_on_triangles(P[r], V[T[:, 0]], V[T[:, 1]], V[T[:, 2]])
                           - P[r], axis=1)
        if len(r):  # the nearest per point: the first of its rows sorted by distance
            o = np.lexsort((t, d, r))
            first = o[np.r_[True, r[o][1:] != r[o][:-1]]]
            out[r[first]], near[r[first]] = d[first], t[first]
        pos = stop
    far = out > tol
    out[far], near[far] = np.inf, -1
    return (out, near) if nearest else out


@dataclass(frozen=True, eq=False)
class SurfaceSolid:
    """The solid inside a closed triangulated surface: points ``V (n, 3)`` and outward
    triangles ``F (m, 3)``, checked (:func:`check_surface`); ``source`` names the file in
    messages. One face, :data:`SURFACE_FACE`; with ``feature_angle`` (degrees), one face per
    patch between sharp edges (:func:`feature_patches`), ``surface.1``, ``surface.2``, ...
    in the order of the patches' first triangles in the file (one patch: ``surface``)."""

    V: np.ndarray
    F: np.ndarray
    source: str = ""
    feature_angle: float | None = None

    @classmethod
    def from_arrays(cls, V, F, name: str, feature_angle: float | None = None
                    ) -> SurfaceSolid:
        """Checked solid of ``V``, ``F`` (unused points dropped); errors start with ``name``."""
        V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
        F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
        if len(F) < 4:
            raise GeometryError(f"{name}: a closed surface needs at least 4 triangles, got "
                                f"{len(F)}")
        used = unique(F)
        remap = np.full(len(V), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        V, F = V[used], remap[F]
        return cls(V, check_surface(V, F, name), name, feature_angle)

    @classmethod
    def read(cls, path, name: str | None = None, feature_angle: float | None = None
             ) -> SurfaceSolid:
        """The solid of a surface file (:func:`read_surface`), checked; errors start with
        ``name`` (default: the path)."""
        name = str(path) if name is None else name
        V, F = read_surface(path, name)
        return cls.from_arrays(V, F, name, feature_angle)

    @cached_property
    def patch(self) -> np.ndarray:
        """The face (index into :attr:`face_names`) of each input triangle."""
        if self.feature_angle is None:
            return np.zeros(len(self.F), dtype=np.int64)
        return feature_patches(self.V, self.F, self.feature_angle)

    @cached_property
    def shells(self) -> tuple[np.ndarray, list[tuple[int, list[int]]]]:
        """``(label (m,), regions)``: each triangle's shell and, per region, its outer
        shell and its cavities (:func:`volumes_of_shells`)."""
        lab, _ = _shell_labels(self.V, self.F)
        return lab, volumes_of_shells(self.V, self.F)

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.V.min(axis=0), self.V.max(axis=0)

    @property
    def diameter(self) -> float:
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    @cached_property
    def volume(self) -> float:
        """The enclosed volume (exact for the triangulated surface)."""
        return signed_volume(self.V, self.F)

    @cached_property
    def area(self) -> float:
        return float(0.5 * np.linalg.norm(np.cross(self.V[self.F[:, 1]] - self.V[self.F[:, 0]],
                                                   self.V[self.F[:, 2]] - self.V[self.F[:, 0]]),
                                          axis=1).sum())

    @cached_property
    def face_names(self) -> tuple[str, ...]:
        k = int(self.patch.max()) + 1
        return (SURFACE_FACE,) if k == 1 else tuple(f"{SURFACE_FACE}.{i + 1}" for i in range(k))

    def winding(self, points) -> np.ndarray:
        """The generalised winding number at ``points`` (1 inside, 0 outside)."""
        return _winding(self.V, self.F, points)

    def distance(self, points) -> np.ndarray:
        """The distance of ``points`` to the surface."""
        return distance_to_triangles(self.V, self.F, points)

    def distance_within(self, points, tol: float) -> np.ndarray:
        """The distance of ``points`` to the surface where it is at most ``tol``, else
        ``inf`` (:func:`distance_within`: fast when few triangles are that close)."""
        return distance_within(self.V, self.F, points, tol)

    def contains(self, points, tol: float | None = None) -> np.ndarray:
        """Whether each point ``(N, 3)`` lies in the solid (an odd number of crossings
        along +z, :func:`ray_parity`) or within ``tol`` of its surface (default: 2e-3 x
        the diameter, the default chord tolerance: a mesh's boundary may deviate that much
        from the facets)."""
        from .mesher import CHORD
        tol = CHORD * self.diameter if tol is None else tol
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        ok = ray_parity(self.V, self.F, p)
        if tol > 0 and not ok.all():
            rest = np.flatnonzero(~ok)
            ok[rest] = np.isfinite(self.distance_within(p[rest], tol))
        return ok

    def classify_faces(self, tri_points, tol: float | None = None) -> np.ndarray:
        """Face index (into :attr:`face_names`) of boundary triangles ``(K, 3, 3)``: the
        face of the input triangle nearest to the centroid, where all three corners are
        within ``tol`` (default 1 % of the diameter) of the surface; -1 elsewhere."""
        tol = 0.01 * self.diameter if tol is None else tol
        tri = np.asarray(tri_points, dtype=float).reshape(-1, 3, 3)
        d = self.distance_within(tri.reshape(-1, 3), tol)
        ok = np.isfinite(d.reshape(-1, 3)).all(axis=1)
        _, near = distance_within(self.V, self.F, tri.mean(axis=1), tol, nearest=True)
        return np.where(ok & (near >= 0), self.patch[np.maximum(near, 0)], -1)

    def sample(self, n: int = 24) -> np.ndarray:
        """The points of the regular ``n``^3 grid over the bounds inside the surface."""
        lo, hi = self.bounds
        g = [np.linspace(lo[k], hi[k], n) for k in range(3)]
        p = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1).reshape(-1, 3)
        return p[ray_parity(self.V, self.F, p)]
