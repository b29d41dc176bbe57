"""Pixel sampling: delta(T) over every pixel centre an element covers, complemented by its
vertices (an element may cover no pixel centre at all)."""

from __future__ import annotations

import numpy as np

from .field import ImageField

__all__ = ["pixel_centres_in_triangles", "element_pixel_delta"]


# ---------------------------------------------------------------------- pixel sampling
def pixel_centres_in_triangles(points: np.ndarray, triangles: np.ndarray, origin,
                               spacing, shape, *, block: int = 1 << 15):
    """The pixel centres each triangle covers.

    Parameters
    ----------
    points : ``(N, 2)``; triangles : ``(M, 3)``
    origin, spacing : ``(2,)`` centre of the first pixel and pixel size, x first
    shape : ``(ny, nx)``

    Returns
    -------
    element : ``(K,)`` int64
        The triangle of each (triangle, pixel) pair, ascending.
    pixel : ``(K,)`` int64
        The flat index ``j * nx + i`` of the pixel centre (closed triangles: a centre on a
        shared edge counts for both).

    Examples
    --------
    >>> e, p = pixel_centres_in_triangles(np.array([[0., 0], [4, 0], [0, 4]]),
    ...                                   np.array([[0, 1, 2]]), (0.5, 0.5), (1, 1), (4, 4))
    >>> p.tolist()
    [0, 1, 2, 3, 4, 5, 6, 8, 9, 12]
    """
    P = np.asarray(points, float)
    T = np.asarray(triangles, np.int64)
    o, s = np.asarray(origin, float), np.asarray(spacing, float)
    ny, nx = (int(v) for v in shape)
    out_e, out_p = [], []
    for b in range(0, len(T), block):
        tri = T[b:b + block]
        u = (P[tri] - o) / s  # (B, 3, 2) in index units
        lo = np.maximum(np.ceil(u.min(axis=1) - 1e-9).astype(np.int64), 0)
        hi = np.minimum(np.floor(u.max(axis=1) + 1e-9).astype(np.int64), [nx - 1, ny - 1])
        cnt = np.maximum(hi - lo + 1, 0)
        tot = cnt[:, 0] * cnt[:, 1]
        if not tot.sum():
            continue
        e = np.repeat(np.arange(len(tri)), tot)
        start = np.cumsum(tot) - tot
        k = np.arange(int(tot.sum())) - np.repeat(start, tot)
        i = lo[e, 0] + k % cnt[e, 0]
        j = lo[e, 1] + k // cnt[e, 0]
        q = np.column_stack([i, j]).astype(float)
        a, bb, c = u[e, 0], u[e, 1], u[e, 2]
        d = _cross(bb - a, c - a)
        eps = 1e-12 * np.abs(d)
        l1 = _cross(bb - q, c - q) * np.sign(d)
        l2 = _cross(c - q, a - q) * np.sign(d)
        l3 = _cross(a - q, bb - q) * np.sign(d)
        ins = (l1 >= -eps) & (l2 >= -eps) & (l3 >= -eps)
        out_e.append(e[ins] + b)
        out_p.append(j[ins] * nx + i[ins])
    if not out_e:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(out_e), np.concatenate(out_p)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def element_pixel_delta(field: ImageField, points: np.ndarray, triangles: np.ndarray,
                        vertex_composition: np.ndarray | None = None) -> np.ndarray:
    """delta(T) ``(M,)`` over every pixel centre each element covers *and* its vertices.

    The values at the pixel centres are the field's samples there (``field.samples``, the
    mapped and smoothed pixels); an element that covers no pixel centre is judged by its
    vertices alone (vertex interpolation complements the pixel sampling). delta is the
    largest spread (max - min) of a constituent's fraction over those samples.
    """
    P = np.asarray(points, float)
    T = np.asarray(triangles, np.int64)
    vc = field.composition(P) if vertex_composition is None else vertex_composition
    corners = vc[T]  # (M, 3, m)
    hi, lo = corners.max(axis=1), corners.min(axis=1)
    e, pix = pixel_centres_in_triangles(P, T, field.origin - field._offset, field.spacing,
                                        field.shape)
    if len(e):
        vals = field.samples.reshape(len(field.constituents), -1)[:, pix].T  # (K, m)
        np.maximum.at(hi, e, vals)
        np.minimum.at(lo, e, vals)
    return (hi - lo).max(axis=1)
