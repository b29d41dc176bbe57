"""Tests of the safe formula compiler (hetmesh.expr): values, derivatives, rejections."""

from __future__ import annotations

import inspect
import re
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from hetmesh import expr as expr_module
from hetmesh.errors import FormulaError, MaterialError
from hetmesh.expr import MAX_LENGTH, Expr, compile_expr, split_conditions

RNG = np.random.default_rng(20240611)
X = RNG.uniform(0.05, 0.95, 64)
Y = RNG.uniform(0.05, 0.95, 64)


# --------------------------------------------------------------------------- evaluation
@pytest.mark.parametrize(
    "text, reference",
    [
        ("x + 2*y - 3", lambda x, y: x + 2 * y - 3),
        ("x / y - y**3 + -x", lambda x, y: x / y - y**3 - x),
        ("2**-x * x**0.5", lambda x, y: 2.0**-x * x**0.5),
        ("x**y**2", lambda x, y: x ** (y**2)),
        ("sin(x) + cos(y) + tan(x*y)", lambda x, y: np.sin(x) + np.cos(y) + np.tan(x * y)),
        ("arcsin(x) + asin(y) + arccos(x) + acos(y)",
         lambda x, y: np.arcsin(x) + np.arcsin(y) + np.arccos(x) + np.arccos(y)),
        ("arctan(x) + atan(y) + atan2(y, x - 0.5) + arctan2(x, y)",
         lambda x, y: np.arctan(x) + np.arctan(y) + np.arctan2(y, x - 0.5) + np.arctan2(x, y)),
        ("sinh(x) * cosh(y) / tanh(x + 1)", lambda x, y: np.sinh(x) * np.cosh(y) / np.tanh(x + 1)),
        ("exp(-x) + log(y) + log10(x) + sqrt(y)",
         lambda x, y: np.exp(-x) + np.log(y) + np.log10(x) + np.sqrt(y)),
        ("abs(x - y) + sign(x - 0.5)", lambda x, y: np.abs(x - y) + np.sign(x - 0.5)),
        ("min(x, y) + max(x, y, 0.5) + min(1, 2, x)",
         lambda x, y: np.minimum(x, y) + np.maximum(np.maximum(x, y), 0.5) + np.minimum(1, x)),
        ("clip(3*x - 1, 0, 1)", lambda x, y: np.clip(3 * x - 1, 0, 1)),
        ("where(x > y, x, y**2)", lambda x, y: np.where(x > y, x, y**2)),
        ("x if 0.2 <= x < 0.7 else -y", lambda x, y: np.where((x >= 0.2) & (x < 0.7), x, -y)),
        ("where(x < 0.3 or y > 0.6 and not x > 0.9, 1, 0)",
         lambda x, y: np.where((x < 0.3) | ((y > 0.6) & ~(x > 0.9)), 1.0, 0.0)),
        ("pi*x + e*y", lambda x, y: np.pi * x + np.e * y),
        ("0x10 * 1_000 * 1e-3 * x", lambda x, y: 16.0 * x),
    ],
)
def test_values_match_numpy(text: str, reference) -> None:
    f = compile_expr(text)
    np.testing.assert_allclose(f(x=X, y=Y), reference(X, Y), rtol=1e-12, atol=1e-14)


def test_parameters_and_custom_variables() -> None:
    f = compile_expr("((b - y)/b)**2", parameters={"b": 30})
    np.testing.assert_allclose(f(x=0.0, y=np.array([0.0, 15.0, 30.0])), [1.0, 0.25, 0.0])
    assert f.names == frozenset({"y"})
    g = compile_expr("(d_b/(d_int + d_b))**3", variables=("d_b", "d_int"))
    np.testing.assert_allclose(g(d_b=1.0, d_int=3.0), 1 / 64)
    # a parameter shadows the constant e
    assert compile_expr("e", parameters={"e": 0.25}).constant_value == 0.25


