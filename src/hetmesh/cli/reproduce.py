"""``hetmesh reproduce``: the paper's tables and figures, against the paper and the peers
(:func:`hetmesh.reproduce.run`)."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from ..errors import OutputError
from .mesh import check_writable_dir
from .progress import progress_reporter, result_console
from .sweep import worker_count

__all__ = ["add_parser", "run", "summary_table", "summary_3d"]


def _cases(text: str) -> list[str]:
    return [c.strip() for c in text.split(",") if c.strip()]


_cases.__name__ = "case list"


def add_parser(subparsers, parents: list[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    from ..reproduce import CASES

    p = subparsers.add_parser(
        "reproduce", parents=parents,
        help="the paper's tables and figures, against the paper, uniform meshes and peers",
        description="Mesh the paper's models at its thresholds, adaptively and uniformly, and "
                    "write DIR/report.md with PNG figures: Table 1, 3, 5 analogs with the "
                    "paper's numbers in adjacent columns, N_iso, meshes and delta histograms, "
                    "Gmsh and Triangle meeting the same thresholds (if installed: pip install "
                    "\"hetmesh[peers]\") and the FEA Table 7 analog when available. Every "
                    "number except the paper's columns is computed by this run.",
    )
    p.add_argument("--out", type=Path, default=Path("hetmesh-reproduce"), metavar="DIR",
                   help="directory for report.md and figures/, created if missing "
                        "(default: ./hetmesh-reproduce)")
    p.add_argument("--cases", type=_cases, default=None, metavar="LIST",
                   help=f"comma-separated models (default: all: {','.join(CASES)})")
    p.add_argument("--quick", action="store_true",
                   help="one coarse threshold per model and no peers (under a minute)")
    p.add_argument("--no-peers", action="store_true", help="skip the Gmsh/Triangle section")
    p.add_argument("--3d", dest="three_d", action="store_true",
                   help="add the 3-D section: fgm_plate_3d and graded_cylinder, adaptive "
                        "against uniform tetrahedra, Gmsh 3-D as peer, tetrahedra for 0.5 %% "
                        "at the FEA probes (a few minutes with --quick, ~15-20 without); "
                        "naming a solid in --cases runs only the 3-D section for it")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", "-j", type=worker_count, default=None, metavar="N",
                       help="run the models and the FEA study's meshes on a local Dask "
                            "cluster of N worker processes (default: in this process)")
    where.add_argument("--scheduler", metavar="ADDRESS", default=None,
                       help="run them on the Dask scheduler at ADDRESS (tcp://host:8786 or a "
                            "scheduler file); DIR must be shared with the workers")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress bar and no summary; errors only")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    from ..reproduce import plan
    from ..reproduce import run as reproduce

    plan(args.cases, args.quick)  # unknown cases fail before anything is written
    out: Path = args.out
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} is not a directory")
    if out.exists():
        check_writable_dir(out, f"--out {out}")
    command = "hetmesh " + " ".join(shlex.quote(a) for a in sys.argv[1:]) \
        if sys.argv and Path(sys.argv[0]).name in ("hetmesh", "__main__.py") else None
    with progress_reporter(quiet=args.quiet, label="reproduce") as progress:
        report = reproduce(out, cases=args.cases, quick=args.quick,
                           peers=False if args.no_peers else None, progress=progress,
                           command=command, workers=args.workers, scheduler=args.scheduler,
                           three_d=args.three_d)
    if not args.quiet:
        console = result_console()
        if report.runs:
            console.print(summary_table(report))
        for line in summary_3d(report):
            console.print(line)
        n_runs = len(report.runs)
        failed = sum(r.error is not None for r in report.runs)
        console.print(f"{n_runs} model/threshold runs ({failed} failed), "
                      f"{len(report.figures)} figures, {report.seconds:.1f} s")
        console.print(f"wrote {report.path}")
    return 0


def _count(v) -> str:
    return "n/a" if v is None else f"{v:.0f}"


def summary_3d(report) -> list[str]:
    """One line per 3-D solid and threshold (tetrahedra adaptive, uniform, ratio) and per
    FEA study (tetrahedra for 0.5 % at the probes); nothing without the 3-D section."""
    sec = getattr(report, "study3d", None)
    if sec is None:
        return []
    out = []
    for r in sec.runs:
        if r.error:
            out.append(f"3-D {r.case} δ0={r.threshold:g}: error: {r.error}")
            continue
        out.append(f"3-D {r.case} δ0={r.threshold:g}: adaptive {r.adaptive['elements']} tets, "
                   f"uniform {r.uniform['elements']}, ratio {r.ratio:.3f}")
    for name, s in sec.studies.items():
        nd = s.needed
        u, a = nd["uniform"], nd["adaptive"]
        out.append(f"3-D FEA {name}, 0.5 % at {nd['probes']}: uniform {_count(u)} tets, "
                   f"adaptive {_count(a)}" + (f" (ratio {a / u:.2f})" if u and a else ""))
    for name, msg in sec.study_errors.items():
        out.append(f"3-D FEA {name}: failed: {msg}")
    return out


def summary_table(report):
    """A rich table of the report's headline numbers: elements adaptive and uniform, their
    ratio beside the paper's, the best peer's elements and hetmesh's count divided by it."""
    from rich import box
    from rich.table import Table

    from ..reproduce.paper import CASES
    from ..reproduce.report import num, paper_row, peer_verdicts

    table = Table(title=f"hetmesh reproduce ({'quick' if report.quick else 'full'}): elements "
                        "adaptive, uniform, best peer", title_justify="left",
                  box=box.SIMPLE_HEAD, pad_edge=False)
    for col in ("model", "δ0", "adaptive", "uniform", "ratio", "paper", "best peer",
                "÷ peer"):
        table.add_column(col, justify="left" if col == "model" else "right",
                         no_wrap=col == "model", min_width=len(col))
    for r in report.runs:
        if r.error:
            table.add_row(r.case, f"{r.threshold:g}", "error: " + r.error)
            continue
        case = CASES[r.case]
        pa, pu = paper_row(case, "adaptive", r.threshold), paper_row(case, "uniform", r.threshold)
        v = peer_verdicts(r)
        best = str(r.peers[v["best"]].stats.n_elements) if v else "-"
        table.add_row(r.case, f"{r.threshold:g}", str(r.adaptive.stats.n_elements),
                      str(r.uniform.stats.n_elements), num(r.ratio, 3),
                      num(pa.n_elements / pu.n_elements, 3) if pa and pu else "-", best,
                      num(v["ratio"], 3) if v else "-")
    return table
