"""hetmesh reproduce: the report, its tables and figures, the peers, the blade model."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import shapely

import hetmesh
from hetmesh import peers, reproduce
from hetmesh.cli import main
from hetmesh.reproduce.paper import CASES

HAVE_GMSH = peers.available()["gmsh"] is not None
HAVE_TRIANGLE = peers.available()["triangle"] is not None
QUICK_CASES = ["power_plate", "hft_ring", "blade"]
TEXT_COLUMNS = {"model", "mesh", "best peer", "fewer elements", "≥ 35 % fewer (δ0 ≤ 0.05)",
                "q_avg ≥ peer − 0.03", "probes", "≥ 40 % fewer"}


# ----------------------------------------------------------------------------- helpers
def tables(text: str) -> list[tuple[list[str], list[list[str]]]]:
    """Every Markdown table of ``text`` as (headers, rows)."""
    out, block = [], []
    for line in text.splitlines() + [""]:
        if line.startswith("|"):
            block.append([c.strip() for c in line.strip().strip("|").split("|")])
        elif block:
            out.append((block[0], block[2:]))
            block = []
    return out


def cell_number(cell: str) -> float:
    """A numeric cell ('n/a' is nan; a footnote marker ' [1]' is dropped)."""
    cell = re.sub(r"\s*\[\d+\]$", "", cell)
    return math.nan if cell == "n/a" else float(cell)


def check_numbers_parse(text: str) -> int:
    count = 0
    for headers, rows in tables(text):
        for row in rows:
            assert len(row) == len(headers), (headers, row)
            for h, c in zip(headers, row):
                if h in TEXT_COLUMNS or c.startswith(("error:", "failed:")):
                    continue
                cell_number(c)  # raises if not a number
                count += 1
    return count


def table_with(text: str, header: str):
    found = [(h, r) for h, r in tables(text) if header in h]
    assert found, f"no table with a column {header!r}"
    return found


def check_figures(out: Path, text: str) -> list[Path]:
    refs = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert refs
    paths = [out / r for r in refs]
    for p in paths:
        assert p.is_file(), p
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", p
    return paths


# ----------------------------------------------------------------------------- quick report
@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("rep")
    stages = []
    report = reproduce.run(out, cases=QUICK_CASES, quick=True,
                           progress=lambda stage, f: stages.append((stage, f)))
    return out, report, report.path.read_text(encoding="utf-8"), stages


def test_quick_report_exists_with_the_tables(quick):
    out, report, text, _ = quick
    assert report.path == out / "report.md"
    for title in ("## Table 1 analog: power_plate", "## Table 3 analog: hft_ring",
                  "## Table 5 analog: blade"):
        assert title in text
    assert "## Peers" in text and "Peers were not run" in text
    assert len(report.runs) == 3 and all(r.error is None for r in report.runs)


def test_quick_report_figures_exist(quick):
    out, report, text, _ = quick
    paths = check_figures(out, text)
    assert {p.resolve() for p in paths} == {p.resolve() for p in report.figures}
    assert len(paths) == 6  # a mesh and a histogram per model
    assert not list(out.glob("**/*.tmp*"))  # atomic writes leave no temporary files


def test_quick_report_numbers_parse_and_match_the_run(quick):
    _, report, text, _ = quick
    assert check_numbers_parse(text) > 50
    (headers, rows), = [t for t in table_with(text, "Ne paper") if t[1][0][0] == "power_plate"]
    run = report.runs[0]
    row = {h: c for h, c in zip(headers, rows[0])}
    assert row["mesh"] == "adaptive"
    assert int(row["Ne"]) == run.adaptive.stats.n_elements
    assert run.adaptive.stats.delta_max < 0.1
    assert cell_number(row["δ_max"]) <= 0.1  # printed to 4 decimals: 0.09996 is 0.1000
    assert abs(cell_number(row["q_avg"]) - run.adaptive.stats.q_avg) < 1e-4
    uni = {h: c for h, c in zip(headers, rows[1])}
    assert int(uni["Ne"]) == run.uniform.stats.n_elements


def test_quick_report_paper_columns_are_labelled_and_are_the_papers(quick):
    _, _, text, _ = quick
    for headers, rows in table_with(text, "Ne paper"):
        for label in ("Np", "Ne", "q_min", "q_avg", "δ_min", "δ_avg"):
            i = headers.index(label)
            assert headers[i + 1] == f"{label} paper"  # adjacent
        for row in rows:
            r = dict(zip(headers, row))
            paper = getattr(CASES[r["model"]], r["mesh"])[float(r["δ0"])]
            assert int(r["Ne paper"]) == paper.n_elements
            assert cell_number(r["δ_avg paper"]) == pytest.approx(paper.delta_avg)
    assert "0.0356 [1]" in text and "misprint" in text  # Table 1's corrected misprint

    ratio = table_with(text, "adaptive/uniform paper")
    r = dict(zip(ratio[0][0], ratio[0][1][0]))
    assert cell_number(r["adaptive/uniform paper"]) == pytest.approx(454 / 1218, abs=1e-3)
    assert cell_number(r["N_iso"]) > 0 and cell_number(r["Ne/N_iso adaptive"]) > 0


def test_quick_report_progress_covers_every_run(quick):
    _, _, _, stages = quick
    fractions = [f for _, f in stages]
    assert fractions == sorted(fractions) and fractions[0] == 0 and fractions[-1] == 1.0
    assert any("blade" in s for s, _ in stages)


def test_quick_report_has_no_table7_without_fgm_plate(quick):
    _, report, text, _ = quick
    assert "fgm_plate" not in report.cases and report.fea is None
    assert "Table 7" not in text


def test_cli_reproduce_quick(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["reproduce", "--quick", "--cases", "power_plate", "--out", str(out)]) == 0
    assert (out / "report.md").is_file()
    assert "wrote" in capsys.readouterr().out
    check_figures(out, (out / "report.md").read_text(encoding="utf-8"))


def test_cli_reproduce_unknown_case(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["reproduce", "--quick", "--cases", "power_plate,nope", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "'nope'" in err and "power_plate" in err
    assert not out.exists()


def test_cli_reproduce_out_is_a_file(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["reproduce", "--quick", "--cases", "power_plate", "--out", str(f)]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_plan():
    assert [c.name for c, _ in reproduce.plan()] == [
        "power_plate"] * 4 + ["hft_ring"] * 4 + ["blade", "hft_complex", "fgm_plate"]
    assert [t for _, t in reproduce.plan(["hft_ring"], quick=True)] == [0.15]
    with pytest.raises(hetmesh.OptionError, match="unknown case"):
        reproduce.plan(["x"])


def test_uniform_like_matches_the_element_count():
    from hetmesh.reproduce.runs import uniform_like

    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    delta = uniform_like(model, 0.05, 1400)
    assert abs(len(delta) / 1400 - 1) <= 0.05 and delta.max() > 0


# ----------------------------------------------------------------------------- peers
def test_peer_section_says_when_peers_are_missing(tmp_path, monkeypatch):
    monkeypatch.setattr(peers, "available", lambda: {"gmsh": None, "triangle": None})
    report = reproduce.run(tmp_path, cases=["power_plate"], quick=True, peers=True)
    text = report.path.read_text(encoding="utf-8")
    assert "Neither Gmsh nor Triangle is installed" in text and 'hetmesh[peers]' in text
    assert "## Table 1 analog" in text


@pytest.mark.skipif(not HAVE_GMSH, reason="gmsh is not installed")
def test_peer_section(tmp_path):
    report = reproduce.run(tmp_path, cases=["power_plate"], quick=True, peers=True)
    text = report.path.read_text(encoding="utf-8")
    (headers, rows), = table_with(text, "Gmsh Ne")
    assert len(rows) == 1
    row = dict(zip(headers, rows[0]))
    run = report.runs[0]
    assert int(row["Gmsh Ne"]) == run.peers["gmsh"].stats.n_elements
    assert run.peers["gmsh"].stats.delta_max < 0.1
    assert int(row["hetmesh Ne"]) == run.adaptive.stats.n_elements
    assert row["best peer"] in ("Gmsh", "Triangle")
    assert row["fewer elements"] in ("yes", "no")
    assert row["≥ 35 % fewer (δ0 ≤ 0.05)"] == "n/a"  # delta_0 = 0.1
    assert "target met:" in text
    check_numbers_parse(text)


def ring_model():
    return hetmesh.load_model(hetmesh.example_path("hft_ring"))


def crossing_circle(points, triangles, radius: float, tol: float = 1e-6) -> int:
    r = np.hypot(*points.T)[triangles]
    return int(((r.min(axis=1) < radius - tol) & (r.max(axis=1) > radius + tol)).sum())


@pytest.mark.parametrize("peer", [
    pytest.param("gmsh", marks=pytest.mark.skipif(not HAVE_GMSH, reason="no gmsh")),
    pytest.param("triangle", marks=pytest.mark.skipif(not HAVE_TRIANGLE, reason="no triangle"))])
def test_peer_mesh_conforms_to_holes_and_interfaces(peer):
    model = ring_model()
    mesh = peers.PEERS[peer](model.domain, peers.size_field(model, 0.15, 1.0))
    P, T = mesh.points, mesh.triangles
    assert np.unique(T).size == len(P)  # only used nodes
    a, b = P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum()
    # elements are straight: polygons inscribed in the circles, chords of sagitta up to
    # 1e-3 x diameter (the size field's cap along arcs): the outer circle loses up to
    # (2/3) 0.107 x 239 = 17 of 4,335, 0.4 %
    assert area == pytest.approx(model.domain.area, rel=5e-3)
    assert crossing_circle(P, T, 28.0) == 0  # the interface circle A is embedded
    assert np.hypot(*P.T).min() >= 8 - 1e-6  # nothing inside the hole C


@pytest.mark.skipif(not HAVE_TRIANGLE, reason="no triangle")
def test_search_finds_the_coarsest_passing_scale():
    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    r = peers.search("triangle", model, 0.08)
    assert r.stats.delta_max < 0.08 and r.s > 0
    assert any(not t["pass"] and t["s"] > r.s for t in r.trace)  # a coarser s failed
    assert all(t["s"] <= r.s for t in r.trace if t["pass"])


def test_size_field_is_graded_and_capped():
    model = hetmesh.load_model(hetmesh.example_path("blade"))
    f = peers.size_field(model, 0.1, 1.0)
    X, Y, H = f.grid
    step = X[0, 1] - X[0, 0]
    h_max = model.domain.diameter / 8
    assert H.max() <= h_max + 1e-12
    assert np.abs(np.diff(H, axis=0)).max() <= 0.3 * step * (1 + 1e-9)
    assert np.abs(np.diff(H, axis=1)).max() <= 0.3 * step * (1 + 1e-9)
    half = peers.size_field(model, 0.1, 0.5)
    assert np.all(half.grid[2] <= H + 1e-12)
    pts = np.array([[30.27, 5.64], [50.0, 12.0]])
    assert f(pts).shape == (2,)


def test_peers_unknown_name_and_missing_module(monkeypatch):
    model = ring_model()
    with pytest.raises(hetmesh.OptionError, match="unknown peer"):
        peers.search("nope", model, 0.1)
    import builtins

    real = builtins.__import__

    def fake(name, *a, **k):
        if name == "gmsh":
            raise ImportError("No module named 'gmsh'")
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", fake)
    assert peers.available()["gmsh"] is None
    with pytest.raises(peers.PeerUnavailable, match="hetmesh\\[peers\\]"):
        peers.gmsh_mesh(model.domain, peers.size_field(model, 0.15))


# ----------------------------------------------------------------------------- the blade
def naca4(m=0.06, p=0.4, t=0.28, n=801, chord=100.0):
    beta = np.linspace(0, np.pi, n)
    x = 0.5 * (1 - np.cos(beta))
    yt = 5 * t * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3
                  - 0.1036 * x**4)
    yc = np.where(x < p, m / p**2 * (2 * p * x - x**2),
                  m / (1 - p)**2 * ((1 - 2 * p) + 2 * p * x - x**2))
    th = np.arctan(np.where(x < p, 2 * m / p**2 * (p - x), 2 * m / (1 - p)**2 * (p - x)))
    up = np.c_[x - yt * np.sin(th), yc + yt * np.cos(th)] * chord
    lo = np.c_[x + yt * np.sin(th), yc - yt * np.cos(th)] * chord

    def camber(xc):
        u = xc / chord
        return chord * (m / p**2 * (2 * p * u - u**2) if u < p
                        else m / (1 - p)**2 * ((1 - 2 * p) + 2 * p * u - u**2))

    return up, lo, camber


def test_blade_outline_is_naca_6428_with_three_holes():
    model = hetmesh.load_model(hetmesh.example_path("blade"))
    d = model.domain
    up, lo, camber = naca4()
    outline = np.vstack([up, lo])
    assert d.outer.curves and len(d.holes) == 3
    batch = hetmesh.tri.geometry.CurveBatch.from_curves(list(d.outer.curves))
    assert batch.distance(outline).max() < 0.011  # the arcs fit the profile within 0.01 mm
    for hole, frac in zip(d.holes, (0.25, 0.45, 0.65)):
        (c,) = hole.curves
        assert c.radius == 5.0
        assert c.center[0] == pytest.approx(100 * frac)
        assert c.center[1] == pytest.approx(camber(100 * frac), abs=1e-6)
    x0, y0, x1, y1 = d.bounds
    assert (x1 - x0) == pytest.approx(100.0, abs=0.5)  # chord 100 (the leading edge is round)
    assert "RECONSTRUCTION" in hetmesh.example_path("blade").read_text()


def test_blade_metal_fraction_is_c_dp_squared():
    model = hetmesh.load_model(hetmesh.example_path("blade"))
    d = model.domain
    ring = np.vstack([c.point(np.linspace(0, 1, 400)) for c in d.outer.curves])
    outer = shapely.LinearRing(ring)
    rng = np.random.default_rng(3)
    x0, y0, x1, y1 = d.bounds
    pts = np.column_stack([rng.uniform(x0, x1, 4000), rng.uniform(y0, y1, 4000)])
    pts = pts[d.contains(pts)]
    dp = shapely.distance(shapely.points(pts), outer)
    metal = model.material.composition(pts)[:, 1]
    assert np.allclose(metal, (dp / 14.0) ** 2, atol=2e-4)
    # c = 1/max(d_p)^2: the largest value, between the first two holes, is just below 1
    top = model.material.composition(np.array([[30.266, 5.6407]]))[0, 1]
    assert 0.999 < top <= 1.0
    assert metal.max() <= 1.0
    on_boundary = model.material.composition(ring[::37])[:, 1]
    assert np.abs(on_boundary).max() < 1e-9


# ----------------------------------------------------------------------------- Table 7
def test_table7_section_renders_the_fea_study():
    """The Table 7 analog as it will appear once hetmesh.fea.study lands (docs/reproduce.md
    gives the contract); absent study -> no section at all."""
    from hetmesh.reproduce import Report
    from hetmesh.reproduce.report import render

    vm = {f"P{i}": 1e9 * v for i, v in enumerate((0.82, 1.44, 2.22, 0.57, 0.99, 1.49), 1)}
    study = {"reference": {"elements": 40000, "von_mises": vm},
             "meshes": [{"family": "uniform", "elements": 900, "von_mises": vm,
                         "max_error": 0.004},
                        {"family": "adaptive", "elements": 600, "von_mises": vm,
                         "max_error": 0.003}],
             "needed": {"uniform": 1000.0, "adaptive": 500.0}}
    base = dict(path=Path("r.md"), quick=True, cases=["fgm_plate"], runs=[],
                peer_versions={"gmsh": None, "triangle": None}, peers_run=False)
    text = render(Report(**base, fea=study))
    assert "## Table 7 analog" in text
    check_numbers_parse(text)
    (headers, rows), = table_with(text, "P1 GPa")
    paper = [r for r in rows if r[0].endswith("paper")]
    assert len(paper) == 8 and ["adaptive paper", "633"] == paper[5][:2]
    (h2, r2), = table_with(text, "reduction paper")
    assert dict(zip(h2, r2[0]))["reduction"] == "0.500"
    assert "Table 7" not in render(Report(**base))


@pytest.mark.slow
def test_quick_report_of_every_case(tmp_path):
    report = reproduce.run(tmp_path, quick=True)
    text = report.path.read_text(encoding="utf-8")
    assert report.cases == list(CASES)
    assert all(r.error is None and r.adaptive.stats.delta_max < r.threshold for r in report.runs)
    assert "## Table 5 analog: blade, hft_complex, fgm_plate" in text
    assert len(check_figures(tmp_path, text)) == 10
    check_numbers_parse(text)
    # the quick FEA study (hetmesh.fea.study) as the Table 7 analog: both families reach
    # 0.5 % at P1..P6 and the adaptive meshes need at least 40 % fewer elements (the
    # target; the paper's 32 %)
    assert report.fea_error is None and report.fea.quick
    assert all("error" not in m for m in report.fea.meshes)
    assert report.fea.needed["uniform_exact"] and report.fea.needed["adaptive"] is not None
    assert report.fea.reduction is not None and report.fea.reduction >= 0.40
    assert "## Table 7 analog" in text and "**Quick run**" in text
    (headers, rows), = table_with(text, "P1 GPa")
    ours = [dict(zip(headers, r)) for r in rows if not r[0].endswith("paper")]
    assert len(ours) == 1 + len(report.fea.meshes)
    assert ours[0]["elements"] == str(report.fea.reference["elements"])
    for row, m in zip(ours[1:], report.fea.meshes):
        assert (row["mesh"], int(row["elements"])) == (m["family"], m["elements"])
        assert cell_number(row["max error P1..P6 %"]) == pytest.approx(100 * m["max_error"],
                                                                        abs=1e-3)
    (h2, r2), = table_with(text, "reduction paper")
    need = dict(zip(h2, r2[0]))
    assert need["probes"] == "P1..P6"
    assert int(need["uniform"]) == round(report.fea.needed["uniform"])


def test_run_passes_quick_and_progress_to_the_fea_study(tmp_path, monkeypatch):
    """reproduce.run calls hetmesh.fea.study(model, quick=..., progress=...) and folds the
    study's progress into its own; a HetmeshError from the study is one line in the section."""
    from hetmesh.errors import FEAError

    calls = []
    vm = {f"P{i}": 1e9 for i in range(1, 7)}

    def fake(model, *, quick=False, progress=None):
        calls.append((model.name, quick))
        for f in (0.0, 0.5, 1.0):
            progress(f"mesh {f}", f)
        return {"reference": {"elements": 100, "von_mises": vm}, "quick": quick,
                "meshes": [{"family": "uniform", "elements": 50, "von_mises": vm,
                            "max_error": 0.0}],
                "needed": {"uniform": 50.0, "adaptive": None}}

    monkeypatch.setattr(reproduce, "fea_study_function", lambda: fake)
    stages = []
    report = reproduce.run(tmp_path, cases=["power_plate"], quick=True, fea=True,
                           progress=lambda s, f: stages.append((s, f)))
    assert calls == [("fgm_plate", True)]
    fr = [f for _, f in stages]
    assert fr == sorted(fr) and fr[-1] == 1.0
    assert any(s.startswith("fgm_plate FEA study: mesh 0.5") for s, _ in stages)
    text = report.path.read_text(encoding="utf-8")
    assert "## Table 7 analog" in text and "**Quick run**" in text
    check_numbers_parse(text)

    def broken(model, *, quick=False, progress=None):
        raise FEAError("the study's reference mesh failed: out of budget\nmore")

    monkeypatch.setattr(reproduce, "fea_study_function", lambda: broken)
    report = reproduce.run(tmp_path, cases=["power_plate"], quick=True, fea=True)
    text = report.path.read_text(encoding="utf-8")
    assert "The FEA study failed: the study's reference mesh failed: out of budget\n" in text


