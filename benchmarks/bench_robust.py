#!/usr/bin/env python
"""hetmesh robustness benchmark: seeded random models, an independent check, Gmsh for scale.

    PYTHONPATH=src python benchmarks/bench_robust.py --jobs 2 --json robust.json
    PYTHONPATH=src python benchmarks/bench_robust.py --quick --no-peers      # ~1 min
    PYTHONPATH=src python benchmarks/bench_robust.py --only 17 --only tanh    # some cases

Every model of ``hetmesh.testing.robust_suite(n)`` (48 seeded random models: star, arc and
L/U-shaped domains, holes, interfaces, far from the origin; tanh fronts, power laws with
p < 1, S-FGM, Gaussians, sines, kinks) at each of its thresholds, and the repository's
2D examples at delta_0 = 0.1 and 0.05, are meshed with ``hetmesh.generate`` (default method), each
run in its own worker process with a wall-clock limit, and checked with
``hetmesh.testing.independent_check``. A run that raises, times out, dies or fails the check
is a failure: a row of the tables, never a crash of the benchmark.

Tables
  a. per family: runs, verified, failed, timeouts, CVT fallbacks per cause
     (``result.options["fallbacks"]``), runs with warnings, times; then every failure with
     the first line of its error.
  b. quality and economy against Gmsh: ``hetmesh.peers.search("gmsh", result.model, delta_0)``
     (Frontal-Delaunay fed s delta_0/|grad f|, s lowered until its delta_max < delta_0) on
     every verified run: Ne and q_avg of both, the element ratio, the q_avg difference, q_min;
     with summary lines.

Output order is the order of the cases, whatever order the workers finish in (progress lines
go to stderr). See benchmarks/README.md.
"""

from __future__ import annotations

import os

# one BLAS thread per worker: the workers are the parallelism (set before numpy loads)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import logging  # noqa: E402
import math  # noqa: E402
import multiprocessing as mp  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402
from multiprocessing.connection import wait as wait_conns  # noqa: E402
from pathlib import Path  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_core import (  # noqa: E402
    ROOT,
    environment,
    err_text,
    fmt,
    limit_memory,
    median,
    print_table,
    save_json,
)

import hetmesh  # noqa: E402
from hetmesh import peers  # noqa: E402
from hetmesh.testing import FAMILIES, independent_check, random_model  # noqa: E402

EXAMPLES = ROOT / "examples"
EXAMPLE_THRESHOLDS = (0.1, 0.05)
N_MODELS = 48
QUICK_MODELS = 14
TIMEOUT = 120.0          # seconds per hetmesh run (generate + check)
PEER_TIMEOUT = 300.0     # seconds per Gmsh search
BUDGET_FACTOR = 20       # element budget: this times hetmesh's a-priori estimate ...
BUDGET_MIN = 100_000     # ... but at least this many elements
Q_TOL = 0.01             # q_avg within this of Gmsh's counts as "as good"
Q_MIN = 0.6


# ----------------------------------------------------------------------------- cases
def build_cases(n: int, first_seed: int, quick: bool, examples: bool, only) -> list[dict]:
    """The runs, in output order: random models by seed (each at its thresholds; with
    ``quick`` only the finer one), then the examples."""
    cases = []
    for seed in range(first_seed, first_seed + n):
        rm = random_model(seed)
        thresholds = rm.thresholds[-1:] if quick else rm.thresholds
        for t in thresholds:
            cases.append(dict(id=f"{rm.name} {t:g}", name=rm.name, family=rm.family, seed=seed,
                              threshold=t, tags=list(rm.kind), toml=rm.toml, path=None))
    if examples:
        for p in sorted(EXAMPLES.glob("*.toml")):
            if "\n[solid]" in p.read_text(encoding="utf-8"):
                continue  # a 3D model: the tetrahedral benchmarks (bench_tet.py) cover it
            for t in (EXAMPLE_THRESHOLDS[:1] if quick else EXAMPLE_THRESHOLDS):
                cases.append(dict(id=f"{p.stem} {t:g}", name=p.stem, family="example", seed=None,
                                  threshold=t, tags=[], toml=None, path=str(p)))
    if only:
        cases = [c for c in cases if any(_selected(c, s) for s in only)]
    return cases


