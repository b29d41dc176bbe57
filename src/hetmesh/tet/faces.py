"""The boundary faces of a tetrahedral mesh, from its tetrahedra alone.

>>> import numpy as np
>>> t = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
>>> f, counts = boundary_faces(t)
>>> len(f), int(counts.max())
(6, 2)
"""

from __future__ import annotations

import numpy as np

from ..topology import unique
from .quality import TET_FACES

__all__ = ["boundary_faces", "interface_faces", "same_triangles", "BARY"]

#: the barycentric points at which the verifications check a triangle against its surface
#: (a curved face, an interface, a voxel contour): the corners, the edge midpoints, the
#: centroid and five more
BARY = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, .5, 0], [0, .5, .5], [.5, 0, .5],
                 [1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6],
                 [1 / 6, 1 / 6, 2 / 3], [.25, .25, .5], [.5, .25, .25]])


def boundary_faces(tets: np.ndarray, *, owners: bool = False):
    """``(faces (K, 3), counts (F,))``: the faces of one tetrahedron only, oriented outward
    (for positive tetrahedra), in first-occurrence order; ``counts`` the multiplicity of
    every distinct face. With ``owners``, also ``(K,)`` the row ``4 t + k`` of every
    boundary face: tetrahedron ``t``, the face opposite its vertex ``k``."""
    f = tets[:, TET_FACES].reshape(-1, 3).astype(np.int64)
    key = np.sort(f, axis=1)
    n = int(key.max()) + 1 if len(key) else 1
    if n < 2_000_000:  # one int64 per face: much faster than unique rows
        key = (key[:, 0] * n + key[:, 1]) * n + key[:, 2]
        _, first, counts = unique(key, return_index=True, return_counts=True)
    else:
        _, first, counts = unique(key, axis=0, return_index=True, return_counts=True)
    once = np.flatnonzero(counts == 1)
    rows = np.sort(first[once])
    if owners:
        return f[rows], counts, rows
    return f[rows], counts


def interface_faces(tets: np.ndarray, phase: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The triangles between tetrahedra of different phases, once each, with the phases of
    the tetrahedra on either side: ``(faces (K, 3), sides (K, 2))``."""
    f = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]],
                        tets[:, [0, 2, 1]]])
    owner = np.tile(np.arange(len(tets)), 4)
    key = np.sort(f, axis=1)
    order = np.lexsort(key.T[::-1])
    ks = key[order]
    same = (ks[1:] == ks[:-1]).all(axis=1)
    a, b = order[:-1][same], order[1:][same]
    differ = phase[owner[a]] != phase[owner[b]]
    a, b = a[differ], b[differ]
    return f[a], np.column_stack([phase[owner[a]], phase[owner[b]]])


def same_triangles(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the triangles ``a (K, 3)`` and ``b`` are the same, each once (as vertex sets,
    in any order)."""
    return len(a) == len(b) and np.array_equal(np.unique(np.sort(a, axis=1), axis=0),
                                               np.unique(np.sort(b, axis=1), axis=0))