def test_table7_renders_a_probe_study():
    """A ProbeStudy's extras: the quick note, the reference check, Q errors, h and δ0, one
    'needed' row per probe set, upper bounds and unreached counts explained."""
    from hetmesh.fea.probe_study import ProbeStudy
    from hetmesh.reproduce import Report
    from hetmesh.reproduce.report import render

    P = [f"P{i}" for i in range(1, 7)]
    Q = [f"Q{i}" for i in range(1, 7)]
    vm = {k: 2e9 for k in P + Q}
    need = {"P": {"names": P, "uniform": 2500.0, "uniform_exact": True, "adaptive": 700.0,
                  "adaptive_exact": False, "reduction": 0.72},
            "Q": {"names": Q, "uniform": 1200.0, "uniform_exact": True, "adaptive": None,
                  "adaptive_exact": False, "reduction": None},
            "all": {"names": P + Q, "uniform": 2500.0, "uniform_exact": True,
                    "adaptive": 1000.0, "adaptive_exact": True, "reduction": 0.6}}
    s = ProbeStudy(
        reference={"elements": 19000, "h": 0.35, "von_mises": vm, "solve_seconds": 1.9,
                   "check": {"elements": 4700, "von_mises": vm,
                             "difference": {k: 0.0028 if k == "P2" else 0.001 for k in vm}}},
        meshes=[{"family": "uniform", "param": 1.07, "elements": 1932, "von_mises": vm,
                 "max_error": 0.0086, "errors": {"P": 0.0086, "Q": 0.0025, "all": 0.0086},
                 "solve_seconds": 0.1},
                {"family": "adaptive", "param": 0.2, "elements": 754, "von_mises": vm,
                 "max_error": 0.0036, "errors": {"P": 0.0036, "Q": 0.0081, "all": 0.0081},
                 "solve_seconds": 0.05},
                {"family": "adaptive", "param": 0.05, "error": "budget exceeded"}],
        needed=need["P"], needed_by_set=need, probe_sets={"P": P, "Q": Q, "all": P + Q},
        primary="P", quick=True, order=2, note="quick run: reference uniform h = 0.35")
    text = render(Report(path=Path("r.md"), quick=True, cases=["fgm_plate"], runs=[],
                         peer_versions={}, peers_run=False, fea=s))
    check_numbers_parse(text)
    assert "**Quick run**" in text and "Study: quick run: reference uniform h = 0.35." in text
    assert "differs from the reference by at most 0.280 % at P1..P6" in text
    (headers, rows), = table_with(text, "P1 GPa")
    rows = [dict(zip(headers, r)) for r in rows]
    assert rows[0]["h"] == "0.350" and rows[0]["solve s"] == "1.90"
    assert rows[1]["max error P1..P6 %"] == "0.860" and rows[1]["max error Q1..Q6 %"] == "0.250"
    assert (rows[1]["h"], rows[1]["δ0"]) == ("1.070", "n/a")
    assert (rows[2]["h"], rows[2]["δ0"]) == ("n/a", "0.200")
    assert "- adaptive mesh 0.050 failed: budget exceeded" in text
    (h2, r2), = table_with(text, "reduction paper")
    got = {r[0]: dict(zip(h2, r)) for r in r2}
    assert list(got) == ["P1..P6", "Q1..Q6", "all 12"]
    assert got["P1..P6"]["reduction"] == "0.720" and got["P1..P6"]["≥ 40 % fewer"] == "yes"
    assert got["P1..P6"]["reduction paper"] == "0.320"
    assert got["Q1..Q6"]["adaptive"] == "n/a" and got["Q1..Q6"]["reduction"] == "n/a"
    assert "P1..P6: the coarsest adaptive mesh is within 0.5 % already, so 700 is an upper " \
           "bound and the reduction a lower bound." in text
    assert "Q1..Q6: no adaptive mesh of the study brings every probe within 0.5 %" in text


