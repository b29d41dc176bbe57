"""Rendering a :class:`~hetmesh.reproduce.Report` as Markdown (pure: records in, text out).

Numbers are written plainly (``1398``, ``0.9448``; ``n/a`` where there is none) so that the
report's tables can be parsed back. Every column holding the paper's values has ``paper`` in
its header.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from .. import peers as pc
from ..io.atomic import atomic_write
from .paper import CASES, NOTE_KEYS, NOTES, PAPER_TABLE7

__all__ = ["render", "write_report", "markdown_table", "num", "PEER_LABELS", "peer_verdicts",
           "paper_row", "render3d"]

NA = "n/a"
PEER_LABELS = {"gmsh": "Gmsh", "triangle": "Triangle"}
STAT_COLUMNS = (("Np", "n_points", 0), ("Ne", "n_elements", 0), ("q_min", "q_min", 4),
                ("q_avg", "q_avg", 4), ("δ_min", "delta_min", 4), ("δ_avg", "delta_avg", 4))
#: hetmesh's peer targets (reported, not asserted)
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
        "example file and docs/cases.md in hetmesh's repository), so the paper's element "
        "counts are a reference, not a target; its *ratios* adaptive/uniform are the "
        "comparable quantity.",
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


def paper_row(case, kind: str, threshold: float):
    """The paper's ``kind`` ("adaptive" or "uniform") row of ``case`` at ``threshold``, or None."""
    rows = getattr(case, kind)
    for t, row in rows.items():
        if math.isclose(t, threshold):
            return row
    return None


def stats_table(runs) -> list[str]:
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
            paper = paper_row(case, kind, r.threshold)
            cells = [r.case, num(r.threshold, 2), kind]
            for _label, key, digits in STAT_COLUMNS:
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
        pa, pu = paper_row(case, "adaptive", r.threshold), paper_row(case, "uniform", r.threshold)
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
        out += stats_table(runs) + [""]
        out += [f"Element counts against N_iso and the uniform baseline ({table}):", ""]
        out += _ratio_table(runs) + [""]
        out += [f"Figures ({figs} analogs): meshes coloured by the last constituent's fraction, "
                "interfaces and embedded material discontinuities in red.", ""]
        out += _figures(runs)
    return out


def peer_verdicts(run) -> dict | None:
    """hetmesh's peer targets at one threshold: best peer, element ratio, verdicts."""
    ok = {p: pr for p, pr in run.peers.items() if pr.stats is not None}
    if run.adaptive is None or not ok:
        return None
    best = min(ok, key=lambda p: ok[p].stats.n_elements)
    h, b = run.adaptive.stats, ok[best].stats
    ratio = h.n_elements / b.n_elements
    return {"best": best, "ratio": ratio, "fewer": ratio < 1.0,
            "fewer_35": (ratio <= 1.0 - FEWER_BY) if run.threshold <= FEWER_AT + 1e-12 else None,
            "quality": h.q_avg >= b.q_avg - Q_SLACK}


