"""The mesher's local frame: a model meshes the same at any scale and offset a float holds,
and steep fronts (flat plateaus around a narrow transition) mesh with the default method."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

import hetmesh
from conftest import check_invariants
from hetmesh.io.model import parse_model
from hetmesh.tri.frame import local_field, local_frame

SQUARE = """
[parameters]
L = {L}
[domain.outer]
start = [{x0}, 0]
path = [{{ to = [{x1}, 0] }}, {{ to = [{x1}, {L}] }}, {{ to = [{x0}, {L}] }}, {{ to = [{x0}, 0] }}]
[material]
constituents = ["ceramic", "metal"]
[material.composition]
metal = "{formula}"
"""


def square(L, x0=0.0, formula="(1 - y/L)**2"):
    text = SQUARE.format(L=repr(L), x0=repr(x0), x1=repr(x0 + L), formula=formula)
    return parse_model(tomllib.loads(text), "square.toml")


def test_frame_scale_is_a_power_of_two_near_the_diameter():
    for d in (1e-300, 3e-150, 0.7, 1.0, 48.0, 1e150, 1e300):
        f = local_frame((0.0, 0.0, d, 0.0))
        m, _ = np.frexp(f.scale)
        assert m == 0.5  # a power of two: exact scaling
        assert 0.7 < d / f.scale < 1.42


def test_local_field_chain_rule():
    m = square(2.0)
    fr = local_frame(m.domain.bounds)
    fl = local_field(m.material, fr)
    p = np.array([[0.1, -0.2], [0.0, 0.3]])
    np.testing.assert_array_equal(fl.composition(p), m.material.composition(fr.to_user(p)))
    np.testing.assert_allclose(fl.gradient(p), m.material.gradient(fr.to_user(p)) * fr.scale)


@pytest.mark.parametrize("k", [-480, -200, 200, 480])
def test_same_mesh_at_any_power_of_two_scale(k):
    """Scaling the model by 2**k scales the mesh by 2**k, bit for bit."""
    ref = hetmesh.generate(square(1.0), 0.1)
    s = 2.0 ** k
    r = hetmesh.generate(square(s), 0.1)
    np.testing.assert_array_equal(r.mesh.triangles, ref.mesh.triangles)
    np.testing.assert_array_equal(r.mesh.points, ref.mesh.points * s)


@pytest.mark.parametrize("L", [1e-150, 1e150, 1e-8])
def test_extreme_units_mesh(L):
    ref = hetmesh.generate(square(1.0), 0.1)
    m = square(L)
    r = hetmesh.generate(m, 0.1)
    check_invariants(r, m, 0.1)
    # not a power of two: the local coordinates round differently, the smoothing carries
    # that into the node positions, and the vertex removal, decided by the geometry, may
    # take a node or two more or less (powers of two: bit for bit, above)
    assert abs(r.stats.n_elements - ref.stats.n_elements) <= 0.015 * ref.stats.n_elements
    assert r.options["max_size"] == pytest.approx(m.domain.diameter / 8)


def test_far_offset():
    m = square(1.0, x0=1e12)
    r = hetmesh.generate(m, 0.1)
    check_invariants(r, m, 0.1)


@pytest.mark.parametrize("eps,threshold", [
    (0.01, 0.1), pytest.param(0.01, 0.05, marks=pytest.mark.slow), (0.005, 0.1)])
def test_steep_tanh_front(eps, threshold):
    """Plateaus where |grad f| ~ 1e-20: a Newton step onto a level curve from there used to
    throw row nodes 1e13 widths away, and every triangle was then called degenerate."""
    m = square(1.0, formula=f"0.5*(1 + tanh((x - 0.5)/{eps}))")
    r = hetmesh.generate(m, threshold)
    check_invariants(r, m, threshold)
    assert np.abs(r.mesh.points).max() <= 1.0 + 1e-12


@pytest.mark.parametrize("L", [1e-300, 1e300])
def test_sizes_beyond_the_range_are_a_clear_error(L):
    with pytest.raises(hetmesh.errors.GeometryError, match="outside the range hetmesh supports"):
        square(L)
