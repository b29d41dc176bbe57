"""The material field interface and its validation.

A material field maps points ``(N, 2)`` to compositions ``(N, m)`` (volume fractions of the
``m`` constituents, rows summing to 1) and their gradients ``(N, m, 2)``. Any object with
``constituents``, ``composition`` and ``gradient`` is a field (duck typing; see
:class:`MaterialField`). :func:`check_field` samples a field densely over a domain and raises
:class:`~hetmesh.errors.MaterialError` naming the constituent and a coordinate where it is
not a valid composition.
"""

from __future__ import annotations

import logging
from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import MaterialError

__all__ = ["MaterialField", "check_field", "sample_domain", "as_points", "TOLERANCE"]

logger = logging.getLogger(__name__)

#: Tolerance of :func:`check_field` on the range [0, 1] and on the row sums.
TOLERANCE = 1e-9


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

    Examples
    --------
    >>> from hetmesh.material import CallableField
    >>> f = CallableField(lambda x, y: y, ["ceramic", "metal"])
    >>> isinstance(f, MaterialField)
    True
    """

    constituents: tuple[str, ...]

    def composition(self, points: np.ndarray) -> np.ndarray:
        """Volume fractions ``(N, m)`` at ``points`` ``(N, 2)``."""
        ...

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """Gradients ``(N, m, 2)`` of the volume fractions (d/dx, d/dy last)."""
        ...


def as_points(points, where: str = "points") -> np.ndarray:
    """``points`` as a float64 ``(N, 2)`` array; a single ``(2,)`` point becomes ``(1, 2)``."""
    p = np.asarray(points, dtype=float)
    if p.ndim == 1 and p.shape[0] == 2:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 2:
        raise MaterialError(f"{where}: expected points of shape (N, 2), got shape {p.shape}")
    return p


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
    x0, y0, x1, y1 = (float(v) for v in domain.bounds)
    xs = np.linspace(x0, x1, n)
    ys = np.linspace(y0, y1, n)
    gx, gy = np.meshgrid(xs, ys)
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    parts = [grid[np.asarray(domain.contains(grid), dtype=bool)]]
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
    return np.concatenate(parts, axis=0)


def _prefix(where: str) -> str:
    return f"{where}: " if where else ""


def check_field(field, domain, where: str = "", n: int = 200) -> None:
    """Check that ``field`` is a valid composition everywhere on ``domain``.

    Evaluates the field on :func:`sample_domain` (``n`` x ``n`` grid plus curve points) and
    raises :class:`~hetmesh.errors.MaterialError` if a value is not finite, lies outside
    [0, 1] (tolerance 1e-9), a row does not sum to 1 (tolerance 1e-9), a gradient is NaN, or
    the arrays have the wrong shape. The message names the constituent, the value and a
    coordinate where it happens (the worst one), e.g.
    ``m.toml: material.composition.metal: value 1.44 at (0, -6) is outside [0, 1]``.

    Infinite gradients (e.g. of ``sqrt(y)`` at ``y = 0``) are allowed: the density caps them.

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
    >>> from hetmesh.geometry import Arc, Loop, make_domain
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
    pts = sample_domain(domain, n)
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
        bad = np.isnan(g).any(axis=1)
        if bad.any():
            i = int(np.argmax(bad))
            raise MaterialError(f"{pre}material.composition.{names[j]}: gradient is undefined "
                                f"(nan) at {_at(pts[i], scale)}")
    logger.debug("%schecked %d constituents at %d points", pre, m, len(pts))
