"""Model files: the examples, the schema's strictness and its error messages."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hetmesh.errors import FormulaError, GeometryError, HetmeshError, MaterialError, ModelFileError
from hetmesh.io.model import Model, load_model, parse_model
from hetmesh.material import AnalyticField, CallableField, check_field
from hetmesh.tri.geometry import Loop, Segment, make_domain

EXAMPLES = Path(__file__).resolve().parents[1] / "src" / "hetmesh" / "examples"
EXAMPLE_FILES = sorted(p for p in EXAMPLES.glob("*.toml")  # 2D models (3D: test_tet_models)
                       if "\n[solid]" not in p.read_text(encoding="utf-8"))

SQUARE = """
[domain.outer]
start = [0, 0]
path = [{ to = [1, 0] }, { to = [1, 1] }, { to = [0, 1] }, { to = [0, 0] }]
"""
MATERIAL = """
[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "(1 - y)**2"
"""


def _write(tmp_path: Path, text: str, name: str = "m.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _error(tmp_path: Path, text: str, exc=HetmeshError) -> str:
    """Load ``text`` and return the (one-line) message of the expected exception."""
    p = _write(tmp_path, text)
    with pytest.raises(exc) as info:
        load_model(p)
    msg = str(info.value)
    assert msg.startswith(f"{p}: "), msg
    assert "\n" not in msg, msg
    return msg


# ----------------------------------------------------------------------------- examples

def test_required_examples_exist():
    names = {p.stem for p in EXAMPLE_FILES}
    assert {"power_plate", "unit_square", "plate_with_holes", "three_phase"} <= names


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.stem)
def test_every_example_loads_and_checks(path):
    m = load_model(path)
    assert m.name == path.stem
    assert m.source == path
    assert m.domain.area > 0
    check_field(m.material, m.domain, path.name)
    assert len(m.constituents) >= 2


def test_power_plate_area_is_exact():
    m = load_model(EXAMPLES / "power_plate.toml")
    R, h = 39.75, 6.0
    segment = R**2 * math.acos((R - h) / R) - (R - h) * math.sqrt(2 * R * h - h * h)
    assert m.domain.area == pytest.approx(42 * 24 + segment, rel=1e-12)
    assert m.domain.bounds == pytest.approx((0, 0, 42, 30), abs=1e-12)
    assert m.units == "mm" and "reconstruct" in (EXAMPLES / "power_plate.toml").read_text()
    assert m.parameters == {"b": 30.0}


def test_power_plate_composition_and_gradient_closed_form():
    """Eqs. (10)-(11): f = ((b - y)/b)^2 and |grad f| = 2 (b - y)/b^2."""
    m = load_model(EXAMPLES / "power_plate.toml")
    b = 30.0
    g = np.random.default_rng(1).uniform((0, 0), (42, 30), size=(500, 2))
    p = g[m.domain.contains(g)]
    y = p[:, 1]
    c = m.material.composition(p)
    grad = m.material.gradient(p)
    i = m.constituents.index("metal")
    np.testing.assert_allclose(c[:, i], ((b - y) / b) ** 2, rtol=1e-14)
    np.testing.assert_allclose(c.sum(axis=1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(np.hypot(*grad[:, i].T), 2 * (b - y) / b**2, rtol=1e-14)


def test_three_phase_and_named_points():
    m = load_model(EXAMPLES / "three_phase.toml")
    assert m.constituents == ("ceramic", "binder", "metal")
    assert set(m.domain.points) == {"P1", "P2", "P3"}
    c = m.material.composition(np.array([[20.0, 10.0]]))
    np.testing.assert_allclose(c, [[0.25, 0.25, 0.5]])


def test_plate_with_holes_structure():
    m = load_model(EXAMPLES / "plate_with_holes.toml")
    assert len(m.domain.holes) == 2 and len(m.domain.interfaces) == 1
    assert m.domain.area == pytest.approx(60 * 40 - math.pi * (16 + 25), rel=1e-12)
    c = m.material.composition(np.array([[20.0, 0.0]]))
    np.testing.assert_allclose(c, [[0.5, 0.5]])


def test_names_reach_the_domain():
    m = load_model(EXAMPLES / "power_plate.toml")
    names = [info.name for info in m.domain.curves]
    assert names == ["bottom", "right", "top", "left"]
    assert m.domain.outer.name == "outer"


# ----------------------------------------------------------------------------- valid variants

def test_minimal_file_and_defaults(tmp_path):
    m = load_model(_write(tmp_path, SQUARE + MATERIAL, "my_square.toml"))
    assert m.name == "my_square" and m.description == "" and m.parameters == {}
    assert m.domain.area == pytest.approx(1.0)


def test_arc_by_center_directions(tmp_path):
    def area(direction):
        text = f"""
[domain.outer]
start = [1, 0]
path = [{{ to = [-1, 0], center = [0, 0], direction = "{direction}" }}, {{ to = [1, 0] }}]
""" + MATERIAL.replace("(1 - y)**2", "0.5")
        return load_model(_write(tmp_path, text)).domain.area

    assert area("ccw") == pytest.approx(math.pi / 2, rel=1e-12)
    assert area("cw") == pytest.approx(math.pi / 2, rel=1e-12)


def test_circle_outer_interface_hole_and_number_formula(tmp_path):
    text = """
[domain.outer]
circle = { center = [0, 0], radius = 38 }
[[domain.holes]]
circle = { center = [0, 0], radius = 8 }
[[domain.interfaces]]
name = "A"
circle = { center = [0, 0], radius = 28 }
[material]
constituents = ["ceramic", "metal"]
[material.composition]
metal = 0.25
"""
    m = load_model(_write(tmp_path, text))
    assert m.domain.area == pytest.approx(math.pi * (38**2 - 8**2), rel=1e-12)
    assert [h.name for h in m.domain.holes] == ["hole[0]"]
    assert [p.name for p in m.domain.interfaces] == ["A"]
    np.testing.assert_allclose(m.material.composition(np.zeros((1, 2))), [[0.75, 0.25]])


def test_interface_between_boundary_vertices(tmp_path):
    text = """
[domain.outer]
start = [0, 0]
path = [{ to = [1, 0] }, { to = [1, 0.5] }, { to = [1, 1] }, { to = [0, 1] }, { to = [0, 0.5] },
        { to = [0, 0] }]
[[domain.interfaces]]
name = "seam"
start = [1, 0.5]
path = [{ to = [0, 0.5] }]
""" + MATERIAL
    m = load_model(_write(tmp_path, text))
    assert [p.name for p in m.domain.interfaces] == ["seam"]


def test_all_formulas_given(tmp_path):
    text = SQUARE + """
[material]
constituents = ["a", "b", "c"]
[material.composition]
a = "x/2"
b = "y/2"
c = "1 - x/2 - y/2"
"""
    m = load_model(_write(tmp_path, text))
    assert m.material.derived is None


def test_square_far_from_origin(tmp_path):
    text = """
[parameters]
c = 1e9
[domain.outer]
start = [1e9, 1e9]
path = [{ to = [1000000001, 1e9] }, { to = [1000000001, 1000000001] },
        { to = [1e9, 1000000001] }, { to = [1e9, 1e9] }]
[domain.points]
P = [1000000000.5, 1000000000.5]
[material]
constituents = ["ceramic", "metal"]
[material.composition]
metal = "(1 - (y - c))**2"
"""
    m = load_model(_write(tmp_path, text))
    assert m.domain.area == pytest.approx(1.0, rel=1e-6)
    local = m.material.shifted([1e9, 1e9])
    np.testing.assert_allclose(local.composition(np.array([[0.5, 0.5]])), [[0.75, 0.25]])


def test_parse_model_from_dict_and_check_flag():
    data = {"domain": {"outer": {"circle": {"center": [0, 0], "radius": 1}}},
            "material": {"constituents": ["a", "b"], "composition": {"b": "2*x"}}}
    m = parse_model(data, "dict", check=False)        # out of range, not checked
    assert m.name == "model" and m.source is None
    with pytest.raises(MaterialError,
                       match=r"^dict: material.composition.b: value -?2 at \(-?1, 0\)"):
        parse_model(data, "dict")


def test_model_in_code():
    pts = [(0, 0), (1, 0), (1, 1), (0, 1)]
    outer = Loop(tuple(Segment(a, b) for a, b in zip(pts, pts[1:] + pts[:1])), "outer")
    m = Model(name="m", domain=make_domain(outer),
              material=CallableField(lambda x, y: (1 - y) ** 2, ["ceramic", "metal"]))
    assert m.constituents == ("ceramic", "metal") and m.parameters == {} and m.source is None
    m.check()
    bad = Model(name="m", domain=make_domain(outer),
                material=AnalyticField({"metal": "2*y"}, ["ceramic", "metal"]))
    with pytest.raises(MaterialError, match="^model 'm': material.composition.metal: value 2 at"):
        bad.check()
    with pytest.raises(MaterialError, match="expected a MaterialField"):
        Model(name="m", domain=make_domain(outer), material="metal")


# ----------------------------------------------------------------------------- file errors

def test_missing_file(tmp_path):
    with pytest.raises(ModelFileError, match="^no such model file: .*x.toml$"):
        load_model(tmp_path / "x.toml")


def test_directory(tmp_path):
    with pytest.raises(ModelFileError, match="is a directory"):
        load_model(tmp_path)


def test_not_utf8(tmp_path):
    p = tmp_path / "m.toml"
    p.write_bytes(b"[model]\nname = '\xff'\n")
    with pytest.raises(ModelFileError, match=r"m.toml: not UTF-8 text \(byte 0xff"):
        load_model(p)


def test_not_toml_reports_line_and_column(tmp_path):
    msg = _error(tmp_path, "[model]\nname = 'a'\n[domain]\nouter = {\n", ModelFileError)
    assert "not valid TOML" in msg and "line 4" in msg and "column" in msg


# ----------------------------------------------------------------------------- schema errors

_UNKNOWN = [
    (SQUARE + MATERIAL + "\n[extra]\na = 1\n", "'extra'", "model, parameters"),
    ("[model]\nnam = 'a'\n" + SQUARE + MATERIAL, "'model.nam'", "name, description, units"),
    (SQUARE.replace("path =", "pth =") + MATERIAL, "'domain.outer.pth'",
     "name, start, path, circle"),
    (SQUARE.replace("{ to = [1, 0] }", "{ to = [1, 0], bulge = 1 }") + MATERIAL,
     "'domain.outer.path[0].bulge'", "to, name, through, center, direction"),
    (SQUARE + "[domain.hole]\ncircle = {center=[0.5,0.5], radius=0.1}\n" + MATERIAL,
     "'domain.hole'", "outer, holes, interfaces, points"),
    ("[domain.outer]\ncircle = { center = [0, 0], r = 1 }\n" + MATERIAL,
     "'domain.outer.circle.r'", "center, radius"),
    (SQUARE + MATERIAL + "steel = 'x'\n", "'material.composition.steel'", "ceramic, metal"),
    (SQUARE + MATERIAL.replace("[material]", "[material]\nkind = 1"), "'material.kind'",
     "constituents, composition"),
]


@pytest.mark.parametrize("text, key, expected", _UNKNOWN)
def test_unknown_keys(tmp_path, text, key, expected):
    msg = _error(tmp_path, text, ModelFileError)
    assert f"unknown key {key}" in msg and expected in msg


@pytest.mark.parametrize("text, key", [
    (MATERIAL, "'domain'"),
    (SQUARE, "'material'"),
    (SQUARE + "[material]\nconstituents = ['a', 'b']\n", "'material.composition'"),
    (SQUARE + "[material]\n[material.composition]\nb = 'x'\n", "'material.constituents'"),
    ("[domain.outer]\nstart = [0, 0]\n" + MATERIAL, "'domain.outer.path'"),
    ("[domain.outer]\nname = 'o'\n" + MATERIAL, "'domain.outer.start'"),
    (SQUARE.replace("{ to = [1, 0] }", "{ name = 'b' }") + MATERIAL, "'domain.outer.path[0].to'"),
    ("[domain]\n" + MATERIAL, "'domain.outer'"),
    (SQUARE + "[material]\nconstituents = ['a', 'b', 'c']\n[material.composition]\na = 'x/3'\n",
     "'material.composition."),
])
def test_missing_keys(tmp_path, text, key):
    msg = _error(tmp_path, text, ModelFileError)
    assert f"missing key {key}" in msg


_WRONG_TYPES = [
    ("[parameters]\nb = true\n" + SQUARE + MATERIAL, "parameters.b: expected a number"),
    ("[parameters]\nb = 'x'\n" + SQUARE + MATERIAL, "parameters.b: expected a number"),
    ("[parameters]\nb = inf\n" + SQUARE + MATERIAL, "parameters.b: expected a finite number"),
    ("[parameters]\nb = nan\n" + SQUARE + MATERIAL, "parameters.b: expected a finite number"),
    ("[model]\nname = 3\n" + SQUARE + MATERIAL, "model.name: expected a string"),
    ("model = 3\n" + SQUARE + MATERIAL, "model: expected a table"),
    (SQUARE.replace("start = [0, 0]", "start = [0, true]") + MATERIAL,
     "domain.outer.start: expected a point [x, y] of 2 finite numbers"),
    (SQUARE.replace("start = [0, 0]", "start = [0, 0, 0]") + MATERIAL,
     "domain.outer.start: expected a point"),
    (SQUARE.replace("start = [0, 0]", "start = [0, nan]") + MATERIAL,
     "domain.outer.start: expected a point"),
    (SQUARE.replace("start = [0, 0]", "start = '0, 0'") + MATERIAL,
     "domain.outer.start: expected a point"),
    (SQUARE.replace("{ to = [1, 1] }", "{ to = [1, '1'] }") + MATERIAL,
     "domain.outer.path[1].to: expected a point"),
    (SQUARE.replace("path = [", "path = [3, ") + MATERIAL,
     "domain.outer.path[0]: expected a table"),
    (SQUARE.replace("path = [", "path = [] #") + MATERIAL, "domain.outer.path: expected a "
                                                           "non-empty array"),
    ("[domain.outer]\ncircle = { center = [0, 0], radius = true }\n" + MATERIAL,
     "domain.outer.circle.radius: expected a number"),
    ("[domain.outer]\ncircle = { center = [0, 0], radius = 0 }\n" + MATERIAL,
     "domain.outer.circle.radius: expected a positive number"),
    ("[domain.outer]\ncircle = { center = [0, 0], radius = -2 }\n" + MATERIAL,
     "domain.outer.circle.radius: expected a positive number"),
    ("[domain.outer]\ncircle = 3\n" + MATERIAL, "domain.outer.circle: expected a table"),
    (SQUARE + "[domain.points]\nP = [0.5]\n" + MATERIAL, "domain.points.P: expected a point"),
    (SQUARE + "[domain]\nholes = 3\n" + MATERIAL, None),  # TOML itself rejects the re-open
    (SQUARE.replace("[domain.outer]", "[domain]\nholes = 3\n[domain.outer]") + MATERIAL,
     "domain.holes: expected an array of tables"),
    (SQUARE + MATERIAL.replace('["ceramic", "metal"]', '"ceramic, metal"'),
     "material.constituents: expected an array of names"),
    (SQUARE + MATERIAL.replace('["ceramic", "metal"]', '["ceramic", 2]'),
     "material.constituents: expected an array of names"),
    (SQUARE + MATERIAL.replace('"(1 - y)**2"', "true"),
     "material.composition.metal: expected a formula string"),
    (SQUARE + MATERIAL.replace('"(1 - y)**2"', "['y']"),
     "material.composition.metal: expected a formula string"),
    (SQUARE + "[material]\nconstituents = ['a', 'b']\ncomposition = 'y'\n",
     "material.composition: expected a table"),
    ("[model]\nname = ''\n" + SQUARE.replace("[domain.outer]", "[domain.outer]\nname = ''")
     + MATERIAL, "domain.outer.name: expected a non-empty name"),
]


@pytest.mark.parametrize("text, expected", _WRONG_TYPES)
def test_wrong_types(tmp_path, text, expected):
    msg = _error(tmp_path, text, ModelFileError)
    if expected is not None:
        assert expected in msg


@pytest.mark.parametrize("name", ["x", "y", "pi", "e", "sin", "exp", "where", "min", "lambda",
                                  "_b", "1b", "a b"])
def test_reserved_or_invalid_parameter_names(tmp_path, name):
    msg = _error(tmp_path, f'[parameters]\n"{name}" = 1.0\n' + SQUARE + MATERIAL,
                 ModelFileError)
    assert f"parameters.{name}:" in msg


@pytest.mark.parametrize("constituents, expected", [
    ('["ceramic", "ceramic"]', "material.constituents: constituent 'ceramic' is listed twice"),
    ('["metal"]', "material.constituents: at least 2 constituents are needed, got 1"),
    ("[]", "material.constituents: at least 2"),
    ('["metal", ""]', "material.constituents: names must be non-empty"),
])
def test_bad_constituents(tmp_path, constituents, expected):
    text = SQUARE + MATERIAL.replace('["ceramic", "metal"]', constituents)
    assert expected in _error(tmp_path, text, ModelFileError)


def test_parameters_in_formulas_only(tmp_path):
    text = "[parameters]\nb = 1\n" + SQUARE.replace("start = [0, 0]", "start = ['b', 0]") \
        + MATERIAL
    assert "domain.outer.start: expected a point" in _error(tmp_path, text, ModelFileError)


def test_arc_step_conflicts(tmp_path):
    both = SQUARE.replace("{ to = [1, 1] }", "{ to = [1, 1], through = [2, 0.5], "
                                             "center = [1, 0.5] }") + MATERIAL
    assert "domain.outer.path[1]: give either 'through' or 'center'" in \
        _error(tmp_path, both, ModelFileError)
    lone = SQUARE.replace("{ to = [1, 1] }", "{ to = [1, 1], direction = 'cw' }") + MATERIAL
    assert "domain.outer.path[1].direction: only an arc given by 'center'" in \
        _error(tmp_path, lone, ModelFileError)
    bad = SQUARE.replace("{ to = [1, 1] }", "{ to = [1, 1], center = [1, 0.5], "
                                            "direction = 'left' }") + MATERIAL
    assert "domain.outer.path[1].direction: expected \"ccw\" or \"cw\", got 'left'" in \
        _error(tmp_path, bad, ModelFileError)
    both_forms = "[domain.outer]\ncircle = {center=[0,0], radius=1}\nstart = [0, 0]\n" \
        "path = [{to=[1,1]}]\n" + MATERIAL
    assert "domain.outer: give either 'circle' or 'start' and 'path'" in \
        _error(tmp_path, both_forms, ModelFileError)


def test_duplicate_loop_names(tmp_path):
    text = SQUARE + """
[[domain.holes]]
name = "outer"
circle = { center = [0.5, 0.5], radius = 0.1 }
""" + MATERIAL
    msg = _error(tmp_path, text, ModelFileError)
    assert "domain.holes[0].name: name 'outer' is already used by domain.outer" in msg


def test_unknown_material_type(tmp_path):
    text = SQUARE + MATERIAL.replace("[material]", "[material]\ntype = 'magic'")
    assert "material.type: unknown material type 'magic'" in _error(tmp_path, text,
                                                                    ModelFileError)


# ----------------------------------------------------------------------------- geometry errors

_GEOMETRY = [
    (SQUARE.replace("{ to = [0, 0] }", "{ to = [0, 0.5] }"),
     "domain.outer.path[3].to: a closed loop must end at its start (0, 0), not at (0, 0.5)"),
    (SQUARE.replace("{ to = [1, 1] }", "{ to = [1, 1], center = [0.5, 0.2] }"),
     "domain.outer.path[1]: arc end point (1, 1) is not on its circle"),
    (SQUARE.replace("{ to = [1, 1] }", "{ to = [1, 1], through = [1, 0.5] }"),
     "domain.outer.path[1]: arc points (1, 0), (1, 0.5), (1, 1) are collinear"),
    (SQUARE.replace("{ to = [1, 1] }", "{ to = [1, 0] }, { to = [1, 1] }"),
     "domain.outer.path[1].to: zero-length segment"),
    (SQUARE.replace("[1, 0] }, { to = [1, 1] }, { to = [0, 1] }",
                    "[2, 0] }, { to = [0, 1] }, { to = [1, 1] }"),
     "domain.outer: outer: the boundary intersects itself"),
    (SQUARE + "[[domain.holes]]\ncircle = { center = [2, 2], radius = 0.1 }\n",
     "domain.holes[0]: hole[0]: not strictly inside outer"),
    (SQUARE + "[[domain.holes]]\nname = 'H'\ncircle = { center = [0.5, 0.5], radius = 0.6 }\n",
     "domain.holes[0]: H: not strictly inside outer"),
    (SQUARE + "[[domain.interfaces]]\nstart = [0.5, 0.5]\npath = [{ to = [1.5, 0.5] }]\n",
     "domain.interfaces[0]: interface[0]: touches or crosses the boundary outer"),
    (SQUARE + "[domain.points]\nP = [2, 2]\n",
     "domain.points.P: point 'P' at (2, 2) is not inside the domain"),
]


@pytest.mark.parametrize("text, expected", _GEOMETRY)
def test_geometry_errors(tmp_path, text, expected):
    msg = _error(tmp_path, text + MATERIAL, GeometryError)
    assert expected in msg


# ----------------------------------------------------------------------------- formulas, material

@pytest.mark.parametrize("formula, expected", [
    ("z", "material.composition.metal: unknown name 'z'"),
    ("(1 - y", "material.composition.metal:"),
    ("__import__('os')", "material.composition.metal:"),
    ("y^2", "material.composition.metal:"),
])
def test_formula_errors(tmp_path, formula, expected):
    text = SQUARE + MATERIAL.replace('"(1 - y)**2"', repr(formula))
    assert expected in _error(tmp_path, text, FormulaError)


def test_formula_out_of_range_names_coordinate(tmp_path):
    text = """
[parameters]
b = 30
[domain.outer]
start = [0, -6]
path = [{ to = [1, -6] }, { to = [1, 0] }, { to = [0, 0] }, { to = [0, -6] }]
[material]
constituents = ["ceramic", "metal"]
[material.composition]
metal = "((b - y)/b)**2"
"""
    msg = _error(tmp_path, text, MaterialError)
    assert msg.endswith("m.toml: material.composition.metal: value 1.44 at (0, -6) "
                        "is outside [0, 1]")


def test_formulas_not_summing_to_one(tmp_path):
    text = SQUARE + """
[material]
constituents = ["a", "b", "c"]
[material.composition]
a = "x/2"
b = "y/2"
c = "0.7"
"""
    msg = _error(tmp_path, text, MaterialError)
    assert "material.composition: fractions sum to 1.7, not 1, at (1, 1) (a 0.5, b 0.5, c 0.7)" \
        in msg


def test_derived_constituent_out_of_range_blames_given_formula(tmp_path):
    text = SQUARE + MATERIAL.replace('"(1 - y)**2"', '"0.5 + y"')
    msg = _error(tmp_path, text, MaterialError)
    assert "material.composition.metal: value 1.5 at" in msg
