"""Certified element variation: an upper bound on delta(T) that holds inside the element.

Vertex sampling (the paper's Eqs. 14-15) measures delta(T) at the three corners of an
element; a lattice (``sampling="dense"``) at 15 points. Both are lower bounds on the true
variation ``max_j (max_T c_j - min_T c_j)`` and both miss a narrow peak between their
samples. :func:`certified_delta` bounds it from above instead:

* **Formula fields** (:class:`~hetmesh.material.AnalyticField`): each formula is enclosed
  over the bounding box of a piece of the element by interval arithmetic on its compiled
  tree (:meth:`hetmesh.expr.Expr.interval`), intersected with the mean-value form
  ``f(c) + grad f(box) . (box - c)`` (the gradient's tree enclosed the same way) where the
  formula is smooth on the piece. A piecewise field's element is enclosed on its own
  subregion's branch, as the mesher evaluates it.
* **Feature-tree fields** (:class:`~hetmesh.material.hft.HFTField`): the fractions are
  enclosed over the piece's bounding box through the tree
  (:meth:`~hetmesh.material.hft.HFTField.enclose`, :mod:`hetmesh.material.hft.enclose`):
  distances to points and segments exactly (the distance is convex), to circles and arcs by
  ``|rho - R|`` (exact within the arc's angular span) and the 1-Lipschitz ``d(c) +- r``
  beyond it; a curve's linear composition by the range of its nearest point's parameter;
  a parent by its forced child (the element's subregion) or the hull of the children that
  may own a point of the box (for a ``select`` used only as a distance, all of them: its
  rules are opaque predicates, so such a bound is loose); a blend's weight by interval arithmetic
  on its formula over the distances' intervals (by its corner values where every ``dW/dd_i`` keeps
  one sign),
  and ``W M_1 + (1 - W) M_2`` at the corners of the three intervals. A proof, first-order
  tight: the subdivision takes the pieces near the extremes down until the bound settles.
  A tree with a node that has no enclosure (a user's own leaf class; see
  :meth:`~hetmesh.material.hft.HFTField.unenclosable`) falls back, with a
  :class:`CertificationUnavailable` warning naming the node, to a Lipschitz estimate:
  within a subregion ``c_j`` stays within ``L_j R / 2`` of its values at a piece's corners
  and edge midpoints (``R`` its circumradius), ``L_j`` the gradient norm at seven samples
  times :data:`LIPSCHITZ_SAFETY` (an estimate, not a proof; :data:`TREE_BOUND` selects it
  for every tree, for comparisons).
* **Tetrahedra**: the same, on 3D boxes. A formula in ``x, y, z`` is enclosed as above. A
  2D field seen through a prism's section (an extruded model,
  :class:`~hetmesh.tet.extrude.SectionField`) is constant along the axis, so a
  tetrahedron's variation is that of the 2D field over its shadow on the section: the
  shadow is covered by triangles (one for a tetrahedron of a swept prism, else four) that
  are bounded as 2D elements, each distinct shadow once (subdividing the tetrahedron
  itself, eight children a level, would spend most of its pieces along the axis, where
  nothing varies); through a revolution (:class:`~hetmesh.tet.revolve.RevolvedField`),
  on the 2D box ``(r, z)`` whose ``r`` runs from the distance of the box's ``(x, y)``
  rectangle to the axis to that of its farthest corner.
* Anything else (a Python callable, :class:`~hetmesh.material.CallableField`) has no tree
  to enclose: :func:`certified_delta` warns and returns the dense-sampled delta.

Each element is subdivided (at the edge midpoints: four children per triangle, eight per
tetrahedron, four at its corners and four around a diagonal of the inner octahedron) where its
enclosure is not yet within ``atol + rtol * L`` of ``L``, the variation witnessed by the
samples (corners, edge midpoints and centroids of the pieces), or, given delta_0, until it
is decided (bound below delta_0, or samples at or above it), up to ``max_depth`` levels
and a budget of pieces (:data:`MAX_PIECES` a level; :data:`WORK_PER_ELEMENT` times the
elements, at least :data:`MAX_PIECES`, in all: a call's work is bounded, whatever the field);
pieces whose enclosure already lies within that margin of the witnessed extremes (given
delta_0: within delta_0 / 2 of their middle) are not split further. The result is the
enclosure's ``max - min``, so it is never below the true delta(T) of the element; an element
the enclosure cannot decide keeps a loose (large) bound, which makes the refinement split it.

Rounding: intervals are widened outwards by a few units in the last place (see
:data:`hetmesh.expr.Interval`); the pieces' boxes by a few units in the last place of the
coordinates, so the affine map from the mesher's local frame to the model's coordinates
loses nothing.
"""

