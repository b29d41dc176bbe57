"""delta(T) of tetrahedra by another sampling than the vertices, and the repair that meets
delta_0 under it.

``sampling = "dense"``: delta(T) also over the order-4 lattice of every tetrahedron (35
points, :func:`hetmesh.metrics.delta_dense`); ``"certified"``: an upper bound on the
variation over the whole tetrahedron (:func:`hetmesh.certify.certified_delta`: formulas in
x, y, z, and extruded or revolved 2D formulas and feature trees); ``"pixels"`` (a material
from a 3D volume): delta(T) over every voxel centre a tetrahedron covers and its four
vertices (:meth:`hetmesh.material.image.ImageField.pixel_delta`). The mesher places and
repairs by the vertices first; :func:`resample` then bisects every tetrahedron whose sampled
delta still reaches delta_0 and verifies the result with that delta. The subregions of an
extruded feature-tree model travel with the tetrahedra (a child takes its parent's), and
each tetrahedron is sampled in its own subregion. A violator's vertices may agree (a peak
inside it), so the edge with the largest composition jump is no guide: its longest edge is
split instead (many at a time, :func:`hetmesh.tet.refine.select_edges` ranking edges by
length), which shrinks tetrahedra without flattening them; the boundary triangles split
with their edges (:func:`bisect_faces`), so the boundary and its face names stay.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np

from ..delta import element_delta
from ..errors import BudgetError, MeshingError
from ..options import check_sampling
from ..refinement import check_budget, check_progress
from .refine import MAX_PASSES, bisect_edges, select_edges

__all__ = ["sampled_delta", "repair_sampled", "bisect_faces", "resample", "Repaired",
           "TET_SAMPLINGS", "result_problems", "worst_violator"]

log = logging.getLogger(__name__)

#: the samplings of the tetrahedral mesher
TET_SAMPLINGS = ("vertices", "dense", "certified", "pixels")


def sampled_delta(field, sampling: str, threshold: float | None = None):
    """``delta_of(points, tets, comp, regions=None)``: delta(T) of ``tets`` by ``sampling``
    (:func:`hetmesh.delta.element_delta`; ``comp`` the compositions at ``points``,
    ``regions`` every tetrahedron's subregion for a piecewise field; ``threshold`` lets the
    certified bound stop once an element is decided against it)."""
    check_sampling(field, sampling)

    def delta_of(points: np.ndarray, tets: np.ndarray, comp: np.ndarray,
                 regions: np.ndarray | None = None) -> np.ndarray:
        if not len(tets):
            return np.zeros(0)
        return element_delta(field, points, tets, sampling, composition=comp,
                             regions=regions, threshold=threshold)
    return delta_of


class Repaired(NamedTuple):
    """What :func:`repair_sampled` returns: the mesh, the compositions at its points, its
    sampled delta, the number of passes, every tetrahedron's subregion (None without) and
    the boundary triangles with their face markers (None if none were given)."""

    points: np.ndarray
    tets: np.ndarray
    comp: np.ndarray
    delta: np.ndarray
    passes: int
    regions: np.ndarray | None
    faces: np.ndarray | None
    markers: np.ndarray | None


def repair_sampled(points: np.ndarray, tets: np.ndarray, comp: np.ndarray, field,
                   threshold: float, delta_of, *, max_elements: int | None = None,
                   regions: np.ndarray | None = None,
                   faces: np.ndarray | None = None,
                   markers: np.ndarray | None = None) -> Repaired:
    """Bisect the longest edges (max norm) of the tetrahedra with ``delta_of(points, tets,
    comp, regions) >= threshold`` until there are none (:class:`Repaired`). ``regions``:
    every tetrahedron's subregion, children inheriting their parent's; ``faces`` and
    ``markers``: the boundary triangles and their face markers, a triangle split with its
    edge into two that keep its marker (the boundary does not move).
    :class:`BudgetError` past ``max_elements``, :class:`MeshingError` after
    :data:`~hetmesh.tet.refine.MAX_PASSES` passes.

    Local: a pass works on the patch of tetrahedra that share a vertex with a violator
    (every tetrahedron holding one of their edges is in it, so the selection is that of the
    whole mesh, :func:`~hetmesh.tet.refine.select_edges`), and only the tetrahedra it makes
    are sampled again; the others keep their place and delta (new ones come last).
    """
    tets = np.asarray(tets, np.int64)
    delta = delta_of(points, tets, comp, regions)
    passes = 0
    while (bad := delta >= threshold).any():
        if passes >= MAX_PASSES:
            raise MeshingError(f"sampled delta repair did not converge in {MAX_PASSES} "
                               f"passes ({int(bad.sum())} tetrahedra left; "
                               f"{worst_violator(points, tets, delta, bad)})")
        if max_elements is not None and len(tets) > max_elements:
            try:
                check_budget(len(tets), max_elements)
            except BudgetError as err:
                raise BudgetError(f"{err} ({int(bad.sum())} tetrahedra left at delta >= "
                                  f"{threshold:g}; "
                                  f"{worst_violator(points, tets, delta, bad)})") from None
        mark = np.zeros(len(points), dtype=bool)
        mark[tets[bad]] = True
        patch = mark[tets].any(axis=1)
        sub = tets[patch]
        # coordinates as the values whose jumps rank the edges: the longest edge
        split = select_edges(sub, points, bad[patch])
        n0 = len(points)
        if faces is not None:
            faces, markers = bisect_faces(faces, markers, split, n0)
        points, made, parent = bisect_edges(points, sub, split, with_parents=True)
        check_progress(n0, len(points), passes, int(bad.sum()), 0, threshold)
        comp = np.concatenate([comp, field.composition(points[n0:])])
        tets = np.concatenate([tets[~patch], made])
        made_reg = None
        if regions is not None:
            made_reg = regions[patch][parent]
            regions = np.concatenate([regions[~patch], made_reg])
        delta = np.concatenate([delta[~patch], delta_of(points, made, comp, made_reg)])
        passes += 1
    return Repaired(points, tets, comp, delta, passes, regions, faces, markers)


def worst_violator(points: np.ndarray, tets: np.ndarray, delta: np.ndarray,
                   bad: np.ndarray) -> str:
    """Where the repair is stuck, for its error message: the violating tetrahedron with the
    largest delta, its centroid and its longest edge.

    >>> p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    >>> worst_violator(p, np.array([[0, 1, 2, 3]]), np.array([0.5]), np.array([True]))
    'the worst has delta 0.5 at (0.25, 0.25, 0.25), longest edge 1.41'
    """
    k = int(np.argmax(np.where(bad, delta, -np.inf)))
    c = points[tets[k]]
    x, y, z = c.mean(axis=0)
    edge = max(float(np.linalg.norm(c[i] - c[j])) for i in range(4) for j in range(i))
    return (f"the worst has delta {delta[k]:.4g} at ({x:.6g}, {y:.6g}, {z:.6g}), "
            f"longest edge {edge:.3g}")


def bisect_faces(faces: np.ndarray, markers: np.ndarray, split: np.ndarray, n0: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The boundary triangles after :func:`~hetmesh.tet.refine.bisect_edges` splits the
    edges ``split (K, 2)`` with new points ``n0 + k`` (in the order of the rows of
    ``split`` sorted within each row, as it numbers them): each triangle holding a split
    edge (one at most: it belongs to one tetrahedron) becomes two with its marker.

    >>> f, m = bisect_faces(np.array([[0, 1, 2]]), np.array([7]), np.array([[1, 0]]), 3)
    >>> f.tolist(), m.tolist()
    ([[3, 1, 2], [0, 3, 2]], [7, 7])
    """
    if not len(split):
        return faces, markers
    s = np.sort(split, axis=1).astype(np.int64)
    nn = int(max(faces.max(), s.max())) + 1
    skey = s[:, 0] * nn + s[:, 1]
    order = np.argsort(skey)
    f = faces.astype(np.int64)
    hit = np.full(len(f), -1, dtype=np.int64)
    side = np.zeros(len(f), dtype=np.int64)
    for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        a, b = np.minimum(f[:, i], f[:, j]), np.maximum(f[:, i], f[:, j])
        pos = np.clip(np.searchsorted(skey[order], a * nn + b), 0, len(s) - 1)
        found = skey[order][pos] == a * nn + b
        hit[found] = order[pos[found]]
        side[found] = k
    rows = np.flatnonzero(hit >= 0)
    if not len(rows):
        return faces, markers
    mid = n0 + hit[rows]
    i = np.array([0, 1, 2])[side[rows]]
    j = np.array([1, 2, 0])[side[rows]]
    r = np.arange(len(rows))
    first, second = f[rows].copy(), f[rows].copy()
    first[r, i] = mid  # keeps vertex j
    second[r, j] = mid  # keeps vertex i
    keep = hit < 0
    out = np.concatenate([f[keep], first, second]).astype(faces.dtype)
    return out, np.concatenate([markers[keep], markers[rows], markers[rows]])


