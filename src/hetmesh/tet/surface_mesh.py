"""The surface-solid tetrahedral mesher: a solid bounded by a closed triangulated surface
(:class:`~hetmesh.tet.surface.SurfaceSolid`), meshed to the material's size.

1. *Initial volume* (:func:`initial_volume`): the conforming Delaunay fill
   (:func:`hetmesh.tet.surface_fill.fill_surface`; Qhull, permissive): the input
   triangles, some split in their plane, are the boundary, with a coarse lattice of points
   inside. Logged, and recorded in ``info["fill"]`` ("builtin").
2. *Size*: MMG remeshes to the isotropic size ``h = delta_0 / |grad f|`` (as for solids of
   primitives, :mod:`hetmesh.tet.general`), at most a quarter of the extent (or
   ``max_size``), with the Hausdorff distance ``hausd`` at half the chord tolerance: MMG
   detects the sharp edges (dihedral angles under 135 degrees: ridges, kept as polylines)
   and moves the other boundary vertices on a smooth interpolation of the facets, within
   ``hausd`` of them. Up to :data:`~hetmesh.tet.general.SIZE_ROUNDS` times the size at the
   vertices of tetrahedra with ``delta >= delta_0`` is multiplied by
   :data:`~hetmesh.tet.general.SHRINK` and MMG remeshes again.
3. *Repair*: the violators left are bisected (:func:`hetmesh.tet.refine.repair`); a
   boundary edge's midpoint lies in its triangle's plane, so the boundary does not move.
4. *Verification* (:func:`surface_problems`): positive volumes, conformity, a closed
   boundary, every boundary triangle within the chord tolerance of the input surface (at 12
   points per triangle), every input vertex within the chord tolerance of the mesh's
   boundary (no corner cut off), the volume within the chord tolerance x the surface's area
   of the surface's, every tetrahedron's centroid inside, delta_max < delta_0.

The fill (Qhull, a seeded perturbation) and MMG are deterministic: the same model gives the
same mesh, bit for bit.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np

from ..errors import BudgetError, MeshingError
from ..mesh import simplex_measures
from ..metrics import delta_vertices
from .faces import BARY, boundary_faces
from .general import (
    HGRAD,
    SIZE_ROUNDS,
    centroid_and_delta_problems,
    mmg_remesh,
    next_size,
    size_field,
)
from .mesher import CHORD, TetResult
from .refine import repair
from .surface import SurfaceSolid, distance_to_triangles, distance_within
from .surface_fill import fill_surface
from .verify import raise_problems, validity_problems

__all__ = ["generate_surface", "surface_problems", "initial_volume", "estimate_surface",
           "keep_markers"]

log = logging.getLogger(__name__)


def initial_volume(solid: SurfaceSolid) -> tuple[np.ndarray, np.ndarray]:
    """A first tetrahedral mesh of the inside of the surface whose boundary is the input
    triangles, some split in their planes (:func:`hetmesh.tet.surface_fill.fill_surface`,
    the conforming Delaunay fill with Qhull): ``(points, tets)``, tetrahedra positively
    oriented."""
    p, t, _, _ = fill_surface(solid.V, solid.F, solid.source or "the surface")
    return p, t


def estimate_surface(solid: SurfaceSolid, field, threshold: float, h_max: float) -> float:
    """A-priori element count: twice the regular tetrahedra of edge ``delta_0 / |grad f|``
    (capped at ``h_max``) over the solid (a 32^3 grid), plus 100."""
    lo, hi = solid.bounds
    n = 32
    h = (hi - lo) / n
    g = [lo[k] + h[k] * (np.arange(n) + 0.5) for k in range(3)]
    pts = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1).reshape(-1, 3)
    pts = pts[solid.contains(pts, 0.0)]
    if not len(pts):
        return 100.0
    hh = size_field(field, pts, threshold, h_max, 1e-300)
    per = 6.0 * np.sqrt(2.0) / hh ** 3
    return 2.0 * float(per.sum() * np.prod(h)) + 100.0


def generate_surface(solid: SurfaceSolid, field, threshold: float, *, seed: int = 0,
                     chord_tol: float | None = None, max_elements: int | None = None,
                     max_size: float | None = None, check: bool = True,
                     initial: Callable[[SurfaceSolid], tuple[np.ndarray, np.ndarray]]
                     = initial_volume) -> TetResult:
    """Tetrahedralise a :class:`~hetmesh.tet.surface.SurfaceSolid` with every element's delta
    below ``threshold`` (module docstring). ``chord_tol`` in model units (default 2e-3 x the
    diameter); ``seed`` is accepted for the common interface (the mesh does not depend on
    it); ``initial`` makes the first volume mesh (default :func:`initial_volume`; a
    benchmark passes a peer's), its name recorded in ``info["fill"]``."""
    t0 = time.perf_counter()
    chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
    lo, hi = solid.bounds
    h_max = float((hi - lo).max()) / 4
    if max_size is not None:
        h_max = min(h_max, float(max_size))
    h_min = 1e-4 * solid.diameter
    est = estimate_surface(solid, field, threshold, h_max)
    if max_elements is not None and est > max_elements:
        raise BudgetError(f"about {est:.0f} tetrahedra are needed for delta_0 = {threshold} "
                          f"but the budget is {max_elements}")
    t_fill = time.perf_counter()
    p, t = initial(solid)
    t_fill = time.perf_counter() - t_fill
    fill = "builtin" if initial is initial_volume else getattr(initial, "__name__", "other")
    log.info("surface: %s fill, %d points, %d tetrahedra, %.3f s", fill, len(p), len(t),
             t_fill)
    n_fill = len(p)
    faces, _ = boundary_faces(t)
    markers = _classify(solid, p, faces, chord)
    size = size_field(field, p, threshold, h_max, h_min)
    hausd = 0.5 * chord
    rounds = 0
    for rounds in range(SIZE_ROUNDS + 1):
        p, t, fm, rm, h_mmg, _ = mmg_remesh(p, t, faces, markers, size, hausd)
        faces, markers = keep_markers(solid, p, t, fm, rm, chord)
        if max_elements is not None and len(t) > max_elements:
            raise BudgetError(f"the mesh has {len(t)} tetrahedra, over the budget of "
                              f"{max_elements}")
        comp = field.composition(p)
        bad = delta_vertices(comp, t) >= threshold
        log.info("surface: size round %d: %d tetrahedra, %d over delta_0", rounds, len(t),
                 int(bad.sum()))
        if not bad.any() or rounds == SIZE_ROUNDS:
            break
        size = next_size(h_mmg, field, p, t, bad, threshold, h_max, h_min)
    t_place = time.perf_counter() - t0
    p, t, comp, delta, passes = repair(p, t, field, threshold, comp=comp,
                                       max_elements=max_elements)
    if passes:  # bisected boundary triangles: the new ones take the face they lie on
        faces, markers = keep_markers(solid, p, t, faces, markers, chord)
    t = t.astype(np.int32)
    info = {"placement": "surface", "fill": fill, "fill_points": n_fill, "time_fill": t_fill,
            "size_rounds": rounds, "repair_passes": passes,
            "estimate": est, "composition": comp, "time_place": t_place, "h_max": h_max,
            "chord_tol": chord, "hgrad": HGRAD}
    res = TetResult(p, t, faces.astype(np.int32), (markers + 1).astype(np.int32),
                    tuple(solid.face_names), delta, float(threshold), info)
    if check:
        raise_problems(surface_problems(res, solid, field, chord))
    res.info["time_total"] = time.perf_counter() - t0
    log.info("surface mesh: %d points, %d tetrahedra, %d size rounds, %d repair passes, "
             "%.2f s", len(p), len(t), rounds, passes, res.info["time_total"])
    return res


def _classify(solid: SurfaceSolid, p, faces, chord: float) -> np.ndarray:
    """The face of each boundary triangle (:meth:`SurfaceSolid.classify_faces` within the
    chord tolerance); :class:`MeshingError` where none."""
    markers = solid.classify_faces(p[faces], chord)
    if (markers < 0).any():
        c = p[faces[markers < 0][0]].mean(axis=0)
        raise MeshingError(f"{int((markers < 0).sum())} boundary triangles off the surface "
                           f"(e.g. at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    return markers


def keep_markers(solid, p, t, known, known_markers, chord):
    """The boundary triangles of ``t`` and their faces: those of the triangles ``known``
    (MMG's, with the references it kept; or the mesh's before a repair; may be empty)
    where they are the same, the others classified by their geometry
    (:class:`MeshingError` where a triangle is off the surface)."""
    faces, _ = boundary_faces(t)
    if len(solid.face_names) == 1:
        return faces, np.zeros(len(faces), dtype=np.int64)
    n = len(p) + 1

    def key(f):
        s = np.sort(np.asarray(f, dtype=np.int64), axis=1)
        return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]

    markers = np.full(len(faces), -1, dtype=np.int64)
    if len(known):
        kb, km = key(faces), key(known)
        order = np.argsort(km)
        pos = np.clip(np.searchsorted(km[order], kb), 0, len(km) - 1)
        hit = km[order][pos] == kb
        markers = np.where(hit, np.asarray(known_markers, dtype=np.int64)[order][pos], -1)
    bad = (markers < 0) | (markers >= len(solid.face_names))
    if bad.any():
        markers[bad] = _classify(solid, p, faces[bad], chord)
    return faces, markers




def surface_problems(res, solid: SurfaceSolid, field, chord_tol: float) -> list[str]:
    """Every broken claim of a mesh of ``solid``, one line each (empty: valid). delta is
    recomputed from ``field`` at the vertices (None: the result's own delta)."""
    p, t = res.points, res.tets
    if len(t) == 0:
        return ["no tetrahedra"]
    out = validity_problems(p, t)
    faces = np.asarray(res.faces, dtype=np.int64)
    bf, _ = boundary_faces(t)
    if len(bf) != len(faces):
        out.append(f"{len(faces)} boundary triangles recorded, {len(bf)} in the tetrahedra")
    lim = chord_tol * (1 + 1e-9)
    pts = np.einsum("bk,nkd->nbd", BARY, p[faces]).reshape(-1, 3)
    far = np.flatnonzero(np.isinf(solid.distance_within(pts, lim)))
    if len(far):
        dev = solid.distance(pts[far[:1000]])
        c = pts[far[int(np.argmax(dev))]]
        out.append(f"{len(far)} points of boundary triangles are off the surface, by up to "
                   f"{float(dev.max()):.3g} at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}) "
                   f"(allowed {chord_tol:.3g})")
    far = np.flatnonzero(np.isinf(distance_within(p, faces, solid.V, lim)))
    if len(far):
        back = distance_to_triangles(p, faces, solid.V[far[:1000]])
        c = solid.V[far[int(np.argmax(back))]]
        out.append(f"{len(far)} vertices of the surface are off the mesh's boundary, by up "
                   f"to {float(back.max()):.3g} at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}) "
                   f"(allowed {chord_tol:.3g})")
    markers = np.asarray(res.face_markers, dtype=np.int64) - 1
    if ((markers < 0) | (markers >= len(solid.face_names))).any():
        out.append(f"{int(((markers < 0) | (markers >= len(solid.face_names))).sum())} "
                   f"boundary triangles on no face")
    elif len(solid.face_names) > 1:
        mark = np.repeat(markers, len(BARY))
        for k, name in enumerate(solid.face_names):
            sel = np.flatnonzero(mark == k)
            own = solid.F[solid.patch == k]
            far = np.isinf(distance_within(solid.V, own, pts[sel], lim))
            if far.any():
                c = pts[sel[np.flatnonzero(far)[0]]]
                out.append(f"face {name!r}: {int(far.sum())} points of its triangles are "
                           f"off its part of the surface (e.g. at ({c[0]:.6g}, {c[1]:.6g}, "
                           f"{c[2]:.6g}))")
    vol = float(simplex_measures(p, t).sum())
    if abs(vol - solid.volume) > chord_tol * solid.area + 1e-9 * solid.volume:
        out.append(f"volume {vol:.12g} differs from the surface's {solid.volume:.12g} by "
                   f"more than the chord tolerance x its area allows")
    return out + centroid_and_delta_problems(res, solid, field, chord_tol, "the surface")
