"""The parser: formula text -> expression tree, through an allow-list of :mod:`ast` nodes."""

from __future__ import annotations

import ast
import math
import warnings
from collections.abc import Callable, Iterable, Mapping
from functools import partial, reduce
from itertools import accumulate

from ..errors import FormulaError
from .compiled import Expr
from .tree import Node, add, const, div, logic, make, mul, neg, power, sub, where_

__all__ = ["compile_expr", "FUNCTIONS", "MAX_LENGTH", "MAX_NODES", "MAX_DEPTH"]

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



_BINOPS = {ast.Add: add, ast.Sub: sub, ast.Mult: mul, ast.Div: div, ast.Pow: power}


class _Converter:
    """Walk a parsed formula with the allow-list, producing a simplified tree."""

    def __init__(self, where: str, variables: tuple[str, ...],
                 parameters: dict[str, float]) -> None:
        self.where, self.variables, self.parameters = where, variables, parameters

    def fail(self, message: str) -> FormulaError:
        return FormulaError(f"{self.where}: {message}")

    def expr(self, node: ast.AST) -> Node:
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
                return neg(u) if isinstance(node.op, ast.USub) else u
            raise self.fail(_CONDITION_ONLY if isinstance(node.op, ast.Not)
                            else "operator '~' is not allowed")
        if isinstance(node, ast.Call):
            return self.call(node)
        if isinstance(node, ast.IfExp):
            return where_(self.cond(node.test), self.expr(node.body), self.expr(node.orelse))
        if isinstance(node, (ast.Compare, ast.BoolOp)):
            raise self.fail(_CONDITION_ONLY)
        message = _FORBIDDEN.get(type(node))
        raise self.fail(message or f"{type(node).__name__} expressions are not allowed")

    def cond(self, node: ast.AST) -> Node:
        if isinstance(node, ast.Compare):  # a < b <= c means (a < b) and (b <= c)
            for op in node.ops:
                if type(op) not in _CMPOPS:
                    raise self.fail(f"comparison '{_OPSYMBOLS.get(type(op), '?')}' is not "
                                    "allowed (use <, <=, >, >=)")
            terms = [self.expr(node.left), *map(self.expr, node.comparators)]
            return reduce(partial(logic, "and"), [make(_CMPOPS[type(op)], a, b) for op, a, b
                                                   in zip(node.ops, terms, terms[1:])])
        if isinstance(node, ast.BoolOp):
            op = "and" if isinstance(node.op, ast.And) else "or"
            return reduce(partial(logic, op), map(self.cond, node.values))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            return make("not", self.cond(node.operand))
        raise self.fail("a condition must be a comparison such as 'x > 0' "
                        "(optionally combined with and, or, not)")

    def constant(self, value: object) -> Node:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            try:
                return const(float(value))
            except OverflowError:
                raise self.fail("number is too large") from None
        raise self.fail("strings are not allowed" if isinstance(value, (str, bytes)) else
                        "complex numbers are not allowed" if isinstance(value, complex) else
                        f"{value!r} is not allowed")

    def name(self, ident: str) -> Node:
        if "__" in ident:
            raise self.fail(f"names containing '__' are not allowed ({ident!r})")
        if ident in self.variables:
            return Node("var", value=ident)
        if ident in self.parameters:
            return const(self.parameters[ident])
        if ident in _CONSTANTS:
            return const(_CONSTANTS[ident])
        if ident in FUNCTIONS:
            raise self.fail(f"{ident!r} is a function; call it as {ident}(...)")
        allowed = ", ".join([*self.variables, *self.parameters])
        raise self.fail(f"unknown name {ident!r} (allowed: {allowed})")

    def call(self, node: ast.Call) -> Node:
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
            return where_(self.cond(node.args[0]), self.expr(node.args[1]),
                          self.expr(node.args[2]))
        args = [self.expr(a) for a in node.args]
        if op == "clip":  # clip(u, lo, hi) = min(max(u, lo), hi), as np.clip
            return make("min", make("max", args[0], args[1]), args[2])
        return make(op, *args) if arity else reduce(partial(make, op), args)  # min, max


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
