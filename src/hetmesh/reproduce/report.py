"""Rendering a :class:`~hetmesh.reproduce.Report` as Markdown (pure: records in, text out).

Numbers are written plainly (``1398``, ``0.9448``; ``n/a`` where there is none) so that the
report's tables can be parsed back. Every column holding the paper's values has ``paper`` in
its header.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterable, Sequence

from ..io.atomic import atomic_write
from .paper import CASES, NOTE_KEYS, NOTES, PAPER_TABLE7

__all__ = ["render", "write_report", "markdown_table", "num", "PEER_LABELS", "peer_verdicts"]

NA = "n/a"
PEER_LABELS = {"gmsh": "Gmsh", "triangle": "Triangle"}
STAT_COLUMNS = (("Np", "n_points", 0), ("Ne", "n_elements", 0), ("q_min", "q_min", 4),
                ("q_avg", "q_avg", 4), ("δ_min", "delta_min", 4), ("δ_avg", "delta_avg", 4))
#: the issue's peer targets (reported, not asserted)
FEWER_AT, FEWER_BY, Q_SLACK = 0.05, 0.35, 0.03


def num(value: Any, digits: int = 4) -> str:
    """A number as a table cell: ints plainly, floats with ``digits`` decimals, else n/a."""
    if value is None:
        return NA
    if isinstance(value, (int,)) and not isinstance(value, bool):
        return str(value)
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    if not math.isfinite(v):
        return NA
    return str(int(round(v))) if digits == 0 else f"{v:.{digits}f}"


def markdown_table(headers: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    """Lines of a Markdown table (first column left-aligned, the others right-aligned)."""
    lines = ["| " + " | ".join(headers) + " |",
             "|" + "|".join([":--"] + ["--:"] * (len(headers) - 1)) + "|"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return lines


def write_report(path: Path, text: str) -> Path:
    """Write the report atomically."""
    with atomic_write(path) as fh:
        fh.write(text)
    return path


# ----------------------------------------------------------------------------- sections
def _header(report) -> list[str]:
    env = report.environment
    mode = ("quick (one coarse threshold per model" +
            (", peers included)" if report.peers_run else ", no peers)")) if report.quick \
        else "full"
    return [
        "# hetmesh reproduce: the paper's tables and figures",
        "",
        f"hetmesh {env.get('hetmesh', '?')}, Python {env.get('python', '?')}, numpy "
        f"{env.get('numpy', '?')}, {env.get('platform', '?')}, {env.get('cpus', '?')} CPU(s); "
        f"{env.get('date', '')}. Mode: {mode}. Models: {', '.join(report.cases)}. "
        f"Total wall time: {num(report.seconds, 1)} s.",
        *([f"Command: `{env['command']}`"] if env.get("command") else []),
        "",
        "Every number in this report was computed by this run, except the columns headed "
        "**paper**, which are the paper's own values (its Tables 1, 3, 5 and 7). The paper "
        "gives no figure dimensions: the models' geometries are reconstructions (see each "
        "example file and CASES.md), so the paper's element counts are a reference, not a "
        "target; its *ratios* adaptive/uniform are the comparable quantity.",
        "",
        "Definitions. *adaptive*: `hetmesh.generate(model, delta_0)` with default options; "
        "*uniform*: `hetmesh.uniform(model, delta_0)`, the coarsest uniform quality mesh with "
        "delta_max < delta_0 (the paper's baseline); *time*: wall seconds of that call. "
        "q = 2r/R (Eq. 17). δ(T) = the largest composition difference between an element's "
        "vertices (Eqs. 14-15), every element evaluated in its own subregion. "
        "N_iso = (4/√3) ∫ |∇f|² dA / δ0², the number of equilateral elements of side "
        "δ0/|∇f| (`hetmesh.density.n_iso`).",
        "",
    ]


def _paper_row(case, kind: str, threshold: float):
    rows = getattr(case, kind)
    for t, row in rows.items():
        if math.isclose(t, threshold):
            return row
    return None


def _stats_table(report, table: str, runs) -> list[str]:
    headers = ["model", "δ0", "mesh"]
    for label, _, _ in STAT_COLUMNS:
        headers += [label, f"{label} paper"]
    headers += ["δ_max", "time s"]
    rows, notes = [], []
    for r in runs:
        case = CASES[r.case]
        if r.error:
            rows.append([r.case, num(r.threshold, 2), "error: " + r.error.replace("|", "/")]
                        + [""] * (len(headers) - 3))
            continue
        for kind in ("adaptive", "uniform"):
            mr = getattr(r, kind)
            paper = _paper_row(case, kind, r.threshold)
            cells = [r.case, num(r.threshold, 2), kind]
            for label, key, digits in STAT_COLUMNS:
                cells.append(num(getattr(mr.stats, key), digits))
                pv = num(getattr(paper, key), digits) if paper else NA
                if paper and key in NOTE_KEYS.get(paper.note, ()):
                    if NOTES[paper.note] not in notes:
                        notes.append(NOTES[paper.note])
                    pv += f" [{notes.index(NOTES[paper.note]) + 1}]"
                cells.append(pv)
            cells += [num(mr.stats.delta_max, 4), num(mr.seconds, 3)]
            rows.append(cells)
    out = markdown_table(headers, rows)
    if notes:  # each note once, numbered in order of appearance
        out += [""] + [f"[{i + 1}] {n}" for i, n in enumerate(notes)]
    return out


def _ratio_table(runs) -> list[str]:
    headers = ["model", "δ0", "N_iso", "Ne adaptive", "Ne uniform", "adaptive/uniform",
               "adaptive/uniform paper", "Ne/N_iso adaptive", "Ne/N_iso uniform",
               "δ_avg/δ0 adaptive", "δ_avg/δ0 paper"]
    rows = []
    for r in runs:
        if r.error:
            continue
        case = CASES[r.case]
        pa, pu = _paper_row(case, "adaptive", r.threshold), _paper_row(case, "uniform", r.threshold)
        a, u = r.adaptive.stats, r.uniform.stats
        rows.append([r.case, num(r.threshold, 2), num(r.n_iso, 0), num(a.n_elements),
                     num(u.n_elements), num(r.ratio, 3),
                     num(pa.n_elements / pu.n_elements, 3) if pa and pu else NA,
                     num(a.n_elements / r.n_iso, 3), num(u.n_elements / r.n_iso, 3),
                     num(a.delta_avg / r.threshold, 3),
                     num(pa.delta_avg / r.threshold, 3) if pa else NA])
    return markdown_table(headers, rows)


def _figures(runs) -> list[str]:
    out = []
    for r in runs:
        if r.mesh_figure:
            out += [f"![{r.case}, adaptive mesh at δ0 = {r.threshold:g}]({r.mesh_figure})", ""]
        if r.histogram:
            out += [f"![{r.case}, δ histograms at δ0 = {r.threshold:g}]({r.histogram})",
                    "",
                    f"δ over the elements at δ0 = {r.threshold:g}: the adaptive mesh "
                    f"({r.adaptive.stats.n_elements} elements) against a uniform mesh of about "
                    f"the same size ({r.histogram_uniform_elements} elements).", ""]
    return out


def _case_sections(report) -> list[str]:
    out = []
    tables: dict[str, list] = {}
    for r in report.runs:
        tables.setdefault(CASES[r.case].table, []).append(r)
    for table, runs in tables.items():
        names = list(dict.fromkeys(r.case for r in runs))
        figs = ", ".join(CASES[n].figures for n in names)
        out += [f"## {table} analog: {', '.join(names)}", ""]
        out += [f"- `{n}`: {CASES[n].title}" for n in names] + [""]
        out += _stats_table(report, table, runs) + [""]
        out += [f"Element counts against N_iso and the uniform baseline ({table}):", ""]
        out += _ratio_table(runs) + [""]
        out += [f"Figures ({figs} analogs): meshes coloured by the last constituent's fraction, "
                "interfaces and embedded material discontinuities in red.", ""]
        out += _figures(runs)
    return out


def peer_verdicts(run) -> dict | None:
    """The issue's peer targets at one threshold: best peer, element ratio, verdicts."""
    ok = {p: pr for p, pr in run.peers.items() if pr.stats is not None}
    if run.adaptive is None or not ok:
        return None
    best = min(ok, key=lambda p: ok[p].stats.n_elements)
    h, b = run.adaptive.stats, ok[best].stats
    ratio = h.n_elements / b.n_elements
    return {"best": best, "ratio": ratio, "fewer": ratio < 1.0,
            "fewer_35": (ratio <= 1.0 - FEWER_BY) if run.threshold <= FEWER_AT + 1e-12 else None,
            "quality": h.q_avg >= b.q_avg - Q_SLACK}


