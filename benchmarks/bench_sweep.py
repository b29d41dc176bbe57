#!/usr/bin/env python
"""Sweep benchmarks (hetmesh.sweep on Dask): measure, never assert.

    PYTHONPATH=src python benchmarks/bench_sweep.py            # 3 repeats (~5 min)
    PYTHONPATH=src python benchmarks/bench_sweep.py --quick    # 1 repeat
    PYTHONPATH=src python benchmarks/bench_sweep.py --out results.json

The study: 40 runs, 5 example models (unit_square, power_plate, hft_ring, three_phase,
plate_with_holes) x 8 thresholds from 0.3 to 0.08, adaptive meshes, no files.

Tables
  1. Serial (in this process, no Dask) against local Dask clusters of 1, 2 and 4 workers
     (one single-threaded process each): wall time of the 40 runs (median), speedup over
     serial, the cluster's start-up (cluster, client, hetmesh imported on the workers) apart,
     and the overhead per run: (workers x wall - the runs' own time) / runs, i.e. the time a
     worker spends on anything but meshing (scheduling, serialisation, the result's trip,
     idle workers at the end).
  2. Scale-out estimate for a cluster: every run's measured cost (its time in the serial
     sweep) plus the measured overhead per run (1 worker), assigned in the sweep's order
     (largest a-priori element estimate first) to the first free worker on 1 .. 64 workers;
     for the 40 runs and for each run 16 times over (640 runs). Cluster start-up (the batch queue of
     dask-jobqueue, pods of dask-kubernetes) is not included.

Targets (reported, not asserted): 2 workers at least 1.7 x faster than serial on a 2-core
machine; overhead below 50 ms per run. The load average and a calibration (a pure-Python
loop in two processes against one: the speedup the machine offers two processes at that
moment) are printed beside them, since on a shared machine other users' load caps it.
"""

from __future__ import annotations

import argparse
import heapq
import json
import logging
import os
import platform
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
try:
    import hetmesh  # noqa: F401
except ImportError:  # not installed and no PYTHONPATH=src: use the checkout
    sys.path.insert(0, str(ROOT / "src"))

import hetmesh  # noqa: E402
from hetmesh.io.atomic import atomic_write  # noqa: E402
from hetmesh.study import parse_study, sweep  # noqa: E402

logging.getLogger("hetmesh").setLevel(logging.ERROR)
logging.getLogger("distributed").setLevel(logging.ERROR)

STUDY = {"study": {"name": "bench40"},
         "grid": {"model": ["unit_square", "power_plate", "hft_ring", "three_phase",
                            "plate_with_holes"],
                  "threshold": [0.3, 0.25, 0.2, 0.17, 0.15, 0.12, 0.1, 0.08]}}
WORKERS = (1, 2, 4)
ESTIMATE_WORKERS = (1, 2, 4, 8, 16, 32, 64)


def _warm(client) -> None:
    """Import hetmesh and mesh once on every worker: the start-up a long sweep pays once."""
    def warm():
        import hetmesh as h
        h.generate(h.load_model(h.example_path("unit_square")), 0.3)
        return os.getpid()
    client.run(warm)


def _forget(client, timeout: float = 10.0) -> None:
    """Wait until the scheduler has released every task, so the next repeat computes its
    runs again instead of finding their results under the same keys."""
    def n_tasks(dask_scheduler=None):
        return len(dask_scheduler.tasks)
    deadline = time.monotonic() + timeout
    while client.run_on_scheduler(n_tasks) and time.monotonic() < deadline:
        time.sleep(0.05)


def start_cluster(n: int):
    """A local cluster of ``n`` workers with hetmesh warm on each: ``(cluster, client,
    seconds)``."""
    from dask.distributed import Client, LocalCluster

    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.ERROR)
    client = Client(cluster)
    _warm(client)
    return cluster, client, time.perf_counter() - t0


def timed_sweep(study, **kwargs):
    t0 = time.perf_counter()
    table = sweep(study, **kwargs)
    wall = time.perf_counter() - t0
    bad = table[table["status"] != "ok"]
    if len(bad):
        raise SystemExit(f"bench_sweep: runs failed: {list(bad['error'])}")
    return wall, table


def _spin(n: int) -> float:
    t0 = time.perf_counter()
    s = 0
    for i in range(n):
        s += i * i
    return time.perf_counter() - t0


def cpu_ceiling(n: int = 10_000_000) -> float:
    """The speedup two processes can get on this machine right now: a pure-Python loop
    twice in one process against once in each of two (other users' load included)."""
    from concurrent.futures import ProcessPoolExecutor

    t0 = time.perf_counter()
    _spin(n)
    _spin(n)
    one = time.perf_counter() - t0
    with ProcessPoolExecutor(2) as pool:
        list(pool.map(_spin, [1000, 1000]))
        t0 = time.perf_counter()
        list(pool.map(_spin, [n, n]))
        two = time.perf_counter() - t0
    return one / two


