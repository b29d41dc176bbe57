"""Exported files against real solvers: CalculiX on hetmesh's deck vs ``hetmesh fea``.

    PYTHONPATH=src python benchmarks/bench_export.py                 # ~1 min
    PYTHONPATH=src python benchmarks/bench_export.py --delta 0.1 0.05 --plane strain stress

Measures, never asserts. For examples/fgm_plate.toml meshed at each delta_0 and each plane
(the model's [fea] table with ``plane`` replaced), ``hetmesh export --to calculix`` with
bins of delta_0 / 4, CalculiX (``ccx``) run on the deck, and ``hetmesh fea`` on the same
mesh. CalculiX's nodal stresses (.frd) are interpolated linearly in the element holding
each probe, as ``hetmesh fea`` interpolates its recovered stresses.

Tables
  E1. Per run: elements, bins, largest property change from binning, temperatures'
      largest difference over their range, the von Mises difference at each probe (%).
  E2. Writing the mesh (median of 3): .msh, .inp, .xdmf, .vtu of the finest mesh.
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_core import ROOT, environment, median, print_table  # noqa: E402


def agreement(model, mesh, workdir: Path, width: float) -> dict:
    import hetmesh.fea
    from hetmesh.fea.analysis import locate, von_mises
    from hetmesh.io.deck import frd_nodal, read_frd, write_deck

    report = write_deck(mesh, model, workdir, "calculix", bin_width=width)
    t0 = time.perf_counter()
    run = subprocess.run(["ccx", "-i", model.name], cwd=workdir, capture_output=True, text=True)
    ccx_s = time.perf_counter() - t0
    if run.returncode != 0:
        raise RuntimeError(run.stdout[-500:])
    ours = hetmesh.fea.solve(mesh, model)
    frd = read_frd(workdir / f"{model.name}.frd")
    n = mesh.n_points

    def nodal(block):
        return frd_nodal(frd, block, n)

    T = nodal("NDTEMP")[:, 0]
    s = nodal("STRESS")
    vm = von_mises(np.column_stack([s[:, 0], s[:, 1], s[:, 3], s[:, 2]]))
    probes = {}
    for name, q in model.fea.probes.items():
        e, lam = locate(mesh.points, mesh.triangles, np.asarray(q, float))
        ref = ours.probes[name]["von_mises"]
        probes[name] = 100 * (float(lam @ vm[mesh.triangles[e]]) / ref - 1)
    return {"elements": mesh.n_elements, "bins": report.bins,
            "binning": 100 * report.max_property_error,
            "T": 100 * float(np.abs(T - ours.temperature).max() / np.ptp(ours.temperature)),
            "probes": probes, "ccx_s": ccx_s}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--delta", type=float, nargs="+", default=[0.1, 0.05])
    ap.add_argument("--plane", nargs="+", default=["strain", "stress"],
                    choices=["strain", "stress"])
    args = ap.parse_args()
    import hetmesh
    from hetmesh.io.export import write_mesh

    env = environment()
    print("hetmesh", hetmesh.__version__, "from", Path(hetmesh.__file__).parent,
          "| ccx", shutil.which("ccx"), "|", {k: env[k] for k in list(env)[:6]})
    if shutil.which("ccx") is None:
        print("ccx not found: apt-get install calculix-ccx")
        return
    base = hetmesh.load_model(ROOT / "examples" / "fgm_plate.toml")
    rows, finest = [], None
    with tempfile.TemporaryDirectory() as tmp:
        for d0 in args.delta:
            mesh = hetmesh.generate(base, d0).mesh
            finest = mesh if finest is None or mesh.n_elements > finest.n_elements else finest
            for plane in args.plane:
                model = dataclasses.replace(base, fea=dataclasses.replace(base.fea, plane=plane))
                r = agreement(model, mesh, Path(tmp) / f"{d0}_{plane}", d0 / 4)
                p = r["probes"]
                rows.append([f"{d0:g}", plane, r["elements"], r["bins"], f"{r['binning']:.2f}",
                             f"{r['T']:.3f}",
                             f"{min(p[k] for k in p if k[0] == 'P'):+.2f} .. "
                             f"{max(p[k] for k in p if k[0] == 'P'):+.2f}",
                             f"{min(p[k] for k in p if k[0] == 'Q'):+.2f} .. "
                             f"{max(p[k] for k in p if k[0] == 'Q'):+.2f}",
                             f"{r['ccx_s']:.2f}"])
        print_table("E1. CalculiX on hetmesh's deck (bins delta_0 / 4) vs hetmesh fea, same mesh",
                    ["delta_0", "plane", "elements", "bins", "binning max %", "T diff % range",
                     "vM P1..P6 %", "vM Q1..Q6 %", "ccx s"], rows)
        rows = []
        for ext in (".msh", ".inp", ".xdmf", ".vtu"):
            times = []
            for _ in range(3):
                t0 = time.perf_counter()
                write_mesh(finest, Path(tmp) / f"w{ext}")
                times.append(time.perf_counter() - t0)
            rows.append([ext, finest.n_elements, f"{median(times):.3f}"])
        print_table("E2. Writing the mesh (median of 3)", ["format", "elements", "s"], rows)


if __name__ == "__main__":
    main()
