"""Pixel sampling: delta(T) over every pixel centre an element covers, complemented by its
vertices (an element may cover no pixel centre at all). Triangles over a 2D image, and
tetrahedra over a 3D volume (voxel centres, :func:`voxel_centres_in_tets`)."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from ...topology import unique

__all__ = ["pixel_centres_in_triangles", "pixel_blocks", "voxel_centres_in_tets",
           "voxel_blocks", "element_pixel_delta"]


class PixelImage(Protocol):
    """What :func:`element_pixel_delta` reads of an image field
    (:class:`~hetmesh.material.image.ImageField` is one)."""

    constituents: tuple[str, ...]
    samples: np.ndarray  #: ``(m, ny, nx)`` / ``(m, nz, ny, nx)`` the field at the centres
    spacing: np.ndarray
    shape: tuple[int, ...]

    @property
    def local_origin(self) -> np.ndarray: ...

    def composition(self, points) -> np.ndarray: ...


# ---------------------------------------------------------------------- pixel sampling
def pixel_centres_in_triangles(points: np.ndarray, triangles: np.ndarray, origin,
                               spacing, shape, *, block: int = 1 << 19):
    """The pixel centres each triangle covers.

    Parameters
    ----------
    points : ``(N, 2)``; triangles : ``(M, 3)``
    origin, spacing : ``(2,)`` centre of the first pixel and pixel size, x first
    shape : ``(ny, nx)``
    block : int
        About how many candidate centres (bounding-box pixels) to test at once.

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
    parts = list(pixel_blocks(points, triangles, origin, spacing, shape, block=block))
    if not parts:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate([e for e, _ in parts]), np.concatenate([p for _, p in parts])


