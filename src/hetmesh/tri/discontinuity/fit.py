"""Stage 3, fit: a traced polyline as a chain of circular arcs and segments."""

from __future__ import annotations

import numpy as np

from ..geometry import Arc, Segment
from .regions import DISCONTINUITY

__all__ = ["fit_curves"]


def _circle3(a, b, c):
    """Centre and radius of the circle through three points, or None if collinear."""
    ab, ac = b - a, c - a
    d = 2.0 * (ab[0] * ac[1] - ab[1] * ac[0])
    if abs(d) <= 1e-12 * (ab @ ab + ac @ ac):
        return None
    u = np.array([ac[1] * (ab @ ab) - ab[1] * (ac @ ac), ab[0] * (ac @ ac) - ac[0] * (ab @ ab)]) / d
    return a + u, float(np.hypot(*u))


def _deviation(p: np.ndarray, i: int, j: int):
    """How far points ``p[i..j]`` are from the arc (or segment) through ``p[i]``,
    ``p[(i+j)//2]``, ``p[j]``; returns ``(deviation, centre or None)``."""
    a, m, b = p[i], p[(i + j) // 2], p[j]
    q = p[i:j + 1]
    circ = _circle3(a, m, b) if j - i >= 2 else None
    if circ is None or circ[1] > 1e6 * np.hypot(*(b - a)):
        d = b - a
        L = float(np.hypot(*d))
        dev = np.abs((q[:, 0] - a[0]) * d[1] - (q[:, 1] - a[1]) * d[0]) / L
        return float(dev.max()), None
    c, r = circ
    dev = np.abs(np.hypot(q[:, 0] - c[0], q[:, 1] - c[1]) - r)
    return float(dev.max()), c


def fit_curves(points: np.ndarray, tol: float, name: str = DISCONTINUITY) -> list:
    """Arcs and segments through ``points`` (ordered; ends kept exactly), each piece within
    ``tol`` of the points it replaces; greedy, each piece as long as the tolerance allows."""
    p = np.asarray(points, dtype=float)
    n = len(p)
    if n > 3 and np.array_equal(p[0], p[-1]):  # a closed curve: two open halves
        return fit_curves(p[:n // 2 + 1], tol, name) + fit_curves(p[n // 2:], tol, name)
    out = []
    i = 0
    while i < n - 1:
        step, j = 1, i + 1
        while j < n - 1:  # grow geometrically, then bisect back to the longest fitting piece
            k = min(i + 2 * step, n - 1)
            if _deviation(p, i, k)[0] > tol:
                lo, hi = j, k
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    if _deviation(p, i, mid)[0] <= tol:
                        lo = mid
                    else:
                        hi = mid
                j = lo
                break
            j, step = k, 2 * step
        _, c = _deviation(p, i, j)
        out.append(Segment(tuple(p[i]), tuple(p[j]), name) if c is None
                   else Arc.through(tuple(p[i]), tuple(p[(i + j) // 2]), tuple(p[j]), name=name))
        i = j
    return out
