#!/usr/bin/env python
"""hetmesh core benchmarks: measure, never assert.

    PYTHONPATH=src python benchmarks/bench_core.py            # full run (~5-10 min)
    PYTHONPATH=src python benchmarks/bench_core.py --quick    # fewer repeats, no 1M run
    PYTHONPATH=src python benchmarks/bench_core.py --out results.json

Tables
  1. power_plate, delta_0 in {0.1, 0.08, 0.05, 0.03}: adaptive (layers, auto, cvt) vs uniform, with
     the paper's element counts as reference columns and the targets as PASS/FAIL.
  2. Closeness to the limit on unit_square, delta_0 in {0.05, 0.03, 0.01}: Ne / N_iso for
     hetmesh (layers, auto, cvt) and the peer Gmsh (Frontal-Delaunay + size callback, scale lowered
     until its delta_max < delta_0).
  3. Speed: power_plate at 0.03 end to end in-process; then (not with --quick) a ~1,000,000
     element run on unit_square against Gmsh making about as many elements, each in a fresh
     subprocess (clean peak memory).
  4. (only with --only 4) ~10,000,000 elements on unit_square: wall, peak memory and the
     cost per element against the ~1M run (minutes).

Timings are medians of several runs; ratios are taken against a peer measured in the same
run. Nothing here fails: targets are reported as PASS/FAIL columns. See benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import functools
import json
import logging
import math
import os
import platform
import resource
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
try:
    import hetmesh  # noqa: F401
except ImportError:  # not installed and no PYTHONPATH=src: use the checkout
    sys.path.insert(0, str(ROOT / "src"))

import hetmesh  # noqa: E402
from hetmesh import peers  # noqa: E402
from hetmesh.density import n_iso  # noqa: E402
from hetmesh.io.atomic import atomic_write  # noqa: E402

logging.getLogger("hetmesh").setLevel(logging.WARNING)

EXAMPLES = ROOT / "examples"
POWER_PLATE = EXAMPLES / "power_plate.toml"
UNIT_SQUARE = EXAMPLES / "unit_square.toml"

PLATE_THRESHOLDS = (0.1, 0.08, 0.05, 0.03)
# The paper's Table 1: (adaptive Ne, uniform Ne) per delta_0.
PAPER = {0.1: (454, 1218), 0.08: (564, 1298), 0.05: (1353, 5075), 0.03: (3815, 11534)}
SQUARE_THRESHOLDS = (0.05, 0.03, 0.01)
N_ISO_EXPECTED = {0.05: 1232, 0.03: 3421, 0.01: 30792}
#: unit_square at this delta_0 makes about 990,000 elements with the default row spacing
#: (0.85 x delta_0; 0.00155 did at 0.985): Ne ~ 1/delta_0^2 at a fixed spacing
BIG_THRESHOLD = 0.0018
#: about 9.9 million elements: BIG_THRESHOLD / sqrt(10)
HUGE_THRESHOLD = 0.000569
#: targets: 1M-element wall <= this x Gmsh's; 10M elements under this peak memory (MB), at
#: most this x the 1M run's cost per element
TARGET_VS_GMSH = 0.5
TARGET_HUGE_MB = 6 * 1024
TARGET_PER_ELEMENT = 1.3

# Gmsh peer settings (reported in the output).
GMSH_ALGORITHM = 6              # Frontal-Delaunay
GMSH_THREADS = 1
GMSH_H_CAP = 0.2                # largest size
GMSH_S_START, GMSH_S_FACTOR, GMSH_S_TRIES = 1.2, 0.9, 40


def gmsh_grad_floor(delta0: float) -> float:
    """Floor of |grad f| in the Gmsh size field.

    f = (1-y)^2 has f'' = 2, so near y = 1 the variation over an element of size h is ~h^2,
    not h |grad f|: the curvature-limited size sqrt(2 delta_0 / f'') = sqrt(delta_0) equals
    delta_0 / g at g = sqrt(delta_0). Flooring g there keeps the size field honest at the top
    edge (a tiny floor would leave h = 0.2 there and delta ~ 0.04 for every s).
    """
    return math.sqrt(delta0)


# ----------------------------------------------------------------------------- helpers

def median(xs):
    return float(statistics.median(xs)) if xs else float("nan")


CASE_TIMEOUT = 300.0   # seconds per in-process run (--case-timeout); 0 = none


class CaseTimeout(Exception):
    pass


def _alarm(signum, frame):
    raise CaseTimeout(f"no result after {CASE_TIMEOUT:.0f} s")


def guarded(fn):
    """Call ``fn`` with a wall-clock limit (SIGALRM; checked between Python bytecodes)."""
    if not CASE_TIMEOUT or not hasattr(signal, "setitimer"):
        return fn()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, CASE_TIMEOUT)
    try:
        return fn()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def timed(fn, repeats: int):
    """Run ``fn`` ``repeats`` times; return (last result, list of wall times)."""
    times, out = [], None
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        out = guarded(fn)
        times.append(time.perf_counter() - t)
    return out, times


def err_text(e: BaseException) -> str:
    return f"ERROR {type(e).__name__}: {str(e).splitlines()[0][:110] if str(e) else ''}".strip()


def limit_memory(gb: float) -> None:
    """Cap the address space so a runaway case raises MemoryError instead of the OOM killer."""
    if gb and gb > 0:
        lim = int(gb * 2 ** 30)
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        if hard != resource.RLIM_INFINITY:
            lim = min(lim, hard)
        resource.setrlimit(resource.RLIMIT_AS, (lim, hard))


def pf(ok) -> str:
    return "n/a" if ok is None else ("PASS" if ok else "FAIL")


def fmt(v, spec=".3f"):
    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    if isinstance(v, float) and not math.isfinite(v):
        return "-"
    if isinstance(v, int):
        return f"{v:,}"
    return format(v, spec)


def print_table(title: str, headers: list[str], rows: list[list[str]], notes=()):
    """Aligned plain text. A row shorter than the header is a 'span' row (e.g. an error):
    its leading cells are aligned and its last cell runs on unaligned."""
    rows = [[str(c) for c in r] for r in rows]
    full = [r for r in rows if len(r) == len(headers)]
    spans = [r for r in rows if len(r) < len(headers)]
    widths = [len(h) for h in headers]
    for r in full:
        widths = [max(w, len(c)) for w, c in zip(widths, r)]
    for r in spans:
        for i, c in enumerate(r[:-1]):
            widths[i] = max(widths[i], len(c))

    def line(cells):
        out = []
        for i, (c, w) in enumerate(zip(cells, widths)):
            out.append(c.ljust(w) if i < 2 else c.rjust(w))
        return "  ".join(out).rstrip()

    print()
    print(title)
    print("=" * len(title))
    print(line(headers))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        if len(r) < len(headers):
            print("  ".join(c.ljust(widths[i]) for i, c in enumerate(r[:-1])) + "  " + r[-1])
        else:
            print(line(r))
    for n in notes:
        print(f"  {n}")
    sys.stdout.flush()


def save_json(path: Path, data: dict) -> None:
    """Write the measurements as JSON (atomically, hetmesh.io.atomic) and say so."""
    with atomic_write(path) as fh:
        json.dump(data, fh, indent=2, default=float)
    print(f"wrote {path}")


def environment() -> dict:
    info = {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "hetmesh": getattr(hetmesh, "__version__", "?"),
        "hetmesh_path": str(Path(hetmesh.__file__).resolve().parent),
        "numpy": np.__version__,
        "loadavg_start": os.getloadavg(),
    }
    try:
        import scipy
        info["scipy"] = scipy.__version__
    except ImportError:
        pass
    gm = gmsh_available()
    info["gmsh"] = gm if gm else "not installed"
    try:
        import subprocess as sp
        info["git"] = sp.run(["git", "-C", str(ROOT), "describe", "--always", "--dirty"],
                             capture_output=True, text=True, timeout=10).stdout.strip()
    except Exception:
        pass
    return info


def gmsh_available():
    """Gmsh's version, or None if it is not installed (hetmesh.peers.available)."""
    return peers.available()["gmsh"]


