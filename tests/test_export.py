"""Mesh export/import round trips (every format) and atomic writes."""

from __future__ import annotations

import os

import meshio
import numpy as np
import pytest

from hetmesh.errors import OptionError, OutputError
from hetmesh.io import textio
from hetmesh.io.atomic import atomic_path, atomic_write
from hetmesh.io.export import FILE_FORMATS, FORMATS, region_tag_offset, write_mesh
from hetmesh.io.read import read_mesh
from hetmesh.mesh import Mesh

# (extension, file_format, keeps point data, keeps cell data, keeps marker names)
CASES = [
    (".vtu", None, True, True, False),
    (".vtk", None, True, True, False),
    (".xdmf", None, True, True, True),
    (".msh", None, True, True, True),
    (".msh", "gmsh41", True, True, True),
    (".msh", "gmsh22", True, False, True),
    (".inp", None, False, False, True),
    (".mesh", None, False, False, False),
]
IDS = [f"{ext}-{ff}" if ff else ext for ext, ff, *_ in CASES]


def square_mesh() -> Mesh:
    """Unit square, 3 x 3 nodes, 8 triangles; region 0 left of x = 0.5, region 1 right.

    Edges: the bottom (marker 1, "bottom") and the interface x = 0.5 (marker 2).
    """
    x, y = np.meshgrid([0.0, 0.5, 1.0], [0.0, 0.5, 1.0])
    points = np.column_stack([x.ravel(), y.ravel()])
    tris = []
    for j in range(2):
        for i in range(2):
            a = 3 * j + i
            tris += [[a, a + 1, a + 4], [a, a + 4, a + 3]]
    tris = np.array(tris)
    c = points[tris].mean(axis=1)
    metal = points[:, 1] ** 2
    return Mesh(points, tris, regions=(c[:, 0] > 0.5).astype(int),
                facets=[[0, 1], [1, 2], [1, 4], [4, 7]], facet_markers=[1, 1, 2, 2],
                point_data={"ceramic": 1 - metal, "metal": metal},
                cell_data={"delta": c[:, 0] / 3, "quality": 1 - c[:, 1] / 7},
                marker_names={1: "bottom", 2: "interface x=0.5"})


def by_triangle(mesh: Mesh, values) -> dict:
    """Values keyed by the triangle's sorted vertex triple (order-independent)."""
    return {tuple(sorted(t)): v
            for t, v in zip(mesh.triangles.tolist(), np.asarray(values).tolist())}


def edge_set(mesh: Mesh) -> set:
    return {(tuple(sorted(e)), m) for e, m in zip(mesh.edges.tolist(), mesh.edge_markers.tolist())}


@pytest.mark.parametrize("ext, file_format, point_data, cell_data, names", CASES, ids=IDS)
def test_round_trip(tmp_path, ext, file_format, point_data, cell_data, names):
    mesh = square_mesh()
    path = tmp_path / f"out{ext}"
    assert write_mesh(mesh, path, file_format=file_format) == path
    side = [path.with_suffix(".h5").name] if ext == ".xdmf" else []
    assert sorted(os.listdir(tmp_path)) == sorted([path.name] + side)  # no temp file
    back = read_mesh(path)
    np.testing.assert_allclose(back.points, mesh.points, rtol=0, atol=1e-12)
    assert by_triangle(back, back.regions) == by_triangle(mesh, mesh.regions)
    assert edge_set(back) == edge_set(mesh)
    if point_data:
        assert set(back.point_data) == {"ceramic", "metal"}
        for k, v in mesh.point_data.items():
            np.testing.assert_allclose(back.point_data[k], v, rtol=0, atol=1e-12)
    if cell_data:
        assert set(back.cell_data) == {"delta", "quality"}
        for k, v in mesh.cell_data.items():
            got, want = by_triangle(back, back.cell_data[k]), by_triangle(mesh, v)
            assert got.keys() == want.keys()
            np.testing.assert_allclose([got[t] for t in want], list(want.values()), rtol=0,
                                       atol=1e-12)
    if names:
        expected = {1: "bottom", 2: "interface x=0.5"}
        if ext == ".inp":
            expected = {1: "bottom", 2: "interface_x_0_5"}  # sanitised Abaqus set names
        assert back.marker_names == expected


