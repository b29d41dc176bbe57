"""Material fields from images: readers, value maps, interpolation, traced domains, label
phases, pixel sampling, model files and their errors."""

from __future__ import annotations

import base64
import struct
import zlib
from pathlib import Path

import imageio.v3 as iio
import nrrd
import numpy as np
import pytest
import shapely
import tifffile

from hetmesh.cli import main
from hetmesh.errors import MaterialError
from hetmesh.io.model import load_model
from hetmesh.io.model3d import Model3D
from hetmesh.material.image import (
    Image,
    channel_map,
    element_pixel_delta,
    image_field,
    linear_map,
    pixel_centres_in_triangles,
    read_image,
    table_map,
)
from hetmesh.tri.geometry.trace import (
    OUTSIDE,
    label_domain,
    label_rings,
    mask_domain,
    pixel_to_xy,
    region_lookup,
    ring_polygons,
    simplify_chains,
    trace_labels,
)


# ---------------------------------------------------------------------------- helpers
def write_vti(path: Path, values: np.ndarray, origin, spacing, fmt: str = "ascii",
              cell: bool = False) -> None:
    """A minimal VTK ImageData file: ascii, inline binary, or zlib-compressed binary."""
    ny, nx = values.shape
    ext = f"0 {nx - (0 if cell else 1)} 0 {ny - (0 if cell else 1)} 0 0"
    v = np.ascontiguousarray(values, "<f4")
    comp = ' compressor="vtkZLibDataCompressor"' if fmt == "zlib" else ""
    if fmt == "ascii":
        text, f = " ".join(f"{x:.9g}" for x in v.ravel()), "ascii"
    elif fmt == "binary":
        raw = v.tobytes()
        text, f = base64.b64encode(struct.pack("<I", len(raw)) + raw).decode(), "binary"
    else:
        raw = zlib.compress(v.tobytes())
        hdr = struct.pack("<4I", 1, v.nbytes, v.nbytes, len(raw))
        text, f = (base64.b64encode(hdr) + base64.b64encode(raw)).decode(), "binary"
    data = "CellData" if cell else "PointData"
    path.write_text(
        f'<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" '
        f'byte_order="LittleEndian" header_type="UInt32"{comp}>\n'
        f'<ImageData WholeExtent="{ext}" Origin="{origin[0]} {origin[1]} 0" '
        f'Spacing="{spacing[0]} {spacing[1]} 1">\n<Piece Extent="{ext}">\n'
        f'<{data} Scalars="f"><DataArray type="Float32" Name="f" format="{f}">\n{text}\n'
        f'</DataArray></{data}>\n</Piece>\n</ImageData>\n</VTKFile>\n')


def ramp(ny=24, nx=32) -> np.ndarray:
    j, i = np.mgrid[0:ny, 0:nx]
    return (i + 2 * j).astype(float) / (nx - 1 + 2 * (ny - 1))


# ---------------------------------------------------------------------------- readers
@pytest.mark.parametrize("suffix,dtype", [(".png", np.uint8), (".png", np.uint16),
                                          (".tif", np.uint8), (".tif", np.uint16),
                                          (".tif", np.float32), (".npy", np.float64)])
def test_raster_round_trip_flips_rows(tmp_path, suffix, dtype):
    a = ramp()
    v = (a * (np.iinfo(dtype).max if np.dtype(dtype).kind == "u" else 1)).astype(dtype)
    path = tmp_path / f"img{suffix}"
    if suffix == ".npy":
        np.save(path, v)
    elif suffix == ".tif":
        tifffile.imwrite(path, v)
    else:
        iio.imwrite(path, v)
    img = read_image(path)
    assert img.values.dtype == v.dtype
    np.testing.assert_array_equal(img.values, v[::-1])  # row 0 is the bottom row
    assert img.spacing == (1.0, 1.0) and img.origin == (0.5, 0.5)
    np.testing.assert_allclose(img.extent(), [[0, 0], [32, 24]])


def test_tiff_imagej_calibration_and_stack(tmp_path):
    vol = np.stack([ramp() * k for k in range(1, 4)]).astype(np.float32)
    path = tmp_path / "stack.tif"
    tifffile.imwrite(path, vol, imagej=True, resolution=(1 / 0.25, 1 / 0.5),
                     metadata={"unit": "mm", "spacing": 2.0, "axes": "ZYX"})
    img = read_image(path)
    assert img.dim == 3 and img.shape == (3, 24, 32)
    assert img.spacing == pytest.approx((0.25, 0.5, 2.0))
    np.testing.assert_array_equal(img.values[1], vol[1][::-1])


@pytest.mark.parametrize("fmt", ["ascii", "binary", "zlib"])
def test_vti_reader(tmp_path, fmt):
    a = ramp().astype(np.float32)
    write_vti(tmp_path / "a.vti", a, (2.0, -1.0), (0.5, 0.25), fmt)
    img = read_image(tmp_path / "a.vti")
    np.testing.assert_array_equal(img.values, a)  # VTK: j along +y, no flip
    assert img.origin == (2.0, -1.0) and img.spacing == (0.5, 0.25)


