"""Tetrahedron measures for the tetrahedral mesher, on the shared metrics of
:mod:`hetmesh.metrics`: signed volumes, dihedral angles, radius ratio, delta over vertices,
the faces and edges of tetrahedra, and the quality figures the benchmarks report.

All functions take ``points (N, 3)`` float64 and ``tets (M, 4)`` int and work on whole arrays.
A tetrahedron ``(a, b, c, d)`` is positively oriented when ``(b - a) x (c - a) . (d - a) > 0``.

>>> import numpy as np
>>> p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
>>> t = np.array([[0, 1, 2, 3]])
>>> float(volumes(p, t)[0]) == 1 / 6
True
>>> [round(float(v), 6) for v in np.sort(dihedral_angles(p, t)[0])]
[54.73561, 54.73561, 54.73561, 90.0, 90.0, 90.0]
"""

from __future__ import annotations

import numpy as np

from .. import metrics

__all__ = ["volumes", "dihedral_angles", "min_dihedral", "radius_ratio", "delta_tets",
           "TET_FACES", "TET_EDGES", "quality_summary"]

#: the faces of tetrahedron (0, 1, 2, 3), each opposite vertex k, outward for positive tets
TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], dtype=np.int64)
#: the six edges (i, j), i < j, in the column order of :func:`dihedral_angles`
TET_EDGES = np.array(metrics.TET_EDGES, dtype=np.int64)


def volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes ``(M,)``: positive for positively oriented tetrahedra."""
    return metrics.tet_volumes6(points, tets) / 6.0


def dihedral_angles(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The six interior dihedral angles ``(M, 6)`` in degrees, in :data:`TET_EDGES` order."""
    return metrics.dihedral_angles(points, tets)


def min_dihedral(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The smallest dihedral angle of each tetrahedron ``(M,)``, degrees."""
    return dihedral_angles(points, tets).min(axis=1)


def radius_ratio(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """``3 r_in / R_circ`` ``(M,)``: 1 for the regular tetrahedron, 0 when flat."""
    return metrics.tet_quality(points, tets)


def delta_tets(composition: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """delta(T) ``(M,)`` from the four vertex compositions (Eqs. 14-15, max-norm)."""
    return metrics.delta_vertices(composition, tets)


def quality_summary(points: np.ndarray, tets: np.ndarray) -> dict:
    """Minimum and 1st-percentile of the tetrahedra's smallest dihedral angles (degrees),
    mean and minimum radius ratio."""
    if len(tets) == 0:
        return {"dihedral_min": float("nan"), "dihedral_p1": float("nan"),
                "radius_ratio_mean": float("nan"), "radius_ratio_min": float("nan")}
    dmin = min_dihedral(points, tets)
    rr = radius_ratio(points, tets)
    return {"dihedral_min": float(dmin.min()),
            "dihedral_p1": float(np.percentile(dmin, 1.0)),
            "radius_ratio_mean": float(rr.mean()), "radius_ratio_min": float(rr.min())}