def resample(res, solid, field, sampling: str, *, max_elements: int | None = None,
             chord_tol: float | None = None, check: bool = True):
    """``res`` (a :class:`~hetmesh.tet.mesher.TetResult` meeting delta_0 at its vertices)
    refined until delta(T) by ``sampling`` is below delta_0 everywhere, its ``delta`` that
    sampled one (``info["sampling"]``, ``info["sampling_passes"]``), verified: the whole
    mesh again if it was refined (:func:`hetmesh.tet.verify.tet_problems`, with
    ``chord_tol`` absolute, default 2e-3 x the solid's diameter: edge bisection never moves
    a face away from the solid), else the sampled delta (the mesher verified the rest)."""
    from .mesher import CHORD, TetResult

    if sampling == "vertices":
        return res
    delta_of = sampled_delta(field, sampling, res.threshold)
    comp = res.info.get("composition")
    if comp is None:
        comp = field.composition(res.points)
    regions = res.info.get("regions")
    rep = repair_sampled(res.points, res.tets.astype(np.int64), comp, field, res.threshold,
                         delta_of, max_elements=max_elements,
                         regions=None if regions is None else np.asarray(regions, np.int64),
                         faces=res.faces, markers=res.face_markers)
    delta, passes = rep.delta, rep.passes
    info = dict(res.info, composition=rep.comp, sampling=sampling, sampling_passes=passes)
    if rep.regions is not None:
        info["regions"] = rep.regions.astype(np.int32)
    if passes:
        res = TetResult(rep.points, rep.tets.astype(np.int32), rep.faces.astype(np.int32),
                        rep.markers.astype(np.int32), res.face_names, delta, res.threshold,
                        info)
    else:
        res = TetResult(res.points, res.tets, res.faces, res.face_markers, res.face_names,
                        delta, res.threshold, info)
    if check and not passes:  # the mesher's verified mesh, now with the sampled delta
        dmax = float(res.delta.max())
        probs = [] if dmax < res.threshold else [
            f"delta_max = {dmax:.6g} is not below delta_0 = {res.threshold:g}"]
    elif check:
        chord = CHORD * solid.diameter if chord_tol is None else chord_tol
        probs = result_problems(res, solid, chord)
        if probs:
            from ..errors import VerificationError
            raise VerificationError(f"tetrahedral mesh verification failed ({sampling} "
                                    f"sampling): {probs[0]}")
    log.info("%s sampling: %d repair passes, %d tetrahedra", sampling, passes, len(res.tets))
    return res


def result_problems(res, solid, chord: float) -> list[str]:
    """The verification of ``res`` with its own (sampled) delta, by the solid's kind."""
    from .general import solid_problems
    from .implicit import CSGSolid
    from .revolve import Revolution, revolution_problems
    from .verify import tet_problems
    if isinstance(solid, Revolution):
        return revolution_problems(res, solid, None, chord)
    if isinstance(solid, CSGSolid):
        return solid_problems(res, solid, None, chord)
    if hasattr(solid, "mesh_problems"):  # a solid with its own checks (voxel masks)
        return solid.mesh_problems(res, None, chord)
    return tet_problems(res.points, res.tets, res.faces, res.face_markers, solid,
                        res.delta, res.threshold, chord)
