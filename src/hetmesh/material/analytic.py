"""Material fields given by formulas (:class:`AnalyticField`) or Python callables
(:class:`CallableField`).

Both evaluate whole ``(N, 2)`` arrays at once and accept (and ignore) the ``region`` keyword
of piecewise fields. ``shifted(offset)`` returns the same field evaluated at
``points + offset``: the mesher works in local coordinates near the origin and shifts the
field back to the model's coordinates (which may be far from the origin, e.g. at 1e9).
"""

from __future__ import annotations

import copy
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from ..errors import MaterialError
from ..expr import compile_expr
from .field import as_points

__all__ = ["AnalyticField", "CallableField", "check_constituents"]


def _prefix(where: str) -> str:
    return f"{where}: " if where else ""


def check_constituents(constituents: Iterable[str], where: str = "") -> tuple[str, ...]:
    """The constituent names as a tuple: at least two, non-empty strings, all different.

    >>> check_constituents(["ceramic", "metal"])
    ('ceramic', 'metal')
    """
    key = f"{_prefix(where)}material.constituents"
    if isinstance(constituents, str):
        raise MaterialError(f"{key}: expected a list of names, got the string {constituents!r}")
    names = tuple(constituents)
    for name in names:
        if not isinstance(name, str) or not name.strip():
            raise MaterialError(f"{key}: names must be non-empty strings, got {name!r}")
    if len(names) < 2:
        raise MaterialError(f"{key}: at least 2 constituents are needed, got {len(names)}")
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise MaterialError(f"{key}: constituent {name!r} is listed twice")
        seen.add(name)
    return names


def _offset(offset) -> np.ndarray:
    o = np.asarray(offset, dtype=float).reshape(-1)
    if o.shape != (2,) or not np.all(np.isfinite(o)):
        raise MaterialError(f"shifted: expected an offset of 2 finite numbers, got {offset!r}")
    return o


class _Shiftable:
    """Shared ``offset`` handling: fields evaluate at ``points + offset``."""

    _offset_xy: np.ndarray = np.zeros(2)

    @property
    def offset(self) -> np.ndarray:
        """The offset added to the points before evaluation (zeros unless shifted)."""
        return self._offset_xy.copy()

    def shifted(self, offset) -> "_Shiftable":
        """The same field evaluated at ``points + offset``.

        ``f.shifted(a).composition(p)`` equals ``f.composition(p + a)``; shifts add up.
        """
        new = copy.copy(self)
        new._offset_xy = self._offset_xy + _offset(offset)
        return new

    def _global(self, points) -> np.ndarray:
        p = as_points(points, f"{type(self).__name__}")
        if self._offset_xy.any():
            p = p + self._offset_xy
        return p


