"""Effective properties of a graded material from its composition (paper Sec. 4.4, Table 6).

Every function takes compositions ``c`` ``(N, m)`` (volume fractions, rows summing to 1) and
the constituents' property columns (``(m,)`` arrays, :meth:`FEAConfig.table`) and returns
``(N,)`` arrays of the conductivity ``k``, Young's modulus ``E``, Poisson ratio ``nu`` and
expansion ``alpha``. Both rules return a constituent's own values at a pure composition.

``linear`` -- the (Voigt) rule of mixtures, ``P = sum_r c_r P_r`` for each property.

``mori-tanaka`` -- the Mori-Tanaka estimate for spherical inclusions in the matrix
constituent ``m`` (Benveniste's multi-phase form), through the bulk and shear moduli
``K = E / (3 (1 - 2 nu))``, ``G = E / (2 (1 + nu))``::

    K = sum_r c_r K_r A_r / sum_r c_r A_r,   A_r = (K_m + 4/3 G_m) / (K_r + 4/3 G_m)
    G = sum_r c_r G_r B_r / sum_r c_r B_r,   B_r = (G_m + f_m) / (G_r + f_m),
                                             f_m = G_m (9 K_m + 8 G_m) / (6 (K_m + 2 G_m))
    k = sum_r c_r k_r D_r / sum_r c_r D_r,   D_r = 3 k_m / (k_r + 2 k_m)
    alpha = sum_r c_r K_r alpha_r A_r / sum_r c_r K_r A_r      (Levin's relation)
    E = 9 K G / (3 K + G),   nu = (3 K - 2 G) / (2 (3 K + G))

For two constituents these are the familiar ``K = K_m + c (K_i - K_m) / (1 + (1 - c)
(K_i - K_m) / (K_m + 4/3 G_m))`` and its shear and conductivity (Hatta-Taya) analogues, and
the expansion is Levin's exact two-phase formula.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

__all__ = ["MIXING_RULES", "mix", "mix_linear", "mix_mori_tanaka", "mix_config", "lame",
           "thermal_modulus"]


def mix_linear(c: np.ndarray, table: Mapping[str, np.ndarray], matrix: int | None = None
               ) -> dict[str, np.ndarray]:
    """The linear rule of mixtures, ``P = c @ P_r`` for each property.

    >>> t = {"conductivity": np.array([35.0, 90.7]), "youngs_modulus": np.array([393e9, 199.5e9]),
    ...      "poisson_ratio": np.array([0.25, 0.3]), "expansion": np.array([7.4e-6, 15.4e-6])}
    >>> float(mix_linear(np.array([[0.5, 0.5]]), t)["poisson_ratio"][0])
    0.275
    """
    c = np.asarray(c, dtype=np.float64)
    return {k: c @ np.asarray(v, dtype=np.float64) for k, v in table.items()}


def _weighted(c: np.ndarray, value: np.ndarray, factor: np.ndarray) -> np.ndarray:
    w = c * factor
    return (w @ value) / w.sum(axis=1)


def mix_mori_tanaka(c: np.ndarray, table: Mapping[str, np.ndarray], matrix: int = 0
                    ) -> dict[str, np.ndarray]:
    """The Mori-Tanaka estimate with constituent ``matrix`` (an index) as the matrix (see the
    module docstring for the formulas)."""
    c = np.asarray(c, dtype=np.float64)
    E, nu = np.asarray(table["youngs_modulus"]), np.asarray(table["poisson_ratio"])
    k, alpha = np.asarray(table["conductivity"]), np.asarray(table["expansion"])
    K = E / (3 * (1 - 2 * nu))
    G = E / (2 * (1 + nu))
    Km, Gm, km = K[matrix], G[matrix], k[matrix]
    fm = Gm * (9 * Km + 8 * Gm) / (6 * (Km + 2 * Gm))
    A = (Km + 4 / 3 * Gm) / (K + 4 / 3 * Gm)
    B = (Gm + fm) / (G + fm)
    D = 3 * km / (k + 2 * km)
    Ke = _weighted(c, K, A)
    Ge = _weighted(c, G, B)
    return {"conductivity": _weighted(c, k, D),
            "youngs_modulus": 9 * Ke * Ge / (3 * Ke + Ge),
            "poisson_ratio": (3 * Ke - 2 * Ge) / (2 * (3 * Ke + Ge)),
            "expansion": _weighted(c, alpha, K * A)}


#: mixing rules by the name used in ``[fea] mixing``
MIXING_RULES: dict[str, Callable] = {"linear": mix_linear, "mori-tanaka": mix_mori_tanaka}


def mix(c: np.ndarray, table: Mapping[str, np.ndarray], rule: str = "linear",
        matrix: int = 0) -> dict[str, np.ndarray]:
    """Effective properties by the named rule (``"linear"`` or ``"mori-tanaka"``)."""
    return MIXING_RULES[rule](c, table, matrix)


def mix_config(c: np.ndarray, config, constituents) -> dict[str, np.ndarray]:
    """Effective properties of compositions ``c`` ``(N, m)`` (columns in the order of
    ``constituents``) by the rule and constituent properties of an ``[fea]`` table
    (:class:`~hetmesh.fea.config.FEAConfig`; boundary conditions not needed)."""
    cons = list(constituents)
    matrix = cons.index(config.matrix) if config.matrix is not None else 0
    return mix(c, config.table(), config.mixing, matrix)


def lame(E: np.ndarray, nu: np.ndarray, plane: str = "strain") -> tuple[np.ndarray, np.ndarray]:
    """Lame parameters ``(lambda, mu)`` of the 2-D constitutive law.

    Plane strain: ``lambda = E nu / ((1 + nu)(1 - 2 nu))``; plane stress uses the reduced
    ``lambda* = E nu / (1 - nu^2)``; ``mu = E / (2 (1 + nu))`` in both.
    """
    mu = E / (2 * (1 + nu))
    lam = E * nu / (1 - nu * nu) if plane == "stress" else E * nu / ((1 + nu) * (1 - 2 * nu))
    return lam, mu


def thermal_modulus(E: np.ndarray, nu: np.ndarray, alpha: np.ndarray,
                    plane: str = "strain") -> np.ndarray:
    """``beta`` with thermal stress ``-beta dT I`` in the plane: ``E alpha / (1 - 2 nu)`` in
    plane strain (``(3 lambda + 2 mu) alpha``), ``E alpha / (1 - nu)`` in plane stress."""
    return E * alpha / (1 - nu) if plane == "stress" else E * alpha / (1 - 2 * nu)
