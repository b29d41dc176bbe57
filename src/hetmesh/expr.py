"""Safe compiler for user formulas, with a symbolic derivative.

Model files are untrusted input: a formula never reaches ``eval``, ``exec``, ``compile``,
``sympify``, ``lambdify`` or ``numexpr``. The text is length-capped, parsed
with ``ast.parse(text, mode="eval")``, checked for node count and nesting depth, and walked
with an allow-list into a small expression tree:

* numbers (int and float literals), the declared variables, the parameters (substituted as
  constants) and the constants ``pi`` and ``e``;
* ``+ - * / **`` and unary ``-``/``+`` (``^`` is rejected: use ``**``);
* calls, by plain name, of the functions in :data:`FUNCTIONS`;
* comparisons ``< <= > >=`` (chained allowed), ``and``, ``or``, ``not`` -- only as the
  condition of ``where(cond, a, b)`` or ``a if cond else b`` (both map to ``np.where``).

The tree is simplified (constant folding, ``0*u``, ``u+0``, ``1*u``, ...) and compiled once
into a flat list of numpy calls sharing common subexpressions, so calls do not walk the tree.
:meth:`Expr.diff` differentiates the same tree (not the text) with the chain rule.

>>> f = compile_expr("((b - y) / b)**2", parameters={"b": 30.0})
>>> f(x=0.0, y=[0.0, 15.0, 30.0])
array([1.  , 0.25, 0.  ])
>>> f.diff("y")(y=15.0)  # -2 * (b - y) / b**2
array(-0.03333333)
>>> sorted(f.names), f.diff("x").constant_value, compile_expr("x**3 + y").diff("x").text
(['y'], 0.0, '3*x**2')
"""

from __future__ import annotations

import ast
import math
import warnings
from collections.abc import Callable, Iterable, Mapping
from functools import partial, reduce
from itertools import accumulate
from typing import Any

import numpy as np

from .errors import FormulaError

__all__ = ["compile_expr", "Expr", "FUNCTIONS", "MAX_LENGTH", "MAX_NODES", "MAX_DEPTH",
           "split_conditions", "Interval"]

MAX_LENGTH = 1000  #: longest accepted formula, in characters
MAX_NODES = 500  #: most expression nodes in a parsed formula
MAX_DEPTH = 50  #: deepest nesting of expressions (and of brackets) in a formula

#: Allowed function name -> (canonical name, number of arguments; None: two or more).
FUNCTIONS: dict[str, tuple[str, int | None]] = {
    **{f: (f, 1) for f in ("sin", "cos", "tan", "arcsin", "arccos", "arctan", "sinh", "cosh",
                           "tanh", "exp", "log", "log10", "sqrt", "abs", "sign")},
    "asin": ("arcsin", 1), "acos": ("arccos", 1), "atan": ("arctan", 1),
    "atan2": ("atan2", 2), "arctan2": ("atan2", 2), "min": ("min", None),
    "max": ("max", None), "clip": ("clip", 3), "where": ("where", 3),
}
_CONSTANTS = {"pi": math.pi, "e": math.e}
# op name -> numpy callable; used both by constant folding and by the compiled tape.
_APPLY: dict[str, Callable[..., Any]] = {
    "add": np.add, "sub": np.subtract, "mul": np.multiply, "div": np.divide,
    "pow": np.power, "neg": np.negative,
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "arcsin": np.arcsin, "arccos": np.arccos,
    "arctan": np.arctan, "atan2": np.arctan2, "sinh": np.sinh, "cosh": np.cosh,
    "tanh": np.tanh, "exp": np.exp, "log": np.log, "log10": np.log10, "sqrt": np.sqrt,
    "abs": np.abs, "sign": np.sign, "min": np.minimum, "max": np.maximum, "where": np.where,
    "lt": np.less, "le": np.less_equal, "gt": np.greater, "ge": np.greater_equal,
    "and": np.logical_and, "or": np.logical_or, "not": np.logical_not,
}
_CMPOPS = {ast.Lt: "lt", ast.LtE: "le", ast.Gt: "gt", ast.GtE: "ge"}
_OPSYMBOLS = {ast.FloorDiv: "//", ast.Mod: "%", ast.MatMult: "@", ast.LShift: "<<",
              ast.RShift: ">>", ast.BitOr: "|", ast.BitAnd: "&", ast.Eq: "==",
              ast.NotEq: "!=", ast.Is: "is", ast.IsNot: "is not", ast.In: "in",
              ast.NotIn: "not in", ast.Invert: "~"}