def pixel_blocks(points, triangles, origin, spacing, shape, *, block: int = 1 << 19):
    """:func:`pixel_centres_in_triangles` by blocks of triangles: yields ``(element,
    pixel)`` pairs, each block testing about ``block`` candidate centres (a triangle whose
    bounding box alone holds more is a block of its own), elements ascending overall."""
    P = np.asarray(points, float)
    T = np.asarray(triangles, np.int64)
    o, s = np.asarray(origin, float), np.asarray(spacing, float)
    ny, nx = (int(v) for v in shape)
    u_all = (P - o) / s  # index units
    lo = np.full((len(T), 2), 0, np.int64)
    hi = np.full((len(T), 2), -1, np.int64)
    for b in range(0, len(T), 1 << 16):  # bounding boxes in pixel indices
        u = u_all[T[b:b + (1 << 16)]]
        lo[b:b + (1 << 16)] = np.maximum(np.ceil(u.min(axis=1) - 1e-9), 0)
        hi[b:b + (1 << 16)] = np.minimum(np.floor(u.max(axis=1) + 1e-9), [nx - 1, ny - 1])
    cnt = np.maximum(hi - lo + 1, 0)
    tot = cnt[:, 0] * cnt[:, 1]
    ends = np.searchsorted(np.cumsum(tot), np.arange(1, 1 + tot.sum() // block + 1) * block,
                           side="right")
    bounds = unique(np.r_[0, np.maximum(ends, 1), len(T)].clip(0, len(T)))
    for b0, b1 in zip(bounds[:-1], bounds[1:]):
        if not tot[b0:b1].sum():
            continue
        # scanlines: every (element, pixel row) pair, the element's x-interval on that row
        rows = cnt[b0:b1, 1]
        er = np.repeat(np.arange(b0, b1), rows)
        jr = lo[er, 1] + np.arange(len(er)) - np.repeat(np.cumsum(rows) - rows, rows)
        xl, xr = _row_span(u_all[T[er]], jr.astype(float))
        empty = ~(xl <= xr)
        xl[empty], xr[empty] = 1.0, 0.0
        i0 = np.maximum(np.ceil(xl - _EPS), 0).astype(np.int64)
        n = np.maximum(np.minimum(np.floor(xr + _EPS), nx - 1).astype(np.int64) - i0 + 1, 0)
        e = np.repeat(er, n)
        i = np.repeat(i0, n) + np.arange(len(e)) - np.repeat(np.cumsum(n) - n, n)
        yield e, np.repeat(jr, n) * nx + i


#: how far (in pixels) a pixel centre may lie outside a triangle and still count as covered
_EPS = 1e-9


def _row_span(u: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The x-interval ``[xl, xr]`` of the closed triangles ``u (R, 3, 2)`` on the lines
    ``y (R,)`` (empty, ``xl > xr``, where a line misses its triangle by more than
    :data:`_EPS`)."""
    xl = np.full(len(y), np.inf)
    xr = np.full(len(y), -np.inf)
    for k in range(3):
        a, b = u[:, k], u[:, (k + 1) % 3]
        ya, yb = a[:, 1], b[:, 1]
        hit = (np.minimum(ya, yb) - _EPS <= y) & (y <= np.maximum(ya, yb) + _EPS)
        dy = yb - ya
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.clip(np.where(dy != 0, (y - ya) / dy, 0.0), 0.0, 1.0)
        x = a[:, 0] + t * (b[:, 0] - a[:, 0])
        flat = dy == 0  # a horizontal edge on the line: both ends
        xlo = np.where(flat, np.minimum(a[:, 0], b[:, 0]), x)
        xhi = np.where(flat, np.maximum(a[:, 0], b[:, 0]), x)
        xl = np.where(hit, np.minimum(xl, xlo), xl)
        xr = np.where(hit, np.maximum(xr, xhi), xr)
    return xl, xr


# ---------------------------------------------------------------------- voxel sampling
def voxel_centres_in_tets(points: np.ndarray, tets: np.ndarray, origin, spacing, shape, *,
                          block: int = 1 << 19):
    """The voxel centres each tetrahedron covers.

    Parameters
    ----------
    points : ``(N, 3)``; tets : ``(M, 4)``
    origin, spacing : ``(3,)`` centre of the first voxel and voxel size, x first
    shape : ``(nz, ny, nx)``
    block : int
        About how many candidate centres (bounding-box voxels) to test at once.

    Returns
    -------
    element : ``(K,)`` int64
        The tetrahedron of each (tetrahedron, voxel) pair, ascending.
    voxel : ``(K,)`` int64
        The flat index ``(k * ny + j) * nx + i`` of the voxel centre (closed tetrahedra: a
        centre on a shared face counts for each).

    Examples
    --------
    >>> p = np.array([[0., 0, 0], [3, 0, 0], [0, 3, 0], [0, 0, 3]])
    >>> e, v = voxel_centres_in_tets(p, np.array([[0, 1, 2, 3]]), (0.5, 0.5, 0.5),
    ...                              (1, 1, 1), (3, 3, 3))
    >>> v.tolist()  # the centres with x + y + z <= 3: (0.5, 0.5, 0.5), (1.5, ...), ...
    [0, 1, 3, 9]
    """
    parts = list(voxel_blocks(points, tets, origin, spacing, shape, block=block))
    if not parts:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate([e for e, _ in parts]), np.concatenate([v for _, v in parts])


def _barycentric_maps(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For tetrahedra ``u (B, 4, 3)``: ``(inv (B, 3, 3), shift (B, 3), ok (B,))`` with the
    barycentric coordinates 1..3 of a point ``q`` equal to ``inv @ q - shift`` (coordinate 0
    is 1 minus their sum); ``ok`` False for flat tetrahedra."""
    a = np.stack([u[:, 1] - u[:, 0], u[:, 2] - u[:, 0], u[:, 3] - u[:, 0]], axis=2)
    c0 = np.cross(a[:, :, 1], a[:, :, 2])
    c1 = np.cross(a[:, :, 2], a[:, :, 0])
    c2 = np.cross(a[:, :, 0], a[:, :, 1])
    det = np.einsum("ij,ij->i", a[:, :, 0], c0)
    scale = np.abs(a).max(axis=(1, 2)) ** 3
    ok = np.abs(det) > 1e-14 * scale
    d = np.where(ok, det, 1.0)
    inv = np.stack([c0, c1, c2], axis=1) / d[:, None, None]  # rows: the adjugate / det
    shift = np.einsum("bij,bj->bi", inv, u[:, 0])
    return inv, shift, ok


def voxel_blocks(points, tets, origin, spacing, shape, *, block: int = 1 << 19):
    """:func:`voxel_centres_in_tets` by blocks of tetrahedra: yields ``(element, voxel)``
    pairs, each block testing about ``block`` candidate centres, elements ascending overall.

    Scanlines: for every voxel row ``(j, k)`` that crosses a tetrahedron's bounding box, the
    barycentric coordinates are affine in ``i``, so the row's centres inside the (closed)
    tetrahedron form one interval, found from its four coordinates at once.
    """
    P = np.asarray(points, float)
    T = np.asarray(tets, np.int64)
    o, s = np.asarray(origin, float), np.asarray(spacing, float)
    nz, ny, nx = (int(v) for v in shape)
    top = np.array([nx - 1, ny - 1, nz - 1])
    u_all = (P - o) / s  # index units
    lo = np.zeros((len(T), 3), np.int64)
    hi = np.full((len(T), 3), -1, np.int64)
    for b in range(0, len(T), 1 << 16):
        u = u_all[T[b:b + (1 << 16)]]
        lo[b:b + (1 << 16)] = np.maximum(np.ceil(u.min(axis=1) - _EPS), 0)
        hi[b:b + (1 << 16)] = np.minimum(np.floor(u.max(axis=1) + _EPS), top)
    cnt = np.maximum(hi - lo + 1, 0)
    tot = cnt[:, 0] * cnt[:, 1] * cnt[:, 2]
    ends = np.searchsorted(np.cumsum(tot), np.arange(1, 1 + tot.sum() // block + 1) * block,
                           side="right")
    bounds = unique(np.r_[0, np.maximum(ends, 1), len(T)].clip(0, len(T)))
    for b0, b1 in zip(bounds[:-1], bounds[1:]):
        if not tot[b0:b1].sum():
            continue
        inv, shift, ok = _barycentric_maps(u_all[T[b0:b1]])
        rows = np.where(ok, cnt[b0:b1, 1] * cnt[b0:b1, 2], 0)
        loc = np.repeat(np.arange(b1 - b0), rows)
        er = loc + b0
        r = np.arange(len(er)) - np.repeat(np.cumsum(rows) - rows, rows)
        jr = lo[er, 1] + r % cnt[er, 1]
        kr = lo[er, 2] + r // cnt[er, 1]
        # barycentric coordinates along the row: lam = a + b i (coordinate 0: 1 - the rest)
        m = inv[loc]
        a = m[:, :, 1] * jr[:, None] + m[:, :, 2] * kr[:, None] - shift[loc]
        b = m[:, :, 0]
        a = np.column_stack([1.0 - a.sum(axis=1), a])
        b = np.column_stack([-b.sum(axis=1), b])
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = (-_EPS - a) / b
        xl = np.where(b > 0, bound, -np.inf).max(axis=1)
        xr = np.where(b < 0, bound, np.inf).min(axis=1)
        missed = ((b == 0) & (a < -_EPS)).any(axis=1)
        xl = np.maximum(xl, lo[er, 0])
        xr = np.minimum(xr, hi[er, 0])
        # an empty row: missed, or bounds past each other (an infinite bound where a
        # coordinate barely changes along the row)
        empty = missed | ~(xl <= xr)
        xl, xr = np.where(empty, 0.0, xl), np.where(empty, -1.0, xr)
        i0 = np.ceil(xl).astype(np.int64)
        n = np.maximum(np.floor(xr).astype(np.int64) - i0 + 1, 0)
        e = np.repeat(er, n)
        i = np.repeat(i0, n) + np.arange(len(e)) - np.repeat(np.cumsum(n) - n, n)
        yield e, (np.repeat(kr, n) * ny + np.repeat(jr, n)) * nx + i


def element_pixel_delta(field: PixelImage, points: np.ndarray, triangles: np.ndarray,
                        vertex_composition: np.ndarray | None = None) -> np.ndarray:
    """delta(T) ``(M,)`` over every pixel centre each element covers *and* its vertices:
    triangles ``(M, 3)`` over a 2D image, or tetrahedra ``(M, 4)`` over the voxel centres
    of a 3D volume.

    The values at the pixel centres are the field's samples there (``field.samples``, the
    mapped and smoothed pixels); an element that covers no pixel centre is judged by its
    vertices alone (vertex interpolation complements the pixel sampling). delta is the
    largest spread (max - min) of a constituent's fraction over those samples. Works by
    blocks (:func:`pixel_blocks`), so memory stays bounded on large images.
    """
    P = np.asarray(points, float)
    T = np.asarray(triangles, np.int64)
    vc = field.composition(P) if vertex_composition is None else vertex_composition
    corners = vc[T]  # (M, 3, m)
    hi, lo = corners.max(axis=1), corners.min(axis=1)
    flat = field.samples.reshape(len(field.constituents), -1)
    blocks = voxel_blocks if T.shape[1] == 4 else pixel_blocks
    for e, pix in blocks(P, T, field.local_origin, field.spacing, field.shape):
        if not len(e):
            continue
        vals = flat[:, pix].T  # (K, m)
        first = np.flatnonzero(np.r_[True, e[1:] != e[:-1]])
        el = e[first]
        hi[el] = np.maximum(hi[el], np.maximum.reduceat(vals, first, axis=0))
        lo[el] = np.minimum(lo[el], np.minimum.reduceat(vals, first, axis=0))
    return (hi - lo).max(axis=1)