# ----------------------------------------------------------------------------- Gmsh peer
# The driver (geometry, size field, generate, read back) and the s search live in
# hetmesh.peers; here only the unit square's analytic size: f = (1-y)^2, |grad f| = 2(1-y).

@functools.cache
def _square_domain():
    return hetmesh.load_model(UNIT_SQUARE).domain


def unit_square_size(delta0: float, s: float, field: str = "callback"):
    """h = min(cap, s*delta0/max(|grad f|, floor)) as a Gmsh callback or MathEval formula."""
    floor = gmsh_grad_floor(delta0)
    sd = s * delta0
    if field == "callback":
        return lambda x, y: min(GMSH_H_CAP, sd / max(2.0 * (1.0 - y), floor))
    return f"min({GMSH_H_CAP!r}, {sd!r} / max(2*(1-y), {floor!r}))"


def gmsh_unit_square(delta0: float, s: float, *, field: str = "callback",
                     threads: int = GMSH_THREADS):
    """Mesh the unit square with Gmsh (hetmesh.peers.gmsh_mesh), size from
    :func:`unit_square_size`. Returns (points (N,2), triangles (M,3), wall seconds of model
    build + generate + read back)."""
    m = peers.gmsh_mesh(_square_domain(), unit_square_size(delta0, s, field), field=field,
                        threads=threads, algorithm=GMSH_ALGORITHM)
    return m.points, m.triangles, m.seconds


