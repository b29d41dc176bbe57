"""Interpolated image fields (:class:`ImageField`) and label-image phases
(:class:`LabelField`): the :class:`~hetmesh.material.MaterialField` interface over pixels.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np

from ...errors import MaterialError
from ...topology import unique
from ..field import as_points
from .maps import ValueMap
from .read import Image, image_error
from .sampling import element_pixel_delta

__all__ = ["ImageField", "LabelField", "image_field", "covers", "INTERPOLATIONS"]

INTERPOLATIONS = ("linear", "cubic")


# ---------------------------------------------------------------------------- the field
def _bspline_weights(t: np.ndarray):
    """Cubic B-spline weights ``(4, N)`` for offsets -1..2 and their derivatives."""
    t2, t3 = t * t, t * t * t
    w = np.stack([(1 - t) ** 3 / 6.0, (3 * t3 - 6 * t2 + 4) / 6.0,
                  (-3 * t3 + 3 * t2 + 3 * t + 1) / 6.0, t3 / 6.0])
    dw = np.stack([-(1 - t) ** 2 / 2.0, (3 * t2 - 4 * t) / 2.0,
                   (-3 * t2 + 2 * t + 1) / 2.0, t2 / 2.0])
    return w, dw


def _mirror(i: np.ndarray, n: int) -> np.ndarray:
    """Indices reflected about the end samples (scipy's ``mode="mirror"``)."""
    if n == 1:
        return np.zeros_like(i)
    period = 2 * (n - 1)
    i = np.abs(i) % period
    return np.where(i > n - 1, period - i, i)


class ImageField:
    """A material field interpolated from per-pixel fractions.

    Parameters
    ----------
    fractions : ndarray ``(m, *shape)``
        Volume fractions at the pixel centres (rows summing to 1).
    image : Image
        The geometry (origin, spacing); its values are not used.
    constituents : sequence of str
    interpolation : ``"linear"`` or ``"cubic"``
        Multilinear, or the interpolating cubic B-spline (scipy's ``spline_filter``,
        mirrored at the edges). Outside the pixel centres (the half-pixel rim of the
        image) the value of the nearest centre line is kept.
    smoothing : float
        Standard deviation of a Gaussian applied to the fractions first, in model units
        (0: none).

    The composition is the interpolant clipped to [0, 1] and renormalised to sum 1 (neither
    acts for linear interpolation of valid fractions; a cubic spline can overshoot at sharp
    edges); the gradient is the exact derivative of that function, so a mesher's Newton
    steps and size fields see the same field as the delta checks.
    """

    #: the dimension of the points the field takes: the image's (2, or 3 for a volume)
    dim = 2

    def __init__(self, fractions: np.ndarray, image: Image, constituents: Sequence[str], *,
                 interpolation: str = "linear", smoothing: float = 0.0):
        if interpolation not in INTERPOLATIONS:
            raise MaterialError(f"interpolation {interpolation!r} is not one of "
                                f"{', '.join(INTERPOLATIONS)}")
        f = np.asarray(fractions, float)
        self.constituents = tuple(constituents)
        if f.shape[0] != len(self.constituents) or f.ndim - 1 != image.dim:
            raise MaterialError(f"fractions of shape {f.shape} do not fit "
                                f"{len(self.constituents)} constituents on a {image.dim}-D "
                                f"image")
        self.dim = image.dim
        self.origin = np.asarray(image.origin, float)
        self.spacing = np.asarray(image.spacing, float)
        self.shape = f.shape[1:]
        self.interpolation = interpolation
        self.smoothing = float(smoothing)
        self.source = image.source
        if smoothing > 0:
            from scipy.ndimage import gaussian_filter

            sigma = [0.0] + [self.smoothing / s for s in self.spacing[::-1]]
            f = gaussian_filter(f, sigma=sigma, mode="nearest", truncate=4.0)
        self.samples = f  # the field at the pixel centres
        if interpolation == "cubic":
            from scipy.ndimage import spline_filter

            self._coef = np.stack([spline_filter(c, order=3, mode="mirror") for c in f])
        else:
            self._coef = f
        self._offset = np.zeros(self.dim)
        self._cache = None

    @property
    def local_origin(self) -> np.ndarray:
        """The centre of the first pixel in the coordinates the field is evaluated at
        (:attr:`origin` moved by the opposite of every :meth:`shifted` offset)."""
        return self.origin - self._offset

    def __repr__(self) -> str:
        return (f"ImageField({self.source!r}, shape={self.shape}, "
                f"interpolation={self.interpolation!r}, smoothing={self.smoothing:g})")

    # -- the MaterialField interface
    def shifted(self, offset) -> ImageField:
        """The same field evaluated at ``points + offset``."""
        new = copy.copy(self)
        new._offset = self._offset + np.asarray(offset, float).reshape(self.dim)
        new._cache = None
        return new

    def composition(self, points, region=None) -> np.ndarray:
        """Volume fractions ``(N, m)``."""
        return self.evaluate(points)[0].copy()

    def gradient(self, points, region=None) -> np.ndarray:
        """Gradients ``(N, m, d)`` of the interpolant (exact)."""
        return self.evaluate(points)[1].copy()

    def pixel_delta(self, points, triangles, regions=None, composition=None) -> np.ndarray:
        """delta(T) over every pixel centre each element covers and its vertices
        (:func:`~hetmesh.material.image.element_pixel_delta`; ``triangles`` are tetrahedra
        ``(M, 4)`` on a volume, and the centres voxel centres); ``composition`` ``(N, m)``:
        the fractions at ``points`` if known; ``regions`` is ignored."""
        vc = composition
        if vc is not None and (np.ndim(vc) != 2 or len(vc) != len(points)):
            vc = None
        return element_pixel_delta(self, points, triangles, vc)

    def evaluate(self, points) -> tuple[np.ndarray, np.ndarray]:
        """``(composition (N, m), gradient (N, m, d))``, cached for the last points."""
        p = self._points(points)
        key = (p.shape, hash(p.tobytes()))
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        out = self._evaluate(p)
        self._cache = (key, out)
        return out

    def _points(self, points) -> np.ndarray:
        p = as_points(points, repr(self), self.dim)
        return p + self._offset if self._offset.any() else p

    def _evaluate(self, p: np.ndarray, block: int = 1 << 17):
        n = len(p)
        m = len(self.constituents)
        comp = np.empty((n, m))
        grad = np.empty((n, m, self.dim))
        for s in range(0, n, block):
            c, g = self._raw(p[s:s + block])
            comp[s:s + block], grad[s:s + block] = _normalise(c, g)
        return comp, grad

    def _raw(self, p: np.ndarray):
        """Interpolated (unclipped) values ``(N, m)`` and gradients ``(N, m, d)``."""
        u = (p - self.origin) / self.spacing  # index coordinates, x first
        nax = np.asarray(self.shape[::-1])
        inside = (u >= 0) & (u <= nax - 1)
        u = np.clip(u, 0, nax - 1)
        if self.interpolation == "linear":
            i0 = np.minimum(np.floor(u).astype(np.int64), np.maximum(nax - 2, 0))
            t = u - i0
            offs = (0, 1)
            w = [np.stack([1 - t[:, k], t[:, k]]) for k in range(self.dim)]
            dw = [np.stack([-np.ones(len(t)), np.ones(len(t))]) for _ in range(self.dim)]
            idx = [[np.minimum(i0[:, k] + o, nax[k] - 1) for o in offs]
                   for k in range(self.dim)]
        else:
            i0 = np.floor(u).astype(np.int64)
            t = u - i0
            offs = (-1, 0, 1, 2)
            w, dw = zip(*[_bspline_weights(t[:, k]) for k in range(self.dim)])
            idx = [[_mirror(i0[:, k] + o, int(nax[k])) for o in offs]
                   for k in range(self.dim)]
        m = len(self.constituents)
        val = np.zeros((len(p), m))
        der = np.zeros((len(p), m, self.dim))
        flat = self._coef.reshape(m, -1)
        strides = np.cumprod([1] + list(nax[:-1]))  # flat index = sum idx_k * stride_k
        for combo in np.ndindex(*(len(offs),) * self.dim):
            lin = sum(idx[k][combo[k]] * strides[k] for k in range(self.dim))
            vals = flat[:, lin].T  # (N, m)
            ws = [w[k][combo[k]] for k in range(self.dim)]
            prod = np.prod(ws, axis=0)
            val += prod[:, None] * vals
            for k in range(self.dim):
                others = np.prod([ws[j] for j in range(self.dim) if j != k], axis=0) \
                    if self.dim > 1 else 1.0
                der[:, :, k] += (dw[k][combo[k]] * others)[:, None] * vals
        der /= self.spacing
        der *= inside[:, None, :]
        return val, der


def _normalise(c: np.ndarray, g: np.ndarray):
    """Clip to [0, 1] and renormalise to sum 1, with the derivative of that map."""
    clipped = (c < 0) | (c > 1)
    if not clipped.any() and np.abs(c.sum(axis=1) - 1).max() < 1e-12:
        return c, g
    cc = np.clip(c, 0.0, 1.0)
    gg = np.where(clipped[:, :, None], 0.0, g)
    s = cc.sum(axis=1)
    s = np.where(s > 0, s, 1.0)
    ds = gg.sum(axis=1)
    comp = cc / s[:, None]
    grad = (gg * s[:, None, None] - cc[:, :, None] * ds[:, None, :]) / (s * s)[:, None, None]
    return comp, grad


def image_field(image: Image, vmap: ValueMap, constituents: Sequence[str], *,
                interpolation: str = "linear", smoothing: float = 0.0) -> ImageField:
    """Map ``image``'s values with ``vmap`` and interpolate them (:class:`ImageField`)."""
    frac = vmap(image.values, image.source)
    return ImageField(frac, image, constituents, interpolation=interpolation,
                      smoothing=smoothing)


def covers(image: Image, bounds, where: str = "") -> None:
    """Raise :class:`MaterialError` unless the pixels of ``image`` cover the box ``bounds``
    ``(x0, y0, x1, y1)`` (up to 1e-9 of its size)."""
    lo, hi = image.extent()
    b = np.asarray(bounds, float).reshape(2, -1)
    tol = 1e-9 * float(np.abs(b).max() + np.ptp(b))
    if (b[0] < lo - tol).any() or (b[1] > hi + tol).any():
        def fmt(v):
            return "(" + ", ".join(f"{x:.6g}" for x in v) + ")"
        bad = b[0] if (b[0] < lo - tol).any() else b[1]
        raise image_error(where or image.source,
                          f"the image covers {fmt(lo)} - {fmt(hi)} but the domain reaches "
                          f"{fmt(bad)}: it must lie inside the image (check origin and spacing)")


# ---------------------------------------------------------------------------- label fields
class LabelField:
    """Phases of a label image, each a subregion with its own composition.

    Parameters
    ----------
    regions : callable ``points (N, dim) -> (N,) int``
        The subregion of each point (phase index into ``phases``), normally the traced,
        simplified label polygons (:func:`hetmesh.tri.geometry.trace.region_lookup`), or
        for a label volume the contours of its labels
        (:meth:`hetmesh.tet.masked.VoxelSolid.phase`).
    phases : list
        Per subregion, either a composition ``(m,)`` (a constant phase) or an
        :class:`ImageField` (a graded phase, its pixels outside the phase filled with the
        nearest pixel of the phase so that interpolation never mixes phases).
    names : list of str
        The subregion names (``"label 3"``).
    dim : int
        2 (a label image) or 3 (a label volume): the dimension of the points it takes.
    """

    def __init__(self, regions, phases: list, names: list[str],
                 constituents: Sequence[str], source: str = "labels", dim: int = 2):
        self._regions = regions
        self.phases = phases
        self.region_names = list(names)
        self.constituents = tuple(constituents)
        self.source = source
        self.dim = int(dim)
        self._offset = np.zeros(self.dim)

    def __repr__(self) -> str:
        return f"LabelField({self.source!r}, {self.n_regions} phases)"

    @property
    def n_regions(self) -> int:
        return len(self.phases)

    def describe_jump(self, a: int, b: int) -> str:
        return f"{self.source}: between {self.region_names[a]} and {self.region_names[b]}"

    def shifted(self, offset) -> LabelField:
        new = copy.copy(self)
        new._offset = self._offset + np.asarray(offset, float).reshape(self.dim)
        return new

    def _points(self, points):
        p = as_points(points, repr(self), self.dim)
        return p + self._offset if self._offset.any() else p

    def region(self, points) -> np.ndarray:
        """The phase (subregion id) of each point."""
        return np.asarray(self._regions(self._points(points)), dtype=np.int64)

    def _evaluate(self, points, region):
        p = self._points(points)
        r = self._regions(p) if region is None else np.broadcast_to(
            np.asarray(region, np.int64), (len(p),))
        m = len(self.constituents)
        comp = np.empty((len(p), m))
        grad = np.zeros((len(p), m, self.dim))
        for k, ph in enumerate(self.phases):
            sel = np.flatnonzero(r == k)
            if not len(sel):
                continue
            if isinstance(ph, ImageField):
                comp[sel], grad[sel] = ph.evaluate(p[sel])
            else:
                comp[sel] = ph
        return comp, grad

    def composition(self, points, region=None) -> np.ndarray:
        """Volume fractions ``(N, m)``; with ``region``, those of the given phases."""
        return self._evaluate(points, region)[0]

    def gradient(self, points, region=None) -> np.ndarray:
        """Gradients ``(N, m, dim)`` (zero in a constant phase)."""
        return self._evaluate(points, region)[1]

    def pixel_delta(self, points, triangles, regions=None, composition=None) -> np.ndarray:
        """delta(T) over the vertices of each element (in its own phase, ``regions``: its
        phase, default that of its centroid) and, in a graded phase, every pixel centre it
        covers (its elements lie inside the phase, so those pixels are the phase's).
        ``composition`` is ignored: a vertex on a phase boundary has one value per phase."""
        P = np.asarray(points, float)
        T = np.asarray(triangles, np.int64)
        own = (self.region(P[T].mean(axis=1)) if regions is None
               else np.asarray(regions, np.int64))
        corner = np.stack([self.composition(P[T[:, k]], region=own)
                           for k in range(T.shape[1])], 1)
        delta = (corner.max(axis=1) - corner.min(axis=1)).max(axis=1)
        for k, ph in enumerate(self.phases):
            sel = np.flatnonzero(own == k)
            if isinstance(ph, ImageField) and len(sel):
                used, tri = unique(T[sel], return_inverse=True)
                d = element_pixel_delta(ph.shifted(self._offset), P[used],
                                        tri.reshape(-1, T.shape[1]))
                delta[sel] = np.maximum(delta[sel], d)
        return delta

