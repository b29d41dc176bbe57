"""``hetmesh export``: a mesh of a model as a solver's input, graded material included.

``--to calculix|abaqus`` writes a complete, runnable deck (mesh, material bins, the
``[fea]`` analysis when the model has boundary conditions); ``fenics`` the dolfinx XDMF
with the element properties; ``comsol`` NASTRAN bulk data and a composition table. See
docs/export.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .progress import result_console

__all__ = ["add_parser", "run"]


def _width(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"expected a composition width in (0, 1], got {text}")
    return value


def add_parser(subparsers, parents: list[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    from ..io.deck import TARGETS

    p = subparsers.add_parser(
        "export", parents=parents,
        help="write a mesh as a solver's input with the graded material (CalculiX, Abaqus, "
             "FEniCS, COMSOL)",
        description="Write a mesh of a model for a solver, with every element's material "
                    "properties mixed from its mean composition by the model's [fea] "
                    "properties and mixing rule. calculix/abaqus: one .inp deck in SI units "
                    "with element sets binned by composition (one *MATERIAL each) and, if "
                    "the model has [fea] boundary conditions, the heat step then the "
                    "thermoelastic step; fenics: dolfinx XDMF (+ .h5) with cell tags, facet "
                    "tags and the properties as cell data; comsol: NASTRAN bulk data and an "
                    "interpolation table of the composition. See docs/export.md.",
        epilog="Example: hetmesh export examples/fgm_plate.toml --mesh plate.vtu --to "
               "calculix --output deck/ && (cd deck && ccx -i fgm_plate)",
    )
    p.add_argument("model", type=Path, metavar="MODEL",
                   help="model file (TOML) with an [fea] table")
    p.add_argument("--mesh", "-m", type=Path, required=True, metavar="MESH",
                   help="the mesh (.vtu, .msh, .xdmf, .inp, .vtk, .mesh), in the model's "
                        "coordinates")
    p.add_argument("--to", required=True, choices=TARGETS, help="the solver")
    p.add_argument("--output", "-o", type=Path, required=True, metavar="DIR",
                   help="directory for the files (created if missing)")
    p.add_argument("--bin-width", type=_width, metavar="W",
                   help="composition width of the material bins (calculix, abaqus); default "
                        "the mesh's largest element delta, below the delta_0 it was made for")
    p.add_argument("--distribution", action="store_true",
                   help="abaqus: every element's own Young's modulus and Poisson ratio "
                        "through *DISTRIBUTION (Abaqus/Standard), the bins keeping the "
                        "expansion and conductivity")
    p.add_argument("--quiet", "-q", action="store_true", help="print nothing but errors")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    from ..errors import OutputError
    from ..io.deck import write_deck
    from ..io.model import load_model
    from ..io.read import read_mesh

    if args.output.exists() and not args.output.is_dir():
        raise OutputError(f"--output {args.output} is a file, not a directory")
    model = load_model(args.model)
    mesh = read_mesh(args.mesh)
    report = write_deck(mesh, model, args.output, args.to, bin_width=args.bin_width,
                        distribution=args.distribution)
    if not args.quiet:
        console = result_console()
        what = "analysis deck" if report.analysis else "mesh and material"
        line = f"{model.name}: {mesh.n_elements} elements, {args.to} {what}"
        if report.bins:
            line += (f"; {report.bins} material bins of width {report.bin_width:.4g}, largest "
                     f"property change from binning {100 * report.max_property_error:.3g} %")
            if report.distribution:
                line += "; E and nu element by element (*DISTRIBUTION)"
        console.print(line)
        for path in report.files:
            console.print(f"wrote {path}")
    return 0
