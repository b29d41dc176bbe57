"""A tetrahedral mesh of the inside of a closed triangulated surface whose boundary is the
input triangles, some split in their own plane: a conforming Delaunay tetrahedralisation
(Qhull through scipy; permissive licences), the first volume of the surface-solid mesher
(:func:`hetmesh.tet.surface_mesh.initial_volume`).

0. *Inner points* (:func:`inner_points`): a lattice of step 1.5 x the cube root of the
   volume per surface point, the points inside and more than half a step from the
   surface (none for solids too thin for them). They give MMG, which remeshes the fill
   next, a start with fewer flat tetrahedra across the solid (on a torus of 6,144
   triangles, 31 % fewer tetrahedra at the end; docs/tet.md).
1. *Triangulation* (:func:`regular_tets`): the Delaunay tetrahedralisation of the points
   (Qhull's lower convex hull of the points lifted onto the paraboloid ``|q|^2``, ``q``
   the points scaled into [-1, 1]^3, with a point above them all as Qhull's ``Qz`` adds),
   each lift raised by ``s u_i h_i^2`` (``h_i`` the distance to the nearest other point,
   ``u_i`` in [0, 1) from a fixed-seed generator, ``s`` = 1e-4): a regular triangulation
   of the same points that breaks the ties of co-spherical points (a cube's eight
   corners, two parallel circles of a torus) that Qhull would otherwise merge and
   triangulate into tetrahedra of zero volume. No point moves (Qhull's joggle, ``QJ``,
   would move them). Simplices of four points in one plane (the convex hull's faces,
   lifted, which Qhull may report slightly tilted) are dropped, and the rest must tile
   the convex hull: every point a vertex, the hull's volume, the faces of one tetrahedron
   the hull's area (a hole, however flat, adds area), no face in three; otherwise the
   lift is tried again with ``s`` = 1e-2 (:data:`LIFTS`), then :class:`MeshingError`.
2. *Recovery* (:func:`fill_surface`): inside each planar facet of the surface (input
   triangles joined across edges whose four points lie in one plane) the triangles are
   flipped into the facet's own regular triangulation for the same lifts
   (:func:`regular_flips`: an input's fan of thin triangles is not Delaunay, and no split
   in its plane makes it so; the boundary does not move). The surface triangles that are
   still not faces of the tetrahedra are split, and the points triangulated again, until
   every surface triangle is a face (at most :data:`MAX_ROUNDS` rounds and
   :data:`MAX_GROWTH` x the input's points, else :class:`MeshingError`). Each missing
   triangle marks its longest edge; a triangle with a marked edge marks its own longest
   edge too (repeated until no more, as in longest-edge bisection), and each marked edge
   gets its midpoint ``(a + b) / 2``: a point of the segment, so in the plane of both
   triangles on it (to rounding). A triangle is then bisected at its longest edge and
   each half at the marked edge it kept: 2, 3 or 4 triangles in the parent's plane, the
   surface stays conforming (no hanging points) and every triangle keeps its parent's
   orientation and input triangle (a flip keeps the input triangles of the two, both in
   the facet's plane).
3. *Inside* (:func:`inside_tets`): the tetrahedra joined across faces that are not
   surface triangles form regions; a region is inside where its tetrahedra see a surface
   triangle from its inner side (the triangle is a face of the tetrahedron with the
   tetrahedron's own outward orientation), outside where they see one from its outer side
   or reach the convex hull. Combinatorial, so exact; a region both inside and outside is
   a :class:`MeshingError`.
4. *Check*: the kept tetrahedra have positive volumes and their boundary is the split
   surface, triangle for triangle with the same orientation (:class:`MeshingError`
   otherwise).

Qhull is deterministic and the perturbation is seeded: the same surface gives the same
mesh, bit for bit. Cavities need nothing special: a cavity's tetrahedra see its (inward)
triangles from their outer side.

>>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
>>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
>>> p, t, faces, parent = fill_surface(V, F)
>>> len(p), sorted(t[0].tolist()), sorted(parent.tolist())
(4, [0, 1, 2, 3], [0, 1, 2, 3])
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import MeshingError
from ..mesh import simplex_measures
from ..topology import component_labels, unique
from .quality import TET_FACES

__all__ = ["fill_surface", "lift", "facets", "regular_flips", "regular_tets",
           "missing_triangles", "split_triangles", "inside_tets", "MAX_ROUNDS", "MAX_GROWTH",
           "LIFTS", "SEED", "INNER", "inner_points"]

log = logging.getLogger(__name__)

#: rounds of splitting and triangulating again before giving up
MAX_ROUNDS = 60
#: the most points the recovery may reach, as a multiple of the input's (plus 1,000)
MAX_GROWTH = 50
#: the lift's perturbations tried in turn, relative to the squared distance to the nearest
#: other point (on a torus of 12,000 points Qhull's tiling failed with 1e-6 and passed with
#: 1e-4 and 1e-2)
LIFTS = (1e-4, 1e-2)
#: seed of the lift's perturbation
SEED = 0
#: the step of the lattice of inner points, relative to the cube root of the volume per
#: surface point (a torus of 6,144 triangles meshed at 0.2 to 33,916 tetrahedra without
#: inner points, 23,354 with these; docs/tet.md)
INNER = 1.5

def _keys(tri: np.ndarray, n: int) -> np.ndarray:
    """One int64 per unoriented triangle of points numbered below ``n``."""
    s = np.sort(np.asarray(tri, dtype=np.int64), axis=1)
    if n >= 2_000_000:  # n^3 would overflow int64
        raise MeshingError(f"the surface fill reached {n} points, more than it can number")
    return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]


def lift(p: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """``(q, w)``: the points scaled into [-1, 1]^3 and their perturbed lifts
    ``w = |q|^2 + size u h^2`` (module docstring, step 1)."""
    from scipy.spatial import cKDTree
    lo, hi = p.min(axis=0), p.max(axis=0)
    scale = 0.5 * float((hi - lo).max())
    q = (p - 0.5 * (lo + hi)) / scale
    h = cKDTree(q).query(q, k=2)[0][:, 1]
    u = np.random.default_rng(SEED).random(len(p))
    return q, np.einsum("ij,ij->i", q, q) + size * h * h * u


def regular_tets(p: np.ndarray, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The tetrahedra ``(m, 4)``, positively oriented, of the regular triangulation of the
    points ``p (n, 3)`` (scaled ``q``, lifted ``w``: :func:`lift`): the Delaunay
    tetrahedralisation with co-spherical ties broken (module docstring, step 1); every point
    is a vertex."""
    from scipy.spatial import ConvexHull, QhullError
    n = len(p)
    try:
        # a point above every lift (Qhull's Qz): five points at least, no lower facet lost
        top = np.r_[q.mean(axis=0), w.max() + 1.0]
        hull = ConvexHull(np.r_[np.c_[q, w], top[None]], qhull_options="Qc Q12")
    except QhullError as exc:
        msg = " ".join(str(exc).split()[:12])
        raise MeshingError(f"Qhull could not triangulate {n} points of the surface: "
                           f"{msg}") from None
    # the lower facets (outward normal pointing down), none with the point on top
    lower = (hull.equations[:, 3] < 0) & (hull.simplices < n).all(axis=1)
    t = hull.simplices[lower].astype(np.int64)
    vol = simplex_measures(q, t)
    # four points in one plane: a piece of a vertical facet (a face of the convex hull,
    # lifted), which Qhull may report tilted by rounding where it merged it with a
    # neighbour; left out, and the tiling checked below
    edge = np.linalg.norm(q[t[:, 1:]] - q[t[:, :1]], axis=2).max(axis=1)
    keep = np.abs(vol) > 1e-12 * edge ** 3
    t, vol = t[keep], vol[keep]
    neg = vol < 0
    t[neg, 2], t[neg, 3] = t[neg, 3], t[neg, 2].copy()
    _check_tiling(p, q, t, np.abs(vol))
    return t


