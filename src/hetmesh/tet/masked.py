"""Solids from voxel masks: the non-zero voxels of a 3-D mask, and the phases of a label
volume inside them, meshed through level-set cuts of the voxel-centre grid and MMG
remeshing to the material's size.

A mask is a boolean volume ``inside (nz, ny, nx)`` on the voxel centres ``origin + (i, j, k)
* spacing``. Its staircase region ``V`` is the union of the non-zero voxels' boxes.

1. *Cut*: the grid of voxel centres (one layer of zero voxels added around the non-zero ones)
   is cut into Kuhn tetrahedra and MMG's level-set mode splits them along the zero set of
   the piecewise-linear interpolant of ``phi = 1/2 - inside``: ``phi`` is +-1/2 at every
   centre, so the surface crosses each edge between unlike centres at its midpoint (on the
   voxel face between them) and never passes through a grid vertex; no cut tetrahedron is
   degenerate. This surface is the marching-tetrahedra contour of the mask. Where the mask
   reaches the volume's border the surface is the border's face.
2. *Size*: MMG remeshes the inside to ``delta_0 / |grad f|`` (as for solids of primitives,
   :mod:`hetmesh.tet.general`), the boundary within a Hausdorff distance of
   :data:`HAUSD` voxels of the contour, then shrinks the size at violators for a few rounds.
   A round's remeshing is repeated while it removes more than
   :data:`~hetmesh.tet.general.SETTLE` of the tetrahedra, up to :data:`SETTLE_PASSES`
   remeshings (:func:`remesh_round`): one pass coarsens the far finer cut only part of
   the way. Round 0's remeshings are to the
   material's size; the later rounds' to the size MMG interpolated, shrunk at the
   violators (:func:`hetmesh.tet.general.next_size`). Each remeshing after the cut's first
   remeshes a surface MMG made, which may move it by up to the Hausdorff distance again:
   once one breaks the voxel claims (:func:`voxel_claims`), it is redone from its start
   with the boundary and the interfaces kept (MMG's ``nosurf``), as are all after it; the
   rounds then also stop when the violators no longer become fewer.
   One more MMG pass optimises the mesh without touching its surface (``optim``, sizes
   from the mesh itself; ``nosurf``: the boundary and the interfaces stay as they are);
   the violators left are bisected (:func:`hetmesh.tet.refine.repair`; with phases
   :func:`hetmesh.tet.sampling.repair_sampled`), and the tetrahedra whose smallest
   dihedral angle is below :data:`POLISH_ANGLE` are polished (:func:`polish`): their
   vertices move to better places, the points of the surface only within flat patches of
   it, so the surface and every claim of the verification that rests on it stay. The
   thin tetrahedra MMG leaves are at the surface: a triangle of the voxel contour (ridges
   and corners a voxel apart) and an inner vertex close to its plane. The tetrahedra are
   then reconnected within each phase (:func:`reconnect`: flips and collapses of inner
   vertices, :mod:`hetmesh.tet.flips`, and the polish again): where three phases meet,
   the interfaces leave wedges of a phase too narrow for two tetrahedra, which no vertex
   move mends; the radius-ratio flips also keep a plain mask's mean radius ratio at the
   target once the repeated remeshing has made its inside coarser (a plain mask is one
   phase: only the flips and the polish act).
3. *Faces*: the boundary triangles take the name of the zero region on their side: ``outer``
   (the zeros connected to the outside of the volume) or ``cavity[k]`` (an enclosed zero
   region, numbered in the order of its first voxel, k fastest x).
4. *Phases* (a label volume: ``labels`` and the ``phases`` inside the solid): after the
   mask's cut, the tetrahedra no earlier phase took are cut along ``1/2 - I_k``, ``I_k``
   phase ``k``'s interpolated indicator, one phase after another; the pieces no phase took
   (where three phases or more meet) take the phase of the largest indicator at their
   centroid, a phase with a voxel at a corner of their Kuhn tetrahedron. MMG's remeshing
   keeps the interfaces between tetrahedra of different phases like the boundary, the
   repair keeps every tetrahedron in its phase (``info["regions"]``), and delta is
   measured with every tetrahedron's vertices in its own phase.
5. *Verification* (:func:`mask_problems`), besides positive volumes, conformity, a closed
   boundary and delta_max < delta_0: **every voxel centre of the mask is inside the mesh
   and every other centre outside it** (and, with phases, inside tetrahedra of its own
   phase only), and **the boundary passes only between unlike centres**: at 12 points of
   every boundary triangle, the box of one voxel centred on the point overlaps a non-zero
   and a zero voxel (closed boxes: the eight voxels around the point, or more on a plane
   of centres); that is, every checked point of the boundary lies within half a voxel,
   along each axis, of the voxel faces between non-zero and zero voxels. Interfaces
   between phases are checked in the same way against the voxels of their two phases. If
   MMG's surface breaks a claim, the remeshing is repeated with the next, smaller,
   Hausdorff distance of :data:`HAUSD`; after the last, :class:`VerificationError`.

The mask's 6-connected components other than the largest are dropped (with a warning);
zero regions inside become cavities. The same input gives the same mesh.

>>> import numpy as np
>>> k, j, i = np.mgrid[0:8, 0:8, 0:8]
>>> s = VoxelSolid((i - 3.5) ** 2 + (j - 3.5) ** 2 + (k - 3.5) ** 2 < 9, (0.5, 0.5, 0.5),
...                (1.0, 1.0, 1.0))
>>> s.face_names, [b.tolist() for b in s.bounds]
(('outer',), [[1.0, 1.0, 1.0], [7.0, 7.0, 7.0]])
>>> s.contains([[4.0, 4.0, 4.0], [0.6, 0.6, 0.6]]).tolist()
[True, False]
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import BudgetError, GeometryError, MeshingError
from ..topology import unique
from .faces import BARY, boundary_faces, interface_faces
from .jumps import phase_delta
from .mesher import TetResult
from .refine import repair
from .verify import raise_problems, validity_problems

__all__ = ["VoxelSolid", "largest_component", "generate_masked", "mask_problems", "polish",
           "remesh_phases", "phase_delta", "boundary_estimate", "contour_faces", "voxel_claims",
           "HAUSD", "remesh_round"]

log = logging.getLogger(__name__)

#: MMG's Hausdorff distance for the boundary, in voxels (the smallest spacing): tried in
#: order until the boundary claims hold
HAUSD = (0.3, 0.2, 0.1)
#: the polish: the free vertices of the tetrahedra whose smallest dihedral angle is below
#: POLISH_ANGLE degrees are moved, in up to POLISH_ROUNDS rounds, to the trial position
#: (steps of POLISH_STEPS x their mean distance to their neighbours along 26 directions, or
#: the neighbours' mean) that most raises the smallest dihedral angle around them
POLISH_ANGLE = 20.0
POLISH_ROUNDS = 30
POLISH_STEPS = (0.04, 0.12, 0.3)
_DIRS = np.array([d for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)], float) - 1.0
_DIRS /= np.linalg.norm(_DIRS, axis=1, keepdims=True)
#: with phases, after the polish: flips (:func:`hetmesh.tet.flips.flip_improve`) of the
#: tetrahedra whose radius ratio is below FLIP_RADIUS, in up to FLIP_RADIUS_PASSES passes,
#: then FLIP_ROUNDS rounds of flips of those under POLISH_ANGLE degrees and the polish
FLIP_RADIUS = 0.6
FLIP_RADIUS_PASSES = 4
FLIP_ROUNDS = 2
#: size rounds before the bisection repair
SIZE_ROUNDS = 6
#: a size round's MMG remeshing is repeated while it removes more than
#: :data:`~hetmesh.tet.general.SETTLE` of the tetrahedra, up to this many remeshings in all
SETTLE_PASSES = 2
#: MMG's gradation
HGRAD = 1.3
#: the a-priori count's tetrahedra per voxel face of the contour (:func:`boundary_estimate`):
#: MMG's meshes at the Hausdorff distance HAUSD[0] have 7.3 on the two examples (docs/tet.md)
CONTOUR_TETS = 7.5
_SIX = np.array([[[0, 0, 0], [0, 1, 0], [0, 0, 0]], [[0, 1, 0], [1, 1, 1], [0, 1, 0]],
                 [[0, 0, 0], [0, 1, 0], [0, 0, 0]]], bool)


def largest_component(inside: np.ndarray, where: str = "mask") -> np.ndarray:
    """The largest 6-connected (face-connected) component of ``inside``; the others are
    dropped with a warning. :class:`GeometryError` if ``inside`` is empty."""
    from scipy import ndimage

    inside = np.asarray(inside, bool)
    if not inside.any():
        raise GeometryError(f"{where}: the mask has no non-zero voxels")
    lab, n = ndimage.label(inside, structure=_SIX)
    if n == 1:
        return inside
    sizes = np.bincount(lab.ravel())[1:]
    keep = int(np.argmax(sizes)) + 1
    log.warning("%s: %d separate regions of the mask dropped (%d voxels; the solid is its "
                "largest face-connected region, %d voxels)", where, n - 1,
                int(sizes.sum() - sizes[keep - 1]), int(sizes[keep - 1]))
    return lab == keep


@dataclass(frozen=True, eq=False)
class VoxelSolid:
    """The solid of the non-zero voxels ``inside (nz, ny, nx)`` (one face-connected region,
    :func:`largest_component`) on centres ``origin + (i, j, k) * spacing``; ``source`` names
    the mask in messages."""

    inside: np.ndarray
    origin: tuple
    spacing: tuple
    source: str = "mask"
    where: str = ""
    labels: np.ndarray | None = None
    phases: tuple = ()

    def __post_init__(self):
        a = np.asarray(self.inside, bool)
        if a.ndim != 3:
            raise GeometryError(f"{self.source}: a mask volume must be 3-D, got shape "
                                f"{a.shape}")
        if not a.any():
            raise GeometryError(f"{self.source}: the mask has no non-zero voxels")
        object.__setattr__(self, "inside", a)
        if self.labels is not None:
            lab = np.asarray(self.labels, np.int64)
            if lab.shape != a.shape:
                raise GeometryError(f"{self.source}: labels of shape {lab.shape}, mask of "
                                    f"shape {a.shape}")
            missing = set(unique(lab[a]).tolist()) - set(self.phases)
            if missing:
                raise GeometryError(f"{self.source}: labels {sorted(missing)} inside the "
                                    f"solid have no phase")
            object.__setattr__(self, "labels", lab)
            object.__setattr__(self, "phases", tuple(int(v) for v in self.phases))
        object.__setattr__(self, "origin", tuple(float(v) for v in self.origin))
        object.__setattr__(self, "spacing", tuple(float(v) for v in self.spacing))

    # -- the cropped, padded grid ---------------------------------------------------------
    @cached_property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """Index ranges ``(lo, hi)`` (``(k, j, i)``, inclusive) of the non-zero voxels."""
        idx = np.argwhere(self.inside)
        return idx.min(axis=0), idx.max(axis=0)

    @cached_property
    def padded(self) -> tuple[np.ndarray, np.ndarray]:
        """``(inside, origin)`` of the non-zero voxels' box with one zero layer around."""
        lo, hi = self.box
        sub = self.inside[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1]
        pad = np.pad(sub, 1)
        org = np.asarray(self.origin) + (lo[::-1] - 1) * np.asarray(self.spacing)
        return pad, org

    @property
    def n_phases(self) -> int:
        return max(len(self.phases), 1)

    @cached_property
    def phase_grid(self) -> np.ndarray:
        """Per voxel of :attr:`padded`: its phase (index into :attr:`phases`; 0 for every
        voxel of a plain mask), -1 outside the solid."""
        pad, _ = self.padded
        out = np.where(pad, 0, -1).astype(np.int64)
        if self.labels is not None:
            lo, hi = self.box
            sub = np.pad(self.labels[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1], 1)
            index = {lab: k for k, lab in enumerate(self.phases)}
            for lab, k in index.items():
                out[pad & (sub == lab)] = k
        return out

    def interpolate(self, grid: np.ndarray, points) -> np.ndarray:
        """The piecewise-linear interpolation of ``grid`` (values on the padded centres)
        over the Kuhn tetrahedra of the centre grid (Freudenthal's: in each cell, the one
        whose vertices are visited in the order of the decreasing fractional coordinates)
        at ``points``; 0 beyond the padded box."""
        _, org = self.padded
        g = np.asarray(grid, float)
        u = (np.asarray(points, float).reshape(-1, 3) - org) / np.asarray(self.spacing)
        top = np.array(g.shape[::-1]) - 2
        i0 = np.clip(np.floor(u).astype(np.int64), 0, top)
        f = np.clip(u - i0, 0.0, 1.0)
        out = ((u < 0) | (u > top + 1)).any(axis=1)
        order = np.argsort(-f, axis=1, kind="stable")
        fs = np.take_along_axis(f, order, axis=1)
        w = np.column_stack([1 - fs[:, 0], fs[:, 0] - fs[:, 1], fs[:, 1] - fs[:, 2], fs[:, 2]])
        c = i0.copy()
        val = w[:, 0] * g[c[:, 2], c[:, 1], c[:, 0]]
        rows = np.arange(len(u))
        for k in range(3):
            c[rows, order[:, k]] += 1
            val = val + w[:, k + 1] * g[c[:, 2], c[:, 1], c[:, 0]]
        return np.where(out, 0.0, val)

    def phase(self, points) -> np.ndarray:
        """The phase of each point as the cuts decide it (``points`` inside the solid): the
        first phase (in :attr:`phases` order) whose interpolated indicator (:meth:`
        interpolate`) exceeds 1/2, else the phase of the largest one."""
        p = np.asarray(points, float).reshape(-1, 3)
        grid = self.phase_grid
        ind = np.stack([self.interpolate(grid == k, p) for k in range(self.n_phases)], 1)
        over = ind > 0.5
        return np.where(over.any(axis=1), np.argmax(over, axis=1), np.argmax(ind, axis=1))

    @cached_property
    def regions(self) -> np.ndarray:
        """Per voxel of :attr:`padded`: -1 inside, else the index of its zero region (0 the
        outside, k + 1 cavity k)."""
        from scipy import ndimage

        pad, _ = self.padded
        lab, n = ndimage.label(~pad, structure=_SIX)
        out = np.full(pad.shape, -1, np.int64)
        border = lab[0, 0, 0]  # the added layer is zero and connected: the outside
        order = [border] + [r for r in range(1, n + 1) if r != border]
        for k, r in enumerate(order):
            out[lab == r] = k
        return out

    @cached_property
    def face_names(self) -> tuple[str, ...]:
        n = int(self.regions.max()) + 1
        return ("outer",) + tuple(f"cavity[{k}]" for k in range(n - 1))

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self.box
        o, s = np.asarray(self.origin), np.asarray(self.spacing)
        return o + (lo[::-1] - 0.5) * s, o + (hi[::-1] + 0.5) * s

    @property
    def diameter(self) -> float:
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    @property
    def volume(self) -> float:
        """The volume of the non-zero voxels (the staircase; the mesh's contour differs by
        less than half a voxel at the boundary)."""
        return float(self.inside.sum() * np.prod(self.spacing))

    @property
    def voxel(self) -> float:
        """The smallest spacing."""
        return float(min(self.spacing))

    def indicator(self, points) -> np.ndarray:
        """The trilinear interpolation of the mask (1 inside, 0 outside) at ``points``."""
        from scipy.ndimage import map_coordinates

        pad, org = self.padded
        u = (np.asarray(points, float).reshape(-1, 3) - org) / np.asarray(self.spacing)
        return map_coordinates(pad.astype(np.float64), u[:, ::-1].T, order=1, mode="constant",
                               cval=0.0)

    def contains(self, points, tol: float | None = None) -> np.ndarray:
        """Whether ``points`` lie inside the contour (trilinear indicator >= 1/2)."""
        return self.indicator(points) >= 0.5

    def sample(self, n: int = 24) -> np.ndarray:
        from .solid import grid_inside
        return grid_inside(self, n)

    def _around(self, grid: np.ndarray, points, fill: int) -> tuple[np.ndarray, np.ndarray]:
        """``(values (N, 27), valid (N, 27))``: ``grid`` at the voxel centres whose voxels
        the box of one voxel centred on each point overlaps (closed boxes: 2 per axis, 3
        where the point lies on a plane of centres), ``fill`` beyond the padded box."""
        _, org = self.padded
        u = (np.asarray(points, float).reshape(-1, 3) - org) / np.asarray(self.spacing)
        lo = np.floor(u - 1e-9).astype(np.int64)
        hi = np.floor(u + 1e-9).astype(np.int64) + 1
        shape = np.array(grid.shape[::-1])
        vals = np.full((len(u), 27), fill, np.int64)
        valid = np.zeros((len(u), 27), bool)
        for n, d in enumerate(np.ndindex(3, 3, 3)):
            ii = lo + np.array(d)
            use = (ii <= hi).all(axis=1)
            ok = use & ((ii >= 0) & (ii < shape)).all(axis=1)
            valid[:, n] = use
            vals[ok, n] = grid[ii[ok, 2], ii[ok, 1], ii[ok, 0]]
        return vals, valid

    def stencil(self, points) -> tuple[np.ndarray, np.ndarray]:
        """For every point, whether the voxels the box of one voxel centred on it overlaps
        include a non-zero and a zero voxel, and the smallest zero-region index among them
        (-1: none)."""
        r, valid = self._around(self.regions, points, 0)  # beyond the box: the outside
        inside = ((r < 0) & valid).any(axis=1)
        out = (r >= 0) & valid
        best = np.where(out, r, np.iinfo(np.int64).max).min(axis=1)
        has_out = out.any(axis=1)
        return inside & has_out, np.where(has_out, best, -1)

    def between(self, points, a, b) -> np.ndarray:
        """Whether the voxels the box of one voxel centred on each point overlaps include
        phase ``a`` and phase ``b`` (per point; -1 the outside)."""
        r, valid = self._around(self.phase_grid, points, -1)
        a = np.broadcast_to(np.asarray(a, np.int64), (len(r),))[:, None]
        b = np.broadcast_to(np.asarray(b, np.int64), (len(r),))[:, None]
        return ((r == a) & valid).any(axis=1) & ((r == b) & valid).any(axis=1)

    def mesh_problems(self, res, field, chord_tol: float | None = None) -> list[str]:
        """:func:`mask_problems` of a mesh of this solid."""
        return mask_problems(res, self, field, chord_tol)

    def classify_faces(self, tri_points) -> np.ndarray:
        """The face index of each boundary triangle ``(K, 3, 3)``: the zero region next to
        its centroid (-1 where none)."""
        tri = np.asarray(tri_points, float).reshape(-1, 3, 3)
        return self.stencil(tri.mean(axis=1))[1]