def _selected(case: dict, sel: str) -> bool:
    s = sel.strip().lower()
    if s.isdigit():
        return case["seed"] == int(s)
    return s in (case["family"], "examples" if case["family"] == "example" else "random") \
        or s in case["name"].lower() or s in case["tags"]


# ----------------------------------------------------------------------------- worker
class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record):
        msg = f"{record.name}: {record.getMessage()}".splitlines()[0][:300]
        if msg not in self.messages:
            self.messages.append(msg)


def _load(case: dict):
    if case["path"]:
        return hetmesh.load_model(case["path"])
    with tempfile.TemporaryDirectory(prefix="bench-robust-") as tmp:
        p = Path(tmp) / f"{case['name']}.toml"
        p.write_text(case["toml"], encoding="utf-8")
        return hetmesh.load_model(p)


def _fallbacks(result) -> list[dict]:
    out = list((getattr(result, "options", None) or {}).get("fallbacks") or [])
    for h in getattr(result, "history", None) or []:
        if isinstance(h, dict) and "cause" in h and h not in out:
            out.append(h)
    return [f if isinstance(f, dict) else {"cause": str(f)} for f in out]


_FALLBACK_RE = re.compile(r"placement failed \((.*)\); meshing from the CVT placement")


def worker(case: dict, opts: dict, conn) -> None:
    """One case in a child process: send ("hetmesh", record), then ("peer", record)."""
    limit_memory(opts["mem_limit_gb"])
    logging.getLogger("hetmesh").setLevel(logging.WARNING)
    log = _Collect()
    logging.getLogger().addHandler(log)
    logging.getLogger().setLevel(logging.WARNING)
    py_warnings: list[str] = []

    def showwarning(message, category, filename, lineno, file=None, line=None):
        text = f"{category.__name__}: {message}"
        if text not in py_warnings:
            py_warnings.append(text)

    warnings.showwarning = showwarning
    warnings.simplefilter("always")
    rec: dict = {"id": case["id"]}
    result = None
    try:
        t = time.perf_counter()
        model = _load(case)
        rec["load_s"] = time.perf_counter() - t
    except Exception as e:
        rec.update(status="invalid-model", error=err_text(e), error_class=type(e).__name__)
        conn.send(("hetmesh", rec))
        conn.send(("peer", None))
        return
    try:
        from hetmesh.density import estimate_elements

        est = float(estimate_elements(model.material, model.domain, case["threshold"],
                                      model.domain.diameter / 8.0))
        budget = opts["max_elements"] or (max(BUDGET_MIN, int(BUDGET_FACTOR * est))
                                          if math.isfinite(est) else 5_000_000)
        rec.update(estimate=est, max_elements=budget)
        times = []
        for _ in range(max(1, opts["repeats"])):
            t = time.perf_counter()
            result = hetmesh.generate(model, case["threshold"], max_elements=budget)
            times.append(time.perf_counter() - t)
        rec.update(times=times, time=median(times), stats=result.stats.as_dict(),
                   method=result.options.get("method"), rounds=len(result.history),
                   placements=result.options.get("placements"),
                   fallbacks=_fallbacks(result),
                   timings={k: v for k, v in result.timings.items() if not k.endswith("_s")})
        t = time.perf_counter()
        problems = independent_check(result, model, case["threshold"])
        rec["check_s"] = time.perf_counter() - t
        rec["problems"] = problems
        rec["status"] = "verified" if not problems else "check-failed"
        if problems:
            rec["error"] = "check: " + problems[0]
    except Exception as e:
        rec.update(status="error", error=err_text(e), error_class=type(e).__name__,
                   traceback=traceback.format_exc(limit=-6)[-4000:])
        result = None
    if result is None:  # a fallback that failed too: only its warning tells
        rec["fallbacks"] = [{"cause": m.group(1), "from_warning": True} for m in
                            (_FALLBACK_RE.search(w) for w in log.messages) if m]
    rec["warnings"] = log.messages
    rec["python_warnings"] = py_warnings
    conn.send(("hetmesh", rec))
    if not opts["peers"] or result is None:
        conn.send(("peer", None))
        return
    peer: dict = {}
    try:
        pr = peers.search("gmsh", result.model, case["threshold"])
        peer = dict(s=pr.s, stats=pr.stats.as_dict(), seconds=pr.seconds,
                    search_seconds=pr.search_seconds, tries=len(pr.trace),
                    trace=[{k: v for k, v in tr.items()} for tr in pr.trace])
    except Exception as e:
        peer = dict(error=err_text(e))
    conn.send(("peer", peer))


