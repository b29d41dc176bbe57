"""Graded material sizes: the placement's element size grows by at most ``grade`` per unit
length, as a geometric mesher's size field does.

The material asks for elements of size h(x) = delta' / |grad f(x)| (Eqs. 4, 7), capped at
``h_max``. Where |grad f| falls from large to nearly zero over a short distance (the flank
and the top of a narrow Gaussian bump, a steep front in a flat plate) that size jumps by
one or two orders of magnitude within a few elements. The CVT then puts triangles of size
``h_max`` next to triangles a hundred times smaller; the quality refinement (Ruppert's
insertions to the angle floor) has to grade them afterwards, one ring of off-centres per
round, and that costs more elements than grading the size field in the first place: on a
plate with two narrow bumps the repaired CVT mesh had 2.3 x the elements it had when its
delta was first below delta_0. Gmsh and MMG limit the size field's gradient (MMG's
``hgrad``); the Gmsh peer of :mod:`hetmesh.peers` is fed such a graded field.

:func:`material_grading` samples ``h0 = min(h_max, delta_0 / g)`` (``g`` the capped gradient
norm the placement uses) on a regular lattice over the domain's bounding box, limits its
growth to ``grade`` per unit length in the L1 distance, ``h(x) = min_y h0(y) + grade |x -
y|_1`` (exact on the lattice, two running minima per axis), and returns the floor
``delta_0 / h`` it puts on the gradient norm, interpolated bilinearly. The floor only makes
elements smaller where a much smaller element is near; delta is not affected by it (the
delta-driven refinement evaluates f itself).
"""

from __future__ import annotations

import numpy as np

__all__ = ["GradientFloor", "material_grading", "graded", "CELLS"]

#: lattice cells along the longer side of the bounding box
CELLS = 256


class GradientFloor:
    """``delta_0 / h(x)``, the graded size ``h`` given at the nodes of a regular lattice
    (``origin``, ``step``), interpolated bilinearly; constant beyond the lattice."""

    def __init__(self, origin, step: float, sizes: np.ndarray, threshold: float):
        self.origin = np.asarray(origin, float)
        self.step = float(step)
        self.sizes = np.asarray(sizes, float)  # (ny, nx)
        self.threshold = float(threshold)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, float).reshape(-1, 2)
        ny, nx = self.sizes.shape
        u = np.nan_to_num((p - self.origin) / self.step)
        i = np.clip(np.floor(u[:, 0]), 0, nx - 2).astype(np.int64)
        j = np.clip(np.floor(u[:, 1]), 0, ny - 2).astype(np.int64)
        s = np.clip(u[:, 0] - i, 0.0, 1.0)
        t = np.clip(u[:, 1] - j, 0.0, 1.0)
        H = self.sizes
        h = ((1 - s) * (1 - t) * H[j, i] + s * (1 - t) * H[j, i + 1]
             + (1 - s) * t * H[j + 1, i] + s * t * H[j + 1, i + 1])
        return self.threshold / h


def graded(H: np.ndarray, step: float, grade: float) -> np.ndarray:
    """``min_y H(y) + grade |x - y|_1`` over the lattice: one pass per axis, each the
    smaller of a forward and a backward running minimum of ``H -+ grade x``.

    >>> graded(np.array([[1.0, 1.0, 0.1, 1.0]]), 1.0, 0.3).round(3).tolist()
    [[0.7, 0.4, 0.1, 0.4]]
    """
    for axis in (1, 0):
        n = H.shape[axis]
        ramp = grade * step * np.arange(n, dtype=float)
        ramp = ramp[None, :] if axis == 1 else ramp[:, None]
        fwd = np.minimum.accumulate(H - ramp, axis=axis) + ramp
        bwd = np.flip(np.minimum.accumulate(np.flip(H + ramp, axis=axis), axis=axis),
                      axis=axis) - ramp
        H = np.minimum(fwd, bwd)
    return H


def material_grading(g, inside, bounds, threshold: float, h_max: float, grade: float, *,
                     cells: int = CELLS) -> GradientFloor:
    """The :class:`GradientFloor` of the gradient norm ``g`` (``(N, 2) -> (N,)``, already
    capped) over ``bounds`` ``(x0, y0, x1, y1)``: sizes ``min(h_max, delta_0 / g)`` at the
    lattice nodes (``cells`` cells along the longer side, one more node each way) where
    ``inside`` (``(N, 2) -> (N,)`` bool) holds, ``h_max`` at the others (the field need not
    be defined outside the domain), graded by ``grade`` per unit length (see the module
    docstring).

    >>> fl = material_grading(lambda p: np.where(p[:, 0] < 0.1, 10.0, 0.0),
    ...                       lambda p: np.ones(len(p), bool), (0, 0, 1, 1), 0.1, 0.5, 0.3,
    ...                       cells=10)
    >>> fl(np.array([[0.05, 0.5], [0.55, 0.5], [0.95, 0.5]])).round(3).tolist()
    [4.0, 0.571, 0.339]
    """
    x0, y0, x1, y1 = (float(v) for v in bounds)
    step = max(x1 - x0, y1 - y0) / cells
    nx = max(int(np.ceil((x1 - x0) / step)), 1) + 1
    ny = max(int(np.ceil((y1 - y0) / step)), 1) + 1
    X, Y = np.meshgrid(x0 + step * np.arange(nx), y0 + step * np.arange(ny))
    pts = np.column_stack([X.ravel(), Y.ravel()])
    h0 = np.full(len(pts), float(h_max))
    ins = np.asarray(inside(pts), bool)
    if ins.any():
        gv = np.asarray(g(pts[ins]), float)
        with np.errstate(divide="ignore", invalid="ignore"):
            h = threshold / gv
        h0[ins] = np.minimum(np.nan_to_num(h, nan=h_max, posinf=h_max), h_max)
    h0 = h0.reshape(ny, nx)
    return GradientFloor((x0, y0), step, graded(h0, step, grade), threshold)
