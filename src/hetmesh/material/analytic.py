"""Material fields given by formulas (:class:`AnalyticField`) or Python callables
(:class:`CallableField`).

Both evaluate whole ``(N, 2)`` arrays at once. ``shifted(offset)`` returns the same field
evaluated at ``points + offset``: the mesher works in local coordinates near the origin and
shifts the field back to the model's coordinates (which may be far from the origin, e.g. at
1e9).

Gradients are finite wherever the composition is. Where the exact derivative of a formula
is undefined (the tip of a cone ``sqrt(x**2 + y**2)``) or infinite (``sqrt(x)`` at
``x = 0``), a finite difference over :data:`SINGULAR_STEP` of the field's length scale takes
its place: central, or one-sided where the composition is not finite on one side. A
callable's central difference falls back to one-sided differences the same way.

A formula field whose formulas contain jumps (``where``, ``a if c else b``, ``sign``) is
*piecewise*: like a feature tree it offers ``region(points)``, ``n_regions``,
``region_names`` and ``composition(points, region=r)`` / ``gradient(points, region=r)``, the
smooth field of subregion ``r`` continued past its boundary, so that
:mod:`hetmesh.tri.discontinuity` can find the jumps and embed them in the mesh. A smooth field
has no ``region`` (``n_regions`` is 1) and ignores the ``region`` keyword.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable, Mapping, Sequence
from collections.abc import Sequence as _SequenceABC

import numpy as np

from ..errors import MaterialError
from ..expr import compile_expr, condition_level, split_conditions
from .field import as_points

__all__ = ["AnalyticField", "CallableField", "Shiftable", "check_constituents", "SINGULAR_STEP",
           "MAX_CONDITIONS", "difference_step"]

#: Where the exact derivative is not finite, the finite difference spans this fraction of
#: the field's length scale (the domain's diameter; without one, ``max(1, |x|, |y|)``): the
#: mean slope near a kink or an infinite slope (``sqrt(x)`` at ``x = 0`` has none), coarse
#: enough not to ask for needlessly small elements there; the delta-driven refinement
#: resolves what it underestimates.
SINGULAR_STEP = 1e-2
#: The most jump conditions (comparisons of ``where`` and ``sign``) a formula field may have:
#: its subregion ids are their truth values read as bits.
MAX_CONDITIONS = 24
_PROBE_ROUNDS = 26  # continuation probes at radii 4**k x the smallest step, k < this
_DIRECTIONS = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0],
                        [1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]]) / \
    np.array([1.0, 1.0, 1.0, 1.0, *[np.sqrt(2.0)] * 4])[:, None]
#: the continuation probes' unit directions in 3D: the 26 neighbours of a cube's centre
_DIRECTIONS3 = np.array([v for v in np.ndindex(3, 3, 3) if v != (1, 1, 1)], float) - 1.0
_DIRECTIONS3 /= np.linalg.norm(_DIRECTIONS3, axis=1)[:, None]
#: the coordinate names of each dimension
VARIABLES = {2: ("x", "y"), 3: ("x", "y", "z")}


def probe_directions(dim: int) -> np.ndarray:
    """Unit directions ``(K, dim)`` of :meth:`AnalyticField`'s continuation probes."""
    return _DIRECTIONS if dim == 2 else _DIRECTIONS3


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


def _offset(offset, dim: int = 2) -> np.ndarray:
    o = np.asarray(offset, dtype=float).reshape(-1)
    if o.shape != (dim,) or not np.all(np.isfinite(o)):
        raise MaterialError(f"shifted: expected an offset of {dim} finite numbers, "
                            f"got {offset!r}")
    return o


def difference_step(local: np.ndarray, glob: np.ndarray, relative: float = 1e-6,
                    length: float | None = None) -> np.ndarray:
    """Finite-difference steps ``(N,)``: ``relative * length``, or without a length
    ``relative * max(1, |x|, |y|)`` in the coordinates the field is called with
    (``local``); never below 16 units in the last place of the evaluated (global)
    coordinates ``glob``, so that large offsets cost no accuracy."""
    if not len(local):
        return np.zeros(0)
    h = (np.full(len(local), relative * length) if length is not None else
         relative * np.maximum(1.0, np.abs(local).max(axis=1)))
    return np.maximum(h, 16.0 * np.spacing(np.abs(glob).max(axis=1)))


