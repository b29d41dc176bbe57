"""A goal-oriented (dual-weighted) error indicator for the von Mises stress at point probes.

Zienkiewicz-Zhu's indicator (:mod:`hetmesh.fea.estimate`) measures the error in the energy
norm over the whole solid; a study that asks for the stress at a few points is served by
the elements whose error reaches those points. The classic answer (Becker and Rannacher
2001, "An optimal control approach to a posteriori error estimation in finite element
methods"; Prudhomme and Oden 1999, "On goal-oriented error estimation for elliptic
problems") weights the error of every element by the solution of a **dual problem** whose
load is the quantity of interest:

1. **The functional.** For each probe ``x_i`` with von Mises stress ``s_i`` in the primal
   solution, the linearised, relative von Mises functional
   ``J_i(v) = int k_i(x) n_i : sigma(v) dx``, ``n_i = 3 dev(sigma(x_i)) / (2 s_i^2)`` (so
   that ``J_i(u) ~ 1`` and an error ``e`` changes it by ``delta s_i / s_i``), mollified by
   a Gaussian ``k_i = exp(-|x - x_i|^2 / rho^2)`` normalised to ``int k_i = 1`` on the
   mesh (``rho`` a fraction of the solid's diameter, at least a factor, 1 unless told, times
   the longest edge of the element holding the probe); the functional of all probes is
   the sum ``J = sum_i J_i``.
2. **The dual problem**: ``z`` with ``a(v, z) = J(v)`` for every admissible ``v`` (the
   primal's stiffness and fixed displacement components, homogeneous); its load is a
   prestress, ``int k 2 mu n : eps(v)`` (``n`` is deviatoric, so the ``lambda tr n`` part
   vanishes), solved with the primal's element order by
   :func:`hetmesh.fea.linsolve.solve_spd`.
3. **The indicator**: ``J(u) - J(u_h) = a(u - u_h, z - z_h) <= sum_T ||u - u_h||_T
   ||z - z_h||_T`` (Galerkin orthogonality, then Cauchy-Schwarz on every element), each
   factor estimated by ZZ recovery (:func:`hetmesh.fea.estimate.zz_indicator`):
   ``eta_T = eta_T(u) eta_T(z)``. Their sum bounds the relative probe error up to the
   recovery's accuracy; marking by it puts the elements where the primal's error reaches
   the probes.

Only 3-D (tetrahedral) meshes, like :mod:`hetmesh.fea.adapt`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import FEAError
from .analysis3d import mesh_conditions
from .estimate import zz_indicator
from .linsolve import blas_threads, rigid_modes, solve_spd
from .recovery3d import (
    STRESS_NAMES_3D,
    displacement_gradients,
    locate_tet,
    recover_stresses,
    stresses_3d,
)
from .solid import (
    elasticity_matrix,
    node_pattern,
    quadrature_properties,
    surface_dofs,
    tet_space,
)

__all__ = ["von_mises_direction", "DualSolution", "dual_solution", "dual_indicator",
           "goal_indicator", "goal_estimate", "DEFAULT_RADIUS", "DEFAULT_ELEMENT_FACTOR"]

#: the mollifier's radius rho, x the solid's diameter (at least the probe element's size)
DEFAULT_RADIUS = 0.005
#: the mollifier's radius is at least this times the longest edge of the probe's element
DEFAULT_ELEMENT_FACTOR = 1.0


def von_mises_direction(stress: np.ndarray) -> np.ndarray:
    """``n = 3 dev(sigma) / (2 s^2)`` (3 x 3) for a stress ``(6,)`` (``xx, yy, zz, xy, yz,
    xz``) of von Mises stress ``s``: the derivative of ``s`` divided by ``s``, so that
    ``n : sigma = 1`` and ``n : d sigma`` is the relative change of ``s``; zeros for a
    zero deviator.

    >>> n = von_mises_direction(np.array([2.0, 0, 0, 0, 0, 0]))   # uniaxial: s = 2
    >>> float(np.tensordot(n, np.diag([2.0, 0, 0]))), float(np.trace(n))
    (1.0, 0.0)
    """
    s = np.asarray(stress, dtype=np.float64)
    S = np.array([[s[0], s[3], s[5]], [s[3], s[1], s[4]], [s[5], s[4], s[2]]])
    dev = S - np.trace(S) / 3.0 * np.eye(3)
    vm2 = 1.5 * float((dev * dev).sum())
    return np.zeros((3, 3)) if vm2 <= 0 else 1.5 * dev / vm2


def _mollifier(xq: np.ndarray, dx: np.ndarray, center: np.ndarray, rho: float) -> np.ndarray:
    """``k (M, Q)``: the Gaussian of radius ``rho`` about ``center`` at the quadrature points
    ``xq (M, Q, 3)``, normalised so that ``sum dx k = 1``."""
    d2 = ((xq - center) ** 2).sum(axis=-1)
    k = np.exp(-d2 / rho ** 2)
    total = float((dx * k).sum())
    if not total > 0:
        raise FEAError(f"the probe functional at ({center[0]:.6g}, {center[1]:.6g}, "
                       f"{center[2]:.6g}) has no weight on the mesh")
    return k / total


@dataclass(frozen=True, eq=False)
class DualSolution:
    """The dual problem of the probe functional, solved: the element ``space``, the dual
    displacement dofs ``z`` (interleaved, metres per unit functional) and its ``load``
    (``J`` as a vector: ``load . u`` is ``J(u_h)`` for a displacement ``u_h`` of the same
    space), the properties at the quadrature points, the element pieces, the mollifier
    radius of every probe (model units) and the linear solver's facts."""

    space: Any
    z: np.ndarray
    load: np.ndarray
    props: dict
    groups: np.ndarray
    rho: dict
    solver: dict


