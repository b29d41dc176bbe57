"""Solids from voxel masks: the non-zero voxels of a 3-D mask, meshed through a level-set cut
of the voxel-centre grid and MMG remeshing to the material's size.

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
   :data:`HAUSD` voxels of the contour, then shrinks the size at violators for a few rounds
   and bisects the rest (:func:`hetmesh.tet.refine.repair`).
3. *Faces*: the boundary triangles take the name of the zero region on their side: ``outer``
   (the zeros connected to the outside of the volume) or ``cavity[k]`` (an enclosed zero
   region, numbered in the order of its first voxel, k fastest x).
4. *Verification* (:func:`mask_problems`), besides positive volumes, conformity, a closed
   boundary and delta_max < delta_0: **every voxel centre of the mask is inside the mesh
   and every other centre outside it**, and **the boundary passes only between unlike
   centres**: at 12 points of every boundary triangle the eight voxel centres around the
   point (those its trilinear interpolation uses) include a non-zero and a zero voxel. The
   second claim is the same as: every point of the boundary lies within half a voxel,
   along each axis, of the voxel faces between non-zero and zero voxels (the box of one
   voxel centred on it overlaps voxels of both). If MMG's surface breaks a claim, the
   remeshing is repeated with half the Hausdorff distance (at most :data:`HAUSD` has
   entries).

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
import time
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import BudgetError, GeometryError, MeshingError, VerificationError
from ..metrics import delta_vertices
from .faces import boundary_faces
from .mesher import TetResult
from .refine import repair
from .verify import validity_problems

__all__ = ["VoxelSolid", "largest_component", "generate_masked", "mask_problems", "HAUSD"]

log = logging.getLogger(__name__)

#: MMG's Hausdorff distance for the boundary, in voxels (the smallest spacing): tried in
#: order until the boundary claims hold
HAUSD = (0.3, 0.2, 0.1)
#: size rounds before the bisection repair
SIZE_ROUNDS = 6
#: the size at the vertices of violating tetrahedra is multiplied by this each round
SHRINK = 0.85
#: MMG's gradation
HGRAD = 1.3
#: barycentric points at which the boundary triangles are checked
_BARY = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, .5, 0], [0, .5, .5], [.5, 0, .5],
                  [1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6],
                  [1 / 6, 1 / 6, 2 / 3], [.25, .25, .5], [.5, .25, .25]])
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

    def __post_init__(self):
        a = np.asarray(self.inside, bool)
        if a.ndim != 3:
            raise GeometryError(f"{self.source}: a mask volume must be 3-D, got shape "
                                f"{a.shape}")
        if not a.any():
            raise GeometryError(f"{self.source}: the mask has no non-zero voxels")
        object.__setattr__(self, "inside", a)
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

    def stencil(self, points) -> tuple[np.ndarray, np.ndarray]:
        """For every point, whether the 8 voxel centres around it include a non-zero and a
        zero voxel, and the smallest zero-region index among them (-1: none)."""
        pad, org = self.padded
        u = (np.asarray(points, float).reshape(-1, 3) - org) / np.asarray(self.spacing)
        i0 = np.floor(u).astype(np.int64)
        reg = self.regions
        shape = np.array(pad.shape[::-1])
        has_in = np.zeros(len(u), bool)
        has_out = np.zeros(len(u), bool)
        best = np.full(len(u), np.iinfo(np.int64).max)
        for d in np.ndindex(2, 2, 2):
            ii = i0 + np.array(d)
            ok = ((ii >= 0) & (ii < shape)).all(axis=1)
            r = np.zeros(len(u), np.int64)  # outside the padded box: the outside region
            r[ok] = reg[ii[ok, 2], ii[ok, 1], ii[ok, 0]]
            has_in |= r < 0
            has_out |= r >= 0
            best = np.where(r >= 0, np.minimum(best, r), best)
        return has_in & has_out, np.where(has_out, best, -1)

    def classify_faces(self, tri_points) -> np.ndarray:
        """The face index of each boundary triangle ``(K, 3, 3)``: the zero region next to
        its centroid (-1 where none)."""
        tri = np.asarray(tri_points, float).reshape(-1, 3, 3)
        return self.stencil(tri.mean(axis=1))[1]


# -- 1. the cut ---------------------------------------------------------------------------

def cut_mask(solid: VoxelSolid) -> tuple[np.ndarray, np.ndarray]:
    """The Kuhn tetrahedra of the padded voxel-centre grid cut along the mask's contour,
    those inside: ``(points, tets)``."""
    from .general import _orient, _quiet_mmg, kuhn_grid

    mmgpy = _quiet_mmg()
    pad, org = solid.padded
    s = np.asarray(solid.spacing)
    nz, ny, nx = pad.shape
    xs, ys, zs = (org[a] + s[a] * np.arange(n) for a, n in enumerate((nx, ny, nz)))
    p, t = kuhn_grid(xs, ys, zs)
    phi = 0.5 - pad.transpose(2, 1, 0).astype(np.float64).ravel()  # kuhn_grid's (i, j, k)
    t = t[~(phi[t] > 0).all(axis=1)]  # tetrahedra wholly outside: not needed
    used = np.unique(t)
    remap = np.full(len(p), -1, np.int64)
    remap[used] = np.arange(len(used))
    p, t, phi = p[used], remap[t], phi[used]
    m = mmgpy.MmgMesh3D(np.ascontiguousarray(p), np.ascontiguousarray(t, dtype=np.int32))
    m.set_tetrahedra(np.ascontiguousarray(t, dtype=np.int32),
                     np.ones(len(t), dtype=np.int32))
    m.set_multi_materials([dict(ref=1, split=1, ref_minus=3, ref_plus=5)])
    out = m.remesh_levelset(np.ascontiguousarray(phi.reshape(-1, 1)), verbose=-1,
                            noinsert=1, noswap=1, nomove=1)
    if out.get("return_code", 0) != 0:
        raise MeshingError(f"MMG's level-set cut of the mask failed (code "
                           f"{out.get('return_code')})")
    p = np.array(m.get_vertices(), dtype=np.float64)
    tt, rr = m.get_tetrahedra_with_refs()
    t = np.asarray(tt, dtype=np.int64)[np.asarray(rr) == 3]
    used = np.unique(t)
    remap = np.full(len(p), -1, np.int64)
    remap[used] = np.arange(len(used))
    return p[used], _orient(p[used], remap[t])


# -- 2. size -------------------------------------------------------------------------------

def _mesh(solid, field, threshold, p, t, hausd, h_max, h_min, max_elements):
    from .general import _remesh, size_field

    faces, _ = boundary_faces(t)
    markers = np.zeros(len(faces), np.int64)
    size = size_field(field, p, threshold, h_max, h_min)
    rounds = 0
    for rounds in range(SIZE_ROUNDS + 1):
        p, t, faces, markers, h_mmg = _remesh(p, t, faces, np.zeros(len(faces), np.int64),
                                              size, hausd)
        if max_elements is not None and len(t) > max_elements:
            raise BudgetError(f"the mesh has {len(t)} tetrahedra, over the budget of "
                              f"{max_elements}")
        delta = delta_vertices(field.composition(p), t)
        bad = delta >= threshold
        log.info("mask: size round %d: %d tetrahedra, %d over delta_0", rounds, len(t),
                 int(bad.sum()))
        if not bad.any() or rounds == SIZE_ROUNDS:
            break
        size = np.minimum(h_mmg, size_field(field, p, threshold, h_max, h_min))
        shrink = np.ones(len(p))
        shrink[t[bad].ravel()] = SHRINK
        size = np.maximum(size * shrink, h_min)
    p, t, comp, delta, passes = repair(p, t, field, threshold, max_elements=max_elements)
    return p, t, comp, delta, rounds, passes


def estimate_masked(solid: VoxelSolid, field, threshold: float) -> float:
    """A-priori element count, as for solids of primitives
    (:func:`hetmesh.tet.general.estimate_solid`), plus the boundary at the voxel size."""
    from .general import estimate_solid

    lo, hi = solid.bounds
    est = estimate_solid(solid, field, threshold)
    area = 2.0 * float(((hi - lo)[[0, 1, 2]] * (hi - lo)[[1, 2, 0]]).sum())
    return est + 4.0 * area / solid.voxel ** 2


def generate_masked(solid: VoxelSolid, field, threshold: float, *, seed: int = 0,
                    chord_tol: float | None = None, max_elements: int | None = None,
                    max_size: float | None = None, check: bool = True) -> TetResult:
    """Tetrahedralise a :class:`VoxelSolid` with every element's delta below ``threshold``
    (see the module docstring). ``seed`` and ``chord_tol`` are accepted for the common
    interface: the boundary follows the voxels (:data:`HAUSD`) and MMG is deterministic."""
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
    p0, t0_ = cut_mask(solid)
    log.info("mask: cut %d tetrahedra of the voxel grid", len(t0_))
    probs: list[str] = []
    for hv in HAUSD:
        hausd = hv * solid.voxel
        p, t, comp, delta, rounds, passes = _mesh(solid, field, threshold, p0, t0_, hausd,
                                                  h_max, h_min, max_elements)
        t = t.astype(np.int32)
        faces, _ = boundary_faces(t)
        markers = solid.classify_faces(p[faces])
        info = {"placement": "mask", "size_rounds": rounds, "repair_passes": passes,
                "estimate": est, "composition": comp, "hausd": hausd, "h_max": h_max,
                "time_place": time.perf_counter() - t0}
        res = TetResult(p, t, faces.astype(np.int32), (markers + 1).astype(np.int32),
                        tuple(solid.face_names), delta, float(threshold), info)
        if not check:
            break
        probs = mask_problems(res, solid, field)
        if not probs:
            break
        log.info("mask: Hausdorff distance %.3g voxels: %s; again with less", hv, probs[0])
    if check and probs:
        raise VerificationError("tetrahedral mesh verification failed: " + probs[0]
                                + (f" (and {len(probs) - 1} more)" if len(probs) > 1 else ""))
    res.info["time_total"] = time.perf_counter() - t0
    log.info("mask mesh: %d points, %d tetrahedra, %.2f s", len(res.points), len(res.tets),
             res.info["time_total"])
    return res


# -- 3. verification -----------------------------------------------------------------------

def mask_problems(res, solid: VoxelSolid, field, chord_tol: float | None = None) -> list[str]:
    """Every broken claim of a mesh of ``solid``, one line each (empty: valid): validity,
    the recorded boundary, the voxel centres inside exactly the mask's, the boundary between
    unlike centres, delta_max < delta_0 (recomputed from ``field`` at the vertices; None:
    the result's own delta)."""
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
    pad, org = solid.padded
    _, v = voxel_centres_in_tets(p, t, org, solid.spacing, pad.shape)
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
    pts = np.einsum("bk,nkd->nbd", _BARY, p[res.faces]).reshape(-1, 3)
    mixed, _ = solid.stencil(pts)
    if not mixed.all():
        c = pts[np.flatnonzero(~mixed)[0]]
        out.append(f"the boundary leaves the voxels' contour by more than half a voxel at "
                   f"{int((~mixed).sum())} of {len(pts)} checked points (e.g. at "
                   f"({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    delta = res.delta if field is None else delta_vertices(field.composition(p), t)
    if not float(delta.max()) < res.threshold:
        out.append(f"delta_max = {float(delta.max()):.6g} is not below delta_0 = "
                   f"{res.threshold:g}")
    return out