_FORBIDDEN = {kind: message for kinds, message in [
    ((ast.Attribute,), "attribute access is not allowed"),
    ((ast.Subscript, ast.Slice), "subscripts are not allowed"),
    ((ast.Lambda,), "lambda is not allowed"),
    ((ast.JoinedStr, ast.FormattedValue), "f-strings are not allowed"),
    ((ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp),
     "comprehensions are not allowed"),
    ((ast.NamedExpr,), "assignment (:=) is not allowed"),
    ((ast.Starred,), "starred arguments are not allowed"),
    ((ast.List, ast.Tuple, ast.Set, ast.Dict), "lists, tuples, sets and dicts are not allowed"),
    ((ast.Await, ast.Yield, ast.YieldFrom), "await and yield are not allowed"),
] for kind in kinds}
_CONDITION_ONLY = ("comparisons, 'and', 'or' and 'not' are only allowed in the condition "
                   "of where(cond, a, b) or 'a if cond else b'")


# --------------------------------------------------------------------------- tree nodes
class _Node:
    """Immutable node: ``op`` in _APPLY, or a leaf 'const' / 'bool' / 'var'."""

    __slots__ = ("op", "args", "value", "names", "_hash")

    def __init__(self, op: str, args: tuple[_Node, ...] = (), value: Any = None) -> None:
        self.op, self.args, self.value = op, args, value
        self.names: frozenset[str] = frozenset((value,)) if op == "var" else \
            frozenset().union(*(a.names for a in args))
        self._hash = hash((op, value, args))

    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other: object) -> bool:
        return self is other or (
            isinstance(other, _Node) and self._hash == other._hash and self.op == other.op
            and self.value == other.value and self.args == other.args)

    def is_const(self, value: float | None = None) -> bool:
        return self.op == "const" and (value is None or self.value == value)


def _const(value: Any) -> _Node:
    return _Node("const", value=float(value) + 0.0)  # + 0.0 turns -0.0 into 0.0


ZERO, ONE, TWO = _const(0.0), _const(1.0), _const(2.0)


def _make(op: str, *args: _Node) -> _Node:
    """Build ``op(*args)``, folding it when every argument is a constant."""
    if all(a.op in ("const", "bool") for a in args):
        with np.errstate(all="ignore"):
            value = _APPLY[op](*(a.value for a in args))
        if op in ("lt", "le", "gt", "ge", "and", "or", "not"):
            return _Node("bool", value=bool(value))
        return _const(value)
    return _Node(op, args)


def _minus(n: _Node) -> bool:
    """Whether ``n`` reads better with its sign moved: -u, a negative constant, -2*u."""
    c = n.args[0] if n.op == "mul" else n
    return n.op == "neg" or (c.is_const() and c.value < 0)


def _add(a: _Node, b: _Node) -> _Node:
    if a.is_const(0.0) or b.is_const(0.0):
        return b if a.is_const(0.0) else a
    return _sub(a, _neg(b)) if _minus(b) else _make("add", a, b)


def _sub(a: _Node, b: _Node) -> _Node:
    if a.is_const(0.0) or b.is_const(0.0):
        return a if b.is_const(0.0) else _neg(b)
    if _minus(b):
        return _add(a, _neg(b))
    if b.is_const() and a.op in ("add", "sub") and a.args[1].is_const():  # (u - 1) - 1
        c = a.args[1].value
        return _add(a.args[0], _const(c - b.value)) if a.op == "add" else \
            _sub(a.args[0], _const(c + b.value))
    return _make("sub", a, b)


def _neg(a: _Node) -> _Node:
    if a.op == "neg":
        return a.args[0]
    if a.op == "mul" and a.args[0].is_const():
        return _mul(_const(-a.args[0].value), a.args[1])
    return _make("neg", a)


def _mul(a: _Node, b: _Node) -> _Node:
    if b.is_const() and not a.is_const():
        a, b = b, a  # constant factor first
    if a.is_const(0.0) or b.is_const(0.0):
        return ZERO
    if a.is_const(1.0) or a.is_const(-1.0):
        return b if a.value == 1.0 else _neg(b)
    if a.is_const() and b.op == "mul" and b.args[0].is_const():  # 2*(3*u) = 6*u
        return _mul(_make("mul", a, b.args[0]), b.args[1])
    if a.is_const() and b.op == "neg":
        return _mul(_const(-a.value), b.args[0])
    return _make("mul", a, b)


def _div(a: _Node, b: _Node) -> _Node:
    return ZERO if a.is_const(0.0) else a if b.is_const(1.0) else _make("div", a, b)