def test_result_shape_dtype_and_no_aliasing() -> None:
    x = np.linspace(0.0, 1.0, 6)
    y = np.linspace(0.0, 1.0, 4)[:, None]
    out = compile_expr("x*y + 1")(x=x, y=y)
    assert out.shape == (4, 6) and out.dtype == np.float64
    # broadcast to all values passed, even the unused ones
    out = compile_expr("x")(x=x, y=y)
    assert out.shape == (4, 6)
    same = compile_expr("x*1 + 0")(x=x)
    assert same.base is None and same is not x
    same[:] = -1.0
    assert x[1] == 0.2  # the input was not written through
    const = compile_expr("2*pi/4")
    assert const.names == frozenset() and const.constant_value == pytest.approx(np.pi / 2)
    filled = const(x=np.zeros((3, 2)))
    assert filled.shape == (3, 2) and filled.flags.writeable
    np.testing.assert_array_equal(filled, np.full((3, 2), np.pi / 2))
    assert const().shape == () and isinstance(const(), np.ndarray)
    ints = compile_expr("x/2")(x=np.array([1, 2, 3]))
    np.testing.assert_array_equal(ints, [0.5, 1.0, 1.5])  # integer input, float division
    assert isinstance(compile_expr("x")(x=3), np.ndarray)


def test_non_finite_results_are_returned_quietly() -> None:
    f = compile_expr("where(x < 1, log(x), where(x < 2, 1/(x - 1), sqrt(-x)))")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = f(x=np.array([0.0, 1.0, 3.0]))
        assert np.isneginf(out[0]) and np.isposinf(out[1]) and np.isnan(out[2])
        assert np.isnan(f.diff("x")(x=np.array([0.0, 1.0, 3.0]))).any()
    assert compile_expr("1e999").constant_value == np.inf


def test_call_with_wrong_variables() -> None:
    f = compile_expr("x + y", where="m.toml: f")
    with pytest.raises(TypeError, match=r"m.toml: f: missing value for 'y'"):
        f(x=1.0)
    with pytest.raises(TypeError, match=r"unexpected variable 'z'"):
        f(x=1.0, y=2.0, z=3.0)


def test_repr_and_text() -> None:
    f = compile_expr(" x**2 ")
    assert f.text == " x**2 " and repr(f) == "Expr(' x**2 ')"
    assert isinstance(f.diff("x"), Expr)


# --------------------------------------------------------------------------- derivatives
def central_difference(f: Expr, name: str, values: dict[str, np.ndarray], h: float = 1e-6):
    up = dict(values, **{name: values[name] + h})
    down = dict(values, **{name: values[name] - h})
    return (f(**up) - f(**down)) / (2 * h)


DERIVATIVE_CASES = [
    # text, variables, parameters, {variable: (low, high)}
    ("((b - y)/b)**2", ("x", "y"), {"b": 30.0}, {"x": (0, 1), "y": (0, 30)}),
    ("exp(-5*d/(d + t))", ("d",), {"t": 2.0}, {"d": (0.1, 10)}),
    ("(d_b/(d_int + d_b))**3", ("d_b", "d_int"), None, {"d_b": (0.1, 5), "d_int": (0.1, 5)}),
    ("sqrt(x**2 + y**2 + 1)", ("x", "y"), None, {"x": (-1, 1), "y": (-1, 1)}),
    ("sqrt(x) * y", ("x", "y"), None, {"x": (0.2, 1), "y": (0, 1)}),
    ("where(x > 0.3, x**2, sin(y))", ("x", "y"), None, {"x": (0, 1), "y": (0, 1)}),
    ("abs(x - y) * y", ("x", "y"), None, {"x": (0, 1), "y": (0, 1)}),
    ("min(x, y)**2 + max(x, 2*y, 0.4)", ("x", "y"), None, {"x": (0, 1), "y": (0, 1)}),
    ("x**y", ("x", "y"), None, {"x": (0.5, 2), "y": (-1, 2)}),
    ("y**(x - 2) * 3**x", ("x", "y"), None, {"x": (0, 1), "y": (0.5, 2)}),
    ("atan2(y, x) + arctan2(x*y, 1 + x)", ("x", "y"), None, {"x": (0.5, 2), "y": (-1, 1)}),
    ("tan(x) + arcsin(y/2) + acos(y/3) + atan(x*y)", ("x", "y"), None,
     {"x": (-1, 1), "y": (-1, 1)}),
    ("sinh(x)*cosh(y) + tanh(x*y)", ("x", "y"), None, {"x": (-1, 1), "y": (-1, 1)}),
    ("log(x + 2) + log10(y + 2) - cos(x)", ("x", "y"), None, {"x": (-1, 1), "y": (-1, 1)}),
    ("2**x + e**y + pi*x/y", ("x", "y"), None, {"x": (0, 1), "y": (0.5, 1)}),
    ("clip(3*x, 0.2, 1.5) * y", ("x", "y"), None, {"x": (0, 1), "y": (0, 1)}),
    ("x if 0.2 < x < 0.7 else y**2", ("x", "y"), None, {"x": (0, 1), "y": (0, 1)}),
    ("where(x > 0.5 and not y < 0.2 or x < 0.1, x*y, -y)", ("x", "y"), None,
     {"x": (0, 1), "y": (0, 1)}),
    ("1/(1 + x**2) - 1/y", ("x", "y"), None, {"x": (-2, 2), "y": (0.5, 2)}),
    ("sign(x - 0.5)*x**3", ("x", "y"), None, {"x": (0, 1), "y": (0, 1)}),
    ("x**-2 + (-x)**2 + x**0 + x**1", ("x", "y"), None, {"x": (0.5, 2), "y": (0, 1)}),
]