from __future__ import annotations

import logging
import warnings

import numpy as np

from .topology import unique

__all__ = ["certified_delta", "certifiable", "split_simplices", "radial_range",
           "CertificationUnavailable", "LIPSCHITZ_SAFETY", "TREE_BOUND", "RTOL", "ATOL",
           "MAX_DEPTH", "MAX_PIECES", "WORK_PER_ELEMENT"]

log = logging.getLogger(__name__)

#: relative gap between the certified bound and the witnessed variation at which an element
#: is settled
RTOL = 0.01
#: absolute gap (in composition) at which an element is settled
ATOL = 1e-4
#: the most subdivision levels of an element (4**MAX_DEPTH pieces at most, in practice a few
#: dozen: only the pieces near the extremes are split)
MAX_DEPTH = 14
#: the most pieces enclosed in one pass; past it the remaining elements keep their bounds
MAX_PIECES = 1 << 21
#: the most pieces enclosed in one call, per element (and at least :data:`MAX_PIECES`);
#: past it the open elements keep their bounds, so one call's work stays linear in its
#: elements (the examples' certified meshes use at most about 620 an element)
WORK_PER_ELEMENT = 1024
#: feature trees: the sampled gradient norm is multiplied by this to bound the Lipschitz
#: constant of a piece
LIPSCHITZ_SAFETY = 2.0
#: how feature trees are bounded: ``"interval"`` (an enclosure through the tree, a proof) or
#: ``"lipschitz"`` (the sampled Lipschitz estimate, used anyway for a tree with a node that
#: has no enclosure; benchmarks/bench_certify.py compares the two)
TREE_BOUND = "interval"

_CHILDREN = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]])  # of (a, b, c, ab, bc, ca)
#: a tetrahedron's edges, in the order of its midpoints among the samples (after the corners)
_TET_EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
#: the eight children of a tetrahedron (corners 0-3, midpoints 4-9 as in _TET_EDGES): four
#: at the corners, four around the diagonal 02-13 (samples 5 and 8) of the inner octahedron
_TET_CHILDREN = np.array([[0, 4, 5, 6], [4, 1, 7, 8], [5, 7, 2, 9], [6, 8, 9, 3],
                          [5, 8, 4, 6], [5, 8, 6, 9], [5, 8, 9, 7], [5, 8, 7, 4]])


class CertificationUnavailable(UserWarning):
    """The field has no expression tree to enclose; dense sampling was used instead."""


def _unwrap(field):
    """``(base field, scale, offset)`` with the field's values at local points ``p`` those of
    ``base`` at ``p * scale + offset`` (the mesher's local frame undone)."""
    scale, offset = 1.0, np.zeros(getattr(field, "dim", 2))
    while hasattr(field, "base") and hasattr(field, "frame"):
        frame = field.frame
        offset = offset * frame.scale + frame.offset  # p -> (p s1 + o1) s2 + o2
        scale = scale * frame.scale
        field = field.base
    return field, scale, offset


