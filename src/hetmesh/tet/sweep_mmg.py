"""An MMG pass over swept and repaired tetrahedral meshes: better shapes after the bisection.

A sweep whose composition varies along the sweep is repaired by edge bisection
(:func:`hetmesh.tet.refine.repair`), which roughly halves the worst radius ratios. This pass
remeshes the repaired mesh with MMG (``mmgpy``) to the isotropic size ``h = S delta_0 /
|grad f|`` at every vertex, capped by the mean length of its edges (the repaired mesh's local
size), and then:

* the boundary and interface triangles go to MMG with their face markers as references, so
  MMG keeps every face and interface a surface of triangles (it treats a change of reference
  as a feature line) and moves a vertex only within its face; the triangles of curved faces
  and curved interfaces are required (kept as they are: their vertices stay on the exact
  surface); the vertices of the planar ones are put back on their planes exactly after MMG
  (which leaves them within rounding errors);
* every tetrahedron's MMG reference is its piece: the connected part of the mesh between
  the boundary and interface triangles (MMG keeps an inner triangle only between two
  references), each in one subregion, so no tetrahedron straddles a discontinuity;
* delta is measured again (every tetrahedron's corners in its subregion); the size at the
  vertices of the violators is multiplied by :data:`SHRINK` and MMG remeshes again, at most
  :data:`ROUNDS` times; the violators left are repaired by bisection, the interface
  triangles split with their edges (:func:`split_faces`).

The caller verifies the result and keeps it only if it is better (:func:`better`). MMG runs
single-threaded and deterministically: the same input gives the same mesh.

>>> import numpy as np
>>> f = np.array([[0, 1, 2], [1, 3, 2]])
>>> split_faces(f, np.array([5, 6]), np.array([[1, 2]]), 4)[0].tolist()
[[1, 4, 0], [2, 4, 3], [4, 2, 0], [4, 1, 3]]
"""

from __future__ import annotations

import logging
import time

import numpy as np

from ..errors import BudgetError, MeshingError
from ..metrics import delta_vertices
from .faces import boundary_faces
from .general import orient_positive, quiet_mmg
from .mesher import TetResult
from .quality import quality_summary
from .refine import corner_compositions, repair, unique_edges

__all__ = ["mmg_improve", "improve_result", "split_faces", "better", "targets_met", "S",
           "SHRINK", "ROUNDS", "TARGETS"]

log = logging.getLogger(__name__)

#: the size factor: h = S delta_0 / |grad f| (capped by the repaired mesh's local size)
S = 1.0
#: the size at the vertices of the tetrahedra still over delta_0 is multiplied by this
SHRINK = 0.85
#: MMG rounds at most (then the bisection repair of the violators left)
ROUNDS = 3
#: MMG's gradation (largest ratio of adjacent edge lengths)
HGRAD = 1.3
#: the quality targets: smallest dihedral angle, its 1st percentile (degrees), mean radius
#: ratio 3 r_in / R_circ
TARGETS = (10.0, 20.0, 0.75)


