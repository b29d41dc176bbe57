"""``hetmesh mesh``: the adaptive, material-aware mesh of a model file.

Also holds what ``uniform`` and ``demo`` share with it: the meshing options, their validation
(done before any meshing), the output checks, and writing the results (mesh, plot, stats JSON).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import OutputError
from ..io.export import FILE_FORMATS
from ..io.jsondoc import jsonable
from ..options import SAMPLINGS, check_options, check_sampling
from .progress import progress_reporter, result_console

__all__ = [
    "add_parser", "run", "add_meshing_options", "meshing_kwargs", "check_threshold",
    "check_outputs", "check_output_paths", "check_writable_dir", "write_outputs",
    "run_pipeline",
]


# -- parser ------------------------------------------------------------------

def _count(text: str) -> int:
    """An element count: ``20000``, ``20_000`` or ``2e4``."""
    try:
        return int(text)
    except ValueError:
        value = float(text)  # ValueError -> argparse reports "invalid count value"
        if not value.is_integer():
            raise
        return int(value)


_count.__name__ = "count"



def add_meshing_options(p: argparse.ArgumentParser, *, adaptive: bool) -> None:
    """The options of ``mesh`` (``adaptive=True``) and ``uniform``."""
    p.add_argument("model", type=Path, metavar="MODEL", help="model file (TOML)")
    p.add_argument("--threshold", "-d", type=float, required=True, metavar="D",
                   help="largest material variation delta_0 allowed in an element, 0 < D < 1; "
                        "every element of the result has delta < D")
    p.add_argument("--output", "-o", type=Path, required=True, metavar="OUT",
                   help="mesh file to write; the format follows the extension: .vtu, .vtk, "
                        ".msh (Gmsh 4.1), .xdmf, .inp (Abaqus), .mesh (Medit: geometry, "
                        "regions and edge markers only, no compositions)")
    p.add_argument("--format", choices=sorted(FILE_FORMATS), default=None, metavar="FMT",
                   help="write this format whatever the extension, e.g. gmsh22 for Gmsh 2.2 "
                        f"(one of: {', '.join(sorted(FILE_FORMATS))})")
    p.add_argument("--min-angle", type=float, metavar="A",
                   help="smallest angle (degrees) the quality refinement aims for, "
                        "0 < A <= 34 (default: 30)")
    if adaptive:
        p.add_argument("--max-size", type=float, metavar="H",
                       help="the longest edge allowed, > 0, in model units; longer edges are "
                            "split and the result is verified (default: no bound; the coarsest "
                            "elements are about the domain diameter / 8)")
    p.add_argument("--max-elements", type=_count, metavar="N",
                   help="element budget; meshing stops with an error rather than exceed it "
                        "(default: 5000000)")
    p.add_argument("--sampling", choices=SAMPLINGS,
                   help="where delta(T) < D is guaranteed: at the vertices (the paper's "
                        "definition), also on a 15-point lattice in every element, which "
                        "sees most composition peaks between vertices, or 'certified': "
                        "everywhere inside every element, proven by interval arithmetic on "
                        "the formulas and feature trees (dense sampling, "
                        "with a warning, for other materials), or 'pixels' (image "
                        "materials): also at every pixel centre in every element "
                        "(default: vertices); the "
                        "statistics show the lattice's delta_max_dense either way")
    p.add_argument("--chord-tol", type=float, metavar="C",
                   help="largest distance between a curved boundary or interface and any of "
                        "its mesh edges (chords), relative to the domain diameter, "
                        "1e-7 <= C <= 0.05; verified chord by chord (default: 0.001)")
    if adaptive:
        p.add_argument("--method", choices=("auto", "layers", "springs", "cvt"),
                       help="point placement: nodes on iso-composition layers, nodes "
                            "relaxed as a truss of springs (nearly equilateral elements), "
                            "the paper's density-weighted CVT, or auto: layers, and on small "
                            "models (estimate up to 50,000 elements) springs too, keeping "
                            "the better mesh (default: auto)")
        p.add_argument("--row-spacing", type=float, metavar="R",
                       help="step in composition between the rows of nodes of the layers "
                            "placement, as a fraction of the threshold, 0.3 <= R <= 0.99: "
                            "lower gives more elements of better shape, 0.985 the fewest "
                            "(default: 0.85)")
        p.add_argument("--gradation", type=float, metavar="G",
                       help="how fast the element size may grow per unit length, 0 <= G <= "
                            "10, as Gmsh's and MMG's size gradation: lower grades more "
                            "smoothly from small elements to large ones; 0 does not grade "
                            "(default: 0.3)")
        p.add_argument("--seed", type=int, metavar="S",
                       help="random seed, >= 0; same input and seed give the same mesh "
                            "(default: 0)")
    p.add_argument("--plot", type=Path, metavar="PNG",
                   help="also write a picture of the mesh coloured by composition "
                        "(.png, .pdf, .svg)")
    p.add_argument("--stats", type=Path, metavar="JSON",
                   help="also write the statistics, history, timings and options as JSON")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress bar and no summary; only errors and warnings")


def add_parser(subparsers, parents: list[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "mesh", parents=parents,
        help="adaptive material-aware mesh of a model",
        description="Mesh a model adaptively: as few elements as possible such that the "
                    "material variation delta of every element is below the threshold, with "
                    "good element quality. The mesh is written only once it is verified.",
    )
    add_meshing_options(p, adaptive=True)
    p.set_defaults(run=run)
    return p


# -- validation (before any meshing) ----------------------------------------

#: how the CLI names the options in error messages
FLAGS = {"threshold": "--threshold", "min_angle": "--min-angle", "max_elements": "--max-elements",
         "max_size": "--max-size", "sampling": "--sampling", "seed": "--seed",
         "chord_tol": "--chord-tol", "row_spacing": "--row-spacing", "gradation": "--gradation"}


def check_threshold(value: float) -> None:
    check_options(value, names=FLAGS)


def meshing_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The keyword arguments of ``generate``/``uniform`` the user gave, validated by the
    library's own rules (:func:`hetmesh.options.check_options`) under the CLI's flag names.

    Options not given are left out, so the library's defaults apply.
    """
    kw: dict[str, Any] = {}
    for key in ("min_angle", "max_size", "max_elements", "sampling", "method", "seed",
                "chord_tol", "row_spacing", "gradation"):
        value = getattr(args, key, None)
        if value is not None:
            kw[key] = value
    check_options(args.threshold, names=FLAGS, **{k: v for k, v in kw.items() if k != "method"})
    return kw


