"""Label volumes: every label a phase with its own composition, the phases' contours embedded
as surfaces of the tetrahedral mesh (no tetrahedron straddles two phases), checked here
without hetmesh's own verification; bad input is one line with exit 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hetmesh.cli import main
from hetmesh.io.model import load_model
from hetmesh.tet.api import mesh_model
from tet_checks import tet_quality

N = 12  # voxels per edge (spacing 0.5: a 6 mm cube)


def labels(n=N) -> np.ndarray:
    """1 a matrix, 2 a ball, 3 a slab along one face, 0 a notch (outside with a mask)."""
    k, j, i = np.mgrid[0:n, 0:n, 0:n]
    c = (n - 1) / 2
    lab = np.ones((n, n, n), np.uint8)
    lab[(i - c) ** 2 + (j - c) ** 2 + (k - c) ** 2 < (0.3 * n) ** 2] = 2
    lab[j >= n - 3] = 3
    lab[(i < 3) & (k < 3)] = 0
    return lab


def grey(n=N) -> np.ndarray:
    k, j, i = np.mgrid[0:n, 0:n, 0:n]
    return (255 * (0.2 + 0.6 * i / (n - 1))).round().astype(np.uint8)


MODEL = """
[solid]
image = "{how}"
[material]
type = "image"
constituents = ["matrix", "metal"]
labels = "labels.npy"
file = "grey.npy"
spacing = 0.5
{phases}
"""

PHASES = """
[[material.phases]]
label = 1
composition = { metal = 0.1 }
[[material.phases]]
label = 2
name = "ball"
map = { linear = [0, 255], constituent = "metal" }
[[material.phases]]
label = 3
composition = { metal = 0.9 }
"""
ZERO = """
[[material.phases]]
label = 0
composition = { metal = 0.5 }
"""


def write(folder: Path, how="mask", phases=PHASES, lab=None) -> Path:
    np.save(folder / "labels.npy", labels() if lab is None else lab)
    np.save(folder / "grey.npy", grey())
    p = folder / "m.toml"
    p.write_text(MODEL.format(how=how, phases=phases))
    return p


def covering(P, T, centres) -> list[np.ndarray]:
    """For every centre, the tetrahedra containing it (closed), by brute force."""
    x = P[T]
    A = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]], axis=2)
    inv = np.linalg.inv(A)
    out = []
    for b in range(0, len(centres), 128):
        c = centres[b:b + 128]
        lam = np.einsum("tij,ctj->cti", inv, c[:, None, :] - x[None, :, 0])
        ok = (lam >= -1e-9).all(axis=2) & (lam.sum(axis=2) <= 1 + 1e-9)
        out.extend(np.flatnonzero(row) for row in ok)
    return out


def check_phases(r, lab, field, threshold, solid_labels):
    """No tetrahedron straddles two phases (each voxel centre only in tetrahedra of its own
    label, none outside the solid), delta per phase below delta_0, a valid mesh."""
    P, T = r.points, r.tets.astype(np.int64)
    assert r.mesh.problems() == []
    reg = np.asarray(r.info["regions"], np.int64)
    np.testing.assert_array_equal(r.mesh.cell_data["subregion"], reg)
    phases = np.array(solid_labels)
    n = lab.shape[0]
    k, j, i = np.mgrid[0:n, 0:n, 0:n]
    C = 0.25 + 0.5 * np.column_stack([i.ravel(), j.ravel(), k.ravel()]).astype(float)
    want = lab.ravel()
    for q, tets in enumerate(covering(P, T, C)):
        if want[q] in phases:
            assert len(tets) and (phases[reg[tets]] == want[q]).all(), q
        else:
            assert not len(tets), q
    # delta with every tetrahedron's vertices in its own phase
    comp = np.stack([field.composition(P[T[:, c]], region=reg) for c in range(4)], 1)
    d = (comp.max(axis=1) - comp.min(axis=1)).max(axis=1)
    assert d.max() < threshold
    # the constant phases are constant in their tetrahedra
    for ph, value in ((0, 0.1), (2, 0.9)):
        assert np.allclose(comp[reg == ph][..., 1], value)


@pytest.mark.slow  # 48 s: the default suite stays under 10 minutes
def test_label_volume_extent_and_cli(tmp_path):
    from hetmesh.io.read import read_mesh

    path = write(tmp_path, how="extent", phases=PHASES + ZERO)
    m = load_model(path)
    assert m.solid.phases == (0, 1, 2, 3)
    assert m.solid.volume == pytest.approx(6.0 ** 3)
    out = tmp_path / "out.vtu"
    assert main(["mesh", str(path), "-d", "0.3", "-o", str(out), "--quiet",
                 "--sampling", "pixels"]) == 0
    mesh = read_mesh(out)
    assert mesh.problems() == [] and set(np.unique(mesh.regions).tolist()) == {0, 1, 2, 3}
    # every tetrahedron in its own phase, over its vertices and the voxel centres it covers
    d = m.material.pixel_delta(mesh.points, mesh.cells, regions=mesh.regions)
    assert d.max() < 0.3


@pytest.mark.slow
def test_label_volume_phases_are_embedded_and_meet_the_angle_targets(tmp_path):
    """Three phases meeting along lines (the ball, the slab, the matrix, the notch), each
    embedded with its own composition; the smallest dihedral angle >= 10 degrees and its
    1st percentile >= 20. (The mean radius ratio of this small volume, most of whose
    tetrahedra touch an interface, is about 0.72; the example below reaches 0.75.)"""
    m = load_model(write(tmp_path))
    assert m.solid.phases == (1, 2, 3) and m.material.dim == 3
    assert m.material.region_names == ["label 1", "ball", "label 3"]
    r = mesh_model(m, 0.3)
    assert r.mesh.problems() == [] and r.delta.max() < 0.3
    check_phases(r, labels(), m.material, 0.3, m.solid.phases)
    assert len(set(r.info["regions"].tolist())) == 3
    dmin, _ = tet_quality(r.points, r.tets.astype(np.int64))
    assert dmin.min() >= 10.0, dmin.min()
    assert np.percentile(dmin, 1.0) >= 20.0, np.percentile(dmin, 1.0)


@pytest.mark.slow
def test_example_phase_volume_meets_the_quality_targets(tmp_path):
    """The example label volume (32^3 voxels): its three named phases embedded; smallest
    dihedral angle >= 10 degrees, its 1st percentile >= 20, mean radius ratio >= 0.75."""
    from hetmesh.material.image import write_examples

    models = write_examples(tmp_path, shape=(32, 64), volume=8, masked=8, phases=32)
    m = load_model(models["phase_volume"])
    assert m.solid.phases == (1, 2, 3)
    assert m.material.region_names == ["matrix", "inclusion", "fibre"]
    r = mesh_model(m, 0.3)
    assert r.delta.max() < 0.3 and r.mesh.problems() == []
    assert len(set(r.info["regions"].tolist())) == 3
    dmin, rr = tet_quality(r.points, r.tets.astype(np.int64))
    assert dmin.min() >= 10.0, dmin.min()
    assert np.percentile(dmin, 1.0) >= 20.0, np.percentile(dmin, 1.0)
    assert rr.mean() >= 0.75, rr.mean()


BAD = [
    ("mask", PHASES.split("[[material.phases]]\nlabel = 3")[0], None,
     "labels.npy: label 3 (405 voxels, the first at voxel (3, 9, 0)) has no composition: "
     "add a [[material.phases]] entry with label = 3"),
    ("extent", PHASES, None, "labels.npy: label 0 (108 voxels, the first at voxel (0, 0, 0)) "
                             "has no composition"),
    ("mask", PHASES, labels().astype(np.float32), "labels.npy: a label volume needs integer "
                                                  "voxels, got float32"),
    ("mask", PHASES, labels().astype(np.int16) - 2, "labels.npy: label -2 at voxel (0, 0, 0): "
                                                    "labels must be >= 0"),
    ("mask", PHASES + 'map = { linear = [0, 255], constituent = "metal" }', None,
     "m.toml: material.phases[2]: give either composition = {...} (a constant phase) or "
     "map = {...}"),
    ("mask", "map = { linear = [0, 255], constituent = \"metal\" }\n" + PHASES, None,
     "m.toml: material.map: with a label volume every phase has its own map"),
]


@pytest.mark.parametrize("how,phases,lab,message", BAD)
def test_bad_label_volumes_one_line_exit_2(tmp_path, capsys, how, phases, lab, message):
    model = write(tmp_path, how, phases, lab)
    out = tmp_path / "out.vtu"
    code = main(["mesh", str(model), "-d", "0.2", "-o", str(out)])
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and message in lines[0], err
    assert not out.exists()


def test_label_volume_in_a_given_solid_is_refused(tmp_path, capsys):
    model = write(tmp_path)
    model.write_text(model.read_text().replace('image = "mask"',
                                               'type = "box"\nmin = [0, 0, 0]\nmax = [5, 5, 5]'))
    assert main(["mesh", str(model), "-d", "0.2", "-o", str(tmp_path / "o.vtu")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "m.toml: solid: a label volume needs [solid] image = " in err[0]
