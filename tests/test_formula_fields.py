"""Formula models with kinks, infinite slopes and jumps: loaded, meshed end to end, verified.

Distance-type fields (to a corner, a point, ``abs(x - c)``) have kinks where the exact
derivative is undefined; power-law profiles such as ``sqrt(x)`` have infinite slopes at an
edge; ``where``/``sign`` formulas jump along curves, which hetmesh finds and embeds in the
mesh like a feature tree's discontinuities.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

import hetmesh
import hetmesh.io.read
from conftest import check_invariants
from hetmesh.cli import main
from hetmesh.errors import MaterialError, MeshingError
from hetmesh.io.model import Model, load_model
from hetmesh.material import AnalyticField, has_subregions
from hetmesh.tri.geometry import Loop, Segment, make_domain

THRESHOLD = 0.1

L_BRACKET = """
[parameters]
s = 2.0

[domain.outer]
start = [0, 0]
path = [{ to = [10, 0] }, { to = [10, 4] }, { to = [4, 4] }, { to = [4, 10] },
        { to = [0, 10] }, { to = [0, 0] }]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
ceramic = "exp(-sqrt((x - 4)**2 + (y - 4)**2)/s)"
"""

UNIT_SQUARE = """
[domain.outer]
start = [0, 0]
path = [{{ to = [1, 0] }}, {{ to = [1, 1] }}, {{ to = [0, 1] }}, {{ to = [0, 0] }}]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""

#: jumps written as formulas, each with the subregion ids its mesh must show
JUMPS = {
    "step": ("where(x < 0.5, 0.2, 0.8)", [0, 1]),
    "inclusion": ("where((x-0.5)**2 + (y-0.5)**2 < 0.09, 0.1, 0.9)", [0, 1]),
    "graded": ("where(y < 0.4, 0.5*y, 0.3 + 0.5*y)", [0, 1]),
    "two": ("where(x < 0.5, 0.2, 0.6) + where(y < 0.3, 0.0, 0.3)", [0, 1, 2, 3]),
    "and": ("where(x < 0.5 and y < 0.5, 0.2, 0.8)", [0, 1, 2, 3]),
    "if_else": ("0.1 + 0.8*x if x + y < 1 else 0.9 - 0.5*y", [0, 1]),
    "sign": ("0.5 + 0.3*sign(x - y)", [0, 1]),
}


