"""3D model files, the CLI on solids, every 3D example, the writers' round trips."""

from __future__ import annotations

import json
import re
from pathlib import Path

import meshio
import numpy as np
import pytest

import hetmesh
from conftest import EXAMPLES_3D
from hetmesh.cli import main
from hetmesh.errors import FormulaError, GeometryError, ModelFileError
from hetmesh.io.model import load_model
from hetmesh.tet.api import mesh_model
from hetmesh.tet.mesher import CHORD
from hetmesh.tet.revolve import Revolution
from test_tet import check_tet_mesh

CUBE = """
[model]
name = "cube"

[solid]
type = "box"
min = [0, 0, 0]
max = [1, 1, 1]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "(1 - z)**2"
"""

SOLID_ONLY = """
[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""


def write(tmp_path, text, name="m.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_the_3d_examples_exist():
    names = {p.stem for p in EXAMPLES_3D}
    assert {"unit_cube", "graded_rod", "graded_cylinder", "fgm_plate_3d", "blade_3d",
            "graded_ring", "graded_sphere"} <= names


#: the examples meshed in the default run; the others (larger at any threshold) run with -m slow
FAST_3D = ("unit_cube", "graded_rod", "seamed_plate_z", "coated_rod")


@pytest.mark.parametrize("path", [p if p.stem in FAST_3D else
                                  pytest.param(p, marks=pytest.mark.slow)
                                  for p in EXAMPLES_3D], ids=lambda p: p.stem)
def test_every_3d_example_meets_the_guarantee(path):
    m = load_model(path)
    assert m.dim == 3 and m.name == path.stem
    check_model_mesh(m, 0.3)


def test_revolved_feature_tree_keeps_its_subregions(tmp_path):
    import hetmesh as hm
    text = hm.example_path("fgm_plate_3d").read_text(encoding="utf-8").replace(
        'type = "extrusion"\nlength = 10', 'type = "revolution"\nangle = 30')
    text = text.split("\n[fea]")[0]  # its conditions name the extrusion's end faces
    m = load_model(write(tmp_path, text, "plate_turned.toml"))
    res = check_model_mesh(m, 0.3)
    assert res.info["placement"] == "revolved"
    assert len(np.unique(res.info["regions"])) >= 3


def check_model_mesh(m, d0):
    """Mesh ``m`` at ``d0`` and check it independently (subregions: each element's
    vertices evaluated in its own subregion)."""
    res = mesh_model(m, d0)
    comp = m.material.composition
    faces = None
    for j in range(len(m.constituents)):
        if "regions" in res.info:
            # vertices on a material discontinuity take their element's side
            f2, q = m.material2d, res.points[res.tets].reshape(-1, 3)
            if f2 is None:  # a piecewise formula varying along the sweep: the 3D field's
                f2 = m.material
            else:
                q, _ = m.solid.to2d(q)
            c = f2.composition(q, region=np.repeat(res.info["regions"], 4))[:, j]
            c = c.reshape(-1, 4)
            assert (c.max(axis=1) - c.min(axis=1)).max() < d0
            func = lambda p: np.zeros(len(p))  # noqa: E731  (checked just above)
        else:
            func = lambda p, j=j: comp(p)[:, j]  # noqa: E731
        lo, hi = m.solid.bounds
        box = (lo, hi) if m.solid.face_names[2:] == ("ymin", "xmax", "ymax", "xmin") else None
        faces = check_tet_mesh(res.points, res.tets, func, d0, box_bounds=box)
    # the boundary: every triangle on a face of the solid, the caps' area exact (the
    # interface triangles of an extruded or revolved domain come after the boundary's)
    dom = getattr(m.solid, "section", None) or getattr(m.solid, "profile", None)
    inter = np.zeros(len(res.faces), bool)
    if dom is not None:
        kinds = ["", ""] + [c.kind for c in dom.curves]  # then the discontinuities'
        kinds = np.array(kinds + ["interface"] * (len(res.face_names) - len(kinds)))
        inter = kinds[res.face_markers - 1] == "interface"
    assert len(faces) == len(res.faces) - int(inter.sum())
    assert not inter[:len(faces)].any()
    assert (res.face_markers >= 1).all()
    if isinstance(m.solid, Revolution):
        check_revolution(m.solid, res.points, res.tets, faces)
        return res
    if not hasattr(m.solid, "section"):  # a solid of primitives: tests/test_tet_solids.py
        return res
    area = 0.5 * np.linalg.norm(np.cross(*(res.points[res.faces[:, k]]
                                           - res.points[res.faces[:, 0]] for k in (1, 2))),
                                axis=1)
    cap = area[res.face_markers == 1].sum()
    # chords of arcs within the default chord tolerance: the area is off by at most
    # (arc length x tolerance)
    arcs = sum(c.curve.length for c in m.solid.section.curves if hasattr(c.curve, "radius"))
    assert abs(cap - m.solid.section.area) <= arcs * CHORD * m.solid.diameter + 1e-9 * cap
    return res


def check_revolution(solid, points, tets, faces):
    """Boundary vertices on the profile's curves, volume within the chord tolerance."""
    if not solid.full:  # triangles on the planar ends (angle 0 and the sweep) aside
        t = solid.sweep
        tol = 1e-9 * solid.diameter
        on0 = np.abs(points[faces][..., 1]) <= tol
        on1 = np.abs(-np.sin(t) * points[faces][..., 0]
                     + np.cos(t) * points[faces][..., 1]) <= tol
        faces = faces[~(on0.all(axis=1) | on1.all(axis=1))]
    p = points[np.unique(faces)]
    q = np.column_stack([np.hypot(p[:, 0], p[:, 1]), p[:, 2]])
    assert solid.profile.distance_to_boundary(q).max() <= 1e-9 * solid.diameter
    a, b, c, d = (points[tets[:, k]] for k in range(4))
    vol = np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)).sum() / 6.0
    perim = sum(cv.curve.length for cv in solid.profile.curves)
    bound = CHORD * solid.diameter * perim * solid.sweep * float(np.abs(q[:, 0]).max())
    assert abs(vol - solid.volume) <= bound + 1e-9 * solid.volume