def _yes(v) -> str:
    return NA if v is None else ("yes" if v else "no")


def _peer_section(report) -> list[str]:
    out = ["## Peers: Gmsh and Triangle at the same thresholds", ""]
    if not report.peers_run:
        return out + ["Peers were not run (`--quick` or `peers=False`).", ""]
    installed = [p for p, v in report.peer_versions.items() if v]
    missing = [PEER_LABELS[p] for p, v in report.peer_versions.items() if not v]
    if not installed:
        return out + ["Neither Gmsh nor Triangle is installed, so this section is empty: "
                      "`pip install \"hetmesh[peers]\"` adds them.", ""]
    out += [
        "Each peer meshes the domain as hetmesh meshed it (material discontinuities embedded "
        "as constraint curves) with the size field h = min(h_max, s·δ0/|∇f|), h_max = domain "
        "diameter / 8, sampled on a 400-cell grid and graded (h grows by at most 0.3 per unit "
        "length), `hetmesh.peers`. s starts at 1.2 and is lowered by the factor 0.9 until the "
        "peer's δ_max < δ0 (raised while it already holds), then the last step is bisected "
        "twice: the peer's mesh is the coarsest found that meets the threshold. δ and q are "
        "evaluated exactly as for hetmesh's meshes. "
        "Gmsh: Frontal-Delaunay (`Mesh.Algorithm = 6`), 1 thread, lines and circular arcs, "
        "sizes from the background field only (a PostView). Triangle: the curves sampled "
        "with the same size, `-pq30` (hetmesh's 30° angle floor), then `-rpq30a` with a "
        "per-triangle maximum area √3/4·h(centroid)² until every triangle obeys it. "
        "*time*: wall seconds of the one accepted peer run (geometry, field, meshing; the "
        "search costs more, column *search s*); hetmesh's time is its `generate` call.",
        "",
        "Versions: " + ", ".join(f"{PEER_LABELS[p]} {report.peer_versions[p]}"
                                 for p in installed) + "."
        + (f" Not installed: {', '.join(missing)}." if missing else ""),
        "",
    ]
    headers = ["model", "δ0", "hetmesh Ne", "hetmesh q_min", "hetmesh q_avg", "hetmesh time s"]
    for p in installed:
        L = PEER_LABELS[p]
        headers += [f"{L} Ne", f"{L} q_min", f"{L} q_avg", f"{L} time s", f"{L} search s",
                    f"{L} s"]
    headers += ["best peer", "Ne / best peer", "fewer elements", "≥ 35 % fewer (δ0 ≤ 0.05)",
                "q_avg ≥ peer − 0.03"]
    rows, verdicts = [], []
    for r in report.runs:
        if r.adaptive is None:
            continue
        a = r.adaptive
        cells = [r.case, num(r.threshold, 2), num(a.stats.n_elements), num(a.stats.q_min),
                 num(a.stats.q_avg), num(a.seconds, 3)]
        for p in installed:
            pr = r.peers.get(p)
            if pr is None or pr.stats is None:
                msg = f"failed: {pr.error}" if pr is not None and pr.error else NA
                cells += [msg.replace("|", "/")] + [NA] * 5
                continue
            cells += [num(pr.stats.n_elements), num(pr.stats.q_min), num(pr.stats.q_avg),
                      num(pr.seconds, 3), num(pr.search_seconds, 2), num(pr.s, 3)]
        v = peer_verdicts(r)
        verdicts.append((r, v))
        if v is None:
            cells += [NA] * 5
        else:
            cells += [PEER_LABELS[v["best"]], num(v["ratio"], 3), _yes(v["fewer"]),
                      _yes(v["fewer_35"]), _yes(v["quality"])]
        rows.append(cells)
    out += markdown_table(headers, rows) + [""]
    out += _peer_summary(verdicts)
    return out