@pytest.mark.parametrize("text, variables, parameters, box", DERIVATIVE_CASES)
def test_derivatives_match_finite_differences(text, variables, parameters, box) -> None:
    rng = np.random.default_rng(7)
    values = {v: rng.uniform(lo, hi, 200) for v, (lo, hi) in box.items()}
    f = compile_expr(text, variables, parameters)
    for name in variables:
        d = f.diff(name)
        assert d.names <= frozenset(variables)
        np.testing.assert_allclose(d(**values), central_difference(f, name, values),
                                   rtol=1e-6, atol=1e-7, err_msg=f"d/d{name} of {text}")
        for second in variables:  # second derivatives, also mixed ones
            np.testing.assert_allclose(
                d.diff(second)(**values), central_difference(d, second, values),
                rtol=1e-5, atol=1e-6, err_msg=f"d2/d{name}d{second} of {text}")


@pytest.mark.parametrize(
    "text, name, expected",
    [
        ("x**2", "x", "2*x"),
        ("x**3 + sin(y)", "x", "3*x**2"),
        ("3*x + 4*y", "y", "4"),
        ("x*y", "x", "y"),
        ("exp(x)", "x", "exp(x)"),
        ("log(x)", "x", "1/x"),
        ("sin(y)", "x", "0"),
    ],
)
def test_derivatives_are_simplified(text: str, name: str, expected: str) -> None:
    assert compile_expr(text).diff(name).text == expected


def test_derivative_trees_stay_small() -> None:
    assert compile_expr("x**3").diff("x").diff("x").text == "6*x"
    assert compile_expr("x**3").diff("x").diff("x").diff("x").diff("x").constant_value == 0
    zero = compile_expr("sin(y)").diff("x")
    assert zero.names == frozenset() and zero.constant_value == 0.0
    np.testing.assert_array_equal(zero(x=np.ones(3), y=np.ones(3)), np.zeros(3))
    # a smooth, typical composition: fourth derivative still evaluates and stays modest
    f = compile_expr("exp(-5*d/(d + t))*sin(pi*d)", ("d",), {"t": 2.0})
    d4 = f.diff("d").diff("d").diff("d").diff("d")
    assert np.all(np.isfinite(d4(d=np.linspace(0.1, 5, 50))))
    assert len(d4.text) < 20_000


def test_diff_of_unknown_variable() -> None:
    with pytest.raises(FormulaError, match=r"^f\.toml: k: cannot differentiate with respect "
                                           r"to 'z' \(variables: x, y\)$"):
        compile_expr("x", where="f.toml: k").diff("z")


