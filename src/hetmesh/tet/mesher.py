"""The tetrahedral mesher: layers, Delaunay slabs, delta repair, verification.

``generate_tets(solid, field, threshold)`` fills a :class:`~hetmesh.tet.solid.Prism` with
tetrahedra whose composition variation over their four vertices is below ``threshold``
(delta_max < delta_0, strictly), every one of positive volume, conforming, its boundary
faces exactly the solid's planar faces (and within the chord tolerance of its curved ones).

Two placements (:mod:`hetmesh.tet.place`):

* *planar levels* -- the composition varies along the prism's axis only: the level surfaces
  are planes across the prism. Each slab between two adjacent planes is tetrahedrised on its
  own (3D Delaunay of the two layers' points); a tetrahedron of a slab has its vertices on
  both planes, so its delta is the level step exactly, and two slabs meet on the 2D Delaunay
  triangulation of their shared layer (the restriction of both), so the mesh conforms.
* *curved levels* -- otherwise: every layer's points are moved along the axis onto their
  level, caps get their own layers, and one 3D Delaunay triangulation of all points fills
  the (convex) prism.

Then violators left are repaired by bisecting their largest-jump edges
(:mod:`hetmesh.tet.refine`) until none is left or the element budget is spent
(:class:`~hetmesh.errors.BudgetError`), and :func:`hetmesh.tet.verify.verify_tets` checks
every claim (:class:`~hetmesh.errors.VerificationError` if one fails).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import Delaunay

from ..errors import BudgetError, GeometryError, MeshingError, OptionError
from ..mesh import simplex_measures
from ..topology import unique
from .faces import boundary_faces
from .field3d import scalar_column
from .place import BOUNDARY_GAP, arc_count, column_roots, level_values, section_points
from .quality import min_dihedral
from .refine import repair
from .verify import verify_tets

__all__ = ["TetResult", "generate_tets", "estimate_tets", "n_iso3", "is_planar", "BETA"]

log = logging.getLogger(__name__)

#: level step as a fraction of delta_0
BETA = 0.95
#: default chord tolerance of curved faces, x the solid's diameter
CHORD = 2e-3
#: largest ratio of the spacings of adjacent layers
GRADE = 1.5
#: ratio of consecutive layer spacings on the ladder (:func:`_ladder`)
LADDER = 2.0 ** (1.0 / 3.0)
#: largest node spacing in a prism with curved faces, x their chord-limited step
ARC_SPACING = 2.0
#: sliver removal: vertices of tetrahedra with a dihedral angle below this (degrees) move
SLIVER_ANGLE = 15.0
#: sliver removal rounds
SLIVER_ROUNDS = 12
#: largest in-plane move of a vertex in sliver removal, x its layer's spacing
PERTURB = 0.15

@dataclass
class TetResult:
    """A verified tetrahedral mesh and what was measured on it."""

    points: np.ndarray          # (N, 3) float64
    tets: np.ndarray            # (M, 4) int32, positively oriented
    faces: np.ndarray           # (K, 3) int32 boundary triangles, outward
    face_markers: np.ndarray    # (K,) int32, 1 + index into face_names
    face_names: tuple[str, ...]
    delta: np.ndarray           # (M,) delta(T) over the vertices
    threshold: float
    info: dict = field(default_factory=dict)
    mesh: object = None         # the hetmesh.mesh.Mesh (hetmesh.tet.api.to_mesh)


def n_iso3(solid, field, threshold: float, n: int = 48) -> float:
    """N_iso3 = 6 sqrt(2) * integral |grad f|^3 dV / delta_0^3: the number of regular
    tetrahedra of edge delta_0 / |grad f| filling the solid (midpoint rule on an ``n``^3
    grid; ``|grad f|`` the largest constituent gradient norm)."""
    lo, hi = solid.bounds
    h = (hi - lo) / n
    g = [lo[k] + h[k] * (np.arange(n) + 0.5) for k in range(3)]
    p = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1).reshape(-1, 3)
    p = p[solid.contains(p)]
    gn = np.linalg.norm(field.gradient(p), axis=2).max(axis=1)
    integral = float((gn ** 3).sum() * np.prod(h))
    return 6.0 * math.sqrt(2.0) * integral / threshold ** 3


def estimate_tets(solid, field, threshold: float) -> float:
    """A-priori element count of the layered placement: about 3 |grad f|^3 / df^3 tetrahedra
    per unit volume (the face-centred cubic arrangement between levels df apart), i.e.
    ``N_iso3 / (2 sqrt(2) BETA^3)``, with 20 % for the boundary layers and grading."""
    base = n_iso3(solid, field, threshold) / (2.0 * math.sqrt(2.0) * BETA ** 3)
    return 1.2 * base + 100.0


def _scalar(field, solid, j):
    def F(q, s):
        return field.composition(solid.to3d(q, s))[:, j]
    return F


def is_planar(field, solid, samples: np.ndarray) -> bool:
    """Whether the composition depends on the axis coordinate only (at the samples)."""
    q, s = solid.to2d(samples)
    ref = solid.section.polygon().representative_point()
    qr = np.tile([ref.x, ref.y], (len(s), 1))
    a = field.composition(samples)
    b = field.composition(solid.to3d(qr, s))
    return bool(np.abs(a - b).max() <= 1e-12)


def _smooth_spacing(a: np.ndarray, grade: float = GRADE) -> np.ndarray:
    a = a.copy()
    for _ in range(len(a)):
        b = a.copy()
        b[1:] = np.minimum(b[1:], grade * a[:-1])
        b[:-1] = np.minimum(b[:-1], grade * a[1:])
        if np.array_equal(a, b):
            break
        a = b
    return a


def _ladder(a: np.ndarray, ratio: float = LADDER) -> np.ndarray:
    """Spacings rounded down to the ladder ``a_min * ratio**i``: runs of adjacent layers
    share one spacing (a perfect offset lattice between them, no slivers); only where the
    spacing steps up do two different lattices meet."""
    a0 = float(a.min())
    i = np.floor(np.log(a / a0) / np.log(ratio) + 1e-9)
    return a0 * ratio ** i


def _planes(F1, s0: float, s1: float, levels: np.ndarray, n: int = 4097) -> np.ndarray:
    """Axis values of the planes: the caps and every crossing of a level (1D roots)."""
    ss = np.linspace(s0, s1, n)
    v = F1(ss)
    out = [s0, s1]
    for lev in levels:
        d = v - lev
        idx = np.flatnonzero(d[:-1] * d[1:] < 0)
        # samples on the level: the ends of every run of them (a plateau at the level, a
        # constant composition, is one plane at each end, not a plane per sample: a
        # constant composition gave 4,097 planes and ran for minutes)
        z = d == 0
        idx = np.r_[idx, np.flatnonzero(z & ~np.r_[False, z[:-1]]),
                    np.flatnonzero(z & ~np.r_[z[1:], False])]
        for i in unique(idx):
            if d[i] == 0:
                out.append(ss[i])
                continue
            a, b, fa = ss[i], ss[i + 1], d[i]
            for _ in range(80):
                m = 0.5 * (a + b)
                fm = F1(np.array([m]))[0] - lev
                if np.sign(fm) == np.sign(fa):
                    a, fa = m, fm
                else:
                    b = m
            out.append(0.5 * (a + b))
    s = unique(np.array(out))
    tol = 1e-9 * (s1 - s0)
    keep = np.r_[True, np.diff(s) > tol]
    s = s[keep]
    s[0], s[-1] = s0, s1
    if len(s) >= 2 and s[-2] >= s1 - tol:
        s = np.r_[s[:-2], s1]
    return s


def _layers_planar(solid, field, threshold, rng, chord_tol, h_max):
    """Points per plane ``[(n_k, 3)]`` of the planar-level placement, and the level step."""
    sec = solid.section
    ref = sec.polygon().representative_point()

    def F1(s):
        s = np.asarray(s, dtype=float)
        return field.composition(solid.to3d(np.tile([ref.x, ref.y], (len(s), 1)), s))

    ss = np.linspace(solid.s0, solid.s1, 4097)
    c = F1(ss)
    j = int(np.argmax(np.abs(np.diff(c, axis=0)).sum(axis=0)))
    lev = level_values(float(c[:, j].min()), float(c[:, j].max()), BETA * threshold)
    s = _planes(lambda t: F1(t)[:, j], solid.s0, solid.s1, lev)
    # planes between levels where the gap is over what the largest spacing can shape well
    g_max = h_max / np.sqrt(2.0)
    n_sub = np.maximum(1, np.ceil(np.diff(s) / g_max - 1e-9)).astype(int)
    if (n_sub > 1).any():
        s = np.concatenate([s[k] + (s[k + 1] - s[k]) * np.arange(n_sub[k]) / n_sub[k]
                            for k in range(len(s) - 1)] + [s[-1:]])
    gaps = np.diff(s)
    lo = np.r_[gaps[0], gaps]
    hi = np.r_[gaps, gaps[-1]]
    a = np.sqrt(2.0) * np.sqrt(lo * hi)
    a = _ladder(_smooth_spacing(np.minimum(a, h_max)))
    layers, fixed = [], []
    for k, (sk, ak) in enumerate(zip(s, a)):
        q, onb = section_points(sec, float(ak), k, rng, chord_tol)
        layers.append(solid.to3d(q, np.full(len(q), sk)))
        # interior points far enough from the boundary may slide in their plane
        free = ~onb
        free[free] = sec.distance_to_boundary(q[free]) >= (BOUNDARY_GAP - PERTURB) * ak
        fixed.append(~free)
    return layers, fixed, a, float(np.diff(lev).max()) if len(lev) > 1 else 0.0


def _delaunay(points: np.ndarray, axis: int | None = None) -> np.ndarray:
    """Positively oriented Delaunay tetrahedra of ``points`` (Qhull), flat ones dropped.

    ``axis``: the points lie on planes across this axis (a slab). Qhull is then slow (the
    lifted points of a plane lie in one hyperplane that supports the lifted set: a facet
    with thousands of points, merged in quadratic time); two helper points far beyond the
    planes along the axis take that support away (14 x faster on 5,000 points, the same
    tetrahedra between the planes) and their tetrahedra are dropped.
    """
    if len(points) < 4:
        return np.empty((0, 4), dtype=np.int64)
    c = 0.5 * (points.min(axis=0) + points.max(axis=0))
    q = points - c
    n = len(q)
    if axis is not None:
        far = 10.0 * float(np.ptp(points, axis=0).max())
        helpers = np.zeros((2, 3))
        helpers[0, axis], helpers[1, axis] = -far, far
        q = np.concatenate([q, helpers])
    try:
        d = Delaunay(q)
    except Exception as exc:  # scipy raises QhullError (a RuntimeError)
        raise MeshingError(f"3D Delaunay triangulation failed: {exc}".splitlines()[0]) \
            from None
    t = d.simplices.astype(np.int64)
    if axis is not None:
        t = t[(t < n).all(axis=1)]
    v = simplex_measures(points, t)
    neg = v < 0
    t[neg, 2], t[neg, 3] = t[neg, 3], t[neg, 2].copy()
    scale = np.ptp(points, axis=0).max() ** 3
    return t[np.abs(v) > 1e-14 * scale]


def _slab(layers, k, axis: int | None = None):
    """Delaunay tetrahedra of slab ``k`` (layers ``k`` and ``k + 1``), local ids."""
    return _delaunay(np.concatenate([layers[k], layers[k + 1]]), axis)


def circumspheres(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres ``(M, 3)`` and radii ``(M,)`` of the tetrahedra's circumscribed spheres."""
    a = points[tets[:, 0]]
    u, v, w = (points[tets[:, k]] - a for k in (1, 2, 3))
    vw, wu, uv = np.cross(v, w), np.cross(w, u), np.cross(u, v)
    den = 2.0 * np.einsum("ij,ij->i", u, vw)
    with np.errstate(divide="ignore", invalid="ignore"):
        off = ((u * u).sum(1)[:, None] * vw + (v * v).sum(1)[:, None] * wu
               + (w * w).sum(1)[:, None] * uv) / den[:, None]
    return a + off, np.linalg.norm(off, axis=1)


