"""The command line: ``main([...])`` with ``tmp_path`` and ``capsys`` (meshio, optimesh style)."""

from __future__ import annotations

import json
import os
from importlib import resources
from pathlib import Path

import pytest

from hetmesh.cli import main

THRESHOLD = 0.1  # coarse: a few hundred elements on the power plate


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    """The packaged power-plate example, as a real file."""
    src = resources.files("hetmesh") / "examples" / "power_plate.toml"
    path = tmp_path_factory.mktemp("model") / "power_plate.toml"
    path.write_text(src.read_text(encoding="utf-8"), encoding="utf-8")
    return path


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code, out, err, *, contains: str = "") -> str:
    assert code == 2, (code, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hetmesh: error:"), err
    assert "Traceback" not in err
    assert contains in lines[0], lines[0]
    return lines[0]


# -- help and version ------------------------------------------------------------------

@pytest.mark.parametrize("command", [[], ["mesh"], ["uniform"], ["stats"], ["demo"]])
def test_help_exits_0(command, capsys):
    code, out, err = run([*command, "--help"], capsys)
    assert code == 0
    assert out.startswith("usage: hetmesh")
    assert err == ""


def test_version(capsys):
    code, out, _ = run(["--version"], capsys)
    assert code == 0
    assert out.startswith("hetmesh ")


def test_no_command_is_a_usage_error(capsys):
    assert_one_line_error(*run([], capsys), contains="COMMAND")


# -- bad input: exit 2, one line, nothing written ---------------------------------------

def mesh_argv(model, out, *extra, command="mesh", threshold=THRESHOLD):
    return [command, model, "--threshold", threshold, "--output", out, "--quiet", *extra]


@pytest.mark.parametrize("command", ["mesh", "uniform"])
@pytest.mark.parametrize("extra, contains", [
    (["--threshold", "0"], "--threshold 0 is outside (0, 1)"),
    (["--threshold", "-1"], "--threshold -1 is outside (0, 1)"),
    (["--threshold", "1"], "--threshold"),
    (["--threshold", "nan"], "--threshold"),
    (["--threshold", "abc"], "--threshold"),
    (["--min-angle", "40"], "--min-angle 40 is outside (0, 34]"),
    (["--min-angle", "0"], "--min-angle 0 is outside (0, 34]"),
    (["--max-elements", "0"], "--max-elements 0"),
    (["--max-elements", "1.5"], "--max-elements"),
    (["--sampling", "sparse"], "--sampling"),
    (["--chord-tol", "0"], "--chord-tol 0 is outside [1e-07, 0.05]"),
    (["--chord-tol", "0.5"], "--chord-tol 0.5 is outside"),
    (["--chord-tol", "nan"], "--chord-tol nan"),
])
def test_bad_options(command, extra, contains, model, tmp_path, capsys):
    out = tmp_path / "out.vtu"
    argv = mesh_argv(model, out, command=command)
    if extra[0] == "--threshold":
        argv[argv.index("--threshold") + 1] = extra[1]
    else:
        argv += extra
    assert_one_line_error(*run(argv, capsys), contains=contains)
    assert not out.exists()


@pytest.mark.parametrize("extra, contains", [
    (["--max-size", "0"], "--max-size 0"),
    (["--max-size", "-2"], "--max-size -2"),
    (["--seed", "-1"], "--seed -1"),
    (["--method", "magic"], "--method"),
])
def test_bad_adaptive_options(extra, contains, model, tmp_path, capsys):
    out = tmp_path / "out.vtu"
    assert_one_line_error(*run(mesh_argv(model, out, *extra), capsys), contains=contains)
    assert not out.exists()


def test_missing_required_option(model, tmp_path, capsys):
    assert_one_line_error(*run(["mesh", model, "--output", tmp_path / "o.vtu"], capsys),
                          contains="--threshold")


def test_nonexistent_model(tmp_path, capsys):
    out = tmp_path / "out.vtu"
    line = assert_one_line_error(*run(mesh_argv(tmp_path / "nope.toml", out), capsys))
    assert "nope.toml" in line
    assert not out.exists()


def test_model_not_toml(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("this is [not toml\n")
    out = tmp_path / "out.vtu"
    line = assert_one_line_error(*run(mesh_argv(bad, out), capsys))
    assert "bad.toml" in line
    assert not out.exists()


def test_existing_output_untouched_when_model_is_bad(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[model]\nname = 3\nfoo = [\n")
    out = tmp_path / "out.vtu"
    out.write_text("keep me")
    stats = tmp_path / "stats.json"
    stats.write_text("{}")
    assert_one_line_error(*run(mesh_argv(bad, out, "--stats", stats), capsys))
    assert out.read_text() == "keep me"
    assert stats.read_text() == "{}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml", "out.vtu", "stats.json"]


def test_unknown_output_extension(model, tmp_path, capsys):
    out = tmp_path / "out.stl"
    assert_one_line_error(*run(mesh_argv(model, out), capsys), contains="--output")
    assert not out.exists()


def test_unknown_plot_extension(model, tmp_path, capsys):
    out = tmp_path / "out.vtu"
    assert_one_line_error(*run(mesh_argv(model, out, "--plot", tmp_path / "p.xyz"), capsys),
                          contains="--plot")
    assert not out.exists()


def test_output_directory_missing(model, tmp_path, capsys):
    out = tmp_path / "missing" / "out.vtu"
    assert_one_line_error(*run(mesh_argv(model, out), capsys), contains="does not exist")
    assert not out.parent.exists()


def test_output_directory_is_a_file(model, tmp_path, capsys):
    (tmp_path / "file").write_text("")
    out = tmp_path / "file" / "out.vtu"
    assert_one_line_error(*run(mesh_argv(model, out), capsys), contains="not a directory")


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0,
                    reason="root can write to read-only directories")
def test_output_directory_unwritable(model, tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        assert_one_line_error(*run(mesh_argv(model, ro / "out.vtu"), capsys),
                              contains="not writable")
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o700)


def test_output_directory_unwritable_simulated(model, tmp_path, capsys, monkeypatch):
    """As above, also when running as root: creating a file in the directory fails."""
    import hetmesh.cli.mesh

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(hetmesh.cli.mesh.tempfile, "mkstemp", denied)
    out = tmp_path / "out.vtu"
    assert_one_line_error(*run(mesh_argv(model, out), capsys), contains="not writable")
    assert not out.exists()


def test_stats_output_unwritable(model, tmp_path, capsys):
    out = tmp_path / "out.vtu"
    assert_one_line_error(*run(mesh_argv(model, out, "--stats", tmp_path / "no" / "s.json"),
                               capsys), contains="--stats")
    assert not out.exists()


def test_output_is_the_model(model, tmp_path, capsys):
    copy = tmp_path / "m.vtu"
    copy.write_text(model.read_text())
    before = copy.read_text()
    assert_one_line_error(*run(mesh_argv(copy, tmp_path / "o.vtu", "--stats", copy), capsys),
                          contains="same file")
    assert copy.read_text() == before


def test_stats_missing_mesh(model, tmp_path, capsys):
    assert_one_line_error(*run(["stats", tmp_path / "none.vtu", "--model", model], capsys),
                          contains="none.vtu")


def test_demo_out_is_a_file(tmp_path, capsys):
    f = tmp_path / "f"
    f.write_text("x")
    assert_one_line_error(*run(["demo", "--out", f, "--quiet"], capsys), contains="--out")


def test_demo_bad_threshold(tmp_path, capsys):
    assert_one_line_error(*run(["demo", "--out", tmp_path / "d", "--threshold", "2"], capsys),
                          contains="--threshold 2")
    assert not (tmp_path / "d").exists()


# -- unexpected failures ---------------------------------------------------------------

def test_keyboard_interrupt_exits_130(model, tmp_path, capsys, monkeypatch):
    import hetmesh.io.model

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(hetmesh.io.model, "load_model", interrupted)
    code, _, err = run(mesh_argv(model, tmp_path / "o.vtu"), capsys)
    assert code == 130
    assert "Traceback" not in err


def test_internal_error_is_one_line_or_traceback_with_debug(model, tmp_path, capsys, monkeypatch):
    import hetmesh.io.model

    def bug(*a, **k):
        raise ZeroDivisionError("boom")

    monkeypatch.setattr(hetmesh.io.model, "load_model", bug)
    code, _, err = run(mesh_argv(model, tmp_path / "o.vtu"), capsys)
    assert code == 1
    assert err.strip().splitlines() == [
        "hetmesh: error: internal error: ZeroDivisionError: boom (a bug in hetmesh: please "
        "report it with the model file and the command; --debug shows the traceback)"]
    with pytest.raises(ZeroDivisionError):
        main([str(a) for a in mesh_argv(model, tmp_path / "o.vtu", "--debug")])


def test_help_states_the_exit_codes(capsys):
    code, out, _ = run(["--help"], capsys)
    assert code == 0
    text = " ".join(out.split())
    assert "2 bad input" in text and "element budget" in text
    assert "1 system error, or internal error" in text and "please report it" in text


def _error_classes():
    import hetmesh.errors as E

    return [getattr(E, n) for n in E.__all__]


@pytest.mark.parametrize("cls", _error_classes(), ids=lambda c: c.__name__)
def test_every_error_class_has_its_exit_code(cls, model, tmp_path, capsys, monkeypatch):
    """Bad input (and the budget the user chose) exits 2 with the message; hetmesh failing
    on valid input (MeshingError, VerificationError) exits 1 asking for a report."""
    import hetmesh.io.model
    from hetmesh.errors import BudgetError, MeshDataError, MeshingError

    def fail(*a, **k):
        raise cls("something went wrong")

    monkeypatch.setattr(hetmesh.io.model, "load_model", fail)
    code, out, err = run(mesh_argv(model, tmp_path / "o.vtu"), capsys)
    internal = issubclass(cls, MeshingError) and not issubclass(cls, (BudgetError,
                                                                     MeshDataError))
    assert code == (1 if internal else 2) == cls.exit_code
    assert cls.internal is internal
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    if internal:
        assert lines[0].startswith("hetmesh: error: internal error: something went wrong")
        assert "please report it" in lines[0] and "--debug" in lines[0]
    else:
        assert lines[0] == "hetmesh: error: something went wrong"
    assert not (tmp_path / "o.vtu").exists()


def test_a_verification_failure_on_valid_input_is_an_internal_error(model, tmp_path, capsys,
                                                                   monkeypatch):
    import hetmesh.tri.pipeline
    from hetmesh.errors import VerificationError

    def failing_finish(*a, **k):
        raise VerificationError("the mesh failed verification: 3 degenerate or inverted "
                                "triangles (first #7)")

    monkeypatch.setattr(hetmesh.tri.pipeline, "finish", failing_finish)
    out = tmp_path / "o.vtu"
    code, _, err = run(mesh_argv(model, out), capsys)
    assert code == 1
    assert err.strip().splitlines() == [
        "hetmesh: error: internal error: the mesh failed verification: 3 degenerate or "
        "inverted triangles (first #7) (a bug in hetmesh: please report it with the model "
        "file and the command; --debug shows the traceback)"]
    assert not out.exists()
    with pytest.raises(VerificationError):
        main([str(a) for a in mesh_argv(model, out, "--debug")])


def test_a_stalled_refinement_is_internal_and_a_budget_overrun_bad_input(model, tmp_path,
                                                                         capsys, monkeypatch):
    code, _, err = run(mesh_argv(model, tmp_path / "o.vtu", "--max-elements", "10"), capsys)
    assert code == 2 and "budget" in err and "internal" not in err
    import hetmesh.tri.pipeline
    from hetmesh.errors import MeshingError

    def stalled(*a, **k):
        raise MeshingError("refinement stalled in round 3 with 2 elements at delta >= 0.1")

    monkeypatch.setattr(hetmesh.tri.pipeline, "repair", stalled)
    code, _, err = run(mesh_argv(model, tmp_path / "o.vtu", "--method", "cvt"), capsys)
    assert code == 1 and len(err.strip().splitlines()) == 1
    assert err.startswith("hetmesh: error: internal error: refinement stalled")


def _noisy(then=None):
    """A stand-in for ``load_model`` that logs warnings and lets numpy warn (twice each),
    then raises ``then`` or loads the model."""
    import logging

    import numpy as np

    import hetmesh.io.model

    real = hetmesh.io.model.load_model

    def load(path, *a, **k):
        for _ in range(2):
            logging.getLogger("hetmesh.tri.pipeline").warning(
                "the angle floor was given up\nsomewhere")
            logging.getLogger("somelib").warning("a library warning")
            np.log(np.array([-1.0]))  # RuntimeWarning: invalid value encountered in log
        if then is not None:
            raise then
        return real(path, *a, **k)

    return load


@pytest.mark.parametrize("exc", ["bad input", "internal", "bug"])
def test_a_failing_run_prints_exactly_one_line(exc, model, tmp_path, capsys, monkeypatch):
    """Warnings logged or raised before the error (numpy's RuntimeWarning with its source
    line, hetmesh's and other libraries' logged warnings) do not reach stderr."""
    import hetmesh.io.model
    from hetmesh.errors import GeometryError, VerificationError

    then = {"bad input": GeometryError("outer: self-intersection at (1, 2)"),
            "internal": VerificationError("the mesh failed verification: x"),
            "bug": ZeroDivisionError("boom")}[exc]
    monkeypatch.setattr(hetmesh.io.model, "load_model", _noisy(then))
    code, out, err = run(mesh_argv(model, tmp_path / "o.vtu"), capsys)
    assert code == (2 if exc == "bad input" else 1)
    assert len(err.splitlines()) == 1 and err.startswith("hetmesh: error: "), err
    assert out == ""


def test_warnings_of_a_successful_run_come_after_it_one_line_each(model, tmp_path, capsys,
                                                                  monkeypatch):
    import hetmesh.io.model

    monkeypatch.setattr(hetmesh.io.model, "load_model", _noisy())
    for extra in ([], ["--quiet"]):
        code, out, err = run([a for a in mesh_argv(model, tmp_path / "o.vtu", *extra)
                              if extra or a != "--quiet"], capsys)
        assert code == 0
        lines = err.splitlines()
        assert lines[0] == ("hetmesh: warning: the angle floor was given up somewhere "
                            "(2 times)")
        assert lines[1] == "hetmesh: warning: a library warning (2 times)"
        assert lines[2].startswith("hetmesh: warning: RuntimeWarning: invalid value "
                                   "encountered in log (")
        assert len(lines) == 3, err  # numpy's source line is never printed
        assert "np.log" not in err
        assert ("wrote" in out) is not bool(extra)


def test_verbose_streams_the_log(model, tmp_path, capsys):
    code, _, err = run(mesh_argv(model, tmp_path / "o.vtu", "-v"), capsys)
    assert code == 0
    assert any(line.startswith("hetmesh: info: hetmesh.") for line in err.splitlines())


# -- meshing ---------------------------------------------------------------------------

@pytest.fixture(scope="module")
def meshed(model, tmp_path_factory):
    """``hetmesh mesh`` at a coarse threshold, with a plot and stats JSON."""
    d = tmp_path_factory.mktemp("mesh")
    out, stats, plot = d / "plate.vtu", d / "plate.json", d / "plate.png"
    code = main([str(a) for a in mesh_argv(model, out, "--stats", stats, "--plot", plot,
                                           "--seed", "3")])
    assert code == 0
    return out, stats, plot


def test_mesh_writes_mesh_stats_and_plot(meshed):
    from hetmesh.io.read import read_mesh

    out, stats, plot = meshed
    doc = json.loads(stats.read_text())
    assert doc["stats"]["delta_max"] < THRESHOLD
    assert doc["threshold"] == THRESHOLD
    assert doc["model"]["name"] == "power_plate"
    assert doc["command"] == "mesh"
    assert doc["options"]["seed"] == 3
    assert doc["options"]["sampling"] == "vertices"
    assert doc["options"]["chord_tol"] == 1e-3
    # the dense lattice's maximum beside the guarantee of the sampling (the vertices')
    assert 0.9 * THRESHOLD < doc["stats"]["delta_max_dense"] < 1.1 * THRESHOLD
    assert doc["hetmesh_version"]
    assert isinstance(doc["history"], list) and doc["history"]
    assert all("elements" in h and "delta_max" in h for h in doc["history"])
    assert doc["timings"]["wall"] > 0
    mesh = read_mesh(out)
    assert mesh.n_elements == doc["stats"]["n_elements"]
    assert mesh.n_points == doc["stats"]["n_points"]
    assert mesh.is_valid()
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    leftovers = [p.name for p in out.parent.iterdir() if p.name.startswith(".")]
    assert leftovers == []


def test_mesh_prints_summary(model, tmp_path, capsys):
    out = tmp_path / "o.msh"
    argv = [a for a in mesh_argv(model, out) if a != "--quiet"]
    code, stdout, _ = run(argv, capsys)
    assert code == 0
    assert out.exists()
    for label in ("Np", "Ne", "q_min", "q_avg", "delta_min", "delta_avg", "delta_max",
                  "delta_max_dense"):
        assert label in stdout
    assert f"wrote {out}" in stdout


def test_a_long_output_path_is_printed_on_one_line(model, tmp_path, capsys):
    """Output is not a terminal here (rich would wrap at 80 columns): the written file's
    path stays whole on its line, so scripts can take it from the output."""
    out = tmp_path / ("a_folder_with_a_rather_long_name_" * 4) / "the_mesh_of_the_plate.vtu"
    out.parent.mkdir()
    argv = [a for a in mesh_argv(model, out) if a != "--quiet"]
    code, stdout, _ = run(argv, capsys)
    assert code == 0 and len(str(out)) > 120
    assert f"wrote {out}" in stdout.splitlines()


def test_progress_bar_on_a_terminal(model, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("TTY_COMPATIBLE", "1")  # rich: treat stderr (and stdout) as a terminal
    out = tmp_path / "o.vtu"
    argv = [a for a in mesh_argv(model, out) if a != "--quiet"]
    code, stdout, err = run(argv, capsys)
    assert code == 0, err
    assert "Traceback" not in err
    assert "delta_max" in stdout
    assert out.exists()


def test_uniform_writes_mesh_and_stats(model, meshed, tmp_path, capsys):
    out, stats = tmp_path / "u.vtu", tmp_path / "u.json"
    code, _, err = run(mesh_argv(model, out, "--stats", stats, command="uniform"), capsys)
    assert code == 0, err
    doc = json.loads(stats.read_text())
    assert doc["command"] == "uniform"
    assert doc["stats"]["delta_max"] < THRESHOLD
    adaptive = json.loads(meshed[1].read_text())
    assert doc["stats"]["n_elements"] > adaptive["stats"]["n_elements"]
    from hetmesh.io.read import read_mesh

    assert read_mesh(out).n_elements == doc["stats"]["n_elements"]


def test_chord_tolerance_reaches_the_uniform_mesher(model, tmp_path, capsys):
    out, stats = tmp_path / "u.vtu", tmp_path / "u.json"
    code, _, err = run(mesh_argv(model, out, "--stats", stats, "--chord-tol", "0.01",
                                 command="uniform"), capsys)
    assert code == 0, err
    assert json.loads(stats.read_text())["options"]["chord_tol"] == 0.01


def test_stats_prints_the_numbers(model, meshed, capsys):
    out, stats, _ = meshed
    expected = json.loads(stats.read_text())["stats"]
    code, stdout, _ = run(["stats", out, "--model", model], capsys)
    assert code == 0
    for label in ("Np", "Ne", "q_min", "q_avg", "delta_min", "delta_avg", "delta_max",
                  "delta_max_dense"):
        assert label in stdout
    assert str(expected["n_elements"]) in stdout
    assert f"{expected['q_min']:.4f}" in stdout

    code, stdout, _ = run(["stats", out, "--model", model, "--json"], capsys)
    assert code == 0
    got = json.loads(stdout)
    assert got["n_elements"] == expected["n_elements"]
    assert got["n_points"] == expected["n_points"]
    assert got["delta_max"] == pytest.approx(expected["delta_max"], rel=1e-6)
    assert got["q_min"] == pytest.approx(expected["q_min"], rel=1e-6)
    assert got["delta_max_dense"] == pytest.approx(expected["delta_max_dense"], rel=1e-6)
    code, stdout, _ = run(["stats", out, "--model", model, "--json", "--sampling", "dense"],
                          capsys)
    got = json.loads(stdout)
    assert got["delta_max"] >= got["delta_max_dense"] == pytest.approx(
        expected["delta_max_dense"], rel=1e-6)


def test_delta_max_never_prints_as_the_threshold():
    from rich.console import Console

    from hetmesh.cli.stats import stats_table

    console = Console(width=80, record=True)
    stats = dict(n_points=3, n_elements=1, q_min=1.0, q_avg=1.0, delta_min=0.01,
                 delta_avg=0.0449, delta_max=0.0499996, angle_min=60.0)
    console.print(stats_table({"m": stats}))
    text = console.export_text()
    assert "0.04999" in text and "0.0500" not in text
    assert "0.0449" in text


def test_demo_writes_four_files(tmp_path, capsys):
    out = tmp_path / "demo"
    code, stdout, err = run(["demo", "--out", out, "--quiet"], capsys)
    assert code == 0, err
    names = sorted(p.name for p in out.iterdir())
    assert names == ["power_plate.png", "power_plate.vtu", "power_plate_delta.png",
                     "power_plate_uniform.vtu"]
    assert stdout == ""


def test_format_option_writes_gmsh22(tmp_path):
    from hetmesh.cli import main

    out = tmp_path / "m.msh"
    import hetmesh

    rc = main(["mesh", str(hetmesh.example_path("unit_square")), "-d", "0.1", "-o", str(out),
               "--format", "gmsh22", "--quiet"])
    assert rc == 0
    assert out.read_text().splitlines()[1].startswith("2.2")


# -- promises: --max-size, stats and fea on a mesh of another model, history ------------

def _example(name: str, tmp_path: Path) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text((resources.files("hetmesh") / "examples" / f"{name}.toml")
                    .read_text(encoding="utf-8"), encoding="utf-8")
    return path


def test_max_size_bounds_every_edge(tmp_path, capsys):
    import numpy as np

    from hetmesh.io.read import read_mesh

    square, out = _example("unit_square", tmp_path), tmp_path / "s.vtu"
    code, _, err = run(["mesh", square, "-d", "0.1", "--max-size", "0.05", "-o", out, "-q"],
                       capsys)
    assert code == 0, err
    mesh = read_mesh(out)
    P, T = mesh.points, mesh.triangles
    edges = np.sqrt(((P[T] - P[T][:, [1, 2, 0]]) ** 2).sum(axis=2))
    assert edges.max() <= 0.05
    # without it the coarsest elements are larger
    code, _, _ = run(["mesh", square, "-d", "0.1", "-o", out, "-q"], capsys)
    mesh = read_mesh(out)
    P, T = mesh.points, mesh.triangles
    assert np.sqrt(((P[T] - P[T][:, [1, 2, 0]]) ** 2).sum(axis=2)).max() > 0.06


def test_stats_refuses_a_mesh_of_another_model(model, meshed, tmp_path, capsys):
    square = _example("unit_square", tmp_path)
    line = assert_one_line_error(*run(["stats", meshed[0], "--model", square], capsys),
                                 contains="not a mesh of model 'unit_square'")
    assert "boundary node" in line


def _with_nan_node(src: Path, dst: Path) -> Path:
    import meshio

    m = meshio.read(src)
    m.points[3, 0] = float("nan")
    meshio.write(dst, m)
    return dst


def test_stats_and_fea_refuse_a_mesh_with_a_nan_node(tmp_path, capsys):
    plate, good = _example("fgm_plate", tmp_path), tmp_path / "plate.vtu"
    assert run(["mesh", plate, "-d", "0.3", "-o", good, "-q"], capsys)[0] == 0
    bad = _with_nan_node(good, tmp_path / "nan.vtu")
    assert_one_line_error(*run(["stats", bad, "--model", plate], capsys),
                          contains="non-finite coordinates (node 3")
    assert_one_line_error(*run(["fea", plate, "--mesh", bad], capsys),
                          contains="non-finite coordinates (node 3")
    assert run(["fea", plate, "--mesh", good, "-q"], capsys)[0] == 0


def test_stats_quiet_prints_nothing(model, meshed, capsys):
    code, out, err = run(["stats", meshed[0], "--model", model, "--quiet"], capsys)
    assert (code, out, err) == (0, "", "")


def test_stats_reports_each_sampling_and_the_certified_bound(model, meshed, capsys):
    code, out, _ = run(["stats", meshed[0], "--model", model, "--json", "--sampling",
                        "certified"], capsys)
    assert code == 0
    got = json.loads(out)
    assert got["delta_max_certified"] == got["delta_max"]
    # the lattice is pulled a hair inside the element: it may see a hair less than the vertices
    assert got["delta_max"] >= max(got["delta_max_dense"], got["delta_max_vertices"]) > 0
    code, out, _ = run(["stats", meshed[0], "--model", model], capsys)
    assert "delta_max_vertices" in out and "delta_max_certified" in out
    code, out, _ = run(["stats", meshed[0], "--model", model, "--json", "--sampling",
                        "certified", "-d", str(THRESHOLD)], capsys)
    assert got["delta_max_vertices"] <= json.loads(out)["delta_max_certified"] < THRESHOLD
    assert_one_line_error(*run(["stats", meshed[0], "--model", model, "-d", "1.5"], capsys),
                          contains="--threshold 1.5")


def test_history_ends_with_the_optimisation_pass(meshed):
    doc = json.loads(meshed[1].read_text())
    last = doc["history"][-1]
    assert last["stage"] == "optimize"
    assert last["delta_max"] == pytest.approx(doc["stats"]["delta_max"], rel=1e-9)
    assert last["elements"] == doc["stats"]["n_elements"]


def test_mesh_with_certified_sampling(model, tmp_path, capsys):
    out, stats = tmp_path / "c.vtu", tmp_path / "c.json"
    code, _, err = run(mesh_argv(model, out, "--stats", stats, "--sampling", "certified"),
                       capsys)
    assert code == 0, err
    doc = json.loads(stats.read_text())["stats"]
    assert doc["delta_max_certified"] == doc["delta_max"] < THRESHOLD
    assert doc["delta_max_dense"] <= doc["delta_max"]


# -- signals and temporary files ----------------------------------------------------------

_TERMINATE_WHILE_WRITING = """
import os, signal, sys, time
import hetmesh.io.atomic as atomic
from hetmesh.cli import main

def fsync(tmp):  # the mesh is in the temporary file, not yet renamed: terminate now
    assert tmp.stat().st_size > 0
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(5)

atomic.fsync = fsync
sys.exit(main(sys.argv[1:]))
"""


def test_sigterm_while_writing_leaves_nothing(model, tmp_path):
    import subprocess
    import sys

    out = tmp_path / "plate.vtu"
    proc = subprocess.run([sys.executable, "-c", _TERMINATE_WHILE_WRITING, "mesh", str(model),
                           "-d", "0.2", "-o", str(out), "-q"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 128 + 15, proc.stderr
    assert sorted(os.listdir(tmp_path)) == []


def test_stale_temporary_files_are_removed_by_the_next_write(model, tmp_path, capsys):
    import subprocess
    import sys

    out = tmp_path / "plate.vtu"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    stale = tmp_path / f".plate.{dead}-0123abcd.tmp.vtu"   # its writer was killed (-9)
    old = tmp_path / ".plate.89abcdef.tmp.vtu"              # an older hetmesh's, a day old
    live = tmp_path / f".plate.{os.getpid()}-fedc4321.tmp.vtu"  # a write in progress
    other = tmp_path / f".other.{dead}-0123abcd.tmp.vtu"    # another output's
    for p in (stale, old, live, other):
        p.write_text("partial")
    os.utime(old, (1e9, 1e9))
    assert run(["mesh", model, "-d", "0.2", "-o", out, "-q"], capsys)[0] == 0
    assert sorted(os.listdir(tmp_path)) == sorted(["plate.vtu", live.name, other.name])


# -- the packaged examples -------------------------------------------------------------------

def test_examples_lists_and_copies_out(tmp_path, capsys):
    code, out, _ = run(["examples"], capsys)
    assert code == 0
    for name in ("power_plate", "fgm_plate", "unit_square"):
        assert name in out
    code, out, _ = run(["examples", "power_plate", "--out", tmp_path], capsys)
    assert code == 0 and (tmp_path / "power_plate.toml").read_text() == (
        resources.files("hetmesh") / "examples" / "power_plate.toml").read_text()
    assert_one_line_error(*run(["examples", "power_plate", "--out", tmp_path], capsys),
                          contains="use --force")
    assert run(["examples", "power_plate", "--out", tmp_path, "--force"], capsys)[0] == 0
    assert_one_line_error(*run(["examples", "nope"], capsys), contains="power_plate")
    # the copy meshes
    assert run(["mesh", tmp_path / "power_plate.toml", "-d", "0.2", "-o",
                tmp_path / "p.vtu", "-q"], capsys)[0] == 0


@pytest.mark.parametrize("command", [["mesh", "-d", "0.1", "-o", "x.vtu"],
                                     ["stats", "--model"], ["fea", "--mesh", "x.vtu"]])
def test_a_missing_example_path_points_to_the_packaged_examples(command, tmp_path, capsys,
                                                                monkeypatch):
    monkeypatch.chdir(tmp_path)
    model = "examples/power_plate.toml"
    argv = {"mesh": ["mesh", model, *command[1:]], "stats": ["stats", "m.vtu", "--model", model],
            "fea": ["fea", model, *command[1:]]}[command[0]]
    (tmp_path / "m.vtu").write_text("")
    assert_one_line_error(*run(argv, capsys),
                          contains="`hetmesh examples power_plate` writes power_plate.toml")


def test_scaled_models_mesh_the_same_up_to_the_scale(tmp_path, capsys):
    """A power-of-two scale gives the same mesh scaled, bit for bit; others (1e12) change the
    coordinates in their last bits, and the element count by a few per cent at most."""
    import numpy as np

    from hetmesh.io.read import read_mesh

    text = (resources.files("hetmesh") / "examples" / "unit_square.toml").read_text()
    meshes = {}
    for s in (1.0, 2.0 ** 40, 1e12):
        scaled = (text.replace("to = [1, 0]", f"to = [{s!r}, 0]")
                  .replace("to = [1, 1]", f"to = [{s!r}, {s!r}]")
                  .replace("to = [0, 1]", f"to = [0, {s!r}]")
                  .replace('"(1 - y)**2"', f'"(1 - y/{s!r})**2"'))
        model, out = tmp_path / f"sq{s:g}.toml", tmp_path / f"sq{s:g}.vtu"
        model.write_text(scaled)
        assert run(["mesh", model, "-d", "0.1", "-o", out, "-q"], capsys)[0] == 0
        meshes[s] = read_mesh(out)
    one, two, ten = meshes[1.0], meshes[2.0 ** 40], meshes[1e12]
    np.testing.assert_array_equal(two.points / 2.0 ** 40, one.points)
    np.testing.assert_array_equal(two.triangles, one.triangles)
    assert abs(ten.n_elements - one.n_elements) <= 0.03 * one.n_elements