def certifiable(field) -> str | None:
    """``None`` if :func:`certified_delta` can bound ``field``, else the reason it cannot."""
    from .material.analytic import AnalyticField
    from .material.hft import HFTField
    base = _unwrap(field)[0]
    if isinstance(base, (AnalyticField, HFTField)) or _box_enclosure_2d(base) is not None:
        return None
    return (f"certified sampling needs a formula or feature-tree material; "
            f"{type(base).__name__} has no expression to enclose")


# --------------------------------------------------------------------------- enclosures
def _box(corners: np.ndarray, off: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounding boxes ``(lo (K, d), hi (K, d))`` of pieces ``(K, d + 1, d)`` shifted by
    ``off``, widened by 8 units in the last place of the coordinates."""
    return _padded(corners.min(axis=1) + off, corners.max(axis=1) + off)


def _padded(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The boxes ``[lo, hi]`` widened by 8 units in the last place of the coordinates."""
    pad = 8.0 * np.spacing(np.maximum(np.abs(lo), np.abs(hi)))
    return lo - pad, hi + pad


def _imul(a, b):
    p = [a[i] * b[j] for i in (0, 1) for j in (0, 1)]
    p = [np.where(np.isnan(v), 0.0, v) for v in p]
    lo, hi = np.minimum(np.minimum(p[0], p[1]), np.minimum(p[2], p[3])), \
        np.maximum(np.maximum(p[0], p[1]), np.maximum(p[2], p[3]))
    return _widen(lo, hi)


def _widen(lo, hi):
    eps = 4.0 * np.finfo(float).eps
    tiny = np.finfo(float).tiny
    lo = lo - (np.abs(lo) * eps + tiny)
    hi = hi + (np.abs(hi) * eps + tiny)
    return np.where(np.isnan(lo), -np.inf, lo), np.where(np.isnan(hi), np.inf, hi)


class _FormulaEnclosure:
    """Interval enclosures of an :class:`AnalyticField`'s fractions over boxes (2D or 3D:
    its variables ``x, y`` or ``x, y, z``)."""

    def __init__(self, field, offset: np.ndarray):
        self.field = field
        self.off = field.offset  # the field's own shift (AnalyticField.shifted)
        self.m = len(field.constituents)

    def enclose(self, corners: np.ndarray, region: np.ndarray | None):
        return self._enclose(*_box(corners, self.off), region)

    def enclose_box(self, lo: np.ndarray, hi: np.ndarray, region: np.ndarray | None):
        """Intervals ``(lo (K, m), hi (K, m))`` holding the fractions at every point of each
        box ``[lo, hi]`` (``(K, d)`` each, in the field's coordinates before its shift)."""
        return self._enclose(*_padded(lo + self.off, hi + self.off), region)

    def _enclose(self, lo: np.ndarray, hi: np.ndarray, region: np.ndarray | None):
        f = self.field
        names = f._vars
        box = {v: (lo[:, i], hi[:, i]) for i, v in enumerate(names)}
        mid = {v: 0.5 * (lo[:, i] + hi[:, i]) for i, v in enumerate(names)}
        piecewise = bool(f._conds)
        env: dict = {}
        if piecewise and region is not None:
            bits = f._region_bits(region, len(lo)).astype(np.float64)
            env = {name: bits[:, i] for i, name in enumerate(f._cond_names)}
            exprs, grads, smooth = f._fixed, f._fixed_grads, True
        else:
            exprs, grads, smooth = f._exprs, f._grads, not piecewise
        k = len(lo)
        out_lo = np.empty((k, self.m))
        out_hi = np.empty((k, self.m))
        for j, e, grad in zip(f._given, exprs, grads):
            a, b = e.interval(**box, **env)
            if smooth:  # the mean-value form f(c) + grad f(box) . (box - c)
                mlo, mhi = e.interval(**mid, **env)
                for i, (v, dv) in enumerate(zip(names, grad)):
                    t = _imul(dv.interval(**box, **env),
                              _widen(lo[:, i] - mid[v], hi[:, i] - mid[v]))
                    mlo, mhi = mlo + t[0], mhi + t[1]
                mlo, mhi = _widen(mlo, mhi)
                a, b = np.maximum(a, mlo), np.minimum(b, mhi)
            out_lo[:, j], out_hi[:, j] = a, b
        if f._derived_col is not None:
            d = f._derived_col
            g = f._given
            out_lo[:, d], out_hi[:, d] = _widen(1.0 - out_hi[:, g].sum(axis=1),
                                                1.0 - out_lo[:, g].sum(axis=1))
        return out_lo, out_hi


class _TreeEnclosure:
    """Interval enclosures of an :class:`HFTField`'s fractions over boxes, through its tree
    (:meth:`hetmesh.material.hft.HFTField.enclose`)."""

    def __init__(self, field, offset: np.ndarray):
        self.field = field

    def enclose(self, corners: np.ndarray, region: np.ndarray | None):
        return self.enclose_box(*_box(corners, np.zeros(2)), region)

    def enclose_box(self, lo: np.ndarray, hi: np.ndarray, region: np.ndarray | None):
        return self.field.enclose((lo[:, 0], hi[:, 0], lo[:, 1], hi[:, 1]), region)


class _SectionEnclosure:
    """A 3D field that is a 2D field of a prism's section coordinates ``(u, v)`` (an
    extruded model), constant along the axis: a tetrahedron's variation is that of the 2D
    field over its shadow on the section, which :meth:`project` covers with triangles, and
    those are bounded as 2D elements (``inner``, the 2D field's own enclosure)."""

    def __init__(self, inner, uv: tuple[int, int]):
        self.inner = inner
        self.uv = list(uv)

    def project(self, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(triangles (M, 4, 3, 2), single (M,) bool)``: four triangles of the section
        whose union is the shadow of each tetrahedron ``(M, 4, 3)``, the convex hull of its
        four projected corners, each triangle's corners in lexicographic order. That hull
        is the union of the four triangles of three of them (Caratheodory: every point of
        the hull of four points in the plane lies in a triangle of three); where two
        projected corners coincide exactly (a tetrahedron of a swept prism, or one bisected
        from it) the triangle of the other three and one of the pair is the whole hull,
        and it fills all four places (``single``).

        >>> c = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 5.0]]])
        >>> t, one = _SectionEnclosure(None, (0, 1)).project(c)
        >>> t[0, 0].tolist(), bool(one[0]), bool((t == t[:, :1]).all())
        ([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]], True, True)
        """
        q = corners[:, :, self.uv]  # (M, 4, 2)
        m = len(q)
        drop = np.full(m, -1)  # a corner whose twin stands for it, else -1
        for i, j in _TET_EDGES[::-1]:  # the first pair wins
            drop[(q[:, i] == q[:, j]).all(axis=1)] = j
        without = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])  # corner k left out
        single = drop >= 0
        faces = np.where(single[:, None, None], without[np.maximum(drop, 0)][:, None],
                         without[None])  # (M, 4, 3)
        tri = q[np.arange(m)[:, None, None], faces]  # (M, 4, 3, 2)
        rank = np.lexsort((tri[..., 1], tri[..., 0]), axis=-1)  # corners by (u, v)
        return np.take_along_axis(tri, rank[..., None], axis=2), single


class _RevolvedEnclosure:
    """Enclosures of a 3D field that is a 2D field of ``(r, z)``, ``r`` the distance to the
    z axis (a revolved model): over a box, ``r`` lies between the distance from the axis to
    the box's ``(x, y)`` rectangle and that of its farthest corner, ``z`` in the box's own
    range; that 2D box is enclosed by the 2D field's enclosure."""

    def __init__(self, inner):
        self.inner = inner

    def enclose(self, corners: np.ndarray, region: np.ndarray | None):
        lo, hi = _box(corners, np.zeros(3))
        rlo, rhi = radial_range(lo, hi)
        lo2 = np.column_stack([rlo, lo[:, 2]])
        hi2 = np.column_stack([rhi, hi[:, 2]])
        return self.inner.enclose_box(lo2, hi2, region)


