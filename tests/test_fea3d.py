"""3-D conduction and thermoelasticity on tetrahedra (hetmesh.fea.solid, linsolve,
verification): assembly against scikit-fem, patch tests, loads, singular systems, the solvers,
and the graded cylinder against its exact radial reference."""

from __future__ import annotations

import numpy as np
import pytest

from hetmesh.errors import FEAError
from hetmesh.fea import linsolve, recovery3d, solid, verification
from hetmesh.fea.solid import Displacement, solve_tets

E0, NU0, ALPHA0, K0 = 200e9, 0.3, 1.2e-5, 40.0


def homogeneous(x):
    one = np.ones(len(x))
    return {"conductivity": K0 * one, "youngs_modulus": E0 * one, "poisson_ratio": NU0 * one,
            "expansion": ALPHA0 * one}


def graded_box(x):
    """A material varying in all three directions (for the assembly comparison)."""
    c = 0.2 + 0.6 * (x[:, 0] ** 2 + 0.5 * x[:, 1] + 0.3 * x[:, 2] * x[:, 0])
    return {"conductivity": 35.0 + 55.0 * c, "youngs_modulus": 393e9 - 190e9 * c,
            "poisson_ratio": 0.25 + 0.05 * c, "expansion": (7.4 + 8.0 * c) * 1e-6}


def box(n=3):
    from skfem import MeshTet

    m = MeshTet.init_tensor(*(np.linspace(0.0, 1.0, n + 1),) * 3)
    # a shear of the grid, so that no element is axis-aligned
    P = m.p.T @ np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.15], [0.05, 0.0, 1.0]])
    return P, m.t.T.copy()


@pytest.mark.parametrize("order", [1, 2])
def test_assembly_matches_scikit_fem(order):
    """The chunked block assembly equals scikit-fem's own forms on a graded material."""
    from skfem import Basis, BilinearForm, ElementTetP1, ElementTetP2, ElementVector, asm
    from skfem.helpers import ddot, dot, grad, sym_grad, trace

    P, T = box(2)
    space = solid.tet_space(P, T, order)
    xq = space.quadrature_points()
    M, Q = xq.shape[:2]
    pr = {k: v.reshape(M, Q) for k, v in graded_box(xq.reshape(-1, 3)).items()}
    E, nu = pr["youngs_modulus"], pr["poisson_ratio"]
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    A = solid.elasticity_matrix(space, lam, mu).toarray()
    K = solid.conduction_matrix(space, pr["conductivity"]).toarray()

    elem = ElementTetP2() if order == 2 else ElementTetP1()
    vb = Basis(space.mesh, ElementVector(elem), intorder=2 * order)

    @BilinearForm
    def stiffness(u, v, w):
        eu, ev = sym_grad(u), sym_grad(v)
        return w["lam"] * trace(eu) * trace(ev) + 2.0 * w["mu"] * ddot(eu, ev)

    @BilinearForm
    def conduction(u, v, w):
        return w["k"] * dot(grad(u), grad(v))

    ref = asm(stiffness, vb, lam=lam, mu=mu).toarray()
    # skfem's vector dofs -> interleaved 3 s + c
    sb = space.basis
    perm = np.empty(3 * space.n, dtype=np.int64)
    for c in range(3):
        perm[3 * sb.nodal_dofs[0] + c] = vb.nodal_dofs[c]
        if order == 2:
            perm[3 * sb.edge_dofs[0] + c] = vb.edge_dofs[c]
    scale = np.abs(ref).max()
    np.testing.assert_allclose(A, ref[np.ix_(perm, perm)], rtol=0, atol=1e-12 * scale)
    kref = asm(conduction, space.basis, k=pr["conductivity"]).toarray()
    np.testing.assert_allclose(K, kref, rtol=0, atol=1e-12 * np.abs(kref).max())


