"""Thermo-mechanical FEA (paper Sec. 4.4): closed forms, patch test, mixing rules,
the [fea] table's errors, the CLI, the fgm_plate case study on a coarse mesh and the case-4
probe study (hetmesh.fea.study; the quick and full runs are slow tests)."""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest

import hetmesh
import hetmesh.fea as fea
import hetmesh.io.read
from hetmesh.cli import main
from hetmesh.errors import FEAError, ModelFileError
from hetmesh.fea.analysis import elastic, p1_basis, p1_gradient, pieces, stresses
from hetmesh.fea.config import rigid_rank
from hetmesh.fea.mixing import lame, mix_linear, mix_mori_tanaka, thermal_modulus
from hetmesh.io.model import parse_model
from hetmesh.mesh import Mesh

CERAMIC = dict(conductivity=35.0, youngs_modulus=393e9, poisson_ratio=0.25, expansion=7.4e-6)
METAL = dict(conductivity=90.7, youngs_modulus=199.5e9, poisson_ratio=0.3, expansion=15.4e-6)
TABLE = {k: np.array([CERAMIC[k], METAL[k]]) for k in CERAMIC}


# ----------------------------------------------------------------------------- helpers

def strip_toml(*, metal="x / 10", fea_extra="", temperature=None, displacement=None,
               probes="", units="mm", plane="strain", mixing="", length=10.0, height=1.0):
    """A rectangle [0, length] x [0, height] with named sides bottom, right, top, left."""
    temperature = temperature if temperature is not None else """
[[fea.temperature]]
curves = ["left"]
value = 300
[[fea.temperature]]
curves = ["right"]
value = 800
"""
    displacement = displacement if displacement is not None else f"""
[[fea.displacement]]
point = [0, 0]
ux = 0
uy = 0
[[fea.displacement]]
point = [{length:g}, 0]
uy = 0
"""
    props = "\n".join(f"[fea.properties.{n}]\n" + "\n".join(f"{k} = {v!r}" for k, v in p.items())
                      for n, p in (("ceramic", CERAMIC), ("metal", METAL)))
    return f"""
[model]
name = "strip"
units = "{units}"

[domain.outer]
start = [0, 0]
path = [
  {{ to = [{length}, 0], name = "bottom" }},
  {{ to = [{length}, {height}], name = "right" }},
  {{ to = [0, {height}], name = "top" }},
  {{ to = [0, 0], name = "left" }},
]

[material]
constituents = ["ceramic", "metal"]
composition = {{ metal = "{metal}" }}

[fea]
plane = "{plane}"
reference_temperature = 300
{mixing}
{fea_extra}
{props}
{temperature}
{displacement}
{probes}
"""


def load(text: str, where: str = "strip.toml"):
    return parse_model(tomllib.loads(text), where)


def grid_mesh(length: float, height: float, nx: int, ny: int, jitter: float = 0.0,
              seed: int = 0) -> Mesh:
    """A structured triangulation of the rectangle (alternating diagonals); interior nodes
    moved randomly by ``jitter`` x the spacing."""
    x, y = np.meshgrid(np.linspace(0, length, nx + 1), np.linspace(0, height, ny + 1))
    P = np.column_stack([x.ravel(), y.ravel()])
    if jitter:
        inner = (P[:, 0] > 0) & (P[:, 0] < length) & (P[:, 1] > 0) & (P[:, 1] < height)
        rng = np.random.default_rng(seed)
        P[inner] += jitter * rng.uniform(-1, 1, (inner.sum(), 2)) * [length / nx, height / ny]
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    a = (j * (nx + 1) + i).ravel()
    b, c, d = a + 1, a + nx + 2, a + nx + 1
    flip = ((i + j) % 2 == 0).ravel()
    t1 = np.where(flip[:, None], np.column_stack([a, b, c]), np.column_stack([a, b, d]))
    t2 = np.where(flip[:, None], np.column_stack([a, c, d]), np.column_stack([b, c, d]))
    return Mesh(P, np.vstack([t1, t2]))


# ------------------------------------------------------------------------------ conduction

def graded_exact(x, length, k0, k1, T0, T1):
    """1-D conduction with k linear in x: k T' = const, so
    T = T0 + (T1 - T0) ln(k/k0) / ln(k1/k0)."""
    k = k0 + (k1 - k0) * x / length
    return T0 + (T1 - T0) * np.log(k / k0) / np.log(k1 / k0)