def test_table7_accepts_the_benchmark_keys():
    from hetmesh.reproduce import Report
    from hetmesh.reproduce.report import render

    vm = {f"P{i}": 1e9 for i in range(1, 7)}
    study = {"reference": vm,
             "runs": [{"kind": "adaptive", "elements": 600, "vm": vm, "err_P": 0.001},
                      {"kind": "uniform", "param": 1.0, "error": "ERROR x"}],
             "needed": {"P1..P6": {"uniform": 900.0, "adaptive": 600.0}}}
    text = render(Report(path=Path("r.md"), quick=True, cases=["fgm_plate"], runs=[],
                         peer_versions={}, peers_run=False, fea=study))
    check_numbers_parse(text)
    (headers, rows), = table_with(text, "P1 GPa")
    assert rows[1][:3] == ["adaptive", "600", "1.0000"]
    (h2, r2), = table_with(text, "reduction paper")
    assert dict(zip(h2, r2[0]))["reduction"] == "0.333"


def test_misprint_footnotes_are_numbered_once():
    from hetmesh.metrics import MeshStats
    from hetmesh.reproduce.report import stats_table
    from hetmesh.reproduce.runs import CaseRun, MeshRun

    st = MeshStats(10, 20, 0.5, 0.9, 0.0, 0.01, 0.05, 30.0)
    run = CaseRun("hft_ring", 0.10, adaptive=MeshRun(st, 1.0), uniform=MeshRun(st, 1.0))
    text = "\n".join(stats_table([run]))
    (headers, rows), = tables(text)
    uni = dict(zip(headers, rows[1]))
    assert uni["q_min paper"] == "0.5356 [1]" and uni["q_avg paper"] == "0.9247 [1]"
    assert text.count("[1] the paper's q_min/q_avg") == 1 and "[2]" not in text