@pytest.mark.parametrize("order", [1, 2])
def test_patch_test_linear_displacement(order):
    """Boundary dofs (vertices, and edge midpoints for P2) of a linear field: the solution is
    that field exactly and the stress the constant ``C : eps`` at every quadrature point."""
    from skfem import MeshTet

    P, T = box(3)
    G = np.array([[1.0, 0.4, -0.2], [0.3, -0.5, 0.1], [0.0, 0.2, 0.7]]) * 1e-3
    m = MeshTet(P.T, T.T)
    on = np.zeros(len(P), dtype=bool)
    on[m.facets[:, m.boundary_facets()].ravel()] = True
    space = solid.tet_space(P, T, order)
    M, Q = space.dx.shape
    lam = np.full((M, Q), E0 * NU0 / ((1 + NU0) * (1 - 2 * NU0)))
    mu = np.full((M, Q), E0 / (2 * (1 + NU0)))
    A = solid.elasticity_matrix(space, lam, mu)
    x = np.asarray(space.basis.doflocs).T
    exact = (x @ G.T).ravel()
    bd = solid.surface_dofs(space, on)
    fixed = np.zeros(3 * space.n, dtype=bool)
    for c in range(3):
        fixed[3 * bd + c] = True
    assert (~fixed).any()
    u, _ = linsolve.solve_spd(A, np.zeros(3 * space.n), fixed, np.where(fixed, exact, 0.0),
                              what="elastic", method="direct")
    np.testing.assert_allclose(u, exact, rtol=0, atol=1e-15)
    U = u.reshape(-1, 3)
    du = np.einsum("mia,mqib->mqab", U[space.dofs], space.gradients(slice(None)))
    s = recovery3d.stresses_3d(du, lam, mu, np.zeros((M, Q)), np.zeros((M, Q)))
    eps = 0.5 * (G + G.T)
    sig = lam[0, 0] * np.trace(eps) * np.eye(3) + 2 * mu[0, 0] * eps
    want = [sig[0, 0], sig[1, 1], sig[2, 2], sig[0, 1], sig[1, 2], sig[0, 2]]
    np.testing.assert_allclose(s, np.broadcast_to(want, s.shape), rtol=0,
                               atol=1e-9 * np.abs(want).max())


def test_free_thermal_expansion_is_stress_free():
    """A uniform temperature rise with statically determinate supports (3-2-1): zero
    stress, and ``u`` is ``alpha dT x`` plus a rigid motion, with both element orders and
    both solvers."""
    P, T = box(3)
    i0 = int(np.argmin(P.sum(axis=1)))
    i1 = int(np.argmax(P[:, 0] - P[:, 1] - P[:, 2]))
    i2 = int(np.argmax(P[:, 1] - P[:, 0] - P[:, 2]))

    def at(i):
        m = np.zeros(len(P), dtype=bool)
        m[i] = True
        return m

    disp = [Displacement(at(i0), 0.0, 0.0, 0.0), Displacement(at(i1), uy=0.0, uz=0.0),
            Displacement(at(i2), uz=0.0)]
    hot, ref = 500.0, 300.0
    temps = [(np.ones(len(P), dtype=bool), hot)]  # every vertex at the same temperature
    scale = E0 * ALPHA0 * (hot - ref)
    for order, method in ((1, "direct"), (2, "amg")):
        r = solve_tets(P, T, homogeneous, order=order, temperature=temps, displacement=disp,
                       reference_temperature=ref, solver=method,
                       probes={"c": tuple(P.mean(axis=0))})
        np.testing.assert_allclose(r.temperature, hot)
        assert np.abs(r.stress).max() < 1e-8 * scale
        assert np.abs(r.cell_stress).max() < 1e-8 * scale
        assert r.probes["c"]["von_mises"] < 1e-8 * scale
        # u - alpha dT x = W x + c with W skew (a rigid motion)
        rest = r.displacement - ALPHA0 * (hot - ref) * P
        X = np.column_stack([P, np.ones(len(P))])
        coef, *_ = np.linalg.lstsq(X, rest, rcond=None)
        W = coef[:3].T
        assert np.abs(X @ coef - rest).max() < 1e-12
        assert np.abs(W + W.T).max() < 1e-12
        assert np.abs(r.displacement[i0]).max() == 0.0


