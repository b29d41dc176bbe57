"""The Zienkiewicz-Zhu error estimate of a 3-D solution (used by
:func:`hetmesh.fea.solid.solve_tets` for every solve and by :mod:`hetmesh.fea.adapt` to
mark elements): the recovered stress against the element stress, in the energy-like norm of
the mixed material (Zienkiewicz and Zhu 1987)."""

from __future__ import annotations

import math

import numpy as np

from .blocks import CHUNK

__all__ = ["compliance_energy", "zz_indicator", "relative_estimate"]


def compliance_energy(s: np.ndarray, E: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """``s : C^-1 s`` of stresses ``s (..., 6)`` (``xx, yy, zz, xy, yz, xz``) for an
    isotropic material ``E, nu (...)``: ``((1 + nu) s:s - nu (tr s)^2) / E``.

    >>> float(compliance_energy(np.array([2.0, 0, 0, 0, 0, 0]), 4.0, 0.25))  # s^2 / E
    1.0
    """
    tr = s[..., 0] + s[..., 1] + s[..., 2]
    ss = (s[..., :3] ** 2).sum(axis=-1) + 2.0 * (s[..., 3:] ** 2).sum(axis=-1)
    return ((1.0 + nu) * ss - nu * tr ** 2) / E


def zz_indicator(space, rec: np.ndarray, copies: np.ndarray, sq: np.ndarray,
                 E: np.ndarray, nu: np.ndarray) -> tuple[np.ndarray, float]:
    """The Zienkiewicz-Zhu indicator of every element and the energy-like norm of the stress.

    Parameters
    ----------
    space : TetSpace
        The element space (its ``dx (M, Q)`` quadrature weights and the reference
        quadrature points ``basis.X``).
    rec : (D, 6) recovered stresses at the vertex copies; copies : (M, 4) every element's
        vertex copies (:func:`hetmesh.fea.recovery3d.recover_stresses`)
    sq : (M, Q, 6) element stresses at the quadrature points
    E, nu : (M, Q) the mixed Young's modulus and Poisson's ratio there

    Returns
    -------
    eta : (M,) ``sqrt(int_T (sigma* - sigma_h) : C^-1 (sigma* - sigma_h))``, with
        ``sigma*`` the recovered stress interpolated linearly at the quadrature points
    energy : float
        ``sqrt(int sigma_h : C^-1 sigma_h)`` over the mesh
    """
    X = np.asarray(space.basis.X)
    phi = np.vstack([1 - X.sum(axis=0), X])  # (4, Q) the P1 basis at the points
    dx = np.asarray(space.dx)
    M = len(dx)
    eta2 = np.empty(M)
    energy = 0.0
    for a in range(0, M, CHUNK):
        sl = slice(a, min(a + CHUNK, M))
        star = np.einsum("iq,mic->mqc", phi, rec[copies[sl]])
        e = compliance_energy(star - sq[sl], E[sl], nu[sl])
        eta2[sl] = (dx[sl] * e).sum(axis=1)
        energy += float((dx[sl] * compliance_energy(sq[sl], E[sl], nu[sl])).sum())
    return np.sqrt(np.maximum(eta2, 0.0)), math.sqrt(max(energy, 0.0))


def relative_estimate(eta: np.ndarray, energy: float) -> float:
    """ZZ's relative error ``eta / sqrt(energy^2 + eta^2)``, ``eta`` the root sum of
    squares of the element indicators (0 for a zero field).

    >>> relative_estimate(np.array([3.0, 4.0]), 0.0)
    1.0
    """
    e2 = float((np.asarray(eta) ** 2).sum())
    den = energy ** 2 + e2
    return math.sqrt(e2 / den) if den > 0 else 0.0
