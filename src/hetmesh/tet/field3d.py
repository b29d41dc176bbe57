"""Material fields in three dimensions: compositions given by formulas in ``x, y, z``.

A small field with the interface of :class:`hetmesh.material.AnalyticField` on ``(N, 3)``
points: ``composition(points) -> (N, m)``, ``gradient(points) -> (N, m, 3)`` (exact, from the
symbolic derivatives of the compiled formulas; a central difference where one is not finite).
Formulas are compiled by :func:`hetmesh.expr.compile_expr` (never ``eval``).

>>> f = Field3D({"metal": "(1 - z)**2"}, ["ceramic", "metal"])
>>> f.composition([[0.0, 0.0, 0.5]]).tolist()
[[0.75, 0.25]]
>>> f.gradient([[0.0, 0.0, 0.5]])[0, 1].tolist()
[0.0, 0.0, -1.0]
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..errors import MaterialError
from ..expr import compile_expr

__all__ = ["Field3D", "VARIABLES", "check_field3d", "scalar_column"]

VARIABLES = ("x", "y", "z")


def _prefix(where: str) -> str:
    return f"{where}: " if where else ""


class Field3D:
    """Volume fractions given by formulas in ``x``, ``y``, ``z`` and named parameters.

    Parameters
    ----------
    formulas : mapping of constituent name to formula text
        All ``m`` constituents, or all but one (completed as 1 - the sum of the others).
    constituents : sequence of str
    parameters : mapping of str to float, optional
    where : str
        Prefix of error messages (the model file name).
    """

    dim = 3

    def __init__(self, formulas: Mapping[str, str], constituents: Sequence[str],
                 parameters: Mapping[str, float] | None = None, where: str = ""):
        pre = _prefix(where)
        self.constituents = tuple(str(c) for c in constituents)
        if len(self.constituents) < 2 or len(set(self.constituents)) != len(self.constituents):
            raise MaterialError(f"{pre}material.constituents: expected two or more distinct "
                                f"names, got {list(self.constituents)!r}")
        unknown = [k for k in formulas if k not in self.constituents]
        if unknown:
            raise MaterialError(f"{pre}material.composition.{unknown[0]}: unknown constituent "
                                f"{unknown[0]!r} (constituents are: "
                                f"{', '.join(self.constituents)})")
        missing = [c for c in self.constituents if c not in formulas]
        if len(missing) > 1:
            raise MaterialError(f"{pre}material.composition: no formula for "
                                f"{', '.join(missing)}; give all constituents or all but one")
        self.formulas = {c: formulas[c] for c in self.constituents if c in formulas}
        self._given = [j for j, c in enumerate(self.constituents) if c in formulas]
        self._derived = (self.constituents.index(missing[0]) if missing else None)
        self._exprs, self._grads = [], []
        for c, text in self.formulas.items():
            if not isinstance(text, str):
                raise MaterialError(f"{pre}material.composition.{c}: expected a formula "
                                    f"string, got {text!r}")
            e = compile_expr(text, VARIABLES, parameters or {},
                             where=f"{pre}material.composition.{c}")
            self._exprs.append(e)
            self._grads.append(tuple(e.diff(v) for v in VARIABLES))

    def __repr__(self) -> str:
        return f"Field3D({self.formulas!r})"

    @staticmethod
    def _eval(e, p: np.ndarray) -> np.ndarray:
        v = np.asarray(e(x=p[:, 0], y=p[:, 1], z=p[:, 2]), dtype=float)
        return np.broadcast_to(v, (len(p),))

    def composition(self, points) -> np.ndarray:
        """Volume fractions ``(N, m)`` at ``points (N, 3)``."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        out = np.empty((len(p), len(self.constituents)))
        for j, e in zip(self._given, self._exprs):
            out[:, j] = self._eval(e, p)
        if self._derived is not None:
            out[:, self._derived] = 1.0 - out[:, self._given].sum(axis=1)
        return out

    def gradient(self, points) -> np.ndarray:
        """Gradients ``(N, m, 3)`` at ``points (N, 3)``."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        out = np.empty((len(p), len(self.constituents), 3))
        for j, gs in zip(self._given, self._grads):
            for k, g in enumerate(gs):
                out[:, j, k] = self._eval(g, p)
        bad = ~np.isfinite(out[:, self._given])
        if bad.any():
            rows = np.flatnonzero(bad.any(axis=(1, 2)))
            h = 1e-6 * np.maximum(1.0, np.abs(p[rows]).max(axis=1))
            for k in range(3):
                d = np.zeros(3)
                d[k] = 1.0
                hi = self.composition(p[rows] + h[:, None] * d)
                lo = self.composition(p[rows] - h[:, None] * d)
                fd = (hi - lo) / (2 * h[:, None])
                sub = out[rows, :, k]
                sub[~np.isfinite(sub)] = fd[~np.isfinite(sub)]
                out[rows, :, k] = sub
        if self._derived is not None:
            out[:, self._derived] = -out[:, self._given].sum(axis=1)
        return out


def scalar_column(field, samples: np.ndarray) -> int:
    """The constituent whose fraction varies most over ``samples (N, 3)`` (largest mean
    gradient norm): the one the layers follow."""
    g = np.linalg.norm(field.gradient(samples), axis=2)  # (N, m)
    return int(np.argmax(g.mean(axis=0)))


def check_field3d(field, samples: np.ndarray, where: str = "") -> None:
    """Raise :class:`MaterialError` unless the field is a valid composition at ``samples``:
    finite, in [0, 1] (tolerance 1e-9), rows summing to 1, finite gradients."""
    pre = _prefix(where)
    c = field.composition(samples)
    g = field.gradient(samples)
    names = field.constituents
    for j, name in enumerate(names):
        col = c[:, j]
        bad = ~np.isfinite(col) | (col < -1e-9) | (col > 1 + 1e-9)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            x, y, z = samples[i]
            raise MaterialError(f"{pre}material.composition.{name}: value {col[i]:.6g} at "
                                f"({x:.6g}, {y:.6g}, {z:.6g}) is outside [0, 1]")
    s = c.sum(axis=1)
    bad = np.abs(s - 1) > 1e-9
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        x, y, z = samples[i]
        raise MaterialError(f"{pre}material.composition: fractions sum to {s[i]:.6g} at "
                            f"({x:.6g}, {y:.6g}, {z:.6g}), not 1")
    if not np.isfinite(g).all():
        i = int(np.flatnonzero(~np.isfinite(g).all(axis=(1, 2)))[0])
        x, y, z = samples[i]
        raise MaterialError(f"{pre}material.composition: gradient not finite at "
                            f"({x:.6g}, {y:.6g}, {z:.6g})")