def _difference(values, local: np.ndarray, offset: np.ndarray, h: np.ndarray,
                center: np.ndarray | None = None) -> np.ndarray:
    """Gradient ``(N, k, d)`` of ``values(global points (K, d)) -> (K, k)`` by differences
    of step ``h`` around ``local + offset``: central where both neighbours are finite, else
    one-sided from the centre (its value ``center``, evaluated if not given), else 0.

    ``values`` is called with the ``2 d`` neighbour blocks stacked (x + h, x - h, y + h,
    y - h, ..., ``N`` points each, in the order of ``local``); quotients divide by the steps
    actually represented in floating point.
    """
    d = local.shape[1]
    plus = [(local[:, a] + h) + offset[a] for a in range(d)]
    minus = [(local[:, a] - h) + offset[a] for a in range(d)]
    g = [local[:, a] + offset[a] for a in range(d)]
    blocks = []
    for a in range(d):
        for side in (plus[a], minus[a]):
            blocks.append([side if b == a else g[b] for b in range(d)])
    both = values(np.column_stack([np.concatenate([blk[b] for blk in blocks])
                                   for b in range(d)]))
    f = np.split(both, 2 * d)
    out = np.empty((len(local), both.shape[1], d))
    with np.errstate(all="ignore"):
        for a in range(d):
            out[:, :, a] = (f[2 * a] - f[2 * a + 1]) / (plus[a] - minus[a])[:, None]
        rows = np.flatnonzero(~np.isfinite(out).all(axis=(1, 2)))
        if len(rows):
            f0 = center[rows] if center is not None else \
                values(np.column_stack([c[rows] for c in g]))
            for a in range(d):
                fp, fm = f[2 * a][rows], f[2 * a + 1][rows]
                cp, cm, c0 = plus[a][rows], minus[a][rows], g[a][rows]
                fwd = (fp - f0) / (cp - c0)[:, None]
                bwd = (f0 - fm) / (c0 - cm)[:, None]
                da = out[rows, :, a]
                out[rows, :, a] = np.where(np.isfinite(da), da, np.where(
                    np.isfinite(fwd), fwd, np.where(np.isfinite(bwd), bwd, 0.0)))
    return out


class Shiftable:
    """Shared ``offset`` handling: fields evaluate at ``points + offset``."""

    _offset_xy: np.ndarray = np.zeros(2)
    #: the dimension of the points the field takes
    dim: int = 2

    @property
    def offset(self) -> np.ndarray:
        """The offset added to the points before evaluation (zeros unless shifted)."""
        return self._offset_xy.copy()

    def shifted(self, offset) -> Shiftable:
        """The same field evaluated at ``points + offset``.

        ``f.shifted(a).composition(p)`` equals ``f.composition(p + a)``; shifts add up.
        """
        new = copy.copy(self)
        new._offset_xy = self._offset_xy + _offset(offset, self.dim)
        return new

    def _global(self, points) -> np.ndarray:
        p = as_points(points, f"{type(self).__name__}", self.dim)
        if self._offset_xy.any():
            p = p + self._offset_xy
        return p


