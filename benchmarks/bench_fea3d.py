"""3-D thermoelastic FEA on tetrahedra: speed and memory at scale, accuracy against the exact
radial solutions.

    PYTHONPATH=src python benchmarks/bench_fea3d.py             # ~5-10 min
    PYTHONPATH=src python benchmarks/bench_fea3d.py --quick     # ~1-2 min: no 1M / 200k runs
    PYTHONPATH=src python benchmarks/bench_fea3d.py --only 1 --out fea3d.json

Measures, never asserts. The problem is the graded Al2O3/Ni cylinder of docs/fea.md
(section "3-D analysis"; hetmesh.fea.verification): a quarter of the tube a = 10, b = 20,
length 5 (mm), metal fraction ((r - a) / (b - a))^2, on structured tetrahedral meshes.

Tables
  G1. Scale: the thermoelastic case (inner face 1173.15 K, outer 273.15 K: conduction, then
      elasticity with the thermal load) at ~1M linear tetrahedra (target: < 60 s, < 8 GB)
      and ~200k quadratic ones (target: < 120 s); each run in a fresh subprocess (its peak
      resident memory is the process's ru_maxrss; its CPU time is printed beside the wall
      time, since on a shared machine the wall time follows the load); phase times
      (material, pattern, thermal, elastic assembly, elastic solve, recovery), CG
      iterations, unknowns, and the largest
      relative error at R1..R3 against the exact solution. Median of --big-repeats runs.
  G2. Solvers: direct (SuperLU) against CG + smoothed-aggregation AMG on the same
      elastic problems at a few sizes (the pressure case, P1 and P2); the ratio direct/AMG.
  G3. Accuracy: the three cases (pressure, thermal, sphere), P1 and P2, errors at the probes
      against the exact radial references over a refinement sweep, and the convergence
      rates from np.polyfit on log(error) against log(h), h ~ tets^(-1/3).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_core import environment, err_text, median, print_table  # noqa: E402

from hetmesh.fea import verification as v  # noqa: E402


def one_run(case: str, n: int, order: int, solver: str) -> dict:
    """Solve once in this process; the dict is what the parent prints."""
    import resource

    from hetmesh.fea import solid

    timings: dict = {}
    orig = solid.solve_tets

    def spy(*a, **k):
        r = orig(*a, **k)
        timings.update(r.timings)
        return r

    v.solve_tets = spy
    t0 = time.perf_counter()
    r = v.run_case(case, n, order, solver=solver)
    wall = time.perf_counter() - t0
    use = resource.getrusage(resource.RUSAGE_SELF)
    rss = use.ru_maxrss / 1024.0  # MB on Linux
    cpu = use.ru_utime + use.ru_stime
    el = r.solver["elastic"]
    th = r.solver.get("thermal", {})
    return {"case": case, "n": n, "order": order, "solver": solver, "tets": r.tets,
            "unknowns": r.unknowns, "wall": wall, "timings": timings,
            "iterations": el.get("iterations"), "thermal_iterations": th.get("iterations"),
            "method": el["method"], "rss_mb": rss, "cpu": cpu, "max_error": r.max_error,
            "errors": r.errors}


def subprocess_run(case: str, n: int, order: int, solver: str, timeout: float) -> dict:
    cmd = [sys.executable, __file__, "--worker", case, str(n), str(order), solver]
    env = dict(os.environ)
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"error": f"timeout after {timeout:.0f} s"}
    if out.returncode != 0:
        tail = (out.stderr.strip().splitlines() or ["?"])[-1]
        return {"error": f"exit {out.returncode}: {tail}"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def table_scale(quick: bool, repeats: int, timeout: float) -> list[dict]:
    # n = 52: 997,776 tets (6 n nt nz, nt = 123, nz = 26); n = 30 P2: 191,700 tets
    cases = [(1, 52, 60.0), (2, 30, 120.0)] if not quick else [(1, 24, 60.0), (2, 12, 120.0)]
    rows, out = [], []
    for order, n, target in cases:
        runs = [subprocess_run("thermal", n, order, "amg", timeout) for _ in range(repeats)]
        ok = [r for r in runs if "error" not in r]
        if not ok:
            rows.append([f"P{order}", str(n), runs[0]["error"]])
            out.append({"order": order, "n": n, "runs": runs})
            continue
        best = sorted(ok, key=lambda r: r["wall"])[len(ok) // 2]
        t = best["timings"]
        wall = median([r["wall"] for r in ok])
        cpu = median([r["cpu"] for r in ok])
        rss = max(r["rss_mb"] for r in ok)
        rows.append([f"P{order}", f"{best['tets']:,}", f"{best['unknowns']:,}",
                     f"{t['material']:.1f}", f"{t['pattern']:.1f}", f"{t['thermal']:.1f}",
                     f"{t['elastic_assembly']:.1f}", f"{t['elastic_solve']:.1f}",
                     f"{t['recovery']:.1f}", f"{wall:.1f}", f"{cpu:.1f}",
                     f"{best['thermal_iterations']}/{best['iterations']}",
                     f"{rss / 1024:.2f}", f"{best['max_error']:.2e}",
                     f"{'PASS' if wall < target and rss < 8192 else 'FAIL'} (<{target:.0f} s)",
                     f"{'PASS' if cpu < target and rss < 8192 else 'FAIL'}"])
        out.append({"order": order, "n": n, "runs": runs})
    print_table("G1. Thermoelastic graded cylinder at scale (subprocess per run; s, GB)",
                ["order", "tets", "unknowns", "material", "pattern", "thermal", "el.asm",
                 "el.solve", "recovery", "wall", "CPU", "CG it T/u", "peak GB", "max err",
                 "target (wall)", "(CPU)"], rows,
                notes=[f"median of {repeats} run(s); peak = ru_maxrss of the worker; max err: "
                       "sigma_r, sigma_t, T at R1..R3 vs the exact radial solution",
                       "CPU: user + system time of the worker (BLAS single-threaded during the "
                       "analysis, so about the wall time of an idle machine; wall time grows "
                       "with the load average printed at the start and end)"])
    return out


def table_solvers(quick: bool) -> list[dict]:
    sizes = [(1, 12), (1, 20), (2, 6), (2, 10)] if not quick else [(1, 12), (2, 6)]
    rows, out = [], []
    for order, n in sizes:
        res = {}
        for solver in ("direct", "amg"):
            try:
                res[solver] = one_run("pressure", n, order, solver)
            except Exception as e:  # noqa: BLE001  (a row, not a crash)
                res[solver] = {"error": err_text(e)}
        d, a = res["direct"], res["amg"]
        if "error" in d or "error" in a:
            rows.append([f"P{order}", str(n), d.get("error") or a.get("error")])
            continue
        td, ta = d["timings"]["elastic_solve"], a["timings"]["elastic_solve"]
        diff = max(abs(d["errors"][p][k] - a["errors"][p][k]) for p in d["errors"]
                   for k in d["errors"][p])
        rows.append([f"P{order}", f"{d['tets']:,}", f"{d['unknowns']:,}", f"{td:.2f}",
                     f"{ta:.2f}", str(a["iterations"]), f"{td / ta:.1f}", f"{diff:.1e}"])
        out.append(res)
    print_table("G2. Elastic solve: direct (SuperLU) against CG + smoothed aggregation (s)",
                ["order", "tets", "unknowns", "direct", "AMG-CG", "CG it", "direct/AMG",
                 "|d err|"], rows,
                notes=["the pressure case; |d err|: largest difference of the probe errors "
                       "(the two solutions agree to the CG tolerance, relative residual 1e-8)"])
    return out


def table_accuracy(quick: bool) -> list[dict]:
    sweeps = {1: (4, 8, 12, 16, 24), 2: (4, 8, 12, 16)} if not quick else \
        {1: (4, 8, 12), 2: (4, 8)}
    rows, out = [], []
    for case in v.CASES:
        ref = v.reference(case)
        for order, ns in sweeps.items():
            runs = [v.run_case(case, n, order, ref=ref) for n in ns]
            for r in runs:
                worst_r = max(e["sigma_r"] for e in r.errors.values())
                worst_t = max(e["sigma_t"] for e in r.errors.values())
                worst_T = max(e.get("T", 0.0) for e in r.errors.values())
                rows.append([case, f"P{order}", f"{r.tets:,}", f"{r.unknowns:,}",
                             f"{worst_r:.2e}", f"{worst_t:.2e}",
                             f"{worst_T:.1e}" if case == "thermal" else "",
                             f"{r.seconds:.1f}"])
            rates = {k: v.convergence(runs, k) for k in ("sigma_r", "sigma_t")}
            rows.append([case, f"P{order}", "rate", "", f"{rates['sigma_r']:.2f}",
                         f"{rates['sigma_t']:.2f}",
                         f"{v.convergence(runs, 'T'):.2f}" if case == "thermal" else "", ""])
            out.append({"case": case, "order": order, "rates": rates,
                        "runs": [{"n": r.n, "tets": r.tets, "errors": r.errors,
                                  "seconds": r.seconds} for r in runs]})
    print_table("G3. Accuracy at R1..R3 against the exact radial solutions (max relative error)",
                ["case", "order", "tets", "unknowns", "sigma_r", "sigma_t", "T", "s"], rows,
                notes=["rate: slope of np.polyfit(log h, log max error), h ~ tets^(-1/3)",
                       "T: temperature error / (T_inner - T_outer)"])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only", action="append", choices=["1", "2", "3"])
    ap.add_argument("--big-repeats", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--worker", nargs=4, metavar=("CASE", "N", "ORDER", "SOLVER"))
    a = ap.parse_args(argv)
    if a.worker:
        case, n, order, solver = a.worker
        print(json.dumps(one_run(case, int(n), int(order), solver)))
        return 0
    env = environment()
    print(f"bench_fea3d: {env}")
    only = set(a.only or ["1", "2", "3"])
    result = {"environment": env}
    if "1" in only:
        result["scale"] = table_scale(a.quick, a.big_repeats, a.timeout)
    if "2" in only:
        result["solvers"] = table_solvers(a.quick)
    if "3" in only:
        result["accuracy"] = table_accuracy(a.quick)
    print(f"\nload average at the end: {os.getloadavg()}")
    if a.out:
        a.out.write_text(json.dumps(result, indent=1, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
