"""Interfaces of extruded and revolved 2D domains: the interface curves' sweeps are surfaces of
tetrahedron faces inside the mesh, recorded and written under their names; every claim is
recomputed here from the arrays (radii, faces, volumes), not by the mesher's own checks."""

from __future__ import annotations

import re

import meshio
import numpy as np
import pytest

import hetmesh
from hetmesh.cli import main
from hetmesh.io.abaqus3d import FACE_NODES
from hetmesh.io.export import write_mesh
from hetmesh.io.read import read_mesh
from hetmesh.tet.api import mesh_model

R_A, R_B, R_C, LENGTH = 28.0, 38.0, 8.0, 10.0
THRESHOLD = 0.3


def tet_faces(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every distinct face (sorted corners) and how many tetrahedra hold it."""
    t = np.asarray(tets, np.int64)
    f = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]])
    return np.unique(np.sort(f, axis=1), axis=0, return_counts=True)


def as_set(tris) -> set[tuple[int, ...]]:
    return {tuple(sorted(int(v) for v in f)) for f in np.asarray(tris)}


def cylinder_faces(points: np.ndarray, tets: np.ndarray, radius: float
                   ) -> tuple[set, np.ndarray]:
    """The faces of ``tets`` whose three corners lie on the cylinder of ``radius`` about z
    (to 1e-9 x the radius), and the number of tetrahedra holding each."""
    faces, held = tet_faces(tets)
    r = np.hypot(points[:, 0], points[:, 1])
    on = (np.abs(r[faces] - radius) <= 1e-9 * radius).all(axis=1)
    return as_set(faces[on]), held[on]


def area(points: np.ndarray, tris: np.ndarray) -> float:
    q = points[np.asarray(tris, np.int64)]
    return float(0.5 * np.linalg.norm(np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]),
                                      axis=1).sum())


@pytest.fixture(scope="module")
def ring():
    model = hetmesh.load_model(hetmesh.example_path("hft_ring_3d"))
    return model, mesh_model(model, THRESHOLD)


def interface_marker(mesh, name: str) -> int:
    (m,) = [m for m, n in mesh.marker_names.items() if n == name]
    return m


def test_the_interface_is_a_surface_of_tetrahedron_faces(ring):
    model, res = ring
    mesh = res.mesh
    p, t = np.asarray(mesh.points), np.asarray(mesh.cells)
    assert res.face_names == ("bottom", "top", "B[0]", "C[0]", "A[0]")
    rec = mesh.facets[mesh.facet_markers == interface_marker(mesh, "A[0]")]
    assert len(rec)
    # the recorded triangles are exactly the tetrahedron faces on the cylinder r = R_A, each
    # between two tetrahedra (inside the solid)
    on, held = cylinder_faces(p, t, R_A)
    assert as_set(rec) == on and len(on) == len(rec)
    assert (held == 2).all()
    # they cover the sweep: the side of the inscribed polygon's prism, within the chord
    # tolerance of the cylinder (2e-3 x the section's diameter, as in 2D)
    exact = 2 * np.pi * R_A * LENGTH
    assert exact * (1 - 1e-3) < area(p, rec) <= exact
    # the boundary faces are the tetrahedron faces of one tetrahedron, and the recorded
    # boundary is exactly them
    faces, count = tet_faces(t)
    bnd = mesh.facets[mesh.facet_markers != interface_marker(mesh, "A[0]")]
    assert as_set(bnd) == as_set(faces[count == 1])


def test_no_tetrahedron_straddles_the_interface(ring):
    model, res = ring
    p, t = res.points, res.tets.astype(np.int64)
    r = np.hypot(p[:, 0], p[:, 1])
    side = np.sign(np.where(np.abs(r - R_A) <= 1e-9 * R_A, 0.0, r - R_A))  # -1, 0 (on), 1
    s = side[t]
    assert not ((s.max(axis=1) > 0) & (s.min(axis=1) < 0)).any()
    inner = (s <= 0).all(axis=1)
    # every tetrahedron's subregion is its side's: one id inside A, another outside
    regions = np.asarray(res.mesh.regions)
    assert len(np.unique(regions[inner])) == 1 and len(np.unique(regions[~inner])) == 1
    assert regions[inner][0] != regions[~inner][0]
    # and the 2D field's subregion at the tetrahedra's centroids
    c = p[t].mean(axis=1)
    np.testing.assert_array_equal(model.material2d.region(c[:, :2]), regions)


def test_volumes_and_delta_recomputed(ring):
    model, res = ring
    p, t = res.points, res.tets.astype(np.int64)
    a, b, c, d = (p[t[:, k]] for k in range(4))
    vol = np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) / 6.0
    assert vol.min() > 0
    exact = np.pi * (R_B ** 2 - R_C ** 2) * LENGTH
    assert exact * (1 - 1e-2) < vol.sum() < exact
    # delta over the four corners, each evaluated in its tetrahedron's subregion
    regions = np.asarray(res.mesh.regions)
    f = model.material2d.composition(p[t].reshape(-1, 3)[:, :2], region=np.repeat(regions, 4))
    f = f.reshape(len(t), 4, -1)
    delta = (f.max(axis=1) - f.min(axis=1)).max(axis=1)
    assert delta.max() < THRESHOLD
    np.testing.assert_allclose(delta, res.delta, rtol=0, atol=1e-12)


def coordinate_set(points, tris) -> set:
    """Triangles as sets of their corners' coordinates (rounded to 1e-9)."""
    q = np.round(np.asarray(points)[np.asarray(tris, np.int64)], 9)
    return {tuple(sorted(map(tuple, t.tolist()))) for t in q}


def test_msh_has_the_interface_as_a_physical_surface(tmp_path, ring):
    _, res = ring
    mesh = res.mesh
    path = write_mesh(mesh, tmp_path / "ring.msh")
    want = mesh.facets[mesh.facet_markers == interface_marker(mesh, "A[0]")]
    # meshio (another reader): a physical surface "A[0]" holding the interface triangles
    m = meshio.read(path)
    tag, dim = m.field_data["A[0]"]
    assert dim == 2
    tris = [c.data for c, ph in zip(m.cells, m.cell_data["gmsh:physical"])
            if c.type == "triangle" and (ph == tag).all()]
    assert coordinate_set(m.points, np.concatenate(tris)) == coordinate_set(mesh.points, want)
    # a physical volume per subregion
    assert sorted(k for k, (_, d) in m.field_data.items() if d == 3) == ["region_0", "region_1"]
    # hetmesh's reader: the same facets under the same name
    back = read_mesh(path)
    (mb,) = [k for k, n in back.marker_names.items() if n == "A[0]"]
    assert as_set(back.facets[back.facet_markers == mb]) == as_set(want)
    np.testing.assert_array_equal(back.cells, mesh.cells)


def test_inp_has_the_interface_surface_and_node_set(tmp_path, ring):
    _, res = ring
    mesh = res.mesh
    text = write_mesh(mesh, tmp_path / "ring.inp").read_text()
    surfaces = re.findall(r"^\*SURFACE, NAME=(\w+)", text, flags=re.M)
    assert len(surfaces) == 5
    blocks: list[tuple[str, list[str]]] = []
    for line in text.splitlines():
        if line.startswith("*") and not line.startswith("**"):
            blocks.append((line, []))
        elif blocks:
            blocks[-1][1].append(line)

    def ids(lines):
        return [int(x) for line in lines for x in line.split(",") if x.strip()]

    elements = {v[0]: v[1:] for k, d in blocks if k.startswith("*ELEMENT")
                for v in (ids([x]) for x in d)}
    sets = {re.search(r"ELSET=(\w+)", k).group(1): ids(d) for k, d in blocks
            if k.startswith("*ELSET")}
    want = mesh.facets[mesh.facet_markers == interface_marker(mesh, "A[0]")] + 1
    # the interface's surface: the surface whose element faces are the interface triangles
    name = [s for s in surfaces if s.startswith("A")][0]
    body = [d for k, d in blocks if k == f"*SURFACE, NAME={name}, TYPE=ELEMENT"][0]
    got = {tuple(sorted(elements[e][j] for j in FACE_NODES[int(s.split(",")[1].strip()[1:]) - 1]))
           for s in body for e in sets[s.split(",")[0]]}
    assert got == as_set(want)
    nodes = [d for k, d in blocks if k == f"*NSET, NSET={name}"][0]
    assert ids(nodes) == np.unique(want).tolist()
    regions = np.asarray(mesh.regions)
    for r in np.unique(regions):
        assert sets[f"REGION_{r}"] == (np.flatnonzero(regions == r) + 1).tolist()


REVOLVED = """
[model]
name = "seamed_ring"

[solid]
type = "revolution"
angle = 90

[domain.outer]
start = [20, 0]
path = [
  {{ to = [25, 0], name = "bottom" }},
  {{ to = [30, 0], name = "bottom" }},
  {{ to = [30, 10], name = "outside" }},
  {{ to = [25, 10], name = "top" }},
  {{ to = [20, 10], name = "top" }},
  {{ to = [20, 0], name = "inside" }},
]

[[domain.interfaces]]
name = "bond"
start = [25, 0]
path = [{{ to = [25, 10] }}]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""


def test_a_revolved_interface_is_a_surface_of_tetrahedron_faces(tmp_path):
    path = tmp_path / "seamed_ring.toml"
    path.write_text(REVOLVED.format(formula="((sqrt(x**2 + y**2) - 20)/10)**2"))
    model = hetmesh.load_model(path)
    res = mesh_model(model, THRESHOLD)
    p, t = res.points, res.tets.astype(np.int64)
    marker = res.face_names.index("bond[0]") + 1
    rec = res.faces[res.face_markers == marker]
    on, held = cylinder_faces(p, t, 25.0)
    assert len(rec) and as_set(rec) == on and (held == 2).all()
    exact = 0.5 * np.pi * 25.0 * 10.0  # a quarter of the cylinder r = 25, 10 high
    assert exact * (1 - 1e-3) < area(p, rec) <= exact
    r = np.hypot(p[:, 0], p[:, 1])
    s = np.sign(np.where(np.abs(r - 25.0) <= 1e-9 * 25.0, 0.0, r - 25.0))[t]
    assert not ((s.max(axis=1) > 0) & (s.min(axis=1) < 0)).any()
    a, b, c, d = (p[t[:, k]] for k in range(4))
    assert (np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) > 0).all()


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


EXTRUDED = """
[model]
name = "seamed_plate"

[solid]
type = "extrusion"
length = {length}

[domain.outer]
start = [0, 0]
path = [{{ to = [5, 0] }}, {{ to = [10, 0] }}, {{ to = [10, 4] }}, {{ to = [5, 4] }},
        {{ to = [0, 4] }}, {{ to = [0, 0] }}]

[[domain.interfaces]]
name = "seam"
start = [5, 0]
path = [{{ to = [5, 4] }}]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "{formula}"
"""


@pytest.mark.parametrize("text, key, message", [
    (EXTRUDED.format(length=0, formula="x/10"), "solid.length",
     "extrusion length must be positive, got 0"),
    (EXTRUDED.format(length=-2, formula="x/10"), "solid.length",
     "extrusion length must be positive, got -2"),
    (EXTRUDED.format(length=3, formula="where(z < 1 + 0.1*x, 0.2, 0.6) + 0.01*x"),
     "material.composition.metal", "the subregion changes with z near"),
    (REVOLVED.format(formula="where(atan2(y, x) < 0.5 + 0.02*z, 0.2, 0.6)"),
     "material.composition.metal", "the subregion changes with the angle near"),
], ids=["length-0", "length-negative", "extrusion-jump-in-z", "revolution-jump-in-angle"])
def test_bad_interface_models_fail_in_one_line(tmp_path, capsys, text, key, message):
    path = tmp_path / "m.toml"
    path.write_text(text)
    out = tmp_path / "m.msh"
    code, _, err = run(["mesh", path, "--threshold", THRESHOLD, "--output", out], capsys)
    assert code == 2
    line = err.strip()
    assert "\n" not in line and f"{key}: " in line and message in line, line
    assert not out.exists()


def test_an_extruded_seam_with_a_formula_is_embedded(tmp_path):
    path = tmp_path / "seamed_plate.toml"
    path.write_text(EXTRUDED.format(length=3, formula="(x/10)**2"))
    res = mesh_model(hetmesh.load_model(path), 0.2)
    p, t = res.points, res.tets.astype(np.int64)
    marker = res.face_names.index("seam[0]") + 1
    rec = res.faces[res.face_markers == marker]
    faces, held = tet_faces(t)
    on = (p[faces][..., 0] == 5.0).all(axis=1)
    assert as_set(rec) == as_set(faces[on]) and (held[on] == 2).all()
    assert area(p, rec) == pytest.approx(4.0 * 3.0, rel=1e-12)


def test_uniform_sweeps_record_the_interfaces_too(tmp_path):
    from hetmesh.tet.uniform import uniform_model

    path = tmp_path / "seamed_ring.toml"
    path.write_text(REVOLVED.format(formula="((sqrt(x**2 + y**2) - 20)/10)**2"))
    for model, name, radius in [
            (hetmesh.load_model(hetmesh.example_path("hft_ring_3d")), "A[0]", R_A),
            (hetmesh.load_model(path), "bond[0]", 25.0)]:
        res = uniform_model(model, THRESHOLD)
        p, t = res.points, res.tets.astype(np.int64)
        rec = res.faces[res.face_markers == res.face_names.index(name) + 1]
        on, held = cylinder_faces(p, t, radius)
        assert len(rec) and as_set(rec) == on and (held == 2).all()
