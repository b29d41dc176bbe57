"""The node step along a row: 2 w / sqrt(3), w = delta' / |grad f| the row distance.

With g = |grad f| (the paper, Eq. 5) two rows delta' apart in f lie w = delta' / g apart, and
nodes 2 w / sqrt(3) apart along them make equilateral triangles of height w between the
rows: every triangle spans delta' of f, g h the same everywhere as the paper's Eq. 7 asks of
the density-weighted placement. The step is clipped to the context's size bounds (h_min, the
local maximum size ``Context.h_at``) and uses the gradient capped by ``Context.cap_at``.
"""

from __future__ import annotations

import numpy as np

from ...parallel import BLOCK, block_concat
from ..workset import Context

#: a node projected onto its level is kept if |f - level| <= LEVEL_TOL x the row spacing in f
LEVEL_TOL = 0.05


def row_step(ctx: Context, gnorm: np.ndarray, dprime, h_cap=None) -> np.ndarray:
    """Node spacing along a row, 2 w / sqrt(3) with w = ``dprime`` / ``gnorm``, between h_min and
    ``h_cap`` (default h_max; where |grad f| is infinite, nan or zero too)."""
    h_cap = ctx.h_max if h_cap is None else h_cap
    with np.errstate(divide="ignore", invalid="ignore"):
        s = 2.0 * dprime / (np.sqrt(3.0) * gnorm)
    s = np.nan_to_num(s, nan=ctx.h_max, posinf=ctx.h_max)
    return np.clip(s, ctx.h_min, h_cap)


def row_step_at(ctx: Context, pts: np.ndarray, dprime, grad: np.ndarray | None = None
                ) -> np.ndarray:
    """:func:`row_step` at ``pts`` (``grad``: grad f there, if known), for the gradient
    capped by the context (:meth:`Context.cap_at`); pointwise, so by blocks of points."""
    if len(pts) > BLOCK:
        dp = np.broadcast_to(dprime, (len(pts),))
        return block_concat(lambda s: row_step_at(ctx, pts[s], dp[s],
                                                  None if grad is None else grad[s]),
                            len(pts), serial=ctx.serial)
    gr = ctx.grad_f(pts) if grad is None else grad
    gn = np.minimum(np.nan_to_num(np.linalg.norm(gr, axis=1), nan=np.inf), ctx.cap_at(pts))
    return row_step(ctx, gn, dprime, ctx.h_at(pts))
