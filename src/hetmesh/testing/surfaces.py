"""Closed triangulated surfaces for tests and benchmarks of the surface-solid mesher."""

from __future__ import annotations

import numpy as np

__all__ = ["torus_surface"]


def torus_surface(R: float = 1.0, r: float = 0.3, nu: int = 24, nv: int = 8
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The points ``(nu nv, 3)`` and outward triangles ``(2 nu nv, 3)`` of a torus about the
    z axis (major radius ``R``, minor ``r``), each quadrilateral of its ``nu x nv`` grid
    split in two.

    >>> V, F = torus_surface()
    >>> V.shape, F.shape
    ((192, 3), (384, 3))
    """
    u = 2 * np.pi * np.arange(nu) / nu
    v = 2 * np.pi * np.arange(nv) / nv
    U, W = np.meshgrid(u, v, indexing="ij")
    V = np.c_[((R + r * np.cos(W)) * np.cos(U)).ravel(),
              ((R + r * np.cos(W)) * np.sin(U)).ravel(), (r * np.sin(W)).ravel()]
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a, b = (i * nv + j).ravel(), (((i + 1) % nu) * nv + j).ravel()
    c, d = (((i + 1) % nu) * nv + (j + 1) % nv).ravel(), (i * nv + (j + 1) % nv).ravel()
    return V, np.r_[np.c_[a, b, c], np.c_[a, c, d]]
