"""Dense and certified sampling on tetrahedral meshes: every tetrahedron below delta_0 by
the chosen sampling, checked again here with a finer lattice and the independent checks."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import hetmesh
from hetmesh.certify import certified_delta
from hetmesh.metrics import delta_dense
from hetmesh.tet.sampling import bisect_faces
from test_tet import check_tet_mesh

BUMP = """
[model]
name = "bump_cube"

[solid]
type = "box"
min = [0, 0, 0]
max = [1, 1, 1]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "0.3*z + 0.5*exp(-((x - 0.43)**2 + (y - 0.57)**2 + (z - 0.51)**2)/0.004)"
"""


@pytest.fixture(scope="module")
def bump_model(tmp_path_factory):
    p = tmp_path_factory.mktemp("bump") / "bump_cube.toml"
    p.write_text(BUMP, encoding="utf-8")
    return hetmesh.load_model(p)


@pytest.mark.parametrize("sampling", ["dense", "certified"])
def test_a_peak_between_vertices_is_met_by_dense_and_certified_sampling(bump_model, sampling):
    d0 = 0.2
    vert = hetmesh.generate(bump_model, d0)
    m = vert.mesh
    # the vertex mesh misses the peak inside some tetrahedra; the 35-point lattice sees it
    assert delta_dense(bump_model.material, m.points, m.cells).max() >= d0
    r = hetmesh.generate(bump_model, d0, sampling=sampling)
    M = r.mesh
    # volumes, conformity, closed boundary, the box's faces: the independent helper
    check_tet_mesh(M.points, M.cells, lambda p: np.zeros(len(p)), d0,
                   box_bounds=(np.zeros(3), np.ones(3)))
    assert r.stats.delta_max < d0
    assert r.options["sampling"] == sampling
    bound = certified_delta(bump_model.material, M.points, M.cells, threshold=d0)
    if sampling == "certified":  # proven inside every tetrahedron (decided against d0)
        assert bound.max() < d0
    assert delta_dense(bump_model.material, M.points, M.cells, order=4).max() < d0
    assert len(M.cells) >= len(m.cells)
    # the named faces are the box's six, whole
    assert set(M.marker_names.values()) >= {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"}


def test_certified_sampling_keeps_the_subregions_of_an_extruded_feature_tree():
    model = hetmesh.load_model(hetmesh.example_path("fgm_plate_3d"))
    r = hetmesh.generate(model, 0.3, sampling="certified")
    M = r.mesh
    assert M.regions is not None and len(np.unique(M.regions)) > 1
    b = certified_delta(model.material, M.points, M.cells, regions=M.regions,
                        threshold=0.3)
    assert b.max() < 0.3
    check_tet_mesh(M.points, M.cells, lambda p: np.zeros(len(p)), 0.3)


def test_certified_sampling_on_a_revolved_part_splits_and_stays_on_its_faces():
    model = hetmesh.load_model(hetmesh.example_path("graded_cylinder"))
    r = hetmesh.generate(model, 0.2, sampling="certified")
    M = r.mesh
    check_tet_mesh(M.points, M.cells, lambda p: np.zeros(len(p)), 0.2)
    assert certified_delta(model.material, M.points, M.cells, threshold=0.2).max() < 0.2
    v = hetmesh.generate(model, 0.2)
    # bisection never moves the boundary: the same total area per named face
    for name in set(v.mesh.marker_names.values()):
        def area(mesh, nm=name):
            ids = [k for k, n in mesh.marker_names.items() if n == nm]
            f = mesh.facets[np.isin(mesh.facet_markers, ids)]
            p = mesh.points[f]
            return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                                        axis=1).sum()
        assert area(M) == pytest.approx(area(v.mesh), rel=1e-9), name


def test_bisect_faces_splits_only_the_triangles_holding_a_split_edge():
    faces = np.array([[0, 1, 2], [1, 3, 2], [4, 5, 6]])
    f, m = bisect_faces(faces, np.array([1, 2, 3]), np.array([[2, 1], [4, 6]]), 10)
    assert len(f) == 6 and sorted(m.tolist()) == [1, 1, 2, 2, 3, 3]
    assert {10, 11} <= set(f.ravel().tolist())
    assert not ({1, 2} <= set(f[m == 1][0]) and {1, 2} <= set(f[m == 1][1]))


def test_cli_mesh_and_stats_take_dense_and_certified_sampling_in_3d(tmp_path):
    out = tmp_path / "cube.vtu"
    ex = str(hetmesh.example_path("unit_cube"))
    run = subprocess.run([sys.executable, "-m", "hetmesh", "mesh", ex, "-d", "0.2", "-o",
                          str(out), "--sampling", "certified", "--quiet"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    st = subprocess.run([sys.executable, "-m", "hetmesh", "stats", str(out), "-m", ex,
                         "--sampling", "dense", "--json"], capture_output=True, text=True)
    assert st.returncode == 0, st.stderr
    assert json.loads(st.stdout)["delta_max"] < 0.2


def test_certified_sampling_on_a_solid_of_primitives():
    model = hetmesh.load_model(hetmesh.example_path("graded_sphere"))
    r = hetmesh.generate(model, 0.3, sampling="certified")
    M = r.mesh
    check_tet_mesh(M.points, M.cells, lambda p: np.zeros(len(p)), 0.3)
    assert certified_delta(model.material, M.points, M.cells, threshold=0.3).max() < 0.3
    assert set(M.marker_names.values()) == {"inner", "outer", "xmin", "ymin", "zmin"}