def _pow(a: _Node, b: _Node) -> _Node:
    if b.is_const(0.0) or a.is_const(1.0):
        return ONE
    return a if b.is_const(1.0) else _make("pow", a, b)


def _where(c: _Node, a: _Node, b: _Node) -> _Node:
    if c.op == "bool" or a == b:
        return a if a == b or c.value else b
    return _make("where", c, a, b)


def _logic(op: str, a: _Node, b: _Node) -> _Node:
    for p, q in ((a, b), (b, a)):
        if p.op == "bool":  # True and q -> q, False and q -> False; dually for 'or'
            return q if p.value == (op == "and") else p
    return _make(op, a, b)


# --------------------------------------------------------------------------- derivative
def _diff(n: _Node, x: str, memo: dict[_Node, _Node]) -> _Node:
    """d n / d x by the chain rule, simplified; ``memo`` shares results of shared nodes."""
    if x not in n.names:
        return ZERO
    if n not in memo:
        d = [_diff(a, x, memo) for a in n.args]
        rule = _RULES.get(n.op)
        memo[n] = rule(n, n.args, d, x) if rule else _mul(_OUTER[n.op](n.args[0], n), d[0])
    return memo[n]


def _d_pow(n: _Node, args: tuple[_Node, ...], d: list[_Node], x: str) -> _Node:
    a, b = args
    if x not in b.names:  # a**c -> c * a**(c - 1) * a'
        return _mul(_mul(b, _pow(a, _sub(b, ONE))), d[0])
    if x not in a.names:  # c**b -> c**b * log(c) * b'
        return _mul(_mul(n, _make("log", a)), d[1])
    return _mul(n, _add(_mul(d[1], _make("log", a)), _div(_mul(b, d[0]), a)))


#: derivative rules (node, its arguments, their derivatives, variable) -> derivative
_RULES: dict[str, Callable[[_Node, tuple[_Node, ...], list[_Node], str], _Node]] = {
    "var": lambda n, a, d, x: ONE,
    "add": lambda n, a, d, x: _add(d[0], d[1]),
    "sub": lambda n, a, d, x: _sub(d[0], d[1]),
    "neg": lambda n, a, d, x: _neg(d[0]),
    "mul": lambda n, a, d, x: _add(_mul(d[0], a[1]), _mul(a[0], d[1])),
    "div": lambda n, a, d, x: _div(d[0], a[1]) if x not in a[1].names else
    _div(_sub(_mul(d[0], a[1]), _mul(a[0], d[1])), _pow(a[1], TWO)),
    "pow": _d_pow,
    "atan2": lambda n, a, d, x: _div(_sub(_mul(a[1], d[0]), _mul(a[0], d[1])),
                                     _add(_pow(a[0], TWO), _pow(a[1], TWO))),
    "min": lambda n, a, d, x: _where(_make("le", a[0], a[1]), d[0], d[1]),
    "max": lambda n, a, d, x: _where(_make("ge", a[0], a[1]), d[0], d[1]),
    "where": lambda n, a, d, x: _where(a[0], d[1], d[2]),
    **dict.fromkeys(("sign", "lt", "le", "gt", "ge", "and", "or", "not"),
                    lambda n, a, d, x: ZERO),
}
_SQRT_1_U2 = lambda u: _make("sqrt", _sub(ONE, _pow(u, TWO)))  # noqa: E731
#: f'(u) for one-argument functions f, given u and n = f(u).
_OUTER: dict[str, Callable[[_Node, _Node], _Node]] = {
    "sin": lambda u, n: _make("cos", u),
    "cos": lambda u, n: _neg(_make("sin", u)),
    "tan": lambda u, n: _div(ONE, _pow(_make("cos", u), TWO)),
    "arcsin": lambda u, n: _div(ONE, _SQRT_1_U2(u)),
    "arccos": lambda u, n: _div(_const(-1.0), _SQRT_1_U2(u)),
    "arctan": lambda u, n: _div(ONE, _add(ONE, _pow(u, TWO))),
    "sinh": lambda u, n: _make("cosh", u),
    "cosh": lambda u, n: _make("sinh", u),
    "tanh": lambda u, n: _sub(ONE, _pow(n, TWO)),
    "exp": lambda u, n: n,
    "log": lambda u, n: _div(ONE, u),
    "log10": lambda u, n: _div(ONE, _mul(_const(math.log(10.0)), u)),
    "sqrt": lambda u, n: _div(ONE, _mul(TWO, n)),
    "abs": lambda u, n: _make("sign", u),
}