@pytest.mark.skipif(not HAVE_GMSH, reason="no gmsh")
def test_peer_size_field_keeps_the_chord_tolerance():
    """The peers' size field is capped along arcs at hetmesh's chord tolerance, so the peer's
    holes are as accurate as hetmesh's (without the cap Gmsh made plate_with_holes' holes at
    0.2 with a handful of chords)."""
    model = hetmesh.load_model(hetmesh.example_path("plate_with_holes"))
    tol = 1e-3 * model.domain.diameter
    worst = {}
    for cap in (1e-3, None):
        mesh = peers.gmsh_mesh(model.domain, peers.size_field(model, 0.2, 1.0, chord_tol=cap))
        P, T = mesh.points, mesh.triangles
        edges = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
        edges = np.unique(edges, axis=0)
        for (cx, cy), r in (((15.0, 20.0), 4.0), ((45.0, 20.0), 5.0)):
            d = np.abs(np.hypot(P[:, 0] - cx, P[:, 1] - cy) - r)
            on = d < 1e-9 * r
            e = edges[on[edges[:, 0]] & on[edges[:, 1]]]
            L = np.linalg.norm(P[e[:, 0]] - P[e[:, 1]], axis=1)
            sag = r - np.sqrt(r * r - (L / 2) ** 2)
            worst[cap] = max(worst.get(cap, 0.0), float(sag.max()))
    assert worst[1e-3] <= tol * (1 + 1e-6)
    assert worst[None] > 5 * tol
