"""The material field interface and its validation.

A material field maps points ``(N, d)`` (d = 2 or 3, its ``dim``) to compositions ``(N, m)``
(volume fractions of the ``m`` constituents, rows summing to 1) and their gradients
``(N, m, d)``. Any object with ``constituents``, ``composition`` and ``gradient`` is a field
(duck typing; see :class:`MaterialField`; without a ``dim`` it is a 2D field). A field with
subregions (a feature tree, formulas with jumps) is a :class:`PiecewiseField`.
:func:`check_field` samples a field densely over a domain and raises
:class:`~hetmesh.errors.MaterialError` naming the constituent and a coordinate where it is
not a valid composition.
"""

from __future__ import annotations

import logging
from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import MaterialError

__all__ = ["MaterialField", "PiecewiseField", "field_dim", "has_subregions", "thread_safe",
           "element_subregions", "check_field", "sample_domain", "as_points", "TOLERANCE", "JUMP",
           "JUMP_REACH"]

logger = logging.getLogger(__name__)

#: Tolerance of :func:`check_field` on the range [0, 1] and on the row sums.
TOLERANCE = 1e-9
#: :func:`check_field` reports a jump where a fraction spreads by more than this within
#: ``JUMP_REACH`` x the domain's diameter of a point on one of its curves.
JUMP = 0.5
JUMP_REACH = 1e-9


@runtime_checkable
class MaterialField(Protocol):
    """What the mesher needs from a material: compositions and their gradients.

    Fields may accept an optional ``region`` keyword (an ``(N,)`` array of region ids or
    ``None``) in both methods; piecewise (feature-tree) fields use it to evaluate each point
    for the subregion that owns it, smooth fields ignore it.

    Attributes
    ----------
    constituents : tuple of str
        Names of the ``m`` constituents, in column order.
    dim : int
        The dimension ``d`` of the points (2 or 3; see :func:`field_dim` for fields
        without the attribute).

    Examples
    --------
    >>> from hetmesh.material import CallableField
    >>> f = CallableField(lambda x, y: y, ["ceramic", "metal"])
    >>> isinstance(f, MaterialField)
    True
    """

    constituents: tuple[str, ...]

    def composition(self, points: np.ndarray) -> np.ndarray:
        """Volume fractions ``(N, m)`` at ``points`` ``(N, d)``."""
        ...

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """Gradients ``(N, m, d)`` of the volume fractions (d/dx, d/dy[, d/dz] last)."""
        ...


@runtime_checkable
class PiecewiseField(MaterialField, Protocol):
    """A field smooth in each of several subregions and discontinuous between them
    (a feature tree, formulas with ``where``): what the mesher needs to keep every element
    inside one subregion.

    ``composition`` and ``gradient`` take ``region=`` ids ``(N,)`` to evaluate each point
    in a given subregion (continued past its boundary), ``region(points)`` gives the
    subregion that owns each point, ``n_regions`` bounds the ids and
    ``describe_jump(ra, rb)`` names, for error messages, what tells two subregions apart.

    >>> from hetmesh.material import AnalyticField
    >>> isinstance(AnalyticField({"metal": "where(x < 0.5, 0.2, 0.8)"},
    ...                          ["ceramic", "metal"]), PiecewiseField)
    True
    """

    n_regions: int

    def region(self, points: np.ndarray) -> np.ndarray:
        """The subregion id ``(N,)`` of each point."""
        ...

    def describe_jump(self, ra: int, rb: int) -> str:
        """What tells subregions ``ra`` and ``rb`` apart, for messages."""
        ...


def as_points(points, where: str = "points", dim: int = 2) -> np.ndarray:
    """``points`` as a float64 ``(N, dim)`` array; a single ``(dim,)`` point becomes
    ``(1, dim)``."""
    p = np.asarray(points, dtype=float)
    if p.ndim == 1 and p.shape[0] == dim:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != dim:
        raise MaterialError(f"{where}: expected points of shape (N, {dim}), got shape {p.shape}")
    return p


def has_subregions(field) -> bool:
    """Whether ``field`` divides the domain into subregions (a feature tree with more than
    one, a formula field with jumps): a :class:`PiecewiseField` with ``n_regions > 1``."""
    return callable(getattr(field, "region", None)) and getattr(field, "n_regions", 1) > 1