def test_vti_appended_raw(tmp_path):
    a = ramp().astype("<f8")
    ny, nx = a.shape
    head = (f'<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" '
            f'byte_order="LittleEndian" header_type="UInt64">\n<ImageData WholeExtent="0 '
            f'{nx - 1} 0 {ny - 1} 0 0" Origin="1 2 0" Spacing="0.5 0.5 1">\n<Piece Extent='
            f'"0 {nx - 1} 0 {ny - 1} 0 0"><PointData><DataArray type="Float64" Name="f" '
            f'format="appended" offset="0"/></PointData></Piece>\n</ImageData>\n'
            f'<AppendedData encoding="raw">\n_').encode()
    blob = struct.pack("<Q", a.nbytes) + a.tobytes()
    (tmp_path / "a.vti").write_bytes(head + blob + b"\n</AppendedData>\n</VTKFile>\n")
    img = read_image(tmp_path / "a.vti")
    np.testing.assert_array_equal(img.values, a)
    assert img.origin == (1.0, 2.0)
    (tmp_path / "t.vti").write_bytes(head + blob[:100] + b"\n</AppendedData>\n</VTKFile>\n")
    with pytest.raises(MaterialError, match="t.vti: truncated data"):
        read_image(tmp_path / "t.vti")


def test_vti_cell_data_is_at_cell_centres(tmp_path):
    a = ramp().astype(np.float32)
    write_vti(tmp_path / "c.vti", a, (0.0, 0.0), (1.0, 2.0), "ascii", cell=True)
    img = read_image(tmp_path / "c.vti")
    assert img.shape == a.shape and img.origin == (0.5, 1.0)


def test_nrrd_reader_origin_and_spacing(tmp_path):
    a = ramp()
    # pynrrd writes C-ordered data when index_order="C": axes (y, x)
    nrrd.write(str(tmp_path / "a.nrrd"), a, {"space dimension": 2,
                                             "space origin": [3.0, 4.0],
                                             "space directions": [[0, 0.2], [0.1, 0]][::-1]},
               index_order="C")
    img = read_image(tmp_path / "a.nrrd")
    np.testing.assert_array_equal(img.values, a)
    assert img.origin == (3.0, 4.0)
    assert img.spacing == pytest.approx((0.1, 0.2))  # directions listed x first