def radial_range(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The range of ``r = hypot(x, y)`` over boxes ``[lo, hi]`` (``(K, >= 2)``): from the
    distance of the box's ``(x, y)`` rectangle to the z axis to that of its farthest corner,
    widened outwards by a few units in the last place.

    >>> radial_range(np.array([[1.0, -1.0, 0.0]]), np.array([[2.0, 1.0, 1.0]]))[0].round(9)
    array([1.])
    """
    near = np.where(lo[:, :2] > 0, lo[:, :2], np.where(hi[:, :2] < 0, -hi[:, :2], 0.0))
    far = np.maximum(np.abs(lo[:, :2]), np.abs(hi[:, :2]))
    rlo, rhi = _widen(np.hypot(near[:, 0], near[:, 1]), np.hypot(far[:, 0], far[:, 1]))
    return np.maximum(rlo, 0.0), rhi


class _LipschitzEnclosure:
    """Enclosures of a feature-tree field's fractions from a Lipschitz bound per piece.

    The four children of a piece (split at its edge midpoints) have circumradius ``R / 2``
    and their corners among the piece's corners and edge midpoints, so every point of the
    piece is within ``R / 2`` of one of those six samples: ``c_j`` lies within
    ``L_j R / 2`` of their range, ``L_j`` the sampled gradient norm's maximum over the
    seven samples (corners, midpoints, centroid) times :data:`LIPSCHITZ_SAFETY`.
    """

    def __init__(self, field, offset: np.ndarray):
        self.field = field
        self.m = len(field.constituents)

    def enclose(self, corners: np.ndarray, region: np.ndarray | None):
        k = len(corners)
        pts = _seven(corners).reshape(-1, 2)
        reg = None if region is None else np.repeat(region, 7)
        with np.errstate(all="ignore"):
            comp = self.field.composition(pts, region=reg).reshape(k, 7, self.m)
            grad = self.field.gradient(pts, region=reg).reshape(k, 7, self.m, 2)
        lip = np.sqrt((grad ** 2).sum(axis=3)).max(axis=1) * LIPSCHITZ_SAFETY  # (k, m)
        reach = 0.5 * _circumradius(corners)[:, None] * lip
        return _widen(comp.min(axis=1) - reach, comp.max(axis=1) + reach)


def _circumradius(corners: np.ndarray) -> np.ndarray:
    """How far a point of each triangle ``(K, 3, 2)`` can be from its nearest corner, at
    most: the circumradius, or the longest edge (the triangle's diameter) where that is
    smaller (flat triangles, whose circumradius grows without bound)."""
    a = np.hypot(*(corners[:, 1] - corners[:, 2]).T)
    b = np.hypot(*(corners[:, 2] - corners[:, 0]).T)
    c = np.hypot(*(corners[:, 0] - corners[:, 1]).T)
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    area2 = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    longest = np.maximum(np.maximum(a, b), c)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(area2 > 0, a * b * c / (2.0 * area2), np.inf)
    return np.minimum(r, longest)


def _enclosure(field):
    from .material.analytic import AnalyticField
    from .material.hft import HFTField
    base, scale, offset = _unwrap(field)
    if isinstance(base, AnalyticField):
        return base, scale, offset, _FormulaEnclosure(base, offset)
    if isinstance(base, HFTField):
        missing = base.unenclosable()
        if TREE_BOUND == "interval" and missing is None:
            return base, scale, offset, _TreeEnclosure(base, offset)
        if missing is not None:
            warnings.warn(f"certified sampling: feature {missing} has no interval enclosure; "
                          f"using a sampled Lipschitz bound instead (an estimate, not a "
                          f"certificate)", CertificationUnavailable, stacklevel=3)
        return base, scale, offset, _LipschitzEnclosure(base, offset)
    inner = _box_enclosure_2d(base)
    if inner is not None:
        solid = base.solid
        enc = _SectionEnclosure(inner, solid.uv) if hasattr(solid, "uv") else \
            _RevolvedEnclosure(inner)
        return base, scale, offset, enc
    return base, scale, offset, None


def _box_enclosure_2d(field):
    """The box enclosure of the 2D field behind a 3D section or revolved field (formula,
    or feature tree whose every node has an interval enclosure), else None."""
    from .material.analytic import AnalyticField
    from .material.hft import HFTField
    inner2d = getattr(field, "field2d", None)
    if inner2d is None or getattr(field, "dim", 2) != 3:
        return None
    inner, scale, offset = _unwrap(inner2d)
    if scale != 1.0 or np.any(offset):  # a 2D field in a local frame: not met in 3D models
        return None
    if isinstance(inner, AnalyticField):
        return _FormulaEnclosure(inner, offset)
    if isinstance(inner, HFTField) and inner.unenclosable() is None:
        return _TreeEnclosure(inner, offset)
    return None


# --------------------------------------------------------------------------- the bound
def certified_delta(field, points: np.ndarray, triangles: np.ndarray, *,
                    regions: np.ndarray | None = None, rtol: float = RTOL,
                    atol: float = ATOL, max_depth: int = MAX_DEPTH,
                    threshold: float | None = None) -> np.ndarray:
    """An upper bound ``(M,)`` on every element's true variation delta(T).

    Parameters
    ----------
    field : material field
        A formula field or feature tree (possibly in the mesher's local frame); for any
        other field a :class:`CertificationUnavailable` warning is issued and the
        dense-sampled delta (:func:`hetmesh.metrics.delta_dense`) returned.
    points, triangles : arrays
        The mesh, in the coordinates ``field`` takes.
    regions : (M,) int, optional
        Each element's subregion (piecewise fields): the element is bounded on that
        subregion's smooth field.
    rtol, atol : float
        An element is settled when its bound is within ``atol + rtol * L`` of the variation
        ``L`` its samples witness.
    max_depth : int
        The most subdivision levels.
    threshold : float, optional
        delta_0: an element is also settled once its bound is below it (certified) or its
        samples reach it (it must be split anyway). Its bound is then the enclosure of that
        moment, which may be looser than ``atol + rtol * L``.

    Returns
    -------
    (M,) float
        ``bound >= max_j (max_T c_j - min_T c_j)`` for every element ``T``.

    Examples
    --------
    >>> from hetmesh.material import AnalyticField
    >>> f = AnalyticField({"b": "exp(-((x - 0.3)**2 + (y - 0.3)**2)/1e-4)"}, ["a", "b"])
    >>> P = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]); T = np.array([[0, 1, 2]])
    >>> float(f.composition(P)[:, 1].max()) < 1e-100       # the corners see nothing
    True
    >>> 1.0 <= float(certified_delta(f, P, T)[0]) < 1.0 + 0.02
    True
    """
    from .metrics import delta_dense
    points = np.asarray(points, dtype=float)
    triangles = np.asarray(triangles)
    if not len(triangles):
        return np.zeros(0)
    base, scale, offset, enc = _enclosure(field)
    if enc is None:
        warnings.warn(f"{certifiable(field)}: using dense sampling instead (a lower "
                      f"bound, not a certificate)", CertificationUnavailable, stacklevel=2)
        return delta_dense(field, points, triangles, regions=regions)
    # the elements in the base field's coordinates (frame undone; the box pads rounding)
    corners = points[triangles] * scale + offset
    own = None if regions is None else np.asarray(regions, dtype=np.int64)
    if isinstance(enc, _SectionEnclosure):  # constant along the axis: bound the shadows
        return _shadow_bound(base.field2d, enc, corners, own, rtol, atol, max_depth,
                             threshold)
    return _bound(base, enc, corners, np.arange(len(corners)), own, rtol, atol, max_depth,
                  threshold)


def _samples(base, corners: np.ndarray, region: np.ndarray | None,
             first: int = 0) -> np.ndarray:
    """Compositions ``(K, S - first, m)`` at the ``S`` samples of pieces
    (:func:`_sample_points`: corners, edge midpoints and centroid), from the ``first`` of
    them (the corners of a child were sampled with its parent)."""
    d = corners.shape[2]
    pts = _sample_points(corners)[:, first:]
    n = pts.shape[1]
    pts = pts.reshape(-1, d)
    with np.errstate(all="ignore"):
        if region is not None:
            comp = base.composition(pts, region=np.repeat(region, n))
        else:
            comp = base.composition(pts)
    comp = np.asarray(comp, dtype=float).reshape(len(corners), n, -1)
    return comp if np.isfinite(comp).all() else np.where(np.isfinite(comp), comp, np.nan)


def _sample_points(corners: np.ndarray) -> np.ndarray:
    """The corners, edge midpoints and centroid of pieces ``(K, d + 1, d)``: ``(K, 7, 2)``
    for triangles (:func:`_seven`), ``(K, 11, 3)`` for tetrahedra."""
    if corners.shape[1] == 3:
        return _seven(corners)
    c = [corners[:, i] for i in range(4)]
    mids = [0.5 * (c[i] + c[j]) for i, j in _TET_EDGES]
    return np.stack(c + mids + [(c[0] + c[1] + c[2] + c[3]) / 4.0], axis=1)


def _seven(corners: np.ndarray) -> np.ndarray:
    """The corners, edge midpoints and centroid ``(K, 7, 2)`` of pieces ``(K, 3, 2)``."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    return np.stack([a, b, c, 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a),
                     (a + b + c) / 3.0], axis=1)