def _local_delaunay(p_old: np.ndarray, p_new: np.ndarray, tets: np.ndarray,
                    moved: np.ndarray, axis: int | None = None) -> np.ndarray | None:
    """The Delaunay tetrahedra of ``p_new`` from those of ``p_old`` (``tets``), where only
    the points ``moved`` (ids) differ: the tetrahedra in conflict (around a moved point's old
    position, or with a new position inside their sphere) are replaced by the globally empty
    ones among the Delaunay tetrahedra of their vertices and the moved points. None if the
    replacement does not fill the same volume (then the caller triangulates again)."""
    from scipy.spatial import cKDTree

    if not len(moved):
        return tets
    is_moved = np.zeros(len(p_old), dtype=bool)
    is_moved[moved] = True
    cc, r = circumspheres(p_old, tets)
    dist, _ = cKDTree(p_new[moved]).query(cc)
    conflict = is_moved[tets].any(axis=1) | (dist < r * (1 - 1e-9))
    cav = tets[conflict]
    verts = unique(np.r_[cav.ravel(), moved])
    local = _delaunay(p_new[verts], axis)
    if not len(local):
        return None
    cand = verts[local]
    c2, r2 = circumspheres(p_new, cand)
    d2, _ = cKDTree(p_new).query(c2)
    cand = cand[d2 >= r2 * (1 - 1e-9)]
    kept = tets[~conflict]
    # candidates already among the kept tetrahedra are not new
    n = len(p_new) + 1
    def keys(t):
        st = np.sort(t, axis=1).astype(np.int64)
        return ((st[:, 0] * n + st[:, 1]) * n + st[:, 2]) * n + st[:, 3]
    new = cand[~np.isin(keys(cand), keys(kept))]
    vol_new = simplex_measures(p_new, new)
    want = float(np.abs(simplex_measures(p_old, cav)).sum())
    if (vol_new <= 0).any() or abs(float(vol_new.sum()) - want) > 1e-9 * max(want, 1e-300) \
            + 1e-12 * float(np.abs(simplex_measures(p_old, kept)).sum()):
        return None
    return np.concatenate([kept, new])