# ----------------------------------------------------------------------------- scheduler
def run_cases(cases: list[dict], opts: dict, jobs: int) -> list[dict]:
    """Run every case in its own process, at most ``jobs`` at a time; kill a case at its
    time limit (hetmesh: ``opts['timeout']``, then Gmsh: ``opts['peer_timeout']``)."""
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    records: list[dict | None] = [None] * len(cases)
    peers_out: list[dict | None] = [None] * len(cases)
    pending = list(range(len(cases)))
    running: dict = {}  # conn -> dict(i, proc, phase, deadline, t0)
    done = 0
    t_start = time.perf_counter()
    while pending or running:
        while pending and len(running) < jobs:
            i = pending.pop(0)
            recv, send = ctx.Pipe(duplex=False)
            proc = ctx.Process(target=worker, args=(cases[i], opts, send), daemon=True)
            proc.start()
            send.close()
            now = time.perf_counter()
            running[recv] = dict(i=i, proc=proc, phase="hetmesh", t0=now,
                                 deadline=now + opts["timeout"])
        ready = wait_conns(list(running), timeout=0.25)
        now = time.perf_counter()
        finished = []
        for conn in ready:
            job = running[conn]
            i = job["i"]
            try:
                kind, payload = conn.recv()
            except (EOFError, OSError):
                job["proc"].join(5)
                code = job["proc"].exitcode
                why = (f"worker died (exit code {code}"
                       f"{': killed, out of memory?' if code in (-9, 137) else ''})")
                if job["phase"] == "hetmesh":
                    records[i] = dict(id=cases[i]["id"], status="crashed", error=why,
                                      time=now - job["t0"])
                else:
                    peers_out[i] = dict(error=why)
                finished.append(conn)
                continue
            if kind == "hetmesh":
                records[i] = payload
                job.update(phase="peer", deadline=now + opts["peer_timeout"])
            else:
                peers_out[i] = payload
                finished.append(conn)
        for conn, job in list(running.items()):
            if conn in finished or now < job["deadline"]:
                continue
            i = job["i"]
            if job["phase"] == "hetmesh":
                records[i] = dict(id=cases[i]["id"], status="timeout", time=now - job["t0"],
                                  error=f"timeout: no result after {opts['timeout']:.0f} s")
            else:
                peers_out[i] = dict(error=f"timeout after {opts['peer_timeout']:.0f} s")
            finished.append(conn)
        for conn in finished:
            job = running.pop(conn)
            proc = job["proc"]
            if proc.is_alive():
                proc.terminate()
                proc.join(5)
                if proc.is_alive():
                    proc.kill()
                    proc.join(5)
            else:
                proc.join(5)
            conn.close()
            done += 1
            i = job["i"]
            r = records[i] or {}
            p = peers_out[i]
            line = (f"[{done}/{len(cases)} {time.perf_counter() - t_start:5.0f} s] "
                    f"{cases[i]['id']}: {r.get('status')}")
            if r.get("stats"):
                line += f", {r['stats']['n_elements']:,} elements, {r.get('time', 0):.1f} s"
            if r.get("error"):
                line += f" -- {r['error'][:120]}"
            if p:
                line += (f" | gmsh {p['stats']['n_elements']:,} (s={p['s']:.3f}, "
                         f"{p['search_seconds']:.0f} s)" if "stats" in p else
                         f" | gmsh {p.get('error', '')[:80]}")
            print(line, file=sys.stderr, flush=True)
    out = []
    for c, r, p in zip(cases, records, peers_out):
        rec = dict(c)
        rec.update(r or {"status": "crashed", "error": "no record"})
        rec["gmsh"] = p
        out.append(rec)
    return out


# ----------------------------------------------------------------------------- tables
def _cause_key(cause: str) -> str:
    """A fallback cause without its numbers, so that like causes count together."""
    return re.sub(r"\d+(\.\d+)?(e-?\d+)?", "#", cause)[:120]