def split_simplices(corners: np.ndarray) -> np.ndarray:
    """The children of pieces at their edge midpoints: four ``(4K, 3, 2)`` per triangle,
    eight ``(8K, 4, 3)`` per tetrahedron (four at its corners, four around the inner
    octahedron's diagonal)."""
    if corners.shape[1] == 3:
        a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
        six = np.stack([a, b, c, 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)], axis=1)
        return six[:, _CHILDREN].reshape(-1, 3, 2)
    ten = _sample_points(corners)[:, :10]
    return ten[:, _TET_CHILDREN].reshape(-1, 4, 3)


def _group(values: np.ndarray, starts: np.ndarray, ufunc) -> np.ndarray:
    """``ufunc`` over consecutive rows of ``values`` from each of ``starts`` (sorted owners)."""
    return ufunc.reduceat(values, starts, axis=0)


def _shadow_bound(field2d, enc, corners, own, rtol, atol, max_depth, threshold
                  ) -> np.ndarray:
    """:func:`_bound` of tetrahedra ``corners`` of a field constant along a prism's axis:
    of their shadows on the section (:meth:`_SectionEnclosure.project`), each distinct
    shadow (with its subregion) once; the tetrahedra of one prism, and the halves of a
    tetrahedron bisected along the axis, share theirs."""
    tri, single = enc.project(corners)
    m = len(tri)
    key = tri.reshape(m, -1)
    if own is not None:
        key = np.column_stack([key, own])
    _, first, inv = unique(key, axis=0, return_index=True, return_inverse=True)
    count = np.where(single[first], 1, 4)
    owner = np.repeat(np.arange(len(first)), count)
    slot = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
    pieces = tri[first[owner], slot]
    reg = None if own is None else own[first]
    return _bound(field2d, enc.inner, pieces, owner, reg, rtol, atol, max_depth,
                  threshold)[inv.reshape(-1)]


