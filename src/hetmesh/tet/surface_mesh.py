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

*Jumps* of a piecewise composition (:func:`hetmesh.tet.jumps.has_jumps`) are embedded as
in solids of primitives (:mod:`hetmesh.tet.jumps`): a jump meeting the input surface at
under :data:`TANGENT_ANGLE` degrees, or that close to parallel within :data:`GAP` x the
element size of it, is refused first (:func:`check_jump_crossings`); the
fill is remeshed to the size capped near curved jumps and cut along them
(:func:`jump_start`); MMG keeps the phases and their interfaces through the size rounds;
after every remeshing the interface vertices go back onto their jump surfaces, those on
the boundary (the rims) onto the input surface as well (:func:`onto_surface_phases`,
:func:`onto_rim`); delta is measured per phase, the repair keeps the phases, thin
tetrahedra are flipped within each phase; the interfaces are recorded as faces
``discontinuity[k]`` and verified with the rims (:func:`rim_problems`).

The fill (Qhull, a seeded perturbation) and MMG are deterministic: the same model gives the
same mesh, bit for bit.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

import numpy as np

from ..errors import BudgetError, MaterialError, MeshingError
from ..mesh import simplex_measures
from ..metrics import delta_vertices
from ..topology import unique
from .faces import BARY, boundary_faces
from .general import (  # JUMP_SNAP, SETTLED: the cut's snap, the interfaces' settling
    HGRAD,
    JUMP_SNAP,
    SETTLED,
    SIZE_ROUNDS,
    centroid_and_delta_problems,
    check_positive,
    flip_plain,
    mmg_remesh,
    moves_in_part,
    next_size,
    recorded_interface_problems,
    size_field,
    with_interfaces,
)
from .implicit import onto_surfaces
from .jumps import (
    JumpSurface,
    cut_jumps,
    has_jumps,
    interface_bits,
    interface_off,
    jump_cap,
    onto_jumps,
    phase_delta,
)
from .mesher import CHORD, TetResult
from .refine import repair
from .surface import (
    SurfaceSolid,
    closest_on_triangles,
    distance_to_triangles,
    distance_within,
)
from .surface_fill import fill_surface
from .verify import raise_problems, validity_problems

__all__ = ["generate_surface", "surface_problems", "initial_volume", "estimate_surface",
           "keep_markers", "check_jump_crossings", "onto_surface_phases", "rim_problems",
           "TANGENT_ANGLE", "GAP", "jump_start", "uniform_surface_jumps"]

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
    phase = None
    jumps = has_jumps(field)
    if jumps:
        check_jump_crossings(solid, field, chord, lambda q: jump_cap(
            field, q, size_field(field, q, threshold, h_max, h_min), chord))
        p, t, faces, markers, phase = jump_start(
            solid, field, p, t, faces, markers,
            lambda q: size_field(field, q, threshold, h_max, h_min), chord, max_elements)
        size = jump_cap(field, p, size_field(field, p, threshold, h_max, h_min), chord)
    rounds = 0
    for rounds in range(SIZE_ROUNDS + 1):
        p, t, fm, rm, h_mmg, phase = mmg_remesh(p, t, faces, markers, size, hausd,
                                                phase=phase)
        faces, markers = keep_markers(solid, p, t, fm, rm, chord)
        if phase is not None:
            p = onto_surface_phases(solid, field, p, t, faces, phase, chord)
        if max_elements is not None and len(t) > max_elements:
            raise BudgetError(f"the mesh has {len(t)} tetrahedra, over the budget of "
                              f"{max_elements}")
        if phase is None:
            comp = field.composition(p)
            bad = delta_vertices(comp, t) >= threshold
            off = 0.0
        else:  # every tetrahedron's corners in its phase; the rounds go on until the
            # interface vertices have settled on their jumps
            bad = phase_delta(field, p, t, phase) >= threshold
            off = interface_off(field, p, t, phase)
        log.info("surface: size round %d: %d tetrahedra, %d over delta_0%s", rounds, len(t),
                 int(bad.sum()), "" if phase is None else f", interfaces {off:.3g} off")
        if (not bad.any() and off <= SETTLED * chord) or rounds == SIZE_ROUNDS:
            break
        size = next_size(h_mmg, field, p, t, bad, threshold, h_max, h_min)
        if phase is not None:
            size = jump_cap(field, p, size, chord)
    t_place = time.perf_counter() - t0
    if phase is None:
        p, t, comp, delta, passes = repair(p, t, field, threshold, comp=comp,
                                           max_elements=max_elements)
    else:  # the children keep their parent's phase
        p, t, _, delta, passes, trace = repair(p, t, field, threshold,
                                               max_elements=max_elements, regions=phase)
        phase = phase[trace.parent]
    if passes:  # bisected boundary triangles: the new ones take the face they lie on
        faces, markers = keep_markers(solid, p, t, faces, markers, chord)
    if phase is not None:  # thin tetrahedra where a jump meets the boundary: flips
        n_faces = len(faces)
        p, t, faces, phase, delta = flip_plain(field, p, t, faces, phase, threshold)
        if len(faces) != n_faces:
            raise MeshingError("the flips changed the boundary")
        comp = field.composition(p)
    t = t.astype(np.int32)
    info = {"placement": "surface", "fill": fill, "fill_points": n_fill, "time_fill": t_fill,
            "size_rounds": rounds, "repair_passes": passes,
            "estimate": est, "composition": comp, "time_place": t_place, "h_max": h_max,
            "chord_tol": chord, "hgrad": HGRAD}
    if phase is not None:
        info["regions"] = phase.astype(np.int32)
    res = with_interfaces(TetResult(p, t, faces.astype(np.int32),
                                    (markers + 1).astype(np.int32), tuple(solid.face_names),
                                    delta, float(threshold), info),
                          field, len(solid.face_names))
    if check:
        raise_problems(surface_problems(res, solid, field, chord))
    res.info["time_total"] = time.perf_counter() - t0
    log.info("surface mesh: %d points, %d tetrahedra, %d size rounds, %d repair passes, "
             "%.2f s", len(p), len(t), rounds, passes, res.info["time_total"])
    return res