SPHERE = """
[solid]
type = "revolution"
angle = {angle}

[domain.outer]
start = [0, -1]
path = [{{ to = [0, 1], name = "axis" }},
        {{ to = [0, -1], center = [0, 0], direction = "cw", name = "surface" }}]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "x**2 + y**2 + z**2"
"""


@pytest.mark.parametrize("angle", [360, 90])
def test_graded_sphere(tmp_path, angle):
    m = load_model(write(tmp_path, SPHERE.format(angle=angle)))
    res = mesh_model(m, 0.25, chord_tol=0.01)
    assert res.info["placement"] == "revolved"
    faces = check_tet_mesh(res.points, res.tets, lambda p: (p ** 2).sum(axis=1), 0.25)
    check_revolution(m.solid, res.points, res.tets, faces)
    names = {res.face_names[k - 1] for k in res.face_markers}
    assert names == ({"surface"} if angle == 360 else {"surface", "start", "end"})


@pytest.mark.parametrize("snippet, contains", [
    ('angle = 0', "revolution angle must be in (0, 360]"),
    ('angle = 400', "revolution angle must be in (0, 360]"),
])
def test_bad_revolutions(tmp_path, snippet, contains):
    text = SPHERE.format(angle=360).replace("angle = 360", snippet)
    with pytest.raises(GeometryError, match=re.escape(contains)):
        load_model(write(tmp_path, text))


def test_revolution_profile_crossing_the_axis(tmp_path):
    text = ('[solid]\ntype = "revolution"\n[domain.outer]\nstart = [-0.5, 0]\n'
            'path = [{ to = [1, 0] }, { to = [1, 1] }, { to = [-0.5, 1] }, { to = [-0.5, 0] }]\n'
            + SOLID_ONLY.format(formula="z"))
    with pytest.raises(GeometryError, match="crosses the axis") as e:
        load_model(write(tmp_path, text))
    assert "\n" not in str(e.value)


@pytest.mark.slow
def test_deterministic_swept():
    m = load_model(hetmesh.example_path("fgm_plate_3d"))
    a, b = mesh_model(m, 0.3), mesh_model(m, 0.3)
    assert a.points.tobytes() == b.points.tobytes() and a.tets.tobytes() == b.tets.tobytes()


