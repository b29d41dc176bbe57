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
  E3. 3-D: examples/graded_cylinder.toml meshed at each --cylinder delta_0, the CalculiX
      deck (C3D10, bins of delta_0 / 4) against hetmesh fea: displacements' largest
      difference over the largest, von Mises and radial stress (sigma_xx, the probes sit on
      y = 0) at R1..R3 (%), CalculiX's and hetmesh fea's times.
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


def agreement3d(model, mesh, workdir: Path, width: float) -> list:
    import hetmesh.fea
    from hetmesh.io.deck import frd_nodal, read_frd, write_deck

    report = write_deck(mesh, model, workdir, "calculix", bin_width=width)
    t0 = time.perf_counter()
    run = subprocess.run(["ccx", "-i", model.name], cwd=workdir, capture_output=True, text=True)
    ccx_s = time.perf_counter() - t0
    if run.returncode != 0:
        raise RuntimeError(run.stdout[-500:])
    t0 = time.perf_counter()
    ours = hetmesh.fea.solve(mesh, model)
    fea_s = time.perf_counter() - t0
    frd = read_frd(workdir / f"{model.name}.frd")
    n = mesh.n_points
    U = frd_nodal(frd, "DISP", n)[:, :3]
    s = frd_nodal(frd, "STRESS", n)
    xx, yy, zz, xy, yz, zx = s.T
    vm = np.sqrt(0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2)
                 + 3 * (xy ** 2 + yz ** 2 + zx ** 2))
    P, T = mesh.points, mesh.cells
    a = P[T[:, 0]]
    J = np.stack([P[T[:, k]] - a for k in (1, 2, 3)], axis=2)
    vms, rads = [], []
    for name, q in model.fea.probes.items():
        lam = np.linalg.solve(J, (np.asarray(q) - a)[..., None])[..., 0]
        bary = np.column_stack([1 - lam.sum(axis=1), lam])
        e = int(np.argmax(bary.min(axis=1)))
        mine = ours.probes[name]
        vms.append(100 * (bary[e] @ vm[T[e]] / mine["von_mises"] - 1))
        rads.append(100 * (bary[e] @ xx[T[e]] / mine["stress_xx"] - 1))
    du = 100 * np.abs(U - ours.displacement).max() / np.abs(ours.displacement).max()
    return [mesh.n_elements, report.bins, f"{du:.2f}", " / ".join(f"{v:+.2f}" for v in vms),
            " / ".join(f"{v:+.2f}" for v in rads), f"{ccx_s:.2f}", f"{fea_s:.2f}"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--delta", type=float, nargs="+", default=[0.1, 0.05])
    ap.add_argument("--plane", nargs="+", default=["strain", "stress"],
                    choices=["strain", "stress"])
    ap.add_argument("--cylinder", type=float, nargs="*", default=[0.25, 0.2, 0.15],
                    help="delta_0 of the 3-D graded_cylinder runs (none: skip E3)")
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
        if args.cylinder:
            cyl = hetmesh.load_model(ROOT / "examples" / "graded_cylinder.toml")
            rows = [[f"{d0:g}"] + agreement3d(cyl, hetmesh.generate(cyl, d0).mesh,
                                              Path(tmp) / f"cyl_{d0}", d0 / 4)
                    for d0 in args.cylinder]
            print_table("E3. 3-D: CalculiX (C3D10, bins delta_0 / 4) vs hetmesh fea on "
                        "graded_cylinder, same mesh",
                        ["delta_0", "tetrahedra", "bins", "U diff %", "vM R1/R2/R3 %",
                         "radial R1/R2/R3 %", "ccx s", "fea s"], rows)


if __name__ == "__main__":
    main()