def jump_start(solid: SurfaceSolid, field, p, t, faces, markers,
               size_of: Callable[[np.ndarray], np.ndarray], chord: float,
               max_elements: int | None = None):
    """The first volume mesh ``(p, t)`` (boundary ``faces`` on the faces ``markers``)
    remeshed twice by MMG to the size ``size_of(points)`` (the material's, or the uniform
    baseline's constant) capped near the curved jump surfaces
    (:func:`hetmesh.tet.jumps.jump_cap`, first looking at the points within a quarter of
    the extent of them, the fill being coarse, then within their size), cut along the jumps
    (:func:`hetmesh.tet.jumps.cut_jumps`, a vertex within :data:`JUMP_SNAP` x the median
    edge counting as on a jump), the boundary triangles named and the interface vertices
    moved onto the jump surfaces (:func:`onto_surface_phases`): ``(points, tets, faces,
    markers, phase)``; :class:`BudgetError` as soon as a mesh has more than
    ``max_elements`` tetrahedra."""
    def budget(t):
        if max_elements is not None and len(t) > max_elements:
            raise BudgetError(f"the mesh has {len(t)} tetrahedra, over the budget of "
                              f"{max_elements}")

    lo, hi = solid.bounds
    for reach in (float((hi - lo).max()) / 4, None):
        size = jump_cap(field, p, size_of(p), chord, reach=reach)
        p, t, fm, rm, _, _ = mmg_remesh(p, t, faces, markers, size, 0.5 * chord)
        budget(t)
        faces, markers = keep_markers(solid, p, t, fm, rm, chord)
    e = np.concatenate([t[:, [0, 1]], t[:, [0, 2]], t[:, [0, 3]], t[:, [1, 2]],
                        t[:, [1, 3]], t[:, [2, 3]]])
    snap = JUMP_SNAP * float(np.median(np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1)))
    p, t, phase = cut_jumps(field, p, t, snap)
    budget(t)
    faces, markers = keep_markers(solid, p, t, faces, markers, chord)
    p = onto_surface_phases(solid, field, p, t, faces, phase, chord)
    return p, t, faces, markers, phase


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
    markers = np.asarray(res.face_markers, dtype=np.int64) - 1
    inner = markers >= len(solid.face_names)  # the jumps' interfaces, after the boundary
    if inner.any():
        out += recorded_interface_problems(res, faces[inner])
        faces, markers = faces[~inner], markers[~inner]
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
    out += centroid_and_delta_problems(res, solid, field, chord_tol, "the surface")
    if field is not None and has_jumps(field):
        out += rim_problems(res, solid, field, chord_tol)
    return out