@pytest.mark.parametrize("snippet, cls, contains", [
    ('[solid]\ntype = "box"\nmin = [0, 0, 0]\nmax = [1, 0, 1]\n', GeometryError,
     "size must be positive"),
    ('[solid]\ntype = "cylinder"\ncenter = [0, 0]\nradius = -1\nfrom = 0\nto = 1\n',
     GeometryError, "radius"),
    ('[solid]\ntype = "extrusion"\nlength = 0\n[domain.outer]\nstart = [0, 0]\n'
     'path = [{ to = [1, 0] }, { to = [1, 1] }, { to = [0, 0] }]\n', GeometryError,
     "extrusion length must be positive"),
    ('[solid]\ntype = "torus"\n', ModelFileError, "solid.type"),
    ('[solid]\ntype = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n'
     '[[solid.subtract]]\ntype = "box"\nmin = [-1, -1, -1]\nmax = [2, 2, 2]\n',
     GeometryError, "solid.subtract"),
])
def test_bad_solids(tmp_path, snippet, cls, contains):
    p = write(tmp_path, snippet + SOLID_ONLY.format(formula="z"))
    with pytest.raises(cls, match=contains) as e:
        load_model(p)
    assert str(e.value).startswith(str(p))
    assert "\n" not in str(e.value)


def test_formula_in_a_missing_variable(tmp_path):
    p = write(tmp_path, CUBE.replace("(1 - z)**2", "w + z"))
    with pytest.raises(FormulaError, match="material.composition.metal"):
        load_model(p)


def test_2d_model_with_z_is_an_error(tmp_path):
    text = ('[domain.outer]\nstart = [0, 0]\npath = [{ to = [1, 0] }, { to = [1, 1] }, '
            '{ to = [0, 0] }]\n' + SOLID_ONLY.format(formula="z"))
    with pytest.raises(FormulaError, match="'z'"):
        load_model(write(tmp_path, text))


def test_through_hole(tmp_path):
    text = CUBE.replace('max = [1, 1, 1]\n', 'max = [1, 1, 1]\n\n[[solid.subtract]]\n'
                        'type = "cylinder"\ncenter = [0.5, 0.5]\nradius = 0.2\n')
    m = load_model(write(tmp_path, text))
    assert m.solid.volume == pytest.approx(1 - np.pi * 0.04)
    res = mesh_model(m, 0.3)
    assert res.info["placement"] == "swept+repair"
    check_tet_mesh(res.points, res.tets, lambda p: (1 - p[:, 2]) ** 2, 0.3)


@pytest.mark.parametrize("ext, fmt", [(".vtu", None), (".vtk", None), (".msh", None),
                                      (".msh", "gmsh22"), (".xdmf", None), (".inp", None),
                                      (".mesh", None)])
