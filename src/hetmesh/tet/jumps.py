"""Jumps of a piecewise composition inside a remeshed solid: the surfaces where a formula's
condition changes (``where``, ``a if c else b``, ``sign``) are cut into the mesh and kept as
interfaces, so that no tetrahedron straddles one.

A piecewise formula field (:class:`hetmesh.material.AnalyticField` with jump conditions)
has a level function per condition (:meth:`~hetmesh.material.AnalyticField.levels`: ``b - a``
for ``a < b``, positive where the condition holds). Its subregion ids are the conditions'
truth values read as bits. The solids of primitives (:mod:`hetmesh.tet.general`) embed them
(and, with the input surface in place of the faces, the solids bounded by a triangulated
surface: :mod:`hetmesh.tet.surface_mesh`):

1. *Cut* (:func:`cut_jumps`): after the solid's own cuts, MMG's level-set mode splits the
   tetrahedra along the zero set of every condition's level function that changes sign
   over the vertices (:func:`hetmesh.tet.levelset.levelset_cut`); those MMG leaves whole
   across it are split exactly (:func:`hetmesh.tet.levelset.split_across`). Every
   tetrahedron's *phase* is its subregion id, read from the sides of the cuts.
2. *Remeshing*: MMG remeshes with the phases as tetrahedron references and the triangles
   between phases given to it, so it keeps them as interfaces (as the phases of a label
   volume, :mod:`hetmesh.tet.masked`); after each remeshing the interface vertices go back
   onto their jump surfaces (:func:`onto_jumps`; with the faces of those on the boundary).
   The size near a curved jump surface is capped as on a curved face (:func:`jump_cap`:
   the edge ``sqrt(6 chord / kappa)`` whose triangles stay within the chord tolerance,
   ``kappa`` the largest principal curvature of the level set, from the level function's
   Hessian ``|P H P| / |grad g|``, ``P`` the projector on its tangent plane).
3. *delta* is measured with every tetrahedron's corners in its own phase (a vertex on a
   jump takes each side's value in that side's tetrahedra: the jump itself is not a
   variation inside any element), so the size rounds and the repair do not refine at the
   jump.
4. *Verification* (:func:`jump_problems`): every tetrahedron's centroid in its phase (or
   within the chord tolerance of the jump surfaces that tell them apart), and every
   triangle between two phases within the chord tolerance of the jump surfaces between
   them at 12 points (the distance taken as ``|g| / |grad g|``, exact for planes, first
   order in the distance otherwise).

>>> from hetmesh.material import AnalyticField
>>> f = AnalyticField({"metal": "where(z < 0.5, 0.2, 0.8)"}, ["ceramic", "metal"], dim=3)
>>> has_jumps(f), JumpSurface(f, 0).g(np.array([[0.0, 0.0, 0.25]])).tolist()
(True, [0.25])
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ..delta import element_delta
from ..errors import MeshingError
from ..material import has_subregions
from ..metrics import delta_vertices
from ..topology import unique
from .faces import BARY, interface_faces
from .implicit import onto_surfaces
from .levelset import split_across

__all__ = ["has_jumps", "JumpSurface", "cut_jumps", "jump_cap", "onto_jumps",
           "jump_problems", "interface_bits", "phase_delta", "jump_radius", "interface_off"]

log = logging.getLogger(__name__)

#: the side bits :func:`cut_jumps` lets split_across record (2**41 and 2**42), above the
#: parent indices the references carry
_SIDE_BIT = 20
_PARENT = (1 << 41) - 1

def has_jumps(field) -> bool:
    """Whether ``field`` is piecewise with level functions for its jumps (a formula field
    with ``where``/``sign``): what :func:`cut_jumps` embeds."""
    return has_subregions(field) and callable(getattr(field, "levels", None))


class JumpSurface:
    """The zero set of condition ``i``'s level function: ``g`` (positive where the condition
    holds; where a side of the comparison is not finite, -1: the condition does not hold
    there) and ``grad``, the interface :func:`hetmesh.tet.implicit.onto_surfaces` moves
    vertices onto."""

    kind = "jump"

    def __init__(self, field, i: int):
        self.field = field
        self.i = int(i)

    def g(self, points) -> np.ndarray:
        v = self.field.levels(np.asarray(points, dtype=float).reshape(-1, 3))[:, self.i]
        return np.where(np.isfinite(v), v, -1.0)

    def grad(self, points) -> np.ndarray:
        v = self.field.levels(np.asarray(points, dtype=float).reshape(-1, 3), 1)[:, self.i]
        return np.where(np.isfinite(v), v, 0.0)

    def signed(self, points) -> np.ndarray:
        """``g / |grad g|``: the signed distance to the surface to first order (exact for a
        plane); infinite where the gradient vanishes off the surface."""
        g = self.g(points)
        n = np.linalg.norm(self.grad(points), axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(g == 0, 0.0, g / n)

    def distance(self, points) -> np.ndarray:
        """``|g| / |grad g|`` (:meth:`signed`)."""
        return np.abs(self.signed(points))


def cut_jumps(field, p: np.ndarray, t: np.ndarray, snap: float) -> tuple[np.ndarray,
                                                                          np.ndarray,
                                                                          np.ndarray]:
    """The tetrahedra ``(p, t)`` cut along every jump surface of ``field`` that crosses
    them (step 1 of the module docstring): ``(points, tets, phase)``, the input points
    first and unchanged, ``phase (M,)`` every tetrahedron's subregion id.

    Each cut bisects the edges across the zero set of the level function's first-order
    distance (:meth:`JumpSurface.signed`) at its interpolated zero
    (:func:`hetmesh.tet.levelset.split_across`), until no tetrahedron has vertices on both
    sides; a vertex within ``snap`` of the surface counts as on it (the interface vertices
    are moved onto the exact surface afterwards). Every tetrahedron then lies on one side of
    every cut, which its vertices' signs tell. MMG's level-set mode is not used here: on the
    slivers the cuts of curved faces leave, it misplaces crossing points and the sides."""
    k = len(field.conditions)
    phase = np.zeros(len(t), dtype=np.int64)
    for i in range(k):
        surf = JumpSurface(field, i)
        ls = surf.signed(p)
        ls = np.where(np.isfinite(ls), ls, np.sign(surf.g(p)))
        ls[np.abs(ls) < snap] = 0.0
        if (ls > 0).any() and (ls < 0).any():
            # the references carry every piece's parent (split_across records its sides
            # in bits above them)
            p, t, parent, ls = split_across(p, t, np.arange(len(t), dtype=np.int64), ls,
                                            _SIDE_BIT, what=f"the jump "
                                            f"{field.conditions[i]!r}")
            phase = phase[parent & _PARENT]
        v = ls[t]
        side = (v > 0).any(axis=1)
        if (side & (v < 0).any(axis=1)).any():
            raise MeshingError(f"tetrahedra left across the jump {field.conditions[i]!r}")
        phase |= side.astype(np.int64) << i
    log.info("jumps: %d conditions, %d phases, %d tetrahedra", k, len(unique(phase)),
             len(t))
    return p, t, phase


def phase_delta(field, p: np.ndarray, t: np.ndarray, phase, comp=None) -> np.ndarray:
    """delta over every tetrahedron's vertices (Eqs. 14-15), each evaluated in the
    tetrahedron's phase where the field has subregions (a piecewise formula, a label
    volume's phases), else every vertex in its own (``phase`` None, or a field of one
    region: a mask's). ``comp``: the vertex compositions, if known."""
    if phase is None or getattr(field, "n_regions", 1) <= 1:
        return delta_vertices(field.composition(p) if comp is None else comp, t)
    return element_delta(field, p, t, composition=comp, regions=np.asarray(phase))