# --------------------------------------------------------------------------- printing
_INFIX = {"add": (" + ", 5), "sub": (" - ", 5), "mul": ("*", 6), "div": ("/", 6),
          "pow": ("**", 8), "lt": (" < ", 4), "le": (" <= ", 4), "gt": (" > ", 4),
          "ge": (" >= ", 4), "and": (" and ", 2), "or": (" or ", 1)}


def _to_text(n: _Node) -> tuple[str, int]:
    """Readable source for a tree and its precedence (higher binds tighter)."""
    if n.op == "const":
        v = n.value
        if not math.isfinite(v):
            return ("nan" if math.isnan(v) else "inf" if v > 0 else "-inf"), 9
        s = str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)
        return s, (7 if v < 0 else 9)
    if n.op in ("var", "bool"):
        return str(n.value), 9
    if n.op == "neg":
        s, p = _to_text(n.args[0])
        return "-" + (s if p >= 7 else f"({s})"), 7
    if n.op == "not":
        s, p = _to_text(n.args[0])
        return "not " + (s if p > 3 else f"({s})"), 3
    if n.op in _INFIX:
        sym, prec = _INFIX[n.op]
        (ls, lp), (rs, rp) = _to_text(n.args[0]), _to_text(n.args[1])
        left_ok, right_ok = (lp > prec, rp >= 7) if n.op == "pow" else (lp >= prec, rp > prec)
        return (ls if left_ok else f"({ls})") + sym + (rs if right_ok else f"({rs})"), prec
    return f"{n.op}({', '.join(_to_text(a)[0] for a in n.args)})", 9


# --------------------------------------------------------------------------- evaluation
def _build_tape(root: _Node) -> list[tuple[int, Any, tuple[int, ...], tuple[int, ...]]]:
    """Flatten the tree into numpy calls in evaluation order, sharing equal subtrees.

    Each entry is ``(kind, payload, input slots, slots to free afterwards)`` with kind 0 a
    constant, 1 a variable, 2 a numpy call; freeing keeps memory at a few arrays.
    """
    slot: dict[_Node, int] = {}
    order: list[tuple[_Node, tuple[int, ...]]] = []
    stack: list[tuple[_Node, bool]] = [(root, False)]
    while stack:  # iterative post-order: no recursion limit on deep trees
        n, expanded = stack.pop()
        if n in slot:
            continue
        if expanded or not n.args:
            slot[n] = len(order)
            order.append((n, tuple(slot[a] for a in n.args)))
        else:
            stack.append((n, True))
            stack.extend((a, False) for a in reversed(n.args))
    last = {i: k for k, (_, ins) in enumerate(order) for i in ins}
    return [((2, _APPLY[n.op]) if n.args else (1, n.value) if n.op == "var" else
             (0, np.float64(n.value) if n.op == "const" else n.value))
            + (ins, tuple({i for i in ins if last[i] == k})) for k, (n, ins) in enumerate(order)]


def _run(tape: list[tuple[int, Any, tuple[int, ...], tuple[int, ...]]],
         env: Mapping[str, np.ndarray]) -> Any:
    slots: list[Any] = [None] * len(tape)
    for k, (kind, payload, ins, frees) in enumerate(tape):
        slots[k] = payload(*[slots[i] for i in ins]) if kind == 2 else \
            env[payload] if kind == 1 else payload
        for i in frees:
            slots[i] = None
    return slots[-1]


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


def _build_itape(root: _Node) -> list[tuple[str, Any, tuple[int, ...]]]:
    """The distinct nodes in evaluation order as ``(op, value, input slots)``."""
    slot: dict[_Node, int] = {}
    tape = []
    for n in _post_order(root):
        slot[n] = len(tape)
        tape.append((n.op, n.value, tuple(slot[a] for a in n.args)))
    return tape


def _irun(tape, env: Mapping[str, Interval]) -> Interval:
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