@pytest.mark.parametrize("ext, file_format", [(c[0], c[1]) for c in CASES], ids=IDS)
def test_round_trip_bare_mesh(tmp_path, ext, file_format):
    """No edges, no data, one region."""
    mesh = Mesh([[0, 0], [2, 0], [2, 1], [0, 1]], [[0, 1, 2], [0, 2, 3]])
    back = read_mesh(write_mesh(mesh, tmp_path / f"bare{ext}", file_format=file_format))
    np.testing.assert_allclose(back.points, mesh.points, atol=1e-12)
    assert by_triangle(back, back.regions) == by_triangle(mesh, mesh.regions)
    assert len(back.edges) == 0


@pytest.mark.parametrize("ext, file_format", [(c[0], c[1]) for c in CASES], ids=IDS)
def test_round_trip_sparse_ids(tmp_path, ext, file_format):
    """Regions 0, 2, 5 interleaved; markers 3 (unnamed) and 7 (named)."""
    base = square_mesh()
    mesh = Mesh(base.points, base.triangles, regions=[5, 0, 2, 5, 0, 2, 5, 0],
                facets=base.edges, facet_markers=[7, 3, 7, 3], marker_names={7: "left side"})
    back = read_mesh(write_mesh(mesh, tmp_path / f"m{ext}", file_format=file_format))
    assert by_triangle(back, back.regions) == by_triangle(mesh, mesh.regions)
    assert edge_set(back) == edge_set(mesh)
    if ext in (".msh", ".inp", ".xdmf"):
        assert back.marker_names == {7: "left_side" if ext == ".inp" else "left side"}


def test_triangles_stay_in_order_where_the_format_allows(tmp_path):
    mesh = square_mesh()
    for name in ("out.vtu", "out.xdmf", "out.inp", "out.msh"):
        back = read_mesh(write_mesh(mesh, tmp_path / name))
        np.testing.assert_array_equal(back.triangles, mesh.triangles)
        np.testing.assert_array_equal(back.regions, mesh.regions)


def test_vtu_content(tmp_path):
    m = meshio.read(write_mesh(square_mesh(), tmp_path / "m.vtu"))
    assert m.points.shape == (9, 3) and not m.points[:, 2].any()
    assert [c.type for c in m.cells] == ["triangle", "line"]
    np.testing.assert_array_equal(m.cell_data["marker"][0], 0)
    np.testing.assert_array_equal(m.cell_data["marker"][1], [1, 1, 2, 2])
    assert np.isnan(m.cell_data["delta"][1]).all()
    np.testing.assert_array_equal(m.cell_data["region"][1], -1)


@pytest.mark.parametrize("file_format, version", [(None, "4.1"), ("gmsh22", "2.2")])
def test_gmsh_physical_groups(tmp_path, file_format, version):
    path = write_mesh(square_mesh(), tmp_path / "m.msh", file_format=file_format)
    assert path.read_text().splitlines()[1].startswith(version)
    m = meshio.read(path)
    assert {k: v.tolist() for k, v in m.field_data.items()} == {
        "bottom": [1, 1], "interface x=0.5": [2, 1], "region_0": [1000, 2], "region_1": [1001, 2]}
    tri_tags = np.concatenate([m.cell_data["gmsh:physical"][i]
                               for i, c in enumerate(m.cells) if c.type == "triangle"])
    assert set(tri_tags.tolist()) == {1000, 1001}


def test_region_tag_offset_clears_the_markers():
    assert region_tag_offset(np.array([1, 2, 999])) == 1000
    assert region_tag_offset(np.array([1000])) == 10_000
    assert region_tag_offset(np.array([], int)) == 1000


def test_gmsh_file_loads_in_scikit_fem(tmp_path):
    skfem = pytest.importorskip("skfem")
    path = write_mesh(square_mesh(), tmp_path / "m.msh")
    m = skfem.Mesh.load(str(path))
    subdomains = {k: len(v) for k, v in m.subdomains.items() if not k.startswith("gmsh:")}
    assert subdomains == {"region_0": 4, "region_1": 4}
    assert len(m.boundaries["bottom"]) == 2


