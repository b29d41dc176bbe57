"""The conditions of formulas with jumps (``where``, ``sign``): split out as variables, so
that a field knows its subregions."""

from __future__ import annotations

from collections.abc import Iterable

from .compiled import Expr
from .tree import ONE, ZERO, Node, const, post_order, sub

__all__ = ["split_conditions", "condition_level"]

_COMPARISONS = ("lt", "le", "gt", "ge")



def _jump_atoms(root: Node) -> list[Node]:
    """The comparisons on which the value of ``root`` may jump, in post-order.

    Every comparison inside the condition of a ``where`` (``a if c else b``), and for
    ``sign(u)`` the comparison ``u >= 0``. The formula is smooth (or merely kinked, as
    ``abs``, ``min``, ``max``, ``clip`` are) where none of them changes.
    """
    out: dict[Node, None] = {}
    for n in post_order(root):
        if n.op in _COMPARISONS:
            out[n] = None
        elif n.op == "sign":
            out[Node("ge", (n.args[0], ZERO))] = None
    return list(out)


def _substitute(n: Node, table: dict[Node, Node], memo: dict[Node, Node]) -> Node:
    """``n`` with every node of ``table`` replaced, and ``sign(u)`` written as
    ``where(u >= 0, 1, -1)`` with the comparison replaced too (iterative, shares subtrees)."""
    for m in post_order(n):
        if m in memo:
            continue
        if m in table:
            memo[m] = table[m]
        elif m.op == "sign":
            memo[m] = Node("where", (table[Node("ge", (m.args[0], ZERO))], ONE,
                                      const(-1.0)))
        elif m.args:
            args = tuple(memo[a] for a in m.args)
            memo[m] = m if all(a is b for a, b in zip(args, m.args)) else Node(m.op, args,
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
    >>> from hetmesh.expr import compile_expr
    >>> conds, (f,) = split_conditions([compile_expr("where(x < 0.5, 0.2, 0.8) + sign(y)")])
    >>> [c.text for c in conds], f.text
    (['x < 0.5', 'y >= 0'], 'where(_c0, 0.2, 0.8) + where(_c1, 1, -1)')
    >>> float(f(x=0.9, y=-1.0, _c0=True, _c1=True))
    1.2
    """
    exprs = list(exprs)
    atoms: dict[Node, None] = {}
    for e in exprs:
        atoms.update(dict.fromkeys(_jump_atoms(e.node)))
    names = [f"{prefix}{i}" for i in range(len(atoms))]
    table = {a: Node("var", value=v) for a, v in zip(atoms, names)}
    conditions = [Expr(a, e0.variables, e0.where) for a, e0 in
                  zip(atoms, [exprs[0]] * len(atoms))] if exprs else []
    fixed = []
    for e in exprs:
        node = _substitute(e.node, table, {}) if atoms else e.node
        fixed.append(Expr(node, (*e.variables, *names), e.where,
                          text=None if node is not e.node else e.text))
    return conditions, fixed


def condition_level(cond: Expr) -> Expr:
    """A function whose zero set is where the jump condition ``cond`` (one of
    :func:`split_conditions`' comparisons) changes: ``b - a`` for ``a < b`` or ``a <= b``,
    ``a - b`` for ``a > b`` or ``a >= b``; positive where the condition holds (up to the
    zero set itself). The 3-D meshers cut the tetrahedra along it.

    >>> from hetmesh.expr import compile_expr
    >>> conds, _ = split_conditions([compile_expr("where(x**2 + y**2 < 0.25, 0.2, 0.8)")])
    >>> condition_level(conds[0]).text
    '0.25 - (x**2 + y**2)'
    """
    n = cond.node
    if n.op not in _COMPARISONS:
        raise ValueError(f"{cond.where}: {cond.text!r} is not a comparison")
    a, b = n.args
    level = sub(b, a) if n.op in ("lt", "le") else sub(a, b)
    return Expr(level, cond.variables, cond.where)

