"""Figures: the mesh coloured by composition, and histograms of delta over the elements.

Figures are built with :class:`matplotlib.figure.Figure` on an Agg canvas, never through
``pyplot``: no global state, no GUI backend, nothing to ``show``, safe in threads. The
``*_figure`` functions return the Figure (for tests and notebooks); the ``plot_*`` functions
save it atomically (:func:`hetmesh.io.atomic.atomic_path`) in the format of the extension
(``.png``, ``.pdf``, ``.svg``, ...) and return the path.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

from .errors import OptionError, OutputError
from .io.atomic import atomic_path
from .mesh import Mesh

__all__ = ["mesh_figure", "plot_mesh", "delta_histogram_figure", "plot_delta_histogram",
           "interface_markers", "label_points", "axis_labels", "new_figure", "figure_size",
           "save_figure", "bin_edges"]

log = logging.getLogger(__name__)


def interface_markers(model) -> list[int]:
    """Edge markers (curve index + 1, as in :class:`~hetmesh.mesh.Mesh`) of the interface
    curves of ``model``: its own interfaces and, for the model as meshed
    (``Result.model``), the embedded material discontinuities. Drawn red by the figures."""
    return [i + 1 for i, info in enumerate(model.domain.curves) if info.kind == "interface"]

DeltaLike = np.ndarray | Sequence[float] | Mesh


# -- the mesh ----------------------------------------------------------------------------

def new_figure(width: float, height: float) -> Figure:
    """A Matplotlib figure of ``width`` x ``height`` inches drawn off screen (Agg), with the
    constrained layout; no pyplot state is involved."""
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _point_values(mesh: Mesh, data: str | None) -> tuple[str, np.ndarray] | None:
    """The name and values of the point data to colour by (None if there is none)."""
    if data is None:
        scalars = [k for k, v in mesh.point_data.items() if np.ndim(v) == 1]
        if not scalars:
            return None
        data = scalars[-1]
    if data not in mesh.point_data:
        known = ", ".join(mesh.point_data) or "none"
        raise OptionError(f"no point data {data!r} to plot (available: {known})")
    values = np.asarray(mesh.point_data[data], np.float64)
    if values.ndim != 1:
        raise OptionError(f"point data {data!r} has shape {values.shape}; only scalars can be "
                          f"plotted")
    return data, values


def figure_size(mesh: Mesh) -> tuple[float, float]:
    """``(width, height)`` in inches of a mesh figure: 7 wide, as tall as the mesh's aspect
    asks (between 2.5 and 10)."""
    span = np.ptp(mesh.points, axis=0) if mesh.n_points else np.ones(2)
    aspect = float(span[1] / span[0]) if span[0] > 0 else 1.0
    width = 7.0
    return width, float(np.clip(width * aspect * 0.85 + 0.6, 2.5, 10.0))


def _edge_segments(mesh: Mesh, select: np.ndarray) -> np.ndarray:
    return mesh.points[mesh.edges[select]]


def axis_labels(ax, units: str = "") -> None:
    """``x``/``y`` axis labels with the model's length unit, e.g. ``x (mm)``."""
    unit = f" ({units.strip()})" if units and units.strip() else ""
    ax.set_xlabel(f"x{unit}")
    ax.set_ylabel(f"y{unit}")


def label_points(ax, xy: np.ndarray, names: Sequence[str], *, color: str = "cyan",
                 fontsize: float = 7.0, offset: float = 5.0) -> None:
    """Annotate points with names, each label on the side away from its nearest
    neighbour (so that labels of close points, e.g. probes 1 mm apart, do not overlap).

    ``offset`` is in typographic points; labels get a thin dark outline for contrast.
    """
    from matplotlib import patheffects

    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    if not len(xy):
        return
    span = float(np.ptp(xy, axis=0).max()) if len(xy) > 1 else 1.0
    for i, name in enumerate(names):
        d = xy[i] - xy
        dist = np.hypot(d[:, 0], d[:, 1])
        dist[i] = np.inf
        j = int(np.argmin(dist))
        if len(xy) > 1 and dist[j] < 0.15 * max(span, 1e-300):
            u = d[j] / max(dist[j], 1e-300)  # away from the nearest neighbour
        else:
            u = np.array([0.7071, 0.7071])
        ha = "left" if u[0] > 0.3 else "right" if u[0] < -0.3 else "center"
        va = "bottom" if u[1] > 0.3 else "top" if u[1] < -0.3 else "center"
        ax.annotate(name, tuple(xy[i]), xytext=(offset * u[0], offset * u[1]),
                    textcoords="offset points", ha=ha, va=va, fontsize=fontsize, color=color,
                    path_effects=[patheffects.withStroke(linewidth=1.5, foreground="black")])