def element_subregions(field, points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The subregion owning each element ``cells (M, d + 1)``: that of its centroid (no
    element straddles a discontinuity once they are embedded, so any interior point would
    do)."""
    return np.asarray(field.region(points[cells].mean(axis=1)), dtype=np.int64)


def thread_safe(field) -> bool:
    """Whether ``field`` may be evaluated from several threads at once: its ``thread_safe``
    attribute, False without one.

    A field sets it when its evaluations share no mutable state (the formula fields: each
    call works on arrays of its own). The mesher then evaluates large point sets by blocks
    in parallel threads (:mod:`hetmesh.parallel`); the values are those of the serial
    evaluation, since every point is evaluated alone. Fields that cache their last call, and
    user callables, are evaluated block after block in one thread."""
    return bool(getattr(field, "thread_safe", False))


def field_dim(field) -> int:
    """The dimension of the points ``field`` takes: its ``dim`` attribute, 2 without one
    (a duck-typed 2D field)."""
    return int(getattr(field, "dim", 2))


def _fmt(v: float) -> str:
    return f"{float(v):.6g}"


def _at(p: np.ndarray, scale: float = 1.0) -> str:
    """``(x, y)``, with rounding noise (below 1e-12 of ``scale``) shown as 0."""
    q = np.where(np.abs(p) < 1e-12 * scale, 0.0, p)
    return f"({_fmt(q[0])}, {_fmt(q[1])})"


def sample_domain(domain, n: int = 200) -> np.ndarray:
    """A deterministic dense sample ``(K, 2)`` of a domain.

    The nodes of an ``n`` x ``n`` grid over ``domain.bounds`` that ``domain.contains``, plus
    ``n + 1`` equally spaced points (by arc length) on every curve of the domain (outer
    boundary, holes, interfaces), plus its corners and named points.
    """
    grid, curves = _sample_parts(domain, n)
    return np.concatenate([grid, curves], axis=0)


def _sample_parts(domain, n: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sample_domain` in two parts: the grid points, the curve and named points."""
    x0, y0, x1, y1 = (float(v) for v in domain.bounds)
    xs = np.linspace(x0, x1, n)
    ys = np.linspace(y0, y1, n)
    gx, gy = np.meshgrid(xs, ys)
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    grid = grid[np.asarray(domain.contains(grid), dtype=bool)]
    parts = [np.zeros((0, 2))]
    t = np.linspace(0.0, 1.0, n + 1)
    for info in domain.curves:
        curve = getattr(info, "curve", info)
        parts.append(np.asarray(curve.point(t), dtype=float).reshape(-1, 2))
    corners = getattr(domain, "corners", None)
    if corners is not None and len(corners):
        parts.append(np.asarray(corners, dtype=float).reshape(-1, 2))
    named = getattr(domain, "points", None) or {}
    if named:
        parts.append(np.asarray(list(named.values()), dtype=float).reshape(-1, 2))
    return grid, np.concatenate(parts, axis=0)


def _prefix(where: str) -> str:
    return f"{where}: " if where else ""


def check_field(field, domain, where: str = "", n: int = 200) -> None:
    """Check that ``field`` is a valid composition everywhere on ``domain``.

    Evaluates the field on :func:`sample_domain` (``n`` x ``n`` grid plus curve points) and
    raises :class:`~hetmesh.errors.MaterialError` if a value is not finite, lies outside
    [0, 1] (tolerance 1e-9), a row does not sum to 1 (tolerance 1e-9), a gradient is not
    finite, or the arrays have the wrong shape. The message names the constituent, the value
    and a coordinate where it happens (the worst one), e.g.
    ``m.toml: material.composition.metal: value 1.44 at (0, -6) is outside [0, 1]``.

    A fraction whose values spread by more than :data:`JUMP` within ``JUMP_REACH`` x the
    diameter of a point on a curve of the domain (``x**1e308`` at ``x = 1``) is reported as
    a jump: a jump the mesh can follow must be written as a condition (``where``, ``sign``),
    which makes the field piecewise (see :mod:`hetmesh.tri.discontinuity`).

    Kinks and infinite slopes are not errors: the built-in fields
    (:class:`~hetmesh.material.AnalyticField`, :class:`~hetmesh.material.CallableField`, the
    feature trees) return finite gradients everywhere their composition is finite (finite
    differences where the exact derivative is undefined, as at the tip of
    ``sqrt(x**2 + y**2)`` or at ``x = 0`` for ``sqrt(x)``). The gradient check guards other
    fields, whose gradients the mesher needs finite.

    Parameters
    ----------
    field : MaterialField
    domain : Domain
        Needs ``bounds``, ``contains``, ``curves`` (``corners`` and ``points`` if present).
    where : str
        Prefix of error messages, normally the model file name.
    n : int
        Grid resolution per axis.

    Examples
    --------
    >>> from hetmesh.tri.geometry import Arc, Loop, make_domain
    >>> from hetmesh.material import AnalyticField
    >>> disk = make_domain(Loop((Arc.circle((0, 0), 2.0),), "outer"))
    >>> check_field(AnalyticField({"b": "x/2"}, ["a", "b"]), disk, "m")
    Traceback (most recent call last):
    ...
    hetmesh.errors.MaterialError: m: material.composition.b: value -1 at (-2, 0) is outside [0, 1]
    """
    pre = _prefix(where)
    names = tuple(field.constituents)
    m = len(names)
    grid, on_curves = _sample_parts(domain, n)
    pts = np.concatenate([grid, on_curves], axis=0)
    scale = float(np.abs(pts).max()) if len(pts) else 1.0
    with np.errstate(all="ignore"):
        comp = np.asarray(field.composition(pts), dtype=float)
        grad = np.asarray(field.gradient(pts), dtype=float)
    if comp.shape != (len(pts), m):
        raise MaterialError(f"{pre}material.composition: the field returned shape {comp.shape} "
                            f"for {len(pts)} points and {m} constituents, expected "
                            f"{(len(pts), m)}")
    if grad.shape != (len(pts), m, 2):
        raise MaterialError(f"{pre}material.composition: the field's gradient has shape "
                            f"{grad.shape}, expected {(len(pts), m, 2)}")
    # Constituents given explicitly are reported before one derived as 1 - the others.
    derived = getattr(field, "derived", None)
    order = [j for j in range(m) if names[j] != derived] + [j for j in range(m)
                                                               if names[j] == derived]
    for j in order:
        c = comp[:, j]
        key = f"{pre}material.composition.{names[j]}"
        bad = ~np.isfinite(c)
        if bad.any():
            i = int(np.argmax(bad))
            raise MaterialError(f"{key}: value {c[i]} at {_at(pts[i], scale)} is not finite")
        excess = np.maximum(c - 1.0, -c)
        i = int(np.argmax(excess))
        if excess[i] > TOLERANCE:
            raise MaterialError(f"{key}: value {_fmt(c[i])} at {_at(pts[i], scale)} is "
                                f"outside [0, 1]")
    total = comp.sum(axis=1)
    err = np.abs(total - 1.0)
    i = int(np.argmax(err))
    if err[i] > TOLERANCE:
        parts = ", ".join(f"{name} {_fmt(v)}" for name, v in zip(names, comp[i]))
        raise MaterialError(f"{pre}material.composition: fractions sum to {_fmt(total[i])}, "
                            f"not 1, at {_at(pts[i], scale)} ({parts})")
    for j in order:
        g = grad[:, j, :]
        bad = ~np.isfinite(g).all(axis=1)
        if bad.any():
            i = int(np.argmax(bad))
            what = "undefined (nan)" if np.isnan(g[i]).any() else "infinite"
            raise MaterialError(f"{pre}material.composition.{names[j]}: gradient is {what} "
                                f"at {_at(pts[i], scale)} (the field must return finite "
                                f"gradients where its composition is finite)")
    _check_curve_jumps(field, domain, on_curves, comp[len(grid):], names, order, pre, scale)
    logger.debug("%schecked %d constituents at %d points", pre, m, len(pts))


def _check_curve_jumps(field, domain, p, c, names, order, pre, scale) -> None:
    """A fraction jumping at a point of the domain's curves without a condition saying so.

    ``x**1e308`` on the unit square is 1 at ``x = 1`` and 0 a hair inside: no mesh can
    resolve that. Each sample ``p`` on a curve (and each corner and named point; values
    ``c``) is compared with the points ``JUMP_REACH`` x diameter away from it along the axes
    that lie inside the domain or on its boundary, evaluated in the sample's own subregion
    for a piecewise field (whose jumps are embedded in the mesh, so they are fine).
    """
    k = len(p)
    if k == 0 or not hasattr(domain, "diameter"):
        return
    eps = np.maximum(JUMP_REACH * float(domain.diameter),
                     16.0 * np.spacing(np.abs(p).max(axis=1)))
    steps = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    q = (p[:, None, :] + eps[:, None, None] * steps).reshape(-1, 2)
    inside = np.asarray(domain.contains(q), dtype=bool)
    if hasattr(domain, "distance_to_boundary") and (~inside).any():  # or along the boundary
        out = np.flatnonzero(~inside)
        near = np.asarray(domain.distance_to_boundary(q[out], interfaces=False)) <= \
            1e-3 * np.repeat(eps, len(steps))[out]
        inside[out[near]] = True
    if not inside.any():
        return
    src = np.repeat(np.arange(k), len(steps))[inside]
    q = q[inside]
    with np.errstate(all="ignore"):
        if callable(getattr(field, "region", None)) and getattr(field, "n_regions", 1) > 1:
            own = np.asarray(field.region(p), dtype=np.int64)
            cq = np.asarray(field.composition(q, region=own[src]), dtype=float)
        else:
            cq = np.asarray(field.composition(q), dtype=float)
    # the spread of each fraction over a sample and its neighbours (a jump may pass
    # between two neighbours, the sample on it taking a value in between)
    cq = np.where(np.isfinite(cq), cq, c[src])
    lo, hi = c.copy(), c.copy()
    np.minimum.at(lo, src, cq)
    np.maximum.at(hi, src, cq)
    for j in order:
        i = int(np.argmax(hi[:, j] - lo[:, j]))
        if hi[i, j] - lo[i, j] > JUMP:
            raise MaterialError(
                f"{pre}material.composition.{names[j]}: value jumps from {_fmt(lo[i, j])} to "
                f"{_fmt(hi[i, j])} within {_fmt(eps[i])} of {_at(p[i], scale)}; a jump must be "
                f"written as a condition (where, if/else, sign) so that the mesh can follow it")