class AnalyticField(Shiftable):
    """Compositions given by formulas in ``x``, ``y`` and named parameters.

    Formulas are compiled by :func:`hetmesh.expr.compile_expr` (never ``eval``); gradients
    are exact, from the symbolic derivatives of the same trees, and finite: where the exact
    derivative is undefined or infinite (a kink, the root of ``sqrt(x)``), a finite
    difference over :data:`SINGULAR_STEP` x ``length`` replaces it (central, or one-sided
    where the composition is not finite on one side). One constituent may be left out: it
    is completed as ``1 - sum(others)`` and its gradient as minus the sum of theirs.

    Formulas with jumps (``where(c, a, b)``, ``a if c else b``, ``sign(u)``) make the field
    piecewise (``n_regions > 1``): its subregions are the patterns of truth values of the
    jump conditions over all formulas (see :func:`hetmesh.expr.split_conditions`), the id of
    a subregion those values read as bits (condition ``i`` true adds ``2**i``). Then
    ``composition(points, region=r)`` evaluates every formula with its conditions fixed to
    subregion ``r``'s values (the smooth branch, continued past its boundary; where that
    continuation is undefined, e.g. ``sqrt`` of a negative number just past the jump, its
    value at the nearest point found where it is defined), and ``composition(points)`` is
    that of each point's own subregion (so ``sign(u)`` is 1 at ``u = 0``).

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
    length : float, optional
        The model's length scale (its domain's diameter), for the finite differences; by
        default the magnitude of the coordinates, ``max(1, |x|, |y|)``.

    Attributes
    ----------
    derived : str or None
        The constituent completed as 1 - the others, if any.
    conditions : tuple of str
        The jump conditions, in subregion-bit order (empty for a smooth field).

    Examples
    --------
    >>> f = AnalyticField({"metal": "((b - y)/b)**2"}, ["ceramic", "metal"], {"b": 30.0})
    >>> f.composition([[0.0, 15.0]]).tolist()          # Eq. (10) of the paper
    [[0.75, 0.25]]
    >>> f.gradient([[0.0, 15.0]])[0, 1].tolist()       # Eq. (11): -2 (b - y) / b^2
    [0.0, -0.03333333333333333]
    >>> s = AnalyticField({"metal": "where(x < 0.5, 0.2, 0.8)"}, ["ceramic", "metal"])
    >>> s.n_regions, s.region([[0.25, 0.0], [0.75, 0.0]]).tolist(), list(s.region_names)
    (2, [1, 0], ['not x < 0.5', 'x < 0.5'])
    >>> float(s.composition([[0.75, 0.0]], region=1)[0, 1])  # the left branch, continued
    0.2
    """

    #: every evaluation works on arrays of its own (see :func:`~hetmesh.material.field.thread_safe`)
    thread_safe = True

    def __init__(self, formulas: Mapping[str, str], constituents: Sequence[str],
                 parameters: Mapping[str, float] | None = None, where: str = "", *,
                 length: float | None = None, dim: int = 2):
        pre = _prefix(where)
        if dim not in VARIABLES:
            raise MaterialError(f"{pre}AnalyticField: dim must be 2 or 3, got {dim!r}")
        self.dim = int(dim)
        self._vars = VARIABLES[self.dim]
        self._offset_xy = np.zeros(self.dim)
        self.constituents = check_constituents(constituents, where)
        self.parameters = dict(parameters or {})
        self.where = where
        if length is not None and (isinstance(length, bool) or not np.isfinite(length)
                                   or length <= 0):
            raise MaterialError(f"{pre}AnalyticField: length must be a positive number, "
                                f"got {length!r}")
        self.length = None if length is None else float(length)
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
            e = compile_expr(text, self._vars, self.parameters,
                             where=f"{pre}material.composition.{c}")
            self._exprs.append(e)
            self._grads.append(tuple(e.diff(v) for v in self._vars))
        self._setup_conditions(pre)

    def _setup_conditions(self, pre: str) -> None:
        """The jump conditions of all formulas and the formulas with them as inputs."""
        conds, fixed = split_conditions(self._exprs)
        keys = list(self.formulas)
        owner = {}
        for c, e in zip(keys, self._exprs):  # the first formula holding each condition
            for cond in split_conditions([e])[0]:
                owner.setdefault(cond.text, c)
        if len(conds) > MAX_CONDITIONS:
            key = owner.get(conds[MAX_CONDITIONS].text, keys[0])
            raise MaterialError(f"{pre}material.composition.{key}: the formulas have "
                                f"{len(conds)} jump conditions (comparisons in where() or "
                                f"'if', and sign()), more than {MAX_CONDITIONS}")
        self._conds = conds
        self._cond_keys = [owner.get(c.text, keys[0]) for c in conds]
        self._cond_names = tuple(f"_c{i}" for i in range(len(conds)))
        self._fixed = fixed if conds else []
        self._fixed_grads = [tuple(e.diff(v) for v in self._vars) for e in self._fixed]
        self._levels = None  # the conditions' level functions, made when first asked for

    def _level_exprs(self):
        """Per condition: its level function (:func:`hetmesh.expr.condition_level`), the
        gradient's and the Hessian's (upper triangle, row by row) expressions."""
        if self._levels is None:
            out = []
            for c in self._conds:
                g = condition_level(c)
                grad = tuple(g.diff(v) for v in self._vars)
                hess = tuple(grad[i].diff(self._vars[j]) for i in range(self.dim)
                             for j in range(i, self.dim))
                out.append((g, grad, hess))
            self._levels = out
        return self._levels

    def __repr__(self) -> str:
        body = ", ".join(f"{c}={t!r}" for c, t in self.formulas.items())
        return f"AnalyticField({body}; constituents={list(self.constituents)})"

    # ------------------------------------------------------------------ subregions
    @property
    def conditions(self) -> tuple[str, ...]:
        """The jump conditions' texts; condition ``i`` is bit ``2**i`` of a subregion id."""
        return tuple(c.text for c in self._conds)

    @property
    def n_regions(self) -> int:
        """``2**k`` for ``k`` jump conditions (1 for a smooth field); not every id need
        occur in a domain."""
        return 1 << len(self._conds)

    @property
    def region_names(self) -> Sequence[str]:
        """Names of the subregions by id: the conditions that hold and, with ``not``,
        those that do not, joined by ``and`` (computed on access)."""
        return _RegionNames(self.conditions)

    @property
    def region(self):
        """``region(points) -> (N,) int``: the subregion id of each point, bit ``i`` set
        where condition ``i`` holds. Only a piecewise field has it (for a smooth one the
        attribute does not exist, as for any field without subregions)."""
        if not self._conds:
            raise AttributeError("a formula field without jumps has no subregions")
        return self._region

    def _region(self, points) -> np.ndarray:
        p = self._global(points)
        return self._bits(p) @ (np.int64(1) << np.arange(len(self._conds), dtype=np.int64))

    def levels(self, points, order: int = 0) -> np.ndarray:
        """The jump conditions' level functions at ``points (N, d)``: zero where a condition
        changes, positive where it holds (``b - a`` for ``a < b``; see
        :func:`hetmesh.expr.condition_level`). ``order`` 0: values ``(N, k)``; 1: gradients
        ``(N, k, d)``; 2: Hessians ``(N, k, d, d)``. Not finite where a side of a comparison
        is not. The 3-D meshers embed the jumps by cutting along these zero sets.

        >>> f = AnalyticField({"metal": "where(x < 0.5, 0.2, 0.8)"}, ["ceramic", "metal"])
        >>> f.levels([[0.25, 0.0]]).tolist(), f.levels([[0.25, 0.0]], 1).tolist()
        ([[0.25]], [[[-1.0, 0.0]]])
        """
        p = self._global(points)
        d, k = self.dim, len(self._conds)
        if order == 0:
            out = np.empty((len(p), k))
            for i, (g, _, _) in enumerate(self._level_exprs()):
                out[:, i] = self._eval(g, p)
            return out
        if order == 1:
            out = np.empty((len(p), k, d))
            for i, (_, grad, _) in enumerate(self._level_exprs()):
                for a, e in enumerate(grad):
                    out[:, i, a] = self._eval(e, p)
            return out
        if order == 2:
            out = np.empty((len(p), k, d, d))
            pairs = [(a, b) for a in range(d) for b in range(a, d)]
            for i, (_, _, hess) in enumerate(self._level_exprs()):
                for (a, b), e in zip(pairs, hess):
                    out[:, i, a, b] = out[:, i, b, a] = self._eval(e, p)
            return out
        raise MaterialError(f"{self!r}: levels() order must be 0, 1 or 2, got {order!r}")

    def describe_jump(self, ra: int, rb: int) -> str:
        """``"<where>material.composition.<key>: condition '<text>'"`` for the first condition
        telling subregions ``ra`` and ``rb`` apart (the first condition if none does): the
        formula key and condition an error about that jump names."""
        if not self._conds:
            return f"{_prefix(self.where)}material.composition"
        diff = int(ra) ^ int(rb)
        i = next((i for i in range(len(self._conds)) if diff >> i & 1), 0)
        return (f"{_prefix(self.where)}material.composition.{self._cond_keys[i]}: "
                f"condition {self._conds[i].text!r}")

    def _bits(self, p: np.ndarray) -> np.ndarray:
        """Truth values ``(N, k)`` of the conditions at global points ``p``."""
        out = np.empty((len(p), len(self._conds)), dtype=bool)
        for i, c in enumerate(self._conds):
            out[:, i] = self._eval(c, p) != 0.0
        return out

    def _region_bits(self, region, n: int) -> np.ndarray:
        r = np.asarray(region)
        if r.dtype.kind not in "iu" and not (r.dtype.kind == "f" and np.all(r == np.round(r))):
            raise MaterialError(f"{self!r}: region must be integer ids, got {r.dtype}")
        r = r.astype(np.int64)
        r = np.broadcast_to(r, (n,)) if r.ndim == 0 else r
        if r.shape != (n,) or (n and (r.min() < 0 or r.max() >= self.n_regions)):
            raise MaterialError(f"{self!r}: region must be {n} ids in [0, {self.n_regions}), "
                                f"got shape {r.shape}")
        return (r[:, None] >> np.arange(len(self._conds), dtype=np.int64)) & 1 == 1

    # ------------------------------------------------------------------ evaluation
    def _eval(self, e, p: np.ndarray, **conds) -> np.ndarray:
        """``e`` at the global points ``p (N, d)``, as ``(N,)`` floats."""
        v = np.asarray(e(**{n: p[:, i] for i, n in enumerate(self._vars)}, **conds),
                       dtype=float)
        return v if v.shape == (len(p),) else np.broadcast_to(v, (len(p),))

    def _values(self, p: np.ndarray, bits: np.ndarray | None) -> np.ndarray:
        """The given constituents' formulas ``(N, g)`` at global points ``p``, with the
        conditions fixed to ``bits`` ``(N, k)`` (piecewise fields) or as written (smooth
        ones)."""
        if not self._conds:
            return np.column_stack([self._eval(e, p) for e in self._exprs])
        conds = dict(zip(self._cond_names, bits.T))
        return np.column_stack([self._eval(e, p, **conds) for e in self._fixed])

    def _continued(self, p: np.ndarray, bits: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``v`` with its non-finite rows (a branch undefined just past its boundary) taken
        at the nearest probe point where the branch is finite: 8 directions at radii growing
        by 4 from a few units in the last place."""
        bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
        if not len(bad):
            return v
        v = v.copy()
        dirs = probe_directions(self.dim)
        base = np.maximum(16.0 * np.spacing(np.abs(p[bad]).max(axis=1)), 1e-15)
        for k in range(_PROBE_ROUNDS):
            q = (p[bad][:, None, :] + (base * 4.0 ** k)[:, None, None] * dirs)
            w = self._values(q.reshape(-1, self.dim), np.repeat(bits[bad], len(dirs), axis=0))
            w = w.reshape(len(bad), len(dirs), -1)
            ok = np.isfinite(w).all(axis=2)
            hit = ok.any(axis=1)
            v[bad[hit]] = w[hit, ok[hit].argmax(axis=1)]
            bad, base = bad[~hit], base[~hit]
            if not len(bad):
                break
        return v

    def composition(self, points, region=None) -> np.ndarray:
        """Volume fractions ``(N, m)`` at ``points`` ``(N, d)``.

        ``region`` (ids ``(N,)`` or one id) selects, for a piecewise field, the subregion
        whose smooth field is evaluated; a smooth field ignores it.
        """
        p = self._global(points)
        out = np.empty((len(p), len(self.constituents)))
        if self._conds:
            own = region is None
            bits = self._bits(p) if own else self._region_bits(region, len(p))
            v = self._values(p, bits)
            out[:, self._given] = v if own else self._continued(p, bits, v)
        else:
            for j, e in zip(self._given, self._exprs):
                out[:, j] = self._eval(e, p)
        if self._derived_col is not None:
            g = self._given  # numpy sums eight or more contiguous columns pairwise
            out[:, self._derived_col] = 1.0 - (out[:, g].sum(axis=1) if len(g) >= 8 else
                                               _summed([out[:, j] for j in g]))
        return out

    def gradient(self, points, region=None) -> np.ndarray:
        """Gradients ``(N, m, d)`` at ``points`` ``(N, d)``: exact, or finite differences
        where the exact ones are not finite.

        ``region`` as for :meth:`composition`; the differences are taken in the point's
        subregion (or the given one), never across a jump.
        """
        local = as_points(points, "AnalyticField", self.dim)
        p = self._global(local)
        # stored by constituent and axis, each a contiguous (N,) row, and returned as the
        # (N, m, d) view: numpy runs a (N, d) slice of an (N, m, d) array by inner loops of d
        # items, several times slower than over contiguous rows
        buf = np.empty((len(self.constituents), self.dim, len(p)))
        out = buf.transpose(2, 0, 1)
        bits = None
        conds = {}
        if self._conds:
            bits = self._bits(p) if region is None else self._region_bits(region, len(p))
            conds = dict(zip(self._cond_names, bits.T))
        for j, grads in zip(self._given, self._fixed_grads if self._conds else self._grads):
            for a, da in enumerate(grads):
                buf[j, a] = self._eval(da, p, **conds)
        if not all(np.isfinite(buf[j]).all() for j in self._given):
            given = out[:, self._given]
            bad = ~np.isfinite(given)
            rows = np.flatnonzero(bad.any(axis=(1, 2)))
            b = bits[rows] if bits is not None else None
            center = self._values(p[rows], b)
            if b is not None and region is not None:
                center = self._continued(p[rows], b, center)
            fd = _difference(lambda q: self._values(q, None if b is None else np.tile(b, (
                len(q) // len(rows), 1))), local[rows], self._offset_xy,
                difference_step(local[rows], p[rows], SINGULAR_STEP, self.length),
                center=center)
            sub = given[rows]
            sub[bad[rows]] = fd[bad[rows]]
            given[rows] = sub
            out[:, self._given] = given
        if self._derived_col is not None:
            buf[self._derived_col] = 0.0 - _summed([buf[j] for j in self._given])
        return out


class _RegionNames(_SequenceABC):
    """Subregion names of a piecewise formula field, made on access (there are ``2**k``)."""

    def __init__(self, conditions: tuple[str, ...]):
        self._conds = conditions

    def __len__(self) -> int:
        return 1 << len(self._conds)

    def __getitem__(self, r):
        if isinstance(r, slice):
            return [self[i] for i in range(*r.indices(len(self)))]
        r = int(r)
        if r < 0:
            r += len(self)
        if not 0 <= r < len(self):
            raise IndexError(r)
        if not self._conds:
            return "all"
        return " and ".join(c if r >> i & 1 else f"not {c}" for i, c in enumerate(self._conds))


class CallableField(Shiftable):
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
        Where ``func`` is not finite on one side of a point (``sqrt(x)`` at ``x = 0``), the
        one-sided difference on the other side is used.

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
        """Central-difference gradients ``(N, m, 2)``; one-sided where the function is not
        finite on one side (e.g. ``sqrt(x)`` at ``x = 0``); ``region`` is ignored."""
        local = as_points(points, "CallableField")
        n = len(local)
        glob = self._global(local)
        h = difference_step(local, glob)
        if self.step is not None and n:
            # never below the spacing of the evaluated (global) coordinates
            h = np.maximum(np.full(n, self.step), 16.0 * np.spacing(np.abs(glob).max(axis=1)))

        def values(q):  # a side outside the function's domain is expected: no warnings
            with np.errstate(all="ignore"):
                return self._call(np.ascontiguousarray(q[:, 0]), np.ascontiguousarray(q[:, 1]))

        return _difference(values, local, self._offset_xy, h)


def _summed(parts: list[np.ndarray]) -> np.ndarray:
    """``parts[0] + parts[1] + ...``, added one after the other: the numbers numpy's sum
    over a short axis gives (``out[:, cols].sum(axis=1)`` of up to seven columns, or of
    any number along an axis that is not the last), without the copy a list index makes
    along the middle axis (ten times the cost of the additions on 100,000 points)."""
    total = parts[0].copy()
    for q in parts[1:]:
        total += q
    return total
