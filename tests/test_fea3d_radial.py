"""The exact 1-D radial references (hetmesh.fea.radial) against closed forms and their ODEs."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from hetmesh.errors import FEAError
from hetmesh.fea import radial
from hetmesh.fea.verification import graded_profiles, reference

A, B = 10.0, 20.0
R = np.linspace(A, B, 9)


def const(v):
    return lambda r: v + 0.0 * np.asarray(r, dtype=np.float64)


def test_homogeneous_cylinder_is_lame():
    p = 100e6
    s = radial.cylinder(A, B, const(200e9), const(0.3), p_inner=p)
    c = p * A * A / (B * B - A * A)
    np.testing.assert_allclose(s.sigma_r(R), c * (1 - B * B / R ** 2), rtol=0, atol=1e-9 * p)
    np.testing.assert_allclose(s.sigma_t(R), c * (1 + B * B / R ** 2), rtol=1e-10)
    # plane strain: sigma_z = nu (sigma_r + sigma_t) = 2 nu c
    np.testing.assert_allclose(s.sigma_z(R), 2 * 0.3 * c, rtol=1e-10)
    # u = (1 + nu) / E (r (1 - 2 nu) c + c b^2 / r)
    u = (1 + 0.3) / 200e9 * ((1 - 2 * 0.3) * c * R + c * B * B / R)
    np.testing.assert_allclose(s.displacement(R), u, rtol=1e-10)
    assert s.error_estimate < 1e-8


def test_homogeneous_sphere_is_lame():
    p = 100e6
    s = radial.sphere(A, B, const(200e9), const(0.3), p_inner=p)
    c = p * A ** 3 / (B ** 3 - A ** 3)
    np.testing.assert_allclose(s.sigma_r(R), c * (1 - B ** 3 / R ** 3), rtol=0, atol=1e-9 * p)
    np.testing.assert_allclose(s.sigma_t(R), c * (1 + B ** 3 / (2 * R ** 3)), rtol=1e-10)
    with pytest.raises(FEAError):
        s.sigma_z(R)


def test_homogeneous_thermal_cylinder_is_the_closed_form():
    """Plane-strain thermal stresses of a homogeneous tube with T = T_a + (T_b - T_a)
    ln(r/a) / ln(b/a) (Timoshenko and Goodier, Sec. 150)."""
    E, nu, alpha, Ta, Tb, Tr = 200e9, 0.3, 1e-5, 1173.15, 273.15, 273.15
    s = radial.cylinder(A, B, const(E), const(nu), alpha=const(alpha), k=const(50.0),
                        t_inner=Ta, t_outer=Tb, t_ref=Tr)
    T = Ta + (Tb - Ta) * np.log(R / A) / np.log(B / A)
    np.testing.assert_allclose(s.temperature(R), T, rtol=1e-12)

    def dT(x):
        return Ta + (Tb - Ta) * np.log(x / A) / np.log(B / A) - Tr

    c = E * alpha / (1 - nu)
    full = quad(lambda x: dT(x) * x, A, B, epsrel=1e-13)[0]
    part = np.array([quad(lambda x: dT(x) * x, A, r, epsrel=1e-13)[0] for r in R])
    sr = c / R ** 2 * ((R ** 2 - A * A) / (B * B - A * A) * full - part)
    st = c / R ** 2 * ((R ** 2 + A * A) / (B * B - A * A) * full + part - dT(R) * R ** 2)
    scale = np.abs(st).max()
    np.testing.assert_allclose(s.sigma_r(R), sr, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(s.sigma_t(R), st, rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize("case", ["pressure", "thermal", "sphere"])
def test_graded_solution_satisfies_its_equations(case):
    """The graded references meet the boundary conditions and the equilibrium equation
    (checked by finite differences), and their error estimate is below 1e-8."""
    s = reference(case)
    assert s.error_estimate < 1e-8
    scale = float(np.abs(s.sigma_t(R)).max())
    p = 100e6 if case != "thermal" else 0.0
    assert abs(s.sigma_r(A) + p) < 1e-9 * scale
    assert abs(s.sigma_r(B)) < 1e-9 * scale
    n = 2 if case == "sphere" else 1
    r = np.linspace(A + 0.5, B - 0.5, 7)
    h = 1e-4
    dsr = (s.sigma_r(r + h) - s.sigma_r(r - h)) / (2 * h)
    np.testing.assert_allclose(dsr, n * (s.sigma_t(r) - s.sigma_r(r)) / r, rtol=0,
                               atol=1e-6 * scale)
    # the constitutive law: sigma_t from u and u' (finite differences), the profiles mixed
    f = graded_profiles()
    E, nu = f["E"](r), f["nu"](r)
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    u = s.displacement(r)
    du = (s.displacement(r + h) - s.displacement(r - h)) / (2 * h)
    th = E * f["alpha"](r) / (1 - 2 * nu) * (s.temperature(r) - s.t_ref)
    st = lam * du + (lam + 2 * mu + (n - 1) * lam) * u / r - th
    np.testing.assert_allclose(st, s.sigma_t(r), rtol=0, atol=1e-6 * scale)


def test_graded_temperature_is_the_quadrature():
    s = reference("thermal")
    k = graded_profiles()["k"]
    total = quad(lambda x: 1 / (x * k(np.asarray(x))), A, B, epsrel=1e-13)[0]
    for r in (12.5, 15.0, 17.5):
        part = quad(lambda x: 1 / (x * k(np.asarray(x))), A, r, epsrel=1e-13)[0]
        assert s.temperature(r) == pytest.approx(1173.15 - 900.0 * part / total, abs=1e-9)


def test_bad_input_is_named():
    with pytest.raises(FEAError, match="0 < a < b"):
        radial.cylinder(2.0, 1.0, const(1e9), const(0.3))
    with pytest.raises(FEAError, match="conductivity"):
        radial.cylinder(1.0, 2.0, const(1e9), const(0.3), t_inner=300.0, t_outer=400.0)
    s = radial.cylinder(1.0, 2.0, const(1e9), const(0.3), p_inner=1.0)
    with pytest.raises(FEAError, match="outside"):
        s.sigma_r(3.0)