def _mesh_planar(layers, fixed, spacing, axis, rng, target: float | None = None,
                 rounds: int | None = None):
    """Slab by slab Delaunay of the planar layers, then sliver removal by perturbation:
    the free vertices of tetrahedra with a dihedral angle below ``target`` slide in their
    plane by up to :data:`PERTURB` x the layer spacing (random, from ``rng``); a move is
    kept where the worst dihedral angle around the vertex got better, and the two slabs
    around a moved vertex are triangulated again. Global ids in layer order."""
    target = SLIVER_ANGLE if target is None else target
    rounds = SLIVER_ROUNDS if rounds is None else rounds
    layers = [p.copy() for p in layers]
    nl = len(layers)
    slabs = [_slab(layers, k, axis) for k in range(nl - 1)]
    inplane = [i for i in range(3) if i != axis]

    def _update(k, prev, moved):
        """Slab ``k`` after the points flagged in ``moved`` (per layer) moved from
        ``prev``: locally if the local update is consistent, else triangulated again."""
        ids = np.r_[np.flatnonzero(moved[k]), len(layers[k]) + np.flatnonzero(moved[k + 1])]
        p_old = np.concatenate([prev[k], prev[k + 1]])
        p_new = np.concatenate([layers[k], layers[k + 1]])
        t = _local_delaunay(p_old, p_new, slabs[k], ids, axis) if len(ids) else slabs[k]
        slabs[k] = _slab(layers, k, axis) if t is None else t

    def worst(k):
        """Per layer-k and layer-(k+1) point: the smallest dihedral of its slab-k tets."""
        p = np.concatenate([layers[k], layers[k + 1]])
        md = min_dihedral(p, slabs[k])
        w = np.full(len(p), 180.0)
        np.minimum.at(w, slabs[k].ravel(), np.repeat(md, 4))
        return md, w[:len(layers[k])], w[len(layers[k]):]

    stats = [worst(k) for k in range(nl - 1)]
    for _ in range(rounds):
        before = [np.full(len(layers[j]), 180.0) for j in range(nl)]
        for k, (_, wa, wb) in enumerate(stats):
            np.minimum(before[k], wa, out=before[k])
            np.minimum(before[k + 1], wb, out=before[k + 1])
        move = [(before[j] < target) & ~fixed[j] for j in range(nl)]
        if not any(m.any() for m in move):
            break
        old = [layers[j][move[j]].copy() for j in range(nl)]
        prev = [layers[j].copy() for j in range(nl)]
        for j in range(nl):
            n = int(move[j].sum())
            if n:
                r = PERTURB * spacing[j] * np.sqrt(rng.uniform(0, 1, n))
                th = rng.uniform(0, 2 * np.pi, n)
                d = np.column_stack([r * np.cos(th), r * np.sin(th)])
                sub = layers[j][move[j]]
                sub[:, inplane] += d
                layers[j][move[j]] = sub
        touched = sorted({k for j in range(nl) if move[j].any() for k in (j - 1, j)
                          if 0 <= k < nl - 1})
        for k in touched:
            _update(k, prev, move)
        after = [np.full(len(layers[j]), 180.0) for j in range(nl)]
        for k in touched:
            _, wa, wb = worst(k)
            np.minimum(after[k], wa, out=after[k])
            np.minimum(after[k + 1], wb, out=after[k + 1])
        # untouched slabs keep their values
        for k in range(nl - 1):
            if k not in touched:
                np.minimum(after[k], stats[k][1], out=after[k])
                np.minimum(after[k + 1], stats[k][2], out=after[k + 1])
        redo = set()
        prev = [layers[j].copy() for j in range(nl)]
        back_all = []
        for j in range(nl):
            worse = move[j].copy()
            worse[move[j]] = after[j][move[j]] < before[j][move[j]]
            back_all.append(worse)
            if worse.any():
                sub = layers[j][move[j]]
                back = worse[move[j]]
                sub[back] = old[j][back]
                layers[j][move[j]] = sub
                redo.update(k for k in (j - 1, j) if 0 <= k < nl - 1)
        for k in sorted(redo):
            _update(k, prev, back_all)
        for k in set(touched) | redo:
            stats[k] = worst(k)
    offs = np.r_[0, np.cumsum([len(p) for p in layers])]
    out = []
    for k in range(nl - 1):
        ids = np.r_[offs[k] + np.arange(len(layers[k])),
                    offs[k + 1] + np.arange(len(layers[k + 1]))]
        out.append(ids[slabs[k]])
    return np.concatenate(layers), np.concatenate(out)