def check_writable_dir(directory: Path, label: str) -> None:
    """Raise :class:`OutputError` unless files can be created in ``directory``.

    Tries to create (and removes) a temporary file: permission bits alone do not tell (root,
    ACLs, read-only mounts).
    """
    if not directory.exists():
        raise OutputError(f"{label}: directory {directory} does not exist")
    if not directory.is_dir():
        raise OutputError(f"{label}: {directory} is not a directory")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".hetmesh-check-", dir=directory)
    except OSError as exc:
        raise OutputError(f"{label}: directory {directory} is not writable "
                          f"({exc.strerror})") from None
    os.close(fd)
    os.unlink(tmp)


def _check_output_path(path: Path, label: str, extensions: list[str] | None, kind: str) -> None:
    if extensions is not None:
        ext = path.suffix.lower()
        if ext not in extensions:
            raise OutputError(f"{label} {path}: unknown {kind} format {ext or '(no extension)'!r} "
                              f"(known: {', '.join(extensions)})")
    if path.is_dir():
        raise OutputError(f"{label} {path} is a directory")
    check_writable_dir(path.parent, f"{label} {path}")


def mesh_extensions() -> list[str]:
    from ..io.export import FORMATS

    return sorted(FORMATS)


def plot_extensions() -> list[str]:
    from matplotlib.backend_bases import FigureCanvasBase

    return sorted("." + e for e in FigureCanvasBase.get_supported_filetypes())


def check_output_paths(outputs: list, inputs: dict[Path, str]) -> None:
    """``outputs`` as ``(option, path, known extensions or None, kind)``: known formats,
    writable directories, distinct files, and none of them one of ``inputs`` ({path:
    label})."""
    seen = {p.resolve(): label for p, label in inputs.items()}
    for label, path, extensions, kind in outputs:
        _check_output_path(path, label, extensions, kind)
        key = path.resolve()
        if key in seen:
            raise OutputError(f"{label} {path} is the same file as {seen[key]}")
        seen[key] = label