def _bound(base, enc, corners, owner, own, rtol, atol, max_depth, threshold) -> np.ndarray:
    """The bound of :func:`certified_delta` for elements covered by the pieces ``corners``
    (``(K, d + 1, d)``, each a subset of element ``owner[k]``, ``owner`` sorted and every
    element present) whose union is the element, or its image in ``base``'s coordinates."""
    m_el = int(owner[-1]) + 1
    dim = corners.shape[2]
    nchild = 2 ** dim  # children per split piece
    pieces = corners
    s = _samples(base, pieces, None if own is None else own[owner])
    starts = unique(owner, return_index=True)[1]
    smax = _group(np.fmax.reduce(s, axis=1), starts, np.fmax)  # witnessed (M, m)
    smin = _group(np.fmin.reduce(s, axis=1), starts, np.fmin)
    frozen_hi = np.full_like(smax, -np.inf)
    frozen_lo = np.full_like(smin, np.inf)
    band_hi = np.full_like(smax, np.inf)  # given delta_0: the band pieces are frozen in,
    band_lo = np.full_like(smin, -np.inf)  # the intersection of all bands so far
    bound = np.full(m_el, np.inf)
    work = 0  # pieces enclosed so far
    for depth in range(max_depth + 1):
        work += len(pieces)
        reg = None if own is None else own[owner]
        lo, hi = enc.enclose(pieces, reg)
        live, starts = unique(owner, return_index=True)  # owner is sorted
        HI = np.maximum(np.maximum(frozen_hi[live], _group(hi, starts, np.maximum)), smax[live])
        LO = np.minimum(np.minimum(frozen_lo[live], _group(lo, starts, np.minimum)), smin[live])
        ub = (HI - LO).max(axis=1)
        bound[live] = ub
        seen = np.nan_to_num(smax[live] - smin[live], nan=0.0).max(axis=1)
        settled = ub - seen <= atol + rtol * seen
        if threshold is not None:  # decided: proven below, or witnessed at or above
            settled |= (ub < threshold) | (seen >= threshold)
        log.debug("certify: depth %d, %d pieces, %d open elements", depth, len(pieces),
                  int((~settled).sum()))
        if depth == max_depth or settled.all():
            break
        margin = np.zeros(m_el)
        margin[live] = 0.5 * (atol + rtol * seen)
        mo = margin[owner][:, None]
        top, bottom = smax[owner] + mo, smin[owner] - mo
        if threshold is not None:  # a piece inside the band of width delta_0 around the
            half = 0.5 * threshold * (1.0 - 1e-9)  # witnessed middle needs no split; the
            mid = 0.5 * (smax[live] + smin[live])  # bands met so far are intersected, so
            band_hi[live] = np.fmin(band_hi[live], mid + half)  # that all frozen pieces
            band_lo[live] = np.fmax(band_lo[live], mid - half)  # lie within one band
            top, bottom = np.fmax(top, band_hi[owner]), np.fmin(bottom, band_lo[owner])
        done = np.zeros(m_el, bool)
        done[live[settled]] = True
        keep = done[owner] | ((hi <= top) & (lo >= bottom)).all(axis=1)
        n_next = nchild * int((~keep).sum())
        if n_next > MAX_PIECES or work + n_next > max(MAX_PIECES, WORK_PER_ELEMENT * m_el):
            log.debug("certify: piece budget reached at depth %d", depth)
            break
        fk = ~done[owner] & keep  # pieces of open elements that need no further split
        if fk.any():
            o = owner[fk]
            lv, st = unique(o, return_index=True)
            frozen_hi[lv] = np.maximum(frozen_hi[lv], _group(hi[fk], st, np.maximum))
            frozen_lo[lv] = np.minimum(frozen_lo[lv], _group(lo[fk], st, np.minimum))
        if keep.all():  # nothing left to split: the open elements keep their bounds
            break
        pieces = split_simplices(pieces[~keep])
        owner = np.repeat(owner[~keep], nchild)
        s = _samples(base, pieces, None if own is None else own[owner], first=dim + 1)
        lv, st = unique(owner, return_index=True)
        smax[lv] = np.fmax(smax[lv], _group(np.fmax.reduce(s, axis=1), st, np.fmax))
        smin[lv] = np.fmin(smin[lv], _group(np.fmin.reduce(s, axis=1), st, np.fmin))
    log.debug("certify: %d elements, %d pieces enclosed, bound max %.4g", m_el, work,
              bound.max())
    return bound