def gmsh_stats(model, pts, tris) -> dict:
    return peers.peer_statistics(model, peers.PeerMesh(pts, tris, 0.0)).as_dict()


# ----------------------------------------------------------------------------- table 1

def table_plate(repeats: int) -> dict:
    model = hetmesh.load_model(POWER_PLATE)
    out = []
    rows = []
    for d0 in PLATE_THRESHOLDS:
        runs = {}
        for name, fn in (("layers", lambda d0=d0: hetmesh.generate(model, d0, method="layers")),
                         ("auto", lambda d0=d0: hetmesh.generate(model, d0)),
                         ("cvt", lambda d0=d0: hetmesh.generate(model, d0, method="cvt")),
                         ("uniform", lambda d0=d0: hetmesh.uniform(model, d0))):
            try:
                res, times = timed(fn, repeats)
                runs[name] = (res.stats.as_dict(), times)
            except Exception as e:  # measure, never assert: report and go on
                runs[name] = (err_text(e), [])
        pa, pu = PAPER[d0]
        ne_u = runs["uniform"][0]["n_elements"] if isinstance(runs["uniform"][0], dict) else None
        for name in ("layers", "auto", "cvt", "uniform"):
            st, times = runs[name]
            if isinstance(st, str):
                out.append(dict(threshold=d0, method=name, error=st))
                rows.append([fmt(d0, "g"), name, st])
                continue
            ratio = st["n_elements"] / ne_u if ne_u else float("nan")
            rec = dict(threshold=d0, method=name, **st, delta_avg_rel=st["delta_avg"] / d0,
                       ratio_vs_uniform=ratio, time_median=median(times), times=times,
                       paper_adaptive=pa, paper_uniform=pu)
            if name == "uniform":
                checks = {"delta_max<d0": st["delta_max"] < d0}
            else:
                checks = {
                    "delta_max<d0": st["delta_max"] < d0,
                    "q_min>=0.6": st["q_min"] >= 0.6,
                    "q_avg>=0.94": st["q_avg"] >= 0.94,
                    "delta_avg/d0>=0.75": st["delta_avg"] / d0 >= 0.75,
                }
                if d0 == 0.03:
                    checks["ratio<=0.30"] = bool(ratio <= 0.30)
            rec["checks"] = checks
            failed = [k for k, v in checks.items() if not v]
            verdict = "PASS" if not failed else "FAIL: " + ", ".join(k.split("<")[0].split(">")[0]
                                                                     for k in failed)
            rec["verdict"] = verdict
            out.append(rec)
            paper_ne = pa if name != "uniform" else pu
            rows.append([fmt(d0, "g"), name, fmt(st["n_points"]), fmt(st["n_elements"]),
                         fmt(st["q_min"]), fmt(st["q_avg"]), fmt(st["delta_avg"] / d0),
                         fmt(st["delta_max"], ".4f"),
                         fmt(ratio, ".3f") if name != "uniform" else "1",
                         fmt(median(times), ".3f"),
                         fmt(paper_ne), fmt(pa / pu, ".3f") if name != "uniform" else "1",
                         verdict if name != "uniform" else pf(checks["delta_max<d0"]) + " (δmax)"])
    print_table(
        f"Table 1. power_plate: adaptive vs uniform (median of {repeats} run(s))",
        ["δ0", "method", "Np", "Ne", "q_min", "q_avg", "δavg/δ0", "δmax", "Ne/Ne_unif",
         "time s", "paper Ne", "paper ratio", "targets"],
        rows,
        notes=["ratio = Ne / Ne of hetmesh.uniform at the same δ0 in this run; 'paper Ne' and "
               "'paper ratio' are the paper's Table 1 (454/1218, 564/1298, 1353/5075, 3815/11534).",
               "targets (adaptive rows): δmax < δ0, q_min >= 0.6, q_avg >= 0.94, "
               "δavg/δ0 >= 0.75, and Ne/Ne_unif <= 0.30 at δ0 = 0.03; FAIL lists the missed ones.",
               "method cvt = the paper's algorithm (CVT start); layers = hetmesh's rows; auto = "
               "hetmesh's default (rows and the springs starts, the best kept).",
               "power_plate geometry is a reconstruction (see examples/power_plate.toml)."])
    return {"rows": out, "repeats": repeats}


