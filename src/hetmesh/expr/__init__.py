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

from .compiled import Expr
from .conditions import condition_level, split_conditions
from .interval import Interval
from .parse import FUNCTIONS, MAX_DEPTH, MAX_LENGTH, MAX_NODES, compile_expr

__all__ = ["compile_expr", "Expr", "FUNCTIONS", "MAX_LENGTH", "MAX_NODES", "MAX_DEPTH",
           "split_conditions", "condition_level", "Interval"]