def test_abaqus_file(tmp_path):
    path = write_mesh(square_mesh(), tmp_path / "m.inp")
    text = path.read_text()
    assert "*ELEMENT, TYPE=CPE3" in text
    assert "*SURFACE, TYPE=ELEMENT, NAME=bottom\n_M1_S1, S1\n" in text
    m = meshio.read(path)  # CPE3 is registered with meshio's reader on import
    assert {k for k in m.cell_sets if k.startswith("REGION")} == {"REGION_0", "REGION_1"}
    assert m.point_sets["bottom"].tolist() == [0, 1, 2]
    assert m.point_sets["interface_x_0_5"].tolist() == [1, 4, 7]
    # the element sets behind the surfaces: elements 1 and 3 on their side S1 = nodes 1-2
    assert m.cell_sets["_M1_S1"][0].tolist() == [0, 2]


def test_unknown_extension(tmp_path):
    with pytest.raises(OutputError,
                       match=r"unknown mesh format '\.xyz' for .*out\.xyz \(known: \.inp, "):
        write_mesh(square_mesh(), tmp_path / "out.xyz")
    with pytest.raises(OutputError, match="unknown mesh file_format 'stl'"):
        write_mesh(square_mesh(), tmp_path / "out.vtu", file_format="stl")
    with pytest.raises(OutputError, match="unknown mesh format"):
        read_mesh(tmp_path / "out.xyz")
    assert not os.listdir(tmp_path)


def test_known_formats():
    assert {".vtu", ".msh", ".xdmf", ".inp", ".vtk", ".mesh"} <= set(FORMATS)
    assert {"gmsh22", "gmsh41", "gmsh"} <= set(FILE_FORMATS)


@pytest.mark.parametrize("where", ["missing parent", "directory", "parent is a file"])
def test_unwritable_path(tmp_path, where):
    if where == "missing parent":
        path = tmp_path / "no" / "such" / "out.vtu"
    elif where == "directory":
        path = tmp_path / "out.vtu"
        path.mkdir()
    else:
        (tmp_path / "file").write_text("x")
        path = tmp_path / "file" / "out.vtu"
    with pytest.raises(OutputError, match=r"^cannot write .*out\.vtu: ") as info:
        write_mesh(square_mesh(), path)
    assert "\n" not in str(info.value)


def test_read_errors(tmp_path):
    with pytest.raises(OutputError, match="no such file"):
        read_mesh(tmp_path / "missing.vtu")
    (tmp_path / "garbage.msh").write_text("not a mesh\n")
    with pytest.raises(OutputError, match="cannot read"):
        read_mesh(tmp_path / "garbage.msh")


def test_negative_regions_rejected_where_they_name_groups(tmp_path):
    mesh = square_mesh().with_regions(np.full(8, -1))
    for name in ("m.msh", "m.inp"):
        with pytest.raises(OutputError, match="regions >= 0"):
            write_mesh(mesh, tmp_path / name)
    assert not os.listdir(tmp_path)
    write_mesh(mesh, tmp_path / "m.vtu")  # fine where regions are plain data


def test_failed_meshio_write_keeps_the_old_file(tmp_path, monkeypatch):
    path = tmp_path / "out.vtu"
    path.write_text("old content")
    seen = []

    def broken(filename, *args, **kwargs):
        seen.append(filename)
        with open(filename, "w") as f:
            f.write("half a mesh")
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(meshio, "write", broken)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_mesh(square_mesh(), path)
    assert path.read_text() == "old content"
    assert os.listdir(tmp_path) == ["out.vtu"]
    assert str(seen[0]).endswith(".vtu") and seen[0] != path  # a temp file, same suffix


def test_failed_own_writer_keeps_the_old_file(tmp_path, monkeypatch):
    path = tmp_path / "out.msh"
    path.write_text("old content")
    real = textio.write_rows
    calls = []

    def flaky(f, row, a):
        calls.append(1)
        if len(calls) > 2:
            raise MemoryError("out of memory")
        real(f, row, a)

    monkeypatch.setattr(textio, "write_rows", flaky)
    with pytest.raises(MemoryError):
        write_mesh(square_mesh(), path)
    assert path.read_text() == "old content"
    assert os.listdir(tmp_path) == ["out.msh"]


