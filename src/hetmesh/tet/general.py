"""The general-solid tetrahedral mesher: solids of primitives (:mod:`hetmesh.tet.implicit`),
meshed through a background grid, level-set cuts and MMG remeshing to the material's size.

1. *Background*: a rectilinear grid over the solid's bounds whose planes include every
   planar face (box faces, cylinder caps), each cell cut into six Kuhn tetrahedra (one
   diagonal for all: conforming). Planar faces are then unions of grid faces: exact.
2. *Cuts*: for every curved surface (sphere, cylinder side) MMG's level-set mode (mmg3d
   ``-ls``, without remeshing) splits the tetrahedra along the piecewise-linear zero set of
   its function; multi-material references record on which side of each cut a tetrahedron
   lies. A tetrahedron is in the solid if its side of every surface and its grid cell (the
   planes) say so; the others are dropped. Where two curved faces meet
   (:attr:`~hetmesh.tet.implicit.CSGSolid.curved_edges`), MMG improves the tetrahedra
   between two cuts (swaps and moves; the planes recorded in the references first), since
   on the slivers an earlier cut leaves its level-set mode misplaces crossing points
   (:func:`_cut_meeting`).
3. *Faces*: every boundary triangle is given the face (surface and primitive) its corners
   lie on, and every boundary vertex is projected onto the exact surfaces of its faces
   (Gauss-Newton on their functions; planes exactly), so curved faces are within
   interpolation error of the true surface before any remeshing.
4. *Size*: MMG remeshes to the isotropic size ``h = S delta_0 / |grad f|`` (``|grad f|``
   the largest constituent gradient norm at the vertex; Eq. 9's density
   ``rho = |grad f|^5`` in 3D), capped at ``max_size`` and at what the chord tolerance
   allows on curved faces, with the Hausdorff distance :data:`HAUSD` x the chord
   tolerance and the boundary triangles' face references kept (MMG keeps edges between
   faces as ridges). The boundary vertices are projected onto their faces again. Where no
   curved faces meet, MMG remeshes again while that still coarsens
   (:func:`remesh_until_settled`). Then, in
   up to :data:`SIZE_ROUNDS` rounds, the size at the vertices of tetrahedra with
   ``delta >= delta_0`` is multiplied by :data:`SHRINK` and MMG remeshes again: the mesh
   gets finer only where it violated. Where curved faces meet, a vertex of both goes onto
   the curve where their surfaces meet (the same Gauss-Newton on both functions); a move
   that would leave a tetrahedron under :data:`MIN_VOLUME` is tried at the fractions
   :data:`PARTIAL`; a vertex still farther than :data:`STUCK` x the chord tolerance from
   its place is collapsed onto a neighbour (:func:`_collapse_stuck`; MMG would keep it as a
   corner), and the rounds go on until no vertex was collapsed and every boundary vertex is
   within :data:`SETTLED` x the chord tolerance of its faces. On that path MMG's ridge angle
   is :data:`RIDGE_ANGLE`, the edges between faces given to it as ridges, so that fewer
   turns of the cuts' polyline become corners. The uniform baseline
   (:func:`uniform_solid_at`) runs the same rounds (:func:`size_rounds`) at a constant size.
5. *Repair*: the violators left are bisected (:func:`hetmesh.tet.refine.repair`); a
   boundary edge's midpoint lies in its triangle's plane, so planar faces stay exact and
   chords of curved faces do not get farther from them. Where curved faces meet, the short
   edges of the tetrahedra under :data:`COLLAPSE_BOUND` degrees are then collapsed and those
   under :data:`FLIP_BOUND` degrees improved by flips (:func:`finish_meeting`).
6. *Verification* (:func:`solid_problems`): positive volumes, conformity, a closed boundary,
   every boundary triangle on a face (planar ones exactly, curved ones within the chord
   tolerance at 12 points per triangle), every edge between two curved faces within the
   chord tolerance of the exact curve where their surfaces meet (:func:`edge_problems`),
   the volume (within the chord tolerance x the boundary area of the exact one where the
   solid has a closed form, else of a grid estimate, with 1 % more for the estimate's own
   error), delta_max < delta_0.

The same input and seed give the same mesh (MMG runs single-threaded and deterministically).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from ..errors import BudgetError, MaterialError, MeshingError
from ..mesh import simplex_measures
from ..metrics import delta_vertices
from ..topology import drop_unused, unique
from ..tri.discontinuity import DISCONTINUITY
from .collapse import collapse_edges, face_incidence, same_boundary
from .faces import BARY, boundary_faces, interface_faces, same_triangles
from .flips import flip_improve, flip_slivers
from .implicit import CSGSolid, onto_surfaces
from .jumps import (
    JumpSurface,
    cut_jumps,
    has_jumps,
    interface_off,
    jump_cap,
    jump_problems,
    jump_radius,
    onto_jumps,
    phase_delta,
)
from .levelset import levelset_cut, quiet_mmg, split_bits
from .mesher import CHORD, TetResult
from .quality import min_dihedral
from .refine import repair
from .verify import raise_problems, validity_problems

__all__ = ["generate_solid", "solid_problems", "estimate_solid", "mmg_remesh", "orient_positive",
           "quiet_mmg", "next_size", "keep_positive", "moves_in_part",
           "centroid_and_delta_problems", "S", "SHRINK", "JUMP_SNAP", "SETTLED",
           "SIZE_ROUNDS", "uniform_solid_at", "background_spacing", "levelset_cut", "split_bits",
           "edge_problems", "onto_curve", "size_rounds", "finish_meeting", "REGULAR_PER_H3",
           "estimate_regular", "check_estimate", "check_count", "remesh_until_settled",
           "SETTLE", "SETTLE_PASSES", "HAUSD", "carry", "solid_start", "onto_phases",
           "INTERFACE_REF", "with_interfaces", "recorded_interface_problems", "check_jumps",
           "onto_planes", "flip_plain", "collapse_phase_slivers", "finish_plain",
           "face_keeper", "check_positive"]

log = logging.getLogger(__name__)

#: the size factor: h = S delta_0 / |grad f|
S = 1.0
#: the size at the vertices of violating tetrahedra is multiplied by this each round
SHRINK = 0.85
#: size rounds before the bisection repair
SIZE_ROUNDS = 6
#: cells of the background grid across the solid's smallest curved radius
CELLS_PER_RADIUS = 3.0
#: background cells along the solid's largest extent, at most
MAX_CELLS = 40
#: rounds of bisection repair and projection of the new boundary vertices, at most
REPROJECT = 4
#: MMG's gradation (largest ratio of adjacent edge lengths)
HGRAD = 1.3
#: the jumps' cuts count a vertex within this x the background spacing of a jump surface as
#: on it (:func:`hetmesh.tet.jumps.cut_jumps`; it is moved there afterwards)
JUMP_SNAP = 0.05
#: MMG's reference of the triangles between two phases (above every face's marker + 1)
INTERFACE_REF = 1_000_000


# -- 1. background ---------------------------------------------------------------------

def grid_lines(solid: CSGSolid, spacing: float) -> list[np.ndarray]:
    """Per axis, the grid coordinates: the bounds, every planar face's coordinate inside,
    and equal steps of at most ``spacing`` between them."""
    lo, hi = solid.bounds
    out = []
    tol = 1e-9 * solid.diameter
    for a in range(3):
        cuts = [lo[a], hi[a]]
        for prim in solid.primitives:
            for s in prim.surfaces:
                if s.kind == "plane" and s.axis == a and lo[a] + tol < s.value < hi[a] - tol:
                    cuts.append(s.value)
        cuts = unique(np.array(cuts))
        cuts = cuts[np.r_[True, np.diff(cuts) > tol]]
        lines = [cuts[:1]]
        for x0, x1 in zip(cuts[:-1], cuts[1:]):
            n = max(1, int(math.ceil((x1 - x0) / spacing - 1e-9)))
            lines.append(x0 + (x1 - x0) * np.arange(1, n + 1) / n)
        g = np.concatenate(lines)
        g[-1] = hi[a]
        out.append(g)
    return out


def kuhn_grid(xs, ys, zs) -> tuple[np.ndarray, np.ndarray]:
    """Points and positively oriented tetrahedra of the rectilinear grid, each cell in six
    tetrahedra along its main diagonal (conforming)."""
    nx, ny, nz = len(xs), len(ys), len(zs)
    p = np.stack(np.meshgrid(xs, ys, zs, indexing="ij"), -1).reshape(-1, 3)

    def vid(i, j, k):
        return (i * ny + j) * nz + k

    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(nx - 1), np.arange(ny - 1),
                                              np.arange(nz - 1), indexing="ij"))
    c = np.stack([vid(i + a, j + b, k + d) for a in (0, 1) for b in (0, 1) for d in (0, 1)],
                 axis=1)
    paths = [(0, 4, 6, 7), (0, 4, 5, 7), (0, 2, 6, 7), (0, 2, 3, 7), (0, 1, 5, 7),
             (0, 1, 3, 7)]
    t = np.concatenate([c[:, list(pp)] for pp in paths]).astype(np.int64)
    return p, orient_positive(p, t)


def orient_positive(p, t):
    """``t`` with the tetrahedra of negative volume turned (two vertices swapped)."""
    v = simplex_measures(p, t)
    t = t.copy()
    neg = v < 0
    t[neg, 2], t[neg, 3] = t[neg, 3], t[neg, 2].copy()
    return t


# -- 2. cuts ---------------------------------------------------------------------------

def cut_solid(solid: CSGSolid, spacing: float, *, meeting: bool) -> tuple[np.ndarray, np.ndarray]:
    """The tetrahedra of the background grid cut by every curved surface, those in the solid
    kept: ``(points, tets)``. ``meeting``: the cuts of the path for meeting curved faces
    (:func:`_cut_meeting`)."""
    p, t = kuhn_grid(*grid_lines(solid, spacing))
    curved = solid.curved
    # drop the cells that lie well outside the base's or the clip's curved surfaces
    margin = 2.0 * spacing
    keep = np.ones(len(t), dtype=bool)
    for prim in solid.primitives[:solid.n_kept]:
        for s in prim.surfaces:
            if s.curved:
                keep &= ~(s.g(p)[t] > margin).all(axis=1)
    t = t[keep]
    if meeting:
        return _cut_meeting(solid, p, t, spacing)
    used = unique(t)
    remap = np.full(len(p), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    p, t = p[used], remap[t]
    refs = np.ones(len(t), dtype=np.int64)
    for i, s in enumerate(curved):
        p, t, refs = levelset_cut(p, t, refs, s.g(p), split_bits(refs, i), f"surface {i}")
    if (refs >= 2 ** 30).any():
        raise MeshingError("too many curved surfaces for the level-set references")
    inside = _membership(solid, p, t, refs, curved)
    t = t[inside]
    used = unique(t)
    remap = np.full(len(p), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return p[used], orient_positive(p[used], remap[t])


#: where curved faces meet: MMG's Hausdorff distance for the improvement between two cuts,
#: as a fraction of the background spacing
BETWEEN_HAUSD = 0.03


def _plane_bits(solid: CSGSolid, c: np.ndarray) -> dict:
    """For every primitive with planes inside the background grid (a subtracted box or a
    cylinder's ends), a reference bit and whether each centroid ``c`` lies on the
    primitive's side of all its planes: ``{id(prim): (bit, inside)}``, bits above the
    curved surfaces' two each."""
    out = {}
    bit = 2 * len(solid.curved) + 1
    for prim in solid.primitives:
        planes = [s for s in prim.surfaces if not s.curved]
        if not planes:
            continue
        ok = np.ones(len(c), dtype=bool)
        for s in planes:
            ok &= s.g(c) < 0
        out[id(prim)] = (bit, ok)
        bit += 1
    return out


def _cut_meeting(solid: CSGSolid, p, t, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """The cuts of :func:`cut_solid` for a solid whose curved faces meet. Cut after cut,
    MMG's level-set mode misplaces the crossing points on some edges of the slivers that
    an earlier cut left (the references then no longer match the sides, and boundary
    triangles end up inside the solid): here MMG improves the tetrahedra between two cuts
    (swaps and moves, no insertion; Hausdorff distance :data:`BETWEEN_HAUSD` x the
    spacing), the references keeping every interface so far as an internal boundary. The
    planes inside the grid are recorded in the references before the first improvement
    (one bit per primitive: its side of all its planes, from the centroids in the grid
    cells), so it keeps them as interfaces too. The two cuts' piecewise-linear surfaces
    cross along a polyline near the exact curve: the edge stays sharp. ``(p, t)``: the
    background grid's points and the tetrahedra kept; returns ``(points, tets)`` of the
    solid."""
    mmgpy = quiet_mmg()
    curved = solid.curved
    used = unique(t)
    remap = np.full(len(p), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    p, t = p[used], remap[t]
    planes = _plane_bits(solid, p[t].mean(axis=1))
    refs = np.ones(len(t), dtype=np.int64)
    for bit, ok in planes.values():
        refs += ok.astype(np.int64) << bit
    if (refs >= 2 ** 30).any():
        raise MeshingError("too many primitives for the level-set references")
    for i, s in enumerate(curved):
        if i:
            m = mmgpy.MmgMesh3D()
            m.set_mesh_size(vertices=len(p), tetrahedra=len(t))
            m.set_vertices(np.ascontiguousarray(p))
            m.set_tetrahedra(np.ascontiguousarray(t, dtype=np.int32),
                             np.ascontiguousarray(refs, dtype=np.int32))
            out = m.remesh(verbose=-1, hausd=float(BETWEEN_HAUSD * spacing), noinsert=1)
            if out.get("return_code", 0) != 0:
                raise MeshingError(f"MMG remeshing between the cuts failed (code "
                                   f"{out.get('return_code')})")
            p = np.array(m.get_vertices(), dtype=np.float64)
            tt, rr = m.get_tetrahedra_with_refs()
            t, refs = np.asarray(tt, dtype=np.int64), np.asarray(rr, dtype=np.int64)
        p, t, refs = levelset_cut(p, t, refs, s.g(p), split_bits(refs, i), f"surface {i}")
    neg = {id(s): ((refs >> (2 * i + 1)) & 1).astype(bool) for i, s in enumerate(curved)}

    def inside(prim):
        ok = np.ones(len(t), dtype=bool)
        for s in prim.surfaces:
            if s.curved:
                ok &= neg[id(s)]
        if id(prim) in planes:
            ok &= ((refs >> planes[id(prim)][0]) & 1).astype(bool)
        return ok

    keep = inside(solid.base)
    if solid.clip is not None:
        keep &= inside(solid.clip)
    for prim in solid.subtract:
        keep &= ~inside(prim)
    t = t[keep]
    used = unique(t)
    remap = np.full(len(p), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return p[used], orient_positive(p[used], remap[t])


def _membership(solid, p, t, refs, curved) -> np.ndarray:
    """Whether each cut tetrahedron lies in the solid: the planes by its centroid (grid
    cells), the curved surfaces by its cut references."""
    c = p[t].mean(axis=1)
    neg = {}
    for i, s in enumerate(curved):
        neg[id(s)] = ((refs >> (2 * i + 1)) & 1).astype(bool)

    def inside(prim):
        ok = np.ones(len(t), dtype=bool)
        for s in prim.surfaces:
            ok &= neg[id(s)] if s.curved else s.g(c) < 0
        return ok

    ok = inside(solid.base)
    if solid.clip is not None:
        ok &= inside(solid.clip)
    for s in solid.subtract:
        ok &= ~inside(s)
    return ok


# -- 3. faces ---------------------------------------------------------------------------

def project(solid: CSGSolid, points: np.ndarray, faces: np.ndarray, markers: np.ndarray,
            iters: int = 30) -> np.ndarray:
    """Boundary vertices moved onto the surfaces of all their faces (Gauss-Newton on the
    surfaces' functions; plane coordinates set exactly)."""
    p = points.copy()
    nf = len(solid.faces)
    inc = np.zeros((len(p), nf), dtype=bool)
    inc[faces.ravel(), np.repeat(markers, 3)] = True
    # the distinct surfaces of each vertex (two faces on one surface count once)
    surf_of = [f.surface for f in solid.faces]
    key = [next(j for j in range(nf) if surf_of[j] == surf_of[i]) for i in range(nf)]
    rows = np.flatnonzero(inc.any(axis=1))
    combos = {}
    for r in rows:
        combos.setdefault(tuple(sorted({key[j] for j in np.flatnonzero(inc[r])})), []).append(r)
    for combo, ids in combos.items():
        ids = np.asarray(ids)
        p[ids] = onto_surfaces(p[ids], [surf_of[j] for j in combo[:3]], iters)
    return p


#: where curved faces meet, the fractions of a projection tried in turn for the vertices
#: whose whole move would flatten a tetrahedron
PARTIAL = (1.0, 0.5, 0.25)
#: where curved faces meet, the size rounds go on while a boundary vertex is farther than
#: this fraction of the chord tolerance from a surface of its faces
SETTLED = 0.25
#: where curved faces meet, a boundary vertex the projection left farther than this fraction
#: of the chord tolerance from its faces is collapsed between the size rounds
STUCK = 0.01
#: on the path for meeting curved faces, short edges of the tetrahedra under this smallest
#: dihedral angle (degrees) are collapsed at the end, in up to COLLAPSE_PASSES collapses
COLLAPSE_BOUND = 10.0
COLLAPSE_PASSES = 200
#: where curved faces meet, the plain path's mesh is kept only if no dihedral angle is
#: under this (degrees; the quality target): it verified with 1.5 degrees on two crossing
#: bores at chord 0.01 and 0.0 on a cylinder minus a ball and a bore at 0.2
PLAIN_DIHEDRAL = 10.0
#: on the path for meeting curved faces, the tetrahedra whose smallest dihedral angle is
#: under this (degrees) are improved by flips at the end
FLIP_BOUND = 20.0
#: a size round's MMG remeshing is repeated while it removes more than this fraction of the
#: tetrahedra (:func:`remesh_until_settled`)
SETTLE = 0.1
#: ... up to this many remeshings in a size round of a solid on the plain path (one where
#: curved faces meet: :func:`size_rounds`)
SETTLE_PASSES = 4
#: MMG's Hausdorff distance in the size rounds of a solid, x the chord tolerance. At 1.0 (as
#: for carved solids) graded_sphere had 9,513 tetrahedra at 0.3 (10,787 at 0.5), but at 0.1
#: about as many as at 0.5 (227,298 against 232,230) and the analysis of docs/fea.md on it
#: 1.3 % off the exact radial stress at R1 (0.85 % at 0.5): the facets of the inner sphere
#: nearer the chord tolerance
HAUSD = 0.5
#: on the path for meeting curved faces, MMG's ridge angle (degrees; its default is 45): a
#: vertex whose two ridge edges turn by more than this is one of MMG's corners, which it
#: never moves or removes. The cuts' polyline zigzags near the curve where curved faces meet,
#: and at 45 degrees its turns made corners the projection could not move (on the crossing
#: bores about 40 a round, the rounds going on to the last); the edges between faces are
#: given to MMG as ridges, so this angle does not decide them
RIDGE_ANGLE = 70.0
#: the smallest volume a projection may leave a tetrahedron of a solid whose curved faces
#: meet, relative to the cube of the diameter (1000 x the validity check's floor)
MIN_VOLUME = 1e-9


def project_safely(solid, points, tets, faces, markers, rounds: int = 20) -> np.ndarray:
    """:func:`_project_safely` on the path the solid's pairs of meeting curved faces
    (:func:`meeting_pairs`) choose."""
    return _project_safely(solid, points, tets, faces, markers, bool(meeting_pairs(solid)),
                           rounds)


def _project_safely(solid, points, tets, faces, markers, meeting: bool,
                    rounds: int = 20) -> np.ndarray:
    """:func:`project`, except for the vertices whose move would leave a tetrahedron
    around them without a positive volume: those stay (a curved face's vertex then stays
    where MMG put it, within its Hausdorff distance of the surface; the verification
    checks the chord tolerance). On the path for meeting curved faces (``meeting``: their
    edge vertices go onto the curve, farther than the others), a volume of at least
    :data:`MIN_VOLUME` x the diameter cubed, the move tried at the fractions
    :data:`PARTIAL`."""
    want = project(solid, points, faces, markers)
    if not meeting:
        moved = (want != points).any(axis=1)
        q = keep_positive(points, want, tets, moved, rounds)
        left = moved & (q != want).any(axis=1)
        if left.any():  # planar faces are exact: their coordinates at least, if that fits
            flat = onto_planes(solid, q, faces, markers)
            q = keep_positive(q, flat, tets, left & (flat != q).any(axis=1), rounds)
        check_positive(q, tets, "after projecting the boundary vertices")
        return q
    floor = MIN_VOLUME * solid.diameter ** 3
    q = points.copy()
    pending = (want != points).any(axis=1)
    for frac in PARTIAL:
        cand = q.copy()
        cand[pending] = q[pending] + frac * (want[pending] - q[pending])
        new = keep_positive(q, cand, tets, pending, rounds, min_volume=floor)
        pending &= ~(new != q).any(axis=1)
        q = new
    back = (q != want).any(axis=1)
    if back.any():
        log.info("projection: %d of %d moves not made in full (largest %.3g)",
                 int(back.sum()), int((want != points).any(axis=1).sum()),
                 float(np.linalg.norm(want[back] - q[back], axis=1).max()))
    check_positive(q, tets, "after projecting the boundary vertices")
    return q


def onto_planes(solid: CSGSolid, points, faces, markers) -> np.ndarray:
    """``points`` with the coordinate of every planar face's plane set at its vertices
    (the planar part of :func:`project`, which a vertex whose whole move would flatten a
    tetrahedron can often still make: a vertex MMG moved along the edge between a plane
    and a curved face)."""
    q = points.copy()
    for fi, f in enumerate(solid.faces):
        if f.surface.kind == "plane":
            ids = unique(faces[markers == fi])
            q[ids, f.surface.axis] = f.surface.value
    return q


def keep_positive(old: np.ndarray, new: np.ndarray, tets: np.ndarray, moved: np.ndarray,
                  rounds: int = 20, min_volume: float = 0.0) -> np.ndarray:
    """``new``, except the ``moved`` vertices whose move leaves a tetrahedron around them
    without a positive volume (above ``min_volume``, or above zero for a tetrahedron
    already under it): those go back to ``old`` (round by round, at most ``rounds``; the
    caller checks what is left)."""
    q, moved = new.copy(), moved.copy()
    # a tetrahedron already under min_volume need only keep a positive volume
    floor = np.minimum(min_volume, simplex_measures(old, tets)) if min_volume > 0 else 0.0
    for _ in range(rounds):
        bad = simplex_measures(q, tets) <= floor
        if not bad.any():
            break
        back = unique(tets[bad])
        back = back[moved[back]]
        if not len(back):
            break
        q[back] = old[back]
        moved[back] = False
    return q


def _collapse_stuck(p, t, faces, markers, want, floor: float, short: float, phase=None):
    """Where curved faces meet (and wherever the projection left a vertex short): the
    boundary vertices the projection left more than
    ``short`` from their place ``want`` collapsed, the farthest first, each onto the
    neighbour nearest to its place that lies on every face it lies on, where the
    tetrahedra changed keep volumes above ``floor`` and the boundary stays the faces'
    triangles less the two collapsed. Such a vertex sits where the cuts' polyline zigzags
    among tiny tetrahedra (too small for its move); MMG's ridge analysis makes it a corner
    (a sharp turn of the ridge), which it never moves or removes, so the size rounds alone
    keep it. With ``phase`` (the tetrahedra's phases, carried), a vertex of an interface
    between phases is not collapsed. ``(points, tets, faces, markers, kept, number
    collapsed, phase)``, the vertices no longer used dropped (``kept``: the indices of those
    kept)."""
    n = len(p)
    inc = face_incidence(n, faces, markers)
    left = np.linalg.norm(want - p, axis=1)
    if phase is not None:  # not the vertices of interfaces between phases
        inter, _ = interface_faces(np.asarray(t, dtype=np.int64), np.asarray(phase))
        left[unique(inter)] = 0.0
    stuck = np.flatnonzero(left > short)
    stuck = stuck[np.lexsort((stuck, -left[stuck]))]
    done = 0
    for v in stuck.tolist():
        star = (t == v).any(axis=1)
        if not star.any():
            continue
        nb = unique(t[star])
        nb = [int(w) for w in nb if w != v and inc[v] <= inc[w]]
        nb.sort(key=lambda w: (float(np.linalg.norm(p[w] - want[v])), w))
        for w in nb:
            gone = star & (t == w).any(axis=1)
            nt = np.where(t == v, w, t)[~gone]
            ch = np.flatnonzero(star[~gone])
            if not len(ch) or (simplex_measures(p, nt[ch]) <= floor).any():
                continue
            fgone = (faces == v).any(axis=1) & (faces == w).any(axis=1)
            nf = np.where(faces == v, w, faces)[~fgone]
            if not same_boundary(nt, nf):
                continue
            t, faces, markers = nt, nf, markers[~fgone]
            if phase is not None:
                phase = phase[~gone]
            inc[w] |= inc[v]
            inc[v] = set()
            done += 1
            break
    if not done:
        return p, t, faces, markers, unique(t), 0, phase
    p, t, faces, used = drop_unused(p, t, faces)
    return p, t, faces, markers, used, done, phase


def _collapse_slivers(solid, p, t, faces, markers, ok, chord: float):
    """On the path for meeting curved faces, the edges between boundary vertices of the
    tetrahedra under :data:`COLLAPSE_BOUND` degrees (where the size rounds left tiny
    tetrahedra along the curve) collapsed, the shortest first
    (:func:`hetmesh.tet.collapse.collapse_edges`, at most :data:`COLLAPSE_PASSES`): only
    if the tetrahedra changed get a larger smallest dihedral angle and pass ``ok(tets)``
    (delta), and the triangles at the kept end pass the verification's checks of their
    faces (curved ones within ``chord``, planes exactly) and of the edges between meeting
    faces (:func:`face_keeper`). ``(tets, faces, markers)``; the points are not changed."""
    return collapse_edges(p, t, faces, markers, angle=min_dihedral,
                          bad=lambda ang: ang < COLLAPSE_BOUND, ok=ok,
                          keeps=face_keeper(solid, p, chord), passes=COLLAPSE_PASSES)


def face_keeper(solid, p, chord: float):
    """The predicate ``keeps(faces, markers)`` of an edge collapse
    (:func:`hetmesh.tet.collapse.collapse_edges`) that holds when the boundary triangles it
    is given pass the verification's checks (:func:`solid_problems`): on a curved face
    within ``chord`` of its surface at the sample points :data:`BARY`, on a plane exactly,
    and the edges between meeting faces (:func:`edge_problems`). ``solid`` a
    :class:`CSGSolid` or another solid with ``faces`` and ``diameter`` (a carved one)."""
    def keeps(f, m) -> bool:
        return _on_their_faces(solid, p, f, m, chord) and not edge_problems(p, f, m, solid,
                                                                             chord)

    return keeps


def _on_their_faces(solid, p, f, m, chord: float) -> bool:
    """Whether the triangles ``f`` lie on the faces ``m`` (indices into ``solid.faces``):
    a curved one within ``chord`` of its surface at the sample points :data:`BARY`, a
    plane within the rounding (1e-9 x the diameter)."""
    exact = 1e-9 * solid.diameter
    for fi in unique(m).tolist():
        surf = solid.faces[fi].surface
        at = np.einsum("bk,nkd->nbd", BARY, p[f[m == fi]]).reshape(-1, 3)
        if float(np.abs(surf.g(at)).max(initial=0.0)) > (chord if surf.curved else exact):
            return False
    return True


def _boundary(solid, p, t, tol):
    faces, _ = boundary_faces(t)
    markers = solid.classify(p[faces], tol)
    if (markers < 0).any():
        c = p[faces[markers < 0][0]].mean(axis=0)
        raise MeshingError(f"{int((markers < 0).sum())} boundary triangles on no face of the "
                           f"solid (e.g. at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    return faces, markers


# -- 4. size ----------------------------------------------------------------------------

def size_field(field, points, threshold, h_max, h_min):
    """``S delta_0 / |grad f|`` at ``points``, in ``[h_min, h_max]``."""
    g = np.linalg.norm(field.gradient(points), axis=2).max(axis=1)
    with np.errstate(divide="ignore"):
        h = S * threshold / g
    return np.clip(h, h_min, h_max)


def next_size(h_mmg, field, points, tets, bad, threshold, h_max, h_min):
    """The size for the next MMG round: the size MMG interpolated at the vertices ``h_mmg``
    (which keeps the earlier rounds' shrinking), at most the field's (:func:`size_field`),
    times :data:`SHRINK` at the vertices of the violating tetrahedra ``bad``, at least
    ``h_min``."""
    size = np.minimum(h_mmg, size_field(field, points, threshold, h_max, h_min))
    shrink = np.ones(len(points))
    shrink[tets[bad].ravel()] = SHRINK
    return np.maximum(size * shrink, h_min)


def cap_curved(solid, size, faces, markers, chord):
    """``size`` with the vertices of curved faces' triangles capped at the edge length
    whose triangles stay within ``chord`` of their surface (:func:`chord_size`)."""
    size = size.copy()
    for fi, f in enumerate(solid.faces):
        if f.surface.curved:
            ids = unique(faces[markers == fi])
            size[ids] = np.minimum(size[ids], math.sqrt(6.0 * f.surface.radius * chord))
    return size


def mmg_remesh(p, t, faces, markers, size, hausd, *, ridge_angle: float | None = None,
               phase=None):
    """One MMG remeshing of ``(p, t)`` to the isotropic ``size`` per vertex, the boundary
    triangles ``faces`` with their ``markers`` kept as references, Hausdorff distance
    ``hausd``, gradation :data:`HGRAD`: ``(points, tets, faces, markers, size, phase)``, the
    size MMG interpolated at the new vertices. ``phase (M,)`` (or None): every
    tetrahedron's phase (the subregion of a piecewise composition,
    :mod:`hetmesh.tet.jumps`), given to MMG as its reference with the triangles between
    phases, so that MMG keeps them as interfaces; the new tetrahedra's phases are returned
    (None without). ``ridge_angle`` (degrees; None: MMG's 45):
    MMG's ridge angle, which makes a vertex whose two ridge edges turn by more than it a
    corner (never moved or removed); given, the edges between triangles of different
    markers are given to MMG as ridges, so that the angle does not decide those (but for
    those between coplanar triangles, which MMG would drop with a warning)."""
    mmgpy = quiet_mmg()
    m = mmgpy.MmgMesh3D()
    ridges = np.zeros((0, 2), dtype=np.int64)
    if ridge_angle is not None:
        edges, ta, tb = boundary_edge_pairs(faces)
        q = p[np.asarray(faces, dtype=np.int64)]
        nrm = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
        flat = np.abs(np.einsum("ij,ij->i", nrm[ta], nrm[tb])) > 1.0 - 1e-5
        mk = np.asarray(markers)
        ridges = edges[(mk[ta] != mk[tb]) & ~flat]
    tri, refs = np.asarray(faces), np.asarray(markers) + 1
    if phase is not None:
        inter, _ = interface_faces(np.asarray(t, dtype=np.int64), np.asarray(phase))
        tri = np.concatenate([tri, inter])
        refs = np.r_[refs, np.full(len(inter), INTERFACE_REF)]
    m.set_mesh_size(vertices=len(p), tetrahedra=len(t), triangles=len(tri),
                    edges=len(ridges))
    m.set_vertices(np.ascontiguousarray(p))
    if phase is None:
        m.set_tetrahedra(np.ascontiguousarray(t, dtype=np.int32))
    else:
        m.set_tetrahedra(np.ascontiguousarray(t, dtype=np.int32),
                         np.ascontiguousarray(np.asarray(phase) + 1, dtype=np.int32))
    m.set_triangles(np.ascontiguousarray(tri, dtype=np.int32),
                    np.ascontiguousarray(refs, dtype=np.int32))
    opts = {}
    if ridge_angle is not None:
        if len(ridges):
            m.set_edges(np.ascontiguousarray(ridges, dtype=np.int32),
                        np.zeros(len(ridges), dtype=np.int32))
            m.set_ridge_edges(np.arange(len(ridges), dtype=np.int32))
        opts["ar"] = float(ridge_angle)
    m.set_field("metric", np.ascontiguousarray(size, dtype=np.float64).reshape(-1, 1))
    out = m.remesh(verbose=-1, hausd=float(hausd), hgrad=HGRAD, **opts)
    if out.get("return_code", 0) != 0:
        raise MeshingError(f"MMG remeshing failed (code {out.get('return_code')})")
    p = np.array(m.get_vertices(), dtype=np.float64)
    tt, tr = m.get_tetrahedra_with_refs()
    t = orient_positive(p, np.asarray(tt, dtype=np.int64))
    f, fr = m.get_triangles_with_refs()
    h = np.asarray(m.get_field("metric"), dtype=np.float64).reshape(-1)
    phase = None if phase is None else np.asarray(tr, dtype=np.int64) - 1
    return p, t, np.asarray(f, dtype=np.int64), np.asarray(fr, dtype=np.int64) - 1, h, phase


def remesh_solid(solid: CSGSolid, p, t, faces, markers, size, hausd: float, tol: float):
    """:func:`_remesh` on the path the solid's pairs of meeting curved faces
    (:func:`meeting_pairs`) choose: ``(points, tets, faces, markers, size MMG
    interpolated)``."""
    return _remesh(solid, p, t, faces, markers, size, hausd, tol,
                   bool(meeting_pairs(solid)))[:5]


def _remesh(solid: CSGSolid, p, t, faces, markers, size, hausd: float, tol: float,
            meeting: bool, phase=None, field=None):
    """One MMG remeshing of a solid's mesh to ``size`` (:func:`mmg_remesh`), its boundary
    triangles named again (within ``tol`` of their faces) and its boundary vertices projected
    onto them (:func:`_project_safely`, ``meeting`` its path); with ``phase``, the phases
    kept and the interface vertices moved back onto the jump surfaces of ``field``
    (:func:`onto_phases`; in part where a whole move would flatten a tetrahedron: the next
    round remeshes around them): ``(points, tets, faces, markers, size MMG interpolated,
    phase)``."""
    p, t, fm, rm, h_mmg, phase = mmg_remesh(p, t, faces, markers, size, hausd,
                                            ridge_angle=RIDGE_ANGLE if meeting else None,
                                            phase=phase)
    faces, markers = _faces_after(solid, p, t, fm, rm, tol)
    p = _project_safely(solid, p, t, faces, markers, meeting)
    if phase is not None:
        p = onto_phases(solid, field, p, t, faces, markers, phase)
    return p, t, faces, markers, h_mmg, phase


def onto_phases(solid: CSGSolid, field, p, t, faces, markers, phase) -> np.ndarray:
    """The vertices of the interfaces between phases moved onto their jump surfaces
    (:func:`hetmesh.tet.jumps.onto_jumps`; a boundary vertex onto its faces' surfaces as
    well), except where a move would leave a tetrahedron around it without a positive
    volume (:func:`keep_positive`)."""
    inc = face_incidence(len(p), faces, markers)

    def face_surfaces(ids):
        out = []
        for v in ids.tolist():
            surfs = []
            for fi in sorted(inc[v]):
                s = solid.faces[fi].surface
                if all(s != o for o in surfs):
                    surfs.append(s)
            out.append(surfs)
        return out

    want = onto_jumps(field, p, t, phase, face_surfaces)
    # on a curved face, a part of the move would leave the surface: whole moves only
    curved = np.array([any(solid.faces[fi].surface.curved for fi in fs) for fs in inc],
                      dtype=bool).reshape(-1)
    q = moves_in_part(p, want, t, whole_only=curved)
    check_positive(q, t, "after moving the interface vertices onto the jumps")
    return q


def moves_in_part(p: np.ndarray, want: np.ndarray, t: np.ndarray, *,
                  whole_only: np.ndarray | None = None) -> np.ndarray:
    """``p`` with every vertex moved to ``want`` where no tetrahedron around it loses its
    positive volume (:func:`keep_positive`), else by the fractions :data:`PARTIAL` of the
    move in turn (not those of ``whole_only (N,) bool``), else not at all."""
    pending = (want != p).any(axis=1)
    q = p
    for frac in PARTIAL:  # what a whole move would flatten, in part
        if frac < 1.0 and whole_only is not None:
            pending &= ~whole_only
        if not pending.any():
            break
        cand = q.copy()
        cand[pending] = q[pending] + frac * (want[pending] - q[pending])
        new = keep_positive(q, cand, t, pending)
        pending &= ~(new != q).any(axis=1) | (frac < 1.0)
        q = new
    return q


def off_faces(solid: CSGSolid, p, faces, markers) -> float:
    """The largest ``|g|`` of a boundary vertex for the surface of a face it is on."""
    off = 0.0
    for fi, f in enumerate(solid.faces):
        ids = unique(faces[markers == fi])
        if len(ids):
            off = max(off, float(np.abs(f.surface.g(p[ids])).max()))
    return off


def _faces_after(solid, p, t, f_mmg, r_mmg, tol):
    """Boundary triangles of ``t`` with the face MMG kept for them (its triangles' refs),
    checked against the geometry."""
    faces, _ = boundary_faces(t)
    n = len(p) + 1
    def key(f):
        s = np.sort(f, axis=1)
        return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]
    kb, km = key(faces), key(f_mmg)
    order = np.argsort(km)
    pos = np.clip(np.searchsorted(km[order], kb), 0, len(km) - 1)
    hit = km[order][pos] == kb
    markers = np.where(hit, r_mmg[order][pos], -1)
    bad = (markers < 0) | (markers >= len(solid.faces))
    if bad.any():  # triangles MMG did not report: classify them by their geometry
        markers[bad] = solid.classify(p[faces[bad]], tol)
    if (markers < 0).any():
        c = p[faces[markers < 0][0]].mean(axis=0)
        raise MeshingError(f"{int((markers < 0).sum())} boundary triangles on no face of the "
                           f"solid after remeshing (e.g. at ({c[0]:.6g}, {c[1]:.6g}, "
                           f"{c[2]:.6g}))")
    return faces, markers


def chord_size(solid: CSGSolid, chord: float) -> float:
    """The edge length whose triangles on the most curved face stay within ``chord``
    (an equilateral triangle of edge e on radius R is e^2 / (6 R) off the surface)."""
    radii = [s.radius for s in solid.curved]
    return math.sqrt(6.0 * min(radii) * chord) if radii else math.inf


def estimate_solid(solid, field, threshold: float) -> float:
    """A-priori element count: regular tetrahedra of edge ``S delta_0 / |grad f|`` (capped
    as the mesher caps it) over the solid, twice for the rounds and the repair, plus the
    boundary layer."""
    lo, hi = solid.bounds
    n = 32
    h = (hi - lo) / n
    g = [lo[k] + h[k] * (np.arange(n) + 0.5) for k in range(3)]
    pts = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1).reshape(-1, 3)
    pts = pts[solid.contains(pts)]
    if not len(pts):
        return 100.0
    hh = size_field(field, pts, threshold, solid.diameter, 1e-300)
    per = 6.0 * math.sqrt(2.0) / hh ** 3  # regular tetrahedra per unit volume
    return 2.0 * float(per.sum() * np.prod(h)) + 100.0


def background_spacing(solid: CSGSolid) -> float:
    """The spacing of the background grid the solid is cut from: its largest extent over
    :data:`MAX_CELLS`, and at least :data:`CELLS_PER_RADIUS` cells across its smallest
    curved radius (at most a sixth of the extent)."""
    lo, hi = solid.bounds
    extent = float((hi - lo).max())
    radii = [s.radius for s in solid.curved]
    spacing = extent / MAX_CELLS
    if radii:
        spacing = max(spacing, min(extent / 6, min(radii) / CELLS_PER_RADIUS))
    return spacing


def meeting_pairs(solid) -> tuple:
    """The pairs of curved faces of ``solid`` that meet
    (:attr:`~hetmesh.tet.implicit.CSGSolid.curved_edges`); none for solids that do not
    list them (the carved sweeps of :mod:`hetmesh.tet.carve`, which share the functions
    here)."""
    return getattr(solid, "curved_edges", ())


def remesh_until_settled(remesh, state, *, most: int, least: int = 1):
    """``state = remesh(state, k)`` for k = 1, 2, ... (``state[1]``: the tetrahedra), at
    least ``least`` and at most ``most`` times, until a remeshing removes at most
    :data:`SETTLE` of the tetrahedra: one MMG pass coarsens a far finer mesh only part of
    the way (the size rounds of carved solids, :mod:`hetmesh.tet.carve`, and of voxel
    masks, :mod:`hetmesh.tet.masked`). ``(state, remeshings)``."""
    k = 0
    for k in range(1, most + 1):
        n = len(state[1])
        state = remesh(state, k)
        log.debug("remeshing %d: %d tetrahedra (from %d)", k, len(state[1]), n)
        if k >= least and len(state[1]) >= (1.0 - SETTLE) * n:
            break
    return state, k


def carry(ref, values, points) -> np.ndarray:
    """``values`` at the points ``ref (K, 3)`` carried to ``points``: each point gets the value
    of its nearest point of ``ref``."""
    from scipy.spatial import cKDTree
    _, j = cKDTree(ref).query(points)
    return np.asarray(values)[j]


def size_rounds(solid: CSGSolid, p, t, faces, markers, size, chord: float, tol: float,
                meeting: bool, material, phase=None, field=None):
    """The size rounds of a solid's mesh (step 4 of the module docstring), shared by the
    adaptive mesh and the uniform baseline: MMG remeshes ``(p, t)`` to ``size`` (Hausdorff
    distance :data:`HAUSD` x the chord tolerance ``chord``) and the boundary vertices are
    projected onto their faces (:func:`_remesh`; ``tol`` names the faces of the triangles
    MMG did not report), then again to the round's size carried to the new vertices
    (:func:`carry`, capped on the curved faces) while a remeshing removes more than
    :data:`SETTLE` of the tetrahedra (:func:`remesh_until_settled`, at most
    :data:`SETTLE_PASSES` remeshings, at least two from the start, whose first remeshing
    refines the boundary as it coarsens the inside); on the path for meeting curved faces
    (``meeting``), one remeshing a round (repeated, with the chord tolerance as Hausdorff
    distance, the cylinder with a wider spherical cavity of tests/test_csg_edges.py at
    delta_0 = 0.4 and chord 0.01 went from 4,074 to 591 tetrahedra, the mean radius ratio
    from 0.755 to 0.737 under the target, the slivers along the edge a larger share), and
    the vertices left short of their faces are collapsed after each round but the last
    (:func:`_collapse_stuck`; on the plain path those the projection left more than
    :data:`STUCK` x ``chord`` short). ``material(points, tets, size MMG interpolated, round,
    phase)`` checks the budget and says whether the material is met, with a callable giving
    the next round's size (before the chord cap) otherwise. ``phase`` (None: none): the
    tetrahedra's phases, kept as interfaces through every remeshing, their vertices put back
    on the jump surfaces of ``field`` (:func:`_remesh`). The rounds (at most :data:`SIZE_ROUNDS`
    after the first) end when the material is met and, on the path for meeting faces, no
    vertex was collapsed and every boundary vertex is within :data:`SETTLED` x ``chord`` of
    its faces. ``(points, tets, faces, markers, last round, phase)``."""
    hausd = HAUSD * chord
    ref = p  # the points the round's size is given at

    def once(state, k):
        q, t, faces, markers, _, phase = state
        s = size if k == 1 else cap_curved(solid, carry(ref, size, q), faces, markers, chord)
        return _remesh(solid, q, t, faces, markers, s, hausd, tol, meeting, phase, field)

    rounds = 0
    for rounds in range(SIZE_ROUNDS + 1):
        (p, t, faces, markers, h_mmg, phase), _ = remesh_until_settled(
            once, (p, t, faces, markers, None, phase), most=1 if meeting else SETTLE_PASSES,
            least=2 if rounds == 0 else 1)
        collapsed = 0
        want = project(solid, p, faces, markers) if rounds < SIZE_ROUNDS else p
        if meeting or (np.linalg.norm(want - p, axis=1) > STUCK * chord).any():
            # MMG keeps the vertices the projection left short (its corners; on the plain
            # path, a vertex it moved along the edge between a plane and a curved face,
            # next to a tetrahedron the move would flatten): collapsed here, MMG remeshes
            # around their neighbours in the next round
            p, t, faces, markers, kept, collapsed, phase = _collapse_stuck(
                p, t, faces, markers, want, MIN_VOLUME * solid.diameter ** 3,
                STUCK * chord, phase)
            if collapsed:
                h_mmg = h_mmg[kept]
                p = _project_safely(solid, p, t, faces, markers, meeting)
                log.info("solid: %d boundary vertices short of their faces collapsed",
                         collapsed)
        met, resize = material(p, t, h_mmg, rounds, phase)
        # where curved faces meet, the rounds go on until the projection has put the
        # boundary vertices on their faces (MMG remeshes what it could not move)
        settled = not collapsed and (
            not meeting or off_faces(solid, p, faces, markers) <= SETTLED * chord)
        if (met and settled) or rounds == SIZE_ROUNDS:
            break
        ref, size = p, cap_curved(solid, resize(), faces, markers, chord)
    return p, t, faces, markers, rounds, phase


def finish_meeting(solid: CSGSolid, p, t, faces, markers, comp, threshold: float,
                   chord: float):
    """The last step of the path for meeting curved faces, shared by the adaptive mesh and
    the uniform baseline: the slivers along the edge collapsed (:func:`_collapse_slivers`,
    every changed tetrahedron's delta over the vertex compositions ``comp`` below
    ``threshold``), then flipped (:func:`_flip_meeting`). ``(points, tets, faces, markers,
    composition, delta)``."""
    t, faces, markers = _collapse_slivers(
        solid, p, t, faces, markers, lambda tets: delta_vertices(comp, tets) < threshold,
        chord)
    p, t, faces, comp, delta = _flip_meeting(p, t, faces, comp, threshold)
    return p, t, faces, markers, comp, delta


def generate_solid(solid: CSGSolid, field, threshold: float, *, seed: int = 0,
                   chord_tol: float | None = None, max_elements: int | None = None,
                   max_size: float | None = None, check: bool = True) -> TetResult:
    """Tetrahedralise a :class:`~hetmesh.tet.implicit.CSGSolid` with every element's delta
    below ``threshold`` (see the module docstring). ``seed`` is accepted for the common
    interface; the mesh does not depend on it (MMG is deterministic). ``info["meeting_path"]``
    says which path made the mesh.

    Where curved faces meet (:attr:`~hetmesh.tet.implicit.CSGSolid.curved_edges`), the
    plain path (one level-set cut after the other, no improvement between them) is tried
    first (``meeting=False``) and kept if its mesh passes the whole verification, the
    edges between curved faces included, and its smallest dihedral angle is at least
    :data:`PLAIN_DIHEDRAL`: it is faster where it works (a bore through a ball). The path
    for meeting faces (``meeting=True``) meshes the solids where it fails
    (a cylinder with a wider spherical cavity, two crossing bores)."""
    kw = dict(seed=seed, chord_tol=chord_tol, max_elements=max_elements, max_size=max_size)
    meeting = bool(meeting_pairs(solid))
    check_jumps(solid, field)
    if meeting:
        chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
        try:
            res = _generate_solid(solid, field, threshold, meeting=False, check=False, **kw)
            problems = solid_problems(res, solid, field, chord) if check else []
        except BudgetError:
            raise
        except (MeshingError, ArithmeticError, ValueError) as exc:
            problems = [str(exc).splitlines()[0] if str(exc) else type(exc).__name__]
        if not problems:
            worst = float(min_dihedral(res.points, res.tets).min()) if len(res.tets) else 0.0
            if worst < PLAIN_DIHEDRAL:
                problems = [f"its smallest dihedral angle is {worst:.1f} degrees"]
        if not problems:
            res.info["meeting_path"] = False
            return res
        log.info("solid: the plain path's mesh is not kept (%s); the path for meeting "
                 "curved faces", problems[0])
    res = _generate_solid(solid, field, threshold, meeting=meeting, check=check, **kw)
    res.info["meeting_path"] = meeting
    return res


def check_jumps(solid: CSGSolid, field) -> bool:
    """Whether the composition has jumps to embed (:func:`hetmesh.tet.jumps.has_jumps`);
    :class:`MaterialError` if it has and curved faces of ``solid`` meet (not supported)."""
    jumps = has_jumps(field)
    if jumps and meeting_pairs(solid):
        raise MaterialError(f"{field.describe_jump(0, 1)}: a composition with jumps in a "
                            f"solid whose curved faces meet is not supported (the jumps are "
                            f"embedded in solids whose curved faces do not meet)")
    return jumps


def solid_start(solid: CSGSolid, field, meeting: bool):
    """Steps 1-3 of the module docstring, shared by the adaptive mesh and the uniform
    baseline: the background grid cut along the curved surfaces (``meeting``: the path for
    meeting curved faces) and, for a piecewise composition, along its jumps
    (:func:`hetmesh.tet.jumps.cut_jumps`: the background's spacing then also fits
    :data:`CELLS_PER_RADIUS` cells across the jump surfaces' smallest radius of curvature,
    and the interface vertices are moved onto them), the boundary triangles named:
    ``(points, tets, faces, markers, phase or None, background spacing)``."""
    spacing = background_spacing(solid)
    phase = None
    jumps = check_jumps(solid, field)
    if jumps:
        lo, hi = solid.bounds
        spacing = max(min(spacing, jump_radius(field, lo, hi) / CELLS_PER_RADIUS),
                      float((hi - lo).max()) / MAX_CELLS)
    p, t = cut_solid(solid, spacing, meeting=meeting)
    if jumps:
        p, t, phase = cut_jumps(field, p, t, JUMP_SNAP * spacing)
    faces, markers = _boundary(solid, p, t, 0.5 * spacing)
    if phase is not None:  # the cut's interpolated crossings onto the jump surfaces
        p = onto_phases(solid, field, p, t, faces, markers, phase)
    return p, t, faces, markers, phase, spacing


def _generate_solid(solid: CSGSolid, field, threshold: float, *, meeting: bool, seed: int,
                    chord_tol, max_elements, max_size, check: bool) -> TetResult:
    """:func:`generate_solid` on one path: the one for meeting curved faces if ``meeting``
    (the cuts improved between each other, the projection's moves tried in part, the
    vertices left short of their faces collapsed between the size rounds, flips at the
    end), else the plain one. The verification (``check``) is the whole one either way."""
    del seed
    t0 = time.perf_counter()
    chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
    est = estimate_solid(solid, field, threshold)
    if max_elements is not None and est > max_elements:
        raise BudgetError(f"about {est:.0f} tetrahedra are needed for delta_0 = {threshold} "
                          f"but the budget is {max_elements}")
    p, t, faces, markers, phase, spacing = solid_start(solid, field, meeting)
    lo, hi = solid.bounds
    h_max = float((hi - lo).max()) / 4
    if max_size is not None:
        h_max = min(h_max, float(max_size))
    h_min = 1e-4 * solid.diameter

    def capped(size, p):  # at curved jump surfaces (the curved faces: cap_curved)
        return size if phase is None else jump_cap(field, p, size, chord)

    size = cap_curved(solid, capped(size_field(field, p, threshold, h_max, h_min), p), faces,
                      markers, chord)
    mtol = max(0.25 * h_max, 10 * chord)

    def material(p, t, h_mmg, rounds, phase):
        if max_elements is not None and len(t) > max_elements:
            raise BudgetError(f"the mesh has {len(t)} tetrahedra, over the budget of "
                              f"{max_elements}")
        bad = phase_delta(field, p, t, phase) >= threshold
        off = interface_off(field, p, t, phase)  # the rounds go on until the jumps settle
        log.info("solid: size round %d: %d tetrahedra, %d over delta_0%s", rounds, len(t),
                 int(bad.sum()), "" if phase is None else f", interfaces {off:.3g} off")
        met = not bad.any() and off <= SETTLED * chord
        return met, lambda: capped(next_size(h_mmg, field, p, t, bad, threshold, h_max,
                                             h_min), p)

    p, t, faces, markers, rounds, phase = size_rounds(solid, p, t, faces, markers, size,
                                                      chord, mtol, meeting, material, phase,
                                                      field)
    t_place = time.perf_counter() - t0
    passes = 0
    comp = field.composition(p)
    for _ in range(REPROJECT):
        if phase is None:
            p, t, comp, delta, n = repair(p, t, field, threshold, comp=comp,
                                          max_elements=max_elements)
        else:  # every tetrahedron's corners in its phase; the children keep it
            p, t, _, delta, n, trace = repair(p, t, field, threshold,
                                              max_elements=max_elements, regions=phase)
            phase = phase[trace.parent]
        passes += n
        faces, _ = boundary_faces(t)
        markers = solid.classify(p[faces], mtol)
        if n == 0:
            break
        # the midpoints of bisected boundary edges onto their curved faces (planar ones are
        # in their plane already); then the compositions there, and the repair again
        q = _project_safely(solid, p, t, faces, markers, meeting)
        moved = np.flatnonzero((q != p).any(axis=1))
        if not len(moved):
            break
        p = q
        if phase is None:
            comp = comp.copy()
            comp[moved] = field.composition(p[moved])
    else:
        raise MeshingError(f"the delta repair and the projection onto curved faces did not "
                           f"settle in {REPROJECT} rounds")
    if meeting:
        p, t, faces, markers, comp, delta = finish_meeting(solid, p, t, faces, markers, comp,
                                                           threshold, chord)
    else:  # (a vertex on a jump: its own subregion's composition)
        p, t, faces, markers, phase, delta = finish_plain(solid, field, p, t, faces, markers,
                                                          phase, threshold, chord)
        comp = field.composition(p)
    t = t.astype(np.int32)
    info = {"placement": "general", "size_rounds": rounds, "repair_passes": passes,
            "estimate": est, "composition": comp, "time_place": t_place,
            "background_spacing": spacing, "h_max": h_max}
    if phase is not None:
        info["regions"] = phase.astype(np.int32)
    res = with_interfaces(TetResult(p, t, faces.astype(np.int32),
                                    (markers + 1).astype(np.int32), tuple(solid.face_names),
                                    delta, float(threshold), info), field, len(solid.faces))
    if check:
        raise_problems(solid_problems(res, solid, field, chord))
    res.info["time_total"] = time.perf_counter() - t0
    log.info("solid mesh: %d points, %d tetrahedra, %d size rounds, %d repair passes, %.2f s",
             len(p), len(t), rounds, passes, res.info["time_total"])
    return res


def finish_plain(solid: CSGSolid, field, p, t, faces, markers, phase, threshold: float,
                 chord: float):
    """The last step of the plain path, shared by the adaptive mesh and the uniform
    baseline: :func:`flip_plain`, and with phases :func:`collapse_phase_slivers` and
    :func:`flip_plain` again. ``(points, tets, faces, markers, phase, delta)``."""
    p, t, faces, phase, delta = flip_plain(field, p, t, faces, phase, threshold)
    if phase is not None:
        p, t, faces, markers, phase = collapse_phase_slivers(
            solid, field, p, t, faces, markers, phase, threshold, chord)
        p, t, faces, phase, delta = flip_plain(field, p, t, faces, phase, threshold)
    return p, t, faces, markers, phase, delta


def flip_plain(field, p, t, faces, phase, threshold: float):
    """On the plain path, the tetrahedra under :data:`FLIP_BOUND` degrees (MMG leaves a
    few where its ridges meet: a plane and a curved face, a jump surface and the boundary)
    improved by flips, edge removals and collapses of inner vertices within each phase
    (:func:`hetmesh.tet.flips.flip_improve`; every new tetrahedron's delta below
    ``threshold`` in its phase); the boundary triangles and the interfaces between phases
    stay. A mesh without such tetrahedra is returned as it is. ``(points, tets, faces,
    phase, delta)``, the vertices no longer used dropped."""
    if len(t) and float(min_dihedral(p, t).min()) < FLIP_BOUND:
        ph = np.zeros(len(t), dtype=np.int64) if phase is None else np.asarray(phase)
        t, ph = flip_improve(p, t, ph, lambda tets, r: phase_delta(field, p, tets, r)
                             < threshold, bound=FLIP_BOUND)
        p, t, faces, _ = drop_unused(p, t, faces)
        phase = None if phase is None else ph
    return p, t, faces, phase, phase_delta(field, p, t, phase)


def collapse_phase_slivers(solid: CSGSolid, field, p, t, faces, markers, phase,
                           threshold: float, chord: float):
    """Where a jump surface meets the boundary, the tetrahedra under :data:`COLLAPSE_BOUND`
    degrees whose vertices all lie on the boundary or an interface (no flip reaches them)
    improved by edge collapses (:func:`hetmesh.tet.collapse.collapse_edges`, at most
    :data:`COLLAPSE_PASSES`): an end onto the other only where that one lies on every face
    and interface the first is on, the tetrahedra changed get a larger smallest dihedral
    angle and keep delta below ``threshold`` in their phases, the triangles at the kept end
    stay on their faces (planes exactly, curved faces within ``chord``) and their jump
    surfaces (within ``chord``), and the boundary and the interfaces stay those of the
    tetrahedra and their phases. ``(points, tets, faces, markers, phase)``, the vertices no
    longer used dropped; unchanged without phases or such tetrahedra."""
    if phase is None or not len(t) or float(min_dihedral(p, t).min()) >= COLLAPSE_BOUND:
        return p, t, faces, markers, phase
    nb = len(solid.faces)
    inter, sides = interface_faces(np.asarray(t, dtype=np.int64), np.asarray(phase))
    allf = np.concatenate([faces, inter]).astype(np.int64)
    allm = np.r_[markers, nb + (sides[:, 0] ^ sides[:, 1])].astype(np.int64)

    def keeps(f, m) -> bool:
        bnd = m < nb
        if not _on_their_faces(solid, p, f[bnd], m[bnd], chord):
            return False
        for fi in unique(m[~bnd]).tolist():
            at = np.einsum("bk,nkd->nbd", BARY, p[f[m == fi]]).reshape(-1, 3)
            for i in range(len(field.conditions)):
                if (fi - nb) >> i & 1 and \
                        float(JumpSurface(field, i).distance(at).max()) > chord:
                    return False
        return True

    def same(nt, nf, nm, nph) -> bool:
        bnd = nm < nb
        return same_boundary(nt, nf[bnd]) and same_triangles(interface_faces(nt, nph)[0],
                                                             nf[~bnd])

    def ok(tets, ph):
        return phase_delta(field, p, tets, ph) < threshold

    t, allf, allm, phase = collapse_edges(
        p, t, allf, allm, angle=min_dihedral, bad=lambda ang: ang < COLLAPSE_BOUND, ok=ok,
        keeps=keeps, passes=COLLAPSE_PASSES, phase=np.asarray(phase, dtype=np.int64),
        same=same)
    faces, markers = allf[allm < nb], allm[allm < nb]
    p, t, faces, _ = drop_unused(p, t, faces)
    return p, t, faces, markers, phase


def _flip_meeting(p, t, faces, comp, threshold: float):
    """On the path for meeting curved faces, the tetrahedra under :data:`FLIP_BOUND`
    degrees (the shallow ones along the edge where the faces meet) improved by flips, edge
    removals and collapses of inner vertices (:func:`hetmesh.tet.flips.flip_slivers`), each
    new tetrahedron's delta below ``threshold``; the boundary triangles stay. ``(points,
    tets, faces, composition, delta)``, the vertices no longer used dropped."""
    p, t, faces, comp = flip_slivers(p, t, faces, comp, threshold, FLIP_BOUND)
    return p, t, faces, comp, delta_vertices(comp, t)


def check_positive(p, t, when: str) -> None:
    """Raise :class:`~hetmesh.errors.MeshingError` if a tetrahedron of ``(p, t)`` has no
    positive volume, naming how many, where the first is and ``when`` (the step that left
    them, e.g. "after projecting the boundary vertices")."""
    v = simplex_measures(p, t)
    if (v <= 0).any():
        i = int(np.argmin(v))
        c = p[t[i]].mean(axis=0)
        raise MeshingError(f"{int((v <= 0).sum())} tetrahedra not of positive volume {when} "
                           f"(e.g. at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")


def recorded_interface_problems(res, recorded) -> list[str]:
    """One line if the interface triangles recorded as faces (``recorded``) are not exactly
    the triangles between the tetrahedra's phases (``res.info["regions"]``)."""
    phase = res.info.get("regions")
    if phase is None:
        return [f"{len(recorded)} triangles recorded after the faces of the solid, but the "
                f"mesh has no phases"]
    inter, _ = interface_faces(np.asarray(res.tets, dtype=np.int64), np.asarray(phase))
    if not same_triangles(inter, recorded):
        return [f"{len(recorded)} interface triangles recorded, {len(inter)} between the "
                f"phases of the tetrahedra"]
    return []


def with_interfaces(res: TetResult, field, n_faces: int) -> TetResult:
    """``res`` with the triangles between its phases (``info["regions"]``) recorded after
    its boundary as faces ``discontinuity[k]``, one per jump condition of ``field`` that has
    any (a triangle between phases that differ in several conditions goes to the first);
    ``n_faces`` the solid's own faces. Unchanged without phases."""
    phase = res.info.get("regions")
    if phase is None:
        return res
    inter, sides = interface_faces(np.asarray(res.tets, dtype=np.int64), np.asarray(phase))
    if not len(inter):
        return res
    bits = (sides[:, 0] ^ sides[:, 1]).astype(np.int64)
    first = np.zeros(len(bits), dtype=np.int64)
    for i in reversed(range(len(field.conditions))):
        first[(bits >> i & 1) == 1] = i
    present = unique(first)
    marker = np.searchsorted(present, first) + n_faces + 1
    names = tuple(f"{DISCONTINUITY}[{k}]" for k in range(len(present)))
    res.faces = np.concatenate([res.faces, inter.astype(np.int32)])
    res.face_markers = np.concatenate([res.face_markers, marker.astype(np.int32)])
    res.face_names = tuple(res.face_names[:n_faces]) + names
    res.info["jump_conditions"] = tuple(field.conditions[i] for i in present.tolist())
    return res


def solid_problems(res, solid: CSGSolid, field, chord_tol: float) -> list[str]:
    """Every broken claim of a mesh of ``solid``, one line each (empty: valid). delta is
    recomputed from ``field`` at the vertices (None: the result's own delta, as another
    sampling measured it)."""
    p, t = res.points, res.tets
    if len(t) == 0:
        return ["no tetrahedra"]
    out = validity_problems(p, t)
    faces, markers = res.faces, res.face_markers.astype(np.int64) - 1
    inner = markers >= len(solid.faces)  # the jumps' interfaces, recorded after the boundary
    if inner.any():
        out += recorded_interface_problems(res, faces[inner])
        faces, markers = faces[~inner], markers[~inner]
    bf, _ = boundary_faces(t)
    if len(bf) != len(faces):
        out.append(f"{len(faces)} boundary triangles recorded, {len(bf)} in the tetrahedra")
    if (markers < 0).any():
        c = p[faces[markers < 0][0]].mean(axis=0)
        out.append(f"{int((markers < 0).sum())} boundary triangles on no face of the solid "
                   f"(e.g. at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
        return out
    exact = 1e-9 * solid.diameter
    for fi, f in enumerate(solid.faces):
        sel = markers == fi
        if not sel.any():
            continue
        tri = p[faces[sel]]
        pts = np.einsum("bk,nkd->nbd", BARY, tri).reshape(-1, 3)
        dev = np.abs(f.surface.g(pts))
        lim = chord_tol if f.surface.curved else exact
        if float(dev.max()) > lim * (1 + 1e-9):
            out.append(f"face {f.name!r}: a triangle is {float(dev.max()):.3g} off its "
                       f"surface (allowed {lim:.3g})")
    out += edge_problems(p, faces, markers, solid, chord_tol)
    vol = float(simplex_measures(p, t).sum())
    # a boundary triangle within chord_tol of its surface bounds a volume of at most
    # chord_tol x its area between them
    area = 0.5 * np.linalg.norm(np.cross(p[faces[:, 1]] - p[faces[:, 0]],
                                         p[faces[:, 2]] - p[faces[:, 0]]), axis=1).sum()
    if solid.exact_volume is not None:
        if abs(vol - solid.exact_volume) > chord_tol * area + 1e-9 * solid.exact_volume:
            out.append(f"volume {vol:.12g} differs from the solid's {solid.exact_volume:.12g} "
                       f"by more than the chord tolerance allows")
    elif abs(vol - solid.volume) > chord_tol * area + 0.01 * solid.volume:
        out.append(f"volume {vol:.12g} differs from the solid's (grid estimate "
                   f"{solid.volume:.12g}) by more than the chord tolerance allows and 1 %")
    return out + centroid_and_delta_problems(res, solid, field, chord_tol, "the solid")


def onto_curve(s1, s2, x: np.ndarray, iters: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """Points of the curve ``s1.g = s2.g = 0`` reached from ``x (N, 3)`` by Gauss-Newton
    with the least-norm step, and whether each converged (to ``1e-12`` of the larger
    coordinate). A point of the curve is at least as far from ``x`` as the curve is, so
    ``|x - result|`` bounds the distance to the curve from above."""
    y = np.asarray(x, dtype=np.float64).reshape(-1, 3).copy()
    ok = np.zeros(len(y), dtype=bool)
    scale = max(1.0, float(np.abs(y).max())) if len(y) else 1.0
    for _ in range(iters):
        g = np.stack([s1.g(y), s2.g(y)], axis=1)
        J = np.stack([s1.grad(y), s2.grad(y)], axis=1)
        JJ = np.einsum("nki,nli->nkl", J, J)
        det = JJ[:, 0, 0] * JJ[:, 1, 1] - JJ[:, 0, 1] * JJ[:, 1, 0]
        good = np.abs(det) > 1e-12
        lam = np.zeros_like(g)
        inv = np.stack([np.stack([JJ[:, 1, 1], -JJ[:, 0, 1]], 1),
                        np.stack([-JJ[:, 1, 0], JJ[:, 0, 0]], 1)], 1)
        lam[good] = np.einsum("nkl,nl->nk", inv[good], g[good]) / det[good, None]
        step = np.einsum("nki,nk->ni", J, lam)
        y -= step
        ok = good & (np.abs(np.stack([s1.g(y), s2.g(y)], 1)).max(axis=1) <= 1e-12 * scale)
        if ok.all():
            break
    return y, ok


def boundary_edge_pairs(faces) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The edges of a closed boundary, each in two of its triangles ``faces``: ``(edges
    (E, 2) sorted, index of the one triangle, index of the other)``."""
    f = np.asarray(faces, dtype=np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    tri = np.tile(np.arange(len(f)), 3)
    n = int(f.max()) + 1 if len(f) else 1
    key = e[:, 0] * n + e[:, 1]
    order = np.lexsort((tri, key))
    key, tri, e = key[order], tri[order], e[order]
    first = np.r_[True, key[1:] != key[:-1]]
    a_idx = np.flatnonzero(first)
    b_idx = a_idx + 1
    b_idx = b_idx[b_idx < len(key)]
    a_idx = a_idx[:len(b_idx)]
    pair = key[a_idx] == key[b_idx]
    a_idx, b_idx = a_idx[pair], b_idx[pair]
    return e[a_idx], tri[a_idx], tri[b_idx]


def edge_problems(points, faces, markers, solid: CSGSolid, chord_tol: float) -> list[str]:
    """The edges between two curved faces (:attr:`CSGSolid.curved_edges`) against the
    exact curve where their surfaces meet: every boundary edge with a triangle of each face
    within ``chord_tol`` of that curve at its ends, quarter points and midpoint (the
    distance bounded from above by a point of the curve, :func:`onto_curve`)."""
    out = []
    if not meeting_pairs(solid):
        return out
    edges, ta, tb = boundary_edge_pairs(faces)
    mk = np.asarray(markers, dtype=np.int64)
    fa, fb = mk[ta], mk[tb]
    ts = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    for i, j in meeting_pairs(solid):
        sel = ((fa == i) & (fb == j)) | ((fa == j) & (fb == i))
        if not sel.any():
            continue
        ed = edges[sel]
        x0, x1 = points[ed[:, 0]], points[ed[:, 1]]
        x = (x0[:, None, :] + ts[None, :, None] * (x1 - x0)[:, None, :]).reshape(-1, 3)
        y, ok = onto_curve(solid.faces[i].surface, solid.faces[j].surface, x)
        d = np.where(ok, np.linalg.norm(x - y, axis=1), np.inf)
        if float(d.max()) > chord_tol * (1 + 1e-9):
            k = int(np.argmax(d))
            out.append(f"edge {solid.faces[i].name!r}/{solid.faces[j].name!r}: a point "
                       f"({x[k, 0]:.6g}, {x[k, 1]:.6g}, {x[k, 2]:.6g}) is {float(d[k]):.3g} "
                       f"off the curve where the surfaces meet (allowed {chord_tol:.3g})")
    return out


def centroid_and_delta_problems(res, solid, field, chord_tol: float, what: str) -> list[str]:
    """The last checks of a remeshed solid: every tetrahedron's centroid inside ``solid``
    (``solid.contains(points, tol)``, called ``what`` in the message), and delta_max below
    delta_0 (``res.delta``, or recomputed at the vertices from ``field`` if given). A mesh
    with phases (``res.info["regions"]``, the jumps of a piecewise composition) has delta
    measured in every tetrahedron's phase and the claims of
    :func:`hetmesh.tet.jumps.jump_problems` checked too."""
    out = []
    p, t = res.points, res.tets
    cen = p[t].mean(axis=1)
    outside = ~solid.contains(cen, chord_tol)
    if outside.any():
        c = cen[outside][0]
        out.append(f"{int(outside.sum())} tetrahedra outside {what} (e.g. at "
                   f"({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    phase = res.info.get("regions") if field is not None and has_jumps(field) else None
    if phase is not None:
        out += jump_problems(field, p, t, phase, chord_tol)
    delta = res.delta if field is None else phase_delta(field, p, t, phase)
    if not float(delta.max()) < res.threshold:
        out.append(f"delta_max = {float(delta.max()):.6g} is not below delta_0 = "
                   f"{res.threshold:g}")
    return out


#: regular tetrahedra of edge h per h^3 of volume (a remeshed uniform mesh's estimate)
REGULAR_PER_H3 = 6.0 * math.sqrt(2.0)


def estimate_regular(solid, h: float) -> float:
    """A-priori tetrahedron count of a remeshed uniform mesh of size ``h``: regular
    tetrahedra of edge ``h`` over the solid's volume (:data:`REGULAR_PER_H3`), plus 100."""
    return REGULAR_PER_H3 * float(solid.volume) / h ** 3 + 100.0


def check_estimate(h: float, est: float, max_elements: int | None) -> float:
    """The uniform baselines' budget before meshing: :class:`BudgetError` if the estimate
    ``est`` of the mesh of size ``h`` exceeds ``max_elements`` (None: no budget); else
    ``est``."""
    if max_elements is not None and est > max_elements:
        raise BudgetError(f"a uniform tetrahedral mesh of size {h:.4g} needs about "
                          f"{est:,.0f} tetrahedra, over the budget of {max_elements:,}")
    return est


def check_count(h: float, n: int, max_elements: int | None) -> None:
    """The uniform baselines' budget after meshing: :class:`BudgetError` if the mesh of
    size ``h`` has more than ``max_elements`` tetrahedra (``n``; None: no budget)."""
    if max_elements is not None and n > max_elements:
        raise BudgetError(f"the uniform mesh of size {h:.4g} has {n:,} tetrahedra, "
                          f"over the budget of {max_elements:,}")


def uniform_solid_at(solid: CSGSolid, field, h: float, threshold: float, *,
                     chord_tol: float | None = None,
                     max_elements: int | None = None) -> TetResult:
    """The uniform baseline's mesh of a solid of primitives at size ``h``, not verified: the
    adaptive mesher's path with the constant size ``h`` and nothing refined for the
    material. The same start as :func:`generate_solid` (the cut background grid), remeshed
    by MMG to ``h`` (capped on curved faces for the chord tolerance ``chord_tol``, absolute,
    as the adaptive mesh is) with the boundary vertices projected onto their faces
    (:func:`size_rounds`: one round, remeshed again while that coarsens, or, where curved
    faces meet, rounds until the vertices are on their faces, those left short collapsed
    between the rounds); where curved faces meet, the slivers
    along the edge collapsed and flipped as in the adaptive mesh (:func:`finish_meeting`, no
    changed tetrahedron's delta reaching ``threshold``). Where curved faces meet, the path
    for meeting faces is taken at once (the adaptive mesher tries the plain one first).
    The jumps of a piecewise composition are cut and kept as in the adaptive mesh
    (:func:`solid_start`; the size capped at curved jump surfaces, the rounds going on until
    the interface vertices are on them). ``delta`` over the vertices is measured,
    ``threshold`` recorded but not required (:func:`hetmesh.tet.uniform.uniform_model`
    searches ``h``)."""
    chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
    est = check_estimate(h, estimate_regular(solid, h), max_elements)
    meeting = bool(meeting_pairs(solid))
    p, t, faces, markers, phase, _ = solid_start(solid, field, meeting)

    def sized(p):  # h, capped at curved jump surfaces (the curved faces: cap_curved)
        size = np.full(len(p), float(h))
        return size if phase is None else jump_cap(field, p, size, chord)

    def constant(p, t, h_mmg, rounds, phase):
        check_count(h, len(t), max_elements)
        return interface_off(field, p, t, phase) <= SETTLED * chord, lambda: sized(p)

    p, t, faces, markers, rounds, phase = size_rounds(
        solid, p, t, faces, markers, cap_curved(solid, sized(p), faces, markers, chord),
        chord, max(0.25 * h, 10 * chord), meeting, constant, phase, field)
    comp = field.composition(p)
    if meeting:
        p, t, faces, markers, comp, delta = finish_meeting(solid, p, t, faces, markers, comp,
                                                           threshold, chord)
    else:
        p, t, faces, markers, phase, delta = finish_plain(solid, field, p, t, faces, markers,
                                                          phase, threshold, chord)
        comp = field.composition(p)
    info = {"placement": "uniform remeshed", "size": float(h), "estimate": est,
            "chord_tol": chord, "composition": comp, "size_rounds": rounds}
    if phase is not None:
        info["regions"] = phase.astype(np.int32)
    return with_interfaces(TetResult(p, t.astype(np.int32), faces.astype(np.int32),
                                     (markers + 1).astype(np.int32), tuple(solid.face_names),
                                     delta, float(threshold), info), field, len(solid.faces))