@pytest.mark.parametrize("order,low,high", [(1, 1.8, 2.5), (2, 2.8, 4.3)])
def test_graded_conduction_matches_closed_form_at_the_expected_rate(order, low, high):
    """Largest nodal error: P1 falls as h^2, P2 at least as h^3 (its vertex values
    superconverge towards h^4 in this 1-D-like problem); k linear in x, Dirichlet ends."""
    model = load(strip_toml(fea_extra=f"order = {order}"))
    errors, sizes = [], []
    for n in (5, 10, 20, 40):
        mesh = grid_mesh(10.0, 1.0, n, max(1, n // 5))
        r = fea.solve(mesh, model)
        exact = graded_exact(mesh.points[:, 0], 10.0, 35.0, 90.7, 300.0, 800.0)
        errors.append(np.abs(r.temperature - exact).max())
        sizes.append(10.0 / n)
    slope = np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert low < slope < high, (slope, errors)
    assert errors[-1] < (0.05 if order == 1 else 1e-3)  # K, on a 500 K range


@pytest.mark.parametrize("order", [1, 2])
def test_homogeneous_conduction_is_exact(order):
    model = load(strip_toml(metal="0.4", fea_extra=f"order = {order}"))
    mesh = grid_mesh(10.0, 1.0, 7, 3, jitter=0.3)
    r = fea.solve(mesh, model)
    np.testing.assert_allclose(r.temperature, 300 + 50 * mesh.points[:, 0], rtol=1e-12)


# ------------------------------------------------------------------------------ elasticity

UNIFORM_T = """
[[fea.temperature]]
curves = ["outer"]
value = 400
"""


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("plane", ["strain", "stress"])
def test_free_plate_under_uniform_heating_has_no_in_plane_stress(plane, order):
    model = load(strip_toml(metal="0.3", temperature=UNIFORM_T, plane=plane,
                            fea_extra=f"order = {order}"))
    mesh = grid_mesh(10.0, 1.0, 12, 3, jitter=0.3)
    r = fea.solve(mesh, model)
    p = mix_linear(np.array([[0.7, 0.3]]), TABLE)
    E, nu, a = (p[k][0] for k in ("youngs_modulus", "poisson_ratio", "expansion"))
    dT = 100.0
    scale = E * a * dT
    assert np.abs(r.stress[:, :3]).max() < 1e-8 * scale
    assert np.abs(r.cell_stress[:, :3]).max() < 1e-8 * scale
    zz = -scale if plane == "strain" else 0.0  # the out-of-plane constraint of plane strain
    np.testing.assert_allclose(r.stress[:, 3], zz, atol=1e-8 * scale)
    # free expansion about the fixed corner, in metres (units mm)
    strain = (1 + nu) * a * dT if plane == "strain" else a * dT
    np.testing.assert_allclose(r.displacement, strain * mesh.points * 1e-3,
                               atol=1e-10 * strain * 1e-2)


@pytest.mark.parametrize("order", [1, 2])
def test_clamped_plane_strain_thermal_stress(order):
    clamp = """
[[fea.displacement]]
curves = ["outer"]
ux = 0
uy = 0
"""
    model = load(strip_toml(metal="0.3", temperature=UNIFORM_T, displacement=clamp,
                            fea_extra=f"order = {order}"))
    mesh = grid_mesh(10.0, 1.0, 10, 3, jitter=0.3)
    r = fea.solve(mesh, model)
    p = mix_linear(np.array([[0.7, 0.3]]), TABLE)
    E, nu, a = (p[k][0] for k in ("youngs_modulus", "poisson_ratio", "expansion"))
    s = -E * a * 100.0 / (1 - 2 * nu)
    np.testing.assert_allclose(r.stress[:, 0], s, rtol=1e-10)
    np.testing.assert_allclose(r.stress[:, 1], s, rtol=1e-10)
    np.testing.assert_allclose(r.stress[:, 2], 0.0, atol=1e-10 * abs(s))
    np.testing.assert_allclose(r.displacement, 0.0, atol=1e-16)  # m
    np.testing.assert_allclose(r.von_mises, 0.0, atol=1e-6 * abs(s))  # hydrostatic


def test_elasticity_patch_test():
    """Linear displacements on the boundary of a distorted patch: the interior nodes follow
    the same linear field and every element has its constant stress."""
    from skfem import Basis, ElementTriP1, ElementVector, MeshTri

    mesh = grid_mesh(2.0, 1.5, 4, 3, jitter=0.35, seed=3)
    P, t = mesh.points, mesh.triangles
    G = np.array([[1e-3, 4e-4], [-2e-4, 5e-4]])  # du_i/dx_j
    exact = P @ G.T + [1e-4, -3e-4]
    vb = Basis(MeshTri(P.T.copy(), t.T.copy()), ElementVector(ElementTriP1()), intorder=2)
    M, Q = len(t), 3
    E, nu = 200e9, 0.3
    lam, mu = (np.full((M, Q), v) for v in lame(E, nu, "strain"))
    zero = np.zeros((M, Q))
    bnd = np.unique(mesh.boundary_edges)
    fixed = np.zeros(vb.N, bool)
    fixed[vb.nodal_dofs[:, bnd].ravel()] = True
    u0 = np.zeros(vb.N)
    u0[vb.nodal_dofs[0]], u0[vb.nodal_dofs[1]] = exact[:, 0], exact[:, 1]
    u = elastic(vb, lam, mu, zero, zero, fixed, u0)
    U = np.column_stack([u[vb.nodal_dofs[0]], u[vb.nodal_dofs[1]]])
    assert len(bnd) < len(P)
    np.testing.assert_allclose(U, exact, rtol=0, atol=1e-14)
    grads, _ = p1_basis(P, t)
    s = stresses(p1_gradient(grads, U, t), lam, mu, zero, zero, "strain")
    eps = 0.5 * (G + G.T)
    tr = np.trace(eps)
    want = [lam[0, 0] * tr + 2 * mu[0, 0] * eps[0, 0], lam[0, 0] * tr + 2 * mu[0, 0] * eps[1, 1],
            2 * mu[0, 0] * eps[0, 1], lam[0, 0] * tr]
    np.testing.assert_allclose(s.reshape(-1, 4), np.broadcast_to(want, (M * Q, 4)), rtol=1e-9)


def test_recovered_stress_is_exact_for_linear_fields_and_splits_pieces():
    """The L2 projection reproduces a linear field; nodes shared by two pieces get a copy
    each."""
    from hetmesh.fea.analysis import recover

    mesh = grid_mesh(1.0, 1.0, 4, 4, jitter=0.3)
    P, t = mesh.points, mesh.triangles
    groups = (P[t].mean(axis=1)[:, 0] > 0.5).astype(int)  # the grid line x = 0.5 splits
    dofs, node = pieces(t, len(P), groups)
    assert len(node) == len(P) + 5  # the 5 nodes on x = 0.5 appear twice
    lam = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
    xq = np.einsum("qi,mid->mqd", lam, P[t])
    f = np.where(groups[:, None, None] == 1, 3 * xq[..., :1] - xq[..., 1:] + 2, xq[..., 1:])
    _, areas = p1_basis(P, t)
    out = recover(dofs, len(node), areas, lam.T, np.full(3, 1 / 3), f)
    vals = out[dofs][..., 0]  # (M, 3)
    want = np.where(groups[:, None] == 1, 3 * P[t][..., 0] - P[t][..., 1] + 2, P[t][..., 1])
    np.testing.assert_allclose(vals, want, atol=1e-9)


# --------------------------------------------------------------------------------- mixing

@pytest.mark.parametrize("rule", [mix_linear, mix_mori_tanaka])
@pytest.mark.parametrize("matrix", [0, 1])
def test_mixing_rules_return_the_constituents_at_pure_compositions(rule, matrix):
    p = rule(np.eye(2), TABLE, matrix)
    for k in TABLE:
        np.testing.assert_allclose(p[k], TABLE[k], rtol=1e-12)


def test_mori_tanaka_two_phase_closed_forms():
    c = np.linspace(0, 1, 11)
    comp = np.column_stack([c, 1 - c])  # ceramic inclusions (c) in the metal matrix
    p = mix_mori_tanaka(comp, TABLE, matrix=1)
    E, nu = TABLE["youngs_modulus"], TABLE["poisson_ratio"]
    K, G = E / (3 * (1 - 2 * nu)), E / (2 * (1 + nu))
    Ke = K[1] + c * (K[0] - K[1]) / (1 + (1 - c) * (K[0] - K[1]) / (K[1] + 4 / 3 * G[1]))
    f = G[1] * (9 * K[1] + 8 * G[1]) / (6 * (K[1] + 2 * G[1]))
    Ge = G[1] + c * (G[0] - G[1]) / (1 + (1 - c) * (G[0] - G[1]) / (G[1] + f))
    np.testing.assert_allclose(p["youngs_modulus"], 9 * Ke * Ge / (3 * Ke + Ge), rtol=1e-12)
    k = TABLE["conductivity"]
    ke = k[1] + c * (k[0] - k[1]) / (1 + (1 - c) * (k[0] - k[1]) / (3 * k[1]))
    np.testing.assert_allclose(p["conductivity"], ke, rtol=1e-12)
    a = TABLE["expansion"]  # Levin: linear in 1/K between the phases
    levin = a[1] + (a[0] - a[1]) * (1 / Ke - 1 / K[1]) / (1 / K[0] - 1 / K[1])
    np.testing.assert_allclose(p["expansion"], levin, rtol=1e-10)
    # between the linear (Voigt) and the harmonic (Reuss) bounds
    lin = mix_linear(comp, TABLE)["youngs_modulus"]
    reuss = 1 / (comp @ (1 / E))
    assert np.all(p["youngs_modulus"] <= lin * (1 + 1e-12))
    assert np.all(p["youngs_modulus"] >= reuss * (1 - 1e-12))


def test_thermal_modulus_and_lame():
    lam, mu = lame(200e9, 0.3, "strain")
    assert thermal_modulus(200e9, 0.3, 1e-5, "strain") == pytest.approx((3 * lam + 2 * mu) * 1e-5)
    lam, mu = lame(200e9, 0.3, "stress")
    assert thermal_modulus(200e9, 0.3, 1e-5, "stress") == pytest.approx((2 * lam + 2 * mu) * 1e-5)


def test_mori_tanaka_through_the_model_file():
    model = load(strip_toml(mixing='mixing = "mori-tanaka"\nmatrix = "metal"'))
    assert model.fea.mixing == "mori-tanaka" and model.fea.matrix == "metal"
    r = fea.solve(grid_mesh(10.0, 1.0, 10, 2), model)
    assert np.isfinite(r.von_mises).all()
    with pytest.raises(ModelFileError, match=r"strip.toml: missing key 'fea.matrix'"):
        load(strip_toml(mixing='mixing = "mori-tanaka"'))


# -------------------------------------------------------------------------------- units

def test_units_scale_displacements_not_stresses():
    mesh = grid_mesh(10.0, 1.0, 10, 2)
    mm = fea.solve(mesh, load(strip_toml(units="mm")))
    m = fea.solve(mesh, load(strip_toml(units="m")))
    np.testing.assert_allclose(m.stress, mm.stress, rtol=1e-8, atol=1e-6 * np.abs(m.stress).max())
    np.testing.assert_allclose(m.displacement, 1000 * mm.displacement, rtol=1e-8,
                               atol=1e-8 * np.abs(m.displacement).max())


def test_rigid_rank():
    P = np.array([[0.0, 0], [1, 0], [0, 1]])
    assert rigid_rank(P, np.array([1, 0, 0], bool), np.array([1, 1, 0], bool)) == 3
    assert rigid_rank(P, np.array([1, 0, 0], bool), np.array([1, 0, 0], bool)) == 2
    assert rigid_rank(P, np.array([0, 0, 0], bool), np.array([1, 1, 0], bool)) == 2
    assert rigid_rank(P, np.array([1, 0, 1], bool), np.array([0, 0, 0], bool)) == 2


# ----------------------------------------------------------------------------- bad input

BAD = {
    "missing properties": (
        strip_toml().replace("[fea.properties.metal]", "[fea.properties.metall]"),
        "strip.toml: unknown key 'fea.properties.metall': not a constituent"),
    "unknown curve": (
        strip_toml().replace('curves = ["right"]', 'curves = ["rigth"]'),
        "strip.toml: fea.temperature[1].curves: unknown curve 'rigth'"),
    "unknown point": (
        strip_toml().replace("point = [0, 0]", 'point = "A"'),
        "strip.toml: fea.displacement[0].point: unknown point 'A'"),
    "too few constraints": (
        strip_toml().replace("point = [10, 0]\nuy = 0", "point = [10, 0]\nux = 0"),
        "strip.toml: fea.displacement: too few constraints"),
    "probe outside": (
        strip_toml(probes="[fea.probes]\nfar = [20, 0.5]"),
        "strip.toml: fea.probes.far: point (20, 0.5) is outside the domain"),
    "no temperature": (
        strip_toml(temperature="", fea_extra="temperature = []"),
        "strip.toml: fea.temperature: at least one fixed temperature is needed"),
}


def test_missing_properties_message():
    text = strip_toml().replace("[fea.properties.metal]", "[fea.properties.metall]")
    with pytest.raises(ModelFileError) as e:
        load(text)
    assert str(e.value) == ("strip.toml: unknown key 'fea.properties.metall': not a "
                            "constituent (expected one of: ceramic, metal)")
    text = strip_toml()
    start = text.index("[fea.properties.metal]")
    end = text.index("[[fea.temperature]]")
    with pytest.raises(ModelFileError) as e:
        load(text[:start] + text[end:])
    assert str(e.value).startswith("strip.toml: missing key 'fea.properties.metal'")


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_fea_tables_raise_one_line(case):
    text, prefix = BAD[case]
    with pytest.raises(ModelFileError) as e:
        load(text)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(prefix), msg


def test_unknown_unit_and_bad_values():
    with pytest.raises(ModelFileError, match=r"model.units: unknown length unit 'furlong'"):
        load(strip_toml(units="furlong"))
    with pytest.raises(ModelFileError, match=r"fea.properties.metal.poisson_ratio: expected "
                                             r"-1 < nu < 0.5, got 0.5"):
        load(strip_toml().replace("poisson_ratio = 0.3", "poisson_ratio = 0.5"))
    with pytest.raises(ModelFileError, match=r"fea.plane: expected one of 'strain', 'stress'"):
        load(strip_toml(plane="strian"))
    with pytest.raises(ModelFileError, match=r"fea.order: expected 1 \(linear\) or 2"):
        load(strip_toml(fea_extra="order = 3"))


def test_element_order_defaults_to_linear():
    assert load(strip_toml()).fea.order == 1
    assert fea.FEAConfig(properties={}, temperature=(), displacement=()).order == 1
    assert load(strip_toml(fea_extra="order = 2")).fea.order == 2


def test_singular_systems_are_named_at_solve_time():
    from dataclasses import replace

    model = load(strip_toml())
    mesh = grid_mesh(10.0, 1.0, 10, 2)
    cfg = model.fea
    few = replace(cfg, displacement=cfg.displacement[:1])  # A only: rotation free
    with pytest.raises(FEAError, match=r"singular elastic system: too few displacement "
                                       r"constraints; they remove 2 of the 3"):
        fea.solve(mesh, model, config=few)
    with pytest.raises(FEAError, match="singular thermal system"):
        fea.solve(mesh, model, config=replace(cfg, temperature=()))
    # two separate parts: the second one is insulated all round and unsupported
    other = Mesh(mesh.points + [0, 5], mesh.triangles)
    both = Mesh(np.vstack([mesh.points, other.points]),
                np.vstack([mesh.triangles, other.triangles + mesh.n_points]))
    with pytest.raises(FEAError, match=r"the part of the mesh containing node \(0, 5\)"):
        fea.solve(both, model)


def test_mesh_that_does_not_fit_the_model():
    model = load(strip_toml())
    shifted = grid_mesh(10.0, 1.0, 10, 2)
    shifted = Mesh(shifted.points + [0.37, 0], shifted.triangles)
    with pytest.raises(FEAError, match=r"fea.temperature\[0\]: no mesh node lies on left"):
        fea.solve(shifted, model)


def test_model_without_fea_table():
    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    assert model.fea is None
    with pytest.raises(FEAError, match="has no \\[fea\\] table"):
        fea.solve(grid_mesh(1, 1, 2, 2), model)


# --------------------------------------------------------------------------- fgm_plate

@pytest.fixture(scope="module")
def plate():
    model = hetmesh.load_model(hetmesh.example_path("fgm_plate"))
    result = hetmesh.generate(model, 0.2)
    return model, result


def test_fgm_plate_is_quadratic_with_named_supports(plate):
    """The case-4 study needs quadratic elements, so the example states order = 2; its
    supports are the named corner points A and H."""
    model, _ = plate
    assert model.fea.order == 2
    assert model.domain.points == {"A": (0.0, 0.0), "H": (60.0, 0.0)}
    a, h = model.fea.displacement
    assert (a.label, a.point, a.ux, a.uy) == ("A", (0.0, 0.0), 0.0, 0.0)
    assert (h.label, h.point, h.ux, h.uy) == ("H", (60.0, 0.0), None, 0.0)
    text = hetmesh.example_path("fgm_plate").read_text()
    assert 'point = "A"' in text and 'point = "H"' in text


def test_fgm_plate_end_to_end(plate):
    model, meshed = plate
    r = fea.solve(meshed.mesh, model)
    assert np.isfinite(r.stress).all() and np.isfinite(r.displacement).all()
    assert r.temperature.min() >= 273.15 - 1e-9 and r.temperature.max() <= 1173.15 + 1e-9
    assert r.temperature.min() == pytest.approx(273.15)
    assert r.temperature.max() == pytest.approx(1173.15)
    assert set(r.probes) == {f"P{i}" for i in range(1, 7)} | {f"Q{i}" for i in range(1, 7)}
    for name, p in r.probes.items():
        assert 273.15 <= p["temperature"] <= 1173.15 + 1e-9
        assert 0.3e9 < p["von_mises"] < 6e9, (name, p)
    for name in ("P1", "P3"):  # on the hot arc
        assert r.probes[name]["temperature"] == pytest.approx(1173.15, abs=1e-6)
    for name in ("P4", "P6"):
        assert r.probes[name]["temperature"] == pytest.approx(873.15, abs=1e-6)
    # at a traction-free corner von Mises tends to |sigma_zz| = E alpha dT
    # (docs/cases.md, section 5)
    assert r.probes["P1"]["von_mises"] == pytest.approx(393e9 * 7.4e-6 * 900, rel=0.1)
    # the hot source stresses more than the cooler one (paper Table 7: P1..P3 > P4..P6)
    assert r.probes["P3"]["von_mises"] > r.probes["P6"]["von_mises"]
    # A is held, H only vertically
    a = np.flatnonzero(np.all(meshed.mesh.points == [0, 0], axis=1))[0]
    h = np.flatnonzero(np.all(meshed.mesh.points == [60, 0], axis=1))[0]
    assert np.all(r.displacement[a] == 0) and r.displacement[h, 1] == 0
    assert r.displacement[h, 0] != 0
    rep = json.loads(json.dumps(r.report()))
    assert {"von_mises", "stress_xx", "stress_yy", "stress_xy", "stress_zz",
            "temperature"} <= set(rep["probes"]["P2"])


def test_fgm_plate_properties_at_quadrature_points_in_own_subregion(plate):
    """Elements on both sides of a discontinuity use their own subregion's composition."""
    from hetmesh.fea.analysis import material_at

    model, meshed = plate
    mesh = meshed.mesh
    field = model.material
    P, t = mesh.points, mesh.triangles
    sub = np.asarray(mesh.cell_data["subregion"])
    x = np.broadcast_to(P[t].mean(axis=1)[:, None, :], (len(t), 1, 2))
    props = material_at(field, model.fea, np.ascontiguousarray(x), sub)
    comp = field.composition(x.reshape(-1, 2), region=sub)
    want = mix_linear(comp, model.fea.table())["youngs_modulus"]
    np.testing.assert_allclose(props["youngs_modulus"][:, 0], want, rtol=1e-12)


def test_fgm_plate_from_a_mesh_file_gives_the_same_answer(plate, tmp_path):
    model, meshed = plate
    path = meshed.mesh.write(tmp_path / "plate.vtu")
    a = fea.solve(meshed.mesh, model)
    b = fea.solve(hetmesh.io.read.read_mesh(path), model)
    for k in a.probes:
        assert b.probes[k]["von_mises"] == pytest.approx(a.probes[k]["von_mises"], rel=1e-9)


# ---------------------------------------------------------------------------------- CLI

def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_help(capsys):
    code, out, err = _run(["fea", "--help"], capsys)
    assert code == 0 and out.startswith("usage: hetmesh fea") and "--report" in out


def test_cli_writes_results(plate, tmp_path, capsys):
    model, meshed = plate
    mpath = tmp_path / "fgm_plate.toml"
    mpath.write_text(hetmesh.example_path("fgm_plate").read_text())
    mesh = meshed.mesh.write(tmp_path / "plate.msh")
    out = tmp_path / "out.vtu"
    rep = tmp_path / "fea.json"
    png = tmp_path / "vm.png"
    code, stdout, err = _run(["fea", mpath, "--mesh", mesh, "-o", out, "--report", rep,
                              "--plot", png], capsys)
    assert code == 0, err
    assert "P1" in stdout and "wrote" in stdout
    doc = json.loads(rep.read_text())
    assert doc["model"] == "fgm_plate" and doc["elements"] == meshed.mesh.n_elements
    assert set(doc["probes"]) >= {"P1", "Q6"}
    assert png.stat().st_size > 1000
    back = hetmesh.io.read.read_mesh(out)
    assert {"temperature", "von_mises", "stress_zz", "displacement"} <= set(back.point_data)
    assert "von_mises" in back.cell_data
    np.testing.assert_allclose(back.point_data["von_mises"],
                               fea.solve(meshed.mesh, model).von_mises, rtol=1e-9)


@pytest.mark.parametrize("case", sorted(BAD))
def test_cli_bad_input_exits_2_and_writes_nothing(case, tmp_path, capsys):
    text, prefix = BAD[case]
    mpath = tmp_path / "strip.toml"
    mpath.write_text(text)
    mesh = grid_mesh(10.0, 1.0, 10, 2).write(tmp_path / "strip.vtu")
    outs = [tmp_path / "o.vtu", tmp_path / "r.json", tmp_path / "p.png"]
    code, out, err = _run(["fea", mpath, "--mesh", mesh, "-o", outs[0], "--report", outs[1],
                           "--plot", outs[2]], capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hetmesh: error: ") and str(mpath) in lines[0]
    assert prefix.replace("strip.toml", str(mpath)) in lines[0]
    assert not any(p.exists() for p in outs)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["strip.toml", "strip.vtu"]


def test_cli_singular_and_missing_table_exit_2(tmp_path, capsys):
    mpath = tmp_path / "plate.toml"
    mpath.write_text(hetmesh.example_path("power_plate").read_text())
    mesh = grid_mesh(1.0, 1.0, 2, 2).write(tmp_path / "m.vtu")
    code, out, err = _run(["fea", mpath, "--mesh", mesh, "--report", tmp_path / "r.json"],
                          capsys)
    assert code == 2 and "no [fea] table" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "r.json").exists()
    # a mesh that does not fit the model: the error names the condition
    spath = tmp_path / "strip.toml"
    spath.write_text(strip_toml())
    code, out, err = _run(["fea", spath, "--mesh", mesh, "--report", tmp_path / "r.json"],
                          capsys)
    assert code == 2 and "no mesh node" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "r.json").exists()
    code, out, err = _run(["fea", spath, "--mesh", mesh, "--report", tmp_path / "r.txt.vtu",
                           "-o", tmp_path / "r.txt.vtu"], capsys)
    assert code == 2 and "same file" in err


# ------------------------------------------------------------------- case-4 probe study
def test_study_is_the_function_even_after_its_module_is_imported():
    import hetmesh.fea.probe_study as module
    from hetmesh.reproduce import fea_study_function

    assert fea.study is module.study and callable(fea.study)
    assert fea_study_function() is module.study
    assert fea.ProbeStudy is module.ProbeStudy


def test_probe_sets_and_elements_needed():
    from hetmesh.fea.probe_study import elements_needed, h_for_elements, probe_sets

    assert probe_sets(["P1", "P2", "Q1", "Q2"]) == {"P": ["P1", "P2"], "Q": ["Q1", "Q2"],
                                                    "all": ["P1", "P2", "Q1", "Q2"]}
    assert probe_sets(["tip", "root"]) == {"tip": ["tip"], "root": ["root"],
                                           "all": ["tip", "root"]}
    assert probe_sets(["P1"]) == {"P": ["P1"]}
    # crossing between 100 (1 %) and 1000 (0.1 %): log-log interpolation -> 10**2.5
    n, exact = elements_needed([1000, 100], [0.001, 0.01], 0.005)
    assert exact and n == pytest.approx(10 ** (2 + math.log10(2)), rel=1e-12)
    # a later mesh above the tolerance again moves the crossing past it
    n, exact = elements_needed([100, 200, 400, 800], [0.01, 0.004, 0.006, 0.002], 0.005)
    assert exact and 400 < n < 800
    assert elements_needed([100, 200], [0.001, 0.002], 0.005) == (100.0, False)  # upper bound
    assert elements_needed([100, 200], [0.02, 0.01], 0.005) == (None, False)     # not reached
    assert elements_needed([], [], 0.005) == (None, False)
    assert h_for_elements(math.sqrt(3) / 4, 1) == pytest.approx(1.0)


def test_study_small_plan_follows_the_contract(plate):
    """A small plan (seconds): the result docs/reproduce.md promises, consistent with itself."""
    model, _ = plate
    stages = []
    s = fea.study(model, quick=True, reference_elements=3000, uniform_elements=(300, 1000),
                  thresholds=(0.3,), progress=lambda st, f: stages.append((st, f)))
    assert s.quick and s.order == 2 and s.primary == "P" and "quick run" in s.note
    assert s.probe_sets["P"] == [f"P{i}" for i in range(1, 7)] and "all" in s.probe_sets
    ref = s.reference
    assert 2500 < ref["elements"] < 3600 and set(ref["von_mises"]) == set(model.fea.probes)
    assert ref["check"]["elements"] < ref["elements"] / 3
    assert all(0 <= d < 0.05 for d in ref["check"]["difference"].values())
    assert [m["family"] for m in s.meshes] == ["uniform", "uniform", "adaptive"]
    for m in s.meshes:
        assert "error" not in m and m["elements"] > 100
        rel = {k: abs(m["von_mises"][k] / ref["von_mises"][k] - 1) for k in ref["von_mises"]}
        assert m["max_error"] == pytest.approx(max(rel[f"P{i}"] for i in range(1, 7)))
        assert m["errors"]["all"] == pytest.approx(max(rel.values()))
        assert m["errors"]["P"] == m["max_error"] and m["max_error"] < 0.1
    uni = [m["elements"] for m in s.meshes if m["family"] == "uniform"]
    assert uni == sorted(uni)
    assert set(s.needed) >= {"uniform", "adaptive", "reduction", "uniform_exact"}
    assert s.needed == s.needed_by_set["P"] and set(s.needed_by_set) == {"P", "Q", "all"}
    assert s.reduction == s.needed["reduction"]
    fr = [f for _, f in stages]
    assert fr == sorted(fr) and fr[0] == 0 and fr[-1] == 1 and len(stages) == 6
    assert json.loads(json.dumps(s.to_dict()))["meshes"][0]["family"] == "uniform"


def test_study_needs_probes_and_an_fea_table():
    model = load(strip_toml())  # no probes
    with pytest.raises(FEAError, match="no probes"):
        fea.study(model)
    bare = hetmesh.load_model(hetmesh.example_path("unit_square"))
    with pytest.raises(FEAError, match=r"no \[fea\] table"):
        fea.study(bare)
    with pytest.raises(FEAError, match="order: expected 1 or 2"):
        fea.study(load(strip_toml(probes="[fea.probes]\na = [1, 0.5]")), order=3)


@pytest.mark.slow
def test_full_study_meets_the_target():
    """The full study (~40 s): a finer reference whose own error (against twice its edge) is
    well below 0.5 %, and the 40 % target at P1..P6."""
    model = hetmesh.load_model(hetmesh.example_path("fgm_plate"))
    s = fea.study(model)
    assert not s.quick and "full run" in s.note
    assert max(s.reference["check"]["difference"].values()) < 0.0025
    assert s.needed["uniform_exact"] and s.needed["adaptive_exact"]
    assert s.reduction >= 0.40
