"""The uniform tetrahedral baseline (hetmesh.tet.uniform) of the solids MMG remeshes from
their adaptive mesher's start: a closed triangulated surface and the non-zero voxels of a
mask. Each gets a mesh of one size with delta_max < delta_0, checked from the arrays alone
(the surface's planes; the mask's voxel centres and contour), with more tetrahedra than the
adaptive mesh at the same delta_0; the budget ends the search in one line; the CLI writes
it."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from hetmesh.cli import main
from hetmesh.errors import BudgetError
from hetmesh.io.model import load_model
from hetmesh.tet.api import mesh_model
from hetmesh.tet.masked import VoxelSolid
from hetmesh.tet.surface import SurfaceSolid
from hetmesh.tet.uniform import uniform_mask_at, uniform_model
from test_image_mask3d import N, boundary_triangles, check_mesh, part_mask, write_model
from test_tet import check_tet_mesh
from test_tet_surface import MODEL, cube, write_surface

#: the surface test solid: a 2 mm cube, metal fraction (x / 2)^3 (steep at x = 2)
SIDE = 2.0
FORMULA = "(x/2)**3"


def cube_model(tmp_path):
    V, F = cube(0.0, SIDE)
    write_surface(tmp_path / "cube.stl", V, F)
    path = tmp_path / "cube.toml"
    path.write_text(MODEL.format(file="cube.stl", formula=FORMULA)
                    + "\n[model]\nname = \"cube_stl\"\n")
    return load_model(path)


def _longest_edge(p, t):
    e = np.concatenate([t[:, [0, 1]], t[:, [0, 2]], t[:, [0, 3]], t[:, [1, 2]], t[:, [1, 3]],
                        t[:, [2, 3]]])
    return float(np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1).max())


def test_a_surface_solid_gets_a_verified_uniform_mesh(tmp_path):
    m = cube_model(tmp_path)
    assert isinstance(m.solid, SurfaceSolid)
    d0 = 0.35
    r = uniform_model(m, d0)
    assert r.info["placement"] == "uniform remeshed" and r.mesh.problems() == []
    # from the arrays: volumes, conformity, delta; every point of the boundary triangles
    # within the chord tolerance of the cube's faces, and the cube's volume within the
    # chord tolerance x its area
    bnd = check_tet_mesh(r.points, r.tets, lambda p: (p[:, 0] / SIDE) ** 3, d0)
    q = r.points[bnd]
    pts = np.concatenate([q, 0.5 * (q + q[:, [1, 2, 0]]), q.mean(axis=1, keepdims=True)],
                         axis=1).reshape(-1, 3)
    chord = 2e-3 * SIDE * np.sqrt(3)
    assert np.minimum(np.abs(pts), np.abs(pts - SIDE)).min(axis=1).max() <= chord
    assert (pts >= -chord).all() and (pts <= SIDE + chord).all()
    a, b, c, d = (r.points[r.tets[:, k]] for k in range(4))
    vol = np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)).sum() / 6
    assert abs(vol - SIDE ** 3) <= chord * 6 * SIDE ** 2
    # one size: no edge much longer than h, and the size search found the coarsest
    h = r.info["size"]
    assert _longest_edge(r.points, r.tets.astype(np.int64)) <= 2.0 * h
    hist = r.info["history"]
    assert any(not s["pass"] for s in hist) or len(hist) >= 2
    assert all(s["h"] <= h * 1.000001 for s in hist if s["pass"] and s["elements"] is not None
               and s["elements"] < len(r.tets))
    # the baseline needs more tetrahedra than the adaptive mesh grading to the steep side
    a = mesh_model(m, d0)
    assert len(r.tets) > len(a.tets), (len(r.tets), len(a.tets))


def graded_mask_model(tmp_path, n=N):
    """The mask test part with a grey volume that grows as the cube of the height (the
    metal fraction steep at the top, flat at the bottom: the adaptive mesh grades)."""
    path = write_model(tmp_path, part_mask(n))
    k = np.mgrid[0:n, 0:n, 0:n][0]
    np.save(tmp_path / "grey.npy", (k / (n - 1.0)) ** 3)
    return load_model(path)


@pytest.mark.slow  # 10-28 s: the default step stays under 10 minutes
def test_a_mask_solid_gets_a_verified_uniform_mesh(tmp_path):
    n = 10
    m = graded_mask_model(tmp_path, n)
    assert isinstance(m.solid, VoxelSolid)
    d0 = 0.15
    r = uniform_model(m, d0)
    assert r.info["placement"] == "uniform remeshed"
    # from the arrays: every voxel centre of the mask inside, every other one outside, the
    # boundary within half a voxel of the voxel faces, delta over the vertices
    check_mesh(r, part_mask(n), threshold=d0)
    p, t = r.points, r.tets.astype(np.int64)
    c = m.material.composition(p)
    assert ((c[t].max(axis=1) - c[t].min(axis=1)).max(axis=1)).max() < d0
    assert len(boundary_triangles(t)) == len(r.faces)
    names = {r.face_names[k - 1] for k in np.unique(r.face_markers)}
    assert names == {"outer", "cavity[0]"}
    a = mesh_model(m, d0)
    assert len(r.tets) > len(a.tets), (len(r.tets), len(a.tets))


def test_the_budget_ends_the_search_in_one_line(tmp_path):
    m = graded_mask_model(tmp_path, 10)
    with pytest.raises(BudgetError, match="^no uniform tetrahedral mesh meets delta_max < "
                                          "0.01 within the budget: ") as exc:
        uniform_model(m, 0.01, max_elements=5_000)
    assert "\n" not in str(exc.value)


def test_cli_uniform_on_a_mask(tmp_path, capsys):
    graded_mask_model(tmp_path, 10)
    path = tmp_path / "m.toml"
    out = tmp_path / "u.vtu"
    code = main(["uniform", str(path), "-d", "0.3", "-o", str(out)])
    o, err = capsys.readouterr()
    assert code == 0 and "tetrahedra" in o and err == ""
    assert meshio.read(out).cells[0].type == "tetra"
    out2 = tmp_path / "v.vtu"
    code = main(["uniform", str(path), "-d", "0.01", "-o", str(out2), "--max-elements",
                 "5000"])
    o, err = capsys.readouterr()
    assert code == 2 and len(err.strip().splitlines()) == 1 and "budget" in err
    assert not out2.exists()


def test_same_mask_same_uniform_mesh(tmp_path):
    m = graded_mask_model(tmp_path, 10)
    a, b = (uniform_mask_at(m.solid, m.material, 0.8, 0.3) for _ in range(2))
    assert a.points.tobytes() == b.points.tobytes() and a.tets.tobytes() == b.tets.tobytes()
    assert a.info["size"] == 0.8 and a.threshold == 0.3


@pytest.mark.slow  # about 70 s on a loaded 2-core machine
def test_a_label_volume_keeps_every_phase(tmp_path):
    """The phases of a label volume: no tetrahedron straddles two, delta in each phase."""
    from test_image_labels3d import check_phases, labels
    from test_image_labels3d import write as write_labels

    m = load_model(write_labels(tmp_path))
    d0 = 0.3
    r = uniform_model(m, d0)
    assert r.info["placement"] == "uniform remeshed"
    check_phases(r, labels(), m.material, d0, m.solid.phases)
    assert len(set(r.info["regions"].tolist())) == 3