def test_pressure_load_resultant():
    """100 MPa on the inner face of a quarter tube (a = 10 mm, L = 5 mm) pushes with
    p a L in x and in y (the chords' projections are exact), for P1 and P2."""
    P, T = verification.annulus_tets(10.0, 20.0, 5.0, nr=2, nt=5, nz=2)
    inner = np.isclose(np.hypot(P[:, 0], P[:, 1]), 10.0)
    for order in (1, 2):
        space = solid.tet_space(P * 1e-3, T, order)
        f = solid.pressure_load(space, solid.boundary_faces(space, inner), 100e6)
        assert f[0::3].sum() == pytest.approx(100e6 * 10e-3 * 5e-3, rel=1e-12)
        assert f[1::3].sum() == pytest.approx(100e6 * 10e-3 * 5e-3, rel=1e-12)
        assert abs(f[2::3].sum()) < 1e-9


def test_prism_split_is_conforming():
    """Every interior triangle of the structured meshes is shared by exactly two tets, every
    tet has positive volume, and the half ring's volume is that of its polygonal section."""
    from skfem import MeshTet

    nt = 4
    for P, T in [
        verification.annulus_tets(1.0, 2.0, 1.0, nr=3, nt=nt, nz=2, angle=np.pi),
        verification.shell_octant_tets(1.0, 2.0, nr=2, ns=4),
    ]:
        m = MeshTet(P.T, T.T)
        counts = np.bincount(m.t2f.ravel(), minlength=m.facets.shape[1])
        assert set(np.unique(counts)) == {1, 2}
        a = P[T[:, 0]]
        v = np.einsum("ij,ij->i", np.cross(P[T[:, 1]] - a, P[T[:, 2]] - a), P[T[:, 3]] - a)
        assert (v > 0).all()
        if len(P) == 4 * (nt + 1) * 3:   # the half ring: 4 radii x 5 angles x 3 levels
            area = 0.5 * nt * np.sin(np.pi / nt) * (2.0 ** 2 - 1.0 ** 2)
            assert v.sum() / 6.0 == pytest.approx(area * 1.0, rel=1e-12)


def test_singular_systems_are_named():
    P, T = box(2)
    corner = np.zeros(len(P), dtype=bool)
    corner[0] = True
    with pytest.raises(FEAError, match="remove 3 of the 6 rigid-body modes"):
        solve_tets(P, T, homogeneous, displacement=[Displacement(corner, 0.0, 0.0, 0.0)])
    bottom = np.isclose(P[:, 2], P[:, 2].min())
    with pytest.raises(FEAError, match="selects no mesh vertex"):
        solve_tets(P, T, homogeneous, displacement=[Displacement(np.zeros(len(P), bool),
                                                                 0.0, 0.0, 0.0)])
    # a second, disconnected box without any temperature condition
    P2 = np.vstack([P, P + [5.0, 0.0, 0.0]])
    T2 = np.vstack([T, T + len(P)])
    both = np.concatenate([bottom, bottom])
    first = np.concatenate([bottom, np.zeros(len(P), bool)])
    with pytest.raises(FEAError, match="no fixed temperature"):
        solve_tets(P2, T2, homogeneous, temperature=[(first, 400.0)],
                   displacement=[Displacement(both, 0.0, 0.0, 0.0)])
    with pytest.raises(FEAError, match="unknown linear solver"):
        linsolve.solve_spd(np.eye(2), np.ones(2), np.zeros(2, bool), np.zeros(2),
                           what="thermal", method="cholesky")
    with pytest.raises(FEAError, match="outside the mesh"):
        recovery3d.locate_tet(P, T, (10.0, 10.0, 10.0))


def test_amg_and_direct_agree():
    """The multigrid-preconditioned CG and the direct solve give the same graded cylinder
    (P2) to the CG tolerance."""
    ref = verification.reference("pressure")
    a = verification.run_case("pressure", 4, 2, solver="direct", ref=ref)
    b = verification.run_case("pressure", 4, 2, solver="amg", ref=ref)
    assert b.solver["elastic"]["method"] == "amg" and b.solver["elastic"]["iterations"] > 0
    for name in a.values:
        for k in ("sigma_r", "sigma_t"):
            assert b.values[name][k] == pytest.approx(a.values[name][k], rel=1e-5)


