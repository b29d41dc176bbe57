"""The measurements of a report: one function per kind of run, each returning plain records.

Nothing here formats text; :mod:`hetmesh.reproduce.report` renders the records. A run that
fails with a :class:`~hetmesh.errors.HetmeshError` is recorded with its message (measure,
never assert) so that the rest of the report still appears.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import HetmeshError
from ..metrics import MeshStats
from .paper import Case

__all__ = ["MeshRun", "PeerRun", "CaseRun", "mesh_pair", "uniform_like",
           "draw_figures", "run_peer", "case_record"]

log = logging.getLogger(__name__)


@dataclass
class MeshRun:
    """Statistics and wall time (seconds) of one hetmesh mesh."""

    stats: MeshStats
    seconds: float


@dataclass
class PeerRun:
    """A peer meeting a threshold (:func:`hetmesh.peers.search`), or its error message."""

    peer: str
    stats: MeshStats | None = None
    seconds: float = math.nan
    search_seconds: float = math.nan
    s: float = math.nan
    tries: int = 0
    error: str | None = None


@dataclass
class CaseRun:
    """Everything measured for one model at one threshold."""

    case: str
    threshold: float
    n_iso: float = math.nan
    adaptive: MeshRun | None = None
    uniform: MeshRun | None = None
    error: str | None = None
    mesh_figure: str | None = None
    histogram: str | None = None
    histogram_uniform_elements: int | None = None
    peers: dict[str, PeerRun] = field(default_factory=dict)

    @property
    def ratio(self) -> float:
        """Adaptive / uniform elements (nan if either is missing)."""
        if self.adaptive is None or self.uniform is None:
            return math.nan
        return self.adaptive.stats.n_elements / self.uniform.stats.n_elements


def _timed(func, *args, **kwargs):
    t0 = time.perf_counter()
    out = func(*args, **kwargs)
    return out, time.perf_counter() - t0


def mesh_pair(model, threshold: float):
    """hetmesh's adaptive mesh and uniform baseline of ``model``: ``(adaptive Result,
    seconds, uniform Result, seconds)``."""
    from ..tri.pipeline import generate
    from ..tri.uniform import uniform

    adaptive, t_a = _timed(generate, model, threshold)
    uni, t_u = _timed(uniform, model, threshold)
    return adaptive, t_a, uni, t_u


def uniform_like(model, threshold: float, n_elements: int, *, tol: float = 0.05,
                 tries: int = 4) -> np.ndarray:
    """delta(T) over a uniform quality mesh of about ``n_elements`` elements (the paper's
    Figs. 6 and 9 compare the adaptive mesh with a uniform one of the same size).

    ``model`` is the model as meshed (discontinuities embedded). The edge length starts from
    equilateral elements tiling the area, ``h = sqrt(4 A / (sqrt(3) n))``, and is corrected
    by the square root of the count ratio until within ``tol``.
    """
    from ..tri.pipeline import prepare
    from ..tri.refine import evaluate
    from ..tri.uniform import uniform_at

    ctx, frame = prepare(model, threshold, None, gradation=0.0)  # uniform: sizes not used
    h = math.sqrt(4.0 * model.domain.area / (math.sqrt(3.0) * max(int(n_elements), 1)))
    for _ in range(tries):
        ws, tris = uniform_at(ctx, h / frame.scale)
        ratio = len(tris) / n_elements
        if abs(ratio - 1.0) <= tol:
            break
        h *= math.sqrt(ratio)
    _, delta = evaluate(ctx, ws, tris, "vertices")
    return delta


def draw_figures(out: Path, name: str, threshold: float, adaptive, *, histogram: bool,
                 histogram_delta: np.ndarray | None = None) -> tuple[str, str | None]:
    """The mesh picture (coloured by composition, interfaces and discontinuities in red) and,
    if ``histogram``, delta histograms of the adaptive mesh against ``histogram_delta``.
    Returns the paths relative to ``out``."""
    from ..plot import interface_markers, plot_delta_histogram, plot_mesh

    figdir = out / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    stem = f"{name}_{threshold:g}"
    mesh_rel = f"figures/{stem}_mesh.png"
    meshed = adaptive.model
    plot_mesh(adaptive.mesh, out / mesh_rel, interface_markers=interface_markers(meshed),
              title=f"{name}: adaptive mesh, delta_0 = {threshold:g} "
                    f"({adaptive.stats.n_elements} elements)")
    hist_rel = None
    if histogram and histogram_delta is not None:
        hist_rel = f"figures/{stem}_delta.png"
        plot_delta_histogram({"adaptive": adaptive.mesh.cell_data["delta"],
                              "uniform": histogram_delta}, out / hist_rel, threshold=threshold,
                             title=f"{name}: delta over the elements, delta_0 = {threshold:g}")
    return mesh_rel, hist_rel


def run_peer(peer: str, model, threshold: float) -> PeerRun:
    """:func:`hetmesh.peers.search` as a record (its error message if it fails)."""
    from .. import peers

    try:
        r = peers.search(peer, model, threshold)
    except HetmeshError as exc:
        log.warning("%s at delta_0 = %g: %s", peer, threshold, exc)
        return PeerRun(peer, error=str(exc).splitlines()[0])
    return PeerRun(peer, stats=r.stats, seconds=r.seconds, search_seconds=r.search_seconds,
                   s=r.s, tries=len(r.trace))


def mesh_record(out: Path, case: Case, threshold: float, model, quick: bool,
                 installed: list[str], step, figures: list[Path]) -> CaseRun:
    """Adaptive + uniform meshes, N_iso, figures and peers of one model at one threshold.

    ``step(stage)`` is called before every peer's run; the figures written are appended to
    ``figures``. A failing mesh is recorded in the returned :class:`CaseRun`, not raised.
    """
    from ..density import n_iso

    record = CaseRun(case.name, threshold)
    record.n_iso = float(n_iso(model.material, model.domain, threshold))
    try:
        adaptive, t_a, uni, t_u = mesh_pair(model, threshold)
    except HetmeshError as exc:
        record.error = str(exc).splitlines()[0]
        log.warning("%s at delta_0 = %g: %s", case.name, threshold, record.error)
        for _ in installed:
            step(f"{case.name} delta_0={threshold:g}: skipped")
        return record
    record.adaptive = MeshRun(adaptive.stats, t_a)
    record.uniform = MeshRun(uni.stats, t_u)
    hist = quick or threshold in case.histogram_thresholds
    delta_u = None
    if hist:
        delta_u = uniform_like(adaptive.model, threshold, adaptive.stats.n_elements)
        record.histogram_uniform_elements = int(len(delta_u))
    record.mesh_figure, record.histogram = draw_figures(out, case.name, threshold, adaptive,
                                                        histogram=hist, histogram_delta=delta_u)
    figures += [out / p for p in (record.mesh_figure, record.histogram) if p]
    for peer in installed:
        step(f"{case.name} delta_0={threshold:g}: {peer}")
        record.peers[peer] = run_peer(peer, adaptive.model, threshold)
    return record


def case_record(out: str, case: str, threshold: float, quick: bool,
                peers: list[str]) -> CaseRun:
    """Everything the report measures for one model at one threshold, as a plain function
    of plain data (the output directory, the case's name, the threshold, quick or not, the
    peers to run), so that it runs the same in this process and on a Dask worker
    (``hetmesh reproduce --workers/--scheduler``; the figures go to ``out/figures``, which
    on a cluster must be a file system the workers share).

    Returns the :class:`CaseRun` (statistics, times, figure paths, peers' results); a
    failing mesh is recorded in it, not raised.
    """
    from ..io.model import example_path, load_model
    from .paper import CASES

    model = load_model(example_path(case))
    return mesh_record(Path(out), CASES[case], float(threshold), model, bool(quick),
                        list(peers), lambda stage: None, [])
