"""MMG's level-set mode as the 3-D meshers use it: cuts of a tetrahedral mesh along the zero
set of a function given at its vertices, without remeshing.

* :func:`levelset_cut`: one cut by MMG (``mmg3d -ls`` with no insertion, swap or move),
  the tetrahedra's references saying which side of it every piece lies on;
* :func:`split_bits`: the references that record the sides of cut ``bit`` as two bits;
* :func:`split_across`: the tetrahedra MMG left whole across the zero set split exactly
  by bisection at the zero of the interpolated values;
* :func:`quiet_mmg`: ``mmgpy``, its C warnings kept in its logger.

The surfaces cut this way: the curved faces of solids of primitives
(:mod:`hetmesh.tet.general`), subtracted primitives (:mod:`hetmesh.tet.carve`), voxel
contours (:mod:`hetmesh.tet.masked`) and the jumps of piecewise compositions
(:mod:`hetmesh.tet.jumps`).
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import MeshingError
from ..topology import unique
from .refine import bisect_edges, select_edges

__all__ = ["quiet_mmg", "levelset_cut", "split_bits", "split_across"]

log = logging.getLogger(__name__)


def _mmg():
    try:
        import mmgpy
    except ImportError as exc:  # a core dependency: a broken installation
        raise MeshingError(f"the general-solid mesher needs mmgpy (MMG): {exc}") from None
    return mmgpy


def quiet_mmg():
    """MMG prints warnings to stdout in C; nothing to do here but keep them in its logger."""
    mmgpy = _mmg()
    try:
        mmgpy.set_log_level("ERROR")
    except Exception:  # noqa: BLE001  (logging configuration is optional)
        pass
    return mmgpy


def levelset_cut(p, t, refs, phi, split: dict, what: str):
    """One MMG level-set cut (``mmg3d -ls`` without remeshing) of the tetrahedra whose
    reference is a key of ``split`` (``{ref: (ref_minus, ref_plus)}``, the references of
    their parts on the negative and the positive side of the zero set of the vertex values
    ``phi``; the others are kept whole): ``(points, tets, refs)``, MMG's points (the input
    ones first, then the new ones)."""
    mmgpy = quiet_mmg()
    m = mmgpy.MmgMesh3D(np.ascontiguousarray(p), np.ascontiguousarray(t, dtype=np.int32))
    m.set_tetrahedra(np.ascontiguousarray(t, dtype=np.int32),
                     np.ascontiguousarray(refs, dtype=np.int32))
    mats = []
    for r in unique(refs).tolist():
        lo, hi = split.get(r, (r, r))
        mats.append(dict(ref=int(r), split=int(r in split), ref_minus=int(lo),
                         ref_plus=int(hi)))
    m.set_multi_materials(mats)
    out = m.remesh_levelset(np.ascontiguousarray(phi, dtype=np.float64).reshape(-1, 1),
                            verbose=-1, noinsert=1, noswap=1, nomove=1)
    if out.get("return_code", 0) != 0:
        raise MeshingError(f"MMG's level-set cut of {what} failed (code "
                           f"{out.get('return_code')})")
    p = np.array(m.get_vertices(), dtype=np.float64)
    tt, rr = m.get_tetrahedra_with_refs()
    return p, np.asarray(tt, dtype=np.int64), np.asarray(rr, dtype=np.int64)


def split_bits(refs, bit: int) -> dict:
    """The ``split`` of :func:`levelset_cut` that splits every tetrahedron and records its
    side in the references: ``+ 2**(2 bit + 1)`` on the negative side, ``+ 2**(2 bit + 2)``
    on the positive one."""
    return {int(r): (int(r + 2 ** (2 * bit + 1)), int(r + 2 ** (2 * bit + 2)))
            for r in unique(refs).tolist()}


def split_across(p, t, refs, ls, bit: int, only=None,
                 what: str = "a subtracted primitive's surface"):
    """The tetrahedra with vertices on both sides of the zero set of the vertex values
    ``ls`` (MMG's level-set split leaves one whole where it finds an edge's split invalid),
    of those where ``only (M,) bool`` (default all), split exactly (``what``: the surface, as
    an error names it): edges across it
    bisected at the zero of ``ls`` along them (on a plane its exact crossing), a set with no
    two in one tetrahedron at a time (:func:`hetmesh.tet.refine.select_edges`), until none
    is across; the pieces' references get the side bits of
    :func:`hetmesh.tet.general.split_bits` (``bit``) by their vertices' signs. ``(points,
    tets, refs, ls)``, the new points after ``p`` with ``ls`` 0."""
    minus, plus = 2 ** (2 * bit + 1), 2 ** (2 * bit + 2)
    touched = np.zeros(len(t), dtype=bool)
    only = np.ones(len(t), dtype=bool) if only is None else np.asarray(only, dtype=bool)
    for _ in range(64):
        v = ls[t]
        across = (v > 0).any(axis=1) & (v < 0).any(axis=1) & only
        if not across.any():
            break
        # an edge across has the largest jump of the signs (2) in its tetrahedron; all
        # those jumps are equal, so the ties go by a hash of the edge ids: by the ids, a
        # structured grid crossed alike everywhere gave one edge in the first round and a
        # wave of them from a corner after it (a box cut by z = 1.5 was left across after
        # 64 rounds; a ball cut by z = 0.5 took 18 rounds, 7 by the hash)
        e = select_edges(t, np.sign(ls), across, hashed=True)
        a, b = ls[e[:, 0]], ls[e[:, 1]]
        w = (a / (a - b))[:, None]
        new = p[e[:, 0]] + w * (p[e[:, 1]] - p[e[:, 0]])
        p, t, parent = bisect_edges(p, t, e, new, with_parents=True)
        ls = np.r_[ls, np.zeros(len(e))]
        refs, touched, only = refs[parent], touched[parent] | across[parent], only[parent]
    else:
        raise MeshingError(f"tetrahedra across {what} could not be split along it")
    if touched.any():
        v = ls[t[touched]]
        side = np.where((v < 0).any(axis=1), minus, np.where((v > 0).any(axis=1), plus, 0))
        r = refs[touched]
        refs[touched] = np.where(side > 0, (r & ~(minus | plus)) | side, r)
        log.debug("level-set cut %d: %d tetrahedra left across it, split", bit,
                  int(touched.sum()))
    return p, t, refs, ls
