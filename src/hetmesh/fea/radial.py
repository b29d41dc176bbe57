"""Exact 1-D radial references for graded cylinders and spheres (the 3-D FEA's validation).

A thick-walled cylinder in plane strain or a hollow sphere, inner radius ``a``, outer ``b``,
whose properties vary only with the radius ``r`` -- Young's modulus ``E(r)``, Poisson ratio
``nu(r)``, expansion ``alpha(r)``, conductivity ``k(r)`` -- deforms radially, ``u = u(r)
e_r``, and the 3-D equations reduce to ordinary differential equations in ``r``
(derived in ``docs/fea.md``, section "3-D analysis"). With ``lambda, mu`` the Lame parameters,
``C11 = lambda + 2 mu``, ``C12 = lambda``, ``beta = (3 lambda + 2 mu) alpha = E alpha /
(1 - 2 nu)`` and ``dT = T(r) - T_ref``:

- cylinder, plane strain (``eps_z = 0``)::

    sigma_r = C11 u' + C12 u / r - beta dT,   sigma_t = C12 u' + C11 u / r - beta dT,
    sigma_z = lambda (u' + u / r) - beta dT,  sigma_r' = (sigma_t - sigma_r) / r

- sphere (``sigma_t = sigma_phi``)::

    sigma_r = C11 u' + 2 C12 u / r - beta dT,  sigma_t = C12 u' + (C11 + C12) u / r - beta dT,
    sigma_r' = 2 (sigma_t - sigma_r) / r

with ``sigma_r(a) = -p_inner``, ``sigma_r(b) = -p_outer``. Written as the first-order system
in ``(u, sigma_r)`` this is linear, so it is solved by superposition: one particular and one
homogeneous initial-value problem, integrated by an 8th-order Runge-Kutta method (DOP853) at
``rtol = 1e-12``, combined to meet the outer condition. Steady conduction ``(r^n k T')' = 0``
(``n = 1`` cylinder, ``2`` sphere) gives ``T = T_a + (T_b - T_a) I(r) / I(b)``,
``I(r) = int_a^r ds / (s^n k(s))``, integrated as a third component of the same system (and
``I(b)`` first by adaptive quadrature). Each solution is computed twice, at ``rtol`` and at
``100 rtol``; their largest difference, relative to the stress scale, is reported as
:attr:`RadialSolution.error_estimate` (it bounds the error of the coarser solve, so of the
finer one as well).

Units: any consistent set; stresses come out in the units of the pressures and moduli (Pa),
displacements in the units of the radii, temperatures in K.

>>> E = lambda r: 200e9 + 0 * r
>>> nu = lambda r: 0.3 + 0 * r
>>> s = cylinder(1.0, 2.0, E, nu, p_inner=100e6)
>>> round(float(s.sigma_t(1.0)) / 100e6, 8)      # Lame: p (b^2 + a^2) / (b^2 - a^2)
1.66666667
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad, solve_ivp

from ..errors import FEAError

__all__ = ["RadialSolution", "cylinder", "sphere", "conduction_integral", "GEOMETRIES"]

Profile = Callable[[np.ndarray], np.ndarray]

#: exponent ``n`` of ``r`` in ``(r^n k T')' = 0`` and ``sigma_r' = n (sigma_t - sigma_r) / r``
GEOMETRIES = {"cylinder": 1, "sphere": 2}


@dataclass(frozen=True, eq=False)
class RadialSolution:
    """A solved radial problem; every method takes radii (array-like) and returns arrays.

    Attributes
    ----------
    geometry : "cylinder" or "sphere"
    a, b : inner and outer radius
    error_estimate : float
        Largest difference of the stresses between the solve at ``rtol`` and at ``100 rtol``,
        over 2001 radii, relative to the largest stress magnitude (and of the temperatures
        relative to the temperature range).
    """

    geometry: str
    a: float
    b: float
    _sol: object
    _props: tuple
    t_inner: float | None
    t_outer: float | None
    t_ref: float
    i_b: float
    error_estimate: float

    def _state(self, r) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        r = np.asarray(r, dtype=np.float64)
        if np.any(r < self.a * (1 - 1e-12)) or np.any(r > self.b * (1 + 1e-12)):
            raise FEAError(f"radius outside [{self.a:g}, {self.b:g}]")
        y = self._sol(np.clip(r, self.a, self.b).ravel())
        shape = r.shape
        return r, y[0].reshape(shape), y[1].reshape(shape), y[2].reshape(shape)

    def temperature(self, r) -> np.ndarray:
        """Temperature (K); ``t_ref`` everywhere for an isothermal problem."""
        _, _, _, i = self._state(r)
        if self.t_inner is None:
            return np.full(np.shape(r), self.t_ref)
        return self.t_inner + (self.t_outer - self.t_inner) * i / self.i_b

    def displacement(self, r) -> np.ndarray:
        """Radial displacement ``u(r)``."""
        return self._state(r)[1]

    def sigma_r(self, r) -> np.ndarray:
        """Radial stress."""
        return self._state(r)[2]

    def _parts(self, r):
        r, u, sr, _ = self._state(r)
        E, nu, alpha = (np.asarray(f(r), dtype=np.float64) for f in self._props)
        lam, mu = _lame(E, nu)
        beta = E * alpha / (1 - 2 * nu)
        dT = self.temperature(r) - self.t_ref
        n = GEOMETRIES[self.geometry]
        c11 = lam + 2 * mu
        du = (sr + beta * dT - n * lam * u / r) / c11
        return r, u, du, lam, c11, beta * dT, n

    def sigma_t(self, r) -> np.ndarray:
        """Hoop stress (``sigma_theta``; in a sphere also ``sigma_phi``)."""
        r, u, du, lam, c11, th, n = self._parts(r)
        return lam * du + (c11 + (n - 1) * lam) * u / r - th

    def sigma_z(self, r) -> np.ndarray:
        """Axial stress of the plane-strain cylinder, ``lambda (u' + u / r) - beta dT``."""
        if self.geometry != "cylinder":
            raise FEAError("sigma_z is defined for the cylinder; a sphere has sigma_t twice")
        r, u, du, lam, _, th, _ = self._parts(r)
        return lam * (du + u / r) - th


def _zero(r):
    return 0.0 * np.asarray(r, dtype=np.float64)


def _lame(E, nu):
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def conduction_integral(a: float, b: float, k: Profile, n: int) -> float:
    """``int_a^b ds / (s^n k(s))`` by adaptive quadrature (relative accuracy ~1e-13)."""
    v, err = quad(lambda s: 1.0 / (s ** n * float(k(np.asarray(s)))), a, b,
                  epsabs=0.0, epsrel=1e-13, limit=200)
    return float(v)


def _solve(geometry: str, a: float, b: float, E: Profile, nu: Profile, alpha: Profile,
           k: Profile | None, p_inner: float, p_outer: float, t_inner, t_outer, t_ref,
           rtol: float):
    n = GEOMETRIES[geometry]
    thermal = t_inner is not None
    i_b = conduction_integral(a, b, k, n) if thermal else 1.0
    E0 = float(np.max(np.abs(E(np.linspace(a, b, 11)))))
    if thermal:
        a0 = float(np.max(np.abs(alpha(np.linspace(a, b, 11)))))
        s_scale = max(abs(p_inner), abs(p_outer), E0 * a0 * max(abs(t_inner - t_ref),
                                                               abs(t_outer - t_ref)))
    else:
        s_scale = max(abs(p_inner), abs(p_outer))
    if s_scale == 0:
        s_scale = 1.0
    u_scale = s_scale * b / E0

    def rhs(r, y):
        # y = [u_p, s_p, u_h, s_h, I]: particular (with loads) and homogeneous solutions
        Er, nur = float(E(np.asarray(r))), float(nu(np.asarray(r)))
        lam, mu = _lame(Er, nur)
        c11 = lam + 2 * mu
        if thermal:
            T = t_inner + (t_outer - t_inner) * y[4] / i_b
            th = Er * float(alpha(np.asarray(r))) / (1 - 2 * nur) * (T - t_ref)
            di = 1.0 / (r ** n * float(k(np.asarray(r))))
        else:
            th, di = 0.0, 0.0
        out = np.empty(5)
        for j, load in ((0, th), (2, 0.0)):
            u, s = y[j], y[j + 1]
            du = (s + load - n * lam * u / r) / c11
            st = lam * du + (c11 + (n - 1) * lam) * u / r - load
            out[j], out[j + 1] = du, n * (st - s) / r
        out[4] = di
        return out

    atol = np.array([u_scale, s_scale, u_scale, s_scale, i_b]) * rtol * 1e-2
    y0 = [0.0, -p_inner, u_scale, 0.0, 0.0]
    sol = solve_ivp(rhs, (a, b), y0, method="DOP853", rtol=rtol, atol=atol,
                    dense_output=True)
    if not sol.success:
        raise FEAError(f"radial {geometry}: the integration failed ({sol.message})")
    yb = sol.y[:, -1]
    if yb[3] == 0:
        raise FEAError(f"radial {geometry}: singular problem (no homogeneous response)")
    c = (-p_outer - yb[1]) / yb[3]
    dense = sol.sol

    def combined(r):
        y = dense(r)
        return np.vstack([y[0] + c * y[2], y[1] + c * y[3], y[4]])

    return combined, i_b, s_scale


def _radial(geometry, a, b, E, nu, alpha, k, p_inner, p_outer, t_inner, t_outer, t_ref,
            rtol) -> RadialSolution:
    if not 0 < a < b:
        raise FEAError(f"radial {geometry}: expected 0 < a < b, got a = {a:g}, b = {b:g}")
    if (t_inner is None) != (t_outer is None):
        raise FEAError("give both t_inner and t_outer, or neither")
    if t_inner is not None and k is None:
        raise FEAError("a thermal problem needs the conductivity profile k")
    alpha = alpha if alpha is not None else _zero
    fine, i_b, s_scale = _solve(geometry, a, b, E, nu, alpha, k, p_inner, p_outer, t_inner,
                                t_outer, t_ref, rtol)
    coarse, _, _ = _solve(geometry, a, b, E, nu, alpha, k, p_inner, p_outer, t_inner,
                          t_outer, t_ref, 100 * rtol)
    sol = RadialSolution(geometry, a, b, fine, (E, nu, alpha), t_inner, t_outer, t_ref, i_b,
                         0.0)
    chk = RadialSolution(geometry, a, b, coarse, (E, nu, alpha), t_inner, t_outer, t_ref,
                         i_b, 0.0)
    r = np.linspace(a, b, 2001)
    stress = max(float(np.max(np.abs(sol.sigma_r(r)))), float(np.max(np.abs(sol.sigma_t(r)))))
    err = max(float(np.max(np.abs(sol.sigma_r(r) - chk.sigma_r(r)))),
              float(np.max(np.abs(sol.sigma_t(r) - chk.sigma_t(r))))) / max(stress, 1e-300)
    if t_inner is not None:
        err = max(err, float(np.max(np.abs(sol.temperature(r) - chk.temperature(r))))
                  / max(abs(t_outer - t_inner), 1e-300))
    return RadialSolution(geometry, a, b, fine, (E, nu, alpha), t_inner, t_outer, t_ref, i_b,
                          err)


def cylinder(a: float, b: float, E: Profile, nu: Profile, *, alpha: Profile | None = None,
             k: Profile | None = None, p_inner: float = 0.0, p_outer: float = 0.0,
             t_inner: float | None = None, t_outer: float | None = None,
             t_ref: float = 293.15, rtol: float = 1e-12) -> RadialSolution:
    """The graded thick-walled cylinder in plane strain (see the module docstring).

    Parameters
    ----------
    a, b : inner and outer radius
    E, nu, alpha, k : callables of the radius (arrays in, arrays out)
    p_inner, p_outer : pressures on the inner and outer surface (positive pushes inwards on
        the surface, i.e. ``sigma_r = -p``)
    t_inner, t_outer : fixed surface temperatures (K), or None for an isothermal problem
    t_ref : stress-free temperature (K)
    rtol : relative tolerance of the integration

    Returns
    -------
    RadialSolution
    """
    return _radial("cylinder", a, b, E, nu, alpha, k, p_inner, p_outer, t_inner, t_outer,
                   t_ref, rtol)


def sphere(a: float, b: float, E: Profile, nu: Profile, *, alpha: Profile | None = None,
           k: Profile | None = None, p_inner: float = 0.0, p_outer: float = 0.0,
           t_inner: float | None = None, t_outer: float | None = None,
           t_ref: float = 293.15, rtol: float = 1e-12) -> RadialSolution:
    """The graded hollow sphere (see :func:`cylinder` for the parameters).

    >>> s = sphere(1.0, 2.0, lambda r: 1e9 + 0 * r, lambda r: 0.25 + 0 * r, p_inner=7.0)
    >>> round(float(s.sigma_t(1.0)), 8)          # p (b^3 + 2 a^3) / (2 (b^3 - a^3))
    5.0
    """
    return _radial("sphere", a, b, E, nu, alpha, k, p_inner, p_outer, t_inner, t_outer,
                   t_ref, rtol)
