"""Value maps: how stored pixel values become volume fractions (linear between two grey
levels, a lookup table, one channel or file per constituent), checked pixel by pixel.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...errors import MaterialError
from .read import image_error, pixel_index

__all__ = ["ValueMap", "linear_map", "table_map", "channel_map", "TOL"]

#: tolerance of the [0, 1] and sum checks of mapped values
TOL = 1e-9


# ---------------------------------------------------------------------------- value maps
@dataclass(frozen=True)
class ValueMap:
    """How stored pixel values become volume fractions.

    ``kind`` is ``"table"`` (piecewise linear in one grey value: ``levels`` ``(K,)``
    increasing, ``fractions`` ``(K, m)``; :func:`linear_map` is a table of two rows) or
    ``"channels"`` (fraction of constituent ``k`` = (channel ``index[k]`` - lo) / (hi - lo);
    ``index[k] = -1`` for the one constituent that is 1 - the others).
    """

    kind: str
    levels: np.ndarray | None = None
    fractions: np.ndarray | None = None
    index: tuple[int, ...] = ()
    lo: float = 0.0
    hi: float = 1.0
    sum_tol: float = 1e-6

    def __call__(self, values: np.ndarray, where: str = "image",
                 mask: np.ndarray | None = None) -> np.ndarray:
        """Fractions ``(m, *shape)`` of the pixel values ``values`` (``(*shape)`` or
        ``(*shape, c)``); only the pixels where ``mask`` is True are checked (others 0).
        Raises :class:`MaterialError` naming the first bad pixel."""
        return (_apply_table if self.kind == "table" else _apply_channels)(self, values,
                                                                           where, mask)


def linear_map(g0: float, g1: float, k: int, m: int = 2) -> ValueMap:
    """Constituent ``k`` of ``m`` (``m == 2``) varies linearly from 0 at grey level ``g0``
    to 1 at ``g1``; the other is 1 minus it. Values beyond ``[g0, g1]`` map outside [0, 1],
    an error."""
    if m != 2:
        raise MaterialError(f"a linear map needs 2 constituents, got {m} (use a table)")
    if not (math.isfinite(g0) and math.isfinite(g1)) or g0 == g1:
        raise MaterialError(f"linear map: grey levels {g0:g} and {g1:g} must differ")
    f = np.zeros((2, 2))
    f[0, k], f[1, k] = 0.0, 1.0
    f[:, 1 - k] = 1.0 - f[:, k]
    lv = np.array([g0, g1], float)
    if g1 < g0:
        lv, f = lv[::-1].copy(), f[::-1].copy()
    return ValueMap("table", levels=lv, fractions=f, sum_tol=TOL)


def table_map(levels: Sequence[float], fractions: np.ndarray) -> ValueMap:
    """A lookup table: grey ``levels`` ``(K,)`` strictly increasing, ``fractions``
    ``(K, m)`` in [0, 1] with rows summing to 1; linear between the levels."""
    lv = np.asarray(levels, float)
    f = np.asarray(fractions, float)
    if lv.ndim != 1 or len(lv) < 2 or f.shape[0] != len(lv) or f.ndim != 2:
        raise MaterialError(f"a table needs at least 2 levels and one row of fractions per "
                            f"level, got {lv.shape} levels and fractions {f.shape}")
    if not np.all(np.diff(lv) > 0):
        raise MaterialError(f"table levels must increase strictly: {lv.tolist()}")
    if (f < -TOL).any() or (f > 1 + TOL).any():
        raise MaterialError(f"table fractions must lie in [0, 1], got {f.min():g} .. "
                            f"{f.max():g}")
    s = f.sum(axis=1)
    if np.abs(s - 1).max() > TOL:
        i = int(np.argmax(np.abs(s - 1)))
        raise MaterialError(f"table fractions at level {lv[i]:g} sum to {s[i]:g}, not 1")
    return ValueMap("table", levels=lv, fractions=f, sum_tol=TOL)


def channel_map(index: Sequence[int], lo: float, hi: float, *, integer: bool) -> ValueMap:
    """One channel per constituent (``-1``: the constituent that is 1 - the others), scaled
    from ``[lo, hi]`` to [0, 1]. Sums must be 1 within 1e-6, or for integer images within
    the quantisation ``1.5 / (hi - lo)`` per channel (then renormalised)."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        raise MaterialError(f"channel range [{lo:g}, {hi:g}] must increase")
    tol = 1e-6 + (1.5 * len(index) / (hi - lo) if integer else 0.0)
    return ValueMap("channels", index=tuple(int(i) for i in index), lo=float(lo),
                    hi=float(hi), sum_tol=tol)


