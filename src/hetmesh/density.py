"""Material-driven density and size fields: Eqs. (5), (8)-(9) of the paper.

g = |grad f| (Eq. 5), taken as the largest gradient norm over the constituents; the CVT density
is rho = g^(d+2) (Eq. 9; d = 2 for a planar domain, 3 for a solid). The matching local element
size follows from Eqs. (4) and (7):
h = c * delta_0 / g, floored by a maximum size so that flat zones stay meshed.
"""

from __future__ import annotations

import numpy as np

__all__ = ["gradient_norm", "density", "size_at", "background_points", "integrate",
           "n_iso", "estimate_elements"]

D = 2  # the default dimension of the domain


def gradient_norm(field, points: np.ndarray) -> np.ndarray:
    """g(x) = max_i |grad f_i(x)| over the constituents, Eq. (5); shape (N,)."""
    gr = field.gradient(points)  # (N, m, d)
    return np.sqrt((gr ** 2).sum(axis=2)).max(axis=1)


def density(g: np.ndarray, h_max: float, threshold: float, dim: int = D) -> np.ndarray:
    """rho = g^(d+2), Eq. (9), with g floored at delta_0 / h_max so rho > 0 everywhere;
    ``dim`` is d, the field's dimension (:func:`hetmesh.material.field_dim`).

    >>> density(np.array([2.0]), 1.0, 0.1).tolist(), density(np.array([2.0]), 1.0, 0.1, 3).tolist()
    ([16.0], [32.0])
    """
    g = np.maximum(g, threshold / h_max)
    return g ** (dim + 2)


def size_at(g: np.ndarray, threshold: float, h_max: float, factor: float = 1.0) -> np.ndarray:
    """Target edge length ``factor * delta_0 / g`` capped at ``h_max`` (Eqs. 4, 7)."""
    with np.errstate(divide="ignore"):
        h = factor * threshold / g
    return np.minimum(np.nan_to_num(h, nan=h_max, posinf=h_max), h_max)


def background_points(domain, n: int = 160) -> np.ndarray:
    """A cell-centred grid (``n`` cells along the longer side of the bounding box), clipped
    to the domain: ``(K, 2)`` points for the quadrature of smooth integrands."""
    x0, y0, x1, y1 = domain.bounds
    w, h = x1 - x0, y1 - y0
    hx = max(w, h) / n
    nx, ny = max(int(np.ceil(w / hx)), 1), max(int(np.ceil(h / hx)), 1)
    xs = x0 + (np.arange(nx) + 0.5) * (w / nx)
    ys = y0 + (np.arange(ny) + 0.5) * (h / ny)
    X, Y = np.meshgrid(xs, ys)
    pts = np.column_stack([X.ravel(), Y.ravel()])
    return pts[domain.contains(pts)]


def integrate(values: np.ndarray, domain) -> float:
    """Mid-point quadrature on the background grid, rescaled to the exact domain area."""
    if len(values) == 0:
        return 0.0
    return float(values.mean() * domain.area)


def n_iso(field, domain, threshold: float, n: int = 400) -> float:
    """N_iso = (4/sqrt(3)) * integral(|grad f|^2 dA) / delta_0^2.

    The number of equilateral elements of side delta_0 / |grad f| that tile the domain: the
    reference count of hetmesh's closeness-to-the-limit benchmark.
    """
    g = gradient_norm(field, background_points(domain, n))
    return 4.0 / np.sqrt(3.0) * integrate(g ** 2, domain) / threshold ** 2


def estimate_elements(field, domain, threshold: float, h_max: float, n: int = 200, *,
                      g=None) -> float:
    """A-priori element count: equilateral elements of side min(delta_0/g, h_max); ``g``
    (``(K, 2) -> (K,)``) replaces :func:`gradient_norm` (a capped or graded one)."""
    pts = background_points(domain, n)
    h = size_at(gradient_norm(field, pts) if g is None else g(pts), threshold, h_max)
    return 4.0 / np.sqrt(3.0) * integrate(1.0 / h ** 2, domain)
