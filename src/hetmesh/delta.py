"""delta(T) of every element by the chosen sampling (``--sampling``).

``"vertices"`` is the paper's Eqs. (14)-(15) (:func:`hetmesh.metrics.delta_vertices`);
``"dense"`` adds an order-4 lattice inside every element (:func:`hetmesh.metrics.delta_dense`);
``"certified"`` an upper bound over the whole element (:mod:`hetmesh.certify`); ``"pixels"``
every pixel centre an element covers (image fields).
"""

from __future__ import annotations

import numpy as np

from .certify import certified_delta
from .metrics import delta_dense, delta_vertices
from .options import check_sampling
from .topology import unique

__all__ = ["element_delta"]


def element_delta(field, points: np.ndarray, triangles: np.ndarray, sampling: str = "vertices",
                  composition: np.ndarray | None = None,
                  regions: np.ndarray | None = None,
                  threshold: float | None = None) -> np.ndarray:
    """delta(T) of every element, from the vertices (Eqs. 14-15), with ``sampling="dense"``
    also from a lattice inside it, with ``sampling="certified"`` an upper bound on its
    variation over the whole element (:func:`hetmesh.certify.certified_delta`);
    with ``sampling="pixels"`` also from every pixel centre it covers (``field.pixel_delta``:
    image fields only, :func:`hetmesh.options.check_sampling`);
    ``composition`` at the points if already known; ``threshold`` (delta_0, optional) lets
    the certified bound stop refining an element once it is decided against delta_0.

    ``regions`` (the subregion of every element, for a feature-tree field) makes every
    element use its own subregion's composition at all its vertices: a vertex on a material
    discontinuity takes, in each element around it, the value of that element's side.
    """
    comp = field.composition(points) if composition is None else composition
    delta = delta_vertices(comp, triangles)
    if regions is not None:
        delta = _delta_own_region(field, points, triangles, comp, regions, delta)
    if sampling == "dense":
        delta = np.maximum(delta, delta_dense(field, points, triangles, regions=regions))
    elif sampling == "certified":
        delta = np.maximum(delta, certified_delta(field, points, triangles, regions=regions,
                                                      threshold=threshold))
    elif sampling == "pixels":
        check_sampling(field, sampling)
        delta = np.maximum(delta, field.pixel_delta(points, triangles, regions=regions,
                                                    composition=comp))
    return delta


def _delta_own_region(field, points, triangles, comp, regions, delta) -> np.ndarray:
    """:func:`delta_vertices` redone for the elements with a vertex owned by another
    subregion (on a discontinuity), with that vertex evaluated in the element's subregion."""
    vreg = field.region(points)
    e, k = np.nonzero(vreg[triangles] != regions[:, None])
    if len(e) == 0:
        return delta
    rows, inv = unique(e, return_inverse=True)
    c = comp if comp.ndim == 2 else comp[:, None]
    v = c[triangles[rows]].copy()  # (R, 3, m)
    v[inv, k] = field.composition(points[triangles[e, k]], region=regions[e])
    out = delta.copy()
    out[rows] = (v.max(axis=1) - v.min(axis=1)).max(axis=1)
    return out