class Expr:
    """A compiled formula: call it with arrays, differentiate it symbolically.

    Attributes
    ----------
    text : str
        The source text (for a derivative, the printed derivative tree).
    names : frozenset of str
        The variables the formula actually uses (a subset of ``variables``).
    variables : tuple of str
        The variables the formula was compiled with; calls accept exactly these keywords.
    where : str
        Prefix of error messages (e.g. ``"plate.toml: material.composition.metal"``).
    """

    __slots__ = ("_text", "_node", "_tape", "_itape", "names", "variables", "where")

    def __init__(self, node: _Node, variables: tuple[str, ...], where: str,
                 text: str | None = None) -> None:
        self._node, self._text, self._tape = node, text, _build_tape(node)
        self._itape: list | None = None
        self.names, self.variables, self.where = node.names, variables, where

    @property
    def text(self) -> str:  # a derivative is printed on first use
        if self._text is None:
            self._text = _to_text(self._node)[0]
        return self._text

    @property
    def constant_value(self) -> float | None:
        """The value if the (simplified) formula uses no variable, else None."""
        return self._node.value if self._node.op == "const" else None

    def __repr__(self) -> str:
        return f"Expr({self.text!r})"

    def __call__(self, **values: Any) -> np.ndarray:
        """Evaluate on broadcast arrays; returns a new float64 array of the broadcast shape.

        Non-finite values (log(0), 1/0, ...) are returned as they are, without warnings.
        """
        wrong = [f"unexpected variable {k!r}" for k in values if k not in self.variables] + \
            [f"missing value for {k!r}" for k in sorted(self.names.difference(values))]
        if wrong:
            raise TypeError(f"{self.where}: {wrong[0]} (variables: {', '.join(self.variables)})")
        env = {k: np.asarray(v, dtype=np.float64) for k, v in values.items()}
        shape = np.broadcast_shapes(*(a.shape for a in env.values()))
        with np.errstate(all="ignore"):
            result = _run(self._tape, env)
        if (not isinstance(result, np.ndarray) or result.shape != shape
                or result.dtype != np.float64 or any(result is a for a in env.values())):
            result = np.array(np.broadcast_to(result, shape), dtype=np.float64)
        return result

    def interval(self, **bounds: Any) -> Interval:
        """An enclosure of the formula's values over boxes: interval arithmetic on the tree.

        Each variable is given as a pair ``(lo, hi)`` of broadcasting arrays (or one array,
        a point). The result ``(lo, hi)`` contains every value the formula takes at points
        of the box where it is defined (rounding outwards, see :data:`Interval`); a box on
        which some operation may be unbounded (a division by an interval holding 0) gives
        ``(-inf, inf)``. Conditions are three-valued: where a comparison is not decided on
        the box, ``where(c, a, b)`` gives the hull of both branches.

        >>> lo, hi = compile_expr("x**2 - y").interval(x=(-1.0, 2.0), y=(0.0, 1.0))
        >>> float(lo) <= -1.0 and 4.0 <= float(hi) < 4.0 + 1e-12
        True
        >>> [float(v) for v in compile_expr("where(x < 0, 0, 1)").interval(x=(0.5, 2.0))]
        [1.0, 1.0]
        """
        wrong = [f"unexpected variable {k!r}" for k in bounds if k not in self.variables] + \
            [f"missing value for {k!r}" for k in sorted(self.names.difference(bounds))]
        if wrong:
            raise TypeError(f"{self.where}: {wrong[0]} (variables: {', '.join(self.variables)})")
        env = {}
        for k, v in bounds.items():
            lo, hi = v if isinstance(v, tuple) else (v, v)
            env[k] = (np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64))
        if self._itape is None:
            self._itape = _build_itape(self._node)
        with np.errstate(all="ignore"):
            lo, hi = _irun(self._itape, env)
        shape = np.broadcast_shapes(*(a.shape for pair in env.values() for a in pair))
        return (np.array(np.broadcast_to(lo, shape), dtype=np.float64),
                np.array(np.broadcast_to(hi, shape), dtype=np.float64))

    def diff(self, name: str) -> Expr:
        """Symbolic derivative with respect to the variable ``name`` (chain rule on the tree).

        >>> compile_expr("x**3 + sin(y)").diff("x").text
        '3*x**2'
        """
        if name not in self.variables:
            raise FormulaError(f"{self.where}: cannot differentiate with respect to {name!r} "
                               f"(variables: {', '.join(self.variables)})")
        try:
            node = _diff(self._node, name, {})
        except RecursionError:
            raise FormulaError(f"{self.where}: formula too complex to differentiate") from None
        return Expr(node, self.variables, self.where)


# --------------------------------------------------------------------------- conditions
_COMPARISONS = ("lt", "le", "gt", "ge")


def _post_order(root: _Node):
    """The distinct nodes of a tree, children before parents, left to right (iterative)."""
    seen: set[_Node] = set()
    stack: list[tuple[_Node, bool]] = [(root, False)]
    while stack:
        n, expanded = stack.pop()
        if n in seen:
            continue
        if expanded or not n.args:
            seen.add(n)
            yield n
        else:
            stack.append((n, True))
            stack.extend((a, False) for a in reversed(n.args))