def _times(n: int) -> str:
    return {1: "once", 2: "twice"}.get(n, f"{n} times")


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
        f"diameter / 8, sampled on a {pc.GRID_CELLS}-cell grid and graded (h grows by at most "
        f"{pc.GRADATION:g} per unit length), `hetmesh.peers`. s starts at {pc.S_START:g} and is "
        f"lowered by the factor {pc.S_FACTOR:g} until the peer's δ_max < δ0 (raised while it "
        f"already holds), then the last step is bisected {_times(pc.S_BISECT)}: the peer's mesh "
        "is the coarsest found that meets the threshold. δ and q are evaluated exactly as for "
        "hetmesh's meshes. "
        f"Gmsh: Frontal-Delaunay (`Mesh.Algorithm = {pc.GMSH_ALGORITHM}`), 1 thread, lines and "
        "circular arcs, sizes from the background field only (a PostView). Triangle: the "
        f"curves sampled with the same size, `-pq{pc.MIN_ANGLE:g}` (hetmesh's {pc.MIN_ANGLE:g}° "
        f"angle floor), then `-rpq{pc.MIN_ANGLE:g}a` with a per-triangle maximum area "
        "√3/4·h(centroid)² until every triangle obeys it. "
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
        verdicts.append(v)
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
    vs = [v for v in verdicts if v is not None]
    if not vs:
        return ["No peer met any threshold.", ""]
    fewer = sum(v["fewer"] for v in vs)
    at35 = [v for v in vs if v["fewer_35"] is not None]
    q = sum(v["quality"] for v in vs)
    met = fewer == len(vs) and all(v["fewer_35"] for v in at35) and q == len(vs)
    return [
        "hetmesh's target (reported, not asserted): hetmesh needs fewer elements than the "
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


def _has(obj, key) -> bool:
    return key in obj if isinstance(obj, dict) else hasattr(obj, key)


def _pct(value) -> str:
    return NA if value is None else num(100.0 * float(value), 3)


def _needed_rows(study) -> tuple[list[list[str]], list[str]]:
    """Rows of the 'elements needed' table (the primary probe set first) and its notes."""
    by_set = _get(study, "needed_by_set", default=None)
    need = _get(study, "needed", default=None)
    if by_set:
        entries = list(by_set.items())
    elif need is not None:
        entries = [("P", _get(need, "P1..P6", default=need))]
    else:
        return [], []
    rows, notes = [], []
    for key, nd in entries:
        names = _get(nd, "names", default=None)
        label = (f"all {len(names)}" if key == "all" and names else
                 f"{names[0]}..{names[-1]}" if names else "P1..P6" if key == "P" else str(key))
        nu, na = _get(nd, "uniform"), _get(nd, "adaptive")
        red = _get(nd, "reduction") if _has(nd, "reduction") else \
            ((1.0 - na / nu) if (nu and na) else None)
        rows.append([label, num(nu, 0), num(na, 0), num(red, 3),
                     "0.320" if key == "P" else NA,
                     NA if red is None else ("yes" if red >= 0.40 else "no")])
        for fam, v in (("uniform", nu), ("adaptive", na)):
            if v is None:
                notes.append(f"{label}: no {fam} mesh of the study brings every probe within "
                             f"0.5 % for good (n/a).")
            elif _get(nd, f"{fam}_exact", default=True) is False:
                notes.append(f"{label}: the coarsest {fam} mesh is within 0.5 % already, so "
                             f"{num(v, 0)} is an upper bound"
                             + (" and the reduction a lower bound." if fam == "adaptive"
                                and red is not None else "."))
    return rows, notes


def _fea_section(report) -> list[str]:
    """The Table 7 analog from ``hetmesh.fea.study`` (omitted when the study is absent).

    The study's result (docs/reproduce.md): ``reference`` (``elements``, ``von_mises``),
    ``meshes`` (``family``, ``elements``, ``von_mises``, ``max_error``) and ``needed``
    (``uniform``, ``adaptive``), optionally ``errors`` per probe set, ``needed_by_set``,
    ``quick`` and ``note`` (:class:`hetmesh.fea.ProbeStudy`); the keys of
    benchmarks/bench_fea.py's old records (``kind``, ``vm``, ``err_P``, ``err_Q``,
    ``needed["P1..P6"]``) are accepted too. Stresses in Pa.
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
    check = _get(ref, "check", default=None) if isinstance(ref, dict) else None
    quick = _get(study, "quick", default=None)
    intro = ("`hetmesh.fea.study` on `fgm_plate` (its `[fea]` table: steady conduction, then "
             "plane-strain thermoelasticity, element order "
             f"{_get(study, 'order', default='?')}): a fine uniform reference mesh, then "
             "uniform meshes (edge h) and adaptive meshes (`hetmesh.generate` at δ0) of "
             "increasing size. Von Mises stress at the probes P1..P6 (GPa) and the largest "
             "relative error against the reference over P1..P6 and over Q1..Q6 (the test "
             "points of docs/cases.md, section 5); "
             "rows labelled *paper* are the paper's Table 7 (its meshes, its geometry).")
    paper_ref = PAPER_TABLE7.get(("uniform", 4600))
    ratios = [_get(ref_vm, p, default=math.nan) / 1e9 / v for p, v in zip(probes, paper_ref or ())]
    ratios = [r for r in ratios if math.isfinite(r)]
    if ratios:
        intro += (f" Our reference stresses are {min(ratios):.2f} to {max(ratios):.2f} times "
                  "the paper's: at a traction-free convex corner plane-strain von Mises tends "
                  "to |σ_zz| = E α ΔT (2.6 GPa at B, P1) whatever the mesh, and the paper's "
                  "geometry and COMSOL settings are not given (docs/fea.md); the errors and "
                  "element counts are the comparable quantities.")
    out += [intro, ""]
    if quick:
        out += ["**Quick run**: a coarser reference and fewer meshes than the full report's "
                "study (`hetmesh reproduce` without `--quick`); its numbers are indicative "
                "only.", ""]
    if _get(study, "note", default=None):
        out += [f"Study: {_get(study, 'note')}.", ""]
    if check:
        diff = _get(check, "difference", default={})
        worst = max((diff[p] for p in probes if p in diff), default=None)
        if worst is not None:
            out += [f"Reference check: the same problem on a uniform mesh of twice the edge "
                    f"({num(_get(check, 'elements'))} elements) differs from the reference "
                    f"by at most {_pct(worst)} % at P1..P6; converging at first order or "
                    f"faster, that bounds the reference's own error.", ""]
    headers = (["mesh", "elements"] + [f"{p} GPa" for p in probes]
               + ["max error P1..P6 %", "max error Q1..Q6 %", "h", "δ0", "solve s"])
    rows = [["reference (uniform)", num(_get(ref, "elements"))]
            + [num(_get(ref_vm, p, default=math.nan) / 1e9, 4) for p in probes]
            + [NA, NA, num(_get(ref, "h"), 3), NA, num(_get(ref, "solve_seconds"), 2)]]
    for m in _get(study, "meshes", "runs", default=[]):
        if _get(m, "error") is not None:
            continue
        vm = _von_mises(m)
        family = str(_get(m, "family", "kind"))
        errors = _get(m, "errors", default={}) or {}
        param = _get(m, "param")
        rows.append([family, num(_get(m, "elements"))]
                    + [num(_get(vm, p, default=math.nan) / 1e9, 4) for p in probes]
                    + [_pct(_get(m, "max_error", "err_P")),
                       _pct(errors.get("Q", _get(m, "err_Q"))),
                       num(param, 3) if family == "uniform" else NA,
                       num(param, 3) if family == "adaptive" else NA,
                       num(_get(m, "solve_seconds"), 2)])
    for (family, ne), values in PAPER_TABLE7.items():
        rows.append([f"{family} paper", str(ne)] + [num(v, 4) for v in values]
                    + [NA] * 5)
    out += markdown_table(headers, rows) + [""]
    failed = [m for m in _get(study, "meshes", "runs", default=[])
              if _get(m, "error") is not None]
    for m in failed:
        out.append(f"- {_get(m, 'family', 'kind')} mesh {num(_get(m, 'param'), 3)} failed: "
                   f"{_get(m, 'error')}")
    if failed:
        out.append("")
    need_rows, notes = _needed_rows(study)
    if need_rows:
        out += ["Elements each family needs to bring every probe within 0.5 % of the "
                "reference for good (the error crossing 0.5 % between two meshes of the "
                "family, interpolated in log-log), and the reduction 1 - adaptive/uniform "
                "(hetmesh's target: at least 0.40; the paper: 633 against 931, 0.32, for "
                "P1..P6):", ""]
        out += markdown_table(["probes", "uniform", "adaptive", "reduction",
                               "reduction paper", "≥ 40 % fewer"], need_rows) + [""]
        out += [f"- {n}" for n in notes] + ([""] if notes else [])
    return out


def render(report) -> str:
    """The whole report.md."""
    lines = _header(report) + _case_sections(report) + _peer_section(report) \
        + _fea_section(report) + render3d(getattr(report, "study3d", None))
    return "\n".join(lines).rstrip() + "\n"


# ----------------------------------------------------------------------------- 3-D section

def render3d(section) -> list[str]:
    """The 3-D section of report.md from a :class:`~hetmesh.reproduce.study3d.Section3D`
    (nothing when it was not run)."""
    if section is None:
        return []
    out = ["## 3-D: graded solids, adaptive against uniform tetrahedra", "",
           "The paper is 2-D; this section runs its comparison on two solids "
           "(`hetmesh reproduce --3d`): `fgm_plate_3d` (case study 4's plate extruded 10 mm, "
           "plane strain) and `graded_cylinder` (a graded tube under 100 MPa internal "
           "pressure). Adaptive: `hetmesh.generate`; uniform: `hetmesh.uniform`, the "
           "coarsest swept mesh of one size meeting δ0 (docs/tet.md); N_iso3 = "
           "6√2 ∫|∇f|³ dV / δ0³. Dihedral angles in degrees; ρ the mean radius ratio; "
           "*adaptive s* the wall time of `hetmesh.generate`.", ""]
    if section.quick:
        out += ["**Quick run**: one threshold per solid and the quick FEA plan (fewer "
                "meshes); indicative only.", ""]
    peers = sorted({p for r in section.runs for p in r.peers})
    headers = ["solid", "δ0", "adaptive Ne", "Ne/N_iso3", "δ_max", "dihedral min / 1st pct",
               "ρ", "adaptive s", "uniform Ne", "h", "uniform δ_max", "adaptive/uniform"]
    headers += [f"{p.capitalize()} Ne" for p in peers]
    rows = []
    for r in section.runs:
        if r.error:
            rows.append([r.case, f"{r.threshold:g}", "error: " + r.error]
                        + [""] * (len(headers) - 3))
            continue
        a, u = r.adaptive, r.uniform
        row = [r.case, f"{r.threshold:g}", num(a["elements"]),
               num(a["elements"] / r.n_iso3, 2), num(a["delta_max"], 4),
               f"{a['dihedral_min']:.1f} / {a['dihedral_p1']:.1f}",
               num(a["radius_ratio_mean"], 3), num(a["seconds"], 1), num(u["elements"]),
               num(u["size"], 3), num(u["delta_max"], 4), num(r.ratio, 3)]
        for p in peers:
            pr = r.peers.get(p, {})
            row.append(num(pr["elements"]) if "elements" in pr else
                       ("error" if "error" in pr else NA))
        rows.append(row)
    out += markdown_table(headers, rows) + [""]
    for r in section.runs:
        for p, pr in r.peers.items():
            if "error" in pr:
                out.append(f"- {p} on {r.case} at δ0 = {r.threshold:g}: {pr['error']}")
            else:
                out.append(f"- {p} on {r.case} at δ0 = {r.threshold:g}: s = {pr['s']:.3f}, "
                           f"δ_max {pr['delta_max']:.4f}, dihedral min "
                           f"{pr['dihedral_min']:.1f}, {pr['seconds']:.1f} s for the "
                           f"accepted mesh, {pr['search_seconds']:.0f} s for the search")
    if any(r.peers for r in section.runs):
        out.append("")
    if section.studies or section.study_errors:
        out += _study_lines(section)
    if getattr(section, "refinements", None):
        out += _refinement_lines(section)
    return out


def _refinement_lines(section) -> list[str]:
    """The study's third family: material-adaptive + solution-adaptive refinement
    (:func:`hetmesh.fea.adapt.refinement_study`)."""
    out = ["### 3-D: material-adaptive + solution-adaptive refinement", "",
           "`hetmesh.fea.adapt`: the adaptive mesh at the plan's largest δ0 solved, its "
           "elements' errors estimated by Zienkiewicz-Zhu stress recovery (with the "
           "indicator `goal`: weighted by the ZZ error of the dual solution for the probes' "
           "von Mises stresses, `hetmesh.fea.goal`), the elements "
           "carrying half of the estimate (Dörfler marking) bisected along their longest "
           "edge (with the edges `stress`: lengths along the directions in which the "
           "recovered stress hardly varies counted shorter), new boundary vertices put on "
           "the exact surface, the mesh re-verified "
           "(δ_max < δ0), solved again; every step one mesh of the family.", ""]
    for name, r in section.refinements.items():
        if "error" in r:
            out += [f"- {name}: the refinement failed: {r['error']}", ""]
            continue
        sets = list(r["needed"])
        rows = [[str(m["param"]), num(m["elements"]), num(100 * m["estimate"], 3)]
                + [num(100 * m["errors"][k], 3) for k in sets] + [num(m["solve_seconds"], 1)]
                for m in r["meshes"]]
        goal = r.get("indicator", "energy") == "goal"
        start = r.get("start_chord_tol")
        factor = r.get("goal_element_factor") if goal else None
        out += [f"**{name}** (from δ0 = {r['threshold']:g}"
                + ("" if start is None else f", chord tolerance {start:g}")
                + f", indicator {r.get('indicator', 'energy')}"
                + f", edges {r.get('edges') or 'longest'}"
                + ("" if factor is None else f" (mollifier at least {factor:g} x the probe "
                   f"element's longest edge)")
                + f", fraction {r['fraction']:g}, "
                f"stopped: {r['reason']}, {r['seconds']:.0f} s).", ""]
        out += markdown_table(["step", "tets", "probe estimate %" if goal else "ZZ estimate %"]
                              + [f"max error {k} %" for k in sets] + ["solve s"], rows) + [""]
        rows = []
        for k, nd in r["needed"].items():
            def cnt(v, exact):
                if v is None:
                    return NA
                return num(int(round(v))) if exact else f"<= {num(int(round(v)))}"
            ratio = NA if nd["ratio"] is None else (
                num(nd["ratio"], 3) if nd["refined_exact"] else f"<= {num(nd['ratio'], 3)}")
            rows.append([k, cnt(nd["uniform"], nd["uniform_exact"]),
                         NA if nd["adaptive"] is None else num(int(round(nd["adaptive"]))),
                         cnt(nd["refined"], nd["refined_exact"]), ratio])
            if "uniform_start_chord" in nd:
                same = nd["ratio_start_chord"]
                rows[-1] += [cnt(nd["uniform_start_chord"], nd["uniform_start_chord_exact"]),
                             NA if same is None else (num(same, 3) if nd["refined_exact"]
                                                      else f"<= {num(same, 3)}")]
        head = ["probes", "(a) uniform", "(b) adaptive", "(c) adaptive + refined",
                "(c)/(a), target <= 0.5"]
        if any("uniform_start_chord" in nd for nd in r["needed"].values()):
            head += [f"(a') uniform, chord {r['start_chord_tol']:g}", "(c)/(a')"]
            rows = [row + [NA, NA] * (len(row) == 5) for row in rows]
        out += markdown_table(head, rows) + [""]
    return out


def _study_lines(section) -> list[str]:
    from .study3d import CHORD_TOL

    out = ["### 3-D FEA study: tetrahedra for 0.5 % at the probes", "",
           "`hetmesh.fea.probe_study.study3d`: quadratic tetrahedra; the von Mises stress at "
           "every probe against the reference (fgm_plate_3d: the 2-D plane-strain solution "
           "of fgm_plate on a fine uniform mesh, exact at every z for these end conditions; "
           "graded_cylinder: the exact radial solution); uniform swept meshes of "
           "increasing size and adaptive meshes at decreasing δ0, both with the chord "
           f"tolerance {CHORD_TOL:g} x the diameter. Tetrahedra needed: where the largest "
           "error crosses 0.5 % for good (log-log interpolation; the target: adaptive at "
           "most half of uniform).", ""]
    for name, msg in section.study_errors.items():
        out += [f"- {name}: the study failed: {msg}", ""]
    for name, s in section.studies.items():
        out += [f"**{name}** ({s.note}).", ""]
        check = s.reference.get("check") if isinstance(s.reference, dict) else None
        if check:
            worst = max(check["difference"].values())
            out += [f"Reference: {s.reference['elements']} triangles; on twice the edge "
                    f"({check['elements']}) it differs by at most {100 * worst:.3f} %.", ""]
        sets = list(s.probe_sets)
        rows = []
        for m in s.meshes:
            if "error" in m:
                rows.append([m["family"], num(m["param"], 3), "error: " + m["error"]]
                            + [""] * len(sets))
                continue
            rows.append([m["family"], num(m["param"], 3), num(m["elements"])]
                        + [num(100 * m["errors"][k], 3) for k in sets]
                        + [num(m["solve_seconds"], 1)])
        out += markdown_table(["mesh", "h or δ0", "tets"]
                              + [f"max error {k} %" for k in sets] + ["solve s"], rows)
        out += [""]
        need = []
        for key, nd in s.needed_by_set.items():
            nu, na = nd["uniform"], nd["adaptive"]
            ratio = na / nu if (nu and na) else None
            need.append([key, num(nu, 0) + ("" if nd["uniform_exact"] or nu is None
                                            else " (upper bound)"),
                         num(na, 0) + ("" if nd["adaptive_exact"] or na is None
                                       else " (upper bound)"),
                         num(ratio, 3), NA if ratio is None else
                         ("yes" if ratio <= 0.5 else "no")])
        out += markdown_table(["probes", "uniform tets", "adaptive tets", "adaptive/uniform",
                               "≤ 0.5"], need) + [""]
    return out