def mesh_figure(mesh: Mesh, *, data: str | None = None, title: str | None = None,
                interface_markers: Iterable[int] = (), show_edges: bool = True,
                units: str = "", constituents: Iterable[str] = ()) -> Figure:
    """The mesh coloured by a point data array (Gouraud shading), with its edges.

    Parameters
    ----------
    mesh : Mesh
    data : str, optional
        Name of a scalar ``mesh.point_data`` array; by default the last one (the last
        constituent, e.g. ``"metal"``). Without point data the triangles are coloured by
        region.
    title : str, optional
    interface_markers : iterable of int
        Edge markers whose constrained edges are drawn thick and red (interfaces).
    show_edges : bool
        Draw the triangles' edges in thin dark lines.
    units : str
        The model's length unit, for the axis labels (``x (mm)``).
    constituents : iterable of str
        The model's constituents: a colour bar of one of them says ``(volume fraction)``.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = mesh_figure(mesh, data="metal", interface_markers=[5])   # doctest: +SKIP
    """
    interface_markers = list(interface_markers)
    constituents = tuple(constituents)
    width, height = figure_size(mesh)
    legend = bool(len(mesh.edges)) and bool(np.isin(mesh.edge_markers, interface_markers).any())
    fig = new_figure(width, height + (0.45 if legend else 0.0))  # room for the legend
    ax = fig.add_subplot()
    tri = Triangulation(mesh.points[:, 0], mesh.points[:, 1], mesh.triangles)
    picked = _point_values(mesh, data)
    if picked is None:
        art = ax.tripcolor(tri, facecolors=mesh.regions.astype(float), cmap="tab10")
        label = "region"
    else:
        label, values = picked
        art = ax.tripcolor(tri, values, shading="gouraud", cmap="viridis")
        if label in constituents:
            label = f"{label} (volume fraction)"
    fig.colorbar(art, ax=ax, label=label, shrink=0.9)
    if show_edges:
        lw = 0.3 if mesh.n_elements < 20_000 else 0.08
        ax.triplot(tri, color="0.15", lw=lw, alpha=0.8)
    if _draw_constrained_edges(ax, mesh, interface_markers):
        fig.legend(loc="outside lower center", fontsize=8, frameon=False)
    ax.set_aspect("equal")
    axis_labels(ax, units)
    if title:
        ax.set_title(title)
    return fig


def _draw_constrained_edges(ax, mesh: Mesh, interface_markers: Iterable[int]) -> bool:
    """Boundary/interface edges: dark outline, the ``interface_markers`` thick and red
    (labelled for a legend). Returns whether red edges were drawn."""
    if not len(mesh.edges):
        return False
    red = np.isin(mesh.edge_markers, np.fromiter(interface_markers, dtype=np.int64))
    if (~red).any():
        ax.add_collection(LineCollection(_edge_segments(mesh, ~red), colors="0.05", linewidths=0.8))
    if red.any():
        ax.add_collection(LineCollection(_edge_segments(mesh, red), colors="red", linewidths=2.0,
                                         label="interfaces and material discontinuities"))
    return bool(red.any())


def plot_mesh(mesh: Mesh, path: str | Path, *, data: str | None = None, title: str | None = None,
              interface_markers: Iterable[int] = (), show_edges: bool = True,
              dpi: int = 150, units: str = "", constituents: Iterable[str] = ()) -> Path:
    """Save :func:`mesh_figure` to ``path`` (atomically; format from the extension).

    Returns
    -------
    Path
        ``path``.

    Examples
    --------
    >>> plot_mesh(mesh, "plate.png", title="plate, delta_0 = 0.05")   # doctest: +SKIP
    PosixPath('plate.png')
    """
    fig = mesh_figure(mesh, data=data, title=title, interface_markers=interface_markers,
                      show_edges=show_edges, units=units, constituents=constituents)
    return save_figure(fig, path, dpi)


# -- delta histograms --------------------------------------------------------------------

def _delta_values(delta: DeltaLike, what: str) -> np.ndarray:
    if isinstance(delta, Mesh):
        if "delta" not in delta.cell_data:
            raise OptionError(f"{what}: the mesh has no cell data 'delta'")
        delta = delta.cell_data["delta"]
    d = np.asarray(delta, np.float64).ravel()
    return d[np.isfinite(d)]


def _series(delta, other, labels: Sequence[str]) -> list[tuple[str, np.ndarray]]:
    """``[(label, finite delta values)]`` from an array/Mesh (+ other) or a mapping."""
    if isinstance(delta, Mapping):
        return [(str(k), _delta_values(v, str(k))) for k, v in delta.items()]
    items = [delta] if other is None else [delta, other]
    if len(labels) < len(items):
        raise OptionError(f"need {len(items)} labels for the delta histograms, got {len(labels)}")
    return [(labels[i], _delta_values(d, labels[i])) for i, d in enumerate(items)]