def _jump_atoms(root: _Node) -> list[_Node]:
    """The comparisons on which the value of ``root`` may jump, in post-order.

    Every comparison inside the condition of a ``where`` (``a if c else b``), and for
    ``sign(u)`` the comparison ``u >= 0``. The formula is smooth (or merely kinked, as
    ``abs``, ``min``, ``max``, ``clip`` are) where none of them changes.
    """
    out: dict[_Node, None] = {}
    for n in _post_order(root):
        if n.op in _COMPARISONS:
            out[n] = None
        elif n.op == "sign":
            out[_Node("ge", (n.args[0], ZERO))] = None
    return list(out)


def _substitute(n: _Node, table: dict[_Node, _Node], memo: dict[_Node, _Node]) -> _Node:
    """``n`` with every node of ``table`` replaced, and ``sign(u)`` written as
    ``where(u >= 0, 1, -1)`` with the comparison replaced too (iterative, shares subtrees)."""
    for m in _post_order(n):
        if m in memo:
            continue
        if m in table:
            memo[m] = table[m]
        elif m.op == "sign":
            memo[m] = _Node("where", (table[_Node("ge", (m.args[0], ZERO))], ONE,
                                      _const(-1.0)))
        elif m.args:
            args = tuple(memo[a] for a in m.args)
            memo[m] = m if all(a is b for a, b in zip(args, m.args)) else _Node(m.op, args,
                                                                                m.value)
        else:
            memo[m] = m
    return memo[n]


def split_conditions(exprs: Iterable[Expr], prefix: str = "_c"
                     ) -> tuple[list[Expr], list[Expr]]:
    """The jump conditions of formulas, and the formulas with those conditions as inputs.

    A formula jumps only where one of its conditions changes: the comparisons in the
    condition of ``where(cond, a, b)`` / ``a if cond else b``, and ``u >= 0`` for
    ``sign(u)``. Between those curves it is smooth (up to kinks).

    Parameters
    ----------
    exprs : iterable of Expr
        Formulas compiled with the same variables.
    prefix : str
        Names of the boolean variables that stand for the conditions: ``prefix + "0"``,
        ``prefix + "1"``, ... (the default ``_c`` cannot clash with a variable or parameter
        of a model file).

    Returns
    -------
    conditions : list of Expr
        Every distinct condition once, in the order it first occurs (formula by formula,
        left to right). Each evaluates to 1.0 where it holds and 0.0 elsewhere (also where
        a side is NaN).
    fixed : list of Expr
        For each formula, the same formula with condition ``i`` replaced by the variable
        ``prefix + str(i)`` (and ``sign(u)`` by ``where(u >= 0, 1, -1)``). Called with the
        conditions' own values it equals the formula (except ``sign(0)``, which becomes 1);
        called with values fixed, it is the smooth branch those values select, continued past
        the curves where they change. Its derivatives treat the conditions as constants.

    Examples
    --------
    >>> conds, (f,) = split_conditions([compile_expr("where(x < 0.5, 0.2, 0.8) + sign(y)")])
    >>> [c.text for c in conds], f.text
    (['x < 0.5', 'y >= 0'], 'where(_c0, 0.2, 0.8) + where(_c1, 1, -1)')
    >>> float(f(x=0.9, y=-1.0, _c0=True, _c1=True))
    1.2
    """
    exprs = list(exprs)
    atoms: dict[_Node, None] = {}
    for e in exprs:
        atoms.update(dict.fromkeys(_jump_atoms(e._node)))
    names = [f"{prefix}{i}" for i in range(len(atoms))]
    table = {a: _Node("var", value=v) for a, v in zip(atoms, names)}
    conditions = [Expr(a, e0.variables, e0.where) for a, e0 in
                  zip(atoms, [exprs[0]] * len(atoms))] if exprs else []
    fixed = []
    for e in exprs:
        node = _substitute(e._node, table, {}) if atoms else e._node
        fixed.append(Expr(node, (*e.variables, *names), e.where,
                          text=None if node is not e._node else e.text))
    return conditions, fixed


# --------------------------------------------------------------------------- parsing
_BINOPS = {ast.Add: _add, ast.Sub: _sub, ast.Mult: _mul, ast.Div: _div, ast.Pow: _pow}