def table_families(records: list[dict]) -> dict:
    fams = [f for f in FAMILIES if any(r["family"] == f for r in records)]
    if any(r["family"] == "example" for r in records):
        fams.append("example")
    rows, summary = [], {}
    causes_all: dict[str, int] = {}
    for fam in fams + ["all"]:
        rs = [r for r in records if fam == "all" or r["family"] == fam]
        if not rs:
            continue
        ok = [r for r in rs if r.get("status") == "verified"]
        to = [r for r in rs if r.get("status") == "timeout"]
        failed = [r for r in rs if r.get("status") != "verified"]
        causes: dict[str, int] = {}
        for r in rs:
            for fb in r.get("fallbacks") or []:
                k = _cause_key(str(fb.get("cause", "?")))
                causes[k] = causes.get(k, 0) + 1
        if fam == "all":
            causes_all = causes
        warned = sum(1 for r in rs if r.get("warnings") or r.get("python_warnings"))
        times = [r["time"] for r in rs if r.get("stats")]
        summary[fam] = dict(runs=len(rs), verified=len(ok), failed=len(failed),
                            timeouts=len(to), fallbacks=causes, warned=warned,
                            time_median=median(times), time_total=sum(times))
        rows.append([fam, str(len(rs)), str(len(ok)), str(len(failed)), str(len(to)),
                     str(sum(causes.values())), str(warned), fmt(median(times), ".2f"),
                     fmt(max(times) if times else None, ".1f"), fmt(sum(times), ".1f")])
    print_table("Table a. Robustness per family: hetmesh.generate (default method) + "
                "independent_check",
                ["family", "runs", "verified", "failed", "timeouts", "CVT fallbacks",
                 "warned", "median s", "max s", "total s"], rows,
                notes=["verified = generate() returned and independent_check() found nothing; "
                       "failed = raised, timed out, died or failed the check.",
                       "CVT fallbacks: entries of result.options['fallbacks'] (the layers "
                       "placement abandoned for the CVT one), by cause (from the warning when "
                       "the CVT run failed too); warned = runs that logged a warning or raised a "
                       "Python warning (e.g. numpy's RuntimeWarning), listed below.",
                       "times: generate() wall clock (median of the repeats) of the runs that "
                       "returned."])
    if causes_all:
        print_table("CVT fallbacks by family and cause", ["family", "count", "cause", ""],
                    [[fam, str(v), k] for fam in fams
                     for k, v in sorted(summary[fam]["fallbacks"].items(),
                                        key=lambda kv: (-kv[1], kv[0]))])
    warns: dict[str, list] = {}
    for r in records:
        for w in (r.get("warnings") or []) + (r.get("python_warnings") or []):
            warns.setdefault(_cause_key(w), []).append(r["id"])
    if warns:
        print_table("Warnings (runs that logged or raised them)", ["runs", "warning", ""],
                    [[str(len(v)), f"{k} -- {', '.join(v[:4])}{' ...' if len(v) > 4 else ''}"]
                     for k, v in sorted(warns.items(), key=lambda kv: -len(kv[1]))])
    fails = [r for r in records if r.get("status") != "verified"]
    if fails:
        print_table(f"Failures: {len(fails)} (first line of each error)",
                    ["case", "family", "status: error", ""],
                    [[r["id"], r["family"],
                      f"{r.get('status', '?')}: {(r.get('error') or '')[:200]}"] for r in fails])
    else:
        print("\nNo failures.")
    return summary