def dual_solution(mesh, model, cfg, probes: Mapping[str, Mapping[str, float]], *,
                  names: Sequence[str] | None = None, radius: float = DEFAULT_RADIUS,
                  element_factor: float = DEFAULT_ELEMENT_FACTOR) -> DualSolution:
    """Solve the dual problem of the relative von Mises functional of the probes ``names``
    (default all; see the module docstring).

    Parameters
    ----------
    mesh : Mesh
        The tetrahedral mesh of the primal solve.
    model, cfg : the model and its :class:`~hetmesh.fea.config3d.FEAConfig3D`
    probes : name -> the primal's probe record (``x, y, z`` and the six stresses, as
        :attr:`hetmesh.fea.analysis3d.FEAResult3D.probes`)
    radius : float
        The mollifier's radius rho, x the solid's diameter (the mesh's bounding-box diagonal
        when the model has no solid); at least ``element_factor`` times the longest edge of
        the element holding the probe.
    element_factor : float
        That floor's factor (> 0; default :data:`DEFAULT_ELEMENT_FACTOR`, the whole edge).
        On long, flat tetrahedra the whole edge makes the functional an average over a ball
        much larger than the elements around the probe; a smaller factor keeps it near the
        point.
    """
    if not (isinstance(element_factor, (int, float)) and math.isfinite(element_factor)
            and element_factor > 0):
        raise FEAError(f"goal-oriented indicator: the mollifier's element factor must be a "
                       f"number > 0, got {element_factor!r}")
    names = list(probes) if names is None else list(names)
    missing = [n for n in names if n not in probes]
    if missing:
        raise FEAError(f"goal-oriented indicator: no probe named {', '.join(missing)}")
    P = np.asarray(mesh.points, dtype=np.float64)
    T = np.asarray(mesh.cells, dtype=np.int64)
    cond = mesh_conditions(mesh, model, cfg)
    ls = float(cfg.length_scale)
    origin = 0.5 * (P.min(axis=0) + P.max(axis=0))
    solid = getattr(model, "solid", None)
    diam = float(solid.diameter) if solid is not None else float(
        np.linalg.norm(P.max(axis=0) - P.min(axis=0)))
    with blas_threads(1):
        space = tet_space((P - origin) * ls, T, cfg.order)
        props = quadrature_properties(space, cond.material, origin, ls)
        xq = space.quadrature_points() / ls + origin              # (M, Q, 3) model units
        f = np.zeros(3 * space.n)
        rhos = {}
        for name in names:
            rec = probes[name]
            q = np.array([rec["x"], rec["y"], rec["z"]], dtype=np.float64)
            n = von_mises_direction(np.array([rec[k] for k in STRESS_NAMES_3D], dtype=float))
            e, _ = locate_tet(P, T, q)
            h = float(np.linalg.norm(P[T[e]][:, None] - P[T[e]][None], axis=-1).max())
            rho = rhos[name] = max(radius * diam, element_factor * h)
            k = _mollifier(xq, space.dx, q, rho)
            near = np.flatnonzero((k > 1e-12 * k.max()).any(axis=1))
            # int k 2 mu n : eps(v) = sum_q dx k 2 mu (n g_i)_a for component a of node i
            g = space.gradients(near)                             # (m, Q, nb, 3) per metre
            w = space.dx[near] * k[near] * 2.0 * props["mu"][near]
            fe = np.einsum("mq,mqib,ab->mia", w, g, n)
            idx = (3 * space.dofs[near][:, :, None] + np.arange(3)).ravel()
            f += np.bincount(idx, weights=fe.ravel(), minlength=3 * space.n)
        fixed = np.zeros(3 * space.n, dtype=bool)
        for bc in cond.displacement:
            d = surface_dofs(space, np.asarray(bc.mask, dtype=bool))
            for c, v in enumerate(bc.components):
                if v is not None:
                    fixed[3 * d + c] = True
        A = elasticity_matrix(space, props["lam"], props["mu"],
                              node_pattern(space.dofs, space.n))
        z, info = solve_spd(A, f, fixed, np.zeros(3 * space.n), what="elastic",
                            method=cfg.solver, blocksize=3,
                            near_nullspace=rigid_modes(np.asarray(space.basis.doflocs).T))
    return DualSolution(space, z, f, props, cond.groups, rhos, info)