def check_outputs(args: argparse.Namespace, inputs: list[Path]) -> None:
    """Check ``--output``, ``--plot``, ``--stats``: known formats, writable, distinct, and none
    of them overwrites an input file."""
    outputs = [("--output", args.output, mesh_extensions(), "mesh")]
    if args.plot is not None:
        outputs.append(("--plot", args.plot, plot_extensions(), "image"))
    if args.stats is not None:
        outputs.append(("--stats", args.stats, None, ""))
    check_output_paths(outputs, {p: "MODEL" for p in inputs})


# -- running -------------------------------------------------------------------

def run_pipeline(func: Callable, model, threshold: float, kwargs: dict[str, Any], *,
                 quiet: bool, label: str):
    """Call ``generate``/``uniform`` with a progress bar; returns ``(result, seconds)``."""
    with progress_reporter(quiet=quiet, label=label) as progress:
        t0 = time.perf_counter()
        result = func(model, threshold, progress=progress, **kwargs)
        return result, time.perf_counter() - t0


def stats_document(args: argparse.Namespace, model, result, seconds: float) -> dict[str, Any]:
    """The ``--stats`` JSON: everything needed to reproduce and judge the run."""
    from ..version import __version__

    return jsonable({
        "hetmesh_version": __version__,
        "command": args.command,
        "model": {"name": model.name, "file": str(args.model)},
        "threshold": args.threshold,
        "output": str(args.output),
        "stats": result.stats.as_dict(),
        "history": list(result.history),
        "timings": {**dict(result.timings), "wall": seconds},
        "options": result.options,
    })


def write_outputs(args: argparse.Namespace, model, result, seconds: float) -> list[Path]:
    """Write the mesh, then the optional plot and stats JSON (all atomically)."""
    from ..io.export import write_mesh

    written = [write_mesh(result.mesh, args.output, file_format=args.format)]
    if args.plot is not None:
        from ..plot import interface_markers, plot_mesh

        meshed = result.model if result.model is not None else model  # with discontinuities
        kind = "adaptive" if args.command == "mesh" else args.command
        plot_mesh(result.mesh, args.plot, interface_markers=interface_markers(meshed),
                  units=getattr(model, "units", ""),
                  constituents=model.material.constituents,
                  title=f"{model.name}: {kind} mesh, {result.mesh.n_elements} elements, "
                        f"$\\delta_0$ = {args.threshold:g}")
        written.append(args.plot)
    if args.stats is not None:
        from ..io.atomic import atomic_write

        with atomic_write(args.stats) as fh:
            json.dump(stats_document(args, model, result, seconds), fh, indent=2)
            fh.write("\n")
        written.append(args.stats)
    return written


def print_summary(model, result, seconds: float, written: list[Path], threshold: float) -> None:
    from .stats import stats_table

    console = result_console()
    console.print(f"{model.name}, delta_0 = {threshold:g}")
    console.print(stats_table({model.name: result.stats}, times={model.name: seconds}))
    for path in written:
        console.print(f"wrote {path}")


def run_meshing(args: argparse.Namespace, load_pipeline: Callable[[], Callable]) -> int:
    """``mesh`` and ``uniform``: validate, load, mesh, write, summarise.

    ``load_pipeline()`` imports and returns ``generate`` or ``uniform`` (after validation).
    """
    kwargs = meshing_kwargs(args)
    check_outputs(args, [args.model])
    from ..io.model import load_model
    from .examples import check_model_path

    check_model_path(args.model)
    func = load_pipeline()
    model = load_model(args.model)
    if getattr(model, "dim", 2) == 3:  # a solid: the tetrahedral mesher (hetmesh.tet)
        from ..tet.cli import run_tet
        return run_tet(args, model, kwargs)
    check_sampling(model.material, kwargs.get("sampling", "vertices"), names=FLAGS)
    result, seconds = run_pipeline(func, model, args.threshold, kwargs, quiet=args.quiet,
                                   label=model.name)
    from .stats import with_bounds

    result.stats = with_bounds(result.stats, result.mesh, model,
                               result.options.get("sampling"))
    written = write_outputs(args, model, result, seconds)
    if not args.quiet:
        print_summary(model, result, seconds, written, args.threshold)
    return 0


def _generate() -> Callable:
    from ..tri.pipeline import generate

    return generate


def run(args: argparse.Namespace) -> int:
    return run_meshing(args, _generate)