def test_mesh_write_delegates(tmp_path):
    path = square_mesh().write(tmp_path / "m.msh", file_format="gmsh22")
    assert path.read_text().splitlines()[1].startswith("2.2")


# -- atomic writes -----------------------------------------------------------------------

def test_atomic_write_text_and_binary(tmp_path):
    with atomic_write(tmp_path / "a.txt") as f:
        f.write("héllo")
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "héllo"
    with atomic_write(tmp_path / "b.bin", "wb") as f:
        f.write(b"\x00\x01")
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert sorted(os.listdir(tmp_path)) == ["a.txt", "b.bin"]


def test_atomic_write_failure_keeps_old_file(tmp_path):
    path = tmp_path / "stats.json"
    path.write_text("{}")
    with pytest.raises(KeyError):
        with atomic_write(path) as f:
            f.write('{"half": ')
            raise KeyError("boom")
    assert path.read_text() == "{}"
    assert os.listdir(tmp_path) == ["stats.json"]


def test_atomic_write_bad_mode(tmp_path):
    with pytest.raises(OptionError, match="mode"):
        with atomic_write(tmp_path / "x", "a"):
            pass


def test_atomic_path_keeps_suffix_and_permissions(tmp_path):
    path = tmp_path / "pic.png"
    with atomic_path(path) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".png" and tmp.exists()
        tmp.write_bytes(b"png")
    assert path.read_bytes() == b"png"
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


def test_atomic_path_oserror_becomes_output_error(tmp_path):
    with pytest.raises(OutputError, match=r"^cannot write .*x\.txt: no space left"):
        with atomic_path(tmp_path / "x.txt"):
            raise OSError(28, "No space left on device")
    assert not os.listdir(tmp_path)


# -- groups, named points, element types -------------------------------------------------

def split_mesh() -> Mesh:
    """The square mesh with the bottom split in two markers of one name, a named corner."""
    base = square_mesh()
    return Mesh(base.points, base.triangles, regions=base.regions,
                facets=[[0, 1], [1, 2], [1, 4], [4, 7]], facet_markers=[1, 3, 2, 2],
                marker_names={1: "bottom", 3: "bottom", 2: "cut"}, named_points={"A": 0, "C": 8})


@pytest.mark.parametrize("ext, file_format", [(".msh", None), (".msh", "gmsh22"), (".inp", None),
                                              (".xdmf", None)])
def test_one_group_per_name_and_named_points_read_back(tmp_path, ext, file_format):
    mesh = split_mesh()
    back = read_mesh(write_mesh(mesh, tmp_path / f"m{ext}", file_format=file_format))
    assert edge_set(back) == edge_set(mesh)  # markers kept exactly
    assert back.marker_names == {1: "bottom", 3: "bottom", 2: "cut"}
    assert back.named_points == {"A": 0, "C": 8}


def test_gmsh_names_each_group_once(tmp_path):
    m = meshio.read(write_mesh(split_mesh(), tmp_path / "m.msh"))
    assert {k: v.tolist() for k, v in m.field_data.items()} == {
        "A": [10001, 0], "C": [10002, 0], "bottom": [1, 1], "cut": [2, 1],
        "region_0": [1000, 2], "region_1": [1001, 2]}


def test_inp_one_nset_per_name(tmp_path):
    text = write_mesh(split_mesh(), tmp_path / "m.inp").read_text()
    assert text.count("*NSET, NSET=bottom\n") == 1 and "*NSET, NSET=A\n1\n" in text
    assert "*SURFACE, TYPE=ELEMENT, NAME=bottom\n_M1_S1, S1\n_M3_S1, S1\n" in text


@pytest.mark.parametrize("plane, order, kind", [("strain", 1, "CPE3"), ("stress", 1, "CPS3"),
                                                ("strain", 2, "CPE6"), ("stress", 2, "CPS6")])