def simulate(costs: list[float], overhead: float, workers: int) -> float:
    """Wall time of ``costs`` (+ ``overhead`` each) given in order to the first free worker."""
    free = [0.0] * workers
    heapq.heapify(free)
    end = 0.0
    for c in costs:
        t = heapq.heappop(free) + c + overhead
        end = max(end, t)
        heapq.heappush(free, t)
    return end


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one repeat instead of three")
    ap.add_argument("--out", type=Path, help="also write the figures as JSON")
    args = ap.parse_args(argv)
    repeats = 1 if args.quick else 3
    study = parse_study(STUDY)
    n_runs = len(study.specs)
    print(f"hetmesh {hetmesh.__version__}, Python {platform.python_version()}, "
          f"{os.cpu_count()} cores; {n_runs} runs, median of {repeats}")

    sweep({"runs": [{"model": "unit_square", "threshold": 0.3}]}, serial=True)  # warm
    clusters = {n: start_cluster(n) for n in WORKERS}
    load0 = os.getloadavg()[0]
    ceilings = [cpu_ceiling()]
    # interleaved repeats (serial, 1, 2, 4 workers, serial, ...): a load that drifts on a
    # shared machine weighs on every engine alike
    walls: dict = {"serial": []}
    tables: dict = {"serial": []}
    try:
        for _ in range(repeats):
            w, t = timed_sweep(study, serial=True)
            walls["serial"].append(w)
            tables["serial"].append(t)
            for n, (_, client, _) in clusters.items():
                w, t = timed_sweep(study, client=client)
                walls.setdefault(n, []).append(w)
                tables.setdefault(n, []).append(t)
                _forget(client)
    finally:
        for cluster, client, _ in clusters.values():
            client.close()
            cluster.close()
    load1 = os.getloadavg()[0]
    ceilings.append(cpu_ceiling())

    def median(key):
        i = walls[key].index(statistics.median(walls[key]))
        return walls[key][i], tables[key][i]

    serial, reference = median("serial")
    costs = [float(s) for s in reference["seconds"]]
    results = []
    for n, (_, _, startup) in clusters.items():
        wall, table = median(n)
        own = float(table["seconds"].sum())
        results.append({"workers": n, "startup": startup, "wall": wall, "walls": walls[n],
                        "own": own, "overhead": (n * wall - own) / n_runs})
    print(f"load average (1 min) {load0:.2f} at the start, {load1:.2f} at the end; two "
          f"processes' speedup on a pure-Python loop (this machine's ceiling now): "
          f"{ceilings[0]:.2f} at the start, {ceilings[1]:.2f} at the end")

    print("\nTable 1. 40 runs: serial against local Dask clusters")
    print(f"{'engine':<18}{'start-up s':>11}{'wall s':>9}{'speedup':>9}{'overhead/run ms':>17}"
          f"{'target':>20}")
    print(f"{'serial':<18}{'-':>11}{serial:>9.2f}{1.0:>9.2f}{'-':>17}")
    for r in results:
        target = ""
        if r["workers"] == 2:
            ok = serial / r["wall"] >= 1.7 and r["overhead"] < 0.05
            target = f"{'PASS' if ok else 'FAIL'} (1.7x, 50ms)"
        print(f"{'dask ' + str(r['workers']) + ' worker(s)':<18}{r['startup']:>11.2f}"
              f"{r['wall']:>9.2f}{serial / r['wall']:>9.2f}{1000 * r['overhead']:>17.1f}"
              f"{target:>20}")
    print(f"runs' own time: serial {sum(costs):.2f} s, "
          + ", ".join(f"{r['workers']} worker(s) {r['own']:.2f} s" for r in results) + ";")
    print(f"serial runs: median {statistics.median(costs):.3f} s, max {max(costs):.3f} s")

    overhead = next(r["overhead"] for r in results if r["workers"] == 1)
    print(f"\nTable 2. Estimated wall time on a cluster (measured costs + {1000 * overhead:.1f} "
          f"ms per run, largest estimate first, first free worker, start-up excluded)")
    print(f"{'workers':>8}{'40 runs s':>11}{'speedup':>9}{'640 runs s':>12}{'speedup':>9}")
    # in the order a sweep submits them: the largest a-priori element estimate first
    order = sorted(range(n_runs), key=lambda i: (-study.specs[i]["cost"], i))
    costs_sorted = [costs[i] for i in order]
    big = [c for c in costs_sorted for _ in range(16)]
    est = []
    for w in ESTIMATE_WORKERS:
        a, b = simulate(costs_sorted, overhead, w), simulate(big, overhead, w)
        est.append({"workers": w, "runs40": a, "runs640": b})
        print(f"{w:>8}{a:>11.2f}{sum(costs) / a:>9.1f}{b:>12.2f}{sum(big) / b:>9.1f}")
    print(f"(the 40-run study is bounded below by its slowest run, {max(costs):.2f} s)")

    if args.out:
        doc = {"serial": serial, "serial_walls": walls["serial"], "costs": costs,
               "load": [load0, load1], "ceiling": ceilings, "clusters": results,
               "estimate": est, "elements": [int(n) for n in reference["n_elements"]]}
        with atomic_write(args.out) as f:
            json.dump(doc, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
