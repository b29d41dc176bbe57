"""``hetmesh demo``: the packaged power-plate example (the paper's Fig. 3, Table 1), adaptive
against uniform, with files to look at."""

from __future__ import annotations

import argparse
from importlib import resources
from pathlib import Path

from ..io.atomic import output_dir
from .mesh import check_threshold, check_writable_dir, run_pipeline
from .progress import result_console

__all__ = ["add_parser", "run", "EXAMPLE"]

EXAMPLE = "power_plate"


def add_parser(subparsers, parents: list[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "demo", parents=parents,
        help="mesh the packaged power-plate example, adaptive against uniform",
        description=f"Mesh the packaged example {EXAMPLE}.toml (a functionally graded plate, "
                    "the paper's Fig. 3) adaptively and uniformly, write both meshes, a "
                    "picture of the adaptive mesh and a histogram of delta, and print the "
                    "statistics side by side.",
    )
    p.add_argument("--out", type=Path, default=Path("hetmesh-demo"), metavar="DIR",
                   help="directory for the files, created if missing (default: ./hetmesh-demo)")
    p.add_argument("--threshold", "-d", type=float, default=None, metavar="D",
                   help="delta_0, 0 < D < 1 (default: 0.05; 0.1 with --volume)")
    p.add_argument("--image", action="store_true",
                   help="mesh a synthetic 16-bit TIFF with 2%% noise instead (written into DIR "
                        "with its model file; docs/model-format.md, images)")
    p.add_argument("--labels", action="store_true",
                   help="mesh a synthetic two-phase label image instead (a graded phase "
                        "around a constant one; the phase boundary is embedded, so no element "
                        "straddles it; written into DIR with its model file)")
    p.add_argument("--volume", action="store_true",
                   help="mesh a synthetic 3D volume (a 16-bit TIFF stack with 2%% noise, "
                        "written into DIR with its model file) with tetrahedra instead")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress bar and no table; errors only")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    if args.threshold is None:
        args.threshold = 0.1 if args.volume else 0.05
    check_threshold(args.threshold)
    chosen = [f for f in ("--image", "--labels", "--volume")
              if getattr(args, f[2:].replace("-", "_"))]
    if len(chosen) > 1:
        from ..errors import OptionError

        raise OptionError(f"{chosen[0]} and {chosen[1]}: choose one demo")
    out: Path = output_dir(args.out)
    check_writable_dir(out, f"--out {out}")

    from ..io.export import write_mesh
    from ..io.model import load_model
    from ..plot import interface_markers, plot_delta_histogram, plot_mesh
    from ..tri.pipeline import generate
    from ..tri.uniform import uniform

    if args.volume:
        return _volume(args, out)
    if args.image or args.labels:
        from ..material.image import write_examples

        model = load_model(write_examples(out)["graded_part_noisy" if args.image
                                               else "two_phase"])
    else:
        with resources.as_file(resources.files("hetmesh") / "examples" / f"{EXAMPLE}.toml") \
                as path:
            model = load_model(path)
    name = model.name
    D = args.threshold
    adaptive, t_adaptive = run_pipeline(generate, model, D, {}, quiet=args.quiet, label="adaptive")
    uni, t_uniform = run_pipeline(uniform, model, D, {}, quiet=args.quiet, label="uniform")

    files = {
        "adaptive mesh": write_mesh(adaptive.mesh, out / f"{name}.vtu"),
        "uniform mesh": write_mesh(uni.mesh, out / f"{name}_uniform.vtu"),
        "mesh picture": plot_mesh(adaptive.mesh, out / f"{name}.png",
                                  interface_markers=interface_markers(model),
                                  units=model.units,
                                  constituents=model.material.constituents,
                                  title=f"{model.name}: adaptive mesh, "
                                        f"{adaptive.mesh.n_elements} elements, "
                                        f"$\\delta_0$ = {D:g}"),
        "delta histogram": plot_delta_histogram(
            {"adaptive": adaptive.mesh, "uniform": uni.mesh}, out / f"{name}_delta.png",
            threshold=D, title=f"{model.name}: material variation $\\delta(T)$ of the elements"),
    }
    if not args.quiet:
        from .stats import stats_table, with_bounds

        adaptive.stats = with_bounds(adaptive.stats, adaptive.mesh, model, None)
        uni.stats = with_bounds(uni.stats, uni.mesh, model, None)

        console = result_console()
        console.print(f"{model.name}, delta_0 = {D:g}")
        console.print(stats_table({"adaptive": adaptive.stats, "uniform": uni.stats},
                                  times={"adaptive": t_adaptive, "uniform": t_uniform}))
        na, nu = adaptive.stats.n_elements, uni.stats.n_elements
        console.print(f"elements, adaptive / uniform: {na} / {nu} = {na / nu:.3f}")
        for what, path in files.items():
            console.print(f"wrote {path}  ({what})")
    return 0


def _volume(args: argparse.Namespace, out: Path) -> int:
    """``demo --volume``: the graded cube from a TIFF stack, meshed with tetrahedra."""
    import time

    from ..io.export import write_mesh
    from ..io.model import load_model
    from ..material.image import write_examples
    from ..tet.api import mesh_model
    from ..tet.cli import plot_tets, tet_statistics

    model = load_model(write_examples(out)["graded_volume"])
    t0 = time.perf_counter()
    res = mesh_model(model, args.threshold)
    seconds = time.perf_counter() - t0
    name, D = model.name, args.threshold
    files = {"tetrahedral mesh": write_mesh(res.mesh, out / f"{name}.vtu")}
    files["mesh picture"] = out / f"{name}.png"
    plot_tets(model, res, files["mesh picture"],
              f"{name}: {len(res.tets)} tetrahedra, delta_0 = {D:g}")
    if not args.quiet:
        st = tet_statistics(model, res)
        console = result_console()
        console.print(f"{name} (a {' x '.join(map(str, model.material.shape[::-1]))} voxel "
                      f"TIFF stack), delta_0 = {D:g}")
        console.print(f"  {st['n_elements']} tetrahedra, {st['n_points']} points "
                      f"({st['ratio_n_iso3']:.3f} x N_iso3), delta_max "
                      f"{st['delta_max']:.6g}, dihedral min {st['dihedral_min']:.1f} deg, "
                      f"{seconds:.2f} s")
        for what, path in files.items():
            console.print(f"wrote {path}  ({what})")
    return 0