def test_inp_element_types(tmp_path, plane, order, kind):
    from hetmesh.io.abaqus import write_inp_mesh

    mesh = split_mesh()
    path = tmp_path / "m.inp"
    with open(path, "w") as f:
        points = write_inp_mesh(f, mesh, path, plane=plane, order=order)
    text = path.read_text()
    assert f"*ELEMENT, TYPE={kind}, ELSET=EALL\n" in text
    m = meshio.read(path)
    cells = m.cells[0].data
    assert cells.shape == (8, 3 * order)
    np.testing.assert_array_equal(cells[:, :3], mesh.triangles)
    if order == 2:  # mid-side nodes at the midpoints of sides 1-2, 2-3, 3-1
        p = m.points[:, :2]
        for k in range(3):
            np.testing.assert_allclose(p[cells[:, 3 + k]],
                                       0.5 * (p[cells[:, k]] + p[cells[:, (k + 1) % 3]]))
        assert len(points) == 9 + 16  # 16 edges in the 3 x 3 grid
        # the bottom's node set holds its mid-side nodes too
        assert len(m.point_sets["bottom"]) == 5
    assert back_regions(read_mesh(path), mesh)


def back_regions(back, mesh) -> bool:
    return by_triangle(back, back.regions) == by_triangle(mesh, mesh.regions)


# -- graded material -----------------------------------------------------------------------

FGM_TOML = """
[model]
name = "bar"
units = "mm"
[domain.outer]
name = "outer"
start = [0, 0]
path = [{ to = [10, 0], name = "bottom" }, { to = [10, 2], name = "right" },
        { to = [0, 2], name = "top" }, { to = [0, 0], name = "left" }]
[material]
constituents = ["ceramic", "metal"]
[material.composition]
metal = "x / 10"
[fea]
mixing = "mori-tanaka"
matrix = "metal"
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
"""


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    import hetmesh

    path = tmp_path_factory.mktemp("bar") / "bar.toml"
    path.write_text(FGM_TOML)
    model = hetmesh.load_model(path)
    return model, hetmesh.generate(model, 0.1).mesh


def test_properties_without_boundary_conditions(bar):
    model, _ = bar
    assert not model.fea.has_problem and model.fea.mixing == "mori-tanaka"


def test_fea_needs_boundary_conditions(bar):
    from hetmesh.errors import FEAError
    from hetmesh.fea import solve

    model, mesh = bar
    with pytest.raises(FEAError, match="no boundary conditions"):
        solve(mesh, model)


def test_element_material_and_bins(bar):
    from hetmesh.fea.mixing import mix_config
    from hetmesh.io.material import bin_material, element_material

    model, mesh = bar
    mat = element_material(mesh, model)
    centroid_metal = mesh.points[mesh.triangles].mean(axis=1)[:, 0] / 10  # linear field
    np.testing.assert_allclose(mat.mean[:, 1], centroid_metal, atol=1e-12)
    np.testing.assert_allclose(mat.delta, np.ptp(mesh.points[mesh.triangles][..., 0], axis=1) / 10,
                               atol=1e-12)
    assert mat.delta.max() < 0.1
    want = mix_config(mat.mean, model.fea, ("ceramic", "metal"))
    for k, v in want.items():
        np.testing.assert_allclose(mat.properties[k], v)
    for width in (0.1, 0.025):
        bins = bin_material(mat, width, model.fea, ("ceramic", "metal"))
        for b in range(bins.count):  # no constituent varies by more than the width in a bin
            members = mat.mean[bins.index == b]
            assert np.ptp(members, axis=0).max() <= width
        errs = {k: np.max(np.abs(bins.properties[k][bins.index] - v) / np.abs(v))
                for k, v in mat.properties.items()}
        assert bins.errors == pytest.approx(errs) and bins.max_error == max(errs.values())
    assert bin_material(mat, 0.025, model.fea, ("ceramic", "metal")).max_error < \
        bin_material(mat, 0.1, model.fea, ("ceramic", "metal")).max_error