# --------------------------------------------------------------------------- conditions
@pytest.mark.parametrize("texts, conditions", [
    (["x**2 + abs(y - 0.5) + min(x, y) + clip(x, 0.2, 0.8)"], []),  # kinks are no jumps
    (["where(x < 0.5, 0.2, 0.8)"], ["x < 0.5"]),
    (["0.3 if x + y < 1 else 0.6"], ["x + y < 1"]),
    (["where(x < 0.5 and not y >= 0.2 or x > 0.9, x, y)"], ["x < 0.5", "y >= 0.2", "x > 0.9"]),
    (["0.2 if 0.1 <= x < 0.7 else 0.4"], ["0.1 <= x", "x < 0.7"]),
    (["0.5 + 0.3*sign(x - y)"], ["x - y >= 0"]),
    (["where(x < 0.5, where(y < 0.5, 0.1, 0.2), 0.3)", "where(x < 0.5, 0.3, 0.4) + sign(y)"],
     ["x < 0.5", "y < 0.5", "y >= 0"]),  # shared once, in order of first occurrence
    (["where(x < 0.5, 0.2, 0.2)"], []),  # equal branches fold away
])
def test_split_conditions_finds_the_jumps(texts, conditions) -> None:
    conds, fixed = split_conditions([compile_expr(t) for t in texts])
    assert [c.text for c in conds] == conditions
    assert len(fixed) == len(texts)
    names = [f"_c{i}" for i in range(len(conds))]
    for f in fixed:
        assert set(f.variables) == {"x", "y", *names}


def test_fixed_conditions_reproduce_the_formula_and_continue_its_branches() -> None:
    text = "where(x < 0.5 and y > 0.2, x**2, 1 - y) + 0.1*sign(x - y)"
    f = compile_expr(text)
    conds, (g,) = split_conditions([f])
    vals = {c: np.asarray(e(x=X, y=Y)) != 0 for c, e in zip(("_c0", "_c1", "_c2"), conds)}
    np.testing.assert_array_equal(g(x=X, y=Y, **vals), f(x=X, y=Y))  # bit for bit off x = y
    # fixed to one pattern: one smooth branch everywhere, its derivative exact
    on = dict(_c0=True, _c1=True, _c2=False)
    np.testing.assert_allclose(g(x=X, y=Y, **on), X**2 - 0.1)
    np.testing.assert_allclose(g.diff("x")(x=X, y=Y, **on), 2 * X)
    assert g.diff("y")(x=X, y=Y, **on).max() == 0.0
    # sign(0) takes the side u >= 0
    assert compile_expr("sign(x)")(x=0.0) == 0.0
    assert split_conditions([compile_expr("sign(x)")])[1][0](x=0.0, _c0=True) == 1.0


def test_split_conditions_of_smooth_formulas_keeps_them() -> None:
    f = compile_expr("((b - y)/b)**2", parameters={"b": 30.0})
    conds, (g,) = split_conditions([f])
    assert conds == [] and g.text == f.text
    np.testing.assert_array_equal(g(x=X, y=Y), f(x=X, y=Y))
    assert split_conditions([]) == ([], [])


