"""delta(T) of tetrahedra by another sampling than the vertices, and the repair that meets
delta_0 under it.

``sampling = "pixels"`` (a material from a 3D volume): delta(T) over every voxel centre a
tetrahedron covers and its four vertices (:meth:`hetmesh.material.image.ImageField.
pixel_delta`). The mesher places and repairs by the vertices first; :func:`resample` then
bisects every tetrahedron whose sampled delta still reaches delta_0 and verifies the result
with that delta. Such a tetrahedron's vertices may agree (a voxel peak inside it), so the
edge with the largest composition jump is no guide: its longest edge is split instead
(many at a time, :func:`hetmesh.tet.refine.select_edges` ranking edges by length), which
shrinks tetrahedra without flattening them.
"""

from __future__ import annotations

import logging

import numpy as np

from ..delta import element_delta
from ..errors import MeshingError
from ..options import check_sampling
from ..refinement import check_budget, check_progress
from .faces import boundary_faces
from .refine import MAX_PASSES, bisect_edges, select_edges

__all__ = ["sampled_delta", "repair_sampled", "resample", "TET_SAMPLINGS"]

log = logging.getLogger(__name__)

#: the samplings of the tetrahedral mesher
TET_SAMPLINGS = ("vertices", "pixels")


def sampled_delta(field, sampling: str):
    """``delta_of(points, tets, comp)``: delta(T) of ``tets`` by ``sampling``
    (:func:`hetmesh.delta.element_delta`; ``comp`` the compositions at ``points``)."""
    check_sampling(field, sampling)

    def delta_of(points: np.ndarray, tets: np.ndarray, comp: np.ndarray) -> np.ndarray:
        if not len(tets):
            return np.zeros(0)
        return element_delta(field, points, tets, sampling, composition=comp)
    return delta_of


def repair_sampled(points: np.ndarray, tets: np.ndarray, comp: np.ndarray, field,
                   threshold: float, delta_of, *, max_elements: int | None = None):
    """Bisect the longest edges (max norm) of the tetrahedra with ``delta_of(points, tets,
    comp) >= threshold`` until there are none: ``(points, tets, comp, delta, passes)``.
    :class:`BudgetError` past ``max_elements``, :class:`MeshingError` after
    :data:`~hetmesh.tet.refine.MAX_PASSES` passes.

    Local: a pass works on the patch of tetrahedra that share a vertex with a violator
    (every tetrahedron holding one of their edges is in it, so the selection is that of the
    whole mesh, :func:`~hetmesh.tet.refine.select_edges`), and only the tetrahedra it makes
    are sampled again; the others keep their place and delta (new ones come last).
    """
    tets = np.asarray(tets, np.int64)
    delta = delta_of(points, tets, comp)
    passes = 0
    while (bad := delta >= threshold).any():
        if passes >= MAX_PASSES:
            raise MeshingError(f"sampled delta repair did not converge in {MAX_PASSES} "
                               f"passes ({int(bad.sum())} tetrahedra left)")
        if max_elements is not None:
            check_budget(len(tets), max_elements)
        mark = np.zeros(len(points), dtype=bool)
        mark[tets[bad]] = True
        patch = mark[tets].any(axis=1)
        sub = tets[patch]
        # coordinates as the values whose jumps rank the edges: the longest edge
        split = select_edges(sub, points, bad[patch])
        n0 = len(points)
        points, made = bisect_edges(points, sub, split)
        check_progress(n0, len(points), passes, int(bad.sum()), 0, threshold)
        comp = np.concatenate([comp, field.composition(points[n0:])])
        tets = np.concatenate([tets[~patch], made])
        delta = np.concatenate([delta[~patch], delta_of(points, made, comp)])
        passes += 1
    return points, tets, comp, delta, passes


def resample(res, solid, field, sampling: str, *, max_elements: int | None = None,
             chord_tol: float | None = None, check: bool = True):
    """``res`` (a :class:`~hetmesh.tet.mesher.TetResult` meeting delta_0 at its vertices)
    refined until delta(T) by ``sampling`` is below delta_0 everywhere, its ``delta`` that
    sampled one (``info["sampling"]``, ``info["sampling_passes"]``), verified: the whole
    mesh again if it was refined (:func:`hetmesh.tet.verify.tet_problems`, with
    ``chord_tol`` absolute, default 2e-3 x the solid's diameter: edge bisection never moves
    a face away from the solid), else the sampled delta (the mesher verified the rest)."""
    from .mesher import CHORD, TetResult
    from .verify import tet_problems

    if sampling == "vertices":
        return res
    delta_of = sampled_delta(field, sampling)
    comp = res.info.get("composition")
    if comp is None:
        comp = field.composition(res.points)
    points, tets, comp, delta, passes = repair_sampled(
        res.points, res.tets.astype(np.int64), comp, field, res.threshold, delta_of,
        max_elements=max_elements)
    info = dict(res.info, composition=comp, sampling=sampling, sampling_passes=passes)
    if passes:
        tets = tets.astype(np.int32)
        faces, _ = boundary_faces(tets)
        markers = (solid.classify_faces(points[faces]) + 1).astype(np.int32)
        res = TetResult(points, tets, faces.astype(np.int32), markers, res.face_names, delta,
                        res.threshold, info)
    else:
        res = TetResult(res.points, res.tets, res.faces, res.face_markers, res.face_names,
                        delta, res.threshold, info)
    if check and not passes:  # the mesher's verified mesh, now with the sampled delta
        dmax = float(res.delta.max())
        probs = [] if dmax < res.threshold else [
            f"delta_max = {dmax:.6g} is not below delta_0 = {res.threshold:g}"]
    elif check:
        chord = CHORD * solid.diameter if chord_tol is None else chord_tol
        probs = tet_problems(res.points, res.tets, res.faces, res.face_markers, solid,
                             res.delta, res.threshold, chord)
        if probs:
            from ..errors import VerificationError
            raise VerificationError(f"tetrahedral mesh verification failed ({sampling} "
                                    f"sampling): {probs[0]}")
    log.info("%s sampling: %d repair passes, %d tetrahedra", sampling, passes, len(res.tets))
    return res
