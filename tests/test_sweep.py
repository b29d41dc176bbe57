"""Sweeps (hetmesh.study): study files, runs as rows, Dask clusters, killed workers, resume."""

from __future__ import annotations

import os
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pandas as pd
import pytest

import hetmesh
import hetmesh.io.read
from hetmesh.cli import main
from hetmesh.errors import OptionError
from hetmesh.study import load_study, parse_study, rows_to_frame, run_one, sweep

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "studies" / "sweep.toml"

#: the columns that differ between two runs of the same mesh: times, the process
TIMING = ["seconds", "mesh_seconds", "fea_seconds", "timings", "worker"]

#: unit_square and power_plate at coarse thresholds (~0.1-0.3 s each), and a run whose
#: element budget cannot be met (BudgetError: a failed row)
SMALL = {"grid": {"model": ["unit_square", "power_plate"], "threshold": [0.3, 0.1]},
         "runs": [{"model": "unit_square", "threshold": 0.05, "max_elements": 10}]}


def numbers(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.drop(columns=TIMING).reset_index(drop=True)


@pytest.fixture(scope="module")
def serial_table(tmp_path_factory):
    return sweep(SMALL, serial=True, out=tmp_path_factory.mktemp("serial"))


def test_example_study_parses():
    study = load_study(EXAMPLE)
    assert study.name == "thresholds"
    assert [(s["model"], s["threshold"]) for s in study.specs] == [
        (m, t) for m in ("power_plate", "hft_ring") for t in (0.2, 0.1, 0.05)]
    assert len({s["key"] for s in study.specs}) == 6


def test_content_keys():
    base = parse_study({"runs": [{"model": "unit_square", "threshold": 0.1}]}).specs[0]["key"]
    # spelling out a default is the same run; another option or version is another run
    same = parse_study({"runs": [{"model": "unit_square", "threshold": 0.1, "min_angle": 30,
                                  "method": "auto"}]}).specs[0]["key"]
    other = parse_study({"runs": [{"model": "unit_square", "threshold": 0.1,
                                   "row_spacing": 0.9}]}).specs[0]["key"]
    assert base == same != other
    spec = parse_study({"runs": [{"model": "unit_square", "threshold": 0.1}]}).specs[0]
    assert hetmesh.study.content_key(hetmesh.study.text_digest(spec["model_text"]), {
        k: spec[k] for k in ("model", "method", "threshold", "options", "fea", "mesh_format")},
        "0.0.0-other") != base
    # a run listed twice (grid and explicit) runs once
    twice = parse_study({"grid": {"model": "unit_square", "threshold": [0.1, 0.2]},
                         "runs": [{"model": "unit_square", "threshold": 0.1}]})
    assert len(twice.specs) == 2


@pytest.mark.parametrize("data, message", [
    ({"grid": {"model": ["unit_square"], "treshold": [0.1]}},
     "s.toml: grid.treshold: unknown key"),
    ({"grid": {"model": ["unit_square"], "threshold": [0.1, "x"]}},
     "s.toml: grid.threshold[1]: expected a number, got the string 'x'"),
    ({"runs": [{"model": "unit_square", "threshold": 1.5}]},
     "s.toml: runs[0]: threshold 1.5 is outside (0, 1)"),
    ({"runs": [{"model": "nonesuch", "threshold": 0.1}]},
     "s.toml: runs[0].model: 'nonesuch' is neither a model file nor an example"),
    ({"runs": [{"threshold": 0.1}]}, "s.toml: runs[0].model: missing"),
    ({"grid": {"model": "unit_square", "threshold": 0.1, "method": "magic"}},
     "s.toml: grid.method: unknown method 'magic'"),
    ({"grid": {"model": "unit_square", "threshold": 0.1}, "fea": {"order": 3}},
     "s.toml: fea.order: expected 1 or 2"),
    ({}, "s.toml: no runs"),
])
def test_bad_study_one_line_error(data, message):
    with pytest.raises(OptionError) as err:
        parse_study(data, "s.toml")
    assert str(err.value).startswith(message)
    assert "\n" not in str(err.value)


def test_cli_bad_study_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[grid]\nmodel = ["unit_square"]\nthreshold = [0.1, -2]\n')
    assert main(["sweep", str(bad), "--serial", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"hetmesh: error: {bad}: grid")
    assert not (tmp_path / "o").exists()


def test_failing_run_is_a_row(serial_table):
    t = serial_table
    assert len(t) == 5 and list(t["index"]) == list(range(5))
    failed = t[t["status"] != "ok"]
    assert len(failed) == 1
    row = failed.iloc[0]
    assert row["status"] == "failed" and row["threshold"] == 0.05
    assert "budget" in row["error"] and pd.isna(row["n_elements"])
    ok = t[t["status"] == "ok"]
    assert (ok["delta_max"] < ok["threshold"]).all() and (ok["n_elements"] > 0).all()


def test_local_cluster_same_numbers_as_serial(serial_table, tmp_path):
    t = sweep(SMALL, workers=2, out=tmp_path)
    pd.testing.assert_frame_equal(numbers(t), numbers(serial_table))
    assert t["worker"].nunique() == 2  # both workers took runs
    # the files: Parquet and CSV of the same table, the summary, one record per run
    back = pd.read_parquet(tmp_path / "results.parquet")
    pd.testing.assert_frame_equal(numbers(back), numbers(t), check_dtype=False)
    csv = pd.read_csv(tmp_path / "results.csv", keep_default_na=False)
    assert list(csv["n_elements"]) == [str(n) if n is not pd.NA else "" for n in t["n_elements"]]
    assert (tmp_path / "summary.png").stat().st_size > 10_000
    assert len(list((tmp_path / "runs").glob("*.json"))) == 5
    assert not list(tmp_path.glob(".*tmp*"))


def test_killed_worker_nothing_lost_or_duplicated(tmp_path):
    """SIGKILL a worker while it runs a mesh: the scheduler reruns the run on the other
    worker; every run appears once, with the numbers of a serial run."""
    from dask.distributed import Client, LocalCluster

    study = {"grid": {"model": ["hft_ring"], "threshold": [0.2, 0.15]}}
    reference = sweep(study, serial=True)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster, Client(cluster) as client:
        pids = client.run(os.getpid)
        box: dict = {}
        worker = threading.Thread(target=lambda: box.update(t=sweep(study, client=client,
                                                                    out=tmp_path)))
        worker.start()
        victim, task = None, None
        deadline = time.monotonic() + 30
        while victim is None and time.monotonic() < deadline:
            busy = {w: ts for w, ts in client.processing().items() if ts}
            if busy:
                victim, tasks = next(iter(busy.items()))
                task = tasks[0]
                time.sleep(0.3)  # well inside the run (each takes ~0.5-1 s)
                os.kill(pids[victim], signal.SIGKILL)
            time.sleep(0.05)
        worker.join(120)
    assert victim is not None, "no run was seen running"
    t = box["t"]
    assert len(t) == 2 and t["key"].is_unique and (t["status"] == "ok").all()
    pd.testing.assert_frame_equal(numbers(t), numbers(reference))
    # the killed run was finished by another process
    killed = t[t["key"] == task.rsplit("-", 1)[-1]].iloc[0]
    assert not killed["worker"].endswith(f":{pids[victim]}")
    assert len(list((tmp_path / "runs").glob("*.json"))) == 2


def test_resume_reruns_nothing_finished(tmp_path):
    """Interrupt a sweep after two runs (Ctrl-C), start it again: only the others run."""
    study = {"grid": {"model": ["unit_square"], "threshold": [0.3, 0.2, 0.15, 0.1]}}

    def interrupt(counts):
        if counts.done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        sweep(study, serial=True, out=tmp_path, progress=interrupt)
    first = {p.name: p.read_text() for p in (tmp_path / "runs").glob("*.json")}
    assert len(first) == 2 and not (tmp_path / "results.parquet").exists()
    seen = []
    t = sweep(study, serial=True, out=tmp_path, progress=lambda c: seen.append(c.done))
    assert t.attrs["cached"] == 2 and seen[0] == 2 and (t["status"] == "ok").all()
    # the two records were not rewritten, and the table has their rows as recorded
    for name, text in first.items():
        assert (tmp_path / "runs" / name).read_text() == text
    again = sweep(study, serial=True, out=tmp_path)
    assert again.attrs["cached"] == 4
    pd.testing.assert_frame_equal(again, t, check_like=False)
    assert not sweep(study, serial=True, out=tmp_path, resume=False).attrs["cached"]


def test_plain_runs_under_concurrent_futures(serial_table):
    study = parse_study(SMALL)
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(run_one, study.specs))
        via_sweep = sweep(study, client=pool)
    pd.testing.assert_frame_equal(numbers(rows_to_frame(rows)), numbers(serial_table))
    pd.testing.assert_frame_equal(numbers(via_sweep), numbers(serial_table))


def test_cli_sweep_writes_and_resumes(tmp_path, capsys):
    study = tmp_path / "s.toml"
    study.write_text('[study]\nname = "tiny"\n[grid]\nmodel = "unit_square"\n'
                     'threshold = [0.3, 0.2]\n[output]\nmesh = "vtu"\n')
    out = tmp_path / "out"
    assert main(["sweep", str(study), "--serial", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "2 runs (0 failed, 0 found done)" in printed
    t = pd.read_parquet(out / "results.parquet")
    meshes = [out / f for f in t["mesh_file"]]
    assert all(m.suffix == ".vtu" and m.stat().st_size > 0 for m in meshes)
    assert hetmesh.io.read.read_mesh(meshes[0]).n_elements == t["n_elements"][0]
    assert main(["sweep", str(study), "--serial", "--out", str(out)]) == 0
    assert "2 runs (0 failed, 2 found done)" in capsys.readouterr().out


# ------------------------------------------------------------- reproduce and fea.study on Dask
@pytest.fixture(scope="module")
def client():
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster, Client(cluster) as c:
        yield c


def test_reproduce_on_a_cluster_has_the_serial_numbers(tmp_path, client):
    from hetmesh import reproduce

    kw = dict(cases=["power_plate"], quick=True, peers=False, fea=False)
    serial = reproduce.run(tmp_path / "serial", **kw)
    stages = []
    dist = reproduce.run(tmp_path / "dask", client=client,
                         progress=lambda s, f: stages.append(f), **kw)
    assert [(r.case, r.threshold) for r in dist.runs] == \
        [(r.case, r.threshold) for r in serial.runs]
    for a, b in zip(serial.runs, dist.runs):
        assert b.error is None
        assert a.adaptive.stats == b.adaptive.stats and a.uniform.stats == b.uniform.stats
        assert a.n_iso == b.n_iso and a.histogram_uniform_elements == b.histogram_uniform_elements
        assert (a.mesh_figure, a.histogram) == (b.mesh_figure, b.histogram)
    assert sorted(p.relative_to(tmp_path / "dask") for p in dist.figures) == \
        sorted(p.relative_to(tmp_path / "serial") for p in serial.figures)
    assert all(p.is_file() for p in dist.figures)
    assert stages == sorted(stages) and stages[-1] == 1.0


def test_fea_study_on_a_cluster_has_the_serial_numbers(client):
    model = hetmesh.load_model(hetmesh.example_path("fgm_plate"))
    kw = dict(reference_elements=1500, uniform_elements=(250, 600), thresholds=(0.3,),
              check=False, order=1)
    serial = hetmesh.fea.study(model, **kw)
    dist = hetmesh.fea.study(model, client=client, **kw)
    drop = ("mesh_seconds", "solve_seconds")

    def strip(d):
        return {k: strip(v) if isinstance(v, dict) else v for k, v in d.items() if k not in drop}

    assert strip(dist.reference) == strip(serial.reference)
    assert [strip(m) for m in dist.meshes] == [strip(m) for m in serial.meshes]
    assert dist.needed == serial.needed and dist.needed_by_set == serial.needed_by_set


def test_cli_reproduce_workers_flags(tmp_path, capsys):
    assert main(["reproduce", "--workers", "2", "--scheduler", "tcp://x:1", "--out",
                 str(tmp_path)]) == 2
    assert "not allowed with argument" in capsys.readouterr().err
    assert main(["reproduce", "--workers", "0", "--out", str(tmp_path)]) == 2


def test_fea_step_records_probe_values():
    """With [fea], every row has the probes' von Mises stress and temperature, the ones
    hetmesh.fea.solve gives on the same mesh; a model without [fea] is a failed row."""
    t = sweep({"grid": {"model": ["fgm_plate", "unit_square"], "threshold": 0.3},
               "fea": {"probes": ["P1", "P3"], "order": 1}}, serial=True)
    ok, bad = t.iloc[0], t.iloc[1]
    model = hetmesh.load_model(hetmesh.example_path("fgm_plate"))
    r = hetmesh.generate(model, 0.3)
    from dataclasses import replace
    cfg = replace(model.fea, order=1, probes={k: model.fea.probes[k] for k in ("P1", "P3")})
    solved = hetmesh.fea.solve(r.mesh, r.model, config=cfg)
    for p in ("P1", "P3"):
        assert ok[f"fea.{p}.von_mises"] == solved.probes[p]["von_mises"]
        assert ok[f"fea.{p}.temperature"] == solved.probes[p]["temperature"]
    assert "fea.P2.von_mises" not in t.columns and ok["fea_seconds"] > 0
    assert bad["status"] == "failed" and "has no [fea] table" in bad["error"]


DIES = """
import os
from concurrent.futures import ProcessPoolExecutor
from hetmesh.study import map_runs

def exit_process(item):
    os._exit(3)

if __name__ == "__main__":
    got = []
    with ProcessPoolExecutor(1) as pool:
        out = map_runs(exit_process, [1], ["a"], client=pool,
                       on_result=lambda i, v, e: got.append((i, v, e)))
    print(out == [None], got[0][:2] == (0, None), got[0][2])
"""


def test_a_run_whose_process_dies_is_reported_lost(tmp_path):
    """A worker process that dies (os._exit) is a ``lost`` run. The pool runs in a fresh
    interpreter: forking the test process itself, which holds the threads of the Dask
    clusters above, took the whole test run down now and then."""
    import subprocess
    import sys

    script = tmp_path / "dies.py"
    script.write_text(DIES)
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=120, start_new_session=True)
    assert run.returncode == 0, run.stderr[-2000:]
    ok_out, ok_got, error = run.stdout.strip().split(" ", 2)
    assert ok_out == "True" and ok_got == "True"
    assert error.startswith("lost: BrokenProcessPool")


def test_a_uniform_run_meshes_the_uniform_baseline():
    """method = "uniform" meshes the uniform baseline (through hetmesh.meshing, as
    hetmesh.uniform does)."""
    spec = parse_study({"runs": [{"model": "unit_square", "threshold": 0.3,
                                  "method": "uniform"}]}).specs[0]
    row = run_one(spec)
    assert row["status"] == "ok" and row["n_elements"] > 0, row
    assert row["n_elements"] == hetmesh.uniform(
        hetmesh.load_model(hetmesh.example_path("unit_square")), 0.3).stats.n_elements


def test_a_solid_runs_on_the_tetrahedral_kernel():
    """A 3D model in a study: its cost from the tetrahedral estimate, its run through
    hetmesh.generate's tetrahedral kernel."""
    spec = parse_study({"runs": [{"model": "unit_cube", "threshold": 0.3}]}).specs[0]
    row = run_one(spec)
    assert row["status"] == "ok", row
    assert 0 < row["delta_max"] < 0.3 and row["n_elements"] > 0