# --------------------------------------------------------------------------- rejections
@pytest.mark.parametrize(
    "text, message",
    [
        ("__import__('os')", "names containing '__' are not allowed"),
        ("__builtins__", "names containing '__' are not allowed"),
        ("x.real", "attribute access is not allowed"),
        ("x.__class__.__bases__", "attribute access is not allowed"),
        ("np.sin(x)", "attribute access is not allowed"),
        ("(lambda: 1)()", "lambda is not allowed"),
        ("lambda: 1", "lambda is not allowed"),
        ("'a'", "strings are not allowed"),
        ("b'a'", "strings are not allowed"),
        ("f'{x}'", "f-strings are not allowed"),
        ("x[0]", "subscripts are not allowed"),
        ("open('f')", "unknown function 'open'"),
        ("eval('1')", "unknown function 'eval'"),
        ("foo(x)", "unknown function 'foo'"),
        ("sin(x)(y)", "only calls of named functions"),
        ("z", "unknown name 'z' (allowed: x, y, b)"),
        ("sin", "'sin' is a function; call it as sin(...)"),
        ("x ^ 2", "'^' is not allowed; use ** for powers"),
        ("x % 2", "operator '%' is not allowed"),
        ("x // 2", "operator '//' is not allowed"),
        ("~x", "operator '~' is not allowed"),
        ("x < 1", "only allowed in the condition of where"),
        ("x > 0 and y > 0", "only allowed in the condition of where"),
        ("not x", "only allowed in the condition of where"),
        ("where(x, 1, 0)", "a condition must be a comparison"),
        ("1 if x else 0", "a condition must be a comparison"),
        ("where(x == 1, 1, 0)", "comparison '==' is not allowed"),
        ("where(x in y, 1, 0)", "comparison 'in' is not allowed"),
        ("True", "True is not allowed"),
        ("None", "None is not allowed"),
        ("1j", "complex numbers are not allowed"),
        ("[x for x in y]", "comprehensions are not allowed"),
        ("(x for x in y)", "comprehensions are not allowed"),
        ("(x, y)", "lists, tuples, sets and dicts are not allowed"),
        ("{'a': 1}", "lists, tuples, sets and dicts are not allowed"),
        ("(y := 1)", "assignment (:=) is not allowed"),
        ("max(*x)", "starred arguments are not allowed"),
        ("clip(x, lo=0, hi=1)", "keyword arguments are not allowed"),
        ("sin(x, y)", "sin() takes 1 argument (got 2)"),
        ("min(x)", "min() takes at least 2 arguments (got 1)"),
        ("where(x > 0, 1)", "where() takes 3 arguments (got 2)"),
        ("1" + "0" * 400, "number is too large"),
        ("x" * (MAX_LENGTH + 1), "formula is too long (1001 characters, at most 1000)"),
        ("(" * 200 + "x" + ")" * 200, "nested too deeply"),
        ("-" * 200 + "x", "nested too deeply"),
        ("x" + "**x" * 60, "nested too deeply"),
        ("sin(" * 60 + "x" + ")" * 60, "nested too deeply"),
        ("*".join(["(" + "+".join("x" * 30) + ")"] * 9), "formula is too large"),
        ("", "empty formula"),
        ("  \n ", "empty formula"),
        ("x +", "syntax error at column"),
        ("x + (y", "syntax error at column"),
        ("x = 1", "syntax error at column"),
        ("import os", "syntax error at column"),
        ("x\n+ 1", "syntax error at line 2"),
        ("x\x00", "syntax error"),
    ],
)
def test_forbidden_constructs(text: str, message: str) -> None:
    with pytest.raises(FormulaError) as info:
        compile_expr(text, parameters={"b": 2.0}, where="plate.toml: material.metal")
    text_of_error = str(info.value)
    assert text_of_error.startswith("plate.toml: material.metal: ")
    assert message in text_of_error
    assert "\n" not in text_of_error
    assert isinstance(info.value, MaterialError)  # FormulaError is a MaterialError


def test_syntax_error_column_counts_leading_space() -> None:
    with pytest.raises(FormulaError, match=r"^formula: syntax error at column 8"):
        compile_expr("x + y +* 2")
    with pytest.raises(FormulaError, match=r"syntax error at column 10"):
        compile_expr("  x + y +* 2")


def test_bad_arguments_to_compile() -> None:
    with pytest.raises(FormulaError, match="a formula must be a string, got int"):
        compile_expr(3)  # type: ignore[arg-type]
    with pytest.raises(FormulaError, match="invalid variable name '1x'"):
        compile_expr("x", variables=("1x",))
    with pytest.raises(FormulaError, match="invalid variable name '__x'"):
        compile_expr("x", variables=("__x",))
    with pytest.raises(FormulaError, match="'x' is both a variable and a parameter"):
        compile_expr("x", parameters={"x": 1.0})
    for value in (True, "3", float("nan"), float("inf"), 10**400):
        with pytest.raises(FormulaError, match="parameter 'b' must be a finite number"):
            compile_expr("b", parameters={"b": value})
    assert compile_expr("b", parameters={"b": np.float32(0.5)}).constant_value == 0.5


def test_limits_are_inclusive() -> None:
    text = "x + " + "0" * (MAX_LENGTH - 4)
    assert len(text) == MAX_LENGTH
    compile_expr(text)
    compile_expr("(" * 50 + "x" + ")" * 50)


def test_module_never_evaluates_text() -> None:
    source = inspect.getsource(expr_module)
    assert not re.search(r"\b(eval|exec|compile|sympify|lambdify|parse_expr)\(", source)
    assert "numexpr." not in source and "__import__" not in source


# --------------------------------------------------------------------------- properties
@settings(max_examples=150, deadline=None)
@given(coefficients=st.lists(st.integers(-20, 20) | st.floats(-5, 5, allow_nan=False),
                             min_size=1, max_size=7),
       points=st.lists(st.floats(-2, 2, allow_nan=False), min_size=1, max_size=8))
