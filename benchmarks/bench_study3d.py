"""The 3-D study: adaptive against uniform tetrahedra on fgm_plate_3d and graded_cylinder.

    PYTHONPATH=src python benchmarks/bench_study3d.py [--quick] [--no-peers] [--no-study]
        [--cases fgm_plate_3d,graded_cylinder] [--json out.json]
    PYTHONPATH=src python benchmarks/bench_study3d.py --examples 0.1 [--skip fgm_plate_3d]
    PYTHONPATH=src python benchmarks/bench_study3d.py --no-meshes --cases fgm_plate_3d
        --uniform 240000 --thresholds none        # one more point of a study's family

Runs :func:`hetmesh.reproduce.study3d.run3d` -- the same code as ``hetmesh reproduce --3d``
-- and prints its tables:

- T1: per solid and threshold, the adaptive mesh (``hetmesh.generate``) and the uniform
  baseline (``hetmesh.uniform``): tetrahedra, Ne / N_iso3, delta_max, quality, wall time;
  Gmsh's 3-D mesh with the graded size field (``hetmesh.peers.search3d``) when installed;
- T2: the FEA study per solid (quadratic tetrahedra, von Mises at the probes against the
  reference: the 2-D plane-strain fine solution for fgm_plate_3d, the exact radial solution
  for graded_cylinder), every mesh's tetrahedra and largest error per probe set;
- T3: the tetrahedra each family needs for 0.5 % at the probes, and adaptive / uniform
  (the target: at most 0.5);
- T4 (unless ``--no-refine``): the third family, the material-adaptive mesh at the plan's
  largest delta_0 (start chord tolerance 1e-3; fgm_plate_3d's goal functional is narrower,
  ``hetmesh.reproduce.study3d.CASES3D``) refined by the solution
  (:func:`hetmesh.fea.adapt.refinement_study`: the probes' dual-weighted indicator,
  :mod:`hetmesh.fea.goal`, Doerfler marking, bisection of the longest edge once the
  directions along which the stress hardly varies are shrunk,
  :func:`hetmesh.fea.adapt.stress_metric`, new boundary vertices on the exact surface,
  re-verified), every step's tetrahedra, probe estimate and probe
  errors, and the tetrahedra for 0.5 % by (a) uniform, (b) adaptive, (c) adaptive + refined
  meshes with (c)/(a) against 0.5, and (a') the uniform family again at the refined
  family's starting chord tolerance (counts up to 25,000) with the like-for-like (c)/(a').

``--examples D`` prints instead T0: every 3-D example meshed adaptively and uniformly at
delta_0 = D (tetrahedra, ratio, the uniform size, smallest dihedral angles, wall times).

Every number is measured by this run (one run: the FEA study's numbers are counts and errors,
which do not depend on the machine; the wall times do, and are printed for information).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the quick plan")
    ap.add_argument("--no-peers", action="store_true", help="no Gmsh 3-D peer")
    ap.add_argument("--no-study", action="store_true", help="meshes only, no FEA study")
    ap.add_argument("--cases", default=None, help="comma-separated solids")
    ap.add_argument("--json", default=None, help="write the studies' records here")
    ap.add_argument("--no-meshes", action="store_true", help="the FEA study only (no T1)")
    ap.add_argument("--no-refine", action="store_true",
                    help="no solution-adaptive family (T4)")
    ap.add_argument("--uniform", default=None, metavar="COUNTS",
                    help="the study's uniform tetrahedron counts instead of the plan's")
    ap.add_argument("--thresholds", default=None, metavar="LIST",
                    help="the study's adaptive thresholds instead of the plan's ('none': no "
                         "adaptive mesh)")
    ap.add_argument("--examples", type=float, default=None, metavar="D",
                    help="T0 only: every 3-D example, adaptive and uniform at delta_0 = D")
    ap.add_argument("--skip", default="", help="with --examples: comma-separated examples")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    if args.examples is not None:
        return examples_table(args.examples, {s for s in args.skip.split(",") if s})

    from hetmesh import peers
    from hetmesh.reproduce.report import render3d
    from hetmesh.reproduce.study3d import run3d

    have = [p for p, v in peers.available().items() if v and p == "gmsh"]
    t0 = time.perf_counter()

    def progress(stage, fraction):
        print(f"[{time.perf_counter() - t0:7.1f} s] {stage}", file=sys.stderr, flush=True)

    cases = [c.strip() for c in args.cases.split(",")] if args.cases else None
    plan = {}
    if args.uniform:
        plan["uniform_elements"] = [int(float(n)) for n in args.uniform.split(",")]
    if args.thresholds:
        plan["thresholds"] = [] if args.thresholds == "none" else \
            [float(d) for d in args.thresholds.split(",")]
    sec = run3d(quick=args.quick, peers=[] if args.no_peers else have,
                study=not args.no_study, cases=cases, progress=progress,
                meshes=not args.no_meshes, refine=not args.no_refine, **plan)
    print("\n".join(render3d(sec)))
    print(f"\ntotal {sec.seconds:.0f} s; peers: {', '.join(have) or 'none installed'}")
    if args.json:
        doc = {"runs": [r.__dict__ for r in sec.runs],
               "studies": {k: s.to_dict() for k, s in sec.studies.items()},
               "study_errors": sec.study_errors, "refinements": sec.refinements,
               "seconds": sec.seconds}
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(doc, fh, indent=1, default=float)
    return 0


def examples_table(d0: float, skip: set) -> int:
    """T0: adaptive against uniform tetrahedra on every 3-D example at ``d0``."""
    from pathlib import Path

    import hetmesh
    from hetmesh.metrics import dihedral_angles

    root = Path(hetmesh.example_path("unit_cube")).parent
    names = sorted(p.stem for p in root.glob("*.toml") if "\n[solid]" in p.read_text())
    print(f"T0: adaptive (hetmesh.generate) and uniform (hetmesh.uniform) at delta_0 = {d0}")
    print(f"{'model':<16} {'adaptive':>9} {'uniform':>10} {'a/u':>6} {'h':>7} "
          f"{'dih. min a/u':>13} {'t_a s':>6} {'t_u s':>6}")
    for name in names:
        if name in skip:
            continue
        m = hetmesh.load_model(hetmesh.example_path(name))
        t = time.perf_counter()
        a = hetmesh.generate(m, d0)
        ta = time.perf_counter() - t
        t = time.perf_counter()
        u = hetmesh.uniform(m, d0)
        tu = time.perf_counter() - t
        da = dihedral_angles(a.mesh.points, a.mesh.cells).min()
        du = dihedral_angles(u.mesh.points, u.mesh.cells).min()
        print(f"{name:<16} {a.stats.n_elements:>9} {u.stats.n_elements:>10} "
              f"{a.stats.n_elements / u.stats.n_elements:>6.3f} {u.options['size']:>7.3g} "
              f"{da:>6.1f}/{du:<6.1f} {ta:>6.1f} {tu:>6.1f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