def test_rigid_modes_span_the_kernel():
    """The rigid-body modes are in the kernel of the unconstrained elastic matrix."""
    P, T = box(2)
    space = solid.tet_space(P, T, 2)
    M, Q = space.dx.shape
    A = solid.elasticity_matrix(space, np.full((M, Q), 1e9), np.full((M, Q), 1e9))
    Bm = linsolve.rigid_modes(np.asarray(space.basis.doflocs).T)
    assert np.abs(A @ Bm).max() < 1e-9 * abs(A).max()
    assert np.linalg.matrix_rank(Bm) == 6


def test_graded_cylinder_pressure_p2_within_one_percent():
    """The graded Al2O3/Ni cylinder under 100 MPa (plane strain, quarter model): radial and
    hoop stress at R1..R3 within 1 % of the exact radial solution with quadratic elements on
    3,648 tetrahedra (0.79 % at worst; 0.08 % on 98,496 in the slow test)."""
    r = verification.run_case("pressure", 8, 2)
    assert r.tets == 3_648
    assert r.max_error < 0.01, r.errors


@pytest.mark.slow
def test_graded_cylinder_pressure_p2_under_100k_tets():
    r = verification.run_case("pressure", 24, 2)
    assert r.tets == 98_496 and r.solver["elastic"]["method"] == "amg"
    assert r.max_error < 0.002, r.errors


def test_graded_cylinder_rates():
    """Probe-stress convergence rates from np.polyfit on log errors: about 1 for linear and
    about 2 for quadratic elements (recovered stresses at a boundary probe)."""
    ref = verification.reference("pressure")
    p1 = [verification.run_case("pressure", n, 1, ref=ref) for n in (4, 6, 8, 12)]
    p2 = [verification.run_case("pressure", n, 2, ref=ref) for n in (4, 6, 8)]
    r1, r2 = verification.convergence(p1, "sigma_t"), verification.convergence(p2)
    assert 0.8 < r1 < 1.6, r1
    assert r2 > 1.7, r2
    assert p2[-1].max_error < p1[-1].max_error


def test_graded_cylinder_thermal_temperature():
    """The cylinder with 1173.15 K inside, 273.15 K outside: the probe temperatures within
    0.1 % of the range (quadratic elements), the stresses converging to the reference."""
    ref = verification.reference("thermal")
    c = verification.run_case("thermal", 4, 2, ref=ref)
    f = verification.run_case("thermal", 8, 2, ref=ref)
    assert max(e["T"] for e in f.errors.values()) < 1e-3
    assert f.max_error < 0.5 * c.max_error


@pytest.mark.slow
def test_graded_cylinder_thermal_p2_within_one_percent():
    """The thermal cylinder: temperature, radial and hoop stress at R1..R3 within 1 % of the
    exact solution on 29,184 quadratic tetrahedra (0.81 % measured)."""
    r = verification.run_case("thermal", 16, 2)
    assert r.tets == 29_184 and r.max_error < 0.01, r.errors


@pytest.mark.slow
def test_graded_sphere_converges():
    """The pressurised graded sphere (an eighth): the hoop stress within 1 % on 32,448
    quadratic tetrahedra, the radial stress (small near the outer surface) within 2.5 %, and
    both converging faster with P2 than with P1."""
    ref = verification.reference("sphere")
    p2 = [verification.run_case("sphere", n, 2, ref=ref) for n in (8, 12, 16)]
    p1 = [verification.run_case("sphere", n, 1, ref=ref) for n in (8, 12, 16)]
    last = p2[-1].errors
    assert max(e["sigma_t"] for e in last.values()) < 0.01
    assert max(e["sigma_r"] for e in last.values()) < 0.025
    assert verification.convergence(p2, "sigma_t") > 1.5
    assert p2[-1].max_error < p1[-1].max_error