def _peer_summary(verdicts) -> list[str]:
    vs = [v for _, v in verdicts if v is not None]
    if not vs:
        return ["No peer met any threshold.", ""]
    fewer = sum(v["fewer"] for v in vs)
    at35 = [v for v in vs if v["fewer_35"] is not None]
    q = sum(v["quality"] for v in vs)
    met = fewer == len(vs) and all(v["fewer_35"] for v in at35) and q == len(vs)
    return [
        "The issue's target (reported, not asserted): hetmesh needs fewer elements than the "
        "best peer at every threshold, at least 35 % fewer at δ0 ≤ 0.05, with q_avg at least "
        "the peer's minus 0.03.",
        "",
        f"- fewer elements than the best peer: {fewer} of {len(vs)} thresholds",
        f"- at least 35 % fewer at δ0 ≤ 0.05: {sum(bool(v['fewer_35']) for v in at35)} of "
        f"{len(at35)} thresholds",
        f"- q_avg ≥ best peer's q_avg − 0.03: {q} of {len(vs)} thresholds",
        f"- target met: {'yes' if met else 'no'}",
        "",
    ]


def _get(obj, *keys, default=None):
    """The first of ``keys`` that ``obj`` (a mapping or an object) has, else ``default``."""
    for key in keys:
        if isinstance(obj, dict):
            if key in obj:
                return obj[key]
        elif hasattr(obj, key):
            return getattr(obj, key)
    return default


