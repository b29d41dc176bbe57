"""Material fields: AnalyticField, CallableField, shifting and check_field."""

from __future__ import annotations

import numpy as np
import pytest

from hetmesh.errors import FormulaError, MaterialError
from hetmesh.geometry import Arc, Loop, Segment, make_domain
from hetmesh.material import (AnalyticField, CallableField, MaterialField, check_field,
                              sample_domain)


def _rect(x0, y0, x1, y1):
    pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    return make_domain(Loop(tuple(Segment(a, b) for a, b in zip(pts, pts[1:] + pts[:1])),
                            "outer"))


@pytest.fixture
def rng():
    return np.random.default_rng(0)


def _pts(rng, n=200, lo=(0.0, 0.0), hi=(42.0, 30.0)):
    return rng.uniform(lo, hi, size=(n, 2))


# ----------------------------------------------------------------------------- AnalyticField

def test_power_plate_closed_form(rng):
    """Eqs. (10)-(11): f = ((b - y)/b)^2, grad f = (0, -2 (b - y)/b^2)."""
    b = 30.0
    f = AnalyticField({"metal": "((b - y)/b)**2"}, ["ceramic", "metal"], {"b": b})
    p = _pts(rng)
    y = p[:, 1]
    c = f.composition(p)
    g = f.gradient(p)
    assert c.shape == (200, 2) and g.shape == (200, 2, 2)
    np.testing.assert_allclose(c[:, 1], ((b - y) / b) ** 2, rtol=1e-14)
    np.testing.assert_allclose(c[:, 0], 1 - ((b - y) / b) ** 2, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(g[:, 1, 1], -2 * (b - y) / b**2, rtol=1e-14)
    np.testing.assert_allclose(np.hypot(*g[:, 1].T), 2 * (b - y) / b**2, rtol=1e-14)
    np.testing.assert_array_equal(g[:, :, 0], 0.0)
    np.testing.assert_allclose(g[:, 0], -g[:, 1], rtol=1e-15)
    assert f.derived == "ceramic"
    assert isinstance(f, MaterialField)


def test_three_constituents_missing_one(rng):
    f = AnalyticField({"a": "x/10", "c": "y/20"}, ["a", "b", "c"])
    p = _pts(rng, lo=(0, 0), hi=(5, 5))
    c, g = f.composition(p), f.gradient(p)
    np.testing.assert_allclose(c.sum(axis=1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(c[:, 1], 1 - p[:, 0] / 10 - p[:, 1] / 20)
    np.testing.assert_allclose(g[:, 1], np.tile([-0.1, -0.05], (len(p), 1)))
    np.testing.assert_allclose(g.sum(axis=1), 0.0, atol=1e-15)


def test_constant_formula_broadcasts():
    f = AnalyticField({"a": "0.25", "b": "0.75"}, ["a", "b"])
    c = f.composition(np.zeros((5, 2)))
    assert c.shape == (5, 2) and np.all(c == [0.25, 0.75])
    assert np.all(f.gradient(np.zeros((5, 2))) == 0.0)
    assert f.derived is None


def test_region_keyword_is_accepted_and_ignored(rng):
    f = AnalyticField({"metal": "x*y"}, ["ceramic", "metal"])
    p = _pts(rng, hi=(1, 1))
    r = np.zeros(len(p), dtype=int)
    np.testing.assert_array_equal(f.composition(p, region=r), f.composition(p))
    np.testing.assert_array_equal(f.gradient(p, region=r), f.gradient(p))


@pytest.mark.parametrize("formulas, constituents, exc, text", [
    ({"metal": "z"}, ["ceramic", "metal"], FormulaError, "material.composition.metal"),
    ({"steel": "x"}, ["ceramic", "metal"], MaterialError, "unknown constituent 'steel'"),
    ({"a": "x"}, ["a", "b", "c"], MaterialError, "no formula for b, c"),
    ({"a": "x"}, ["a"], MaterialError, "at least 2"),
    ({"a": "x"}, ["a", "a"], MaterialError, "listed twice"),
    ({"a": "x"}, ["a", ""], MaterialError, "non-empty"),
])
def test_analytic_errors(formulas, constituents, exc, text):
    with pytest.raises(exc) as info:
        AnalyticField(formulas, constituents, where="m.toml")
    msg = str(info.value)
    assert msg.startswith("m.toml: ") and text in msg and "\n" not in msg


# ----------------------------------------------------------------------------- CallableField

def test_callable_two_constituents_gradient_vs_exact(rng):
    f = CallableField(lambda x, y: np.sin(x) * np.exp(-y), ["ceramic", "metal"])
    p = _pts(rng, hi=(3, 3))
    x, y = p.T
    c, g = f.composition(p), f.gradient(p)
    np.testing.assert_allclose(c[:, 1], np.sin(x) * np.exp(-y))
    np.testing.assert_allclose(c.sum(axis=1), 1.0)
    np.testing.assert_allclose(g[:, 1, 0], np.cos(x) * np.exp(-y), atol=1e-8)
    np.testing.assert_allclose(g[:, 1, 1], -np.sin(x) * np.exp(-y), atol=1e-8)
    np.testing.assert_allclose(g[:, 0], -g[:, 1], atol=1e-8)


def test_callable_m_columns_and_step(rng):
    def func(x, y):
        a = 0.5 * x * y
        return np.stack([a, 0.5 * np.ones_like(x), 0.5 - a], axis=1)

    p = _pts(rng, hi=(1, 1))
    for step in (None, 1e-4):
        f = CallableField(func, ["a", "b", "c"], step=step)
        g = f.gradient(p)
        np.testing.assert_allclose(g[:, 0], 0.5 * p[:, ::-1], atol=1e-8)
        np.testing.assert_allclose(g[:, 1], 0.0, atol=1e-8)


def test_callable_bad_shape_and_args():
    f = CallableField(lambda x, y: np.zeros((len(x), 2)), ["a", "b", "c"])
    with pytest.raises(MaterialError, match=r"shape \(3, 2\).*expected \(3, 3\)"):
        f.composition(np.zeros((3, 2)))
    with pytest.raises(MaterialError, match="callable"):
        CallableField(1.0, ["a", "b"])
    with pytest.raises(MaterialError, match="step"):
        CallableField(lambda x, y: x, ["a", "b"], step=0.0)
    with pytest.raises(MaterialError, match=r"shape \(3,\)"):
        f.composition(np.zeros(3))


# ----------------------------------------------------------------------------- shifting

def test_shifted_equals_offset_evaluation(rng):
    p = _pts(rng, hi=(1, 1))
    o = np.array([3.0, -2.0])
    for f in (AnalyticField({"metal": "x**2*y/9 + 0.1"}, ["ceramic", "metal"]),
              CallableField(lambda x, y: x**2 * y / 9 + 0.1, ["ceramic", "metal"])):
        s = f.shifted(o)
        np.testing.assert_allclose(s.composition(p), f.composition(p + o), rtol=1e-14)
        np.testing.assert_allclose(s.gradient(p), f.gradient(p + o), rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(s.shifted(-o).composition(p), f.composition(p), rtol=1e-14)
        assert np.all(f.offset == 0) and np.all(s.offset == o)


def test_shifted_far_from_origin_keeps_gradient_accuracy(rng):
    """Local coordinates + 1e9 offset: the central difference divides by the real step."""
    big = 1e9
    p = _pts(rng, hi=(1, 1))
    f = CallableField(lambda x, y: (1 - (y - big)) ** 2, ["ceramic", "metal"])
    g = f.shifted([big, big]).gradient(p)
    np.testing.assert_allclose(g[:, 1, 1], -2 * (1 - p[:, 1]), atol=1e-6)
    np.testing.assert_allclose(g[:, 1, 0], 0.0, atol=1e-6)
    a = AnalyticField({"metal": "(1 - (y - c))**2"}, ["ceramic", "metal"], {"c": big})
    ga = a.shifted([big, big]).gradient(p)
    y = (p[:, 1] + big) - big        # the local coordinate as represented at 1e9
    np.testing.assert_allclose(ga[:, 1, 1], -2 * (1 - y), rtol=1e-12)


# ----------------------------------------------------------------------------- check_field

def test_check_field_accepts_valid_field():
    d = _rect(0, 0, 1, 1)
    check_field(AnalyticField({"metal": "(1 - y)**2"}, ["ceramic", "metal"]), d, "m.toml")
    check_field(CallableField(lambda x, y: x * y, ["ceramic", "metal"]), d, "m.toml")


def test_sample_domain_covers_interior_and_curves():
    d = make_domain(Loop((Arc.circle((0, 0), 1.0),), "outer"))
    s = sample_domain(d, n=50)
    r = np.hypot(*s.T)
    assert r.max() <= 1 + 1e-12
    assert np.sum(np.isclose(r, 1.0)) >= 50       # boundary samples
    assert np.sum(r < 0.99) > 0.7 * 50 * 50 * np.pi / 4


def test_check_field_out_of_range_names_constituent_and_coordinate():
    d = _rect(0, -6, 1, 0)
    f = AnalyticField({"metal": "((b - y)/b)**2"}, ["ceramic", "metal"], {"b": 30.0})
    with pytest.raises(MaterialError) as info:
        check_field(f, d, "m.toml")
    assert str(info.value) == "m.toml: material.composition.metal: value 1.44 at (0, -6) " \
                              "is outside [0, 1]"


def test_check_field_negative_and_nonfinite():
    d = _rect(0, 0, 1, 1)
    with pytest.raises(MaterialError, match=r"metal: value -0\.5 at \(1, 1\) is outside"):
        check_field(AnalyticField({"metal": "0.5 - x*y"}, ["ceramic", "metal"]), d, "m.toml")
    with pytest.raises(MaterialError, match=r"metal: value (nan|inf) at \(.*\) is not finite"):
        check_field(AnalyticField({"metal": "log(x)**2"}, ["ceramic", "metal"]), d, "m.toml")


def test_check_field_sum_not_one():
    d = _rect(0, 0, 1, 1)
    f = AnalyticField({"a": "0.5", "b": "0.5 + 0.2*x"}, ["a", "b"])
    with pytest.raises(MaterialError) as info:
        check_field(f, d, "m.toml")
    msg = str(info.value)
    assert msg.startswith("m.toml: material.composition: fractions sum to 1.2, not 1, at (1, ")
    assert "(a 0.5, b 0.7)" in msg


def test_check_field_tolerance():
    d = _rect(0, 0, 1, 1)
    check_field(AnalyticField({"a": "1 + 1e-10*x", "b": "-1e-10*x"}, ["a", "b"]), d)
    with pytest.raises(MaterialError):
        check_field(AnalyticField({"a": "1 + 1e-8*x", "b": "-1e-8*x"}, ["a", "b"]), d)


def test_check_field_nan_gradient():
    d = _rect(0, 0, 1, 1)

    class Bad:
        constituents = ("a", "b")

        def composition(self, p):
            return np.full((len(p), 2), 0.5)

        def gradient(self, p):
            g = np.zeros((len(p), 2, 2))
            g[-1, 1, 0] = np.nan
            return g

    with pytest.raises(MaterialError, match="material.composition.b: gradient is undefined"):
        check_field(Bad(), d, "m.toml")


def test_check_field_wrong_shape():
    d = _rect(0, 0, 1, 1)

    class Bad:
        constituents = ("a", "b", "c")

        def composition(self, p):
            return np.full((len(p), 2), 0.5)

        def gradient(self, p):
            return np.zeros((len(p), 2, 2))

    with pytest.raises(MaterialError, match="expected"):
        check_field(Bad(), d, "m.toml")


def test_check_field_far_from_origin():
    big = 1e9
    d = _rect(big, big, big + 1, big + 1)
    f = AnalyticField({"metal": "(1 - (y - c))**2"}, ["ceramic", "metal"], {"c": big})
    check_field(f, d, "m.toml")
