"""A cap on |grad f| from the composition's actual variation, for fields whose gradient blows
up where the composition itself stays bounded.

The size field of the placement is h = delta' / |grad f| (Eqs. 4, 7). That is right where f
is smooth on the scale of h, and far too pessimistic next to a point or an edge where the
gradient is singular: f = sqrt(x) (a power-law FGM profile with exponent 1/2) has
|grad f| -> inf at x = 0 but varies by only sqrt(h) over an element of width h there, so an
element of width about delta_0^2 at the edge is homogeneous enough; sized by its gradient
alone, the edge gets elements 1e-4 of the domain or smaller (infinitely small on the edge
itself), and the jump to the sizes a short way inside leaves slivers that the quality
refinement can only cascade on.

:func:`variation_cap` samples f on a regular lattice over the domain's bounding box (cell
corners and centres), builds a pyramid of the composition's range over blocks of 1, 2, 4,
... cells, and finds for every cell the largest block size ``b`` whose range, over the
block holding the cell and its eight neighbouring blocks, stays below delta_0. Those nine
blocks hold the square of side ``h_var = 2 b`` centred anywhere in the cell's block, so f
varies by less than delta_0 over a width ``h_var`` around the cell: the size the smooth
rule gives (a linear f varies by delta_0 over the width delta_0 / |grad f|). The gradient
used for sizes and densities is capped at delta_0 / h_var there. For a smooth field that cap
is at least 1.5 times |grad f| (a range below delta_0 over three blocks means
|grad f| < delta_0 / (3 b)), so it never changes its sizes; where the gradient is
singular it bounds them by what the composition really does on that scale. The delta-driven
refinement, which evaluates f itself and not the cap, has the last word either way.

The size was the block's side ``b`` until the robustness benchmark's S-FGM models with
p < 1 showed it to be twice as fine as needed next to their singular edges: with ``2 b``,
random-0038-sfgm at 0.13 has 356 elements instead of 509 (Gmsh's delta-valid mesh: 394),
random-0017-sfgm at 0.19 161 instead of 159 (of q_avg 0.958 instead of 0.929).
"""

from __future__ import annotations

import numpy as np

__all__ = ["VariationCap", "variation_cap"]

#: lattice cells along the longer side of the bounding box
CELLS = 256
#: ``h_var`` over the side of the quiet blocks: their 3 x 3 neighbourhood holds a square of
#: twice that side centred on the cell's block
WIDTH = 2.0


class VariationCap:
    """Per-cell caps of |grad f| on a regular lattice (see the module docstring)."""

    def __init__(self, origin: np.ndarray, cell: float, caps: np.ndarray):
        self.origin = np.asarray(origin, float)
        self.cell = float(cell)
        self.caps = caps  # (ny, nx)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """The cap at ``points`` ``(N, 2)`` (the nearest cell's outside the lattice)."""
        p = np.asarray(points, float)
        ny, nx = self.caps.shape
        ij = np.floor((p - self.origin) / self.cell)
        ok = np.isfinite(ij).all(axis=1)
        i = np.clip(np.nan_to_num(ij[:, 0]), 0, nx - 1).astype(np.int64)
        j = np.clip(np.nan_to_num(ij[:, 1]), 0, ny - 1).astype(np.int64)
        return np.where(ok, self.caps[j, i], np.inf)


def _cell_ranges(f, x0: float, y0: float, cell: float, nx: int, ny: int):
    """(lo, hi) of f over each cell's corners and centre, ``(ny, nx)`` each; the largest
    range over the columns of a multi-constituent f counts; non-finite values are left out
    (lo = inf, hi = -inf where none is finite)."""
    xs = x0 + cell * np.arange(nx + 1)
    ys = y0 + cell * np.arange(ny + 1)
    X, Y = np.meshgrid(xs, ys)
    Xc, Yc = np.meshgrid(xs[:-1] + 0.5 * cell, ys[:-1] + 0.5 * cell)
    pts = np.vstack([np.column_stack([X.ravel(), Y.ravel()]),
                     np.column_stack([Xc.ravel(), Yc.ravel()])])
    with np.errstate(all="ignore"):
        v = np.asarray(f(pts), float)
    v = v.reshape(len(pts), -1)
    nc = (ny + 1) * (nx + 1)
    corner = v[:nc].reshape(ny + 1, nx + 1, -1)
    centre = v[nc:].reshape(ny, nx, -1)
    samples = np.stack([corner[:-1, :-1], corner[:-1, 1:], corner[1:, :-1], corner[1:, 1:],
                        centre])  # (5, ny, nx, m)
    fin = np.isfinite(samples)
    return (np.where(fin, samples, np.inf).min(axis=0),
            np.where(fin, samples, -np.inf).max(axis=0))