def _local_size(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The mean length of the edges at every vertex."""
    e, _ = unique_edges(tets)
    length = np.linalg.norm(points[e[:, 0]] - points[e[:, 1]], axis=1)
    n = len(points)
    s = np.bincount(e.ravel(), weights=np.repeat(length, 2), minlength=n)
    return s / np.maximum(np.bincount(e.ravel(), minlength=n), 1)


def _delta(field, points, tets, regions) -> np.ndarray:
    """delta of every tetrahedron, its corners evaluated in its subregion."""
    cc = corner_compositions(field, points, tets, regions) if regions is not None else \
        np.asarray(field.composition(points), dtype=np.float64)[tets]
    if cc.ndim == 2:
        cc = cc[..., None]
    return (cc.max(axis=1) - cc.min(axis=1)).max(axis=1)


def _field_size(field, points, tets, regions, threshold: float) -> np.ndarray:
    """``S delta_0 / |grad f|`` at every vertex, ``|grad f|`` the largest over its
    tetrahedra's subregions and the constituents (inf where the field is flat)."""
    t = np.asarray(tets, dtype=np.int64).ravel()
    g = field.gradient(points[t]) if regions is None else \
        field.gradient(points[t], region=np.repeat(np.asarray(regions), 4))
    gn = np.linalg.norm(np.asarray(g, dtype=np.float64), axis=-1).max(axis=-1)
    gv = np.zeros(len(points))
    np.maximum.at(gv, t, gn)
    with np.errstate(divide="ignore"):
        return np.where(gv > 0, S * threshold / np.maximum(gv, 1e-300), np.inf)


def _remesh(points, tets, refs, faces, markers, required, size, hausd):
    """One MMG remeshing to ``size`` per vertex: ``(points, tets, refs, faces, markers,
    size MMG interpolated)``; tetrahedra and triangles keep their references."""
    mmgpy = quiet_mmg()
    m = mmgpy.MmgMesh3D()
    m.set_mesh_size(vertices=len(points), tetrahedra=len(tets), triangles=len(faces))
    m.set_vertices(np.ascontiguousarray(points, dtype=np.float64))
    m.set_tetrahedra(np.ascontiguousarray(tets, dtype=np.int32),
                     np.ascontiguousarray(refs, dtype=np.int32))
    m.set_triangles(np.ascontiguousarray(faces, dtype=np.int32),
                    np.ascontiguousarray(markers, dtype=np.int32))
    if required.any():
        m.set_required_triangles(np.ascontiguousarray(np.flatnonzero(required),
                                                      dtype=np.int32))
    m.set_field("metric", np.ascontiguousarray(size, dtype=np.float64).reshape(-1, 1))
    try:
        out = m.remesh(verbose=-1, hausd=float(hausd), hgrad=HGRAD)
    except RuntimeError as exc:  # mmgpy's report of a failed remeshing
        raise MeshingError(f"MMG remeshing failed: {exc}") from None
    if out.get("return_code", 0) != 0:
        raise MeshingError(f"MMG remeshing failed (code {out.get('return_code')})")
    p = np.array(m.get_vertices(), dtype=np.float64)
    t, tr = m.get_tetrahedra_with_refs()
    t = orient_positive(p, np.asarray(t, dtype=np.int64))
    f, fr = m.get_triangles_with_refs()
    h = np.asarray(m.get_field("metric"), dtype=np.float64).reshape(-1)
    return (p, t, np.asarray(tr, dtype=np.int64), np.asarray(f, dtype=np.int64),
            np.asarray(fr, dtype=np.int64), h)


def split_faces(faces: np.ndarray, markers: np.ndarray, ends: np.ndarray, n0: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """Triangles ``faces (F, 3)`` (with ``markers (F,)``) split as the bisection repair split
    their edges: new point ``n0 + k`` is the midpoint of ``ends[k]``; a triangle ``(a, b, c)``
    whose edge ``(a, b)`` was split at ``m`` becomes ``(a, m, c)`` and ``(m, b, c)`` (the
    same orientation), until no edge of a triangle is split. A triangle's edges are split
    in the order of their midpoints (the order of the repair's passes): the triangulation of
    the faces of the repaired tetrahedra."""
    f = np.asarray(faces, dtype=np.int64).copy()
    mk = np.asarray(markers, dtype=np.int64).copy()
    ends = np.sort(np.asarray(ends, dtype=np.int64).reshape(-1, 2), axis=1)
    if not len(ends) or not len(f):
        return f, mk
    n = int(max(ends.max(), f.max(), n0 + len(ends))) + 1
    key = ends[:, 0] * n + ends[:, 1]
    order = np.argsort(key)
    skey = key[order]
    mid = n0 + order  # the midpoint of every sorted edge
    while True:
        found = np.full(len(f), -1, dtype=np.int64)
        side = np.full(len(f), -1, dtype=np.int64)
        for k in (0, 1, 2):  # the earliest split edge (a, b) = (f[k], f[k+1]) of each
            a, b = f[:, k], f[:, (k + 1) % 3]
            kk = np.minimum(a, b) * n + np.maximum(a, b)
            pos = np.clip(np.searchsorted(skey, kk), 0, len(skey) - 1)
            hit = (skey[pos] == kk) & ((found < 0) | (mid[pos] < found))
            found[hit], side[hit] = mid[pos[hit]], k
        rows = np.flatnonzero(found >= 0)
        if not len(rows):
            return f, mk
        k = side[rows]
        a, b, c = f[rows, k], f[rows, (k + 1) % 3], f[rows, (k + 2) % 3]
        m = found[rows]
        one = np.column_stack([a, m, c])
        two = np.column_stack([m, b, c])
        keep = np.ones(len(f), dtype=bool)
        keep[rows] = False
        f = np.concatenate([f[keep], one, two])
        mk = np.concatenate([mk[keep], mk[rows], mk[rows]])


def mmg_improve(points, tets, regions, faces, markers, curved, field, threshold: float,
                hausd: float, *, snap=None, max_elements: int | None = None):
    """The repaired mesh ``(points, tets)`` remeshed by MMG and repaired again (see the
    module): ``(points, tets, regions, faces, markers, rounds)`` or None if the element
    budget ``max_elements`` would be exceeded. ``regions (M,)`` the subregions (or None),
    ``faces (F, 3)`` the boundary and interface triangles with positive ``markers (F,)``,
    ``curved`` the markers of curved surfaces (their triangles are required: MMG keeps
    them as they are), ``hausd`` MMG's Hausdorff distance, ``snap(points, faces, markers)
    -> points`` puts the vertices MMG moved on planar faces and interfaces back on them
    exactly (after every round; MMG leaves them within rounding errors)."""
    t = np.asarray(tets, dtype=np.int64)
    p = np.asarray(points, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    mk = np.asarray(markers, dtype=np.int64)
    piece = _pieces(t, f)  # the MMG reference of every tetrahedron: its piece + 1
    refs = piece + 1
    region_of = np.zeros(int(piece.max()) + 1, dtype=np.int64)
    if regions is not None:
        region_of[piece] = np.asarray(regions, dtype=np.int64)
    curved = np.asarray(sorted(curved), dtype=np.int64)
    size = np.minimum(_local_size(p, t), _field_size(field, p, t, regions, threshold))
    rounds = 0
    for rounds in range(1, ROUNDS + 1):
        p, t, refs, f, mk, h = _remesh(p, t, refs, f, mk, np.isin(mk, curved), size, hausd)
        if snap is not None:
            p = snap(p, f, mk)
        if max_elements is not None and len(t) > max_elements:
            return None
        reg = None if regions is None else region_of[refs - 1]
        bad = _delta(field, p, t, reg) >= threshold
        log.debug("MMG round %d: %d tetrahedra, %d over delta_0", rounds, len(t),
                  int(bad.sum()))
        if not bad.any():
            break
        shrink = np.ones(len(p))
        shrink[t[bad].ravel()] = SHRINK
        size = h * shrink
    reg = None if regions is None else region_of[refs - 1]
    n0 = len(p)
    try:
        p, t, _, _, _, tr = repair(p, t, field, threshold, max_elements=max_elements,
                                   regions=reg, trace=True)
    except BudgetError:
        return None
    f, mk = split_faces(f, mk, tr.ends, n0)
    reg = None if reg is None else reg[tr.parent]
    return p, t, reg, f, mk, rounds


def _pieces(tets, faces) -> np.ndarray:
    """The connected piece of every tetrahedron, across the faces not in ``faces`` (the
    boundary and interface triangles): MMG keeps an inner triangle only between two
    references, so every piece is one."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    t = np.asarray(tets, dtype=np.int64)
    n = int(t.max()) + 1
    tf = np.sort(np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]],
                                 t[:, [0, 1, 2]]]), axis=1)
    key = (tf[:, 0] * n + tf[:, 1]) * n + tf[:, 2]
    owner = np.tile(np.arange(len(t)), 4)
    fs = np.sort(np.asarray(faces, dtype=np.int64), axis=1)
    cut = np.isin(key, (fs[:, 0] * n + fs[:, 1]) * n + fs[:, 2])
    order = np.argsort(key, kind="stable")
    k, o, c = key[order], owner[order], cut[order]
    pair = np.flatnonzero((k[1:] == k[:-1]) & ~c[1:])
    g = coo_matrix((np.ones(len(pair)), (o[pair], o[pair + 1])), shape=(len(t), len(t)))
    return connected_components(g, directed=False)[1].astype(np.int64)


def improve_result(res, field, threshold: float, *, curved: set, interfaces: set,
                   hausd: float, snap, classify, problems, max_elements: int | None = None):
    """``res`` (a verified swept + repaired :class:`~hetmesh.tet.mesher.TetResult`) if it
    meets every quality target (:data:`TARGETS`); else ``res`` remeshed by MMG and repaired
    again (:func:`mmg_improve`) if the result passes ``problems(result, interface faces,
    their markers) -> list[str]`` (the caller's verification) and is :func:`better`, else
    ``res`` (also if MMG or the repair after it fails). ``curved``: the markers whose
    triangles MMG must keep; ``interfaces``: the interface markers (the others are boundary
    faces, named again by ``classify(points, faces) -> markers``); ``snap``: as
    :func:`mmg_improve`. The kept result has ``info["mmg_rounds"]``."""
    t0 = time.perf_counter()
    q_old = quality_summary(res.points, res.tets)
    if targets_met(q_old) == len(TARGETS):
        return res
    regions = res.info.get("regions")
    try:
        out = mmg_improve(res.points, res.tets, regions, res.faces, res.face_markers, curved,
                          field, threshold, hausd, max_elements=max_elements, snap=snap)
    except MeshingError as exc:  # MMG failed, or the repair after it: keep the repaired mesh
        log.info("MMG pass failed (%s): the repaired sweep is kept", exc)
        return res
    if out is None:
        log.info("MMG pass over the element budget: the repaired sweep is kept")
        return res
    points, tets, regions, f, mk, rounds = out
    tets = tets.astype(np.int32)
    faces, _ = boundary_faces(tets)
    markers = classify(points, faces)
    on = np.isin(mk, sorted(interfaces))
    inter, im = f[on], mk[on]
    comp = None
    if regions is None:
        comp = np.asarray(field.composition(points), dtype=np.float64)
        delta = delta_vertices(comp, tets)
    else:
        delta = _delta(field, points, tets, regions)
    info = {k: v for k, v in res.info.items() if k not in ("regions", "composition")}
    new = TetResult(points, tets, np.concatenate([faces, inter]).astype(np.int32),
                    np.concatenate([markers, im]).astype(np.int32), res.face_names, delta,
                    float(threshold), info)
    if regions is not None:
        new.info["regions"] = regions.astype(np.int32)
    if comp is not None:
        new.info["composition"] = comp
    probs = problems(new, inter, im)
    q_new = quality_summary(points, tets)
    fig = (f"{len(res.tets)} -> {len(tets)} tetrahedra, dihedral min {q_old['dihedral_min']:.1f}"
           f" -> {q_new['dihedral_min']:.1f}, 1st pct {q_old['dihedral_p1']:.1f} -> "
           f"{q_new['dihedral_p1']:.1f}, mean radius ratio {q_old['radius_ratio_mean']:.3f} "
           f"-> {q_new['radius_ratio_mean']:.3f}, {time.perf_counter() - t0:.2f} s")
    if probs or not better(q_new, q_old):
        log.info("MMG pass not kept (%s): %s", probs[0] if probs else "not better", fig)
        return res
    log.info("MMG pass (%d rounds) kept: %s", rounds, fig)
    new.info["mmg_rounds"] = rounds  # the placement stays the caller's
    return new


def targets_met(q: dict) -> int:
    """How many of the quality targets (:data:`TARGETS`) ``q`` (a
    :func:`~hetmesh.tet.quality_summary`) meets."""
    return int(q["dihedral_min"] >= TARGETS[0]) + int(q["dihedral_p1"] >= TARGETS[1]) + \
        int(q["radius_ratio_mean"] >= TARGETS[2])


def better(q_new: dict, q_old: dict) -> bool:
    """Whether the quality ``q_new`` beats ``q_old``: more targets met, or as many and a
    larger mean radius ratio with a smallest dihedral angle at least the smaller of the
    old one and the target."""
    a, b = targets_met(q_new), targets_met(q_old)
    if a != b:
        return a > b
    return (q_new["radius_ratio_mean"] > q_old["radius_ratio_mean"]
            and q_new["dihedral_min"] >= min(q_old["dihedral_min"], TARGETS[0]))