# ----------------------------------------------------------------------------- table 2

def gmsh_search(model, d0: float):
    """Step s from GMSH_S_START by GMSH_S_FACTOR to the largest s = GMSH_S_START *
    GMSH_S_FACTOR^k with delta_max < d0 (hetmesh.peers.search with the analytic callback, no
    bisection); returns (s, stats dict, wall seconds of the accepted run, trace, search
    seconds), s None if no s met the threshold."""
    try:
        r = peers.search("gmsh", model, d0, size=lambda s: unit_square_size(d0, s, "callback"),
                         field="callback", threads=GMSH_THREADS, s_start=GMSH_S_START,
                         factor=GMSH_S_FACTOR, tries=GMSH_S_TRIES, bisect=0)
    except hetmesh.MeshingError:
        return None, None, float("nan"), [], float("nan")
    trace = [dict(t, time=t["seconds"]) for t in r.trace]
    return r.s, r.stats.as_dict(), r.seconds, trace, r.search_seconds


def table_square(repeats: int) -> dict:
    model = hetmesh.load_model(UNIT_SQUARE)
    have_gmsh = gmsh_available()
    out, rows = [], []
    for d0 in SQUARE_THRESHOLDS:
        niso = float(n_iso(model.material, model.domain, d0))
        for name in ("layers", "auto", "cvt"):
            try:
                res, times = timed(
                    lambda d0=d0, name=name: hetmesh.generate(model, d0, method=name), repeats)
            except Exception as e:
                out.append(dict(threshold=d0, mesher=f"hetmesh {name}", error=err_text(e)))
                rows.append([fmt(d0, "g"), f"hetmesh {name}", err_text(e)])
                continue
            st = res.stats.as_dict()
            r = st["n_elements"] / niso
            rec = dict(threshold=d0, mesher=f"hetmesh {name}", n_iso=niso,
                       n_iso_expected=N_ISO_EXPECTED[d0], **st, ne_over_niso=r,
                       time_median=median(times), times=times)
            out.append(rec)
            rows.append([fmt(d0, "g"), f"hetmesh {name}", fmt(st["n_elements"]), fmt(niso, ",.0f"),
                         fmt(r), pf(r <= 1.2), fmt(st["delta_max"], ".5f"),
                         pf(st["delta_max"] < d0), fmt(st["q_min"]), fmt(st["q_avg"]),
                         fmt(median(times), ".3f"), ""])
        if not have_gmsh:
            out.append(dict(threshold=d0, mesher="gmsh", status="not installed"))
            rows.append([fmt(d0, "g"), "gmsh FD", "not installed (pip install gmsh)"])
            continue
        try:
            s, st, wall, trace, search_time = guarded(lambda d0=d0: gmsh_search(model, d0))
        except Exception as e:
            out.append(dict(threshold=d0, mesher="gmsh", error=err_text(e)))
            rows.append([fmt(d0, "g"), "gmsh FD", err_text(e)])
            continue
        if s is None:
            out.append(dict(threshold=d0, mesher="gmsh", status="no s found", trace=trace))
            rows.append([fmt(d0, "g"), "gmsh FD", f"no s in {GMSH_S_TRIES} tries"])
            continue
        times = [wall]  # the accepted s (the search may end on a failing, larger s)
        for _ in range(max(0, repeats - 1)):
            _, _, wall = guarded(lambda d0=d0, s=s: gmsh_unit_square(d0, s, field="callback"))
            times.append(wall)
        r = st["n_elements"] / niso
        rec = dict(threshold=d0, mesher="gmsh frontal-delaunay", n_iso=niso, s=s, **st,
                   ne_over_niso=r, time_median=median(times), times=times, search=trace,
                   search_time=search_time)
        out.append(rec)
        rows.append([fmt(d0, "g"), "gmsh FD", fmt(st["n_elements"]), fmt(niso, ",.0f"), fmt(r),
                     pf(r <= 1.2), fmt(st["delta_max"], ".5f"), pf(st["delta_max"] < d0),
                     fmt(st["q_min"]), fmt(st["q_avg"]), fmt(median(times), ".3f"),
                     f"s={s:.3f} ({len(trace)} tries, {search_time:.1f} s)"])
    gm = f"Gmsh {have_gmsh}" if have_gmsh else "Gmsh not installed"
    print_table(
        f"Table 2. unit_square (f = (1-y)^2): closeness to the limit N_iso "
        f"(median of {repeats} run(s))",
        ["δ0", "mesher", "Ne", "N_iso", "Ne/N_iso", "≤1.2", "δmax", "δmax<δ0", "q_min", "q_avg",
         "time s", "notes"],
        rows,
        notes=["N_iso = (4/√3)∫|∇f|²dA/δ0² from hetmesh.density.n_iso (expected 1232, 3421, "
               "30792); target Ne/N_iso <= 1.2.",
               f"{gm}: Mesh.Algorithm=6 (Frontal-Delaunay), General.NumThreads={GMSH_THREADS}, "
               "General.Terminal=0, MeshSizeExtendFromBoundary=MeshSizeFromPoints="
               "MeshSizeFromCurvature=0,",
               f"  size via setSizeCallback: h = min({GMSH_H_CAP}, s·δ0 / max(2(1-y), √δ0)); "
               f"s = {GMSH_S_START}·{GMSH_S_FACTOR}^k, smallest integer k with δmax < δ0 "
               "(δ from hetmesh.peers.peer_statistics at Gmsh's nodes).",
               "  Gmsh time = initialize + geometry + generate(2) + read back nodes/elements "
               "(the accepted s only; the search time is in notes). hetmesh time = generate()."])
    return {"rows": out, "repeats": repeats}