def interface_bits(t: np.ndarray, phase: np.ndarray, n: int):
    """The triangles between two phases ``(faces (K, 3), bits (K,))`` (``bits``: the
    conditions telling the two sides apart) and, per point of ``n``, the bits of the
    interface triangles it is a corner of (0: on none)."""
    faces, sides = interface_faces(np.asarray(t, dtype=np.int64), np.asarray(phase))
    bits = (sides[:, 0] ^ sides[:, 1]).astype(np.int64)
    per = np.zeros(n, dtype=np.int64)
    for c in range(3):
        np.bitwise_or.at(per, faces[:, c], bits)
    return faces, bits, per


def _surfaces(field, bits: int) -> list:
    return [JumpSurface(field, i) for i in range(len(field.conditions)) if bits >> i & 1]


def onto_jumps(field, p: np.ndarray, t: np.ndarray, phase: np.ndarray,
               face_surfaces=None) -> np.ndarray:
    """Where every vertex of an interface between phases belongs: on the jump surfaces of
    its interface triangles and, for a boundary vertex, on its faces' surfaces
    (``face_surfaces(ids) -> list per id of surfaces``; None: inner vertices only), by
    :func:`hetmesh.tet.implicit.onto_surfaces` (three surfaces at most). The caller makes
    the moves that keep every tetrahedron positive."""
    _, _, per = interface_bits(t, phase, len(p))
    ids = np.flatnonzero(per)
    want = p.copy()
    if not len(ids):
        return want
    extra = face_surfaces(ids) if face_surfaces is not None else [[] for _ in ids]
    groups: dict[tuple, list[int]] = {}
    for v, b, fs in zip(ids.tolist(), per[ids].tolist(), extra):
        groups.setdefault((b, tuple(fs)), []).append(v)
    for (b, fs), vs in groups.items():
        surfs = (list(fs) + _surfaces(field, b))[:3]
        vs = np.asarray(vs)
        want[vs] = onto_surfaces(p[vs], surfs)
    bad = ~np.isfinite(want).all(axis=1)
    want[bad] = p[bad]
    return want