def dual_indicator(dual: DualSolution) -> tuple[np.ndarray, float]:
    """``(eta_z (M,), energy)``: the ZZ indicator of the dual solution, ``||z - z_h||_T``
    estimated by stress recovery (:func:`hetmesh.fea.estimate.zz_indicator`), and the
    energy norm of ``z_h``."""
    space, props = dual.space, dual.props
    T = np.asarray(space.mesh.t.T, dtype=np.int64)
    with blas_threads(1):
        zero = np.zeros(space.dx.shape)
        sq = stresses_3d(displacement_gradients(space, dual.z.reshape(-1, 3)), props["lam"],
                         props["mu"], zero, zero)
        rec, copies, _ = recover_stresses(space, T, int(space.mesh.p.shape[1]), sq,
                                          dual.groups, space.order, None)
        return zz_indicator(space, rec, copies, sq, props["youngs_modulus"],
                            props["poisson_ratio"])


def goal_indicator(eta_primal: np.ndarray, eta_dual: np.ndarray) -> np.ndarray:
    """``sqrt(eta_T(u) eta_T(z))``: the square root of every element's dual-weighted
    contribution, so that :func:`hetmesh.fea.adapt.doerfler_mark` (which sums squares)
    marks by the contributions ``eta_T(u) eta_T(z)`` themselves.

    >>> goal_indicator(np.array([4.0, 1.0]), np.array([1.0, 9.0])).tolist()
    [2.0, 3.0]
    """
    prod = np.asarray(eta_primal, dtype=np.float64) * np.asarray(eta_dual, dtype=np.float64)
    return np.sqrt(np.maximum(prod, 0.0))


def goal_estimate(eta_primal: np.ndarray, eta_dual: np.ndarray) -> float:
    """``sum_T eta_T(u) eta_T(z)``: the estimated bound of the relative probe error (the
    dual functional is relative to the probes' von Mises stresses)."""
    return float(math.fsum(np.asarray(eta_primal) * np.asarray(eta_dual)))