# ----------------------------------------------------------------------------- table 3

def speed_plate(runs: int) -> dict:
    out = {}
    rows = []
    for method in ("layers", "cvt"):
        walls, phases = [], []

        def once(tmp, i, method=method, walls=walls, phases=phases):
            t = time.perf_counter()
            model = hetmesh.load_model(POWER_PLATE)
            t_load = time.perf_counter() - t
            res = hetmesh.generate(model, 0.03, method=method)
            t_w = time.perf_counter()
            res.mesh.write(Path(tmp) / f"plate_{method}_{i}.vtu")
            t_write = time.perf_counter() - t_w
            walls.append(time.perf_counter() - t)
            phases.append({"load": t_load,
                           **{k: v for k, v in res.timings.items() if k != "total"},
                           "write": t_write})
            return res

        try:
            with tempfile.TemporaryDirectory() as tmp:
                for i in range(runs):
                    res = guarded(lambda i=i: once(tmp, i))
        except Exception as e:
            out[method] = dict(error=err_text(e))
            rows.append(["power_plate 0.03", method, err_text(e)])
            continue
        med = median(walls)
        ph_med = {k: median([p[k] for p in phases]) for k in phases[0]}
        out[method] = dict(walls=walls, median=med, phases_median=ph_med,
                           n_elements=res.stats.n_elements, target_lt_1s=med < 1.0)
        rows.append(["power_plate 0.03", method, fmt(res.stats.n_elements), fmt(med, ".3f"),
                     fmt(min(walls), ".3f"), fmt(walls[0], ".3f"),
                     " ".join(f"{k} {v:.3f}" for k, v in ph_med.items()),
                     pf(med < 1.0) if method == "layers" else f"({pf(med < 1.0)})"])
    print_table(
        f"Table 3a. Speed, end to end in-process: load_model + generate + write .vtu "
        f"(median of {runs} runs)",
        ["case", "method", "Ne", "median s", "min s", "first s", "phase medians (s)", "< 1 s"],
        rows,
        notes=["target < 1 s applies to the default method (layers); cvt shown for reference.",
               "first = first run in this process (includes lazy imports / warm-up)."])
    return out


BIG_TIMEOUT = 1800.0


