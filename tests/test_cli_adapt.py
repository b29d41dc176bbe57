"""``hetmesh fea --adapt`` with the goal-oriented indicator, from the command line."""

import json

import pytest

import hetmesh
from hetmesh.cli.main import main

CHORD = 1e-3  # the refined family's start in the 3-D study (x the diameter)


@pytest.fixture(scope="module")
def cylinder_mesh(tmp_path_factory):
    model = hetmesh.load_model(hetmesh.example_path("graded_cylinder"))
    path = tmp_path_factory.mktemp("cyl") / "cyl.vtu"
    hetmesh.generate(model, 0.4, chord_tol=CHORD).mesh.write(path)
    return path


def test_goal_indicator_aims_at_the_named_probe(cylinder_mesh, tmp_path, capsys):
    model = hetmesh.example_path("graded_cylinder")
    rep, out = tmp_path / "a.json", tmp_path / "a.vtu"
    rc = main(["fea", str(model), "--mesh", str(cylinder_mesh), "--adapt", "1e-4", "-d",
               "0.4", "--adapt-steps", "1", "--adapt-fraction", "0.3", "--adapt-indicator",
               "goal", "--adapt-probes", " R1 ", "--adapt-edges", "stress", "--report", str(rep),
               "-o", str(out)])
    assert rc == 0, capsys.readouterr().err
    doc = json.loads(rep.read_text())
    adaptive = doc["adaptive"]
    assert adaptive["indicator"] == "goal" and adaptive["edges"] == "stress"
    assert [s["step"] for s in adaptive["steps"]] == [0, 1]
    first, last = adaptive["steps"]
    assert last["elements"] > first["elements"]
    assert hetmesh.io.read.read_mesh(out).n_elements == last["elements"]
    # the same run through the API: the CLI passed the indicator and the probe on
    from hetmesh.fea.adapt import adapt

    api = adapt(hetmesh.io.read.read_mesh(cylinder_mesh), hetmesh.load_model(model), 0.4,
                tolerance=1e-4, steps=1, fraction=0.3, indicator="goal", goal_probes=["R1"],
                edges="stress")
    assert [s["elements"] for s in api.steps] == [s["elements"] for s in adaptive["steps"]]


@pytest.mark.parametrize("argv, word", [
    (["--adapt-indicator", "goal"], "--adapt-indicator is an option of --adapt"),
    (["--adapt", "0.01", "-d", "0.4", "--adapt-probes", "R1"], "--adapt-indicator goal"),
    (["--adapt", "0.01", "-d", "0.4", "--adapt-indicator", "goal", "--adapt-probes", " , "],
     "--adapt-probes"),
    (["--adapt", "0.01", "-d", "0.4", "--adapt-indicator", "goal", "--adapt-probes", "R1,Q9"],
     "no probe named 'Q9'"),
    (["--adapt", "0.01", "-d", "0.4", "--adapt-indicator", "stress"], "--adapt-indicator"),
    (["--adapt", "0.01", "-d", "0.4", "--adapt-edges", "shortest"], "--adapt-edges"),
    (["--adapt-edges", "stress"], "--adapt-edges is an option of --adapt"),
])
def test_bad_goal_options_are_one_line_errors(cylinder_mesh, tmp_path, capsys, argv, word):
    out = tmp_path / "never.vtu"
    rc = main(["fea", str(hetmesh.example_path("graded_cylinder")), "--mesh",
               str(cylinder_mesh), "-o", str(out), *argv])
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert len(err.splitlines()) == 1 and word in err, err
    assert not out.exists()
