"""The local frame the mesher works in: the model moved to the origin and scaled to a
diameter near 1.

Units are the user's: a part may be given in metres (diameter 1e-3), in nanometres at an
offset of 1e9, or anywhere a float reaches (1e-150 to 1e150). Every tolerance of the mesher
is relative to the domain's diameter, but absolute floors (1e-300 guards, 1e-12 ratios of
coordinates) and the constrained Delaunay kernel's predicates are not: far from 1 they
fail (duplicate vertices at 1e-150, overflow to inf at 1e150). So the pipeline meshes the
model in a :class:`LocalFrame`: points ``local = (user - offset) / scale`` with ``offset``
the centre of the bounding box and ``scale`` the power of two nearest the diameter.
Multiplying by a power of two is exact in floating point, so a model meshes the same at any
scale, up to the scale: ``generate`` on a model scaled by 2**k gives points scaled by 2**k,
bit for bit (the offset, being a sum, may round).

Material fields are wrapped by :func:`local_field`: compositions are evaluated at the user
coordinates, gradients are returned per unit of local length (multiplied by ``scale``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import GeometryError
from ..material.field import thread_safe

__all__ = ["LocalFrame", "local_frame", "local_field"]


@dataclass(frozen=True)
class LocalFrame:
    """``local = (user - offset) / scale``; ``scale`` is a power of two."""

    offset: np.ndarray
    scale: float

    def to_user(self, points: np.ndarray) -> np.ndarray:
        """User coordinates of local ``points`` ``(N, 2)`` (a new array)."""
        out = np.multiply(points, self.scale, dtype=float)
        out += self.offset
        return out

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """Local coordinates of user ``points`` ``(N, 2)``."""
        return (np.asarray(points, float) - self.offset) / self.scale


def local_frame(bounds) -> LocalFrame:
    """The frame of a domain with bounding box ``bounds`` ``(x0, y0, x1, y1)``.

    >>> f = local_frame((0.0, 0.0, 3e-150, 4e-150))
    >>> f.scale == 2.0 ** round(math.log2(5e-150)), f.offset.tolist() == [1.5e-150, 2e-150]
    (True, True)
    """
    x0, y0, x1, y1 = (float(v) for v in bounds)
    offset = np.array([0.5 * x0 + 0.5 * x1, 0.5 * y0 + 0.5 * y1])
    # the diagonal without overflow: halves first (x1 - x0 may overflow near 1.8e308)
    w, h = 0.5 * x1 - 0.5 * x0, 0.5 * y1 - 0.5 * y0
    diam = 2.0 * math.hypot(w, h)
    if not (math.isfinite(diam) and diam > 0.0 and np.all(np.isfinite(offset))):
        raise GeometryError(f"the domain's extent ({x0:.6g}, {y0:.6g}) - ({x1:.6g}, {y1:.6g}) "
                            "cannot be represented in floating point")
    # a power of two: exact scaling; frexp gives diam = m 2**e, m in [0.5, 1)
    m, e = math.frexp(diam)
    scale = math.ldexp(1.0, e if m >= math.sqrt(0.5) else e - 1)
    return LocalFrame(offset=offset, scale=scale)


class _LocalField:
    """A material field evaluated in a :class:`LocalFrame` (see :func:`local_field`)."""

    def __init__(self, base, frame: LocalFrame):
        self.base, self.frame = base, frame
        self.constituents = base.constituents
        self.dim = 2
        self.thread_safe = thread_safe(base)
        if callable(getattr(base, "region", None)):
            self.region = self._region
            self.n_regions = base.n_regions
            self.region_names = getattr(base, "region_names", None)
        if callable(getattr(base, "pixel_delta", None)):
            self.pixel_delta = self._pixel_delta

    def composition(self, points, **kw) -> np.ndarray:
        return self.base.composition(self.frame.to_user(points), **kw)

    def gradient(self, points, **kw) -> np.ndarray:
        return self.base.gradient(self.frame.to_user(points), **kw) * self.frame.scale

    def _region(self, points) -> np.ndarray:
        return self.base.region(self.frame.to_user(points))

    def _pixel_delta(self, points, triangles, **kw) -> np.ndarray:
        # the pixel centres are in the field's (user) coordinates: so must the elements be
        return self.base.pixel_delta(self.frame.to_user(points), triangles, **kw)


def local_field(field, frame: LocalFrame):
    """``field`` seen in local coordinates: ``composition(p) = field.composition(to_user(p))``
    and ``gradient(p) = scale * field.gradient(to_user(p))`` (the chain rule). Piecewise
    fields keep ``region``, ``n_regions`` and ``region_names``, image fields ``pixel_delta``
    (elements given in local coordinates, passed on in user coordinates); keywords such as
    ``region=`` pass through."""
    return _LocalField(field, frame)