def run_worker(args: list[str], timeout: float | None = None) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker"] + args
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT / "src")] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True,
                          timeout=timeout or BIG_TIMEOUT, env=env)
    wall = time.perf_counter() - t
    if proc.returncode != 0:
        raise RuntimeError(f"worker {args} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    data = json.loads(proc.stdout.strip().splitlines()[-1])
    data["process_wall"] = wall
    return data


def peak_rss_mb() -> tuple[float, str]:
    """Peak resident memory of this process in MB, and where it came from.

    /proc/self/status VmHWM is the high-water mark of this process's own address space. After
    exec, ru_maxrss still carries the parent's peak at spawn time (Linux copies the old mm's
    high-water mark into the signal struct), so it is only the fallback.
    """
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024, "VmHWM"
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "ru_maxrss"


def worker_main(argv: list[str]) -> int:
    """Child process: one measurement, JSON on the last stdout line."""
    p = argparse.ArgumentParser()
    p.add_argument("kind", choices=("hetmesh", "gmsh"))
    p.add_argument("--threshold", type=float, required=True)
    p.add_argument("--method", default="layers")
    p.add_argument("--s", type=float, default=1.0)
    p.add_argument("--field", default="matheval")
    p.add_argument("--max-elements", type=int, default=None)
    a = p.parse_args(argv)
    base_rss, _ = peak_rss_mb()
    model = hetmesh.load_model(UNIT_SQUARE)
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    t = time.perf_counter()
    if a.kind == "hetmesh":
        kw = {} if a.max_elements is None else {"max_elements": a.max_elements}
        res = hetmesh.generate(model, a.threshold, method=a.method, **kw)
        wall = time.perf_counter() - t
        stats = res.stats.as_dict()
        timings = dict(res.timings)
    else:
        import gmsh  # noqa: F401
        pts, tris, wall_inner = gmsh_unit_square(a.threshold, a.s, field=a.field)
        wall = time.perf_counter() - t
        stats = gmsh_stats(model, pts, tris)
        timings = {"gmsh (build+generate+read)": wall_inner}
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    peak, source = peak_rss_mb()
    print(json.dumps(dict(kind=a.kind, threshold=a.threshold, s=a.s, field=a.field,
                          method=a.method, wall=wall, cpu=cpu, timings=timings, stats=stats,
                          maxrss_mb=peak, rss_source=source, base_rss_mb=base_rss,
                          ru_maxrss_mb=r1.ru_maxrss / 1024)))
    return 0


def big_gmsh(ne_target: int, repeats: int):
    """Gmsh at BIG_THRESHOLD with s calibrated so that it makes about ``ne_target`` elements."""
    model = hetmesh.load_model(UNIT_SQUARE)
    niso = float(n_iso(model.material, model.domain, BIG_THRESHOLD))
    # calibrate s on a ~150k-element run: Ne ~ 1/s^2 (N_iso(s*δ0) = N_iso(δ0)/s^2)
    s0 = math.sqrt(niso / 150_000)
    print(f"[1M run] gmsh calibration at s={s0:.3f} (~150k elements) ...", flush=True)
    cal = run_worker(["gmsh", "--threshold", str(BIG_THRESHOLD), "--s", repr(s0),
                      "--field", "matheval"])
    s = s0 * math.sqrt(cal["stats"]["n_elements"] / ne_target)
    print(f"[1M run] gmsh s={s:.4f} (target {ne_target:,} elements, {repeats} run(s)) ...",
          flush=True)
    gm = [run_worker(["gmsh", "--threshold", str(BIG_THRESHOLD), "--s", repr(s),
                      "--field", "matheval"]) for _ in range(repeats)]
    return gm, cal



def _subprocess_summary(runs: list[dict]):
    """``(stats of the last run, median wall, median cpu, peak RSS, phase medians as text)``
    of repeated worker-subprocess runs (tables 3b and 4)."""
    st = runs[-1]["stats"]
    wall = median([r["wall"] for r in runs])
    cpu = median([r["cpu"] for r in runs])
    rss = max(r["maxrss_mb"] for r in runs)
    ph = {k: median([r["timings"][k] for r in runs]) for k in runs[0]["timings"]}
    phs = " ".join(f"{k} {v:.1f}" for k, v in ph.items() if k != "total")
    return st, wall, cpu, rss, phs

def speed_big(repeats: int) -> dict:
    out = {}
    print(f"\n[1M run] hetmesh unit_square δ0={BIG_THRESHOLD} (subprocess, {repeats} run(s)) ...",
          flush=True)
    try:
        het = [run_worker(["hetmesh", "--threshold", str(BIG_THRESHOLD)]) for _ in range(repeats)]
    except Exception as e:
        out["hetmesh"] = dict(error=err_text(e))
        print_table("Table 3b. ~1,000,000 elements: unit_square", ["mesher", "result"],
                    [["hetmesh layers", err_text(e)]])
        return out
    out["hetmesh"] = het
    ne_target = het[0]["stats"]["n_elements"]
    gm_ver = gmsh_available()
    gm, cal, gm_error = None, None, None
    if gm_ver:
        try:
            gm, cal = big_gmsh(ne_target, repeats)
            out["gmsh"] = gm
            out["gmsh_calibration"] = cal
        except Exception as e:
            gm_error = err_text(e)
            out["gmsh"] = dict(error=gm_error)
    rows = []

    def row(name, runs, extra):
        st, wall, cpu, rss, phs = _subprocess_summary(runs)
        rows.append([name, fmt(st["n_elements"]), fmt(st["n_points"]), fmt(wall, ".1f"),
                     fmt(cpu, ".1f"), fmt(1e6 * wall / st["n_elements"], ".1f"),
                     fmt(rss, ",.0f"), fmt(st["delta_max"], ".5f"), fmt(st["q_min"]),
                     fmt(st["q_avg"]), phs, extra])
        return wall, cpu, st["n_elements"]

    hw, hc, hn = row("hetmesh layers", het, f"δ0={BIG_THRESHOLD}")
    ru = [f"hetmesh {max(r['ru_maxrss_mb'] for r in het):,.0f} MB"]
    if gm:
        ru.append(f"gmsh {max(r['ru_maxrss_mb'] for r in gm):,.0f} MB")
    notes = [f"each run in a fresh subprocess; peak RSS = {het[0]['rss_source']} of that process "
             f"(its peak after imports, before meshing ≈ {het[0]['base_rss_mb']:.0f} MB); "
             "cpu = user+sys of the meshing.",
             f"ru_maxrss of the same processes: {', '.join(ru)} (after exec it also carries the "
             "parent's peak, hence VmHWM above).",
             "hetmesh phases from Result.timings; wall = generate() only (model load excluded)."]
    if gm:
        gw, gc, gn = row("gmsh FD", gm, f"s={gm[0]['s']:.3f} MathEval")
        out["ratio_wall"] = hw / gw
        out["ratio_cpu"] = hc / gc
        out["ratio_wall_per_element"] = (hw / hn) / (gw / gn)
        out["target_wall_per_element"] = out["ratio_wall_per_element"] <= TARGET_VS_GMSH
        notes += [f"Gmsh {gm_ver}: Mesh.Algorithm=6, NumThreads={GMSH_THREADS}, Terminal=0, "
                  f"MathEval background field F = min({GMSH_H_CAP}, s·δ0/max(2(1-y), √δ0)) "
                  "(not the Python callback), MeshSizeFromPoints/Curvature/ExtendFromBoundary=0;",
                  f"  s calibrated so Ne ≈ hetmesh's Ne (one ~{cal['stats']['n_elements']:,}-"
                  "element calibration run, not timed); Gmsh wall = build+generate(2)+read back; "
                  "its δmax is w.r.t. the same δ0 for information only.",
                  f"ratio hetmesh/gmsh: wall {out['ratio_wall']:.2f}x, "
                  f"cpu {out['ratio_cpu']:.2f}x, "
                  f"wall per element {out['ratio_wall_per_element']:.2f}x "
                  f"(target <= {TARGET_VS_GMSH}x: {pf(out['target_wall_per_element'])})"]
    else:
        rows.append(["gmsh FD", gm_error or "not installed (pip install gmsh)"])
    print_table(f"Table 3b. ~1,000,000 elements: unit_square (median of {repeats} run(s))",
                ["mesher", "Ne", "Np", "wall s", "cpu s", "µs/elem", "peak RSS MB", "δmax",
                 "q_min", "q_avg", "phases (s)", "settings"], rows, notes=notes)
    return out


def speed_huge(big: dict | None, repeats: int) -> dict:
    """Table 4: about 10 million elements (hetmesh only) against the ~1M run of table 3b
    (made here first if table 3b did not run): wall, peak memory, cost per element."""
    out = {}
    one = (big or {}).get("hetmesh")
    rows = []
    try:
        if not isinstance(one, list):
            print(f"\n[10M run] hetmesh unit_square δ0={BIG_THRESHOLD} first, the per-element "
                  f"reference (subprocess, {repeats} run(s)) ...", flush=True)
            one = [run_worker(["hetmesh", "--threshold", str(BIG_THRESHOLD)])
                   for _ in range(repeats)]
        print(f"\n[10M run] hetmesh unit_square δ0={HUGE_THRESHOLD} (subprocess, {repeats} "
              "run(s), minutes) ...", flush=True)
        huge = [run_worker(["hetmesh", "--threshold", str(HUGE_THRESHOLD),
                            "--max-elements", "50000000"]) for _ in range(repeats)]
    except Exception as e:
        out["error"] = err_text(e)
        print_table("Table 4. ~10,000,000 elements: unit_square", ["case", "result"],
                    [["hetmesh layers", err_text(e)]])
        return out
    out["one"], out["huge"] = one, huge

    def row(name, runs):
        st, wall, cpu, rss, phs = _subprocess_summary(runs)
        per = 1e6 * wall / st["n_elements"]
        rows.append([name, fmt(st["n_elements"]), fmt(st["n_points"]), fmt(wall, ".1f"),
                     fmt(cpu, ".1f"), fmt(per, ".1f"), fmt(rss, ",.0f"),
                     fmt(st["delta_max"], ".6f"), fmt(st["q_min"]), fmt(st["q_avg"]), phs])
        return per, rss

    per1, _ = row(f"δ0={BIG_THRESHOLD}", one)
    per10, rss10 = row(f"δ0={HUGE_THRESHOLD}", huge)
    out["ratio_per_element"] = per10 / per1
    out["peak_mb"] = rss10
    out["target_peak"] = rss10 < TARGET_HUGE_MB
    out["target_per_element"] = out["ratio_per_element"] <= TARGET_PER_ELEMENT
    print_table(f"Table 4. ~10,000,000 elements: unit_square (median of {repeats} run(s))",
                ["case", "Ne", "Np", "wall s", "cpu s", "µs/elem", "peak RSS MB", "δmax",
                 "q_min", "q_avg", "phases (s)"], rows,
                notes=[f"cost per element, 10M / 1M: {out['ratio_per_element']:.2f}x (target <= "
                       f"{TARGET_PER_ELEMENT}x: {pf(out['target_per_element'])}); peak RSS "
                       f"{rss10:,.0f} MB (target < {TARGET_HUGE_MB:,} MB: "
                       f"{pf(out['target_peak'])})",
                       "each run in a fresh subprocess (as table 3b); element budget 50,000,000 "
                       "for the 10M run."])
    return out


# ----------------------------------------------------------------------------- main

def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--worker":
        return worker_main(argv[1:])
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true",
                   help="1 repeat for tables 1-2, 3 speed runs, skip the 1M run")
    p.add_argument("--out", type=Path, help="write all measurements as JSON")
    p.add_argument("--repeats", type=int, help="repeats for tables 1-2 (default 3; quick 1)")
    p.add_argument("--big-repeats", type=int, default=1,
                   help="runs of each 1M-element case (default 1; each takes minutes)")
    p.add_argument("--skip-big", action="store_true", help="skip the 1M-element run")
    p.add_argument("--case-timeout", type=float, default=300.0,
                   help="seconds allowed per in-process run before it is reported as an "
                        "error (default 300; 0 = none)")
    p.add_argument("--big-timeout", type=float, default=1800.0,
                   help="seconds allowed per 1M-element subprocess (default 1800)")
    p.add_argument("--mem-limit-gb", type=float, default=12.0,
                   help="address-space cap (RLIMIT_AS) so a runaway case raises MemoryError "
                        "instead of meeting the OOM killer (default 12; 0 = none)")
    p.add_argument("--only", choices=("1", "2", "3", "4"), action="append",
                   help="run only these tables (repeatable); table 4 (~10M elements, "
                        "minutes) runs only when asked for")
    a = p.parse_args(argv)
    global CASE_TIMEOUT, BIG_TIMEOUT
    CASE_TIMEOUT, BIG_TIMEOUT = a.case_timeout, a.big_timeout
    limit_memory(a.mem_limit_gb)
    repeats = a.repeats or (1 if a.quick else 3)
    speed_runs = 3 if a.quick else 5
    only = set(a.only or ("1", "2", "3"))

    env = environment()
    t_all = time.perf_counter()
    print(f"hetmesh benchmarks: hetmesh {env['hetmesh']} ({env.get('git', '?')}), "
          f"Python {env['python']}, numpy {env['numpy']}, scipy {env.get('scipy', '?')}, "
          f"gmsh {env['gmsh']}")
    print(f"hetmesh imported from {env['hetmesh_path']}")
    print(f"{env['platform']}, {env['cpu_count']} CPU(s), load average at start "
          f"{' '.join(f'{x:.2f}' for x in env['loadavg_start'])}"
          f"{' (quick)' if a.quick else ''}")
    results: dict = {"environment": env, "quick": a.quick}
    if "1" in only:
        results["table1_power_plate"] = table_plate(repeats)
    if "2" in only:
        results["table2_unit_square"] = table_square(repeats)
    if "3" in only:
        results["table3_speed"] = speed_plate(speed_runs)
        if not (a.quick or a.skip_big):
            results["table3_big"] = speed_big(a.big_repeats)
    if "4" in only:
        results["table4_huge"] = speed_huge(results.get("table3_big"), a.big_repeats)
    env["loadavg_end"] = os.getloadavg()
    results["total_seconds"] = time.perf_counter() - t_all
    print(f"\ntotal benchmark time {results['total_seconds']:.0f} s; load average at end "
          f"{' '.join(f'{x:.2f}' for x in env['loadavg_end'])} "
          "(timings are wall clock; a loaded machine inflates them)")
    if a.out:
        save_json(a.out, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
