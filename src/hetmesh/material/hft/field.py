"""The HFT material field: a feature tree behind the :class:`~hetmesh.material.MaterialField`
interface (composition, exact gradient, owning subregion), paper Section 3.3.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from ...errors import MaterialError
from ..analytic import Shiftable, check_constituents
from ..field import as_points, sample_domain
from .blend import BlendFeature
from .features import LeafFeature, PointFeature, reached, walk

__all__ = ["HFTField", "OUTSIDE_TOL"]

#: threads whose last evaluation :meth:`HFTField.evaluate` keeps (the pool's and the caller's)
_CACHED_THREADS = 16
OUTSIDE_TOL = 1e-6  # a feature sample farther than this x diameter outside the domain is an error


class HFTField(Shiftable):
    """A material field given by a feature tree.

    Parameters
    ----------
    root : feature
        Normally a :class:`BlendFeature`.
    constituents : sequence of str

    Examples
    --------
    >>> from hetmesh.tri.geometry import Segment
    >>> from hetmesh.material.hft import BlendFeature, CurveFeature
    >>> bot = CurveFeature("bot", Segment((0, 0), (1, 0)), [1.0, 0.0])
    >>> top = CurveFeature("top", Segment((1, 1), (0, 1)), [0.0, 1.0])
    >>> f = HFTField(BlendFeature("r", bot, top, {"d_b": bot, "d_t": top},
    ...                           [("d_t/(d_b + d_t)", None)]), ["ceramic", "metal"])
    >>> f.composition([[0.5, 0.25]]).tolist()
    [[0.75, 0.25]]
    >>> f.gradient([[0.5, 0.25]])[0, 0].tolist()
    [0.0, -1.0]
    """

    #: evaluations share only the per-thread cache (see
    #: :func:`~hetmesh.material.field.thread_safe`)
    thread_safe = True

    def __init__(self, root, constituents: Sequence[str]):
        self.root = root
        self.constituents = check_constituents(constituents)

    def __repr__(self) -> str:
        return f"HFTField(root={self.root.id!r}, constituents={list(self.constituents)})"

    @property
    def n_regions(self) -> int:
        return self.root.n_regions

    @property
    def region_names(self) -> list[str]:
        """Names of the subregions by id: their owning leaves joined by ``|``."""
        return [self.root.region_name(r) for r in range(self.root.n_regions)]

    def _region_arg(self, region, n):
        if region is None:
            return None
        r = np.asarray(region, dtype=np.int64)
        r = np.broadcast_to(r, (n,)) if r.ndim == 0 else r
        if r.shape != (n,) or (n and (r.min() < 0 or r.max() >= self.n_regions)):
            raise MaterialError(f"{self!r}: region must be {n} ids in [0, {self.n_regions}), "
                                f"got shape {r.shape}")
        return r

    def evaluate(self, points, region=None):
        """``(composition (N, m), gradient (N, m, 2), region (N,))`` in one pass.

        The last result of each thread is kept, keyed by the *contents* of the points and
        regions, so that ``composition(p)`` followed by ``gradient(p)`` (as the mesher calls
        them) evaluates the tree once; callers get copies.
        """
        return tuple(a.copy() for a in self._cached(points, region))

    def _cached(self, points, region):
        """``(composition, gradient, region)`` of the calling thread's one-entry cache (not
        copies): threads evaluating blocks at once do not evict each other's entries."""
        p = self._global(points)
        r = self._region_arg(region, len(p))
        key = (p.shape, hash(p.tobytes()), None if r is None else hash(r.tobytes()))
        caches = self.__dict__.setdefault("_cache", {})
        thread = threading.get_ident()
        if thread not in caches and len(caches) >= _CACHED_THREADS:
            caches.clear()  # threads that have ended keep no arrays alive
        cached = caches.get(thread)
        if cached is None or cached[0] != key:
            ev = self.root.evaluate(p, r)
            cached = caches[thread] = (key, ev.comp, ev.dcomp, ev.region)
        return cached[1:]

    def composition(self, points, region=None) -> np.ndarray:
        """Volume fractions ``(N, m)``; with ``region``, those of the given subregions."""
        return self._cached(points, region)[0].copy()

    def gradient(self, points, region=None) -> np.ndarray:
        """Exact gradients ``(N, m, 2)``; with ``region``, those of the given subregions."""
        return self._cached(points, region)[1].copy()

    def region(self, points) -> np.ndarray:
        """The subregion id ``(N,)`` owning each point (see :attr:`region_names`)."""
        return self.root.region(self._global(points))

    def enclose(self, box, region=None) -> tuple[np.ndarray, np.ndarray]:
        """Intervals ``(lo, hi)`` ``(K, m)`` containing every constituent's fraction at every
        point of each box ``(xlo, xhi, ylo, yhi)`` (four ``(K,)`` arrays, in the coordinates
        the field takes), computed through the tree by interval arithmetic (see
        :mod:`hetmesh.material.hft.enclose`); with ``region`` ``(K,)``, those of the given
        subregions' smooth fields, as :meth:`composition` evaluates them. Raises
        ``NotImplementedError`` for a tree with a node that has no enclosure
        (:meth:`unenclosable`).

        >>> from hetmesh.tri.geometry import Segment
        >>> from hetmesh.material.hft import BlendFeature, CurveFeature
        >>> bot = CurveFeature("bot", Segment((0, 0), (1, 0)), [1.0, 0.0])
        >>> top = CurveFeature("top", Segment((1, 1), (0, 1)), [0.0, 1.0])
        >>> f = HFTField(BlendFeature("r", bot, top, {"d_b": bot, "d_t": top},
        ...                           [("d_t/(d_b + d_t)", None)]), ["ceramic", "metal"])
        >>> lo, hi = f.enclose(tuple(np.array([v]) for v in (0.25, 0.75, 0.5, 0.75)))
        >>> bool(lo[0, 1] <= 0.5 and 0.75 <= hi[0, 1] < 0.75 + 1e-12)
        True
        """
        xlo, xhi, ylo, yhi = (np.asarray(b, dtype=float) for b in box)
        ox, oy = self._offset_xy
        if ox or oy:
            xlo, xhi, ylo, yhi = xlo + ox, xhi + ox, ylo + oy, yhi + oy
        r = None if region is None else self._region_arg(region, len(xlo))
        with np.errstate(all="ignore"):
            return self.root.enclose((xlo, xhi, ylo, yhi), r).comp

    def unenclosable(self) -> str | None:
        """None if :meth:`enclose` can enclose every node of the tree, else the first node
        that it cannot, as ``"<kind> '<id>'"``."""
        for node in walk(self.root):
            method = getattr(type(node), "enclose", None)
            if method is None or method is LeafFeature.enclose:
                return f"{type(node).__name__} {node.id!r}"
        return None

    def check_domain(self, domain, where: str = "", n: int = 60) -> None:
        """The checks of a tree against its domain (``where`` prefixes the messages), in
        order: :meth:`check_features_inside`, then on ``sample_domain(domain, n)``
        :meth:`check_owned` and :meth:`check_weights`. Raises :class:`MaterialError`."""
        self.check_features_inside(domain, where)
        points = sample_domain(domain, n)
        self.check_owned(points, where)
        self.check_weights(points, where)

    def check_features_inside(self, domain, where: str = "", n: int = 64) -> None:
        """Raise :class:`MaterialError` if a leaf the root depends on lies outside ``domain``.

        Each leaf is sampled (its point, or ``n`` points along its curve); a sample is
        outside when ``domain.contains`` is False and its distance to the domain's boundary
        exceeds ``OUTSIDE_TOL`` x the domain's diameter, so features on the boundary (the
        ring's circles, the plate's top edge) pass. The message names the feature and the
        first such point.
        """
        pre = f"{where}: " if where else ""
        tol = OUTSIDE_TOL * float(domain.diameter)
        for leaf in (f for f in walk(self.root) if isinstance(f, LeafFeature)):
            pts = leaf.sample(n)
            out = ~np.asarray(domain.contains(pts), dtype=bool)
            if out.any():
                dist = np.asarray(domain.distance_to_boundary(pts[out], interfaces=False))
                far = np.flatnonzero(dist > tol)
                if far.size:
                    x, y = pts[out][far[0]]
                    what = "point" if isinstance(leaf, PointFeature) else "curve"
                    raise MaterialError(f"{pre}feature {leaf.id!r}: {what} lies outside the "
                                        f"domain at ({x:.6g}, {y:.6g}), "
                                        f"{dist[far[0]]:.3g} from its boundary")

    def check_owned(self, points, where: str = "") -> None:
        """Raise :class:`MaterialError` if a ``select`` feature's rules leave one of
        ``points`` unowned (the tree is evaluated, so each select sees the points routed to
        it); the message names the feature and the first unowned point."""
        p = as_points(points)
        try:
            self.root.evaluate(p)
        except MaterialError as exc:
            raise MaterialError(f"{where}: {exc}" if where else str(exc)) from None

    def check_weights(self, points, where: str = "") -> None:
        """Raise :class:`MaterialError` if a blend's W leaves [0, 1] at one of ``points``
        where it applies (a blend under a ``select`` only sees the points routed to it)."""
        pre = f"{where}: " if where else ""
        for feat, p in reached(self.root, as_points(points)):
            if not isinstance(feat, BlendFeature):
                continue
            e1, e2 = feat.evaluate_children(p, None)
            W, _, reg = feat.weight(p, e1, e2)
            widx = feat.weight_of_region[reg]
            excess = np.where(np.isfinite(W), np.maximum(W - 1.0, -W), np.inf)
            i = int(np.argmax(excess)) if len(W) else 0
            if len(W) and excess[i] > 1e-12:  # report the worst point
                text = feat.exprs[widx[i]][0].text
                raise MaterialError(f"{pre}feature {feat.id!r}: weight {text!r} is "
                                    f"{W[i]:.6g} at ({p[i, 0]:.6g}, {p[i, 1]:.6g}) in "
                                    f"subregion {feat.region_name(int(reg[i]))!r}, "
                                    f"outside [0, 1]")

