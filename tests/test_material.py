"""Material fields: AnalyticField, CallableField, shifting and check_field."""

from __future__ import annotations

import numpy as np
import pytest

from hetmesh.errors import FormulaError, MaterialError
from hetmesh.material import AnalyticField, CallableField, MaterialField, check_field, sample_domain
from hetmesh.tri.geometry import Arc, Loop, Segment, make_domain


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


# ------------------------------------------------------------- kinks and infinite slopes

@pytest.mark.parametrize("formula, point", [
    ("exp(-sqrt((x - 4)**2 + (y - 4)**2)/2)", (4.0, 4.0)),   # the tip of a cone: 0/0
    ("sqrt((x - 0.5)**2)", (0.5, 0.3)),                       # a kink line: 0/0
    ("sqrt(x)", (0.0, 0.3)),                                  # an infinite slope: 1/0
    ("x**0.25*y", (0.0, 0.7)),
])
def test_gradient_where_the_derivative_fails_is_a_finite_difference(formula, point):
    f = AnalyticField({"metal": formula}, ["ceramic", "metal"], length=10.0)
    p = np.array([point, (point[0] + 0.25, point[1] + 0.25)])
    g = f.gradient(p)
    assert np.isfinite(g).all()
    np.testing.assert_array_equal(g[:, 0], -g[:, 1])
    exact = AnalyticField({"metal": formula}, ["ceramic", "metal"])
    np.testing.assert_array_equal(g[1], exact.gradient(p[1:])[0])  # exact elsewhere
    with np.errstate(all="ignore"):  # the raw derivative really fails at the point
        raw = f._grads[0][0](x=p[:1, 0], y=p[:1, 1])
    assert not np.isfinite(raw).all()


def test_one_sided_difference_at_an_edge_of_definition():
    f = AnalyticField({"metal": "sqrt(x)"}, ["ceramic", "metal"], length=1.0)
    g = f.gradient([[0.0, 0.5]])[0, 1]
    np.testing.assert_allclose(g, [np.sqrt(0.01) / 0.01, 0.0], rtol=1e-12)  # forward
    g = AnalyticField({"metal": "sqrt(1 - x)"}, ["ceramic", "metal"], length=1.0)
    np.testing.assert_allclose(g.gradient([[1.0, 0.5]])[0, 1], [-10.0, 0.0], rtol=1e-12)


def test_length_must_be_positive():
    for bad in (0.0, -1.0, float("nan"), True):
        with pytest.raises(MaterialError, match="length must be a positive number"):
            AnalyticField({"metal": "x"}, ["ceramic", "metal"], length=bad)


# ----------------------------------------------------------------------- piecewise formulas

def test_piecewise_field_regions_are_condition_bits():
    f = AnalyticField({"a": "where(x < 0.5, 0.2, 0.6)", "b": "0.3*sign(y - 0.5) + 0.3"},
                      ["a", "b", "c"])
    assert f.conditions == ("x < 0.5", "y - 0.5 >= 0") and f.n_regions == 4
    p = np.array([[0.2, 0.2], [0.7, 0.2], [0.2, 0.7], [0.7, 0.7], [0.7, 0.5]])
    np.testing.assert_array_equal(f.region(p), [1, 0, 3, 2, 2])
    assert list(f.region_names) == ["not x < 0.5 and not y - 0.5 >= 0",
                                    "x < 0.5 and not y - 0.5 >= 0",
                                    "not x < 0.5 and y - 0.5 >= 0", "x < 0.5 and y - 0.5 >= 0"]
    assert f.region_names[-1] == "x < 0.5 and y - 0.5 >= 0" and len(f.region_names) == 4
    # composition in its own subregion: the formula (sign(0) counted as +1)
    np.testing.assert_allclose(f.composition(p)[:, :2], [[0.2, 0], [0.6, 0], [0.2, 0.6],
                                                         [0.6, 0.6], [0.6, 0.6]])
    np.testing.assert_array_equal(f.composition(p), f.composition(p, region=f.region(p)))
    # another subregion's field, continued: every point evaluated as in subregion 1
    np.testing.assert_allclose(f.composition(p, region=1)[:, :2], [[0.2, 0.0]] * 5)
    assert f.describe_jump(0, 2) == "material.composition.b: condition 'y - 0.5 >= 0'"
    assert f.shifted([1.0, 0.0]).region(p[:1] - [1.0, 0.0]).tolist() == [1]


def test_smooth_formula_field_has_no_subregions(rng):
    f = AnalyticField({"metal": "x*y + abs(x - 0.5)/4"}, ["ceramic", "metal"])
    assert not hasattr(f, "region") and f.n_regions == 1 and f.conditions == ()