@pytest.mark.parametrize("ext", [".vtu", ".msh", ".xdmf"])
def test_cell_data_carries_the_material(tmp_path, bar, ext):
    from hetmesh.io.material import element_material, with_material

    model, mesh = bar
    graded = with_material(mesh, element_material(mesh, model))
    back = read_mesh(write_mesh(graded, tmp_path / f"g{ext}"))
    for k in ("youngs_modulus", "poisson_ratio", "expansion", "conductivity", "mean_metal"):
        np.testing.assert_allclose(back.cell_data[k], graded.cell_data[k], rtol=1e-15)


def test_material_deck_without_analysis(tmp_path, bar):
    from hetmesh.io.deck import write_deck

    model, mesh = bar
    report = write_deck(mesh, model, tmp_path, "calculix", bin_width=0.05)
    assert not report.analysis and report.bins >= 18
    text = (tmp_path / "bar.inp").read_text()
    assert text.count("*MATERIAL, NAME=MAT_") == report.bins
    assert text.count("*SOLID SECTION, ELSET=MAT_") == report.bins and "*STEP" not in text
    m = meshio.read(tmp_path / "bar.inp")
    sizes = [len(m.cell_sets[f"MAT_{b + 1}"][0]) for b in range(report.bins)]
    assert sum(sizes) == mesh.n_elements
    # SI units: coordinates in metres
    assert m.points[:, 0].max() == pytest.approx(0.01)


