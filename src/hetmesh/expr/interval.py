"""Interval arithmetic over the expression tree: enclosures ``(lo, hi)`` of a formula over
boxes of its variables, rounded outwards."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from functools import reduce
from typing import Any

import numpy as np

from .tree import Node, post_order

__all__ = ["Interval", "build_interval_tape", "run_interval_tape"]

# --------------------------------------------------------------------------- intervals
#: An interval array pair ``(lo, hi)``: every value in ``[lo, hi]`` elementwise.
Interval = tuple[np.ndarray, np.ndarray]
# Outward rounding: bounds are widened by 4 units in the last place (numpy's float
# arithmetic is correctly rounded, its libm functions are within 1-2 ulp), and by the
# smallest normal number near zero.
_ULPS = 4.0 * np.finfo(np.float64).eps
_TINY = np.finfo(np.float64).tiny
_INF = np.inf
_HALF_PI, _TWO_PI = math.pi / 2.0, 2.0 * math.pi


def _out(lo: np.ndarray, hi: np.ndarray) -> Interval:
    """``[lo, hi]`` widened outwards to cover rounding; NaN bounds become infinite."""
    lo = lo - (np.abs(lo) * _ULPS + _TINY)
    hi = hi + (np.abs(hi) * _ULPS + _TINY)
    return np.where(np.isnan(lo), -_INF, lo), np.where(np.isnan(hi), _INF, hi)


def _mono(f: Callable[[np.ndarray], np.ndarray], lo_dom: float = -_INF,
          hi_dom: float = _INF) -> Callable[[Interval], Interval]:
    """An increasing function on ``[lo_dom, hi_dom]``: the argument is clipped to it."""
    def apply(a: Interval) -> Interval:
        lo, hi = np.clip(a[0], lo_dom, hi_dom), np.clip(a[1], lo_dom, hi_dom)
        empty = (a[1] < lo_dom) | (a[0] > hi_dom)  # undefined everywhere on the box
        flo, fhi = _out(f(lo), f(hi))
        return np.where(empty, -_INF, flo), np.where(empty, _INF, fhi)
    return apply


def _i_mul(a: Interval, b: Interval) -> Interval:
    p = [a[i] * b[j] for i in (0, 1) for j in (0, 1)]
    p = [np.where(np.isnan(v), 0.0, v) for v in p]  # 0 * inf is 0 on a closed interval
    return _out(reduce(np.minimum, p), reduce(np.maximum, p))


def _i_div(a: Interval, b: Interval) -> Interval:
    zero = (b[0] <= 0.0) & (b[1] >= 0.0)
    inv = _out(1.0 / np.where(zero, 1.0, b[1]), 1.0 / np.where(zero, 1.0, b[0]))
    lo, hi = _i_mul(a, inv)
    return np.where(zero, -_INF, lo), np.where(zero, _INF, hi)


def _mig_mag(a: Interval) -> Interval:
    """The smallest and largest ``|v|`` over ``[lo, hi]``."""
    alo, ahi = np.abs(a[0]), np.abs(a[1])
    mig = np.where((a[0] <= 0.0) & (a[1] >= 0.0), 0.0, np.minimum(alo, ahi))
    return mig, np.maximum(alo, ahi)


def _i_pow(a: Interval, b: Interval) -> Interval:
    lo_b, hi_b = b
    const = bool(np.all(lo_b == hi_b)) and lo_b.size > 0
    if const and np.all(lo_b == lo_b.flat[0]):
        p = float(lo_b.flat[0])
        if p.is_integer() and abs(p) < 2 ** 53:
            n = int(p)
            if n >= 0:
                if n % 2 == 0:
                    mig, mag = _mig_mag(a)
                    return _out(mig ** n, mag ** n)
                return _out(a[0] ** n, a[1] ** n)
            return _i_div((np.float64(1.0), np.float64(1.0)), _i_pow(a, (-lo_b, -hi_b)))
        lo, hi = np.maximum(a[0], 0.0), a[1]
        empty = a[1] < 0.0
        flo, fhi = (lo ** p, hi ** p) if p > 0 else (hi ** p, lo ** p)
        flo, fhi = _out(flo, fhi)
        return np.where(empty, -_INF, flo), np.where(empty, _INF, fhi)
    # a**b = exp(b log a) for a > 0; elsewhere unbounded (negative bases)
    lg = _mono(np.log, 0.0)(a)
    lo, hi = _I_UNARY["exp"](_i_mul(b, lg))
    ok = a[0] > 0.0
    return np.where(ok, lo, -_INF), np.where(ok, hi, _INF)


def _i_periodic(a: Interval, f, peak: float) -> Interval:
    """``f`` = sin or cos on ``[lo, hi]``: ``f`` is 1 at ``peak + 2 k pi``, -1 half a
    period later."""
    lo, hi = a
    flo, fhi = f(lo), f(hi)
    vlo, vhi = np.minimum(flo, fhi), np.maximum(flo, fhi)

    def holds(at: float) -> np.ndarray:  # some at + 2 k pi in [lo, hi] (rounding: widened)
        k = np.ceil((lo - at) / _TWO_PI - 1e-9)
        return at + k * _TWO_PI <= hi + 1e-9 * np.maximum(1.0, np.abs(hi))

    wide = ~((hi - lo) < _TWO_PI)  # also NaN and infinite bounds
    top = wide | holds(peak)
    bottom = wide | holds(peak + math.pi)
    vlo, vhi = _out(vlo, vhi)
    return np.where(bottom, -1.0, np.maximum(vlo, -1.0)), np.where(top, 1.0,
                                                                   np.minimum(vhi, 1.0))


def _i_tan(a: Interval) -> Interval:
    lo, hi = a
    k = np.ceil((lo - _HALF_PI) / math.pi - 1e-9)  # a pole in [lo, hi]?
    pole = ~((hi - lo) < math.pi) | (_HALF_PI + k * math.pi <= hi + 1e-9 *
                                     np.maximum(1.0, np.abs(hi)))
    flo, fhi = _out(np.tan(lo), np.tan(hi))
    return np.where(pole, -_INF, flo), np.where(pole, _INF, fhi)


def _i_atan2(y: Interval, x: Interval) -> Interval:
    """atan2 over a box: at its corners, unless it holds the origin or straddles the cut
    along the negative x-axis (then [-pi, pi])."""
    c = [np.arctan2(yy, xx) for yy in y for xx in x]
    lo, hi = _out(reduce(np.minimum, c), reduce(np.maximum, c))
    cut = (y[0] <= 0.0) & (y[1] >= 0.0) & (x[0] <= 0.0)
    return np.where(cut, -math.pi - 1e-15, lo), np.where(cut, math.pi + 1e-15, hi)


def _i_cmp(op: str):
    """Comparisons as intervals of truth values: (1, 1) true on the whole box, (0, 0)
    false on it, (0, 1) undecided (also where a side is unbounded or NaN)."""
    strict = op in ("lt", "gt")

    def apply(a: Interval, b: Interval) -> Interval:
        if op in ("gt", "ge"):
            a, b = b, a  # a > b is b < a
        true = (a[1] < b[0]) if strict else (a[1] <= b[0])
        false = (a[0] >= b[1]) if strict else (a[0] > b[1])
        return true.astype(np.float64), (~false).astype(np.float64)
    return apply


def _i_where(c: Interval, a: Interval, b: Interval) -> Interval:
    true, false = c[0] >= 1.0, c[1] <= 0.0
    return (np.where(true, a[0], np.where(false, b[0], np.minimum(a[0], b[0]))),
            np.where(true, a[1], np.where(false, b[1], np.maximum(a[1], b[1]))))


_I_UNARY: dict[str, Callable[[Interval], Interval]] = {
    "neg": lambda a: (-a[1], -a[0]),
    "exp": _mono(np.exp), "log": _mono(np.log, 0.0), "log10": _mono(np.log10, 0.0),
    "sqrt": _mono(np.sqrt, 0.0), "sinh": _mono(np.sinh), "tanh": _mono(np.tanh),
    "arctan": _mono(np.arctan), "arcsin": _mono(np.arcsin, -1.0, 1.0),
    "arccos": lambda a: _I_UNARY["neg"](_mono(lambda v: -np.arccos(v), -1.0, 1.0)(a)),
    "cosh": lambda a: _out(*(np.cosh(v) for v in _mig_mag(a))),
    "abs": lambda a: _mig_mag(a),
    "sign": lambda a: (np.sign(a[0]), np.sign(a[1])),
    "sin": lambda a: _i_periodic(a, np.sin, _HALF_PI),
    "cos": lambda a: _i_periodic(a, np.cos, 0.0),
    "tan": _i_tan,
    "not": lambda a: (1.0 - a[1], 1.0 - a[0]),
}
_I_BINARY: dict[str, Callable[[Interval, Interval], Interval]] = {
    "add": lambda a, b: _out(a[0] + b[0], a[1] + b[1]),
    "sub": lambda a, b: _out(a[0] - b[1], a[1] - b[0]),
    "mul": _i_mul, "div": _i_div, "pow": _i_pow, "atan2": _i_atan2,
    "min": lambda a, b: (np.minimum(a[0], b[0]), np.minimum(a[1], b[1])),
    "max": lambda a, b: (np.maximum(a[0], b[0]), np.maximum(a[1], b[1])),
    "and": lambda a, b: (np.minimum(a[0], b[0]), np.minimum(a[1], b[1])),
    "or": lambda a, b: (np.maximum(a[0], b[0]), np.maximum(a[1], b[1])),
    **{op: _i_cmp(op) for op in ("lt", "le", "gt", "ge")},
}


def build_interval_tape(root: Node) -> list[tuple[str, Any, tuple[int, ...]]]:
    """The distinct nodes in evaluation order as ``(op, value, input slots)``."""
    slot: dict[Node, int] = {}
    tape = []
    for n in post_order(root):
        slot[n] = len(tape)
        tape.append((n.op, n.value, tuple(slot[a] for a in n.args)))
    return tape


def run_interval_tape(tape, env: Mapping[str, Interval]) -> Interval:
    slots: list[Any] = [None] * len(tape)
    for k, (op, value, ins) in enumerate(tape):
        if op == "var":
            lo, hi = env[value]
            lo, hi = np.where(np.isnan(lo), -_INF, lo), np.where(np.isnan(hi), _INF, hi)
            slots[k] = (lo, hi)
        elif op in ("const", "bool"):
            v = np.float64(float(value))
            slots[k] = (v, v)
        elif op == "where":
            slots[k] = _i_where(*(slots[i] for i in ins))
        elif len(ins) == 1:
            slots[k] = _I_UNARY[op](slots[ins[0]])
        else:
            slots[k] = _I_BINARY[op](slots[ins[0]], slots[ins[1]])
    return slots[-1]