def test_cli_writes_and_reads_back(tmp_path, capsys, ext, fmt):
    model = write(tmp_path, CUBE, "cube.toml")
    out = tmp_path / f"cube{ext}"
    argv = ["mesh", model, "--threshold", 0.3, "--output", out, "--quiet"]
    if fmt:
        argv += ["--format", fmt]
    code, o, err = run(argv, capsys)
    assert code == 0, err
    if ext == ".xdmf":  # dolfinx's layout: mesh, cell_tags and facet_tags grids
        from hetmesh.io.xdmf import read_xdmf
        from hetmesh.mesh import Mesh
        hm = Mesh(**read_xdmf(out))
        m = meshio.Mesh(hm.points, [("tetra", hm.cells)], field_data={
            n: None for n in hm.marker_names.values()})
        assert set(hm.marker_names.values()) == {"xmin", "xmax", "ymin", "ymax", "zmin",
                                                 "zmax"}
        assert hm.point_data["metal"].shape == (len(hm.points),)
    else:
        m = meshio.read(out)
    tets = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
    res = mesh_model(load_model(model), 0.3)
    assert len(tets) == len(res.tets)
    # the same points (Gmsh 4.1 orders them by entity; text formats round the last digit)
    a = m.points[np.lexsort(m.points.T[::-1])]
    b = res.points[np.lexsort(res.points.T[::-1])]
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)
    check_tet_mesh(m.points, tets, lambda p: (1 - p[:, 2]) ** 2, 0.3,
                   box_bounds=((0, 0, 0), (1, 1, 1)))
    if ext == ".msh":
        names = set(m.field_data)
        assert {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax", "solid"} <= names
    if ext == ".inp":
        text = out.read_text()
        assert "TYPE=C3D4" in text and "*SURFACE, NAME=ZMIN" in text


def test_cli_plot_and_stats(tmp_path, capsys):
    model = write(tmp_path, CUBE, "cube.toml")
    code, o, err = run(["mesh", model, "--threshold", 0.2, "--output", tmp_path / "c.vtu",
                        "--plot", tmp_path / "c.png", "--stats", tmp_path / "c.json"], capsys)
    assert code == 0, err
    assert (tmp_path / "c.png").stat().st_size > 1000
    doc = json.loads((tmp_path / "c.json").read_text())
    assert doc["stats"]["delta_max"] < 0.2
    assert sum(doc["delta_histogram"]) == doc["stats"]["n_elements"]
    assert "tetrahedra" in o


@pytest.mark.parametrize("extra, contains", [
    (["--method", "cvt"], "--method is not available for 3D models"),
    (["--sampling", "voxels"], "--sampling"),
    (["--threshold", "0"], "threshold"),
    (["--threshold", "0.01", "--max-elements", "1000"], "but the budget is 1000"),
])
def test_cli_bad_options_exit_2(tmp_path, capsys, extra, contains):
    model = write(tmp_path, CUBE, "cube.toml")
    argv = ["mesh", model, "--threshold", 0.2, "--output", tmp_path / "c.vtu"] + extra
    code, o, err = run(argv, capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hetmesh: error:") and contains in lines[0]
    assert not (tmp_path / "c.vtu").exists()


def test_cli_bad_model_exit_2(tmp_path, capsys):
    model = write(tmp_path, CUBE.replace("max = [1, 1, 1]", "max = [1, 1, -1]"), "bad.toml")
    code, o, err = run(["mesh", model, "--threshold", 0.2, "--output", tmp_path / "c.vtu"],
                       capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "bad.toml" in lines[0] and "positive" in lines[0]
    assert not (tmp_path / "c.vtu").exists()


def test_cli_unknown_extension_exit_2(tmp_path, capsys):
    model = write(tmp_path, CUBE, "cube.toml")
    code, o, err = run(["mesh", model, "--threshold", 0.2, "--output", tmp_path / "c.stl"],
                       capsys)
    assert code == 2 and "c.stl" in err
    assert not (tmp_path / "c.stl").exists()


def test_cli_stats_of_a_3d_mesh(tmp_path, capsys):
    model = write(tmp_path, CUBE, "cube.toml")
    out = tmp_path / "c.msh"
    assert run(["mesh", model, "--threshold", 0.3, "--output", out, "-q"], capsys)[0] == 0
    code, o, err = run(["stats", out, "--model", model, "--threshold", 0.3, "--json"], capsys)
    assert code == 0, err
    doc = json.loads(o)
    assert doc["delta_max"] < 0.3 and doc["n_over_threshold"] == 0
    assert doc["volume"] == pytest.approx(1.0, rel=1e-12)
    # a mesh that does not fit the model: one line, exit 2
    shifted = CUBE.replace("min = [0, 0, 0]\nmax = [1, 1, 1]", "min = [2, 0, 0]\nmax = [3, 1, 1]")
    other = write(tmp_path, shifted, "other.toml")
    code, o, err = run(["stats", out, "--model", other], capsys)
    assert code == 2 and "outside the solid" in err and len(err.strip().splitlines()) == 1


def test_cli_uniform_3d_refuses_the_2d_options(tmp_path, capsys):
    model = write(tmp_path, CUBE, "cube.toml")
    code, o, err = run(["uniform", model, "--threshold", 0.3, "--output", tmp_path / "u.vtu",
                        "--min-angle", 20], capsys)
    assert code == 2 and "not available for 3D models" in err
    assert not (tmp_path / "u.vtu").exists()
    code, o, err = run(["uniform", model, "--threshold", 0.3, "--output", tmp_path / "u.vtu"],
                       capsys)
    assert code == 0 and (tmp_path / "u.vtu").exists()


def test_max_size_bounds_the_spacing(tmp_path):
    m = load_model(write(tmp_path, CUBE))
    coarse = mesh_model(m, 0.3)
    fine = mesh_model(m, 0.3, max_size=0.1)
    check_tet_mesh(fine.points, fine.tets, lambda p: (1 - p[:, 2]) ** 2, 0.3,
                   box_bounds=((0, 0, 0), (1, 1, 1)))
    assert len(fine.tets) > 4 * len(coarse.tets)
    p, t = fine.points, fine.tets
    e = p[t[:, [0, 1, 2, 0, 1, 2]]] - p[t[:, [1, 2, 3, 3, 3, 3]]]
    assert np.linalg.norm(e, axis=2).max() <= 2.0 * 0.1


CUBE_FEA = CUBE.replace('[model]\nname = "cube"', '[model]\nname = "cube"\nunits = "mm"') + """
[fea.properties.ceramic]
conductivity = 35.0
youngs_modulus = 393e9
poisson_ratio = 0.25
expansion = 7.4e-6

[fea.properties.metal]
conductivity = 90.7
youngs_modulus = 199.5e9
poisson_ratio = 0.3
expansion = 15.4e-6

[[fea.temperature]]
faces = ["zmin"]
value = 1000.0

[[fea.temperature]]
faces = ["zmax"]
value = 300.0

[[fea.displacement]]
faces = ["zmin"]
ux = 0
uy = 0
uz = 0
"""


@pytest.mark.parametrize("ext", [".vtu", ".msh", ".inp", ".xdmf"])
def test_mesh_read_back_and_fea_3d(tmp_path, capsys, ext):
    """A 3-D model's [fea] table is parsed; the written mesh reads back as tetrahedra
    (hetmesh.io.read) and the 3-D analysis runs on it with the faces found by the solid."""
    from hetmesh.io.read import read_mesh

    model = write(tmp_path, CUBE_FEA, "cube.toml")
    m = load_model(model)
    assert m.fea is not None
    out = tmp_path / f"c{ext}"
    assert run(["mesh", model, "--threshold", 0.3, "--output", out, "-q"], capsys)[0] == 0
    back = read_mesh(out)
    res = mesh_model(m, 0.3)
    assert back.dim == 3 and back.n_elements == len(res.tets)
    if ext in (".msh", ".xdmf"):
        assert set(back.marker_names.values()) == set(res.face_names)
    code, o, err = run(["fea", model, "--mesh", out], capsys)
    assert code == 0, err
    assert "3-D" in o and "T in [300.00, 1000.00] K" in o


#: a box of one material (a constant composition), or two without a gradient in either
HOMOGENEOUS = """
[model]
name = "homogeneous"

[solid]
type = "box"
min = [0, 0, 0]
max = [3, 2, 2]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""


@pytest.mark.parametrize("formula", ["0.3", "where(z < 1.5, 0.2, 0.8)"],
                         ids=["constant", "constant-branches"])
def test_a_composition_without_a_gradient_meshes(tmp_path, capsys, formula):
    """A constant composition went to the layered placement, which put a plane at each of
    its 4,097 axial samples (the field equals its only level everywhere) and ran for
    minutes; constant branches made N_iso3 = 0 and the statistics divided by it. Both mesh
    now, coarsely, and the statistics say N_iso3 = 0."""
    path = write(tmp_path, HOMOGENEOUS.format(formula=formula))
    res = mesh_model(load_model(path), 0.2)
    branch = (lambda p: np.full(len(p), 0.3)) if formula == "0.3" else \
        (lambda p: np.where(p[:, 2] < 1.5, 0.2, 0.8))
    if "regions" in res.info:  # a vertex on the jump takes its tetrahedron's side
        c = res.points[res.tets.astype(np.int64)].mean(axis=1)
        assert ((c[:, 2] < 1.5).astype(int) == np.asarray(res.info["regions"])).all()
        assert not ((res.points[res.tets][..., 2].min(axis=1) < 1.5)
                    & (res.points[res.tets][..., 2].max(axis=1) > 1.5)).any()
    else:
        check_tet_mesh(res.points, res.tets, branch, 0.2,
                       box_bounds=(np.zeros(3), np.array([3.0, 2.0, 2.0])))
    assert 0 < len(res.tets) < 2000
    out = tmp_path / "m.vtu"
    stats = tmp_path / "s.json"
    code, text, _ = run(["mesh", path, "-d", "0.2", "-o", out, "--stats", stats], capsys)
    assert code == 0 and "(N_iso3 = 0)" in text
    doc = json.loads(stats.read_text())
    assert doc["stats"]["n_iso3"] == 0 and doc["stats"]["ratio_n_iso3"] is None