def test_cli_export(tmp_path, bar, capsys):
    from hetmesh.cli.main import main

    model, mesh = bar
    src = tmp_path / "bar.toml"
    src.write_text(FGM_TOML)
    write_mesh(mesh, tmp_path / "bar.vtu")
    out = tmp_path / "deck"
    for target in ("calculix", "abaqus", "fenics", "comsol"):
        code = main(["export", str(src), "--mesh", str(tmp_path / "bar.vtu"), "--to", target,
                     "--output", str(out / target), "-q"])
        assert code == 0
    assert (out / "fenics" / "bar.xdmf").exists() and (out / "fenics" / "bar.h5").exists()
    assert (out / "comsol" / "bar.nas").read_text().count("CTRIA3") == mesh.n_elements
    nas = meshio.read(out / "comsol" / "bar.nas")
    np.testing.assert_allclose(nas.points[:, :2], mesh.points, rtol=1e-10, atol=1e-12)
    table = np.loadtxt(out / "comsol" / "bar_composition.txt", comments="%")
    assert table.shape == (mesh.n_points, 4)
    capsys.readouterr()
    assert main(["export", str(src), "--mesh", str(tmp_path / "none.vtu"), "--to", "calculix",
                 "--output", str(out / "x")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["export", str(src), "--mesh", str(tmp_path / "bar.vtu"), "--to", "calculix",
                 "--output", str(out / "x"), "--bin-width", "2"]) == 2


# ------------------------------------------------------------- Abaqus *DISTRIBUTION

def abaqus_keywords(text: str) -> list[tuple[str, dict, list[list[str]]]]:
    """An Abaqus input file as ``(KEYWORD, {PARAMETER: value}, data lines split at
    commas)``, as the Abaqus keyword reference describes the syntax: a keyword line starts
    with ``*`` (``**`` is a comment), parameters follow after commas as ``NAME=value`` or
    ``NAME``, case-insensitive; data lines hold comma-separated fields."""
    out = []
    for line in text.splitlines():
        if line.startswith("**") or not line.strip():
            continue
        if line.startswith("*"):
            head, *params = [p.strip() for p in line[1:].split(",")]
            kv = {}
            for p in params:
                k, _, v = p.partition("=")
                kv[k.strip().upper()] = v.strip()
            out.append((head.upper(), kv, []))
        else:
            out[-1][2].append([x.strip() for x in line.split(",")])
    return out


def check_distribution_deck(text: str, modulus: np.ndarray, ratio: np.ndarray) -> None:
    """The deck's elasticity against the Abaqus keyword reference: a ``*DISTRIBUTION
    TABLE`` whose only data line is ``MODULUS, RATIO`` (isotropic elasticity); a
    ``*DISTRIBUTION`` with the required LOCATION (ELEMENT), NAME and TABLE (that table),
    a first data line with a blank label (the defaults) then element labels with two
    values each; every ``*MATERIAL``'s ``*ELASTIC`` data line naming the distribution;
    the model data before the first ``*STEP``; every field within 20 characters."""
    kws = abaqus_keywords(text)
    names = [k for k, _, _ in kws]
    tables = [(p, d) for k, p, d in kws if k == "DISTRIBUTION TABLE"]
    dists = [(p, d) for k, p, d in kws if k == "DISTRIBUTION"]
    assert len(tables) == 1 and len(dists) == 1
    (tp, td), (dp, dd) = tables[0], dists[0]
    assert td == [["MODULUS", "RATIO"]]
    assert set(dp) >= {"NAME", "LOCATION", "TABLE"}
    assert dp["LOCATION"].upper() == "ELEMENT" and dp["TABLE"] == tp["NAME"]
    assert dd[0][0] == "" and len(dd[0]) == 3 and float(dd[0][1]) > 0
    ids = [int(r[0]) for r in dd[1:]]
    assert ids == list(range(1, len(modulus) + 1))
    assert all(len(r) == 3 and all(len(x) <= 20 for x in r) for r in dd)
    np.testing.assert_array_equal([float(r[1]) for r in dd[1:]], modulus)
    np.testing.assert_array_equal([float(r[2]) for r in dd[1:]], ratio)
    elastic = [d for k, _, d in kws if k == "ELASTIC"]
    assert len(elastic) == names.count("MATERIAL") > 1
    assert all(d == [[dp["NAME"]]] for d in elastic)
    if "STEP" in names:
        assert names.index("DISTRIBUTION") < names.index("STEP")
    assert names.index("DISTRIBUTION TABLE") < names.index("DISTRIBUTION") < names.index("MATERIAL")


def test_abaqus_distribution_follows_the_keyword_reference(tmp_path, bar):
    from hetmesh.errors import OptionError
    from hetmesh.io.deck import write_deck
    from hetmesh.io.material import element_material

    model, mesh = bar
    report = write_deck(mesh, model, tmp_path, "abaqus", bin_width=0.05, distribution=True)
    assert report.distribution and report.property_errors["youngs_modulus"] == 0.0
    assert report.property_errors["expansion"] > 0  # still binned
    mat = element_material(mesh, model)
    check_distribution_deck((tmp_path / "bar.inp").read_text(),
                            mat.properties["youngs_modulus"], mat.properties["poisson_ratio"])
    plain = write_deck(mesh, model, tmp_path / "plain", "abaqus", bin_width=0.05)
    assert "*DISTRIBUTION" not in (tmp_path / "plain" / "bar.inp").read_text()
    assert plain.property_errors["youngs_modulus"] > 0
    with pytest.raises(OptionError, match="--to abaqus"):
        write_deck(mesh, model, tmp_path / "ccx", "calculix", distribution=True)


def test_abaqus_distribution_3d_and_cli(tmp_path, capsys):
    import hetmesh
    from hetmesh.cli.main import main
    from hetmesh.io.material import element_material

    model = hetmesh.load_model(hetmesh.example_path("graded_cylinder"))
    mesh = hetmesh.generate(model, 0.3).mesh
    write_mesh(mesh, tmp_path / "cyl.vtu")
    code = main(["export", str(hetmesh.example_path("graded_cylinder")), "--mesh",
                 str(tmp_path / "cyl.vtu"), "--to", "abaqus", "--distribution", "--output",
                 str(tmp_path / "deck")])
    assert code == 0 and "*DISTRIBUTION" in capsys.readouterr().out
    text = (tmp_path / "deck" / "graded_cylinder.inp").read_text()
    mat = element_material(read_mesh(tmp_path / "cyl.vtu"), model)
    check_distribution_deck(text, mat.properties["youngs_modulus"],
                            mat.properties["poisson_ratio"])
    assert "*ELEMENT, TYPE=C3D10, ELSET=EALL" in text  # no thermal problem: a static step
    assert main(["export", str(hetmesh.example_path("graded_cylinder")), "--mesh",
                 str(tmp_path / "cyl.vtu"), "--to", "calculix", "--distribution", "--output",
                 str(tmp_path / "x")]) == 2