def test_piecewise_gradient_stays_on_its_side():
    f = AnalyticField({"metal": "where(x < 0.5, 0.5*x, 0.5 + x)"}, ["ceramic", "metal"])
    p = np.array([[0.5, 0.5], [0.5 - 1e-12, 0.5], [0.25, 0.5]])
    np.testing.assert_array_equal(f.gradient(p)[:, 1, 0], [1.0, 0.5, 0.5])
    np.testing.assert_array_equal(f.gradient(p, region=1)[:, 1, 0], [0.5, 0.5, 0.5])
    np.testing.assert_array_equal(f.gradient(p, region=0)[:, 1, 0], [1.0, 1.0, 1.0])


def test_continued_branch_is_finite_just_past_its_boundary():
    """sqrt(x - 0.5) continued a hair left of x = 0.5: its value from the defined side."""
    f = AnalyticField({"metal": "where(x > 0.5, sqrt(x - 0.5), 0)"}, ["ceramic", "metal"])
    p = np.array([[0.5 - 1e-12, 0.3], [0.7, 0.3]])
    c = f.composition(p, region=1)
    assert np.isfinite(c).all() and c[0, 1] < 1e-5
    np.testing.assert_allclose(c[1, 1], np.sqrt(0.2))
    assert np.isfinite(f.gradient(p, region=1)).all()


def test_region_argument_is_checked():
    f = AnalyticField({"metal": "where(x < 0.5, 0.2, 0.8)"}, ["ceramic", "metal"])
    for bad in ([0, 1, 0], [2, 0], [-1, 0]):
        with pytest.raises(MaterialError, match=r"region must be 2 ids in \[0, 2\)"):
            f.composition(np.zeros((2, 2)), region=bad)


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


def test_callable_one_sided_where_the_function_is_undefined():
    f = CallableField(lambda x, y: np.sqrt(x), ["ceramic", "metal"])
    g = f.gradient([[0.0, 0.5], [0.25, 0.5]])
    assert np.isfinite(g).all()
    np.testing.assert_allclose(g[0, 1], [1 / np.sqrt(1e-6), 0.0], rtol=1e-9)  # forward
    np.testing.assert_allclose(g[1, 1], [1.0, 0.0], rtol=1e-6)  # central


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


def test_check_field_infinite_gradient_of_a_foreign_field():
    d = _rect(0, 0, 1, 1)

    class Bad:
        constituents = ("a", "b")

        def composition(self, p):
            return np.full((len(p), 2), 0.5)

        def gradient(self, p):
            g = np.zeros((len(p), 2, 2))
            g[-1, 0, 1] = np.inf
            return g

    with pytest.raises(MaterialError, match=r"material.composition.a: gradient is infinite at "
                                            r"\(.*\) \(the field must return finite"):
        check_field(Bad(), d, "m.toml")


def test_check_field_accepts_kinks_and_infinite_slopes():
    d = _rect(0, 0, 10, 10)
    for formula in ("exp(-sqrt((x - 4)**2 + (y - 4)**2)/2)", "sqrt(x/10)", "abs(x - 5)/5"):
        check_field(AnalyticField({"metal": formula}, ["ceramic", "metal"]), d, "m.toml")
    check_field(CallableField(lambda x, y: np.sqrt(x / 10), ["ceramic", "metal"]), d)


def test_check_field_reports_a_jump_on_the_boundary():
    d = _rect(0, 0, 1, 1)
    with pytest.raises(MaterialError) as info:
        check_field(AnalyticField({"metal": "x**1e308"}, ["ceramic", "metal"]), d, "m.toml")
    msg = str(info.value)
    assert msg.startswith("m.toml: material.composition.metal: value jumps from 0 to 1 "
                          "within 1.41421e-09 of (1, ")
    assert "\n" not in msg
    # a jump inside the domain that a curve sample lies on, approached along the boundary
    with pytest.raises(MaterialError, match=r"value jumps from 0\.1 to 0\.9 within "
                                            r"1\.41421e-09 of \(0\.3, 0\)"):
        check_field(AnalyticField({"metal": "0.5 + 0.4*tanh(1e20*(x - 0.3))"},
                                  ["ceramic", "metal"]), d, "m.toml")
    # the same jump written as a condition is embedded in the mesh: no error
    check_field(AnalyticField({"metal": "where(x < 1, 0, 1)"}, ["ceramic", "metal"]), d)
    # steep but continuous at the boundary: fine
    check_field(AnalyticField({"metal": "x**50"}, ["ceramic", "metal"]), d)


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
