"""The compiled formula (:class:`Expr`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import FormulaError
from .interval import Interval, build_interval_tape, run_interval_tape
from .tree import Node, build_tape, derivative, run_tape, to_text

__all__ = ["Expr"]


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

    def __init__(self, node: Node, variables: tuple[str, ...], where: str,
                 text: str | None = None) -> None:
        self._node, self._text, self._tape = node, text, build_tape(node)
        self._itape: list | None = None
        self.names, self.variables, self.where = node.names, variables, where

    @property
    def node(self) -> Node:
        """The root of the formula's (simplified) expression tree."""
        return self._node

    @property
    def text(self) -> str:  # a derivative is printed on first use
        if self._text is None:
            self._text = to_text(self._node)[0]
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
        if not (self.names <= values.keys() and all(k in self.variables for k in values)):
            wrong = ([f"unexpected variable {k!r}" for k in values if k not in self.variables]
                     + [f"missing value for {k!r}" for k in sorted(self.names.difference(values))])
            raise TypeError(f"{self.where}: {wrong[0]} (variables: {', '.join(self.variables)})")
        env = {k: np.asarray(v, dtype=np.float64) for k, v in values.items()}
        shapes = {a.shape for a in env.values()}
        shape = shapes.pop() if len(shapes) == 1 else np.broadcast_shapes(*shapes)
        if self._node.op == "const":  # a derivative of a linear term, a constant fraction
            return np.full(shape, self._node.value, dtype=np.float64)
        with np.errstate(all="ignore"):
            result = run_tape(self._tape, env)
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

        >>> from hetmesh.expr import compile_expr
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
            self._itape = build_interval_tape(self._node)
        with np.errstate(all="ignore"):
            lo, hi = run_interval_tape(self._itape, env)
        shape = np.broadcast_shapes(*(a.shape for pair in env.values() for a in pair))
        return (np.array(np.broadcast_to(lo, shape), dtype=np.float64),
                np.array(np.broadcast_to(hi, shape), dtype=np.float64))

    def diff(self, name: str) -> Expr:
        """Symbolic derivative with respect to the variable ``name`` (chain rule on the tree).

        >>> from hetmesh.expr import compile_expr
        >>> compile_expr("x**3 + sin(y)").diff("x").text
        '3*x**2'
        """
        if name not in self.variables:
            raise FormulaError(f"{self.where}: cannot differentiate with respect to {name!r} "
                               f"(variables: {', '.join(self.variables)})")
        try:
            node = derivative(self._node, name, {})
        except RecursionError:
            raise FormulaError(f"{self.where}: formula too complex to differentiate") from None
        return Expr(node, self.variables, self.where)