def test_polynomial_derivatives(coefficients, points) -> None:
    text = " + ".join(f"({c!r})*x**{k}" for k, c in enumerate(coefficients))
    f = compile_expr(text, variables=("x",))
    x = np.array(points)
    poly = np.polynomial.Polynomial(coefficients)
    scale = 1.0 + np.abs(coefficients).sum() * 2.0 ** len(coefficients)
    np.testing.assert_allclose(f(x=x), poly(x), rtol=1e-9, atol=1e-12 * scale)
    np.testing.assert_allclose(f.diff("x")(x=x), poly.deriv()(x), rtol=1e-9, atol=1e-12 * scale)
    np.testing.assert_allclose(f.diff("x").diff("x")(x=x), poly.deriv(2)(x), rtol=1e-9,
                               atol=1e-11 * scale)


LEAVES = st.sampled_from(["x", "y", "0.5", "2", "1.5", "3"])


def _combine(children: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    binary = st.tuples(children, st.sampled_from(["+", "-", "*"]), children).map(
        lambda t: f"({t[0]} {t[1]} {t[2]})")
    unary = st.tuples(st.sampled_from(["sin", "cos", "tanh", "arctan", "-"]), children).map(
        lambda t: f"{t[0]}({t[1]})")
    power = st.tuples(children, st.sampled_from(["2", "3"])).map(lambda t: f"({t[0]})**{t[1]}")
    quotient = children.map(lambda c: f"1/(1.5 + sin({c}))")
    return binary | unary | power | quotient


SMOOTH_FORMULAS = st.recursive(LEAVES, _combine, max_leaves=8)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow],
          derandomize=True)
@given(text=SMOOTH_FORMULAS)
def test_random_smooth_formulas(text: str) -> None:
    f = compile_expr(text)
    values = {"x": np.array([-0.7, -0.2, 0.3, 0.9]), "y": np.array([0.4, -0.6, 0.1, -0.9])}
    h = 1e-6
    for name in ("x", "y"):
        d = f.diff(name)
        fd = central_difference(f, name, values, h)
        # the difference quotient's own error, from a second step: a fast oscillation
        # (sin((18 x)**3)) makes it the larger error, not the exact derivative
        fd_err = np.abs(central_difference(f, name, values, 4 * h) - fd)
        magnitude = 1.0 + np.max(np.abs(f(**values)))
        bound = 1e-5 * np.abs(fd) + 1e-6 * magnitude + 2.0 * fd_err
        assert np.all(np.abs(d(**values) - fd) <= bound), \
            f"d/d{name} of {text} = {d.text}: {d(**values)} against {fd}"
        # the printed derivative compiles back to the same function
        try:
            again = compile_expr(d.text)
        except FormulaError as exc:
            assume("too" not in str(exc))  # printed trees may exceed the size limits
            raise
        np.testing.assert_allclose(again(**values), d(**values), rtol=1e-12, atol=1e-12)


TOKENS = ["x", "y", "1", "2.5", "1e3", "+", "-", "*", "/", "**", "^", "%", "(", ")", ",", " ",
          "sin", "min", "max", "where", "clip", "exp", "log", "<", ">", "==", " if ", " else ",
          " and ", " or ", "not ", "e", "pi", "[", "]", ".", "'", "__", "lambda", ":", "=",
          "real", "import", "os", "\n", "{", "}", "*", "@", "j", "True", "_"]


def _must_only_raise_formula_error(text: str) -> None:
    try:
        f = compile_expr(text)
    except FormulaError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("formula: ")
        return
    values = {"x": np.array([0.25, 2.0]), "y": np.array([-1.0, 0.5])}
    assert f(**values).shape == (2,)
    for name in ("x", "y"):
        try:
            d = f.diff(name)
        except FormulaError:
            continue
        assert d(**values).shape == (2,)


@settings(max_examples=400, deadline=None)
@given(text=st.text(max_size=60))
def test_random_text_only_raises_formula_error(text: str) -> None:
    _must_only_raise_formula_error(text)


@settings(max_examples=600, deadline=None)
@given(text=st.lists(st.sampled_from(TOKENS), max_size=30).map("".join))
def test_random_token_soup_only_raises_formula_error(text: str) -> None:
    _must_only_raise_formula_error(text)