def _check_tiling(p, q, t, vol) -> None:
    """:class:`MeshingError` unless the positive tetrahedra ``t`` (volumes ``vol``) of the
    scaled points ``q`` tile their convex hull: every point a vertex, no face in three
    tetrahedra, the hull's volume, and the faces of one tetrahedron the hull's area (to
    1e-9)."""
    from scipy.spatial import ConvexHull
    n = len(q)
    seen = np.zeros(n, dtype=bool)
    seen[t.ravel()] = True
    if not seen.all():
        i = int(np.flatnonzero(~seen)[0])
        raise MeshingError(f"Qhull's tetrahedra leave out {int((~seen).sum())} points of the "
                           f"surface, e.g. ({p[i, 0]:.6g}, {p[i, 1]:.6g}, {p[i, 2]:.6g})")
    hull = ConvexHull(q)
    f = t[:, TET_FACES].reshape(-1, 3)
    _, first, cnt = unique(_keys(f, n), return_index=True, return_counts=True)
    once = q[f[first[cnt == 1]]]
    area = 0.5 * float(np.linalg.norm(np.cross(once[:, 1] - once[:, 0],
                                               once[:, 2] - once[:, 0]), axis=1).sum())
    total = float(vol.sum())
    # a hole (a tetrahedron left out, however flat) adds the area of its faces
    if (cnt > 2).any() or abs(area - hull.area) > 1e-9 * hull.area \
            or abs(total - hull.volume) > 1e-9 * hull.volume:
        raise MeshingError(f"Qhull's tetrahedra of {n} points of the surface are not a "
                           f"tiling of their convex hull (volume {total:.12g}, hull "
                           f"{hull.volume:.12g}; area of the faces of one tetrahedron "
                           f"{area:.12g}, hull {hull.area:.12g}; {int((cnt > 2).sum())} "
                           f"faces in more than two)")