def _von_mises(entry) -> dict:
    vm = _get(entry, "von_mises", "vm", default=None)
    return vm if vm is not None else (entry if isinstance(entry, dict) else {})


def _fea_section(report) -> list[str]:
    """The Table 7 analog from ``hetmesh.fea.study`` (omitted when the study is absent).

    The study's result (docs/reproduce.md): ``reference`` (``elements``, ``von_mises``),
    ``meshes`` (``family``, ``elements``, ``von_mises``, ``max_error``) and ``needed``
    (``uniform``, ``adaptive``); the keys of benchmarks/bench_fea.py (``kind``, ``vm``,
    ``err_P``, ``needed["P1..P6"]``) are accepted too. Stresses in Pa.
    """
    if report.fea is None and report.fea_error is None:
        return []
    out = ["## Table 7 analog: FEA accuracy per element (fgm_plate, case study 4)", ""]
    if report.fea is None:
        return out + [f"The FEA study failed: {report.fea_error}", ""]
    study = report.fea
    probes = [f"P{i}" for i in range(1, 7)]
    ref = _get(study, "reference", default={})
    ref_vm = _von_mises(ref)
    headers = ["mesh", "elements"] + [f"{p} GPa" for p in probes] + ["max rel. error"]
    rows = [["reference (uniform)", num(_get(ref, "elements"))]
            + [num(_get(ref_vm, p, default=math.nan) / 1e9, 4) for p in probes] + [NA]]
    for m in _get(study, "meshes", "runs", default=[]):
        if _get(m, "error") is not None:
            continue
        vm = _von_mises(m)
        rows.append([str(_get(m, "family", "kind")), num(_get(m, "elements"))]
                    + [num(_get(vm, p, default=math.nan) / 1e9, 4) for p in probes]
                    + [num(_get(m, "max_error", "err_P"), 5)])
    for (family, ne), values in PAPER_TABLE7.items():
        rows.append([f"{family} paper", str(ne)] + [num(v, 4) for v in values] + [NA])
    out += ["Von Mises stress at the probes P1..P6 (GPa) for hetmesh's uniform and adaptive "
            "meshes of increasing size, and the largest relative error over P1..P6 against "
            "the reference; rows labelled *paper* are the paper's Table 7 (its meshes, its "
            "geometry).", ""]
    out += markdown_table(headers, rows) + [""]
    need = _get(study, "needed", default=None)
    if need is not None:
        need = _get(need, "P1..P6", default=need)
        nu, na = _get(need, "uniform"), _get(need, "adaptive")
        red = (1.0 - na / nu) if (nu and na) else None
        out += ["Elements each family needs to bring every probe within 0.5 % of the "
                "reference, and the reduction 1 - adaptive/uniform (the paper: 633 against "
                "931, 32 %):", ""]
        out += markdown_table(
            ["mesh", "uniform", "adaptive", "reduction", "reduction paper"],
            [["every probe within 0.5 %", num(nu, 0), num(na, 0), num(red, 3), "0.320"]]) + [""]
    return out


def render(report) -> str:
    """The whole report.md."""
    lines = _header(report) + _case_sections(report) + _peer_section(report) \
        + _fea_section(report)
    return "\n".join(lines).rstrip() + "\n"