class AnalyticField(_Shiftable):
    """Compositions given by formulas in ``x``, ``y`` and named parameters.

    Formulas are compiled by :func:`hetmesh.expr.compile_expr` (never ``eval``); gradients
    are exact, from the symbolic derivatives of the same trees. One constituent may be left
    out: it is completed as ``1 - sum(others)`` and its gradient as minus the sum of theirs.

    Parameters
    ----------
    formulas : mapping of constituent name to formula text
        All ``m`` constituents, or all but one.
    constituents : sequence of str
        The column order of :meth:`composition`.
    parameters : mapping of name to float, optional
        Named numbers usable in the formulas.
    where : str
        Prefix of error messages (the model file name); the key path
        ``material.composition.<name>`` is appended.

    Attributes
    ----------
    derived : str or None
        The constituent completed as 1 - the others, if any.

    Examples
    --------
    >>> f = AnalyticField({"metal": "((b - y)/b)**2"}, ["ceramic", "metal"], {"b": 30.0})
    >>> f.composition([[0.0, 15.0]]).tolist()          # Eq. (10) of the paper
    [[0.75, 0.25]]
    >>> f.gradient([[0.0, 15.0]])[0, 1].tolist()       # Eq. (11): -2 (b - y) / b^2
    [0.0, -0.03333333333333333]
    """

    def __init__(self, formulas: Mapping[str, str], constituents: Sequence[str],
                 parameters: Mapping[str, float] | None = None, where: str = ""):
        pre = _prefix(where)
        self.constituents = check_constituents(constituents, where)
        self.parameters = dict(parameters or {})
        self.where = where
        m = len(self.constituents)
        unknown = [k for k in formulas if k not in self.constituents]
        if unknown:
            raise MaterialError(f"{pre}material.composition.{unknown[0]}: unknown constituent "
                                f"{unknown[0]!r} (constituents are: "
                                f"{', '.join(self.constituents)})")
        missing = [c for c in self.constituents if c not in formulas]
        if len(missing) > 1:
            raise MaterialError(f"{pre}material.composition: no formula for "
                                f"{', '.join(missing)}; give all {m} constituents or all "
                                f"but one (which is then 1 - the sum of the others)")
        self.derived: str | None = missing[0] if missing else None
        self.formulas = {c: formulas[c] for c in self.constituents if c in formulas}
        self._given = [j for j, c in enumerate(self.constituents) if c in formulas]
        self._derived_col = (self.constituents.index(self.derived)
                             if self.derived is not None else None)
        self._exprs = []
        self._grads = []
        for c in self.formulas:
            text = self.formulas[c]
            if not isinstance(text, str):
                raise MaterialError(f"{pre}material.composition.{c}: expected a formula "
                                    f"string, got {text!r}")
            e = compile_expr(text, ("x", "y"), self.parameters,
                             where=f"{pre}material.composition.{c}")
            self._exprs.append(e)
            self._grads.append((e.diff("x"), e.diff("y")))

    def __repr__(self) -> str:
        body = ", ".join(f"{c}={t!r}" for c, t in self.formulas.items())
        return f"AnalyticField({body}; constituents={list(self.constituents)})"

    @staticmethod
    def _eval(e, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        v = np.asarray(e(x=x, y=y), dtype=float)
        return np.broadcast_to(v, x.shape)

    def composition(self, points, region=None) -> np.ndarray:
        """Volume fractions ``(N, m)`` at ``points`` ``(N, 2)``; ``region`` is ignored."""
        p = self._global(points)
        x, y = p[:, 0], p[:, 1]
        out = np.empty((len(p), len(self.constituents)))
        for j, e in zip(self._given, self._exprs):
            out[:, j] = self._eval(e, x, y)
        if self._derived_col is not None:
            out[:, self._derived_col] = 1.0 - out[:, self._given].sum(axis=1)
        return out

    def gradient(self, points, region=None) -> np.ndarray:
        """Exact gradients ``(N, m, 2)`` at ``points`` ``(N, 2)``; ``region`` is ignored."""
        p = self._global(points)
        x, y = p[:, 0], p[:, 1]
        out = np.empty((len(p), len(self.constituents), 2))
        for j, (dx, dy) in zip(self._given, self._grads):
            out[:, j, 0] = self._eval(dx, x, y)
            out[:, j, 1] = self._eval(dy, x, y)
        if self._derived_col is not None:
            out[:, self._derived_col] = 0.0 - out[:, self._given].sum(axis=1)
        return out


class CallableField(_Shiftable):
    """A material field from a Python function of whole coordinate arrays.

    Parameters
    ----------
    func : callable ``func(x, y) -> array``
        ``x``, ``y`` are ``(N,)`` arrays. For two constituents it may return ``(N,)``: the
        fraction of the *last* constituent (the first is 1 - it); otherwise ``(N, m)``.
    constituents : sequence of str
    step : float, optional
        Central-difference step of :meth:`gradient`. By default
        ``1e-6 * max(1, |x|, |y|)`` per point, in the coordinates the field is called with
        (the local ones for a :meth:`shifted` field). The difference quotient divides by the
        step actually represented in floating point, so large offsets cost no accuracy.

    Examples
    --------
    >>> f = CallableField(lambda x, y: (1 - y) ** 2, ["ceramic", "metal"])
    >>> f.composition([[0.0, 0.5]]).tolist()
    [[0.75, 0.25]]
    >>> f.gradient([[0.0, 0.5]])[0, 1].round(6).tolist()
    [0.0, -1.0]
    """

    def __init__(self, func: Callable[[np.ndarray, np.ndarray], np.ndarray],
                 constituents: Sequence[str], step: float | None = None):
        if not callable(func):
            raise MaterialError(f"CallableField: func must be callable, got {func!r}")
        self.func = func
        self.constituents = check_constituents(constituents)
        if step is not None:
            if isinstance(step, bool) or not np.isfinite(step) or step <= 0:
                raise MaterialError(f"CallableField: step must be a positive number, "
                                    f"got {step!r}")
            step = float(step)
        self.step = step
        self.derived = self.constituents[0] if len(self.constituents) == 2 else None

    def __repr__(self) -> str:
        name = getattr(self.func, "__name__", repr(self.func))
        return f"CallableField({name}, constituents={list(self.constituents)})"

    def _call(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        n, m = x.shape[0], len(self.constituents)
        v = np.asarray(self.func(x, y), dtype=float)
        if m == 2 and v.shape in ((n,), ()):
            v = np.broadcast_to(v, (n,))
            return np.stack([1.0 - v, v], axis=-1)
        if v.shape == (n, m):
            return v
        expected = f"({n},) or ({n}, 2)" if m == 2 else f"({n}, {m})"
        raise MaterialError(f"CallableField: {self!r} returned shape {v.shape} for {n} "
                            f"points, expected {expected}")

    def composition(self, points, region=None) -> np.ndarray:
        """Volume fractions ``(N, m)`` at ``points`` ``(N, 2)``; ``region`` is ignored."""
        p = self._global(points)
        return self._call(np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1]))

    def gradient(self, points, region=None) -> np.ndarray:
        """Central-difference gradients ``(N, m, 2)``; ``region`` is ignored."""
        local = as_points(points, "CallableField")
        n = len(local)
        if self.step is not None:
            h = np.full(n, self.step)
        else:
            h = 1e-6 * np.maximum(1.0, np.abs(local).max(axis=1)) if n else np.zeros(0)
        glob = self._global(local)
        # Never below the spacing of the evaluated (global) coordinates.
        h = np.maximum(h, 16.0 * np.spacing(np.abs(glob).max(axis=1))) if n else h
        o = self._offset_xy
        x, y = local[:, 0], local[:, 1]
        xp, xm = (x + h) + o[0], (x - h) + o[0]
        yp, ym = (y + h) + o[1], (y - h) + o[1]
        gx, gy = glob[:, 0], glob[:, 1]
        both = self._call(np.concatenate([xp, xm, gx, gx]), np.concatenate([gy, gy, yp, ym]))
        fxp, fxm, fyp, fym = np.split(both, 4)
        out = np.empty((n, len(self.constituents), 2))
        out[:, :, 0] = (fxp - fxm) / (xp - xm)[:, None]
        out[:, :, 1] = (fyp - fym) / (yp - ym)[:, None]
        return out