@pytest.mark.parametrize("name,content,problem", [
    ("x.png", None, "no such image file"),
    ("x.png", b"\x89PNG\r\n\x1a\n garbage", "cannot read"),
    ("x.tif", b"II*\x00\x08\x00\x00\x00\x05\x00", "cannot read"),
    ("x.npy", b"\x93NUMPY garbage", "cannot read"),
    ("x.nrrd", b"NRRD0004\ntype: float\n", "cannot read"),
    ("x.vti", b"<VTKFile type=", "cannot read"),
])
def test_bad_files(tmp_path, name, content, problem):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(MaterialError, match=problem) as info:
        read_image(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_truncated_and_unsupported(tmp_path):
    p = tmp_path / "t.tif"
    tifffile.imwrite(p, (ramp(64, 64) * 65535).astype(np.uint16))
    p.write_bytes(p.read_bytes()[:2000])
    with pytest.raises(MaterialError, match="t.tif: cannot read"):
        read_image(p)
    c = tmp_path / "c.npy"
    np.save(c, ramp().astype(np.complex128))
    with pytest.raises(MaterialError, match="unsupported pixel type complex128"):
        read_image(c)
    with pytest.raises(MaterialError, match="unsupported image format '.gif'"):
        (tmp_path / "a.gif").write_bytes(b"GIF89a")
        read_image(tmp_path / "a.gif")
    write_vti(tmp_path / "s.vti", ramp(), (0, 0), (0.0, 1.0))
    with pytest.raises(MaterialError, match="spacing .* must be positive"):
        read_image(tmp_path / "s.vti")


# ------------------------------------------------------------------------ value maps
def test_linear_table_and_channel_maps():
    v = np.array([[0, 100], [200, 255]], float)
    f = linear_map(0, 255, 1)(v)
    np.testing.assert_allclose(f[1], v / 255)
    np.testing.assert_allclose(f.sum(axis=0), 1)
    g = linear_map(255, 0, 0)(v)  # reversed levels: the first is 1 at grey 0
    np.testing.assert_allclose(g[0], 1 - v / 255)
    t = table_map([0, 128, 255], [[1, 0, 0], [0, 1, 0], [0, 0.5, 0.5]])(v)
    assert t.shape == (3, 2, 2)
    np.testing.assert_allclose(t[:, 0, 0], [1, 0, 0])
    np.testing.assert_allclose(t[:, 1, 1], [0, 0.5, 0.5])
    np.testing.assert_allclose(t.sum(axis=0), 1)
    rgb = np.zeros((2, 2, 3))
    rgb[..., 0] = v
    rgb[..., 1] = 255 - v
    c = channel_map([0, 1], 0, 255, integer=True)(rgb)
    np.testing.assert_allclose(c[0], v / 255)
    d = channel_map([0, -1], 0, 255, integer=True)(rgb)  # second = 1 - first
    np.testing.assert_allclose(d, c)


def test_maps_reject_values_outside_0_1():
    with pytest.raises(MaterialError, match=r"g.png: value 300 at pixel \(1, 0\) maps to "
                                            r"1.2, outside \[0, 1\]"):
        linear_map(0, 250, 1)(np.array([[0.0, 300.0, 280.0, -3]]), "g.png")
    with pytest.raises(MaterialError, match="outside the table's levels"):
        table_map([10, 20, 30], [[1, 0], [0.5, 0.5], [0, 1]])(np.array([[5.0]]))
    rgb = np.full((1, 1, 2), 200.0)
    with pytest.raises(MaterialError, match="sum to 1.56"):
        channel_map([0, 1], 0, 255, integer=True)(rgb)
    with pytest.raises(MaterialError, match="sum to 0.2"):
        table_map([0, 1], [[0.1, 0.1], [0.5, 0.5]])


# --------------------------------------------------------------------- interpolation
@pytest.mark.parametrize("interpolation,order", [("linear", 1), ("cubic", 3)])
def test_interpolation_matches_scipy_and_gradient_is_its_derivative(interpolation, order):
    from scipy.ndimage import map_coordinates

    rng = np.random.default_rng(3)
    a = rng.random((9, 11))
    img = Image(a, origin=(0.3, -1.0), spacing=(0.5, 0.25))
    f = image_field(img, linear_map(0, 1, 1), ("a", "b"), interpolation=interpolation)
    p = np.column_stack([rng.uniform(0.3, 5.3, 400), rng.uniform(-1, 1, 400)])
    u = (p - img.origin) / img.spacing
    ref = np.clip(map_coordinates(a, [u[:, 1], u[:, 0]], order=order, mode="mirror"), 0, 1)
    c = f.composition(p)
    np.testing.assert_allclose(c[:, 1], ref, atol=1e-12)
    np.testing.assert_allclose(c.sum(axis=1), 1, atol=1e-12)
    g = f.gradient(p)
    h = 1e-6
    for k, e in enumerate(np.eye(2)):
        fd = (f.composition(p + h * e) - f.composition(p - h * e)) / (2 * h)
        ok = (c[:, 1] > 1e-6) & (c[:, 1] < 1 - 1e-6)
        np.testing.assert_allclose(g[ok, :, k], fd[ok], atol=1e-5)
    # at the pixel centres both interpolants pass through the samples
    np.testing.assert_allclose(f.composition(img.centres())[:, 1],
                               np.clip(a.ravel(), 0, 1), atol=1e-9)


def test_smoothing_scale_is_physical():
    from scipy.ndimage import gaussian_filter

    a = np.zeros((41, 41))
    a[20, 20] = 1.0
    img = Image(a, origin=(0, 0), spacing=(0.5, 0.25))
    f = image_field(img, linear_map(0, 1, 1), ("a", "b"), smoothing=1.0)
    ref = gaussian_filter(a, sigma=(4.0, 2.0), mode="nearest")  # (y, x): 1/0.25, 1/0.5
    np.testing.assert_allclose(f.samples[1], ref, atol=1e-15)
    np.testing.assert_allclose(f.samples.sum(axis=0), 1)


def test_cubic_overshoot_is_clipped_consistently():
    a = np.zeros((8, 8))
    a[:, 4:] = 1.0  # a step: the interpolating spline overshoots
    f = image_field(Image(a, (0.5, 0.5), (1, 1)), linear_map(0, 1, 1), ("a", "b"),
                    interpolation="cubic")
    p = np.column_stack([np.linspace(0.5, 7.5, 301), np.full(301, 4.0)])
    c = f.composition(p)
    assert c.min() >= 0 and c.max() <= 1
    np.testing.assert_allclose(c.sum(axis=1), 1)


# ---------------------------------------------------------------------------- tracing
def test_mask_domain_area_holes_and_half_pixel():
    j, i = np.mgrid[0:120, 0:160]
    disk = (i - 80) ** 2 + (j - 60) ** 2 < 50 ** 2
    hole = (i - 95) ** 2 + (j - 55) ** 2 < 12 ** 2
    mask = disk & ~hole
    mask[3, 3] = True  # an island: dropped
    d = mask_domain(mask, origin=(0.05, 0.05), spacing=(0.1, 0.1))
    assert len(d.holes) == 1
    # the traced boundary within 1/2 pixel of the marching-squares contour, which is within
    # sqrt(2)/4 of a pixel of the staircase of pixel edges
    assert abs(d.area - 0.01 * (mask.sum() - 1)) < 0.1 * (0.5 + 0.36) * (
        2 * np.pi * (50 + 12))
    raw = trace_labels(np.where(mask & ~((i < 10) & (j < 10)), 1, OUTSIDE))
    simp = simplify_chains(raw, 0.5)
    for r, s in zip(raw, simp):
        h = shapely.hausdorff_distance(shapely.LineString(r.points),
                                       shapely.LineString(s.points), densify=0.05)
        assert h <= 0.5 + 1e-9
        assert len(s.points) < len(r.points)


def test_saddles_do_not_touch():
    lab = np.ones((6, 6), int)
    lab[0], lab[-1], lab[:, 0], lab[:, -1] = 0, 0, 0, 0
    lab[2, 2] = lab[3, 3] = 0  # two zero pixels meeting at a corner: one hole
    d = mask_domain(lab, (0.5, 0.5), (1, 1), tol=0)
    assert len(d.holes) == 1
    chains = trace_labels(np.where(lab > 0, 1, OUTSIDE))
    assert shapely.is_simple(shapely.MultiLineString([c.points for c in chains]))


def test_label_domain_interfaces_and_region_lookup():
    j, i = np.mgrid[0:80, 0:120]
    lab = np.ones((80, 120), int)
    lab[:, 60:] = 2
    lab[(i - 30) ** 2 + (j - 40) ** 2 < 15 ** 2] = 3
    lab[(i - 60) ** 2 + (j - 40) ** 2 < 10 ** 2] = 4  # a junction of 1, 2, 4
    dom, chains, out = label_domain(lab, (0.5, 0.5), (1, 1))
    assert dom.area == pytest.approx(120 * 80)
    names = [p.name for p in dom.interfaces]
    assert all(n.startswith("discontinuity[") for n in names) and len(names) >= 4
    reg = region_lookup(chains, out, {1: 0, 2: 1, 3: 2, 4: 3}, (0.5, 0.5), (1, 1))
    centres = np.column_stack([i.ravel() + 0.5, j.ravel() + 0.5])
    r = reg(centres)
    agree = (r == lab.ravel() - 1).mean()
    assert agree > 0.995  # pixels a curve passes beyond their centre (corners cut)
    # the lookup agrees with the polygons exactly, fast path or not
    rng = np.random.default_rng(0)
    p = rng.uniform([0, 0], [120, 80], (5000, 2))
    slow = np.full(len(p), -1)
    for k, label in enumerate((1, 2, 3, 4)):
        geom = shapely.MultiPolygon(ring_polygons([pixel_to_xy(rg, (0.5, 0.5), (1, 1)) for rg in
                                                   label_rings(chains, lambda v, L=label: v == L)]))
        slow[shapely.contains_xy(geom, p[:, 0], p[:, 1])] = k
    ok = slow >= 0
    np.testing.assert_array_equal(reg(p)[ok], slow[ok])


# ---------------------------------------------------------------------- pixel sampling
def test_pixel_centres_in_triangles_brute_force():
    rng = np.random.default_rng(1)
    P = rng.uniform(0, 10, (40, 2))
    from scipy.spatial import Delaunay

    T = Delaunay(P).simplices
    e, pix = pixel_centres_in_triangles(P, T, (0.25, 0.25), (0.5, 0.5), (20, 20))
    centres = np.column_stack([(np.arange(400) % 20) * 0.5 + 0.25,
                               (np.arange(400) // 20) * 0.5 + 0.25])
    tri = Delaunay(P)
    owner = tri.find_simplex(centres)
    inside = owner >= 0
    # every centre inside the hull is found in its triangle (and ties only add pairs)
    got = set(zip(e.tolist(), pix.tolist()))
    assert all((int(owner[k]), k) in got for k in np.flatnonzero(inside))
    assert len(got) <= inside.sum() * 1.05


def test_element_pixel_delta_sees_what_vertices_miss():
    a = np.zeros((10, 10))
    a[5, 5] = 1.0  # one bright pixel in the middle of a big triangle
    f = image_field(Image(a, (0.5, 0.5), (1, 1)), linear_map(0, 1, 1), ("a", "b"))
    P = np.array([[0.0, 0], [10, 0], [0, 10], [10, 10]])
    T = np.array([[0, 1, 3], [0, 3, 2]])
    d = element_pixel_delta(f, P, T)
    assert d.max() == pytest.approx(1.0)
    vc = f.composition(P)
    assert (vc[T].max(axis=1) - vc[T].min(axis=1)).max() == 0.0


# ---------------------------------------------------------------------- model files
GRADED = """
[domain]
image = "extent"
[material]
type = "image"
constituents = ["ceramic", "metal"]
file = "part.tif"
bounds = [0, 0, 4, 2]
map = {{ linear = [0, 65535], constituent = "metal" }}
{extra}
"""


@pytest.fixture
def part(tmp_path):
    j, i = np.mgrid[0:40, 0:80]
    y = (39 - j + 0.5) / 40  # row 0 is the top row of the picture
    tifffile.imwrite(tmp_path / "part.tif", (y ** 2 * 65535).round().astype(np.uint16))
    return tmp_path


def write_model(folder: Path, text: str, name: str = "m.toml") -> Path:
    p = folder / name
    p.write_text(text)
    return p


def test_graded_image_model_meshes(part):
    import hetmesh

    m = load_model(write_model(part, GRADED.format(extra="")))
    assert m.domain.bounds == (0, 0, 4, 2)
    c = m.material.composition([[2.0, 1.975], [2.0, 0.025]])[:, 1]
    assert c[0] > 0.95 and c[1] < 0.01  # the top of the picture is y = 2
    r = hetmesh.generate(m, 0.1)
    assert r.stats.delta_max < 0.1 and r.mesh.problems() == []


def test_label_model_with_mask_and_graded_phase(tmp_path):
    import hetmesh

    j, i = np.mgrid[0:60, 0:100]
    x, y = i + 0.5, 59.5 - j
    lab = np.ones((60, 100), np.uint8)
    lab[(x - 40) ** 2 + (y - 30) ** 2 < 18 ** 2] = 2
    lab[(x - 80) ** 2 + (y - 30) ** 2 < 8 ** 2] = 0  # a hole
    iio.imwrite(tmp_path / "lab.png", lab)
    iio.imwrite(tmp_path / "grey.png", (np.clip(x / 100, 0, 1) * 255).astype(np.uint8))
    text = """
[domain]
image = "mask"
[material]
type = "image"
constituents = ["matrix", "fibre"]
file = "grey.png"
labels = "lab.png"
spacing = 0.1
[[material.phases]]
label = 1
composition = { fibre = 0 }
[[material.phases]]
label = 2
map = { linear = [0, 255], constituent = "fibre" }
"""
    m = load_model(write_model(tmp_path, text))
    assert len(m.domain.holes) == 1
    assert any(p.name.startswith("discontinuity") for p in m.domain.interfaces)
    assert m.material.n_regions == 2
    r = hetmesh.generate(m, 0.1)
    # finish() verified that no element crosses the label boundary
    sub = r.mesh.cell_data["subregion"]
    assert set(np.unique(sub)) == {0, 1}
    assert r.stats.delta_max < 0.1


BAD = [
    ("file = \"missing.tif\"", "missing.tif: no such image file"),
    ("file = \"corrupt.tif\"", "corrupt.tif: cannot read the TIF file"),
    ("file = \"complex.npy\"", "complex.npy: unsupported pixel type complex128"),
    ("file = \"part.tif\"\nspacing = [0.0, 0.1]", "material.spacing: spacing must be positive"),
    ("file = \"part.tif\"\nbounds = [0, 0, -4, 2]", "material.bounds: spacing <= 0"),
    ("file = \"part.tif\"\nbounds = [0, 0, 4, 2]",
     "part.tif: value 63907 at pixel (0, 39) maps to 1.27814, outside [0, 1]"),
    ("file = \"part.tif\"\nbounds = [0, 0, 1, 1]", "part.tif: the image covers"),
    ("labels = \"lab.png\"\nbounds = [0, 0, 4, 2]", "lab.png: label 1"),
]


EXTENT = 'image = "extent"'
TRIANGLE = 'outer = { start = [0, 0], path = [{ to = [2, 0] }, { to = [2, 2] }, { to = [0, 0] }] }'


@pytest.mark.parametrize("body,message", BAD)
def test_bad_input_one_line_exit_2_nothing_written(part, capsys, body, message):
    (part / "corrupt.tif").write_bytes(b"II*\x00" + b"\x00" * 20)
    np.save(part / "complex.npy", np.ones((4, 4), np.complex128))
    iio.imwrite(part / "lab.png", np.ones((40, 80), np.uint8))
    top = "50000" if "value 63907" in message else "65535"
    vmap = "" if "labels" in body else \
        'map = { linear = [0, ' + top + '], constituent = "metal" }'
    domain = TRIANGLE if "covers" in message else EXTENT
    text = "\n".join(["[domain]", domain, "[material]", 'type = "image"',
                      'constituents = ["ceramic", "metal"]', body, vmap, ""])
    model = write_model(part, text)
    out = part / "out.vtu"
    code = main(["mesh", str(model), "-d", "0.1", "-o", str(out)])
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and message in lines[0], err
    assert not out.exists()


# ---------------------------------------------------------------------- the examples
def test_example_model_files_match_the_generator():
    from hetmesh.material.image.synthetic import MODELS

    folder = Path(__file__).resolve().parents[1] / "examples" / "images"
    if not folder.exists():
        pytest.skip("examples/ not next to the tests")
    for name, text in MODELS.items():
        assert (folder / f"{name}.toml").read_text() == text


def test_examples_mesh(tmp_path):
    """Every 2-D image example meshes and verifies (the volumes have their own tests:
    graded_volume in test_image3d.py, masked_part in test_image_mask3d.py, phase_volume in
    test_image_labels3d.py; here they are written small and only loaded)."""
    import hetmesh
    from hetmesh.material.image import write_examples

    models = write_examples(tmp_path, shape=(64, 128), volume=8, masked=8, phases=8)
    planar = []
    for name, path in models.items():
        m = load_model(path)
        if isinstance(m, Model3D):
            continue
        planar.append(name)
        r = hetmesh.generate(m, 0.1)
        assert r.stats.delta_max < 0.1 and r.mesh.problems() == []
    assert len(planar) >= 3, planar


def test_demo_image(tmp_path, capsys):
    code = main(["demo", "--image", "--quiet", "--threshold", "0.1", "--out", str(tmp_path)])
    assert code == 0
    assert (tmp_path / "graded_part_noisy.vtu").exists()
    assert (tmp_path / "graded_part.tif").exists()


def test_demo_labels(tmp_path, capsys):
    """``demo --labels``: the two-phase label image, its phase boundary embedded."""
    from hetmesh.io.read import read_mesh
    from hetmesh.material.field import element_subregions

    code = main(["demo", "--labels", "--threshold", "0.1", "--quiet", "--out", str(tmp_path)])
    assert code == 0, capsys.readouterr().err
    mesh = read_mesh(tmp_path / "two_phase.vtu")
    model = load_model(tmp_path / "two_phase.toml")
    sub = np.asarray(mesh.cell_data["subregion"])
    assert len(np.unique(sub)) >= 2
    # every element lies in the phase it is labelled with (centroid test)
    assert np.array_equal(element_subregions(model.material, mesh.points, mesh.cells), sub)
    assert (tmp_path / "two_phase_uniform.vtu").exists()
    capsys.readouterr()
    code = main(["demo", "--labels", "--image", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "choose one" in err
    assert not (tmp_path / "x").exists()


def test_label_field_pixel_delta_and_given_domain(tmp_path):
    """A label image inside a domain given by curves: the phase boundaries are traced from
    the field (embed_discontinuities) and the mesh follows them."""
    import hetmesh

    j, i = np.mgrid[0:80, 0:120]
    lab = np.where((i - 60) ** 2 + (j - 40) ** 2 < 20 ** 2, 2, 1).astype(np.uint8)
    iio.imwrite(tmp_path / "lab.png", lab)
    iio.imwrite(tmp_path / "grey.png", (i * 2).astype(np.uint8))
    text = """
[domain.outer]
start = [1, 1]
path = [{ to = [11, 1] }, { to = [11, 7] }, { to = [1, 7] }, { to = [1, 1] }]
[material]
type = "image"
constituents = ["a", "b"]
labels = "lab.png"
file = "grey.png"
spacing = 0.1
[[material.phases]]
label = 1
composition = { b = 0.2 }
[[material.phases]]
label = 2
map = { linear = [0, 255], constituent = "b" }
"""
    m = load_model(write_model(tmp_path, text))
    r = hetmesh.generate(m, 0.1)
    assert r.stats.delta_max < 0.1
    assert any(p.name.startswith("discontinuity") for p in r.model.domain.interfaces)
    d = m.material.pixel_delta(r.mesh.points, r.mesh.triangles,
                               r.mesh.cell_data["subregion"])
    assert d.shape == (r.stats.n_elements,) and (d >= r.mesh.cell_data["delta"] - 1e-12).all()


@pytest.mark.parametrize("interpolation,order", [("linear", 1), ("cubic", 3)])
def test_volume_field_slots_in(interpolation, order):
    """The same field on an (nz, ny, nx) volume with points (N, 3): what 3-D meshing needs."""
    from scipy.ndimage import map_coordinates

    from hetmesh.material.image import ImageField

    rng = np.random.default_rng(5)
    a = rng.random((5, 6, 7))
    img = Image(a, origin=(0.0, 1.0, 2.0), spacing=(0.5, 0.25, 2.0))
    f = ImageField(np.stack([1 - a, a]), img, ("a", "b"), interpolation=interpolation)
    p = rng.uniform([0, 1, 2], [3, 2.25, 10], (200, 3))
    u = (p - img.origin) / img.spacing
    ref = np.clip(map_coordinates(a, u[:, ::-1].T, order=order, mode="mirror"), 0, 1)
    np.testing.assert_allclose(f.composition(p)[:, 1], ref, atol=1e-12)
    g = f.gradient(p)
    assert g.shape == (200, 2, 3)
    h = 1e-6
    fd = (f.composition(p + [0, 0, h]) - f.composition(p - [0, 0, h]))[:, 1] / (2 * h)
    ok = (ref > 1e-6) & (ref < 1 - 1e-6)
    np.testing.assert_allclose(g[ok, 1, 2], fd[ok], atol=1e-5)


def test_model_keys_maps_channels_files_slices(tmp_path):
    """The value maps and geometry keys through model files, checked at pixel centres."""
    j, i = np.mgrid[0:20, 0:30]
    v = (i * 8).astype(np.uint8)  # 0 .. 232, rising with x
    rgb = np.stack([v, 255 - v, np.zeros_like(v)], axis=-1)
    iio.imwrite(tmp_path / "rgb.png", rgb)
    iio.imwrite(tmp_path / "r.png", v)
    iio.imwrite(tmp_path / "g.png", 255 - v)
    tifffile.imwrite(tmp_path / "stack.tif", np.stack([v * 0, v, v * 0]), photometric="minisblack")
    iio.imwrite(tmp_path / "grey.png", v)
    head = '[domain]\nimage = "extent"\n[material]\ntype = "image"\n' \
           'constituents = ["a", "b", "c"]\n'
    centre = np.array([[10.5, 5.5]])  # pixel (10, 5): v = 80
    cases = {
        'file = "grey.png"\nmap = { levels = [0, 128, 255], fractions = { a = [1, 0, 0], '
        'b = [0, 1, 0.5] } }': [1 - 80 / 128, 80 / 128, 0],
        'file = "rgb.png"\nmap = { channels = { b = 0, a = 1 }, range = [0, 255] }':
            [175 / 255, 80 / 255, 0],
    }
    for body, want in cases.items():
        m = load_model(write_model(tmp_path, head + body + "\n"))
        np.testing.assert_allclose(m.material.composition(centre)[0], want, atol=1e-12)
    two = '[domain]\nimage = "extent"\n[material]\ntype = "image"\n' \
          'constituents = ["a", "b"]\n'
    m = load_model(write_model(tmp_path, two + 'file = { b = "r.png", a = "g.png" }\n'
                                              'map = { range = [0, 255] }\n'))
    np.testing.assert_allclose(m.material.composition(centre)[0], [175 / 255, 80 / 255])
    lin = 'map = { linear = [0, 255], constituent = "b" }\n'
    m = load_model(write_model(tmp_path, two + 'file = "stack.tif"\nslice = 1\n' + lin))
    np.testing.assert_allclose(m.material.composition(centre)[0, 1], 80 / 255)
    # first_row = "bottom": the file's first row is at the bottom, so no flip
    iio.imwrite(tmp_path / "rows.png", (j * 12).astype(np.uint8))
    m = load_model(write_model(tmp_path, two + 'file = "rows.png"\nfirst_row = "bottom"\n'
                                              'interpolation = "cubic"\n' + lin))
    np.testing.assert_allclose(m.material.composition([[3.5, 2.5]])[0, 1], 24 / 255,
                               atol=1e-12)
    with pytest.raises(MaterialError, match="stack.tif: a 3-D volume of 3 slices"):
        load_model(write_model(tmp_path, two + 'file = "stack.tif"\n' + lin))


def test_labels_on_the_image_extent_are_embedded_exactly(tmp_path):
    j, i = np.mgrid[0:40, 0:60]
    lab = np.where(i < 25, 1, np.where(j < 20, 2, 3)).astype(np.uint8)  # a T junction
    iio.imwrite(tmp_path / "t.png", lab)
    text = """
[domain]
image = "extent"
[material]
type = "image"
constituents = ["a", "b"]
labels = "t.png"
[[material.phases]]
label = 1
composition = { b = 0 }
[[material.phases]]
label = 2
composition = { b = 0.5 }
[[material.phases]]
label = 3
composition = { b = 1 }
"""
    m = load_model(write_model(tmp_path, text))
    assert m.domain.area == pytest.approx(60 * 40)
    inter = [p for p in m.domain.interfaces if p.name.startswith("discontinuity")]
    assert len(inter) == 3  # the T: one vertical boundary cut at the junction, one branch
    pts = np.vstack([np.array([c.start, c.end]) for p in inter for c in p.curves])
    # the straight label boundaries are traced straight: x = 25 and y = 20 (row 20 from
    # the top of the picture is y = 40 - 20 = 20)
    on = np.isclose(pts[:, 0], 25) | np.isclose(pts[:, 1], 20)
    assert on.all()
    # label 2 is in the top rows of the picture (y > 20), label 3 below
    np.testing.assert_array_equal(m.material.region(np.array([[10, 10], [40, 30], [40, 10]])),
                                  [0, 1, 2])


# ---------------------------------------------------------------- sampling = "pixels"
STRIPE = """
[domain]
image = "extent"
[material]
type = "image"
constituents = ["a", "b"]
file = "stripe.npy"
first_row = "bottom"
bounds = [0, 0, 4, 0.5]
map = { linear = [0, 1], constituent = "b" }
"""


def stripe_image() -> np.ndarray:
    """50 x 400 pixels of 0.01: a ramp in y (0.3 to 0.6) and, on columns 52, 102, ..., 352,
    stripes one pixel wide, 0.08 higher: narrower than the vertex spacing, and between the
    points of the mesher's 160-cell background grid (x = 200.75 and 203.25 in pixel units
    around column 202). Seven of them, so that wherever the vertices fall some stripe lies
    between them (a vertex in a stripe makes the repair refine around it)."""
    j, _ = np.mgrid[0:50, 0:400]
    a = 0.3 + 0.3 * (j + 0.5) / 50
    a[:, 52:400:50] += 0.08
    return a


def pixel_range(values: np.ndarray, points: np.ndarray, triangles: np.ndarray,
                spacing: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and largest pixel value at the pixel centres each closed triangle covers
    (barycentric coordinates, one triangle at a time; +inf and -inf where it covers none)."""
    ny, nx = values.shape
    lo, hi = np.full(len(triangles), np.inf), np.full(len(triangles), -np.inf)
    for k, t in enumerate(triangles):
        X = points[t]
        i0, j0 = np.floor(X.min(axis=0) / spacing - 0.5).astype(int)
        i1, j1 = np.ceil(X.max(axis=0) / spacing - 0.5).astype(int)
        jj, ii = np.mgrid[max(j0, 0):min(j1, ny - 1) + 1, max(i0, 0):min(i1, nx - 1) + 1]
        c = np.column_stack([(ii.ravel() + 0.5) * spacing, (jj.ravel() + 0.5) * spacing])
        lam = np.linalg.solve(np.vstack([X.T, np.ones(3)]),
                              np.vstack([c.T, np.ones(len(c))]))
        inside = (lam >= -1e-9).all(axis=0)
        if inside.any():
            v = values[jj.ravel()[inside], ii.ravel()[inside]]
            lo[k], hi[k] = v.min(), v.max()
    return lo, hi


def pixel_variation(values, points, triangles) -> np.ndarray:
    """max - min over the pixel centres each triangle covers (0 where none)."""
    lo, hi = pixel_range(values, points, triangles)
    return np.where(hi >= lo, hi - lo, 0.0)


@pytest.fixture
def stripe(tmp_path):
    np.save(tmp_path / "stripe.npy", stripe_image())
    return write_model(tmp_path, STRIPE)


def test_pixel_sampling_sees_a_stripe_vertices_miss(stripe):
    import hetmesh

    m = load_model(stripe)
    a = stripe_image()
    seen = {}
    for sampling in ("vertices", "pixels"):
        # ungraded: the coarse elements beside the stripe are what the vertices miss
        r = hetmesh.generate(m, 0.1, sampling=sampling, method="layers", gradation=0)
        assert r.stats.delta_max < 0.1 and r.mesh.problems() == []
        seen[sampling] = pixel_variation(a, r.mesh.points, r.mesh.triangles)
        if sampling == "pixels":  # the mesh's delta covers the pixels and the vertices
            assert (r.mesh.cell_data["delta"] >= seen[sampling] - 1e-12).all()
            assert r.options["sampling"] == "pixels"
    assert seen["vertices"].max() >= 0.1  # an element straddles a stripe unseen
    assert seen["pixels"].max() < 0.1


def test_pixel_sampling_statistics_and_frame(stripe):
    """mesh_statistics and element_delta through the local frame give the field's own
    pixel_delta: the elements reach the field in its coordinates."""
    import hetmesh
    from hetmesh.delta import element_delta
    from hetmesh.tri.frame import local_field, local_frame

    m = load_model(stripe)
    P = np.array([[1.9, 0.0], [2.1, 0.0], [2.0, 0.3], [2.0, 0.5]])
    T = np.array([[0, 1, 2], [1, 3, 2]])
    mesh = hetmesh.Mesh(P, T)
    d = hetmesh.mesh_statistics(mesh, m, sampling="pixels")
    vb = m.material.composition(P)[:, 1][T]  # the vertices, with the pixel centres
    lo, hi = pixel_range(stripe_image(), P, T)
    want = np.maximum(hi, vb.max(axis=1)) - np.minimum(lo, vb.min(axis=1))
    assert np.isfinite(lo).all() and want[0] > np.ptp(vb[0]) + 0.02  # the stripe counts
    assert d.delta_max == pytest.approx(want.max(), abs=1e-12)
    frame = local_frame(m.domain.bounds)
    loc = element_delta(local_field(m.material, frame), frame.to_local(P), T, "pixels")
    assert np.array_equal(loc, m.material.pixel_delta(P, T))


def test_pixel_sampling_cli(stripe, capsys):
    from hetmesh.io.read import read_mesh

    out = stripe.parent / "out.vtu"
    code = main(["mesh", str(stripe), "-d", "0.1", "--sampling", "pixels", "--method",
                 "layers", "--quiet", "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    mesh = read_mesh(out)
    assert pixel_variation(stripe_image(), mesh.points, mesh.triangles).max() < 0.1
    code = main(["stats", str(out), "-m", str(stripe), "--sampling", "pixels", "--json"])
    assert code == 0


def test_pixel_sampling_needs_an_image(tmp_path, capsys):
    import hetmesh
    from hetmesh.errors import OptionError

    model = Path(__file__).resolve().parents[1] / "examples" / "unit_square.toml"
    if not model.exists():
        pytest.skip("examples/ not next to the tests")
    out = tmp_path / "out.vtu"
    code = main(["mesh", str(model), "-d", "0.1", "--sampling", "pixels", "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and not out.exists()
    assert "--sampling pixels needs a material from an image" in err[0]
    assert "(formula) has no pixels" in err[0]
    with pytest.raises(OptionError, match="sampling pixels needs a material from an image"):
        hetmesh.generate(load_model(model), 0.1, sampling="pixels")