def _coarsen(a: np.ndarray, op) -> np.ndarray:
    """2 x 2 blocks of ``a`` (ny, nx, m) reduced by ``op`` (odd sizes padded by edge values)."""
    ny, nx = a.shape[:2]
    a = np.pad(a, ((0, ny % 2), (0, nx % 2), (0, 0)), mode="edge")
    return op(op(a[0::2, 0::2], a[0::2, 1::2]), op(a[1::2, 0::2], a[1::2, 1::2]))


def _with_neighbours(a: np.ndarray, op, fill: float) -> np.ndarray:
    """``op`` over each block and its eight neighbours."""
    ny, nx = a.shape[:2]
    pad = np.pad(a, ((1, 1), (1, 1), (0, 0)), constant_values=fill)
    out = a.copy()
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            out = op(out, pad[1 + dj:ny + 1 + dj, 1 + di:nx + 1 + di])
    return out


def variation_cap(f, bounds, threshold: float, *, cells: int = CELLS) -> VariationCap:
    """The :class:`VariationCap` of the field ``f`` (``(N, 2) -> (N,)`` or ``(N, m)``) over
    ``bounds`` ``(x0, y0, x1, y1)`` for the threshold delta_0: per lattice cell,
    delta_0 / h_var, ``h_var`` twice the side of the quiet blocks (see the module
    docstring); inf where even one cell's neighbourhood
    varies by delta_0 or more (no cap: the gradient decides).

    >>> cap = variation_cap(lambda p: np.sqrt(np.clip(p[:, 0], 0, None)), (0, 0, 1, 1), 0.1)
    >>> c = cap(np.array([[0.0, 0.5], [0.5, 0.5]]))
    >>> bool(c[0] < 25), bool(c[1] > 1.5 * 0.5 / np.sqrt(0.5))
    (True, True)
    """
    x0, y0, x1, y1 = (float(v) for v in bounds)
    w, h = x1 - x0, y1 - y0
    cell = max(w, h) / cells
    nx, ny = max(int(np.ceil(w / cell)), 1), max(int(np.ceil(h / cell)), 1)
    lo, hi = _cell_ranges(f, x0, y0, cell, nx, ny)
    h_var = np.zeros((ny, nx))
    size = cell
    for level in range(64):
        nlo = _with_neighbours(lo, np.minimum, np.inf)
        nhi = _with_neighbours(hi, np.maximum, -np.inf)
        rng = (nhi - nlo).max(axis=-1)
        quiet = ~(rng >= threshold)  # also where nothing was finite (nan)
        # back to the finest cells: block (j, i) at this level covers cells (j, i) * 2**level
        fine = np.repeat(np.repeat(quiet, 2 ** level, axis=0), 2 ** level, axis=1)[:ny, :nx]
        if level > 0 and not fine.any():
            break
        # the neighbourhoods nest, so a block quiet at this level is quiet at every finer one
        h_var = np.where(fine, WIDTH * size, h_var)
        if lo.shape[0] == 1 and lo.shape[1] == 1:
            break
        lo, hi = _coarsen(lo, np.minimum), _coarsen(hi, np.maximum)
        size *= 2
    with np.errstate(divide="ignore"):
        caps = np.where(h_var > 0, threshold / h_var, np.inf)
    return VariationCap(np.array([x0, y0]), cell, caps)
