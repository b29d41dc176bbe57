"""Tetrahedral meshes in files, with the graded material: cell data in .vtu/.msh/.xdmf,
the Abaqus/CalculiX deck (C3D4/C3D10, surfaces by the manual's face numbering, material
bins), Gmsh reading the .msh, and CalculiX on the deck of graded_cylinder against
``hetmesh fea``."""

from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest

import hetmesh
from hetmesh.cli import main
from hetmesh.io.abaqus3d import FACE_NODES, oriented, quadratic_nodes3d
from hetmesh.io.deck import frd_nodal, read_frd, write_deck
from hetmesh.io.export import write_mesh
from hetmesh.io.material import PROPERTY_NAMES, element_material, with_material
from hetmesh.io.read import read_mesh
from test_solvers import need_ccx, need_module


@pytest.fixture(scope="module")
def cylinder():
    """graded_cylinder (a quarter tube, six named faces) at delta_0 = 0.25."""
    model = hetmesh.load_model(hetmesh.example_path("graded_cylinder"))
    return model, hetmesh.generate(model, 0.25).mesh


def test_tet_material_is_the_mean_composition(cylinder):
    model, mesh = cylinder
    mat = element_material(mesh, model)
    assert mat.mean.shape == (mesh.n_elements, 2)
    np.testing.assert_allclose(mat.mean.sum(axis=1), 1.0, rtol=1e-12)
    # the 4-point rule is exact for quadratics: compare with a fine sampling of one element
    e = int(np.argmax(mat.delta))
    rng = np.random.default_rng(0)
    w = rng.dirichlet(np.ones(4), 200_000)
    x = w @ mesh.points[mesh.cells[e]]
    sampled = np.asarray(model.material.composition(x)).mean(axis=0)
    np.testing.assert_allclose(mat.mean[e], sampled, atol=5e-3)
    assert mat.delta.max() < 0.25  # the mesh's own guarantee


@pytest.mark.parametrize("ext", [".vtu", ".msh", ".xdmf"])
def test_cell_data_carries_the_material_3d(tmp_path, cylinder, ext):
    model, mesh = cylinder
    graded = with_material(mesh, element_material(mesh, model))
    back = read_mesh(write_mesh(graded, tmp_path / f"cyl{ext}"))
    np.testing.assert_array_equal(back.cells, mesh.cells)
    for k in PROPERTY_NAMES + ("mean_ceramic", "mean_metal"):
        np.testing.assert_array_equal(back.cell_data[k], graded.cell_data[k], err_msg=k)
    np.testing.assert_array_equal(back.point_data["metal"], mesh.point_data["metal"])


