"""Mesh pictures and delta histograms."""

from __future__ import annotations

import os

import numpy as np
import pytest
from matplotlib.collections import LineCollection

from hetmesh.errors import OptionError, OutputError
from hetmesh.mesh import Mesh
from hetmesh.plot import delta_histogram_figure, mesh_figure, plot_delta_histogram, plot_mesh

PNG = b"\x89PNG\r\n\x1a\n"


def graded_mesh(n: int = 9) -> Mesh:
    x, y = np.meshgrid(np.linspace(0, 2, n), np.linspace(0, 1, n))
    points = np.column_stack([x.ravel(), y.ravel()])
    j, i = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (j * n + i).ravel()
    tris = np.concatenate([np.column_stack([a, a + 1, a + n + 1]),
                           np.column_stack([a, a + n + 1, a + n])])
    c = points[tris].mean(axis=1)
    metal = points[:, 0] / 2
    bottom = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    middle = np.column_stack([np.arange(n // 2, n * n - n, n), np.arange(n // 2 + n, n * n, n)])
    return Mesh(points, tris, regions=(c[:, 0] > 1).astype(int),
                facets=np.concatenate([bottom, middle]),
                facet_markers=np.r_[np.ones(len(bottom)), np.full(len(middle), 2)],
                point_data={"ceramic": 1 - metal, "metal": metal},
                cell_data={"delta": np.linspace(0, 0.06, len(tris))})


def test_plot_mesh_writes_png(tmp_path):
    path = plot_mesh(graded_mesh(), tmp_path / "mesh.png", title="graded", interface_markers=[2])
    assert path == tmp_path / "mesh.png"
    data = path.read_bytes()
    assert data.startswith(PNG) and len(data) > 5000
    assert os.listdir(tmp_path) == ["mesh.png"]


def test_plot_mesh_other_formats(tmp_path):
    svg = plot_mesh(graded_mesh(), tmp_path / "m.svg", show_edges=False).read_text()
    assert svg.lstrip().startswith("<?xml")
    assert plot_mesh(graded_mesh(), tmp_path / "m.pdf").read_bytes().startswith(b"%PDF")


def test_mesh_figure_content():
    fig = mesh_figure(graded_mesh(), title="t", interface_markers=[2])
    ax, cax = fig.axes
    assert cax.get_ylabel() == "metal"  # default: the last constituent
    assert ax.get_title() == "t" and ax.get_aspect() == 1.0
    red = [c for c in ax.collections if isinstance(c, LineCollection)
           and np.allclose(c.get_colors()[0], (1, 0, 0, 1))]
    assert len(red) == 1 and len(red[0].get_segments()) == 8
    assert ax.lines  # the triplot edges


def test_mesh_figure_data_choice():
    mesh = graded_mesh()
    assert mesh_figure(mesh, data="ceramic").axes[1].get_ylabel() == "ceramic"
    with pytest.raises(OptionError, match="no point data 'gold'.*ceramic, metal"):
        mesh_figure(mesh, data="gold")
    bare = Mesh(mesh.points, mesh.triangles, regions=mesh.regions)
    assert mesh_figure(bare, show_edges=False).axes[1].get_ylabel() == "region"


def test_plot_delta_histogram_writes_png(tmp_path):
    mesh = graded_mesh()
    path = plot_delta_histogram(mesh, tmp_path / "delta.png", threshold=0.05,
                                other=np.random.default_rng(0).random(500) * 0.04)
    assert path.read_bytes().startswith(PNG)
    assert os.listdir(tmp_path) == ["delta.png"]


def test_delta_histogram_fractions_and_threshold():
    delta = np.array([0.01, 0.01, 0.02, 0.07])
    fig = delta_histogram_figure(delta, threshold=0.05, other=np.array([0.03, 0.04]),
                                 bins=np.linspace(0, 0.08, 9), title="Fig. 6")
    ax = fig.axes[0]
    assert ax.get_title() == "Fig. 6" and ax.get_ylabel() == "fraction of elements"
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert texts[0] == "adaptive (4 elements)" and texts[1] == "uniform (2 elements)"
    assert "0.05" in texts[2]
    assert any(np.allclose(line.get_xdata(), 0.05) for line in ax.lines)
    # the first histogram's outline: heights are fractions of elements
    outline = ax.patches[1].get_xy()
    heights = outline[1:-1:2, 1]
    np.testing.assert_allclose(heights, [0, 0.5, 0.25, 0, 0, 0, 0, 0.25])


def test_delta_histogram_inputs():
    mesh = graded_mesh()
    fig = delta_histogram_figure({"a": mesh, "b": mesh.cell_data["delta"] / 2}, threshold=0.05)
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert texts[:2] == ["a (128 elements)", "b (128 elements)"]
    with pytest.raises(OptionError, match="threshold"):
        delta_histogram_figure(mesh, threshold=0)
    with pytest.raises(OptionError, match="no cell data 'delta'"):
        delta_histogram_figure(Mesh(mesh.points, mesh.triangles), threshold=0.1)


def test_unknown_image_format(tmp_path):
    with pytest.raises(OutputError, match=r"unknown image format '\.xyz'"):
        plot_mesh(graded_mesh(), tmp_path / "m.xyz")
    with pytest.raises(OutputError, match="cannot write"):
        plot_delta_histogram(np.ones(3) * 0.01, tmp_path / "no" / "h.png", threshold=0.05)
    assert not os.listdir(tmp_path)


@pytest.mark.parametrize("threshold,top", [(0.05, 0.0499), (0.03, 0.0299999), (0.1, 0.14),
                                           (0.003, 0.0028)])
def test_delta_histogram_bins_have_an_edge_on_the_threshold(threshold, top):
    from hetmesh.plot import bin_edges

    rng = np.random.default_rng(1)
    d = np.r_[rng.uniform(0, top, 400), top]
    edges = bin_edges([("a", d)], threshold, None)
    assert np.isclose(edges, threshold, rtol=0, atol=1e-15).sum() == 1
    assert edges[0] == 0 and edges[-1] > max(top, threshold) and 20 <= len(edges) - 1 <= 60
    # the bars right of the threshold hold exactly the elements at or above it
    counts, _ = np.histogram(d, edges)
    k = int(np.flatnonzero(np.isclose(edges, threshold, rtol=0, atol=1e-15))[0])
    assert counts[k:].sum() == (d >= threshold).sum()
    fig = delta_histogram_figure(d, threshold=threshold)  # drawn on those edges
    assert fig.axes[0].get_xlim()[1] == pytest.approx(edges[-1])


def test_mesh_figure_axes_carry_the_model_units_and_a_legend_for_interfaces():
    fig = mesh_figure(graded_mesh(), interface_markers=[2], units="mm",
                      constituents=["ceramic", "metal"])
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (mm)", "y (mm)")
    assert fig.axes[1].get_ylabel() == "metal (volume fraction)"
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [
        "interfaces and material discontinuities"]
    ax = mesh_figure(graded_mesh()).axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x", "y") and not mesh_figure(
        graded_mesh()).legends


def test_point_labels_of_close_points_do_not_overlap():
    from hetmesh.plot import label_points, new_figure

    fig = new_figure(7, 3)
    ax = fig.add_subplot()
    xy = np.array([[6.0, 0.0], [7.0, 0.0], [15.0, 8.0], [15.0, 9.0], [45.0, 8.0]])
    ax.plot(xy[:, 0], xy[:, 1], "o")
    ax.set_xlim(0, 60)
    ax.set_ylim(-2, 20)
    label_points(ax, xy, ["Q1", "P1", "P2", "Q5", "P5"])
    fig.canvas.draw()
    boxes = [t.get_window_extent() for t in ax.texts]
    assert len(boxes) == 5
    for i in range(5):
        for j in range(i + 1, 5):
            assert not boxes[i].overlaps(boxes[j]), (ax.texts[i].get_text(),
                                                      ax.texts[j].get_text())