class _Converter:
    """Walk a parsed formula with the allow-list, producing a simplified tree."""

    def __init__(self, where: str, variables: tuple[str, ...],
                 parameters: dict[str, float]) -> None:
        self.where, self.variables, self.parameters = where, variables, parameters

    def fail(self, message: str) -> FormulaError:
        return FormulaError(f"{self.where}: {message}")

    def expr(self, node: ast.AST) -> _Node:
        if isinstance(node, ast.Constant):
            return self.constant(node.value)
        if isinstance(node, ast.Name):
            return self.name(node.id)
        if isinstance(node, ast.BinOp):
            build = _BINOPS.get(type(node.op))
            if build is None:
                raise self.fail("'^' is not allowed; use ** for powers"
                                if isinstance(node.op, ast.BitXor) else
                                f"operator '{_OPSYMBOLS.get(type(node.op), '?')}' is not "
                                "allowed (allowed: + - * / **)")
            return build(self.expr(node.left), self.expr(node.right))
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, (ast.USub, ast.UAdd)):
                u = self.expr(node.operand)
                return _neg(u) if isinstance(node.op, ast.USub) else u
            raise self.fail(_CONDITION_ONLY if isinstance(node.op, ast.Not)
                            else "operator '~' is not allowed")
        if isinstance(node, ast.Call):
            return self.call(node)
        if isinstance(node, ast.IfExp):
            return _where(self.cond(node.test), self.expr(node.body), self.expr(node.orelse))
        if isinstance(node, (ast.Compare, ast.BoolOp)):
            raise self.fail(_CONDITION_ONLY)
        message = _FORBIDDEN.get(type(node))
        raise self.fail(message or f"{type(node).__name__} expressions are not allowed")

    def cond(self, node: ast.AST) -> _Node:
        if isinstance(node, ast.Compare):  # a < b <= c means (a < b) and (b <= c)
            for op in node.ops:
                if type(op) not in _CMPOPS:
                    raise self.fail(f"comparison '{_OPSYMBOLS.get(type(op), '?')}' is not "
                                    "allowed (use <, <=, >, >=)")
            terms = [self.expr(node.left), *map(self.expr, node.comparators)]
            return reduce(partial(_logic, "and"), [_make(_CMPOPS[type(op)], a, b) for op, a, b
                                                   in zip(node.ops, terms, terms[1:])])
        if isinstance(node, ast.BoolOp):
            op = "and" if isinstance(node.op, ast.And) else "or"
            return reduce(partial(_logic, op), map(self.cond, node.values))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            return _make("not", self.cond(node.operand))
        raise self.fail("a condition must be a comparison such as 'x > 0' "
                        "(optionally combined with and, or, not)")

    def constant(self, value: object) -> _Node:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            try:
                return _const(float(value))
            except OverflowError:
                raise self.fail("number is too large") from None
        raise self.fail("strings are not allowed" if isinstance(value, (str, bytes)) else
                        "complex numbers are not allowed" if isinstance(value, complex) else
                        f"{value!r} is not allowed")

    def name(self, ident: str) -> _Node:
        if "__" in ident:
            raise self.fail(f"names containing '__' are not allowed ({ident!r})")
        if ident in self.variables:
            return _Node("var", value=ident)
        if ident in self.parameters:
            return _const(self.parameters[ident])
        if ident in _CONSTANTS:
            return _const(_CONSTANTS[ident])
        if ident in FUNCTIONS:
            raise self.fail(f"{ident!r} is a function; call it as {ident}(...)")
        allowed = ", ".join([*self.variables, *self.parameters])
        raise self.fail(f"unknown name {ident!r} (allowed: {allowed})")

    def call(self, node: ast.Call) -> _Node:
        if not isinstance(node.func, ast.Name):  # x.f(), (lambda: 1)(), f(x)(y), ...
            raise self.fail(_FORBIDDEN.get(
                type(node.func), "only calls of named functions such as sin(x) are allowed"))
        fname = node.func.id
        if "__" in fname:
            raise self.fail(f"names containing '__' are not allowed ({fname!r})")
        if fname not in FUNCTIONS:
            raise self.fail(f"unknown function {fname!r} "
                            f"(allowed: {', '.join(sorted(FUNCTIONS))})")
        op, arity = FUNCTIONS[fname]
        if node.keywords:
            raise self.fail(f"keyword arguments are not allowed (in {fname}())")
        if any(isinstance(a, ast.Starred) for a in node.args):
            raise self.fail(f"starred arguments are not allowed (in {fname}())")
        n = len(node.args)
        if (arity is None and n < 2) or (arity is not None and n != arity):
            need = "at least 2 arguments" if arity is None else \
                f"{arity} argument{'s' if arity > 1 else ''}"
            raise self.fail(f"{fname}() takes {need} (got {n})")
        if op == "where":
            return _where(self.cond(node.args[0]), self.expr(node.args[1]),
                          self.expr(node.args[2]))
        args = [self.expr(a) for a in node.args]
        if op == "clip":  # clip(u, lo, hi) = min(max(u, lo), hi), as np.clip
            return _make("min", _make("max", args[0], args[1]), args[2])
        return _make(op, *args) if arity else reduce(partial(_make, op), args)  # min, max


