"""The uniform baseline (the paper's comparison meshes, Tables 1, 3, 5).

``uniform`` finds the coarsest quality mesh of one element size h that meets
delta_max < delta_0: boundary curves split into pieces of length ~h, interior nodes on a
hexagonal lattice of spacing h, a few unweighted Lloyd steps (rho = 1), quality refinement,
then a search over h (expanding, then bisecting on log h).
"""

from __future__ import annotations

import logging
import time

import numpy as np

from ..density import background_points, gradient_norm
from ..errors import BudgetError
from ..kernel import Result
from ..options import DEFAULT_MAX_ELEMENTS, check_options
from .discontinuity import embed_discontinuities
from .finish import CHORD_TOL, finish
from .geometry import build_pslg
from .pipeline import prepare
from .refine import evaluate, repair
from .workset import Context, add_free_points, smooth, triangulate, workset_from_pslg

__all__ = ["uniform", "uniform_at"]

log = logging.getLogger(__name__)


class _UniformContext(Context):
    def rho(self, pts):  # constant density: a uniform CVT
        return np.ones(len(pts))


def _uniform_ctx(ctx: Context) -> _UniformContext:
    return _UniformContext(**{k: getattr(ctx, k) for k in ctx.__dataclass_fields__})


def uniform_at(ctx: Context, h: float, *, min_angle_deg=30.0, min_quality=0.6,
               max_elements=DEFAULT_MAX_ELEMENTS):
    """A quality mesh with edges ~h everywhere; returns ``(workset, triangles)``."""
    uc = _uniform_ctx(ctx)
    tol = ctx.chord_tol if ctx.chord_tol is not None else CHORD_TOL * ctx.domain.diameter
    ws = workset_from_pslg(build_pslg(ctx.domain, h, tol))
    x0, y0, x1, y1 = ctx.domain.bounds
    dy = h * np.sqrt(3) / 2
    ny = int(np.ceil((y1 - y0) / dy)) + 1
    nx = int(np.ceil((x1 - x0) / h)) + 2
    est = (nx * ny)
    if est > 4 * max_elements:
        raise BudgetError(f"a uniform mesh of size {h:.3g} needs ~{2 * est:,} elements, above the "
                          f"budget of {max_elements:,}")
    row, col = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    X = x0 + col * h + (row % 2) * 0.5 * h
    Y = y0 + row * dy
    pts = np.column_stack([X.ravel(), Y.ravel()])
    pts = pts[ctx.domain.contains(pts)]
    if len(pts):
        pts = pts[ctx.domain.distance_to_boundary(pts) > 0.5 * h]
    add_free_points(ws, pts)
    tris = triangulate(ws, uc)
    smooth(ws, uc, tris, iters=3)
    tris, _, _ = repair(ws, uc, min_angle_deg=min_angle_deg, min_quality=min_quality,
                        sampling="vertices", max_elements=max_elements, history=[],
                        check_delta=False)
    return ws, tris


def uniform(model, threshold: float, *, min_angle: float = 30.0,
            max_elements: int = DEFAULT_MAX_ELEMENTS, sampling: str = "vertices",
            min_quality: float = 0.6, chord_tol: float = CHORD_TOL, tries: int = 14,
            progress=None) -> Result:
    """The coarsest uniform quality mesh with delta_max < ``threshold`` (the paper's baseline).

    ``chord_tol`` is the largest distance between a curved boundary or interface and its
    chords, relative to the domain's diameter (as for :func:`hetmesh.generate`); the other
    options as there.

    Examples
    --------
    >>> r = hetmesh.uniform(model, 0.05)   # doctest: +SKIP
    >>> r.stats.delta_max < 0.05           # doctest: +SKIP
    True
    """
    threshold = check_options(threshold, min_angle=min_angle, max_elements=max_elements,
                              sampling=sampling, min_quality=min_quality, chord_tol=chord_tol)
    t0 = time.perf_counter()
    model = embed_discontinuities(model)
    ctx, frame = prepare(model, threshold, None, chord_tol, gradation=0.0)
    pts = background_points(ctx.domain, 200)
    gmax = float(gradient_norm(ctx.field, pts).max()) if len(pts) else 0.0
    h = threshold / gmax if gmax > 0 else ctx.domain.diameter / 10
    h = min(h, ctx.domain.diameter / 4)
    best = None
    h_pass, h_fail = None, None
    history = []
    for i in range(tries):
        ws, tris = uniform_at(ctx, h, min_angle_deg=min_angle, min_quality=min_quality,
                              max_elements=max_elements)
        comp, delta = evaluate(ctx, ws, tris, sampling)
        ok = delta.max() < threshold
        history.append({"round": i, "h": h * frame.scale, "elements": int(len(tris)),
                        "delta_max": float(delta.max()), "pass": bool(ok)})
        if progress:
            progress("uniform", (i + 1) / tries)
        if ok:
            if best is None or len(tris) < len(best[1]):
                best = (ws, tris, comp, delta, h)
            h_pass = h if h_pass is None else max(h_pass, h)
        else:
            h_fail = h if h_fail is None else min(h_fail, h)
        if h_pass is None:
            h *= 0.8
        elif h_fail is None:
            h *= 1.25
        else:
            if h_fail / h_pass < 1.02:
                break
            h = np.sqrt(h_pass * h_fail)
    if best is None:
        raise BudgetError(f"no uniform mesh met delta_max < {threshold:g} within {tries} tries")
    ws, tris, comp, delta, h = best
    mesh, stats = finish(ws, ctx, tris, comp, delta, frame, threshold=threshold,
                         min_angle_deg=min_angle)
    return Result(mesh=mesh, stats=stats, threshold=threshold, history=history,
                  timings={"total": time.perf_counter() - t0},
                  options=dict(threshold=threshold, size=h * frame.scale, min_angle=min_angle,
                               sampling=sampling, max_elements=max_elements,
                               chord_tol=float(chord_tol)), model=model)
