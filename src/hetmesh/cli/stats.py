"""``hetmesh stats``: the statistics of a mesh file against a model.

Also home of the statistics table that ``mesh``, ``uniform`` and ``demo`` print.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable, Mapping
from pathlib import Path

from rich.table import Table

from .progress import result_console

__all__ = ["add_parser", "run", "stats_table", "STAT_ROWS", "with_dense_max", "with_bounds",
           "check_mesh_of_model"]

def _floor4(x: float) -> str:
    """Four significant digits, rounded down: a delta_max just below the threshold must not
    print as the threshold itself (0.0199996 -> 0.01999, not 0.0200)."""
    if not (x > 0 and math.isfinite(x)):
        return f"{x:.4g}"
    scale = 10.0 ** (3 - math.floor(math.log10(x)))
    return f"{math.floor(x * scale * (1 + 1e-12)) / scale:.4g}"  # 1e-12: 0.0449 * 1e5 < 4490


# (label, MeshStats field, formatter); the paper's Tables 1, 3, 5 plus the smallest angle and
# the delta_max of each sampling (delta_max is that of the sampling the mesh was made for;
# the certified bound where computed)
STAT_ROWS: tuple[tuple[str, str, Callable[[float], str]], ...] = (
    ("Np", "n_points", "{:d}".format),
    ("Ne", "n_elements", "{:d}".format),
    ("q_min", "q_min", "{:.4f}".format),
    ("q_avg", "q_avg", "{:.4f}".format),
    ("delta_min", "delta_min", "{:.4g}".format),
    ("delta_avg", "delta_avg", "{:.4g}".format),
    ("delta_max", "delta_max", _floor4),
    ("delta_max_vertices", "delta_max_vertices", _floor4),
    ("delta_max_dense", "delta_max_dense", _floor4),
    ("delta_max_certified", "delta_max_certified", _floor4),
    ("angle_min", "angle_min", "{:.2f}°".format),
)


def stats_table(columns: Mapping[str, object], *,
                times: Mapping[str, float] | None = None) -> Table:
    """A table with one row per statistic and one column per mesh.

    ``columns`` maps a column heading to a ``MeshStats`` (or its ``as_dict()``); ``times``
    optionally maps the same headings to seconds, shown as a last row.
    """
    table = Table()
    table.add_column("")
    for name in columns:
        table.add_column(name, justify="right")
    dicts = [c if isinstance(c, Mapping) else c.as_dict() for c in columns.values()]
    for label, key, fmt in STAT_ROWS:
        table.add_row(label, *(fmt(d[key]) if d.get(key) is not None else "-" for d in dicts))
    if times is not None:
        table.add_row("time", *(f"{times[name]:.2f} s" if name in times else "-"
                                for name in columns))
    return table


def add_parser(subparsers, parents: list[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    from ..options import SAMPLINGS

    p = subparsers.add_parser(
        "stats", parents=parents,
        help="statistics (Np, Ne, q, delta) of a mesh file",
        description="Read a mesh file, check that it is a mesh of the model's domain (finite "
                    "coordinates, boundary nodes on the domain's boundary, triangles inside "
                    "it, the same area), recompute the element quality q and the material "
                    "variation delta of every element from the model, and print Np, Ne, "
                    "q_min, q_avg, delta_min, delta_avg, delta_max (with --sampling), "
                    "delta_max_vertices, delta_max_dense (from a 15-point lattice in every "
                    "element), delta_max_certified (with --sampling certified: an upper "
                    "bound on every element's variation) and the smallest angle. A mesh "
                    "that is not of the model is an error (exit 2).",
    )
    p.add_argument("mesh", type=Path, metavar="MESH",
                   help="mesh file written by hetmesh (.vtu, .msh, ...)")
    p.add_argument("--model", "-m", type=Path, required=True, metavar="MODEL",
                   help="the model file (TOML) the mesh was made for")
    p.add_argument("--sampling", choices=SAMPLINGS, default="vertices",
                   help="delta from the vertex compositions (the paper's), from a dense "
                        "lattice in every element, or certified: an upper bound on the "
                        "variation inside every element (default: vertices)")
    p.add_argument("--threshold", "-d", type=float, metavar="D",
                   help="with --sampling certified: decide every element against delta_0 = D "
                        "(its bound is refined until it is below D or the samples reach D); "
                        "without it the bound is refined to within 1 %% + 1e-4 of the "
                        "sampled variation")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="print nothing; the exit status tells whether the mesh is of the "
                        "model (0) or not (2)")
    p.set_defaults(run=run)
    return p


def with_dense_max(stats, mesh, model):
    """``stats`` with ``delta_max_dense`` filled in if missing: the order-4 lattice of every
    element (:func:`hetmesh.metrics.delta_dense`), each element of a feature-tree model in
    its own subregion, as the mesher evaluates it."""
    return with_bounds(stats, mesh, model, None)


def with_bounds(stats, mesh, model, sampling: str | None):
    """``stats`` with ``delta_max_dense`` and ``delta_max_vertices`` filled in if missing,
    and ``delta_max_certified`` (``delta_max`` itself) when ``sampling`` is "certified".
    Each element of a piecewise model is evaluated in its own subregion, as the mesher
    does."""
    import dataclasses

    from ..delta import element_delta
    from ..material.field import element_subregions, has_subregions
    from ..metrics import delta_dense

    fld = model.material
    regions = None
    if stats.delta_max_dense is None or stats.delta_max_vertices is None:
        regions = (element_subregions(fld, mesh.points, mesh.triangles)
                   if has_subregions(fld) else None)
    changes = {}
    if stats.delta_max_dense is None:
        dense = delta_dense(fld, mesh.points, mesh.triangles, regions=regions)
        changes["delta_max_dense"] = float(dense.max())
    if stats.delta_max_vertices is None:
        vert = element_delta(fld, mesh.points, mesh.triangles, "vertices", regions=regions)
        changes["delta_max_vertices"] = float(vert.max())
    if sampling == "certified" and stats.delta_max_certified is None:
        changes["delta_max_certified"] = stats.delta_max
    return dataclasses.replace(stats, **changes)


def check_mesh_of_model(mesh, model, mesh_path, *, geometry: bool = True) -> None:
    """Raise :class:`~hetmesh.errors.MeshDataError` (exit 2) unless ``mesh`` can be a mesh of
    ``model``'s domain (:func:`hetmesh.tri.verify.mesh_model_problems`; ``geometry=False``:
    only that its nodes are finite)."""
    from ..errors import MeshDataError
    from ..tri.verify import mesh_model_problems

    problems = mesh_model_problems(mesh.points, mesh.triangles, model.domain,
                                   geometry=geometry)
    if problems:
        raise MeshDataError(f"{mesh_path}: not a mesh of model {model.name!r}: {problems[0]}")


def _statistics(mesh, model, sampling: str, threshold: float | None):
    """:func:`hetmesh.mesh_statistics`, with ``threshold`` for certified sampling."""
    from ..delta import element_delta
    from ..material.field import element_subregions, has_subregions
    from ..metrics import statistics

    fld = model.material
    regions = (element_subregions(fld, mesh.points, mesh.triangles) if has_subregions(fld)
               else None)
    delta = element_delta(fld, mesh.points, mesh.triangles, sampling, regions=regions,
                          threshold=threshold)
    return statistics(mesh.points, mesh.triangles, delta)


def run(args: argparse.Namespace) -> int:
    from ..io.model import load_model
    from ..io.read import read_mesh
    from .examples import check_model_path

    check_model_path(args.model)
    model = load_model(args.model)
    if getattr(model, "dim", 2) == 3:  # a solid: tetrahedral statistics (hetmesh.tet)
        from ..tet.cli import run_tet_stats
        return run_tet_stats(args, model)
    from ..options import check_sampling

    check_sampling(model.material, args.sampling, names={"sampling": "--sampling"})
    mesh = read_mesh(args.mesh)
    check_mesh_of_model(mesh, model, args.mesh)
    if args.threshold is not None:
        from ..options import check_options

        check_options(args.threshold, names={"threshold": "--threshold"})
    stats = with_bounds(_statistics(mesh, model, args.sampling, args.threshold), mesh, model,
                        args.sampling)
    if args.quiet:
        return 0
    if args.json:
        print(json.dumps({"mesh": str(args.mesh), "model": str(args.model),
                          "sampling": args.sampling, **stats.as_dict()}, indent=2))
    else:
        console = result_console()
        console.print(f"{args.mesh}: model {model.name}, delta from the {args.sampling}")
        console.print(stats_table({args.mesh.name: stats}))
    return 0