def missing_triangles(tri: np.ndarray, t: np.ndarray, n: int) -> np.ndarray:
    """Whether each triangle ``(k, 3)`` is not a face of the tetrahedra ``t``."""
    faces = np.sort(_keys(t[:, TET_FACES].reshape(-1, 3), n))
    k = _keys(tri, n)
    pos = np.minimum(np.searchsorted(faces, k), len(faces) - 1)
    return faces[pos] != k


def split_triangles(p: np.ndarray, tri: np.ndarray, parent: np.ndarray, bad: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(points, triangles, parent)`` after splitting the triangles ``bad`` (a mask) and
    their neighbours by longest-edge bisection (module docstring, step 2): the new points
    (edge midpoints, in the order of their edges' sorted point pairs) appended."""
    n = len(p)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    edges = np.stack([np.stack([b, c], 1), np.stack([c, a], 1), np.stack([a, b], 1)], 1)
    lo, hi = np.minimum(edges[..., 0], edges[..., 1]), np.maximum(edges[..., 0], edges[..., 1])
    ekey = lo * n + hi                                       # (k, 3): edge opposite vertex j
    length = np.linalg.norm(p[edges[..., 1]] - p[edges[..., 0]], axis=2)
    longest = _longest(length, ekey)
    lkey = ekey[np.arange(len(tri)), longest]
    marked = unique(lkey[bad])
    while True:  # a triangle with a marked edge marks its longest
        has = np.isin(ekey, marked).any(axis=1)
        more = unique(np.r_[marked, lkey[has]])
        if len(more) == len(marked):
            break
        marked = more
    mid = n + np.arange(len(marked))
    new = 0.5 * (p[marked // n] + p[marked % n])
    p = np.r_[p, new]
    out_tri, out_par = [tri[~has]], [parent[~has]]
    for i in np.flatnonzero(has):
        pieces = _bisect(tri[i], ekey[i], longest[i], marked, mid)
        out_tri.append(np.array(pieces, dtype=np.int64))
        out_par.append(np.full(len(pieces), parent[i]))
    return p, np.concatenate(out_tri), np.concatenate(out_par)


def _longest(length: np.ndarray, ekey: np.ndarray) -> np.ndarray:
    """The index (0-2) of each triangle's longest edge, ties to the smallest edge key."""
    best = np.zeros(len(length), dtype=np.int64)
    for j in (1, 2):
        lb = length[np.arange(len(length)), best]
        kb = ekey[np.arange(len(length)), best]
        better = (length[:, j] > lb) | ((length[:, j] == lb) & (ekey[:, j] < kb))
        best[better] = j
    return best


def _bisect(t, ek, j, marked, mid) -> list[tuple[int, int, int]]:
    """The pieces of triangle ``t`` (its edge opposite vertex ``k`` has key ``ek[k]``):
    halved at its longest edge (opposite vertex ``j``, marked), each half at the other
    marked edge it kept."""
    def m(k):
        pos = int(np.searchsorted(marked, ek[k]))
        return int(mid[pos]) if pos < len(marked) and marked[pos] == ek[k] else -1

    v0, v1, v2 = int(t[j]), int(t[(j + 1) % 3]), int(t[(j + 2) % 3])
    c = m(j)                                   # the midpoint of v1-v2, opposite v0
    out = []
    # half (v0, v1, c): its edge v0-v1 is opposite v2 (index j + 2)
    e = m((j + 2) % 3)
    out += [(v0, e, c), (e, v1, c)] if e >= 0 else [(v0, v1, c)]
    # half (v0, c, v2): its edge v2-v0 is opposite v1 (index j + 1)
    e = m((j + 1) % 3)
    out += [(v0, c, e), (e, c, v2)] if e >= 0 else [(v0, c, v2)]
    return out


def facets(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The planar facet of each input triangle ``(m,)``: triangles joined across an edge
    where the fourth point lies in the other's plane (within 1e-12 of the surface's extent;
    their normals then agree), numbered in the order of their first triangles."""
    n = len(V)
    nrm = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    e = np.concatenate([F[:, [1, 2]], F[:, [2, 0]], F[:, [0, 1]]])
    opp = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    tri = np.tile(np.arange(len(F)), 3)
    key = np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1])
    order = np.argsort(key, kind="stable")
    a, b = order[0::2], order[1::2]          # every edge in exactly two triangles
    ta, tb = tri[a], tri[b]
    tol = 1e-12 * float(np.ptp(V, axis=0).max())
    da = np.abs(np.einsum("ij,ij->i", V[opp[b]] - V[F[ta, 0]], nrm[ta]))
    db = np.abs(np.einsum("ij,ij->i", V[opp[a]] - V[F[tb, 0]], nrm[tb]))
    flat = (da <= tol) & (db <= tol)
    return component_labels(len(F), ta[flat], tb[flat])


def regular_flips(q: np.ndarray, w: np.ndarray, tri: np.ndarray, facet: np.ndarray,
                  normal: np.ndarray) -> np.ndarray:
    """``tri`` with the edges inside each planar facet flipped until the facet's triangles
    are its points' 2D regular triangulation for the lifts ``w`` (Lawson's flips; the
    tetrahedra :func:`regular_tets` makes can only hold triangles of that triangulation as
    faces). ``facet`` numbers each triangle's facet, ``normal (k, 3)`` its unit normal;
    flips keep every triangle in its facet's plane and the orientation."""
    tri = tri.copy()
    n = len(q)
    # an orthonormal frame per facet: the lift restricted to a plane is u^2 + v^2 + const
    e1 = np.cross(normal, np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(normal, e1)
    for _ in range(10_000):
        e = np.concatenate([tri[:, [1, 2]], tri[:, [2, 0]], tri[:, [0, 1]]])
        opp = np.concatenate([tri[:, 0], tri[:, 1], tri[:, 2]])
        k = np.tile(np.arange(len(tri)), 3)
        key = np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1])
        order = np.argsort(key, kind="stable")
        x, y = order[0::2], order[1::2]
        tx, ty = k[x], k[y]
        inner = facet[tx] == facet[ty]
        x, y, tx, ty = x[inner], y[inner], tx[inner], ty[inner]
        a, d = opp[x], opp[y]
        b, c = e[x, 0], e[x, 1]            # triangle tx is (a, b, c), ty is (d, c, b)
        f = tx
        # in-plane coordinates from a (the lift relative to a: an affine change, the same
        # test, less rounding)
        uv = [np.stack([np.einsum("ij,ij->i", q[v] - q[a], e1[f]),
                        np.einsum("ij,ij->i", q[v] - q[a], e2[f])], 1) for v in (b, c, d)]
        rows = [np.c_[s, np.einsum("ij,ij->i", s, s) + (w[v] - w[a]) - (np.einsum(
            "ij,ij->i", q[v], q[v]) - np.einsum("ij,ij->i", q[a], q[a]))]
            for s, v in zip(uv, (b, c, d))]
        power = np.einsum("ij,ij->i", rows[0], np.cross(rows[1], rows[2]))

        def orient(r, s):
            return r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]

        sg = np.sign(orient(uv[0], uv[1]))             # (a, b, c)
        # d below the plane of the lifted a, b, c: the edge b-c is not regular; flipped
        # where (a, b, d) and (a, d, c) turn as (a, b, c) does (a convex quadrilateral)
        size = np.einsum("ij,ij->i", uv[1] - uv[0], uv[1] - uv[0]) ** 2
        bad = np.flatnonzero((power * sg < -1e-12 * size)
                             & (orient(uv[0], uv[2]) * sg > 0) & (orient(uv[2], uv[1]) * sg > 0))
        if not len(bad):
            return tri
        used = np.zeros(len(tri), dtype=bool)
        for i in bad[np.argsort(power[bad] * sg[bad], kind="stable")]:
            if used[tx[i]] or used[ty[i]]:
                continue
            used[tx[i]] = used[ty[i]] = True
            tri[tx[i]] = (a[i], b[i], d[i])
            tri[ty[i]] = (a[i], d[i], c[i])
    raise MeshingError("the flips inside the surface's planar facets did not finish")


def inside_tets(t: np.ndarray, tri: np.ndarray, n: int) -> np.ndarray:
    """Whether each tetrahedron ``t`` (positive) is inside the closed outward surface
    ``tri``, every triangle a face of ``t`` (module docstring, step 3)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    f = t[:, TET_FACES].reshape(-1, 3)
    key = _keys(f, n)
    surf = _keys(tri, n)
    on = np.isin(key, surf)
    # tetrahedra sharing a face that is not a surface triangle are in one region
    order = np.argsort(key, kind="stable")
    ks = key[order]
    pair = np.flatnonzero((ks[1:] == ks[:-1]) & ~on[order][1:])
    a, b = order[pair] // 4, order[pair + 1] // 4
    m = len(t)
    _, region = connected_components(coo_matrix((np.ones(len(a)), (a, b)), shape=(m, m)),
                                     directed=False)
    # a face of a tetrahedron on the surface: inside where it has the surface's orientation
    rows = np.flatnonzero(on)
    fr = f[rows]
    so = np.argsort(surf)
    own = tri[so[np.searchsorted(surf[so], key[rows])]]
    same = _cyclic_equal(fr, own)
    k = region.max() + 1
    ins = np.zeros(k, dtype=bool)
    out = np.zeros(k, dtype=bool)
    ins[region[rows[same] // 4]] = True
    out[region[rows[~same] // 4]] = True
    _, inv, cnt = unique(key, return_inverse=True, return_counts=True)
    hull = (cnt[inv.reshape(-1)] == 1) & ~on      # a face of the convex hull
    out[region[np.flatnonzero(hull) // 4]] = True
    both = ins & out
    if both.any():
        raise MeshingError(f"the surface fill found {int(both.sum())} regions of tetrahedra "
                           f"both inside and outside the surface")
    return ins[region]


def _cyclic_equal(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Whether the rows of ``x`` and ``y`` (the same three points) run in the same cyclic
    order."""
    return ((x == y).all(axis=1) | (x == y[:, [1, 2, 0]]).all(axis=1)
            | (x == y[:, [2, 0, 1]]).all(axis=1))


def _triangulate(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, w, tets)``: :func:`regular_tets` with the first perturbation of :data:`LIFTS`
    whose tetrahedra tile the convex hull (the last one's error otherwise)."""
    for size in LIFTS[:-1]:
        q, w = lift(p, size)
        try:
            return q, w, regular_tets(p, q, w)
        except MeshingError as exc:
            log.debug("surface fill: lift %g: %s", size, exc)
    q, w = lift(p, LIFTS[-1])
    return q, w, regular_tets(p, q, w)


def inner_points(V: np.ndarray, F: np.ndarray, spacing: float = INNER) -> np.ndarray:
    """The points of a lattice of step ``spacing x (volume / len(V))^(1/3)`` (cells centred
    in the bounding box) inside the closed outward surface ``V``, ``F`` (ray parity) and
    farther than half a step from it."""
    from .surface import distance_within, ray_parity
    vol = np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6
    step = spacing * float(vol / len(V)) ** (1 / 3)
    lo, hi = V.min(axis=0), V.max(axis=0)
    n = np.maximum(np.floor((hi - lo) / step).astype(np.int64), 1)
    if int(np.prod(n)) > 20 * len(V) + 1000:  # a solid filling little of its box: none
        return np.zeros((0, 3))
    g = [lo[k] + 0.5 * (hi[k] - lo[k] - (n[k] - 1) * step) + step * np.arange(n[k])
         for k in range(3)]
    P = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1).reshape(-1, 3)
    P = P[ray_parity(V, F, P)]
    return P[np.isinf(distance_within(V, F, P, 0.5 * step))]


def fill_surface(V: np.ndarray, F: np.ndarray, name: str = "the surface",
                 spacing: float | None = INNER
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(points, tets, triangles, parent)``: the tetrahedra (positive) inside the closed,
    outward, checked surface ``V``, ``F`` whose boundary is ``triangles``, the input
    triangles split in their planes, ``parent`` the input triangle of each (module
    docstring); with ``spacing``, the :func:`inner_points` of that spacing are vertices
    too. The first ``len(V)`` points are ``V``; :class:`MeshingError` (naming ``name``)
    where the recovery does not converge."""
    p = np.asarray(V, dtype=np.float64)
    tri = np.asarray(F, dtype=np.int64)
    parent = np.arange(len(tri), dtype=np.int64)
    facet = facets(p, tri)
    if spacing is not None:
        p = np.r_[p, inner_points(p, tri, spacing)]
    n_inner = len(p) - len(V)
    nrm = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    normal = np.zeros((int(facet.max()) + 1, 3))
    np.add.at(normal, facet, nrm)                # area-weighted: the facet's normal
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    cap = MAX_GROWTH * len(p) + 1000
    for rounds in range(MAX_ROUNDS + 1):
        q, w, t = _triangulate(p)
        tri = regular_flips(q, w, tri, facet[parent], normal[facet[parent]])
        bad = missing_triangles(tri, t, len(p))
        log.debug("surface fill: round %d, %d points, %d of %d triangles missing", rounds,
                  len(p), int(bad.sum()), len(tri))
        if not bad.any():
            break
        if rounds == MAX_ROUNDS or len(p) > cap:
            c = p[tri[bad][0]].mean(axis=0)
            raise MeshingError(f"the surface fill of {name} did not converge: after "
                               f"{rounds} rounds ({len(p)} points) {int(bad.sum())} surface "
                               f"triangles are still not faces of the tetrahedra, e.g. at "
                               f"({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g})")
        p, tri, parent = split_triangles(p, tri, parent, bad)
    keep = inside_tets(t, tri, len(p))
    t = t[keep]
    _check_boundary(p, t, tri, name)
    log.info("surface fill: %d rounds, %d points (%d inside, %d added on the surface), %d "
             "tetrahedra", rounds, len(p), n_inner, len(p) - len(V) - n_inner, len(t))
    return p, t, tri, parent


def _check_boundary(p, t, tri, name: str) -> None:
    """:class:`MeshingError` unless the tetrahedra are positive and their boundary faces
    are the triangles ``tri``, each with its orientation."""
    n = len(p)
    if not len(t) or (simplex_measures(p, t) <= 0).any():
        raise MeshingError(f"the surface fill of {name} made no tetrahedra or flat ones")
    f = t[:, TET_FACES].reshape(-1, 3)
    _, inv, cnt = unique(_keys(f, n), return_inverse=True, return_counts=True)
    bnd = f[cnt[inv.reshape(-1)] == 1]
    kb, ks = _keys(bnd, n), _keys(tri, n)
    if len(kb) != len(ks) or not np.array_equal(np.sort(kb), np.sort(ks)):
        raise MeshingError(f"the surface fill of {name}: the tetrahedra's {len(kb)} boundary "
                           f"triangles are not the {len(ks)} of the split surface")
    ob, os_ = np.argsort(kb), np.argsort(ks)
    if not _cyclic_equal(bnd[ob], tri[os_]).all():
        raise MeshingError(f"the surface fill of {name}: boundary triangles turned inward")