def _layers_curved(solid, field, threshold, rng, chord_tol, h_max, samples):
    """Points of the curved-level placement (levels moved along the axis) and caps."""
    sec = solid.section
    j = scalar_column(field, samples)
    F = _scalar(field, solid, j)
    fs = field.composition(samples)[:, j]
    lev = level_values(float(fs.min()), float(fs.max()), BETA * threshold)
    df = float(np.diff(lev).max()) if len(lev) > 1 else threshold
    probe, _ = section_points(sec, sec.diameter / 12, 0, np.random.default_rng(0), chord_tol)
    out = []
    L = solid.length
    cap_spacing = []
    for k, f_k in enumerate(lev):
        s = column_roots(F, probe, solid.s0, solid.s1, f_k)
        ok = np.isfinite(s)
        if not ok.any():
            continue
        g = np.linalg.norm(field.gradient(solid.to3d(probe[ok], s[ok]))[:, j], axis=1)
        w = df / np.maximum(np.median(g), 1e-300)
        a = float(min(np.sqrt(2.0) * w, h_max))
        q, _ = section_points(sec, a, k, rng, chord_tol)
        s = column_roots(F, q, solid.s0, solid.s1, f_k)
        ok = np.isfinite(s)
        # keep clear of the caps: they get layers of their own
        ok &= (s - solid.s0 > 0.5 * w) & (solid.s1 - s > 0.5 * w) | \
            (np.abs(s - solid.s0) <= 1e-12 * L) | (np.abs(solid.s1 - s) <= 1e-12 * L)
        out.append(solid.to3d(q[ok], s[ok]))
        cap_spacing.append(a)
    a_cap = float(min(cap_spacing)) if cap_spacing else h_max
    for k, sc in enumerate((solid.s0, solid.s1)):
        q, _ = section_points(sec, a_cap, k, rng, chord_tol)
        out.append(solid.to3d(q, np.full(len(q), sc)))
    pts = np.concatenate(out)
    # caps' points may coincide with level points on a cap: keep the first copy
    _, first = unique(np.round(pts / (1e-10 * solid.diameter)), axis=0, return_index=True)
    pts = pts[np.sort(first)]
    return pts, df


