"""The check that no element interior crosses a discontinuity."""

from __future__ import annotations

import numpy as np

from ...material.field import element_subregions

__all__ = ["crossing_elements"]


def crossing_elements(field, points: np.ndarray, triangles: np.ndarray, curves, *,
                      order: int = 4, tol: float = 0.0,
                      regions: np.ndarray | None = None) -> np.ndarray:
    """Elements whose interior crosses a subregion boundary (bool ``(M,)``).

    Every element is sampled on its order-``order`` lattice (pulled a hair inside); a sample
    owned by another subregion than the element's centroid is a crossing unless it lies within
    the element's chord error of the embedded curves ``curves`` (a :class:`CurveBatch`): an
    edge on a curved discontinuity is its chord, and the sliver between chord and curve,
    of width the sagitta, belongs to the neighbour. ``tol`` adds the fitting tolerance.
    ``regions``: the elements' subregions if already known (:func:`element_subregions`).
    """
    from ...metrics import lattice_barycentric

    own = element_subregions(field, points, triangles) if regions is None else regions
    lam = lattice_barycentric(order)
    lam = 0.999 * lam + 0.001 / 3.0
    xy = np.einsum("kv,cvd->ckd", lam, points[triangles])  # (M, K, 2)
    reg = field.region(xy.reshape(-1, 2)).reshape(len(triangles), -1)
    bad = reg != own[:, None]
    if not bad.any():
        return np.zeros(len(triangles), bool)
    e, k = np.nonzero(bad)
    near = curves.distance(xy[e, k])
    tri = triangles[e]
    nxt = np.roll(tri, -1, axis=1)
    lens = np.hypot(*(points[tri] - points[nxt]).transpose(2, 0, 1))  # (n, 3)
    scale = float(lens.max())
    on = curves.distance(points) <= 1e-9 * scale
    mids = 0.5 * (points[tri] + points[nxt]).reshape(-1, 2)
    sag = np.where(on[tri] & on[nxt], curves.distance(mids).reshape(-1, 3), 0.0).max(axis=1)
    allowed = sag + tol + 1e-9 * scale
    out = np.zeros(len(triangles), bool)
    out[e[near > allowed]] = True
    return out