def table_peers(records: list[dict], have_gmsh) -> dict:
    rows, pairs = [], []
    for r in records:
        g = r.get("gmsh")
        if r.get("status") != "verified":
            continue
        h = r["stats"]
        if not g:
            rows.append([r["id"], fmt(h["n_elements"]), "gmsh not run"])
            continue
        if "error" in g:
            rows.append([r["id"], fmt(h["n_elements"]), f"gmsh: {g['error'][:100]}"])
            continue
        s = g["stats"]
        ratio = h["n_elements"] / s["n_elements"]
        dq = h["q_avg"] - s["q_avg"]
        pairs.append(dict(id=r["id"], ratio=ratio, dq=dq, q_min=h["q_min"],
                          family=r["family"]))
        rows.append([r["id"], fmt(h["n_elements"]), fmt(s["n_elements"]), fmt(ratio, ".2f"),
                     fmt(h["q_avg"]), fmt(s["q_avg"]), f"{dq:+.3f}", fmt(h["q_min"]),
                     fmt(s["q_min"]), fmt(r["time"], ".2f"), fmt(g["seconds"], ".2f"),
                     f"s={g['s']:.3f} ({g['tries']} tries, {g['search_seconds']:.0f} s)"])
    notes = [f"Gmsh {have_gmsh}: hetmesh.peers.search('gmsh', result.model, δ0): Frontal-"
             "Delaunay, one thread, background field h = min(diam/8, s·δ0/|∇f|) graded 0.3, "
             "s from 1.2 lowered by 0.9 until Gmsh's δmax < δ0, last step bisected twice.",
             "ratio = hetmesh Ne / Gmsh Ne; Δq = q_avg(hetmesh) - q_avg(Gmsh); times: "
             "hetmesh generate(), Gmsh the accepted mesh only (the search time is in the "
             "last column). Only verified hetmesh runs are compared."]
    by_model: dict[str, list] = {}
    for r in records:
        if r.get("status") == "verified":
            by_model.setdefault(r["name"], []).append((r["threshold"], r["stats"]["n_elements"]))
    odd = [f"{name} ({', '.join(f'{n:,} at {t:g}' for t, n in sorted(v, reverse=True))})"
           for name, v in by_model.items()
           if any(n1 > n2 for (t1, n1) in v for (t2, n2) in v if t1 > t2)]
    if odd:
        notes.append("more hetmesh elements at the coarser threshold: " + "; ".join(odd))
    summary = {"compared": len(pairs), "coarser_more_elements": odd}
    if pairs:
        n = len(pairs)
        good_q = sum(p["dq"] >= -Q_TOL for p in pairs)
        fewer = sum(p["ratio"] < 1 for p in pairs)
        qmin = sum(p["q_min"] >= Q_MIN for p in pairs)
        summary.update(q_avg_ok=good_q, fewer_elements=fewer, q_min_ok=qmin,
                       ratio_median=median([p["ratio"] for p in pairs]),
                       ratio_max=max(p["ratio"] for p in pairs),
                       dq_median=median([p["dq"] for p in pairs]),
                       dq_min=min(p["dq"] for p in pairs))
        notes += [f"q_avg >= Gmsh's - {Q_TOL}: {good_q} of {n} runs; fewer elements than Gmsh: "
                  f"{fewer} of {n}; q_min >= {Q_MIN}: {qmin} of {n}.",
                  f"element ratio median {summary['ratio_median']:.2f} (max "
                  f"{summary['ratio_max']:.2f}); Δq_avg median {summary['dq_median']:+.3f} "
                  f"(min {summary['dq_min']:+.3f})."]
        worse = [p["id"] for p in pairs if p["ratio"] >= 1]
        if worse:
            notes.append("not fewer elements: " + ", ".join(worse))
        lowq = [p["id"] for p in pairs if p["dq"] < -Q_TOL]
        if lowq:
            notes.append(f"q_avg below Gmsh's - {Q_TOL}: " + ", ".join(lowq))
    print_table("Table b. Quality and economy against Gmsh (verified runs)",
                ["case", "Ne", "Ne gmsh", "ratio", "q_avg", "q_avg gmsh", "Δq_avg", "q_min",
                 "q_min gmsh", "time s", "gmsh s", "gmsh search"], rows, notes=notes)
    return summary


def stored_peers(path: Path) -> dict:
    """The Gmsh records of an earlier run's ``--json`` file by case id, and the versions
    they were made with."""
    data = json.loads(Path(path).read_text(encoding="utf-8"))
    env = data.get("environment", {})
    return {"runs": {r["id"]: r["gmsh"] for r in data.get("runs", []) if r.get("gmsh")},
            "hetmesh": env.get("git", "?"), "gmsh": env.get("gmsh", "?")}


