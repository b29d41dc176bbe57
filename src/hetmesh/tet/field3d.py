"""Helpers for material fields on ``(N, 3)`` points (e.g.
:class:`hetmesh.material.AnalyticField` with ``dim=3``): validation at sample points and the
constituent the layers follow.

>>> from hetmesh.material import AnalyticField
>>> f = AnalyticField({"metal": "(1 - z)**2"}, ["ceramic", "metal"], dim=3)
>>> check_field3d(f, np.array([[0.0, 0.0, 0.5]]))
>>> f.composition([[0.0, 0.0, 0.5]]).tolist()
[[0.75, 0.25]]
"""

from __future__ import annotations

import numpy as np

from ..errors import MaterialError

__all__ = ["VARIABLES", "check_field3d", "scalar_column"]

VARIABLES = ("x", "y", "z")


def _prefix(where: str) -> str:
    return f"{where}: " if where else ""


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
