"""Checks shared by the tetrahedral tests, computed here independently of hetmesh."""

from __future__ import annotations

import numpy as np


def tet_quality(P, T) -> tuple[np.ndarray, np.ndarray]:
    """Every tetrahedron's smallest dihedral angle (degrees: at each edge, the angle between
    the other two vertices seen along it) and its radius ratio ``3 r_in / R_circ`` (the
    inradius from the volume and the face areas, the circumradius from the circumcentre's
    linear system)."""
    x = P[T]
    angles = []
    for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)):
        k, m = (v for v in range(4) if v not in (i, j))
        e = x[:, j] - x[:, i]
        e = e / np.linalg.norm(e, axis=1, keepdims=True)
        u, w = x[:, k] - x[:, i], x[:, m] - x[:, i]
        u = u - (u * e).sum(1, keepdims=True) * e
        w = w - (w * e).sum(1, keepdims=True) * e
        c = (u * w).sum(1) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1))
        angles.append(np.degrees(np.arccos(np.clip(c, -1, 1))))
    a, b, c = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]
    vol = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c))) / 6
    area = sum(0.5 * np.linalg.norm(np.cross(x[:, q] - x[:, p], x[:, r] - x[:, p]), axis=1)
               for p, q, r in ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)))
    A = 2 * np.stack([a, b, c], axis=1)
    rhs = np.stack([(a * a).sum(1), (b * b).sum(1), (c * c).sum(1)], axis=1)
    centre = np.linalg.solve(A, rhs[..., None])[..., 0]
    return np.min(angles, axis=0), 3 * (3 * vol / area) / np.linalg.norm(centre, axis=1)