# ----------------------------------------------------------------------------- main
def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true",
                   help=f"{QUICK_MODELS} random models at their finer threshold only, the "
                        f"examples at {EXAMPLE_THRESHOLDS[0]} only")
    p.add_argument("--models", type=int, help=f"random models (default {N_MODELS}; quick "
                                              f"{QUICK_MODELS})")
    p.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    p.add_argument("--only", action="append",
                   help="run only matching cases: a seed, a family, 'random', 'examples', a "
                        "tag or part of a name (repeatable)")
    p.add_argument("--no-examples", action="store_true", help="random models only")
    p.add_argument("--no-peers", action="store_true", help="skip Gmsh (table b)")
    p.add_argument("--peers-from", type=Path, metavar="JSON",
                   help="table b from the Gmsh figures stored in an earlier run's --json "
                        "(matched by case id; Gmsh is not run): a hetmesh change is compared "
                        "in minutes, not the hour the Gmsh searches take")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    p.add_argument("--repeats", type=int, default=1,
                   help="generate() runs per case, the time is their median (default 1)")
    p.add_argument("--timeout", type=float, default=TIMEOUT,
                   help=f"seconds per hetmesh run before it is a failure (default {TIMEOUT:.0f})")
    p.add_argument("--peer-timeout", type=float, default=PEER_TIMEOUT,
                   help=f"seconds per Gmsh search (default {PEER_TIMEOUT:.0f})")
    p.add_argument("--max-elements", type=int, default=0,
                   help=f"element budget passed to generate() (default: {BUDGET_FACTOR} x "
                        f"the a-priori estimate, at least {BUDGET_MIN:,})")
    p.add_argument("--mem-limit-gb", type=float, default=6.0,
                   help="address-space cap per worker (default 6; 0 = none)")
    p.add_argument("--json", type=Path, help="write every run's record as JSON")
    a = p.parse_args(argv)
    n = a.models if a.models is not None else (QUICK_MODELS if a.quick else N_MODELS)
    have_gmsh = peers.available()["gmsh"]
    use_peers = not a.no_peers and a.peers_from is None and bool(have_gmsh)
    opts = dict(timeout=a.timeout, peer_timeout=a.peer_timeout, peers=use_peers,
                repeats=a.repeats, mem_limit_gb=a.mem_limit_gb, max_elements=a.max_elements)
    env = environment()
    print(f"hetmesh robustness benchmark: hetmesh {env['hetmesh']} ({env.get('git', '?')}), "
          f"Python {env['python']}, numpy {env['numpy']}, gmsh {env['gmsh']}")
    print(f"hetmesh imported from {env['hetmesh_path']}")
    print(f"{env['platform']}, {env['cpu_count']} CPU(s), load average at start "
          f"{' '.join(f'{x:.2f}' for x in env['loadavg_start'])}; {a.jobs} worker(s)"
          f"{' (quick)' if a.quick else ''}")
    t_all = time.perf_counter()
    cases = build_cases(n, a.seed, a.quick, not a.no_examples, a.only)
    budget = (f"{a.max_elements:,}" if a.max_elements else
              f"{BUDGET_FACTOR} x a-priori estimate (>= {BUDGET_MIN:,})")
    print(f"{len(cases)} runs: {n} random models (seeds {a.seed}..{a.seed + n - 1})"
          f"{'' if a.no_examples else ' + examples'}{' (filtered)' if a.only else ''}; "
          f"timeout {a.timeout:.0f} s; element budget {budget}; Gmsh "
          f"{'on' if use_peers else ('off' if a.no_peers else 'not installed')}", flush=True)
    records = run_cases(cases, opts, max(1, a.jobs))
    fam = table_families(records)
    if a.peers_from is not None:
        stored = stored_peers(a.peers_from)
        for r in records:
            r["gmsh"] = stored["runs"].get(r["id"])
        print(f"\nGmsh figures from {a.peers_from} (hetmesh {stored['hetmesh']}, "
              f"gmsh {stored['gmsh']}), matched by case id")
        peer = table_peers(records, stored["gmsh"])
    else:
        peer = table_peers(records, have_gmsh) if use_peers else None
    env["loadavg_end"] = os.getloadavg()
    total = time.perf_counter() - t_all
    print(f"\ntotal benchmark time {total:.0f} s; load average at end "
          f"{' '.join(f'{x:.2f}' for x in env['loadavg_end'])}")
    if a.json:
        save_json(a.json, {"environment": env, "options": {**vars(a), "json": str(a.json),
                                               "peers_from": a.peers_from and str(a.peers_from)},
                           "families": fam, "peers": peer, "runs": records,
                           "total_seconds": total})
    return 0


if __name__ == "__main__":
    sys.exit(main())