# -- jumps of a piecewise composition ------------------------------------------------------

#: a jump surface that crosses the input surface at under this angle (degrees) is refused
#: (:func:`check_jump_crossings`): its rim would need ever smaller tetrahedra
TANGENT_ANGLE = 10.0
#: a jump nearly parallel to the surface within this x the element size of it (inside the
#: solid) is refused as well (:func:`check_jump_crossings`): a thinner layer would be one
#: layer of flat tetrahedra
GAP = 0.2
#: two input triangles within the chord tolerance of a rim vertex whose normals are more
#: than this apart (degrees) make it a vertex of a sharp edge, kept on both planes
RIDGE_ANGLE = 40.0
#: the most intervals per edge of the lattice an input triangle is sampled on for its
#: crossings with the jump surfaces (:func:`check_jump_crossings`)
MAX_LATTICE = 32


def _unit_normals(V, F) -> np.ndarray:
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return n / np.linalg.norm(n, axis=1)[:, None]


def _lattice(n: int) -> np.ndarray:
    """The barycentric points of the regular lattice with ``n`` intervals per edge of a
    triangle: ``((n + 1)(n + 2) / 2, 3)``, the corners among them."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = i + j <= n
    i, j = i[keep], j[keep]
    return np.c_[n - i - j, i, j] / n


def _sample_groups(V, F, spacing: np.ndarray):
    """The input triangles in groups of equal sampling: ``[(triangles, points (m, b, 3))]``,
    each triangle sampled on the lattice (:func:`_lattice`) whose intervals are at most
    ``spacing`` (per triangle) on its longest edge, 2 to :data:`MAX_LATTICE` of them."""
    tri = V[F]
    edge = np.linalg.norm(tri - tri[:, [1, 2, 0]], axis=2).max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        n = np.clip(np.ceil(edge / spacing), 2, MAX_LATTICE)
    n = np.where(np.isfinite(n), n, MAX_LATTICE).astype(np.int64)
    return [(ids, np.einsum("bk,nkd->nbd", _lattice(int(k)), tri[ids]))
            for k in unique(n).tolist() for ids in [np.flatnonzero(n == k)]]


def check_jump_crossings(solid: SurfaceSolid, field, chord: float,
                         size_of: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
    """:class:`MaterialError` (naming the condition, the angle and a point) where a jump
    surface of ``field`` meets the input surface at under :data:`TANGENT_ANGLE` degrees,
    or comes that close to parallel within :data:`GAP` x the element size of it on the
    inside (the element size ``size_of(points)`` at the sample; None: the band is
    ``chord``). Every input triangle is sampled on a lattice of spacing at most the band
    at its centroid (:func:`_sample_groups`), the distance to a jump taken to first order
    (the level function over its gradient's norm).

    * A triangle whose samples lie on both sides of a jump by more than 1e-9 x the
      diameter crosses it: the angle between its normal and the level function's gradient
      at the sample nearest to the jump.
    * A sample within ``chord`` of a jump, or within the band where the jump lies inside
      the solid (the step onto it goes against the outward normal): the angle there. A
      thin layer between the jump and the surface would be one layer of flat tetrahedra; a
      jump touching the surface, or through an edge nearly parallel to a face (a thin
      wedge), too.

    A triangle all of whose samples lie on a jump (within 1e-9 x the diameter: a plane
    through a flat face) is no crossing."""
    V, F = solid.V, solid.F
    nrm = _unit_normals(V, F)
    eps = 1e-9 * solid.diameter
    cos = math.cos(math.radians(TANGENT_ANGLE))
    band = np.full(len(F), chord)
    if size_of is not None:
        band = np.maximum(band, GAP * size_of(V[F].mean(axis=1)))
    groups = _sample_groups(V, F, band)
    for i in range(len(field.conditions)):
        surf = JumpSurface(field, i)
        worst = None
        for ids, pts in groups:
            flat = pts.reshape(-1, 3)
            sd = surf.signed(flat).reshape(len(ids), -1)
            sd = np.where(np.isfinite(sd), sd, np.inf)
            ad = np.abs(sd)
            u = surf.grad(flat).reshape(len(ids), -1, 3)
            u = u / np.maximum(np.linalg.norm(u, axis=2), 1e-300)[:, :, None]
            un = np.einsum("nbd,nd->nb", u, nrm[ids])
            cross = (sd > eps).any(axis=1) & (sd < -eps).any(axis=1)
            near = np.zeros_like(ad, dtype=bool)
            near[np.flatnonzero(cross), np.argmin(ad[cross], axis=1)] = True
            at = np.full(ad.shape, chord)
            if size_of is not None:  # the band at the samples near the jump
                close = np.flatnonzero((ad <= band[ids, None]).ravel())
                at.ravel()[close] = np.maximum(chord, GAP * size_of(flat[close]))
            inward = np.where(np.isfinite(sd), sd, 0.0) * un > 0
            near |= (ad <= chord) | ((ad <= at) & inward)
            near &= (ad.max(axis=1) > eps)[:, None] & np.isfinite(sd)
            bad = near & (np.abs(un) > cos)
            if bad.any():
                j, k = np.argwhere(bad)[np.argmin(ad[bad])]
                if worst is None or ad[j, k] < worst[0]:
                    worst = (float(ad[j, k]), float(abs(un[j, k])), pts[j, k])
        if worst is not None:
            d, c, x = worst
            ang = math.degrees(math.acos(min(1.0, c)))
            where = (f"meets the surface at {ang:.1f} degrees" if d <= eps else
                     f"comes within {d:.3g} of the surface at {ang:.1f} degrees to it")
            raise MaterialError(
                f"{field.describe_jump(0, 1 << i)}: the jump {where} near ({x[0]:.6g}, "
                f"{x[1]:.6g}, {x[2]:.6g}), nearly tangent to it (under {TANGENT_ANGLE:g} "
                f"degrees within {GAP:g} x the element size is not supported)")


class _RowPlanes:
    """One plane per point (row): ``g = n . (x - o)``, for
    :func:`hetmesh.tet.implicit.onto_surfaces` on points in the same order."""

    kind = "rows"

    def __init__(self, normal: np.ndarray, origin: np.ndarray):
        self.n, self.o = normal, origin

    def g(self, x) -> np.ndarray:
        return np.einsum("ij,ij->i", np.asarray(x).reshape(-1, 3) - self.o, self.n)

    def grad(self, x) -> np.ndarray:
        return self.n


def _near_pairs(V, F, x, tol: float):
    """``(rows, triangles, distances)``: every input triangle within ``tol`` of a point of
    ``x`` (boxes widened by ``tol`` first, then the exact distance)."""
    tri = V[F]
    lo, hi = tri.min(axis=1) - tol, tri.max(axis=1) + tol
    rows, cols = [], []
    step = max(1, 2_000_000 // max(len(F), 1))
    for s in range(0, len(x), step):
        q = x[s:s + step, None, :]
        r, c = np.nonzero(((q >= lo[None]) & (q <= hi[None])).all(axis=2))
        rows.append(r + s)
        cols.append(c)
    r, c = np.concatenate(rows), np.concatenate(cols)
    d = np.linalg.norm(closest_on_triangles(x[r], V[F[c, 0]], V[F[c, 1]], V[F[c, 2]])
                       - x[r], axis=1)
    keep = d <= tol
    return r[keep], c[keep], d[keep]


def _first_per_row(r, *keys) -> np.ndarray:
    """The index of the first pair of every row, the pairs sorted by ``keys`` (last key
    first, as :func:`numpy.lexsort`) within a row."""
    o = np.lexsort((*keys, r))
    return o[np.r_[True, r[o][1:] != r[o][:-1]]]


def onto_rim(solid: SurfaceSolid, field, x: np.ndarray, bits: np.ndarray,
             tol: float, rounds: int = 3) -> np.ndarray:
    """Rim vertices ``x`` (on the boundary and on the jump surfaces of ``bits``) moved
    onto their jump surfaces and the input surface: onto the plane of the nearest input
    triangle (and, at a sharp edge, of the input triangle within ``tol`` whose normal is
    farthest from it, more than :data:`RIDGE_ANGLE`) and the jump surfaces at once
    (:func:`hetmesh.tet.implicit.onto_surfaces`), ``rounds`` times with the nearest
    triangles found again (a curved surface's facets). The surfaces are taken jumps
    first, then the planes, each only where its normal is more than :data:`TANGENT_ANGLE`
    / 2 from the span of those taken (three at most): a plane the jump lies on, or a sharp
    edge lying in a jump surface, adds nothing. A point farther than ``4 tol`` from the
    surface only goes onto its jumps."""
    x = np.array(x, dtype=float)
    V, F = solid.V, solid.F
    nrm = _unit_normals(V, F)
    cos_r = math.cos(math.radians(RIDGE_ANGLE))
    sin_t = math.sin(math.radians(0.5 * TANGENT_ANGLE))
    n_cond = len(field.conditions)
    for _ in range(rounds):
        r, c, d = _near_pairs(V, F, x, 4 * tol)
        planes = np.full((len(x), 2), -1, dtype=np.int64)
        if len(r):
            f = _first_per_row(r, c, d)
            planes[r[f], 0] = c[f]
            dots = np.einsum("ij,ij->i", nrm[c], nrm[planes[r, 0]])
            sel = (d <= tol) & (dots < cos_r)
            if sel.any():
                f2 = _first_per_row(r[sel], c[sel], dots[sel])
                planes[r[sel][f2], 1] = c[sel][f2]
        # the surfaces each point goes onto: its jumps, then its planes, each only if its
        # normal is independent of those taken (a plane parallel to a jump through the
        # point, a sharp edge lying in a jump surface: left out), three at most
        normals = np.zeros((len(x), n_cond + 2, 3))
        for i in range(n_cond):
            on = np.flatnonzero(bits >> i & 1)
            if len(on):
                normals[on, i] = JumpSurface(field, i).grad(x[on])
        for k in range(2):
            has = planes[:, k] >= 0
            normals[has, n_cond + k] = nrm[planes[has, k]]
        length = np.linalg.norm(normals, axis=2)
        normals /= np.maximum(length, 1e-300)[:, :, None]
        use = np.zeros((len(x), n_cond + 2), dtype=bool)
        # (a jump whose gradient vanishes at the point gives no direction)
        cand = np.c_[(bits[:, None] >> np.arange(n_cond)) & 1 == 1, planes >= 0] \
            & (length > 0) & np.isfinite(length)
        for j in range(n_cond + 2):
            taken = use.sum(axis=1)
            a = np.where(taken[:, None] >= 1, normals[np.arange(len(x)),
                                                      np.argmax(use, axis=1)], 0.0)
            rest = use.copy()
            rest[np.arange(len(x)), np.argmax(use, axis=1)] = False
            b = np.where(taken[:, None] >= 2, normals[np.arange(len(x)),
                                                      np.argmax(rest, axis=1)], 0.0)
            n = normals[:, j]
            ab = np.cross(a, b)
            indep = np.where(taken == 0, True,
                             np.where(taken == 1,
                                      np.linalg.norm(np.cross(a, n), axis=1) > sin_t,
                                      np.abs(np.einsum("ij,ij->i", ab, n))
                                      > sin_t * np.linalg.norm(ab, axis=1)))
            use[:, j] = cand[:, j] & indep & (taken < 3)
        new = x.copy()
        pattern, which = unique(use, axis=0, return_inverse=True)
        for g, pat in enumerate(pattern):
            rows = np.flatnonzero(which.reshape(-1) == g)
            surfs = [JumpSurface(field, i) for i in range(n_cond) if pat[i]]
            surfs += [_RowPlanes(nrm[planes[rows, k]], V[F[planes[rows, k], 0]])
                      for k in range(2) if pat[n_cond + k]]
            if surfs:
                new[rows] = onto_surfaces(x[rows], surfs)
        ok = np.isfinite(new).all(axis=1)
        x[ok] = new[ok]
    return x


def onto_surface_phases(solid: SurfaceSolid, field, p, t, faces, phase,
                        tol: float) -> np.ndarray:
    """The vertices of the interfaces between phases moved onto their jump surfaces
    (:func:`hetmesh.tet.jumps.onto_jumps`), those also on the boundary onto the input
    surface as well (:func:`onto_rim`, ``tol`` the chord tolerance), except where a move
    would leave a tetrahedron around it without a positive volume
    (:func:`hetmesh.tet.general.keep_positive`): those are moved in part
    (:func:`hetmesh.tet.general.moves_in_part`), or not at all."""
    want = onto_jumps(field, p, t, phase)
    _, _, per = interface_bits(t, phase, len(p))
    on_bnd = np.zeros(len(p), dtype=bool)
    on_bnd[np.asarray(faces, dtype=np.int64).ravel()] = True
    rim = np.flatnonzero(on_bnd & (per > 0))
    if len(rim):
        want[rim] = onto_rim(solid, field, p[rim], per[rim], tol)
    q = moves_in_part(p, want, t)
    check_positive(q, t, "after moving the interface vertices onto the jumps")
    return q


def rim_problems(res, solid: SurfaceSolid, field, chord_tol: float) -> list[str]:
    """One line per jump whose rim (the vertices on the boundary and on an interface
    triangle of that jump) is not within ``chord_tol`` of both the input surface and the
    jump surface."""
    phase = res.info.get("regions")
    if phase is None:
        return []
    p, t = res.points, np.asarray(res.tets, dtype=np.int64)
    bf, _ = boundary_faces(t)
    on_bnd = np.zeros(len(p), dtype=bool)
    on_bnd[bf.ravel()] = True
    _, _, per = interface_bits(t, np.asarray(phase), len(p))
    lim = chord_tol * (1 + 1e-9)
    out = []
    for i in range(len(field.conditions)):
        ids = np.flatnonzero(on_bnd & (per >> i & 1 == 1))
        if not len(ids):
            continue
        off_s = np.isinf(solid.distance_within(p[ids], lim))
        off_j = JumpSurface(field, i).distance(p[ids]) > lim
        if off_s.any() or off_j.any():
            c = p[ids[np.flatnonzero(off_s | off_j)[0]]]
            what = "the surface" if off_s.any() else "the jump"
            out.append(f"the jump {field.conditions[i]!r}: {int((off_s | off_j).sum())} "
                       f"vertices of its rim are off {what} by more than {chord_tol:.3g} "
                       f"(e.g. at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    return out


def uniform_surface_jumps(solid: SurfaceSolid, field, h: float, threshold: float, start,
                          chord: float, *, max_elements: int | None = None):
    """The uniform baseline's remeshing of a surface solid with the jumps of ``field``
    embedded, not verified: the start ``(points, tets, faces, markers)`` (the fill with
    its faces, :func:`hetmesh.tet.uniform.surface_start`) cut along the jumps at the
    constant size ``h`` (:func:`jump_start`; a jump nearly tangent to the surface refused
    first, :func:`check_jump_crossings`), remeshed by MMG to ``h`` capped near curved jump
    surfaces with the phases kept and the interface vertices put back (rounds, at most
    :data:`~hetmesh.tet.general.SIZE_ROUNDS` + 1, until they are within :data:`SETTLED` x
    ``chord`` of their jumps), then flipped within each phase as the adaptive mesh is (no
    new tetrahedron's delta reaching ``threshold``): ``(points, tets, faces, markers,
    phase, delta)``, ``delta`` per phase. The caller
    records ``phase`` as ``info["regions"]`` and the interfaces
    (:func:`hetmesh.tet.general.with_interfaces`)."""
    def sized(q):
        return jump_cap(field, q, np.full(len(q), float(h)), chord)

    check_jump_crossings(solid, field, chord, sized)
    p, t, faces, markers = start

    p, t, faces, markers, phase = jump_start(solid, field, p, t, faces, markers,
                                             lambda q: np.full(len(q), float(h)), chord,
                                             max_elements)
    for _ in range(SIZE_ROUNDS + 1):
        p, t, fm, rm, _, phase = mmg_remesh(p, t, faces, markers, sized(p), 0.5 * chord,
                                            phase=phase)
        faces, markers = keep_markers(solid, p, t, fm, rm, chord)
        p = onto_surface_phases(solid, field, p, t, faces, phase, chord)
        if max_elements is not None and len(t) > max_elements:
            raise BudgetError(f"the mesh has {len(t)} tetrahedra, over the budget of "
                              f"{max_elements}")
        if interface_off(field, p, t, phase) <= SETTLED * chord:
            break
    n_faces = len(faces)
    p, t, faces, phase, delta = flip_plain(field, p, t, faces, phase, threshold)
    if len(faces) != n_faces:
        raise MeshingError("the flips changed the boundary")
    return p, t, faces, markers, phase, delta