def _first_bad(bad: np.ndarray) -> tuple:
    return tuple(np.argwhere(bad)[0])


def _apply_table(vm: ValueMap, values, where, mask):
    v = np.asarray(values, float)
    sel = True if mask is None else mask
    lo, hi = vm.levels[0], vm.levels[-1]
    vs = v if mask is None else v[sel]
    tol = TOL * max(1.0, abs(lo), abs(hi))
    if vs.size and (vs.min() < lo - tol or vs.max() > hi + tol):
        worst = np.where(sel, np.maximum(lo - v, v - hi), -np.inf)
        idx = np.unravel_index(int(np.argmax(worst)), v.shape)
        f = vm.fractions
        t = (v[idx] - lo) / (hi - lo)
        row = f[0] + t * (f[-1] - f[0])  # the linear map extended
        k = int(np.argmax(np.maximum(row - 1.0, -row) + 1e-9 * (row > 1)))
        how = (f"maps to {row[k]:.6g}, outside [0, 1]" if len(vm.levels) == 2
               else f"is outside the table's levels [{lo:g}, {hi:g}]")
        raise image_error(where, f"value {v[idx]:g} at pixel {pixel_index(idx)} {how}")
    vc = np.clip(v, lo, hi)
    m = vm.fractions.shape[1]
    res = np.empty((m,) + v.shape)
    for k in range(m):
        res[k] = np.interp(vc, vm.levels, vm.fractions[:, k])
    if mask is not None:
        res[:, ~mask] = 0.0
    return res


def _apply_channels(vm: ValueMap, values, where, mask):
    v = np.asarray(values, float)
    nc = v.shape[-1]
    bad = [i for i in vm.index if i >= nc]
    if bad:
        raise image_error(where, f"channel {bad[0]} does not exist (the image has {nc} channels)")
    shape = v.shape[:-1]
    sel = np.ones(shape, bool) if mask is None else mask
    m = len(vm.index)
    res = np.empty((m,) + shape)
    derived = [k for k in range(m) if vm.index[k] < 0]
    for k, c in enumerate(vm.index):
        if c >= 0:
            res[k] = (v[..., c] - vm.lo) / (vm.hi - vm.lo)
            out = ((res[k] < -TOL) | (res[k] > 1 + TOL)) & sel
            if out.any():
                idx = _first_bad(out)
                raise image_error(where, f"channel {c} value {v[idx + (c,)]:g} at pixel "
                                         f"{pixel_index(idx)} maps to {res[k][idx]:.6g}, "
                                         f"outside [0, 1]")
    given = [k for k in range(m) if k not in derived]
    total = res[given].sum(axis=0)
    if derived:
        k = derived[0]
        res[k] = 1.0 - total
        bad = (res[k] < -vm.sum_tol) & sel
        if bad.any():
            idx = _first_bad(bad)
            raise image_error(where, f"fractions at pixel {pixel_index(idx)} sum to "
                                     f"{total[idx]:.6g}, more than 1")
        res[k] = np.maximum(res[k], 0.0)
        total = res.sum(axis=0)
    err = (np.abs(total - 1.0) > vm.sum_tol) & sel
    if err.any():
        idx = _first_bad(err)
        raise image_error(where, f"fractions at pixel {pixel_index(idx)} sum to "
                                 f"{total[idx]:.6g}, not 1")
    res = np.clip(res, 0.0, 1.0)
    res /= np.where(total > 0, res.sum(axis=0), 1.0)
    if mask is not None:
        res[:, ~mask] = 0.0
    return res