def jump_radius(field, lo, hi, n: int = 24) -> float:
    """The smallest radius of curvature of the jump surfaces inside the box ``[lo, hi]``,
    sampled at the points of an ``n^3`` grid within a cell of a zero set (infinite for
    planes): the background grid is cut along them at a spacing of a fraction of it."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    axes = [np.linspace(lo[a], hi[a], n) for a in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    cell = float((hi - lo).max()) / (n - 1)
    cap = jump_cap(field, pts, np.full(len(pts), np.inf), 1.0, reach=cell)
    # at chord 1 the cap is sqrt(6 / kappa): the radius 1 / kappa is cap^2 / 6
    r = cap[np.isfinite(cap)] ** 2 / 6.0
    return float(r.min()) if len(r) else math.inf


def interface_off(field, p: np.ndarray, t: np.ndarray, phase) -> float:
    """The largest first-order distance of an interface vertex from a jump surface of its
    interface triangles (0 without phases)."""
    if phase is None:
        return 0.0
    _, _, per = interface_bits(t, phase, len(p))
    off = 0.0
    for i in range(len(field.conditions)):
        ids = np.flatnonzero(per >> i & 1)
        if len(ids):
            off = max(off, float(JumpSurface(field, i).distance(p[ids]).max()))
    return off


def jump_cap(field, points: np.ndarray, size: np.ndarray, chord: float, *,
             reach=None) -> np.ndarray:
    """``size`` capped near the curved jump surfaces: at a point within its size of the
    zero set of a condition's level function, the edge ``sqrt(6 chord / kappa)`` whose
    triangles on a surface of curvature ``kappa`` stay within ``chord`` (``kappa`` the
    largest principal curvature of the level set through the point, ``|P H P| / |grad
    g|``). ``reach``: look at the points within it of a zero set instead (default: within
    their size)."""
    size = np.asarray(size, dtype=float).copy()
    k = len(field.conditions)
    if not k or not len(points):
        return size
    g = field.levels(points)
    dg = field.levels(points, 1)
    for i in range(k):
        n = np.linalg.norm(dg[:, i], axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.abs(g[:, i]) / n
            near = np.isfinite(dist) & (n > 0) & (dist <= (size if reach is None else reach))
        if not near.any():
            continue
        ids = np.flatnonzero(near)
        H = field.levels(points[ids], 2)[:, i]
        u = dg[ids, i] / n[ids, None]
        P = np.eye(3) - u[:, :, None] * u[:, None, :]
        PHP = np.einsum("nij,njk,nkl->nil", P, H, P)
        PHP = np.where(np.isfinite(PHP), PHP, 0.0)
        kappa = np.abs(np.linalg.eigvalsh(PHP)).max(axis=1) / n[ids]
        with np.errstate(divide="ignore"):
            cap = np.where(kappa > 0, np.sqrt(6.0 * chord / kappa), np.inf)
        # only where the capped edge reaches the surface: the cap grows away from it
        # by MMG's gradation
        hit = dist[ids] <= (cap if reach is None else reach)
        size[ids[hit]] = np.minimum(size[ids[hit]], cap[hit])
    return size


def jump_problems(field, p: np.ndarray, t: np.ndarray, phase, chord: float) -> list[str]:
    """The claims about the jumps of a mesh with phases, one line per broken one (step 4 of
    the module docstring)."""
    if phase is None:
        return []
    out = []
    phase = np.asarray(phase, dtype=np.int64)
    cen = p[t].mean(axis=1)
    own = np.asarray(field.region(cen), dtype=np.int64)
    wrong = np.flatnonzero(own != phase)
    if len(wrong):
        diff = own[wrong] ^ phase[wrong]
        far = np.zeros(len(wrong), dtype=bool)
        for i in range(len(field.conditions)):
            sel = (diff >> i & 1) == 1
            if sel.any():
                far[sel] |= JumpSurface(field, i).distance(cen[wrong[sel]]) > chord
        if far.any():
            j = int(wrong[far][0])
            c = cen[j]
            out.append(f"{int(far.sum())} tetrahedra straddle a jump of the composition (e.g. "
                       f"at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}): phase {int(phase[j])}, "
                       f"centroid in {int(own[j])})")
    faces, bits, _ = interface_bits(t, phase, len(p))
    for i in range(len(field.conditions)):
        sel = (bits >> i & 1) == 1
        if not sel.any():
            continue
        at = np.einsum("bk,nkd->nbd", BARY, p[faces[sel]]).reshape(-1, 3)
        dev = JumpSurface(field, i).distance(at)
        if not float(dev.max()) <= chord * (1 + 1e-9):
            out.append(f"the jump {field.conditions[i]!r}: an interface triangle is "
                       f"{float(dev.max()):.3g} off it (allowed {chord:.3g})")
    return out
