"""The checks of every tetrahedral mesh before it is returned: positive volumes, conformity,
boundary faces on the solid's faces (planar ones exactly, curved ones within the chord
tolerance), volume and face areas of the solid, every point used, delta_max < delta_0.
The checks every mesh gets are :meth:`hetmesh.mesh.Mesh.problems`'s.
"""

from __future__ import annotations

import numpy as np

from ..errors import VerificationError
from ..mesh import Mesh, simplex_measures
from ..metrics import delta_vertices

__all__ = ["verify_tets", "tet_problems", "validity_problems", "raise_problems"]


def _tri_area(p: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def validity_problems(points: np.ndarray, tets: np.ndarray) -> list[str]:
    """What every tetrahedral mesh must satisfy, one line per broken claim: the mesher's
    own orientation (positive volumes, checked before :class:`~hetmesh.mesh.Mesh`
    re-orients), then :meth:`hetmesh.mesh.Mesh.problems` (degenerate cells, unused or
    repeated points, faces held by more than two tetrahedra, a boundary not closed)."""
    v = simplex_measures(points, tets)
    out = []
    if (v < 0).any():
        i = int(np.argmin(v))
        out.append(f"{int((v < 0).sum())} tetrahedra of negative volume (smallest "
                   f"{v[i]:.3g}, tetrahedron {i})")
    return out + Mesh(points, tets).problems()


def tet_problems(points, tets, faces, markers, solid, delta, threshold, chord_tol
                 ) -> list[str]:
    """Every broken claim, one line each (empty: the mesh is valid)."""
    if len(tets) == 0:
        return ["no tetrahedra"]
    out = validity_problems(points, tets)
    v = simplex_measures(points, tets)
    if (markers <= 0).any():
        k = int(np.flatnonzero(markers <= 0)[0])
        c = points[faces[k]].mean(axis=0)
        out.append(f"{int((markers <= 0).sum())} boundary triangles on no face of the solid "
                   f"(e.g. at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    L, diam = solid.length, solid.diameter
    area = _tri_area(points[faces])
    names = solid.face_names
    arcs = sum(c.curve.length for c in solid.section.curves if hasattr(c.curve, "radius"))
    # chords within chord_tol of their arcs: the section's area is off by at most
    # (arc length x chord tolerance)
    short = arcs * chord_tol
    exact_vol = True
    for m, name in enumerate(names, start=1):
        sel = markers == m
        got = float(area[sel].sum())
        if m <= 2:
            want = float(solid.section.area)
            slack = 1e-9 * max(want, diam ** 2)
            if abs(got - want) > short + slack:
                out.append(f"face {name!r}: triangles cover {got:.12g}, the face {want:.12g}")
            continue
        curve = solid.section.curves[m - 3].curve
        want = float(curve.length) * L
        if hasattr(curve, "radius"):
            exact_vol = False
            q, _ = solid.to2d(points[faces[sel]].reshape(-1, 3))
            q = q.reshape(-1, 3, 2)
            mids = 0.5 * (q + q[:, [1, 2, 0]])
            r = np.hypot(mids[..., 0] - curve.center[0], mids[..., 1] - curve.center[1])
            sag = float(np.abs(curve.radius - r).max()) if len(r) else 0.0
            if sag > chord_tol * (1 + 1e-9):
                out.append(f"face {name!r}: chord deviation {sag:.3g} exceeds the chord "
                           f"tolerance {chord_tol:.3g}")
            if abs(got - want) > want * (chord_tol / curve.radius + 1e-9):
                out.append(f"face {name!r}: triangles cover {got:.12g}, the face "
                           f"{want:.12g}")
        elif abs(got - want) > 1e-9 * max(want, diam ** 2):
            out.append(f"face {name!r}: triangles cover {got:.12g}, the face {want:.12g}")
    vol = float(v.sum())
    want = solid.volume
    if exact_vol:
        if abs(vol - want) > 1e-9 * want:
            out.append(f"volume {vol:.12g} differs from the solid's {want:.12g}")
    else:
        if abs(vol - want) > short * L + 1e-9 * want:
            out.append(f"volume {vol:.12g} differs from the solid's {want:.12g} by more than "
                       f"the chord tolerance allows")
    if delta is not None:
        dmax = float(delta.max())
        if not dmax < threshold:
            out.append(f"delta_max = {dmax:.6g} is not below delta_0 = {threshold:g}")
    return out


def verify_tets(res, solid, field, chord_tol: float) -> None:
    """Raise :class:`VerificationError` naming the first broken claim of ``res``
    (a :class:`~hetmesh.tet.mesher.TetResult`); delta is recomputed from ``field``."""
    delta = delta_vertices(field.composition(res.points), res.tets)
    probs = tet_problems(res.points, res.tets, res.faces, res.face_markers, solid, delta,
                         res.threshold, chord_tol)
    raise_problems(probs)


def raise_problems(probs: list[str]) -> None:
    """Raise :class:`VerificationError` naming the first of ``probs`` (and how many more),
    if there are any."""
    if probs:
        raise VerificationError(f"tetrahedral mesh verification failed: {probs[0]}"
                                + (f" (and {len(probs) - 1} more)" if len(probs) > 1 else ""))