def write(tmp_path, text: str, name: str = "m.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def square(tmp_path, formula: str, name: str = "m.toml"):
    return write(tmp_path, UNIT_SQUARE.format(formula=formula), name)


def mesh_cli(path, out, capsys):
    code = main(["mesh", str(path), "--threshold", str(THRESHOLD), "--output", str(out),
                 "--quiet"])
    _, err = capsys.readouterr()
    return code, err


def assert_one_line(err: str, code: int, expected: int = 2) -> str:
    lines = err.strip().splitlines()
    assert code == expected and len(lines) == 1, (code, err)
    assert lines[0].startswith("hetmesh: error:") and "Traceback" not in err
    return lines[0]


# ------------------------------------------------------------------------------- kinks
def test_kinked_distance_field_loads_and_meshes(tmp_path, capsys):
    path = write(tmp_path, L_BRACKET, "bracket.toml")
    model = load_model(path)  # the cone's tip at the re-entrant corner is not an error
    g = model.material.gradient(np.array([[4.0, 4.0], [4.0, 4.5]]))
    assert np.isfinite(g).all()
    result = hetmesh.generate(model, THRESHOLD)
    check_invariants(result, model, THRESHOLD)
    assert not has_subregions(model.material)
    code, err = mesh_cli(path, tmp_path / "bracket.vtu", capsys)
    assert code == 0 and err == "" and (tmp_path / "bracket.vtu").exists()


@pytest.mark.parametrize("formula", ["abs(x - 0.5)", "sqrt((x - 0.5)**2 + (y - 0.5)**2)",
                                     "min(x, y)", "1 - max(abs(x - 0.5), abs(y - 0.5))"])
def test_distance_type_fields_mesh(tmp_path, formula):
    model = load_model(square(tmp_path, formula))
    result = hetmesh.generate(model, THRESHOLD)
    check_invariants(result, model, THRESHOLD)


# --------------------------------------------------------------------- infinite slopes
def test_square_root_profile_meshes(tmp_path, capsys):
    """A power-law FGM profile with exponent 1/2: |grad f| = inf on the edge x = 0."""
    path = square(tmp_path, "sqrt(x)")
    model = load_model(path)
    edge = np.column_stack([np.zeros(5), np.linspace(0, 1, 5)])
    g = model.material.gradient(edge)
    assert np.isfinite(g).all() and np.all(g[:, 1, 0] > 0)  # one-sided, pointing into x > 0
    t0 = time.perf_counter()
    result = hetmesh.generate(model, THRESHOLD)
    assert time.perf_counter() - t0 < 30
    check_invariants(result, model, THRESHOLD)
    code, err = mesh_cli(path, tmp_path / "sqrt.vtu", capsys)
    assert code == 0, err


def test_power_overflowing_to_a_jump_is_reported_at_load(tmp_path, capsys):
    """``x**1e308`` is 0 everywhere in the square except on the edge x = 1, where it is 1: a
    jump no mesh can follow (every element touching that edge spans it). Its exact gradient,
    1e308 there, no longer reaches the mesher: the load fails with the key and the place."""
    path = square(tmp_path, "x**1e308")
    t0 = time.perf_counter()
    with pytest.raises(MaterialError) as info:
        load_model(path)
    assert time.perf_counter() - t0 < 5
    msg = str(info.value)
    assert "material.composition.metal: value jumps from 0 to 1 within 1.41421e-09 of (1, " \
        in msg
    assert "where" in msg and "\n" not in msg
    code, err = mesh_cli(path, tmp_path / "pow.vtu", capsys)
    line = assert_one_line(err, code)
    assert "material.composition.metal" in line and not (tmp_path / "pow.vtu").exists()


@pytest.mark.parametrize("formula", ["sqrt(x/L)", "exp(-sqrt((x - 0.4*L)**2 + y**2)/L)",
                                     "where(x < 0.5*L, 0.2, 0.8) + where(y < 0.3*L, 0, 0.1)"])
def test_singular_and_piecewise_fields_mesh_the_same_at_any_scale(formula):
    """With the domain's diameter as the field's length, the finite differences at kinks and
    infinite slopes scale with the model: a model scaled by 2**-200 meshes bit-identically."""
    def run(size):
        sq = [(0, 0), (size, 0), (size, size), (0, size)]
        domain = make_domain(Loop(tuple(Segment(a, b) for a, b in zip(sq, sq[1:] + sq[:1])),
                                  "outer"))
        field = AnalyticField({"metal": formula}, ["ceramic", "metal"], {"L": size},
                              length=domain.diameter)
        return hetmesh.generate(Model(name="m", domain=domain, material=field), THRESHOLD)

    s = 2.0 ** -200
    a, b = run(1.0), run(s)
    np.testing.assert_array_equal(a.mesh.triangles, b.mesh.triangles)
    np.testing.assert_array_equal(a.mesh.points * s, b.mesh.points)


def test_gradient_is_finite_where_the_composition_is(tmp_path):
    f = AnalyticField({"metal": "sqrt(x)"}, ["ceramic", "metal"], length=1.0)
    p = np.array([[0.0, 0.3], [0.25, 0.3], [1e-300, 0.0]])
    g = f.gradient(p)
    assert np.isfinite(g).all()
    assert g[1, 1, 0] == 1.0  # exact where the derivative exists
    np.testing.assert_allclose(g[0, 1, 0], 1 / np.sqrt(1e-2), rtol=1e-12)  # one-sided
    np.testing.assert_array_equal(g[:, 0], -g[:, 1])


# ------------------------------------------------------------------------------- jumps
@pytest.mark.parametrize("name", sorted(JUMPS))
def test_jump_formulas_mesh_with_embedded_discontinuities(tmp_path, name):
    formula, regions = JUMPS[name]
    model = load_model(square(tmp_path, formula))
    assert has_subregions(model.material)
    t0 = time.perf_counter()
    result = hetmesh.generate(model, THRESHOLD)
    seconds = time.perf_counter() - t0
    assert seconds < 20, seconds
    check_invariants(result, model, THRESHOLD)  # incl. no element crossing a jump
    sub = result.mesh.cell_data["subregion"]
    assert sorted(np.unique(sub).tolist()) == regions
    assert any(p.name.startswith("discontinuity[") for p in result.model.domain.interfaces)
    # every element is one side's: its centroid's conditions
    tri = result.mesh.points[result.mesh.triangles].mean(axis=1)
    np.testing.assert_array_equal(model.material.region(tri), sub)


def test_jump_through_a_re_entrant_corner(tmp_path):
    text = L_BRACKET.replace('ceramic = "exp(-sqrt((x - 4)**2 + (y - 4)**2)/s)"',
                             'ceramic = "where(x + y < 8, 0.2, 0.8)"')
    model = load_model(write(tmp_path, text))
    result = hetmesh.generate(model, THRESHOLD)
    check_invariants(result, model, THRESHOLD)
    assert np.unique(result.mesh.cell_data["subregion"]).tolist() == [0, 1]


def test_jump_with_grading_uses_each_side_at_the_jump(tmp_path):
    """Vertices on y = 0.4 count once per side: 0.2 below, 0.5 above."""
    model = load_model(square(tmp_path, JUMPS["graded"][0]))
    result = hetmesh.generate(model, THRESHOLD)
    mesh, field = result.mesh, model.material
    on = np.flatnonzero(np.abs(mesh.points[:, 1] - 0.4) < 1e-9)
    assert len(on) >= 2
    p = mesh.points[on]
    np.testing.assert_allclose(field.composition(p, region=0)[:, 1], 0.3 + 0.5 * p[:, 1])
    np.testing.assert_allclose(field.composition(p, region=1)[:, 1], 0.5 * p[:, 1])


def test_jump_meshes_are_deterministic(tmp_path):
    model = load_model(square(tmp_path, JUMPS["two"][0]))
    a = hetmesh.generate(model, THRESHOLD)
    b = hetmesh.generate(load_model(square(tmp_path, JUMPS["two"][0], "n.toml")), THRESHOLD)
    np.testing.assert_array_equal(a.mesh.points, b.mesh.points)
    np.testing.assert_array_equal(a.mesh.triangles, b.mesh.triangles)
    np.testing.assert_array_equal(a.mesh.cell_data["subregion"], b.mesh.cell_data["subregion"])


@pytest.mark.parametrize("name", ["step", "inclusion", "graded", "two", "sign"])
def test_jump_formulas_from_the_command_line(tmp_path, capsys, name):
    path = square(tmp_path, JUMPS[name][0])
    out = tmp_path / "m.vtu"
    code, err = mesh_cli(path, out, capsys)
    assert code == 0 and err == "", err
    mesh = hetmesh.io.read.read_mesh(out)
    assert "subregion" in mesh.cell_data


@pytest.mark.parametrize("formula, contains", [
    ("where(sin(2000*x) > 0, 0.2, 0.8)", "too many pieces"),
    ("where(sin(1/(x + 0.001)) > 0, 0.2, 0.8)", "narrower than the tracing grid"),
])
def test_jumps_that_cannot_be_embedded_fail_fast(tmp_path, capsys, formula, contains):
    path = square(tmp_path, formula)
    model = load_model(path)
    t0 = time.perf_counter()
    with pytest.raises(MaterialError) as info:
        hetmesh.generate(model, THRESHOLD)
    assert time.perf_counter() - t0 < 10
    msg = str(info.value)
    assert msg.startswith(f"{path}: material.composition.metal: condition ")
    assert "the jump near (" in msg and contains in msg and "\n" not in msg
    code, err = mesh_cli(path, tmp_path / "m.vtu", capsys)
    line = assert_one_line(err, code)
    assert "material.composition.metal" in line and not (tmp_path / "m.vtu").exists()


def test_jump_curves_that_cannot_be_embedded_name_the_formula(tmp_path):
    """Two jumps 1e-7 apart: their traced curves touch; the error names key and place."""
    model = load_model(square(tmp_path, "where(x < 0.5, 0.2, 0.6) + where(x < 0.5000001, "
                                        "0.0, 0.1)"))
    with pytest.raises((MaterialError, MeshingError)) as info:
        hetmesh.generate(model, THRESHOLD)
    msg = str(info.value)
    assert "material.composition.metal: condition 'x < 0.5" in msg and "(0.5, " in msg


def test_too_many_conditions():
    formula = " + ".join(f"where(x < {k / 30}, 0.01, 0)" for k in range(1, 27))
    with pytest.raises(MaterialError, match=r"^m\.toml: material\.composition\.metal: the "
                                            r"formulas have 26 jump conditions"):
        AnalyticField({"metal": formula}, ["ceramic", "metal"], where="m.toml")


# ------------------------------------------------------------------------ finite values
@pytest.mark.parametrize("formula, at", [("sqrt(x - 0.5)", "(0.00502513, 0.00502513)"),
                                         ("where(x < 0.5, 0.2, log(x - 0.5))", "(0.5, 0)")])
def test_non_finite_composition_is_one_clear_error(tmp_path, capsys, formula, at):
    path = square(tmp_path, formula)
    with pytest.raises(MaterialError) as info:
        load_model(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: material.composition.metal: value ")
    assert f"at {at} is not finite" in msg and "\n" not in msg
    code, err = mesh_cli(path, tmp_path / "m.vtu", capsys)
    line = assert_one_line(err, code)
    assert "is not finite" in line
