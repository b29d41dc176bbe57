"""Blend features of a feature tree: ``f = W M_first + (1 - W) M_second`` (the paper's
Eqs. 19, 27), the weight ``W`` a formula of distances to other features."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ...errors import ModelFileError
from ...expr import compile_expr
from ...topology import unique
from . import enclose as _enc
from .features import FeatureEval

__all__ = ["BlendFeature"]


class BlendFeature:
    """A region feature ``f = W M_first + (1 - W) M_second`` (Eqs. 19, 27).

    Parameters
    ----------
    fid : str
    first, second : features
    distances : mapping variable name -> geometric feature (e.g. ``{"d_b": bottom}``)
    weights : list of ``(formula text, owner feature id or None)``; for each subregion the
        first rule whose owner is on the subregion's path applies, ``None`` matches all.
    parameters : mapping, optional
        Constants of the formulas.
    """

    geometric = False

    def __init__(self, fid: str, first, second, distances: Mapping[str, object],
                 weights: Sequence[tuple[str, str | None]], parameters=None, where: str = ""):
        self.id = fid
        self.first, self.second = first, second
        self.children = (first, second)
        pre = f"{where}: " if where else ""
        for var, feat in distances.items():
            if not feat.geometric:
                raise ModelFileError(f"{pre}feature {fid!r}: distance {var!r} refers to blend "
                                     f"{feat.id!r}, which has no distance")
        self.distances = dict(distances)
        self.n2 = second.n_regions
        self.n_regions = first.n_regions * self.n2
        variables = tuple(self.distances)
        self.exprs = []
        for text, _owner in weights:
            e = compile_expr(text, variables, parameters,
                             where=f"{pre}feature {fid!r}: weight {text!r}")
            self.exprs.append((e, {v: e.diff(v) for v in e.names}))
        table = []
        for r in range(self.n_regions):
            path = set(self.region_path(r))
            k = next((i for i, (_, owner) in enumerate(weights)
                      if owner is None or owner in path), None)
            if k is None:
                raise ModelFileError(f"{pre}feature {fid!r}: no weight for subregion "
                                     f"{self.region_name(r)!r} (add a default 'weight')")
            table.append(k)
        self.weight_of_region = np.array(table, dtype=np.int64)

    def region_path(self, r: int) -> list[str]:
        r1, r2 = divmod(r, self.n2)
        return [self.id] + self.first.region_path(r1) + self.second.region_path(r2)

    def region_name(self, r: int) -> str:
        r1, r2 = divmod(r, self.n2)
        return f"{self.first.region_name(r1)}|{self.second.region_name(r2)}"

    def region(self, p):
        return self.first.region(p) * self.n2 + self.second.region(p)

    def curves(self) -> list:
        return []

    def evaluate_children(self, p, region):
        """The first and second features evaluated at ``p`` (in the subregions ``region``
        encodes, if given)."""
        r1 = r2 = None
        if region is not None:
            r1, r2 = np.divmod(np.asarray(region, dtype=np.int64), self.n2)
        e1 = self.first.evaluate(p, r1)
        e2 = e1 if self.second is self.first else self.second.evaluate(p, r2)
        return e1, e2

    def weight(self, p, e1, e2):
        """The blend weight ``W`` ``(N,)``, its gradient ``(N, 2)`` and the subregion
        (that of the pair of the children's) at ``p``, given the children's evaluations."""
        cache = {id(self.first): e1, id(self.second): e2}
        dv, dg = {}, {}
        for var, feat in self.distances.items():
            ev = cache.get(id(feat))
            if ev is None:
                ev = cache[id(feat)] = feat.evaluate(p)
            dv[var], dg[var] = ev.dist, ev.ddist
        reg = e1.region * self.n2 + e2.region
        n = len(p)
        W = np.empty(n)
        dW = np.zeros((n, 2))
        widx = self.weight_of_region[reg] if len(self.exprs) > 1 else None
        for k, (e, de) in enumerate(self.exprs):
            if widx is None:
                idx = slice(None)
            else:
                idx = widx == k
                if not idx.any():
                    continue
            vals = {v: a[idx] for v, a in dv.items()}
            W[idx] = e(**vals)
            g = np.zeros((n if widx is None else int(np.count_nonzero(idx)), 2))
            for v, dexpr in de.items():
                g += dexpr(**vals)[:, None] * dg[v][idx]
            dW[idx] = g
        return W, dW, reg

    def enclose(self, box, region=None) -> _enc.Enclosure:
        """Intervals containing the composition at every point of each box ``(xlo, xhi,
        ylo, yhi)``, ``W M_1 + (1 - W) M_2`` enclosed at the corners of the intervals of
        ``W``, ``M_1`` and ``M_2``. ``W`` is enclosed by interval arithmetic on its formula
        over the distances' intervals; where each ``dW/dd_i`` keeps one sign there, by its
        values at the corners of the distances' box (its exact range over that box).
        With ``region``, the subregion's own children and weight; without, the hull over
        the weights (see :mod:`.enclose`)."""
        r1 = r2 = None
        if region is not None:
            r1, r2 = np.divmod(np.asarray(region, dtype=np.int64), self.n2)
        e1 = self.first.enclose(box, r1)
        e2 = e1 if self.second is self.first else self.second.enclose(box, r2)
        cache = {id(self.first): e1, id(self.second): e2}
        dist = {}
        for var, feat in self.distances.items():
            if id(feat) not in cache:
                cache[id(feat)] = feat.enclose(box)
            dist[var] = cache[id(feat)].dist
        n = len(box[0])
        if region is None or len(self.exprs) == 1:
            parts = [self._enclose_weight(k, dist) for k in range(len(self.exprs))]
            w = _enc.hull(parts)
        else:
            widx = self.weight_of_region[np.asarray(region, dtype=np.int64)]
            w = (np.empty(n), np.empty(n))
            for k in unique(widx):
                idx = np.flatnonzero(widx == k)
                lo, hi = self._enclose_weight(
                    int(k), {v: (d[0][idx], d[1][idx]) for v, d in dist.items()})
                w[0][idx], w[1][idx] = lo, hi
        if self.second is self.first:  # W M + (1 - W) M = M
            return _enc.Enclosure(None, e1.comp)
        return _enc.Enclosure(None, _enc.blend(w, e1.comp, e2.comp))

    def _enclose_weight(self, k: int, dist) -> tuple[np.ndarray, np.ndarray]:
        e, de = self.exprs[k]
        lo, hi = e.interval(**dist)
        if not de:
            return lo, hi
        up = {}
        mono = np.ones(len(lo), dtype=bool)
        for v, dexpr in de.items():
            glo, ghi = dexpr.interval(**dist)
            mono &= (glo >= 0.0) | (ghi <= 0.0)
            up[v] = glo >= 0.0
        if not mono.any():
            return lo, hi
        low = {v: np.where(up.get(v, True), d[0], d[1]) for v, d in dist.items()}
        high = {v: np.where(up.get(v, True), d[1], d[0]) for v, d in dist.items()}
        a, b = e.interval(**low), e.interval(**high)
        mlo, mhi = np.minimum(a[0], b[0]), np.maximum(a[1], b[1])
        return np.where(mono, np.maximum(lo, mlo), lo), np.where(mono, np.minimum(hi, mhi), hi)

    def evaluate(self, p, region=None) -> FeatureEval:
        e1, e2 = self.evaluate_children(p, region)
        W, dW, reg = self.weight(p, e1, e2)
        delta = e1.comp - e2.comp
        comp = e2.comp + W[:, None] * delta  # Eqs. (19), (27): W M_1 + (1 - W) M_2
        dcomp = delta[:, :, None] * dW[:, None, :]
        dcomp += W[:, None, None] * e1.dcomp
        dcomp += (1.0 - W)[:, None, None] * e2.dcomp
        return FeatureEval(None, None, comp, dcomp, reg)
