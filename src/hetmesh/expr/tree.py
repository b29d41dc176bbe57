"""The expression tree of a compiled formula: nodes built simplified (constant folding,
``0*u``, ``u+0``, ``1*u``, ...), their derivative, their text and the flat tape that
evaluates them."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

__all__ = ["Node", "APPLY", "const", "make", "derivative", "to_text", "build_tape", "run_tape",
           "post_order", "ZERO", "ONE", "TWO"]

# op name -> numpy callable; used both by constant folding and by the compiled tape.
APPLY: dict[str, Callable[..., Any]] = {
    "add": np.add, "sub": np.subtract, "mul": np.multiply, "div": np.divide,
    "pow": np.power, "neg": np.negative,
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "arcsin": np.arcsin, "arccos": np.arccos,
    "arctan": np.arctan, "atan2": np.arctan2, "sinh": np.sinh, "cosh": np.cosh,
    "tanh": np.tanh, "exp": np.exp, "log": np.log, "log10": np.log10, "sqrt": np.sqrt,
    "abs": np.abs, "sign": np.sign, "min": np.minimum, "max": np.maximum, "where": np.where,
    "lt": np.less, "le": np.less_equal, "gt": np.greater, "ge": np.greater_equal,
    "and": np.logical_and, "or": np.logical_or, "not": np.logical_not,
}

# --------------------------------------------------------------------------- tree nodes
class Node:
    """Immutable node: ``op`` in APPLY, or a leaf 'const' / 'bool' / 'var'."""

    __slots__ = ("op", "args", "value", "names", "_hash")

    def __init__(self, op: str, args: tuple[Node, ...] = (), value: Any = None) -> None:
        self.op, self.args, self.value = op, args, value
        self.names: frozenset[str] = frozenset((value,)) if op == "var" else \
            frozenset().union(*(a.names for a in args))
        self._hash = hash((op, value, args))

    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other: object) -> bool:
        return self is other or (
            isinstance(other, Node) and self._hash == other._hash and self.op == other.op
            and self.value == other.value and self.args == other.args)

    def is_const(self, value: float | None = None) -> bool:
        return self.op == "const" and (value is None or self.value == value)


def const(value: Any) -> Node:
    return Node("const", value=float(value) + 0.0)  # + 0.0 turns -0.0 into 0.0


ZERO, ONE, TWO = const(0.0), const(1.0), const(2.0)


def make(op: str, *args: Node) -> Node:
    """Build ``op(*args)``, folding it when every argument is a constant."""
    if all(a.op in ("const", "bool") for a in args):
        with np.errstate(all="ignore"):
            value = APPLY[op](*(a.value for a in args))
        if op in ("lt", "le", "gt", "ge", "and", "or", "not"):
            return Node("bool", value=bool(value))
        return const(value)
    return Node(op, args)


def _minus(n: Node) -> bool:
    """Whether ``n`` reads better with its sign moved: -u, a negative constant, -2*u."""
    c = n.args[0] if n.op == "mul" else n
    return n.op == "neg" or (c.is_const() and c.value < 0)


def add(a: Node, b: Node) -> Node:
    if a.is_const(0.0) or b.is_const(0.0):
        return b if a.is_const(0.0) else a
    return sub(a, neg(b)) if _minus(b) else make("add", a, b)


def sub(a: Node, b: Node) -> Node:
    if a.is_const(0.0) or b.is_const(0.0):
        return a if b.is_const(0.0) else neg(b)
    if _minus(b):
        return add(a, neg(b))
    if b.is_const() and a.op in ("add", "sub") and a.args[1].is_const():  # (u - 1) - 1
        c = a.args[1].value
        return add(a.args[0], const(c - b.value)) if a.op == "add" else \
            sub(a.args[0], const(c + b.value))
    return make("sub", a, b)


def neg(a: Node) -> Node:
    if a.op == "neg":
        return a.args[0]
    if a.op == "mul" and a.args[0].is_const():
        return mul(const(-a.args[0].value), a.args[1])
    return make("neg", a)


def mul(a: Node, b: Node) -> Node:
    if b.is_const() and not a.is_const():
        a, b = b, a  # constant factor first
    if a.is_const(0.0) or b.is_const(0.0):
        return ZERO
    if a.is_const(1.0) or a.is_const(-1.0):
        return b if a.value == 1.0 else neg(b)
    if a.is_const() and b.op == "mul" and b.args[0].is_const():  # 2*(3*u) = 6*u
        return mul(make("mul", a, b.args[0]), b.args[1])
    if a.is_const() and b.op == "neg":
        return mul(const(-a.value), b.args[0])
    return make("mul", a, b)


def div(a: Node, b: Node) -> Node:
    return ZERO if a.is_const(0.0) else a if b.is_const(1.0) else make("div", a, b)


def power(a: Node, b: Node) -> Node:
    if b.is_const(0.0) or a.is_const(1.0):
        return ONE
    return a if b.is_const(1.0) else make("pow", a, b)


def where_(c: Node, a: Node, b: Node) -> Node:
    if c.op == "bool" or a == b:
        return a if a == b or c.value else b
    return make("where", c, a, b)


def logic(op: str, a: Node, b: Node) -> Node:
    for p, q in ((a, b), (b, a)):
        if p.op == "bool":  # True and q -> q, False and q -> False; dually for 'or'
            return q if p.value == (op == "and") else p
    return make(op, a, b)


# --------------------------------------------------------------------------- derivative
def derivative(n: Node, x: str, memo: dict[Node, Node]) -> Node:
    """d n / d x by the chain rule, simplified; ``memo`` shares results of shared nodes."""
    if x not in n.names:
        return ZERO
    if n not in memo:
        d = [derivative(a, x, memo) for a in n.args]
        rule = _RULES.get(n.op)
        memo[n] = rule(n, n.args, d, x) if rule else mul(_OUTER[n.op](n.args[0], n), d[0])
    return memo[n]


def _d_pow(n: Node, args: tuple[Node, ...], d: list[Node], x: str) -> Node:
    a, b = args
    if x not in b.names:  # a**c -> c * a**(c - 1) * a'
        return mul(mul(b, power(a, sub(b, ONE))), d[0])
    if x not in a.names:  # c**b -> c**b * log(c) * b'
        return mul(mul(n, make("log", a)), d[1])
    return mul(n, add(mul(d[1], make("log", a)), div(mul(b, d[0]), a)))


#: derivative rules (node, its arguments, their derivatives, variable) -> derivative
_RULES: dict[str, Callable[[Node, tuple[Node, ...], list[Node], str], Node]] = {
    "var": lambda n, a, d, x: ONE,
    "add": lambda n, a, d, x: add(d[0], d[1]),
    "sub": lambda n, a, d, x: sub(d[0], d[1]),
    "neg": lambda n, a, d, x: neg(d[0]),
    "mul": lambda n, a, d, x: add(mul(d[0], a[1]), mul(a[0], d[1])),
    "div": lambda n, a, d, x: div(d[0], a[1]) if x not in a[1].names else
    div(sub(mul(d[0], a[1]), mul(a[0], d[1])), power(a[1], TWO)),
    "pow": _d_pow,
    "atan2": lambda n, a, d, x: div(sub(mul(a[1], d[0]), mul(a[0], d[1])),
                                     add(power(a[0], TWO), power(a[1], TWO))),
    "min": lambda n, a, d, x: where_(make("le", a[0], a[1]), d[0], d[1]),
    "max": lambda n, a, d, x: where_(make("ge", a[0], a[1]), d[0], d[1]),
    "where": lambda n, a, d, x: where_(a[0], d[1], d[2]),
    **dict.fromkeys(("sign", "lt", "le", "gt", "ge", "and", "or", "not"),
                    lambda n, a, d, x: ZERO),
}
_SQRT_1_U2 = lambda u: make("sqrt", sub(ONE, power(u, TWO)))  # noqa: E731
#: f'(u) for one-argument functions f, given u and n = f(u).
_OUTER: dict[str, Callable[[Node, Node], Node]] = {
    "sin": lambda u, n: make("cos", u),
    "cos": lambda u, n: neg(make("sin", u)),
    "tan": lambda u, n: div(ONE, power(make("cos", u), TWO)),
    "arcsin": lambda u, n: div(ONE, _SQRT_1_U2(u)),
    "arccos": lambda u, n: div(const(-1.0), _SQRT_1_U2(u)),
    "arctan": lambda u, n: div(ONE, add(ONE, power(u, TWO))),
    "sinh": lambda u, n: make("cosh", u),
    "cosh": lambda u, n: make("sinh", u),
    "tanh": lambda u, n: sub(ONE, power(n, TWO)),
    "exp": lambda u, n: n,
    "log": lambda u, n: div(ONE, u),
    "log10": lambda u, n: div(ONE, mul(const(math.log(10.0)), u)),
    "sqrt": lambda u, n: div(ONE, mul(TWO, n)),
    "abs": lambda u, n: make("sign", u),
}


# --------------------------------------------------------------------------- printing
_INFIX = {"add": (" + ", 5), "sub": (" - ", 5), "mul": ("*", 6), "div": ("/", 6),
          "pow": ("**", 8), "lt": (" < ", 4), "le": (" <= ", 4), "gt": (" > ", 4),
          "ge": (" >= ", 4), "and": (" and ", 2), "or": (" or ", 1)}


def to_text(n: Node) -> tuple[str, int]:
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
        s, p = to_text(n.args[0])
        return "-" + (s if p >= 7 else f"({s})"), 7
    if n.op == "not":
        s, p = to_text(n.args[0])
        return "not " + (s if p > 3 else f"({s})"), 3
    if n.op in _INFIX:
        sym, prec = _INFIX[n.op]
        (ls, lp), (rs, rp) = to_text(n.args[0]), to_text(n.args[1])
        left_ok, right_ok = (lp > prec, rp >= 7) if n.op == "pow" else (lp >= prec, rp > prec)
        return (ls if left_ok else f"({ls})") + sym + (rs if right_ok else f"({rs})"), prec
    return f"{n.op}({', '.join(to_text(a)[0] for a in n.args)})", 9


# --------------------------------------------------------------------------- evaluation
def build_tape(root: Node) -> list[tuple[int, Any, tuple[int, ...], tuple[int, ...]]]:
    """Flatten the tree into numpy calls in evaluation order, sharing equal subtrees.

    Each entry is ``(kind, payload, input slots, slots to free afterwards)`` with kind 0 a
    constant, 1 a variable, 2 a numpy call; freeing keeps memory at a few arrays.
    """
    slot: dict[Node, int] = {}
    order: list[tuple[Node, tuple[int, ...]]] = []
    stack: list[tuple[Node, bool]] = [(root, False)]
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
    return [((2, APPLY[n.op]) if n.args else (1, n.value) if n.op == "var" else
             (0, np.float64(n.value) if n.op == "const" else n.value))
            + (ins, tuple({i for i in ins if last[i] == k})) for k, (n, ins) in enumerate(order)]


def run_tape(tape: list[tuple[int, Any, tuple[int, ...], tuple[int, ...]]],
         env: Mapping[str, np.ndarray]) -> Any:
    slots: list[Any] = [None] * len(tape)
    for k, (kind, payload, ins, frees) in enumerate(tape):
        slots[k] = payload(*[slots[i] for i in ins]) if kind == 2 else \
            env[payload] if kind == 1 else payload
        for i in frees:
            slots[i] = None
    return slots[-1]



def post_order(root: Node):
    """The distinct nodes of a tree, children before parents, left to right (iterative)."""
    seen: set[Node] = set()
    stack: list[tuple[Node, bool]] = [(root, False)]
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