def generate_tets(solid, field, threshold: float, *, seed: int = 0,
                  chord_tol: float | None = None, max_elements: int | None = None,
                  h_max: float | None = None, check: bool = True) -> TetResult:
    """Tetrahedralise ``solid`` so that every element's delta is below ``threshold``.

    Parameters
    ----------
    solid : Prism
        A convex prism (box, cylinder, extrusion of a convex section).
    field : material field on ``(N, 3)`` points
    threshold : float
        delta_0, in (0, 1].
    seed : int
        Seed of the jitter: same inputs and seed, same mesh, bit for bit.
    chord_tol : float, optional
        Largest distance between a curved face and its triangles (default
        :data:`CHORD` x the diameter).
    max_elements : int, optional
        Element budget; :class:`BudgetError` if the estimate or the mesh exceeds it.
    h_max : float, optional
        Largest node spacing (default: the section's diameter / 2).
    """
    t0 = time.perf_counter()
    if not (isinstance(threshold, (int, float)) and 0 < threshold <= 1):
        raise OptionError(f"threshold must be in (0, 1], got {threshold!r}")
    if not solid.convex:
        raise GeometryError("the layered tetrahedral mesher needs a convex solid (a convex "
                            "section without holes); this one is not")
    chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
    hmax = solid.section.diameter / 2
    if h_max is not None:
        hmax = min(hmax, float(h_max))
    arcs = [c.curve for c in solid.section.curves if hasattr(c.curve, "radius")]
    if arcs:
        # tetrahedra at a curved face are shaped by its step: keep the spacing within
        # ARC_SPACING x that step
        step = min(c.length / arc_count(c, chord) for c in arcs)
        hmax = min(hmax, ARC_SPACING * step)
    est = estimate_tets(solid, field, threshold)
    if max_elements is not None and est > max_elements:
        raise BudgetError(f"about {est:.0f} tetrahedra are needed for delta_0 = {threshold} "
                          f"but the budget is {max_elements}")
    rng = np.random.default_rng(seed)
    samples = solid.sample(24)
    planar = is_planar(field, solid, samples)
    if planar:
        layers, fixed, spacing, df = _layers_planar(solid, field, threshold, rng, chord,
                                                    hmax)
        points, tets = _mesh_planar(layers, fixed, spacing, solid.axis, rng)
    else:
        points, df = _layers_curved(solid, field, threshold, rng, chord, hmax, samples)
        tets = _delaunay(points)
    t_place = time.perf_counter() - t0
    points, tets, comp, delta, passes = repair(points, tets, field, threshold,
                                               max_elements=max_elements)
    tets = tets.astype(np.int32)
    faces, _ = boundary_faces(tets)
    markers = solid.classify_faces(points[faces]) + 1
    info = {"placement": "planar" if planar else "curved", "level_step": df,
            "repair_passes": passes, "estimate": est, "composition": comp,
            "time_place": t_place, "time_total": time.perf_counter() - t0}
    res = TetResult(points, tets, faces.astype(np.int32), markers.astype(np.int32),
                    tuple(solid.face_names), delta, float(threshold), info)
    if check:
        verify_tets(res, solid, field, chord)
    res.info["time_total"] = time.perf_counter() - t0
    log.info("tet mesh: %d points, %d tetrahedra, %d repair passes, %.2f s",
             len(points), len(tets), passes, res.info["time_total"])
    return res
