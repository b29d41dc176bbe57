"""``hetmesh fea``: thermo-mechanical analysis of a mesh against its model (paper Sec. 4.4).

Steady conduction, then linear thermoelasticity, with the ``[fea]`` table of the model file;
prints the probe values and writes the mesh with its results, a JSON report and a von Mises
plot. Every output is checked before the analysis and written atomically after it, so a
failed run writes nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from rich.table import Table

from ..fea.adapt import DEFAULT_FRACTION, DEFAULT_STEPS, EDGES, INDICATORS
from .mesh import check_output_paths, mesh_extensions, plot_extensions
from .progress import result_console
from .stats import check_mesh_of_model

__all__ = ["add_parser", "run", "probe_table"]


def add_parser(subparsers, parents: list[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "fea", parents=parents,
        help="thermo-mechanical FEA (conduction + thermoelasticity) on a mesh",
        description="Solve steady heat conduction, then linear thermoelasticity (plane strain "
                    "or plane stress; 3-D on a tetrahedral mesh), on a mesh of a model whose "
                    "file has an [fea] table "
                    "(constituent properties, fixed temperatures, displacement conditions, "
                    "probes; see docs/model-format.md). Properties are mixed from the "
                    "composition at the quadrature points. Prints the probe values; "
                    "stresses in Pa, temperatures in K.",
        epilog="Example: hetmesh fea examples/fgm_plate.toml --mesh plate.vtu "
               "--output plate_fea.vtu --report fea.json --plot von_mises.png",
    )
    p.add_argument("model", type=Path, metavar="MODEL",
                   help="model file (TOML) with an [fea] table")
    p.add_argument("--mesh", "-m", type=Path, required=True, metavar="MESH",
                   help="the mesh to analyse (.vtu, .msh, .xdmf, .inp, .vtk, .mesh), in the "
                        "model's coordinates")
    p.add_argument("--output", "-o", type=Path, metavar="OUT",
                   help="write the mesh with the results as point and cell data (temperature, "
                        "displacement, stress_xx/yy/xy/zz, von_mises); format from the extension")
    p.add_argument("--report", type=Path, metavar="JSON",
                   help="write a JSON report: settings, extremes, timings, one entry per probe")
    p.add_argument("--plot", type=Path, metavar="PNG",
                   help="write a picture of the von Mises stress (.png, .pdf, .svg)")
    a = p.add_argument_group(
        "solution-adaptive refinement (tetrahedral meshes)",
        "Solve, estimate every element's error by Zienkiewicz-Zhu stress recovery (or, with "
        "--adapt-indicator goal, its share of the probes' error), refine the elements "
        "carrying FRACTION of it (Doerfler marking) by longest-edge bisection (or the "
        "--adapt-edges stress rule), "
        "re-verify (delta_max < delta_0, faces on the solid), repeat; --output gets the last "
        "mesh with its results and the cell data error_indicator (docs/fea.md).")
    a.add_argument("--adapt", type=float, metavar="TOL",
                   help="refine until the relative error estimate (energy norm; at the "
                        "probes with --adapt-indicator goal) is <= TOL, e.g. 0.005")
    a.add_argument("--threshold", "-d", type=float, metavar="D",
                   help="with --adapt: delta_0 of the mesh, which every refined mesh keeps")
    a.add_argument("--adapt-steps", type=int, metavar="N",
                   help=f"with --adapt: at most N refinements (default {DEFAULT_STEPS})")
    a.add_argument("--adapt-fraction", type=float, metavar="F",
                   help=f"with --adapt: Doerfler's bulk fraction, 0 < F <= 1 (default "
                        f"{DEFAULT_FRACTION})")
    a.add_argument("--adapt-max-elements", type=int, metavar="N",
                   help="with --adapt: stop before a mesh of more than N tetrahedra")
    a.add_argument("--adapt-indicator", choices=INDICATORS, metavar="KIND",
                   help="with --adapt: what the marks and the stop follow: 'energy' (ZZ's "
                        "energy-norm error, the default) or 'goal' (the von Mises error at "
                        "the probes, dual-weighted; one more solve per step)")
    a.add_argument("--adapt-edges", choices=EDGES, metavar="RULE",
                   help="with --adapt: the edge a marked tetrahedron is bisected at: "
                        "'longest' (the default) or 'stress' (edges along directions in which "
                        "the recovered stress hardly varies count shorter: no splits along a "
                        "plane-strain part's axis)")
    a.add_argument("--adapt-probes", metavar="NAMES",
                   help="with --adapt-indicator goal: the probes to aim at, comma-separated "
                        "(default all of the [fea] table's)")
    p.add_argument("--quiet", "-q", action="store_true", help="print nothing but errors")
    p.set_defaults(run=run)
    return p


def check_fea_outputs(args: argparse.Namespace) -> None:
    """Known formats, writable directories, distinct files, none of them an input."""
    outputs = []
    if args.output is not None:
        outputs.append(("--output", args.output, mesh_extensions(), "mesh"))
    if args.report is not None:
        outputs.append(("--report", args.report, None, ""))
    if args.plot is not None:
        outputs.append(("--plot", args.plot, plot_extensions(), "image"))
    check_output_paths(outputs, {args.model: "MODEL", args.mesh: "--mesh"})


def check_adapt_args(args: argparse.Namespace) -> None:
    """The refinement options: only with ``--adapt``, which needs ``--threshold``; values by
    :func:`hetmesh.fea.adapt.check_adapt_options`."""
    from ..errors import OptionError
    from ..fea.adapt import check_adapt_options

    extra = [f for f, v in (("--threshold", args.threshold), ("--adapt-steps", args.adapt_steps),
                            ("--adapt-fraction", args.adapt_fraction),
                            ("--adapt-max-elements", args.adapt_max_elements),
                            ("--adapt-indicator", args.adapt_indicator),
                            ("--adapt-edges", args.adapt_edges),
                            ("--adapt-probes", args.adapt_probes)) if v is not None]
    if args.adapt is None:
        if extra:
            raise OptionError(f"{extra[0]} is an option of --adapt, which is not given")
        return
    if args.threshold is None:
        raise OptionError("--adapt needs --threshold D: the delta_0 every refined mesh keeps")
    if args.adapt_probes is not None:
        if args.adapt_indicator != "goal":
            raise OptionError("--adapt-probes is an option of --adapt-indicator goal, which is "
                              "not given")
        names = adapt_probe_names(args.adapt_probes)
        if not names:
            raise OptionError(f"--adapt-probes: expected probe names separated by commas, got "
                              f"{args.adapt_probes!r}")
    check_adapt_options(args.adapt, DEFAULT_STEPS if args.adapt_steps is None
                        else args.adapt_steps,
                        DEFAULT_FRACTION if args.adapt_fraction is None else args.adapt_fraction,
                        args.adapt_max_elements, args.threshold)


def adapt_probe_names(text: str) -> list[str]:
    """The probe names of ``--adapt-probes``: comma-separated, blanks around them ignored."""
    return [n.strip() for n in text.split(",") if n.strip()]


def probe_table(result) -> Table:
    """One row per probe: position, temperature, stresses and von Mises (MPa); the six
    stresses and z for a 3-D result."""
    three = getattr(result.config, "dim", 2) == 3
    coords = ("x", "y", "z") if three else ("x", "y")
    stresses = (("stress_xx", "stress_yy", "stress_zz", "stress_xy", "stress_yz", "stress_xz")
                if three else ("stress_xx", "stress_yy", "stress_xy", "stress_zz"))
    table = Table()
    for head in ("probe", *coords, "T (K)", *(f"s_{k[-2:]}" for k in stresses),
                 "von Mises (MPa)"):
        table.add_column(head, justify="left" if head == "probe" else "right")
    for name, p in result.probes.items():
        table.add_row(name, *(f"{p[c]:.6g}" for c in coords), f"{p['temperature']:.2f}",
                      *(f"{p[k] / 1e6:.2f}" for k in (*stresses, "von_mises")))
    return table


def run(args: argparse.Namespace) -> int:
    from ..errors import FEAError
    from ..fea import plot_von_mises, solve, write_report
    from ..io.export import write_mesh
    from ..io.model import load_model
    from ..io.read import read_mesh
    from .examples import check_model_path

    check_fea_outputs(args)
    check_adapt_args(args)
    check_model_path(args.model)
    model = load_model(args.model)
    if getattr(model, "fea", None) is None:
        raise FEAError(f"{args.model}: no [fea] table (constituent properties, boundary "
                       f"conditions); see docs/model-format.md")
    mesh = read_mesh(args.mesh)
    if getattr(model, "dim", 2) != mesh.dim:
        from ..errors import MeshDataError

        raise MeshDataError(f"{args.mesh}: a {mesh.dim}-D mesh, but model {model.name!r} is "
                            f"{getattr(model, 'dim', 2)}-D")
    if mesh.dim == 2:
        check_mesh_of_model(mesh, model, args.mesh, geometry=False)  # finite nodes
    elif not np.isfinite(mesh.points).all():
        from ..errors import MeshDataError

        raise MeshDataError(f"{args.mesh}: not a mesh of model {model.name!r}: non-finite "
                            f"node coordinates")
    adapted = None
    if args.adapt is not None:
        from ..errors import OptionError

        if mesh.dim != 3:
            raise OptionError(f"--adapt: solution-adaptive refinement needs a tetrahedral "
                              f"mesh; {args.mesh} is {mesh.dim}-D")
        from ..fea.adapt import adapt

        adapted = adapt(mesh, model, args.threshold, tolerance=args.adapt,
                        steps=DEFAULT_STEPS if args.adapt_steps is None else args.adapt_steps,
                        fraction=(DEFAULT_FRACTION if args.adapt_fraction is None
                                  else args.adapt_fraction),
                        max_elements=args.adapt_max_elements,
                        indicator=args.adapt_indicator or "energy",
                        edges=args.adapt_edges or "longest",
                        goal_probes=(None if args.adapt_probes is None
                                     else adapt_probe_names(args.adapt_probes)))
        result, mesh = adapted.result, adapted.mesh
    else:
        result = solve(mesh, model)
    written = []
    if args.output is not None:
        written.append(write_mesh(result.mesh, args.output))
    if args.report is not None:
        written.append(write_report(result, args.report, model_file=str(args.model),
                                    mesh_file=str(args.mesh),
                                    **({} if adapted is None else
                                       {"adaptive": adapted.report()})))
    if args.plot is not None:
        written.append(plot_von_mises(result, args.plot, units=model.units))
    if not args.quiet:
        console = result_console()
        T = result.temperature
        kind = (f"3-D, P{result.config.order}" if mesh.dim == 3
                else f"plane {result.config.plane}")
        console.print(f"{model.name}: {mesh.n_elements} elements, {kind}, "
                      f"{result.config.mixing} mixing; T in [{T.min():.2f}, {T.max():.2f}] K, "
                      f"max von Mises {result.von_mises.max() / 1e6:.2f} MPa "
                      f"({result.timings['total']:.2f} s)")
        if adapted is not None:
            for st in adapted.steps:
                console.print(f"  step {st['step']}: {st['elements']} tetrahedra, error "
                              f"estimate {100 * st['estimate']:.3g} %, delta_max "
                              f"{st['delta_max']:.4g}")
            console.print(f"adaptive refinement stopped: {adapted.reason}")
        if result.probes:
            console.print(probe_table(result))
        for path in written:
            console.print(f"wrote {path}")
    return 0