def _check_size(text: str, fail: Callable[[str], FormulaError]) -> ast.AST:
    """Length cap, bracket depth, parse, then node count and expression depth."""
    if len(text) > MAX_LENGTH:
        raise fail(f"formula is too long ({len(text)} characters, at most {MAX_LENGTH})")
    too_deep = f"formula is nested too deeply (more than {MAX_DEPTH} levels)"
    # deep brackets are refused before Python's own parser sees them
    if max(accumulate((c in "([{") - (c in ")]}") for c in text), default=0) > MAX_DEPTH:
        raise fail(too_deep)
    stripped = text.strip()
    if not stripped:
        raise fail("empty formula")
    try:
        with warnings.catch_warnings():  # e.g. SyntaxWarning: invalid decimal literal
            warnings.simplefilter("ignore")
            tree = ast.parse(stripped, mode="eval")
    except SyntaxError as exc:
        line, col = exc.lineno or 1, exc.offset or len(stripped) + 1
        col = max(col, 1) + (len(text) - len(text.lstrip()) if line == 1 else 0)
        at = f"line {line}, column {col}" if line > 1 else f"column {col}"
        detail = str(exc.msg).splitlines()[0] if exc.msg else "invalid syntax"
        raise fail(f"syntax error at {at}: {detail}") from None
    except ValueError as exc:  # e.g. null bytes on some Python versions
        raise fail(f"syntax error: {str(exc).splitlines()[0]}") from None
    except (RecursionError, MemoryError):
        raise fail(too_deep) from None
    count, stack = 0, [(tree.body, 1)]
    while stack:  # the converter only descends into expression children, so count those
        node, level = stack.pop()
        count += 1
        if level > MAX_DEPTH or count > MAX_NODES:
            raise fail(too_deep if level > MAX_DEPTH else
                       f"formula is too large (more than {MAX_NODES} nodes)")
        stack.extend((c, level + 1) for c in ast.iter_child_nodes(node)
                     if isinstance(c, ast.expr))
    return tree.body


def compile_expr(text: str, variables: Iterable[str] = ("x", "y"),
                 parameters: Mapping[str, float] | None = None, *,
                 where: str = "formula") -> Expr:
    """Compile an untrusted formula into a vectorised :class:`Expr`.

    Parameters
    ----------
    text : str
        The formula, e.g. ``"((b - y)/b)**2"``.
    variables : iterable of str
        Names bound at call time (coordinates, distances such as ``d_b``).
    parameters : mapping of str to float, optional
        Names substituted as constants at compile time; they shadow ``pi`` and ``e``.
    where : str
        Prefix of every error message, e.g. ``"plate.toml: material.composition.metal"``.

    Raises
    ------
    FormulaError
        One-line message: syntax error, unknown name or function, forbidden construct, or
        a formula over :data:`MAX_LENGTH` characters, :data:`MAX_NODES` nodes or
        :data:`MAX_DEPTH` levels of nesting.

    Examples
    --------
    >>> f = compile_expr("exp(-5*d/(d + t))", variables=("d",), parameters={"t": 2.0})
    >>> f(d=[0.0, 2.0])
    array([1.      , 0.082085])
    """
    def fail(message: str) -> FormulaError:
        return FormulaError(f"{where}: {message}")

    if not isinstance(text, str):
        raise fail(f"a formula must be a string, got {type(text).__name__}")
    variables = tuple(dict.fromkeys(variables))
    for v in variables:
        if not isinstance(v, str) or not v.isidentifier() or "__" in v:
            raise fail(f"invalid variable name {v!r}")
    params: dict[str, float] = {}
    for key, value in (parameters or {}).items():
        if key in variables:
            raise fail(f"{key!r} is both a variable and a parameter")
        try:
            params[key] = float(value) if not isinstance(value, (bool, str)) else math.nan
        except (TypeError, ValueError, OverflowError):
            params[key] = math.nan
        if not math.isfinite(params[key]):
            raise fail(f"parameter {key!r} must be a finite number, got {value!r:.40}")
    body = _check_size(text, fail)
    try:
        node = _Converter(where, variables, params).expr(body)
    except RecursionError:
        raise fail(f"formula is nested too deeply (more than {MAX_DEPTH} levels)") from None
    return Expr(node, variables, where, text=text)