# -- 1. the cuts --------------------------------------------------------------------------

def _compact(p, t):
    """The points ``p`` that ``t`` uses (or a tuple of per-point arrays, each kept alike)
    and ``t`` renumbered to them."""
    arrays = p if isinstance(p, tuple) else (p,)
    used = unique(t)
    remap = np.full(len(arrays[0]), -1, np.int64)
    remap[used] = np.arange(len(used))
    kept = tuple(a[used] for a in arrays)
    return (kept if isinstance(p, tuple) else kept[0]), remap[t]


def cut_mask(solid: VoxelSolid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Kuhn tetrahedra of the padded voxel-centre grid cut along the mask's contour and
    then, for a label volume, along the contour of every phase but the last in turn (each
    cut only through the tetrahedra no earlier phase took): ``(points, tets, phase)`` of
    the tetrahedra inside, ``phase`` the index into :attr:`VoxelSolid.phases`."""
    from .general import kuhn_grid, levelset_cut, orient_positive

    pad, org = solid.padded
    sp = np.asarray(solid.spacing)
    nz, ny, nx = pad.shape
    xs, ys, zs = (org[a] + sp[a] * np.arange(n) for a, n in enumerate((nx, ny, nz)))
    p, t = kuhn_grid(xs, ys, zs)
    phi = 0.5 - pad.transpose(2, 1, 0).astype(np.float64).ravel()  # kuhn_grid's (i, j, k)
    p, t = _compact(p, t[~(phi[t] > 0).all(axis=1)])  # wholly outside: not needed
    phi = 0.5 - solid.interpolate(pad, p)
    # refs: 1 outside, 2 the mask before the cuts, 10 + k phase k, 100 + k undecided before
    # the cut of phase k (all distinct, as MMG asks)
    OUT = 1
    p, t, refs = levelset_cut(p, t, np.full(len(t), 2), phi, {2: (100, OUT)}, "the mask")
    n = solid.n_phases
    grid = solid.phase_grid
    for k in range(n if n > 1 else 0):
        if not (refs == 100 + k).any():
            break
        p, t, refs = levelset_cut(p, t, refs, 0.5 - solid.interpolate(grid == k, p),
                          {100 + k: (10 + k, 101 + k)}, f"phase {solid.phases[k]}")
    # what no phase's indicator took (where three phases or more meet): the phase with the
    # largest indicator at the centroid, one whose voxel is a corner of its Kuhn tetrahedron
    rest = np.flatnonzero(refs >= 100)
    if n == 1:
        refs[rest] = 10
    elif len(rest):
        refs[rest] = 10 + solid.phase(p[t[rest]].mean(axis=1))
    keep = refs != OUT
    p, t = _compact(p, t[keep])
    return p, orient_positive(p, t), refs[keep] - 10


# -- 2. size -------------------------------------------------------------------------------

def remesh_phases(p, t, phase, size, hausd, **options):
    """MMG's remeshing to ``size`` with the boundary and the phases' interfaces kept within
    ``hausd``: ``(points, tets, phase, size MMG interpolated)``. ``size`` None and
    ``options`` (MMG's ``optim``, ``nosurf``): the optimisation pass, sizes taken from the
    mesh itself (no size returned)."""
    from .general import orient_positive, quiet_mmg

    mmgpy = quiet_mmg()
    faces, _ = boundary_faces(t)
    inter, _ = interface_faces(t, phase)
    tri = np.concatenate([faces, inter]).astype(np.int32)
    refs = np.r_[np.ones(len(faces)), np.full(len(inter), 2)].astype(np.int32)
    m = mmgpy.MmgMesh3D()
    m.set_mesh_size(vertices=len(p), tetrahedra=len(t), triangles=len(tri))
    m.set_vertices(np.ascontiguousarray(p))
    m.set_tetrahedra(np.ascontiguousarray(t, dtype=np.int32),
                     np.ascontiguousarray(phase + 1, dtype=np.int32))
    m.set_triangles(np.ascontiguousarray(tri), np.ascontiguousarray(refs))
    if size is not None:
        m.set_field("metric", np.ascontiguousarray(size, dtype=np.float64).reshape(-1, 1))
    out = m.remesh(verbose=-1, hausd=float(hausd), hgrad=HGRAD, **options)
    if out.get("return_code", 0) != 0:
        raise MeshingError(f"MMG remeshing failed (code {out.get('return_code')})")
    p = np.array(m.get_vertices(), dtype=np.float64)
    tt, rr = m.get_tetrahedra_with_refs()
    t = orient_positive(p, np.asarray(tt, dtype=np.int64))
    h = None
    if size is not None:
        h = np.asarray(m.get_field("metric"), dtype=np.float64).reshape(-1)
    return p, t, np.asarray(rr, dtype=np.int64) - 1, h


def remesh_round(solid: VoxelSolid, p, t, phase, size, hausd: float, kept: bool,
                 checked: bool, size_of=None):
    """One size round's MMG remeshing (:func:`remesh_phases`) to ``size`` (per point),
    repeated to the size at the new vertices (``size_of(points)``; None: the size MMG
    interpolated at them) while a remeshing removes more than
    :data:`~hetmesh.tet.general.SETTLE` of the tetrahedra, up to :data:`SETTLE_PASSES`
    remeshings (:func:`~hetmesh.tet.general.remesh_until_settled`): one MMG pass
    coarsens a finer mesh only part of the way (phase_volume at 0.3: the cut's 307,178
    tetrahedra became 77,328 in one pass, 61,059 in a second to the same size, then 58,157
    and 56,253; more passes made the test mask's mean radius ratio miss 0.75, so
    :data:`SETTLE_PASSES` is 2). A remeshing of a surface MMG has made may move it by
    ``hausd`` again: with ``checked`` (every remeshing but the cut's first) one that breaks
    the voxel claims (:func:`voxel_claims`) is redone from its start with the boundary and
    the interfaces kept (MMG's ``nosurf``), as are all after it (``kept``). ``(points,
    tets, phase, size MMG interpolated, kept, remeshings)``."""
    from .general import remesh_until_settled

    def once(state, k):
        p, t, phase, h_mmg, kept, checked = state
        sz = size if k == 1 else (h_mmg if size_of is None else size_of(p))
        new = remesh_phases(p, t, phase, sz, hausd, **({"nosurf": 1} if kept else {}))
        if checked and not kept and voxel_claims(solid, *new[:3]):
            log.info("mask: a remeshing moved the surface out of the voxel claims; again "
                     "with the surface kept")
            kept = True
            new = remesh_phases(p, t, phase, sz, hausd, nosurf=1)
        return (*new, kept, True)

    (p, t, phase, h_mmg, kept, _), passes = remesh_until_settled(
        once, (p, t, phase, None, kept, checked), most=SETTLE_PASSES)
    return p, t, phase, h_mmg, kept, passes


def _mesh(solid, field, threshold, p, t, phase, hausd, h_max, h_min, max_elements):
    from .general import next_size, size_field
    from .sampling import repair_sampled, sampled_delta

    def material(points):
        return size_field(field, points, threshold, h_max, h_min)

    size = material(p)

    stages = {}  # the tetrahedra after each step
    rounds = remeshings = 0
    n_bad = None
    kept = False  # the surface kept as it is from this round on (MMG's nosurf)
    for rounds in range(SIZE_ROUNDS + 1):
        p, t, phase, h_mmg, kept_now, n = remesh_round(
            solid, p, t, phase, size, hausd, kept, checked=rounds > 0,
            size_of=material if rounds == 0 else None)
        remeshings += n
        if kept_now and not kept:
            log.info("mask: size round %d moved the surface out of the voxel claims; "
                     "the surface kept from then on", rounds)
        kept = kept_now
        if max_elements is not None and len(t) > max_elements:
            raise BudgetError(f"the mesh has {len(t)} tetrahedra, over the budget of "
                              f"{max_elements}")
        comp = field.composition(p)
        bad = phase_delta(field, p, t, phase, comp) >= threshold
        log.info("mask: size round %d: %d tetrahedra, %d over delta_0", rounds, len(t),
                 int(bad.sum()))
        stages[f"size round {rounds}"] = len(t)
        # with the surface kept, no fewer violators than the round before: the rounds
        # have stalled (a violator whose varying edge lies on the surface stays); the
        # repair bisects the rest
        stalled = kept and n_bad is not None and bad.sum() >= n_bad
        if not bad.any() or rounds == SIZE_ROUNDS or stalled:
            break
        n_bad = int(bad.sum())
        size = next_size(h_mmg, field, p, t, bad, threshold, h_max, h_min)
    # the optimisation pass: swaps, moves and MMG's own size, the boundary and the
    # interfaces kept as they are (nosurf)
    p, t, phase, _ = remesh_phases(p, t, phase, None, hausd, optim=1, nosurf=1)
    comp = field.composition(p)
    log.info("mask: optimisation pass: %d tetrahedra", len(t))
    stages["optimisation"] = len(t)
    if solid.n_phases == 1:
        p, t, comp, delta, passes = repair(p, t, field, threshold, comp=comp,
                                           max_elements=max_elements)
        phase = np.zeros(len(t), np.int64)
    else:
        rep = repair_sampled(p, t, comp, field, threshold, sampled_delta(field, "vertices"),
                             max_elements=max_elements, regions=phase)
        p, t, phase, comp, passes = rep.points, rep.tets, rep.regions, rep.comp, rep.passes
    stages["repair"] = len(t)
    p, comp = polish(p, t, phase, comp, field, threshold)
    p, t, phase, comp = reconnect(p, t, phase, comp, field, threshold)
    stages["reconnection"] = len(t)
    delta = phase_delta(field, p, t, phase, comp)
    return p, t, phase, comp, delta, rounds, remeshings, passes, stages


def voxel_claims(solid: VoxelSolid, p, t, phase) -> list[str]:
    """The broken claims of :func:`mask_problems` of the tetrahedra ``t`` (phases
    ``phase``) other than delta: validity, every voxel centre on its side and in its
    phase, the boundary and the interfaces between unlike centres."""
    t = np.asarray(t, np.int32)
    faces, _ = boundary_faces(t)
    markers = solid.classify_faces(p[faces])
    info = {"regions": np.asarray(phase, np.int32)} if solid.n_phases > 1 else {}
    res = TetResult(p, t, faces.astype(np.int32), (markers + 1).astype(np.int32),
                    tuple(solid.face_names), np.zeros(len(t)), math.inf, info)
    return mask_problems(res, solid, None)


def reconnect(p, t, phase, comp, field, threshold):
    """Flips within the phases (:func:`hetmesh.tet.flips.flip_improve`: face flips, edge
    removals, collapses of inner vertices; every new tetrahedron with delta below
    ``threshold`` in its phase) of the tetrahedra whose radius ratio is below
    :data:`FLIP_RADIUS`, then :data:`FLIP_ROUNDS` rounds of flips of those whose smallest
    dihedral angle is below :data:`POLISH_ANGLE` and the polish (:func:`polish`). The
    boundary and the interfaces keep their triangles (the polish moves their points only
    within flat patches). The thin tetrahedra the polish leaves have three vertices on the
    interfaces, which it does not move: at a line where three phases meet, a phase's wedge
    of 15-20 degrees between two interface triangles, split into two tetrahedra by an
    inner vertex, becomes one by a collapse of that vertex. The radius-ratio flips raise
    the mean radius ratio, which is lowest in the tetrahedra with vertices on the
    voxel-scale interfaces. ``(points, tets, phase, comp)``, the unused points dropped."""
    from ..metrics import tet_quality
    from .flips import flip_improve

    def below(p, comp):
        """The flips' check at the points ``p`` with compositions ``comp``."""
        return lambda tets, ph: phase_delta(field, p, tets, ph, comp) < threshold

    t, phase = flip_improve(p, t, phase, below(p, comp), bound=FLIP_RADIUS,
                            measure=tet_quality, passes=FLIP_RADIUS_PASSES)
    for _ in range(FLIP_ROUNDS):
        t, phase = flip_improve(p, t, phase, below(p, comp), bound=POLISH_ANGLE)
        p, comp = polish(p, t, phase, comp, field, threshold)
    (p, comp), t = _compact((p, comp), t)
    return p, t, phase, comp


def independent_vertices(tets: np.ndarray, cand: np.ndarray, rank: np.ndarray
                         ) -> np.ndarray:
    """The vertices ``cand`` that rank first (``rank`` per candidate: smaller first, then
    the smaller id) among the candidates of every tetrahedron around them: no two of them
    share a tetrahedron."""
    prio = np.zeros(int(tets.max()) + 1, np.int64)
    order = np.lexsort((cand, rank))
    prio[cand[order]] = len(cand) - np.arange(len(cand))
    tp = prio[tets]
    tmax = tp.max(axis=1)
    m, k = np.nonzero(tp > 0)
    lose = np.zeros(len(prio), bool)
    lost = tp[m, k] < tmax[m]
    lose[tets[m[lost], k[lost]]] = True
    return cand[~lose[cand]]


def surface_normals(p, t, phase) -> np.ndarray:
    """Per point, the unit normal of the plane of the boundary or interface triangles
    around it if they all lie in one plane and separate the same two sides (the point
    moves in that plane without changing the surface); zero for the points of no such
    triangle (free to move anywhere); NaN for the others (which stay)."""
    faces, _ = boundary_faces(t)
    inter, sides = interface_faces(t, phase)
    # interface triangles turned to face from the lower phase to the higher
    inter = np.where((sides[:, 0] > sides[:, 1])[:, None], inter[:, ::-1], inter)
    tri = np.concatenate([faces, inter]).astype(np.int64)
    kind = np.r_[np.full(len(faces), -1), sides.min(axis=1) * (sides.max(initial=0) + 1)
                 + sides.max(axis=1)].astype(np.int64)
    n = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    v, f = tri.ravel(), np.repeat(np.arange(len(tri)), 3)
    first = np.full(len(p), -1, np.int64)
    first[v[::-1]] = f[::-1]  # the first triangle of every surface point
    on = first >= 0
    ref = np.zeros((len(p), 3))
    ref[on] = n[first[on]]
    flat = np.ones(len(p), bool)
    flat[v[(n[f] * ref[v]).sum(axis=1) < 1 - 1e-10]] = False
    flat[v[kind[f] != kind[first[v]]]] = False
    out = np.where((on & ~flat)[:, None], np.nan, ref)
    return out


def polish(p, t, phase, comp, field, threshold, *, angle: float = POLISH_ANGLE,
           rounds: int = POLISH_ROUNDS, measure=None):
    """Move vertices of the tetrahedra whose smallest dihedral angle is below ``angle``
    (with ``measure(points, tets)``, another quality, larger better: whose quality is below
    ``angle``; the moves then raise the smallest quality around the vertices):
    in each round, a set of such vertices no two of which share a tetrahedron
    (:func:`independent_vertices`, the worst first) each go to the trial position
    (:data:`POLISH_STEPS` along :data:`_DIRS`, the mean of their neighbours, or where
    they are) with the largest smallest dihedral angle over the tetrahedra around them,
    every one of which keeps a positive volume and delta below ``threshold`` (each in its
    own phase). Points of the boundary and of the interfaces move only in the plane of
    their triangles where these are flat (:func:`surface_normals`), else not at all: the
    surface is the same, and every voxel centre stays in the same phase. A vertex with no
    better place is left alone from then on. ``(points, comp)``."""
    from ..mesh import simplex_measures
    from .quality import min_dihedral

    measure = min_dihedral if measure is None else measure
    p, comp = p.copy(), comp.copy()
    t = np.asarray(t, np.int64)
    normal = surface_normals(p, t, phase)
    stuck = np.isnan(normal).any(axis=1)
    normal = np.nan_to_num(normal)
    for _ in range(rounds):
        dm = measure(p, t)
        bad = dm < angle
        worst = np.full(len(p), np.inf)
        np.minimum.at(worst, t[bad].ravel(), np.repeat(dm[bad], 4))
        cand = np.flatnonzero(np.isfinite(worst) & ~stuck)
        if not len(cand):
            break
        sel = independent_vertices(t, cand, worst[cand])
        is_sel = np.full(len(p), -1, np.int64)
        is_sel[sel] = np.arange(len(sel))
        st = is_sel[t]
        rows = np.flatnonzero((st >= 0).any(axis=1))
        col = np.argmax(st[rows] >= 0, axis=1)
        owner = st[rows, col]  # index into sel
        # trial moves (S, K, 3): none, to the neighbours' mean, steps along _DIRS; those of
        # a surface point projected into its plane
        x = p[sel]
        nsum = np.zeros((len(sel), 3))
        ncnt = np.zeros(len(sel))
        np.add.at(nsum, owner, p[t[rows]].sum(axis=1) - x[owner])
        np.add.at(ncnt, owner, 3.0)
        dist = np.zeros(len(sel))
        np.add.at(dist, owner, np.linalg.norm(p[t[rows]] - x[owner][:, None], axis=2).sum(1))
        steps = (np.asarray(POLISH_STEPS)[:, None, None] * _DIRS[None]).reshape(1, -1, 3)
        move = np.concatenate([np.zeros((len(sel), 1, 3)), (nsum / ncnt[:, None] - x)[:, None],
                               (dist / ncnt)[:, None, None] * steps], axis=1)
        nv = normal[sel][:, None]
        move -= (move * nv).sum(axis=2, keepdims=True) * nv
        trial = x[:, None] + move
        k_n = trial.shape[1]
        n0 = len(p)
        pv = np.concatenate([p, trial.reshape(-1, 3)])
        cv = np.concatenate([comp, field.composition(trial.reshape(-1, 3))])
        tv = np.repeat(t[rows], k_n, axis=0)
        kk = np.tile(np.arange(k_n), len(rows))
        tv[np.arange(len(tv)), np.repeat(col, k_n)] = n0 + np.repeat(owner, k_n) * k_n + kk
        score = measure(pv, tv)
        ok = simplex_measures(pv, tv) > 0
        ok &= phase_delta(field, pv, tv, np.repeat(phase[rows], k_n), cv) < threshold
        score = np.where(ok, score, -np.inf).reshape(len(rows), k_n)
        star = np.full((len(sel), k_n), np.inf)
        np.minimum.at(star, owner, score)
        best = np.argmax(star, axis=1)
        better = star[np.arange(len(sel)), best] > star[:, 0]
        stuck[sel[~better]] = True
        v, b = sel[better], best[better]
        p[v] = trial[better, b]
        comp[v] = cv[n0 + np.flatnonzero(better) * k_n + b]
    return p, comp


def estimate_masked(solid: VoxelSolid, field, threshold: float) -> float:
    """A-priori element count, as for solids of primitives
    (:func:`hetmesh.tet.general.estimate_solid`), plus the contour's
    (:func:`boundary_estimate`)."""
    from .general import estimate_solid

    return estimate_solid(solid, field, threshold) + boundary_estimate(solid)


def contour_faces(solid: VoxelSolid) -> int:
    """The voxel faces of the mask's contour: those between a non-zero and a zero voxel,
    plus twice those between voxels of two phases (an interface has tetrahedra on both
    sides)."""
    g = solid.phase_grid
    n = 0
    for axis in range(3):
        a = np.moveaxis(g, axis, 0)
        x, y = a[1:], a[:-1]
        n += int(((x < 0) != (y < 0)).sum())
        n += 2 * int(((x >= 0) & (y >= 0) & (x != y)).sum())
    return n


def boundary_estimate(solid: VoxelSolid) -> float:
    """The tetrahedra the mask's contour adds: :data:`CONTOUR_TETS` per voxel face of it
    (:func:`contour_faces`)."""
    return CONTOUR_TETS * contour_faces(solid)


def generate_masked(solid: VoxelSolid, field, threshold: float, *, seed: int = 0,
                    chord_tol: float | None = None, max_elements: int | None = None,
                    max_size: float | None = None, check: bool = True) -> TetResult:
    """Tetrahedralise a :class:`VoxelSolid` with every element's delta below ``threshold``
    (see the module docstring); with phases, every tetrahedron in one phase
    (``info["regions"]``). ``info["stages"]``: the tetrahedra after each step (``size round
    k``, ``optimisation``, ``repair``, ``reconnection``) of the Hausdorff distance that
    held; ``info["remeshings"]``: MMG's remeshings in the size rounds. ``seed`` and
    ``chord_tol`` are accepted for the common interface: the boundary follows the voxels
    (:data:`HAUSD`) and MMG is deterministic."""
    t0 = time.perf_counter()
    est = estimate_masked(solid, field, threshold)
    if max_elements is not None and est > max_elements:
        raise BudgetError(f"about {est:.0f} tetrahedra are needed for delta_0 = {threshold} "
                          f"but the budget is {max_elements}")
    lo, hi = solid.bounds
    h_max = float((hi - lo).max()) / 4
    if max_size is not None:
        h_max = min(h_max, float(max_size))
    h_min = 1e-4 * solid.diameter
    p0, t0_, ph0 = cut_mask(solid)
    log.info("mask: cut %d tetrahedra of the voxel grid", len(t0_))
    probs: list[str] = []
    for hv in HAUSD:
        hausd = hv * solid.voxel
        p, t, phase, comp, delta, rounds, remeshings, passes, stages = _mesh(
            solid, field, threshold, p0, t0_, ph0, hausd, h_max, h_min, max_elements)
        t = t.astype(np.int32)
        faces, _ = boundary_faces(t)
        markers = solid.classify_faces(p[faces])
        info = {"placement": "mask", "size_rounds": rounds, "remeshings": remeshings,
                "repair_passes": passes,
                "estimate": est, "composition": comp, "hausd": hausd, "h_max": h_max,
                "stages": stages,
                "time_place": time.perf_counter() - t0}
        if solid.n_phases > 1:
            info["regions"] = phase.astype(np.int32)
        res = TetResult(p, t, faces.astype(np.int32), (markers + 1).astype(np.int32),
                        tuple(solid.face_names), delta, float(threshold), info)
        if not check:
            break
        probs = mask_problems(res, solid, field)
        if not probs:
            break
        log.info("mask: Hausdorff distance %.3g voxels: %s; again with less", hv, probs[0])
    if check:
        raise_problems(probs)
    res.info["time_total"] = time.perf_counter() - t0
    log.info("mask mesh: %d points, %d tetrahedra, %.2f s", len(res.points), len(res.tets),
             res.info["time_total"])
    return res


# -- 3. verification -----------------------------------------------------------------------

def mask_problems(res, solid: VoxelSolid, field, chord_tol: float | None = None) -> list[str]:
    """Every broken claim of a mesh of ``solid``, one line each (empty: valid): validity,
    the recorded boundary, every voxel centre inside exactly the tetrahedra of its own phase
    (none for the mask's zero voxels), the boundary and the phases' interfaces between
    unlike centres, delta_max < delta_0 (recomputed from ``field`` at the vertices, each
    tetrahedron in its own phase; None: the result's own delta)."""
    from ..material.image.sampling import voxel_centres_in_tets

    p, t = res.points, res.tets
    if len(t) == 0:
        return ["no tetrahedra"]
    out = validity_problems(p, t)
    bf, _ = boundary_faces(t)
    if len(bf) != len(res.faces):
        out.append(f"{len(res.faces)} boundary triangles recorded, {len(bf)} in the "
                   f"tetrahedra")
    markers = res.face_markers.astype(np.int64) - 1
    if (markers < 0).any():
        c = p[res.faces[markers < 0][0]].mean(axis=0)
        out.append(f"{int((markers < 0).sum())} boundary triangles on no face of the solid "
                   f"(e.g. at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    regions = res.info.get("regions")
    phase = np.zeros(len(t), np.int64) if regions is None else np.asarray(regions, np.int64)
    pad, org = solid.padded
    grid = solid.phase_grid
    with np.errstate(invalid="ignore"):
        e, v = voxel_centres_in_tets(p, t, org, solid.spacing, pad.shape)
    covered = np.zeros(pad.size, bool)
    covered[v] = True
    covered = covered.reshape(pad.shape)
    wrong = covered != pad
    if wrong.any():
        k, j, i = np.argwhere(wrong)[0]
        c = org + np.array([i, j, k]) * np.asarray(solid.spacing)
        what = "outside" if pad[k, j, i] else "inside"
        out.append(f"{int(wrong.sum())} voxel centres on the wrong side of the boundary "
                   f"(e.g. the centre ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}) is {what} the "
                   f"mesh)")
    other = grid.ravel()[v] != phase[e]
    if other.any():
        q = v[other][0]
        k, j, i = np.unravel_index(q, pad.shape)
        c = org + np.array([i, j, k]) * np.asarray(solid.spacing)
        out.append(f"{int(other.sum())} voxel centres in a tetrahedron of another phase "
                   f"(e.g. the centre ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    pts = np.einsum("bk,nkd->nbd", BARY, p[res.faces]).reshape(-1, 3)
    mixed, _ = solid.stencil(pts)
    if not mixed.all():
        c = pts[np.flatnonzero(~mixed)[0]]
        out.append(f"the boundary leaves the voxels' contour by more than half a voxel at "
                   f"{int((~mixed).sum())} of {len(pts)} checked points (e.g. at "
                   f"({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    if regions is not None:
        inter, sides = interface_faces(np.asarray(t, np.int64), phase)
        if len(inter):
            pts = np.einsum("bk,nkd->nbd", BARY, p[inter]).reshape(-1, 3)
            s = np.repeat(sides, len(BARY), axis=0)
            ok = solid.between(pts, s[:, 0], s[:, 1])
            if not ok.all():
                c = pts[np.flatnonzero(~ok)[0]]
                out.append(f"an interface between phases leaves their voxels' contour by "
                           f"more than half a voxel at {int((~ok).sum())} of {len(pts)} "
                           f"checked points (e.g. at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    if field is None:
        delta = res.delta
    else:
        delta = phase_delta(field, p, np.asarray(t, np.int64), phase, field.composition(p))
    if not float(delta.max()) < res.threshold:
        out.append(f"delta_max = {float(delta.max()):.6g} is not below delta_0 = "
                   f"{res.threshold:g}")
    return out
