"""Tetrahedron measures: signed volumes, dihedral angles, radius ratio, delta over vertices.

All functions take ``points (N, 3)`` float64 and ``tets (M, 4)`` int and work on whole arrays.
A tetrahedron ``(a, b, c, d)`` is positively oriented when ``(b - a) x (c - a) . (d - a) > 0``.

>>> import numpy as np
>>> p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
>>> t = np.array([[0, 1, 2, 3]])
>>> float(volumes(p, t)[0]) == 1 / 6
True
>>> [round(float(v), 6) for v in np.sort(dihedral_angles(p, t)[0])]
[54.735610, 54.735610, 54.735610, 90.0, 90.0, 90.0]
"""

from __future__ import annotations

import numpy as np

__all__ = ["volumes", "dihedral_angles", "min_dihedral", "radius_ratio", "delta_tets",
           "TET_FACES", "TET_EDGES", "face_keys", "edge_keys", "quality_summary"]

#: the faces of tetrahedron (0, 1, 2, 3), each opposite vertex k, outward for positive tets
TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], dtype=np.int64)
#: the six edges (i, j), i < j
TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)
#: the two faces (opposite vertices k, l) meeting at edge (i, j): the complement of (i, j)
_EDGE_OPP = np.array([[2, 3], [1, 3], [1, 2], [0, 3], [0, 2], [0, 1]], dtype=np.int64)

BLOCK = 1 << 18


def _blocks(n: int):
    for s in range(0, n, BLOCK):
        yield slice(s, min(n, s + BLOCK))


def volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes ``(M,)``: positive for positively oriented tetrahedra."""
    out = np.empty(len(tets))
    for s in _blocks(len(tets)):
        t = tets[s]
        a = points[t[:, 0]]
        u, v, w = points[t[:, 1]] - a, points[t[:, 2]] - a, points[t[:, 3]] - a
        out[s] = np.einsum("ij,ij->i", np.cross(u, v), w) / 6.0
    return out


def _face_normals(points: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Area vectors ``(M, 4, 3)`` of the faces opposite each vertex (outward if positive)."""
    p = points[t]  # (M, 4, 3)
    f = TET_FACES
    return 0.5 * np.cross(p[:, f[:, 1]] - p[:, f[:, 0]], p[:, f[:, 2]] - p[:, f[:, 0]])


def dihedral_angles(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The six interior dihedral angles ``(M, 6)`` in degrees, in :data:`TET_EDGES` order."""
    out = np.empty((len(tets), 6))
    for s in _blocks(len(tets)):
        n = _face_normals(points, tets[s])
        ln = np.linalg.norm(n, axis=2)
        with np.errstate(invalid="ignore", divide="ignore"):
            n = n / ln[:, :, None]
        c = -np.einsum("mkj,mkj->mk", n[:, _EDGE_OPP[:, 0]], n[:, _EDGE_OPP[:, 1]])
        out[s] = np.degrees(np.arccos(np.clip(np.nan_to_num(c, nan=1.0), -1.0, 1.0)))
    return out


def min_dihedral(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The smallest dihedral angle of each tetrahedron ``(M,)``, degrees."""
    return dihedral_angles(points, tets).min(axis=1)


def radius_ratio(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """``3 r_in / R_circ`` ``(M,)``: 1 for the regular tetrahedron, 0 when flat."""
    out = np.empty(len(tets))
    for s in _blocks(len(tets)):
        t = tets[s]
        p = points[t]
        vol = np.abs(np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                               p[:, 3] - p[:, 0])) / 6.0
        area = np.linalg.norm(_face_normals(points, t), axis=2).sum(axis=1)
        e = np.linalg.norm(p[:, TET_EDGES[:, 1]] - p[:, TET_EDGES[:, 0]], axis=2)
        # opposite edge pairs: (01, 23), (02, 13), (03, 12)
        x, y, z = e[:, 0] * e[:, 5], e[:, 1] * e[:, 4], e[:, 2] * e[:, 3]
        prod = (x + y + z) * (x + y - z) * (x - y + z) * (-x + y + z)
        with np.errstate(invalid="ignore", divide="ignore"):
            r_in = 3.0 * vol / area
            r_c = np.sqrt(np.maximum(prod, 0.0)) / (24.0 * vol)
            q = 3.0 * r_in / r_c
        out[s] = np.nan_to_num(q, nan=0.0, posinf=0.0)
    return out


def delta_tets(composition: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """delta(T) ``(M,)`` from the four vertex compositions (Eqs. 14-15, max-norm): the
    largest range of a constituent over the vertices. ``composition`` is ``(N, m)`` or
    ``(N,)``."""
    c = composition if composition.ndim == 2 else composition[:, None]
    out = np.zeros(len(tets))
    for s in _blocks(len(tets)):
        t = tets[s]
        for j in range(c.shape[1]):
            v = c[:, j][t]
            np.maximum(out[s], v.max(axis=1) - v.min(axis=1), out=out[s])
    return out


def face_keys(tets: np.ndarray) -> np.ndarray:
    """The four faces of every tetrahedron as sorted vertex triples ``(4 M, 3)`` (face ``k``
    of tet ``i`` at row ``4 i + k``)."""
    f = tets[:, TET_FACES].reshape(-1, 3)
    return np.sort(f, axis=1)


def edge_keys(tets: np.ndarray) -> np.ndarray:
    """The six edges of every tetrahedron as sorted pairs ``(6 M, 2)``."""
    return np.sort(tets[:, TET_EDGES].reshape(-1, 2), axis=1)


def quality_summary(points: np.ndarray, tets: np.ndarray) -> dict:
    """Minimum and 1st-percentile dihedral angle (degrees), mean and minimum radius ratio."""
    if len(tets) == 0:
        return {"dihedral_min": float("nan"), "dihedral_p1": float("nan"),
                "radius_ratio_mean": float("nan"), "radius_ratio_min": float("nan")}
    dmin = min_dihedral(points, tets)
    rr = radius_ratio(points, tets)
    return {"dihedral_min": float(dmin.min()),
            "dihedral_p1": float(np.percentile(dmin, 1.0)),
            "radius_ratio_mean": float(rr.mean()), "radius_ratio_min": float(rr.min())}
