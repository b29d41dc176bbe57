"""Graded material sizes (hetmesh.tri.grading): the size field's Lipschitz limit, the floor it
puts on |grad f|, and the ``gradation`` option of ``generate`` and ``hetmesh mesh``."""

from __future__ import annotations

import numpy as np
import pytest

import hetmesh
from hetmesh.cli import main
from hetmesh.errors import OptionError
from hetmesh.testing import independent_check
from hetmesh.tri.grading import graded, material_grading

#: a plate with a narrow bump: |grad f| is large on the bump's flanks and nearly zero on most
#: of the plate, so the ungraded size jumps from tiny to ``max_size`` within a few elements
BUMP = """
[model]
name = "bump"

[domain.outer]
start = [0, 0]
path = [{ to = [2, 0] }, { to = [2, 1] }, { to = [0, 1] }, { to = [0, 0] }]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "0.2 + 0.6*exp(-((x - 0.6)**2 + (y - 0.55)**2)/0.004)"
"""


@pytest.fixture(scope="module")
def bump(tmp_path_factory):
    path = tmp_path_factory.mktemp("grading") / "bump.toml"
    path.write_text(BUMP, encoding="utf-8")
    return path


def test_graded_is_lipschitz_below_and_idempotent():
    rng = np.random.default_rng(3)
    H = rng.uniform(0.01, 1.0, (40, 60))
    step, grade = 0.05, 0.3
    G = graded(H, step, grade)
    assert np.all(G <= H + 1e-12)
    assert np.abs(np.diff(G, axis=0)).max() <= grade * step * (1 + 1e-12)
    assert np.abs(np.diff(G, axis=1)).max() <= grade * step * (1 + 1e-12)
    np.testing.assert_allclose(graded(G, step, grade), G)
    # the global minimum is kept, and a far node is at most min + grade * L1 distance
    j, i = np.unravel_index(np.argmin(H), H.shape)
    assert G[j, i] == pytest.approx(H[j, i])
    assert G[0, 0] <= H[j, i] + grade * step * (i + j) + 1e-12


def test_floor_ignores_the_outside_of_the_domain():
    """Lattice nodes outside the domain take ``h_max``: a field undefined (nan, a huge
    gradient) outside must not shrink the sizes inside."""
    def g(p):
        return np.where(p[:, 0] > 0.5, np.inf, 1.0)

    inside = lambda p: p[:, 0] <= 0.5  # noqa: E731
    fl = material_grading(g, inside, (0, 0, 1, 1), 0.1, 0.25, 0.3, cells=20)
    # 0.1 / 1.0 = 0.1 inside, nothing smaller anywhere: the floor is the gradient itself
    np.testing.assert_allclose(fl(np.array([[0.1, 0.5], [0.45, 0.2]])), 1.0)


def test_floor_grades_away_from_a_small_size():
    fl = material_grading(lambda p: np.where(np.hypot(p[:, 0] - 0.5, p[:, 1] - 0.5) < 0.05,
                                             100.0, 0.0),
                          lambda p: np.ones(len(p), bool), (0, 0, 1, 1), 0.1, 0.25, 0.3,
                          cells=100)
    d = np.array([0.1, 0.2, 0.3])
    h = 0.1 / fl(np.column_stack([0.5 + d, np.full(3, 0.5)]))
    # about h_min + grade * distance, never above h_max
    assert np.all(np.diff(h) > 0)
    assert np.all(h <= 0.001 + 0.3 * d + 0.3 * 0.02)
    assert np.all(h <= 0.25)


def test_gradation_saves_elements_on_a_narrow_bump(bump):
    """Graded sizes need fewer elements than the ungraded ones whose jumps the quality
    refinement grades afterwards; both meshes keep every guarantee."""
    m = hetmesh.load_model(bump)
    graded_run = hetmesh.generate(m, 0.1)
    plain = hetmesh.generate(m, 0.1, gradation=0)
    assert graded_run.options["gradation"] == 0.3 and plain.options["gradation"] == 0.0
    for r in (graded_run, plain):
        assert independent_check(r, m, 0.1) == []
    assert graded_run.stats.n_elements < 0.9 * plain.stats.n_elements
    assert graded_run.stats.q_min >= 0.6


@pytest.mark.parametrize("value", [-0.1, 11.0, float("nan"), "x"])
def test_bad_gradation(bump, value):
    with pytest.raises(OptionError, match="gradation"):
        hetmesh.generate(hetmesh.load_model(bump), 0.1, gradation=value)


def test_cli_gradation(bump, tmp_path, capsys):
    out = tmp_path / "m.vtu"
    assert main(["mesh", str(bump), "-d", "0.1", "-o", str(out), "--gradation", "0.5",
                 "--quiet"]) == 0
    assert out.exists()
    code = main(["mesh", str(bump), "-d", "0.1", "-o", str(tmp_path / "n.vtu"),
                 "--gradation", "-1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--gradation -1" in err[0], err
    assert not (tmp_path / "n.vtu").exists()


def test_cli_gradation_is_2d_only(tmp_path, capsys):
    code = main(["mesh", str(hetmesh.example_path("unit_cube")), "-d", "0.3", "-o",
                 str(tmp_path / "c.vtu"), "--gradation", "0.3"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--gradation is not available for 3D" in err[0], err
