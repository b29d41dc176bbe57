"""The quality figures of tetrahedral meshes, on the shared metrics of :mod:`hetmesh.metrics`
(volumes, dihedral angles, radius ratio and delta are there): the smallest dihedral angle
per tetrahedron, the summary the benchmarks and ``--stats`` report, and the faces and edges
of a tetrahedron.

All functions take ``points (N, 3)`` float64 and ``tets (M, 4)`` int and work on whole arrays.
A tetrahedron ``(a, b, c, d)`` is positively oriented when ``(b - a) x (c - a) . (d - a) > 0``.

>>> import numpy as np
>>> p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
>>> t = np.array([[0, 1, 2, 3]])
>>> round(float(min_dihedral(p, t)[0]), 6)
54.73561
"""

from __future__ import annotations

import numpy as np

from .. import metrics

__all__ = ["min_dihedral", "TET_FACES", "TET_EDGES", "quality_summary"]

#: the faces of tetrahedron (0, 1, 2, 3), each opposite vertex k, outward for positive tets
TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], dtype=np.int64)
#: the six edges (i, j), i < j, in the column order of :func:`dihedral_angles`
TET_EDGES = np.array(metrics.TET_EDGES, dtype=np.int64)


def min_dihedral(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The smallest dihedral angle of each tetrahedron ``(M,)``, degrees."""
    return metrics.dihedral_angles(points, tets).min(axis=1)


def quality_summary(points: np.ndarray, tets: np.ndarray) -> dict:
    """Minimum and 1st-percentile of the tetrahedra's smallest dihedral angles (degrees),
    mean and minimum radius ratio."""
    if len(tets) == 0:
        return {"dihedral_min": float("nan"), "dihedral_p1": float("nan"),
                "radius_ratio_mean": float("nan"), "radius_ratio_min": float("nan")}
    dmin = min_dihedral(points, tets)
    rr = metrics.tet_quality(points, tets)
    return {"dihedral_min": float(dmin.min()),
            "dihedral_p1": float(np.percentile(dmin, 1.0)),
            "radius_ratio_mean": float(rr.mean()), "radius_ratio_min": float(rr.min())}