def test_gmsh_opens_the_3d_msh_each_name_once(tmp_path, cylinder):
    gmsh = need_module("gmsh")
    model, mesh = cylinder
    graded = with_material(mesh, element_material(mesh, model))
    path = write_mesh(graded, tmp_path / "cyl.msh")
    gmsh.initialize(["-noenv"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        groups = [(d, gmsh.model.getPhysicalName(d, t)) for d, t in gmsh.model.getPhysicalGroups()]
        names = [n for _, n in groups]
        assert len(names) == len(set(names))
        assert sorted(n for d, n in groups if d == 2) == sorted(mesh.marker_names.values())
        assert [n for d, n in groups if d == 3] == ["solid"]
        for d, t in gmsh.model.getPhysicalGroups(2):
            name = gmsh.model.getPhysicalName(d, t)
            marker = {v: k for k, v in mesh.marker_names.items()}[name]
            (ent,) = gmsh.model.getEntitiesForPhysicalGroup(2, t)
            tags, _, _ = gmsh.model.mesh.getNodes(2, int(ent), includeBoundary=True)
            want = np.unique(mesh.facets[mesh.facet_markers == marker])
            assert set((tags - 1).tolist()) <= set(want.tolist())
        _, etags, enodes = gmsh.model.mesh.getElements(3)
        etags, enodes = np.concatenate(etags), np.concatenate(enodes).reshape(-1, 4)
        order = np.argsort(etags)
        np.testing.assert_array_equal(etags[order], np.arange(1, mesh.n_elements + 1))
        np.testing.assert_array_equal(enodes[order] - 1, mesh.cells)
        views = {gmsh.option.getString(f"View[{i}].Name"): v
                 for i, v in enumerate(gmsh.view.getTags())}
        assert {"youngs_modulus", "mean_metal", "metal"} <= set(views)
        kind, tags, data, _, _ = gmsh.view.getModelData(views["youngs_modulus"], 0)
        assert kind == "ElementData"
        got = dict(zip(np.asarray(tags).tolist(), np.concatenate(data).tolist()))
        np.testing.assert_array_equal([got[i + 1] for i in range(mesh.n_elements)],
                                      graded.cell_data["youngs_modulus"])
    finally:
        gmsh.finalize()


def _blocks(text: str) -> list[tuple[str, list[str]]]:
    """The deck as ``(keyword line, data lines)``, comments dropped."""
    out: list[tuple[str, list[str]]] = []
    for line in text.splitlines():
        if line.startswith("**"):
            continue
        if line.startswith("*"):
            out.append((line, []))
        elif out:
            out[-1][1].append(line)
    return out


def _ids(lines: list[str]) -> list[int]:
    return [int(x) for line in lines for x in line.split(",") if x.strip()]


@pytest.mark.parametrize("order", [1, 2])
def test_inp_surfaces_follow_the_abaqus_face_numbering(tmp_path, cylinder, order):
    """Every ``*SURFACE`` entry ``elset, S<k>`` names, through the manual's corner lists
    (S1 = 1-2-3, S2 = 1-4-2, S3 = 2-4-3, S4 = 3-4-1), exactly the named triangles; every
    element has a positive volume in Abaqus' convention; numbers fit 20 characters."""
    model, mesh = cylinder
    write_deck(mesh, model, tmp_path, "calculix", bin_width=0.25 / 4) if order == 2 else None
    path = tmp_path / "graded_cylinder.inp" if order == 2 else write_mesh(mesh, tmp_path / "c.inp")
    blocks = _blocks(path.read_text())
    nodes = {}
    elements = {}
    sets: dict[str, list[int]] = {}
    surfaces: dict[str, list[tuple[str, int]]] = {}
    for key, data in blocks:
        upper = key.upper()
        if upper == "*NODE":
            for line in data:
                f = [x.strip() for x in line.split(",")]
                assert all(len(x) <= 20 for x in f), line
                nodes[int(f[0])] = np.array([float(x) for x in f[1:]])
        elif upper.startswith("*ELEMENT"):
            kind = re.search(r"TYPE=(\w+)", key).group(1)
            assert kind == ("C3D4" if order == 1 else "C3D10")
            for line in data:
                v = _ids([line])
                elements[v[0]] = v[1:]
        elif upper.startswith("*ELSET"):
            sets[re.search(r"ELSET=(\w+)", key).group(1)] = _ids(data)
        elif upper.startswith("*SURFACE"):
            name = re.search(r"NAME=(\w+)", key).group(1)
            surfaces[name] = [(a.strip(), int(b.strip()[1:])) for a, b in
                              (line.split(",") for line in data)]
    assert len(elements) == mesh.n_elements and len(nodes) >= mesh.n_points
    scale = 1e-3 if order == 2 else 1.0
    for e, conn in elements.items():
        a, b, c, d = (nodes[i] for i in conn[:4])
        assert np.dot(np.cross(b - a, c - a), d - a) > 0, e
        if order == 2:  # mid-edge nodes in Abaqus' order 1-2, 2-3, 3-1, 1-4, 2-4, 3-4
            corners = [nodes[i] for i in conn[:4]]
            for j, (p, q) in enumerate(((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3))):
                np.testing.assert_allclose(nodes[conn[4 + j]], 0.5 * (corners[p] + corners[q]),
                                           rtol=0, atol=1e-12)
    assert sorted(surfaces) == sorted(n.upper() for n in mesh.marker_names.values())
    for marker, name in mesh.marker_names.items():
        want = {tuple(sorted(f)) for f in (mesh.facets[mesh.facet_markers == marker] + 1).tolist()}
        got = set()
        for elset, k in surfaces[name.upper()]:
            for e in sets[elset]:
                got.add(tuple(sorted(elements[e][j] for j in FACE_NODES[k - 1])))
        assert got == want, name
    np.testing.assert_allclose(np.array([nodes[i + 1] for i in range(mesh.n_points)]),
                               mesh.points * scale, rtol=1e-14)


def test_quadratic_nodes_and_orientation():
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    T = np.array([[1, 0, 2, 3], [1, 2, 3, 4]])  # the first is negative
    t = oriented(P, T)
    assert t[0].tolist() == [0, 1, 2, 3] and t[1].tolist() == T[1].tolist()
    mp, mid, edges = quadratic_nodes3d(P, t)
    assert len(mp) == 9 and mid.shape == (2, 6)  # 6 + 6 - 3 shared edges
    np.testing.assert_allclose(mp[mid[0, 0] - 5], 0.5 * (P[0] + P[1]))


def test_deck_bins_and_sections(tmp_path, cylinder):
    model, mesh = cylinder
    report = write_deck(mesh, model, tmp_path, "calculix", bin_width=0.25 / 4)
    text = (tmp_path / "graded_cylinder.inp").read_text()
    assert text.count("*MATERIAL, NAME=") == report.bins > 4
    # linear mixing: a bin of width w changes a property by at most w |P_1 - P_0| / min P
    t = model.fea.table()
    bound = max(0.0625 * np.ptp(v) / v.min() for v in t.values())
    assert report.bin_width == 0.0625 and 0 < report.max_property_error <= bound
    # solid sections of solid elements have no thickness line
    for m in re.finditer(r"^\*SOLID SECTION[^\n]*\n([^\n]*)", text, flags=re.M):
        assert m.group(1).startswith("*")
    # the material bins cover every element once
    blocks = _blocks(text)
    covered = sorted(i for k, d in blocks if re.match(r"\*ELSET, ELSET=MAT_\d+$", k)
                     for i in _ids(d))
    assert covered == list(range(1, mesh.n_elements + 1))
    assert "*DLOAD" in text and "*STATIC" in text and "*HEAT TRANSFER" not in text


def test_calculix_on_graded_cylinder_agrees_with_hetmesh_fea(tmp_path, capsys):
    """``hetmesh export`` of graded_cylinder (pressure on the inner face, symmetry planes,
    plane-strain ends) at delta_0 = 0.15, bins of delta_0 / 4, run by CalculiX (C3D10),
    against ``hetmesh fea`` on the same mesh: von Mises and radial stress at R1..R3."""
    ccx = need_ccx()
    model = hetmesh.load_model(hetmesh.example_path("graded_cylinder"))
    mesh = hetmesh.generate(model, 0.15).mesh
    vtu = write_mesh(mesh, tmp_path / "cyl.vtu")
    code = main(["export", str(hetmesh.example_path("graded_cylinder")), "--mesh", str(vtu),
                 "--to", "calculix", "--output", str(tmp_path / "deck"), "--bin-width",
                 "0.0375"])
    out = capsys.readouterr().out
    assert code == 0 and "material bins of" in " ".join(out.split())
    run = subprocess.run([ccx, "-i", "graded_cylinder"], cwd=tmp_path / "deck",
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0 and "*ERROR" not in run.stdout, run.stdout[-2000:]
    frd = read_frd(tmp_path / "deck" / "graded_cylinder.frd")
    ours = hetmesh.fea.solve(read_mesh(vtu), model)
    n = mesh.n_points
    U = frd_nodal(frd, "DISP", n)[:, :3]
    assert np.abs(U - ours.displacement).max() < 5e-3 * np.abs(ours.displacement).max()
    s = frd_nodal(frd, "STRESS", n)  # xx yy zz xy yz zx
    xx, yy, zz, xy, yz, zx = s.T
    vm = np.sqrt(0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2)
                 + 3 * (xy ** 2 + yz ** 2 + zx ** 2))
    P, T = mesh.points, mesh.cells
    for name, q in model.fea.probes.items():
        a = P[T[:, 0]]
        lam = np.linalg.solve(np.stack([P[T[:, k]] - a for k in (1, 2, 3)], axis=2),
                              (np.asarray(q) - a)[..., None])[..., 0]
        bary = np.column_stack([1 - lam.sum(axis=1), lam])
        e = int(np.argmax(bary.min(axis=1)))
        mine = ours.probes[name]
        assert bary[e] @ vm[T[e]] == pytest.approx(mine["von_mises"], rel=0.02), name
        # the probes sit on y = 0: the radial stress is sigma_xx
        assert bary[e] @ xx[T[e]] == pytest.approx(mine["stress_xx"], rel=0.02), name


CUBE_FEA = """
[fea]
reference_temperature = 300
order = {order}
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
value = 900
[[fea.temperature]]
faces = ["zmax"]
value = 300
[[fea.displacement]]
faces = ["xmin"]
ux = 0
[[fea.displacement]]
faces = ["ymin"]
uy = 0
[[fea.displacement]]
faces = ["zmin"]
uz = 0
"""


@pytest.mark.parametrize("order", [1, 2])
def test_calculix_heat_then_static_step_in_3d(tmp_path, order):
    """unit_cube heated from below (900 K on zmin, 300 K on zmax), on rollers: CalculiX's
    heat step then its thermoelastic step (C3D4 / C3D10) against hetmesh fea."""
    ccx = need_ccx()
    text = hetmesh.example_path("unit_cube").read_text() + CUBE_FEA.format(order=order)
    (tmp_path / "cube.toml").write_text(text)
    model = hetmesh.load_model(tmp_path / "cube.toml")
    mesh = hetmesh.generate(model, 0.2).mesh
    report = write_deck(mesh, model, tmp_path, "calculix", bin_width=0.05)
    deck = (tmp_path / "unit_cube.inp").read_text()
    assert report.analysis and deck.index("*HEAT TRANSFER") < deck.index("*STATIC")
    run = subprocess.run([ccx, "-i", "unit_cube"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0 and "*ERROR" not in run.stdout, run.stdout[-2000:]
    frd = read_frd(tmp_path / "unit_cube.frd")
    ours = hetmesh.fea.solve(mesh, model)
    n = mesh.n_points
    T = frd_nodal(frd, "NDTEMP", n)[:, 0]
    assert np.abs(T - ours.temperature).max() <= 0.005 * np.ptp(ours.temperature)
    U = frd_nodal(frd, "DISP", n)[:, :3]
    assert np.abs(U - ours.displacement).max() <= 0.01 * np.abs(ours.displacement).max()


def test_fenics_and_comsol_bundles_of_a_tet_mesh(tmp_path, cylinder):
    import meshio

    model, mesh = cylinder
    write_deck(mesh, model, tmp_path / "fenics", "fenics")
    back = read_mesh(tmp_path / "fenics" / "graded_cylinder.xdmf")
    np.testing.assert_array_equal(back.cells, mesh.cells)
    assert {"youngs_modulus", "mean_metal"} <= set(back.cell_data)
    write_deck(mesh, model, tmp_path / "comsol", "comsol")
    nas = meshio.read(tmp_path / "comsol" / "graded_cylinder.nas")
    assert [c.type for c in nas.cells] == ["tetra"] and len(nas.cells[0]) == mesh.n_elements
    np.testing.assert_allclose(nas.points, mesh.points, rtol=0, atol=1e-9)
    table = np.loadtxt(tmp_path / "comsol" / "graded_cylinder_composition.txt", comments="%")
    assert table.shape == (mesh.n_points, 5)  # x y z ceramic metal
    np.testing.assert_array_equal(table[:, 4], mesh.point_data["metal"])


@pytest.fixture(scope="module")
def regions_and_shared_names():
    """unit_cube with its tetrahedra dealt into three interleaved regions and the four side
    faces (four markers) sharing one name."""
    import dataclasses

    model = hetmesh.load_model(hetmesh.example_path("unit_cube"))
    mesh = hetmesh.generate(model, 0.3).mesh
    names = {m: ("sides" if n not in ("zmin", "zmax") else n)
             for m, n in mesh.marker_names.items()}
    return dataclasses.replace(mesh, regions=np.arange(mesh.n_elements) % 3,
                               marker_names=names)


def test_msh_regions_keep_element_ids_and_names_once(tmp_path, regions_and_shared_names):
    mesh = regions_and_shared_names
    path = write_mesh(mesh, tmp_path / "cube.msh")
    back = read_mesh(path)
    np.testing.assert_array_equal(back.cells, mesh.cells)
    np.testing.assert_array_equal(back.regions, mesh.regions)
    np.testing.assert_array_equal(back.cell_data["quality"], mesh.cell_data["quality"])
    assert back.marker_names == mesh.marker_names
    gmsh = need_module("gmsh")
    gmsh.initialize(["-noenv"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        groups = {(d, gmsh.model.getPhysicalName(d, t)): t
                  for d, t in gmsh.model.getPhysicalGroups()}
        assert sorted(n for d, n in groups if d == 2) == ["sides", "zmax", "zmin"]
        assert sorted(n for d, n in groups if d == 3) == ["region_0", "region_1", "region_2"]
        sides = sorted(gmsh.model.getEntitiesForPhysicalGroup(2, groups[(2, "sides")]).tolist())
        assert sides == sorted(m for m, n in mesh.marker_names.items() if n == "sides")
        _, etags, enodes = gmsh.model.mesh.getElements(3)
        etags, enodes = np.concatenate(etags), np.concatenate(enodes).reshape(-1, 4)
        order = np.argsort(etags)
        np.testing.assert_array_equal(etags[order], np.arange(1, mesh.n_elements + 1))
        np.testing.assert_array_equal(enodes[order] - 1, mesh.cells)
        for r in range(3):
            (vol,) = gmsh.model.getEntitiesForPhysicalGroup(3, groups[(3, f"region_{r}")])
            _, tags, _ = gmsh.model.mesh.getElements(3, int(vol))
            assert sorted(np.concatenate(tags).tolist()) == \
                (np.flatnonzero(mesh.regions == r) + 1).tolist()
        view = gmsh.view.getTags()[[gmsh.option.getString(f"View[{i}].Name")
                                    for i in range(len(gmsh.view.getTags()))].index("quality")]
        _, tags, data, _, _ = gmsh.view.getModelData(int(view), 0)
        got = dict(zip(np.asarray(tags).tolist(), np.concatenate(data).tolist()))
        np.testing.assert_array_equal([got[i + 1] for i in range(mesh.n_elements)],
                                      mesh.cell_data["quality"])
    finally:
        gmsh.finalize()


def test_inp_one_surface_and_node_set_per_face_name(tmp_path, regions_and_shared_names):
    mesh = regions_and_shared_names
    text = write_mesh(mesh, tmp_path / "cube.inp").read_text()
    assert re.findall(r"^\*SURFACE, NAME=(\w+)", text, flags=re.M) == ["ZMIN", "ZMAX", "SIDES"]
    assert re.findall(r"^\*NSET, NSET=(\w+)", text, flags=re.M) == ["ZMIN", "ZMAX", "SIDES"]
    blocks = _blocks(text)
    sets = {re.search(r"ELSET=(\w+)", k).group(1): _ids(d) for k, d in blocks
            if k.startswith("*ELSET")}
    elements = {v[0]: v[1:] for k, d in blocks if k.startswith("*ELEMENT")
                for v in (_ids([x]) for x in d)}
    surface = [d for k, d in blocks if k == "*SURFACE, NAME=SIDES, TYPE=ELEMENT"][0]
    got = {tuple(sorted(elements[e][j] for j in FACE_NODES[int(s.split(",")[1].strip()[1:]) - 1]))
           for s in surface for e in sets[s.split(",")[0]]}
    side = np.isin(mesh.facet_markers, [m for m, n in mesh.marker_names.items() if n == "sides"])
    assert got == {tuple(sorted(f)) for f in (mesh.facets[side] + 1).tolist()}
    for r in range(3):
        assert sets[f"REGION_{r}"] == (np.flatnonzero(mesh.regions == r) + 1).tolist()