def bin_edges(series: list[tuple[str, np.ndarray]], threshold: float, bins) -> np.ndarray:
    """Bins from 0 whose edges fall on the threshold: ``k`` equal bins up to delta_0 (about
    ``bins`` in all over the data), then as many of the same width as the values above it
    need; no bin straddles delta_0, so the bars left of its line hold the elements below it
    and those right of it the elements at or above it."""
    if bins is not None and np.ndim(bins) == 1:
        return np.asarray(bins, np.float64)
    n = 40 if bins is None else int(bins)
    top = max([threshold] + [float(d.max()) for _, d in series if d.size])
    k = max(4, int(round(n * threshold / (1.05 * top))))
    step = threshold / k
    above = int(np.ceil(max(0.0, 1.05 * top - threshold) / step))
    above = max(above, 1)  # room right of the threshold line
    return np.concatenate([np.linspace(0.0, threshold, k + 1),
                           threshold + step * np.arange(1, above + 1)])


def delta_histogram_figure(delta, *, threshold: float, other: DeltaLike | None = None,
                           labels: Sequence[str] = ("adaptive", "uniform"), bins=None,
                           title: str | None = None) -> Figure:
    """Histogram(s) of delta(T) over the elements, as the fraction of elements per bin.

    Like the paper's Fig. 6: one histogram per mesh on shared bins, and a vertical line at
    the threshold delta_0.

    Parameters
    ----------
    delta : array, Mesh or mapping of label to array/Mesh
        delta of every element (a Mesh gives its ``cell_data["delta"]``). A mapping draws
        one histogram per entry and ignores ``other`` and ``labels``.
    threshold : float
        delta_0, drawn as a vertical line.
    other : array or Mesh, optional
        A second mesh's delta (e.g. the uniform baseline).
    labels : sequence of str
        Legend labels of ``delta`` and ``other``.
    bins : int or array, optional
        About how many bins (default 40, from 0 to 1.05 x the largest value or the
        threshold, with a bin edge on the threshold) or the bin edges.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = delta_histogram_figure(adaptive.mesh, other=uniform.mesh,  # doctest: +SKIP
    ...                              threshold=0.05)
    """
    if not (np.isfinite(threshold) and threshold > 0):
        raise OptionError(f"threshold must be a positive number, got {threshold!r}")
    series = _series(delta, other, labels)
    edges = bin_edges(series, float(threshold), bins)
    fig = new_figure(7.0, 4.2)
    ax = fig.add_subplot()
    for i, (label, d) in enumerate(series):
        if not d.size:
            log.warning("no finite delta values for %r; nothing to draw", label)
            continue
        color = f"C{i}"
        w = np.full(d.size, 1.0 / d.size)
        ax.hist(d, bins=edges, weights=w, histtype="stepfilled", alpha=0.35, color=color)
        ax.hist(d, bins=edges, weights=w, histtype="step", lw=1.5, color=color,
                label=f"{label} ({d.size} elements)")
    ax.axvline(threshold, color="red", ls="--", lw=1.5,
               label=f"threshold $\\delta_0$ = {threshold:g}")
    ax.set_xlabel(r"$\delta(T)$")
    ax.set_ylabel("fraction of elements")
    ax.set_xlim(edges[0], edges[-1])
    ax.legend()
    if title:
        ax.set_title(title)
    return fig


def plot_delta_histogram(delta, path: str | Path, *, threshold: float,
                         other: DeltaLike | None = None,
                         labels: Sequence[str] = ("adaptive", "uniform"), bins=None,
                         title: str | None = None, dpi: int = 150) -> Path:
    """Save :func:`delta_histogram_figure` to ``path`` (atomically; format from the extension).

    Returns
    -------
    Path
        ``path``.

    Examples
    --------
    >>> plot_delta_histogram({"adaptive": a.mesh, "uniform": u.mesh}, "delta.png",
    ...                      threshold=0.05)   # doctest: +SKIP
    PosixPath('delta.png')
    """
    fig = delta_histogram_figure(delta, threshold=threshold, other=other, labels=labels,
                                 bins=bins, title=title)
    return save_figure(fig, path, dpi)


# -- saving ------------------------------------------------------------------------------

def save_figure(fig: Figure, path: str | Path, dpi: int) -> Path:
    """Save atomically in the format of the extension, then release the figure."""
    path = Path(path)
    known = fig.canvas.get_supported_filetypes()
    fmt = path.suffix[1:].lower()
    if fmt not in known:
        names = ", ".join("." + k for k in sorted(known))
        raise OutputError(f"unknown image format {path.suffix!r} for {path} (known: {names})")
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, dpi=dpi)
    finally:
        fig.clear()
    log.info("wrote %s", path)
    return path
