"""Material fields from 3D volumes meshed with tetrahedra: readers with origin and spacing,
the trilinear/cubic field, voxel sampling, model files, the example and bad input."""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

import nrrd
import numpy as np
import pytest
import tifffile

from hetmesh.cli import main
from hetmesh.errors import MaterialError
from hetmesh.io.model import load_model
from hetmesh.material.image import Image, ImageField, image_field, linear_map, read_image
from hetmesh.material.image.sampling import element_pixel_delta, voxel_centres_in_tets
from hetmesh.tet.api import mesh_model


# ---------------------------------------------------------------------------- helpers
def ramp3(nz=5, ny=6, nx=7) -> np.ndarray:
    k, j, i = np.mgrid[0:nz, 0:ny, 0:nx]
    return ((i + 2 * j + 3 * k) / (nx - 1 + 2 * (ny - 1) + 3 * (nz - 1))).astype(np.float32)


def write_vti3(path: Path, values: np.ndarray, origin, spacing) -> None:
    """A VTK ImageData volume, inline binary point data."""
    nz, ny, nx = values.shape
    ext = f"0 {nx - 1} 0 {ny - 1} 0 {nz - 1}"
    raw = np.ascontiguousarray(values, "<f4").tobytes()
    text = base64.b64encode(struct.pack("<I", len(raw)) + raw).decode()
    path.write_text(
        f'<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" '
        f'byte_order="LittleEndian" header_type="UInt32">\n'
        f'<ImageData WholeExtent="{ext}" Origin="{" ".join(map(str, origin))}" '
        f'Spacing="{" ".join(map(str, spacing))}">\n<Piece Extent="{ext}">\n'
        f'<PointData Scalars="f"><DataArray type="Float32" Name="f" format="binary">\n{text}\n'
        f'</DataArray></PointData>\n</Piece>\n</ImageData>\n</VTKFile>\n')


def sphere_volume(n=24, size=12.0) -> np.ndarray:
    """Metal fraction of a graded ball (0 inside, 1 outside), ``(n, n, n)`` float."""
    c = (np.arange(n) + 0.5) * size / n
    z, y, x = np.meshgrid(c, c, c, indexing="ij")
    r = np.sqrt((x - size / 2) ** 2 + (y - size / 2) ** 2 + (z - size / 2) ** 2)
    return 0.5 * (1 + np.tanh((r - size / 4) / (size / 6)))


VOLUME = """
[solid]
{solid}
[material]
type = "image"
constituents = ["ceramic", "metal"]
file = "{file}"
map = {{ linear = [0, 65535], constituent = "metal" }}
{extra}
"""


@pytest.fixture
def ball(tmp_path):
    tifffile.imwrite(tmp_path / "ball.tif",
                     np.round(sphere_volume() * 65535).astype(np.uint16))
    return tmp_path


def model_file(folder: Path, solid='image = "extent"', file="ball.tif", extra="",
               name="m.toml") -> Path:
    p = folder / name
    p.write_text(VOLUME.format(solid=solid, file=file, extra=extra))
    return p


# ---------------------------------------------------------------------------- readers
def test_volume_readers_origin_and_spacing(tmp_path):
    a = ramp3()
    # TIFF stack: every page a raster, top row first; ImageJ calibration gives the spacing
    tifffile.imwrite(tmp_path / "a.tif", a[:, ::-1], imagej=True,
                     resolution=(1 / 0.25, 1 / 0.5), metadata={"unit": "mm", "spacing": 2.0,
                                                                "axes": "ZYX"})
    np.save(tmp_path / "a.npy", a)
    write_vti3(tmp_path / "a.vti", a, (1.0, 2.0, 3.0), (0.5, 0.25, 2.0))
    nrrd.write(str(tmp_path / "a.nrrd"), a, {"space dimension": 3,
                                            "space origin": [1.0, 2.0, 3.0],
                                            "space directions": np.diag([0.5, 0.25, 2.0])},
               index_order="C")
    want = {"a.tif": ((0.125, 0.25, 1.0), (0.25, 0.5, 2.0)),
            "a.npy": ((0.5, 0.5, 0.5), (1.0, 1.0, 1.0)),
            "a.vti": ((1.0, 2.0, 3.0), (0.5, 0.25, 2.0)),
            "a.nrrd": ((1.0, 2.0, 3.0), (0.5, 0.25, 2.0))}
    for name, (origin, spacing) in want.items():
        img = read_image(tmp_path / name)
        assert img.dim == 3 and img.shape == a.shape, name
        np.testing.assert_array_equal(img.values, a, err_msg=name)  # j along +y in all
        assert img.origin == pytest.approx(origin) and img.spacing == pytest.approx(spacing)


def test_imagej_stack_without_axes_is_a_volume(tmp_path):
    """tifffile's ImageJ writer files an unlabelled (nz, ny, nx) array as channels (CYX):
    more than four are slices; three stay the channels of a colour image."""
    a = ramp3(nz=6)
    tifffile.imwrite(tmp_path / "s.tif", a[:, ::-1], imagej=True, resolution=(2.0, 2.0),
                     metadata={"unit": "mm", "spacing": 0.5})
    img = read_image(tmp_path / "s.tif")
    assert img.dim == 3 and not img.channels and img.spacing == pytest.approx((0.5,) * 3)
    np.testing.assert_array_equal(img.values, a)
    tifffile.imwrite(tmp_path / "c.tif", (a[:3] * 255).astype(np.uint8), imagej=True)
    img = read_image(tmp_path / "c.tif")
    assert img.dim == 2 and img.channels and img.values.shape == (6, 7, 3)


def test_volume_model_geometry_keys(tmp_path):
    np.save(tmp_path / "v.npy", (ramp3() * 65535).astype(np.uint16))
    m = load_model(model_file(tmp_path, 'image = "extent"', "v.npy", "spacing = [0.5, 1, 2]"))
    np.testing.assert_allclose(np.array(m.solid.bounds), [[0, 0, 0], [3.5, 6, 10]])
    m = load_model(model_file(tmp_path, 'image = "extent"', "v.npy",
                              "bounds = [1, 1, 1, 8, 7, 6]"))
    np.testing.assert_allclose(np.array(m.solid.bounds), [[1, 1, 1], [8, 7, 6]])
    assert m.material.dim == 3 and m.material.spacing.tolist() == [1, 1, 1]
    # a solid given as usual inside the volume; first_row flips the rows of every slice
    m = load_model(model_file(tmp_path, 'type = "box"\nmin = [1, 1, 1]\nmax = [3, 4, 4]',
                              "v.npy", 'origin = [0, 0, 0]\nfirst_row = "top"'))
    a = ramp3()
    p = np.array([[2.0, 3.0, 1.0]])  # voxel (2, 3, 1) of the flipped volume
    assert m.material.composition(p)[0, 1] == pytest.approx(a[1, 5 - 3, 2], abs=1e-4)


def test_volume_per_constituent_files_and_table_map(tmp_path):
    a = ramp3().astype(np.float64)
    np.save(tmp_path / "metal.npy", a)
    np.save(tmp_path / "ceramic.npy", 1 - a)
    text = """
[solid]
image = "extent"
[material]
type = "image"
constituents = ["ceramic", "metal"]
file = { metal = "metal.npy", ceramic = "ceramic.npy" }
map = { range = [0, 1] }
"""
    (tmp_path / "f.toml").write_text(text)
    m = load_model(tmp_path / "f.toml")
    p = np.array([[2.5, 3.5, 1.5]])  # the centre of voxel (2, 3, 1)
    np.testing.assert_allclose(m.material.composition(p), [[1 - a[1, 3, 2], a[1, 3, 2]]])
    (tmp_path / "t.toml").write_text(text.replace(
        'file = { metal = "metal.npy", ceramic = "ceramic.npy" }\nmap = { range = [0, 1] }',
        'file = "metal.npy"\n[material.map]\nlevels = [0, 0.5, 1]\n'
        'fractions = { metal = [0, 0.8, 1] }'))
    m = load_model(tmp_path / "t.toml")
    v = a[1, 3, 2]
    want = np.interp(v, [0, 0.5, 1], [0, 0.8, 1])
    assert m.material.composition(p)[0, 1] == pytest.approx(want)


# ---------------------------------------------------------------------- the field
@pytest.mark.parametrize("interpolation,order", [("linear", 1), ("cubic", 3)])
def test_trilinear_and_cubic_match_scipy_with_consistent_gradient(interpolation, order):
    from scipy.ndimage import map_coordinates

    rng = np.random.default_rng(3)
    a = rng.random((6, 7, 8))
    img = Image(a, origin=(1.0, -1.0, 0.5), spacing=(0.5, 0.25, 1.5))
    f = ImageField(np.stack([1 - a, a]), img, ("a", "b"), interpolation=interpolation)
    lo, hi = np.array(img.origin), np.array(img.origin) + (np.array([8, 7, 6]) - 1) * \
        np.array(img.spacing)
    p = rng.uniform(lo, hi, (300, 3))
    u = (p - img.origin) / img.spacing
    ref = np.clip(map_coordinates(a, u[:, ::-1].T, order=order, mode="mirror"), 0, 1)
    np.testing.assert_allclose(f.composition(p)[:, 1], ref, atol=1e-12)
    g = f.gradient(p)[:, 1]
    h = 1e-6
    ok = (ref > 1e-6) & (ref < 1 - 1e-6)
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        fd = (f.composition(p + e) - f.composition(p - e))[:, 1] / (2 * h)
        np.testing.assert_allclose(g[ok, k], fd[ok], atol=1e-5)


def test_smoothing_scale_is_physical_in_3d():
    a = np.zeros((41, 41, 41))
    a[20, 20, 20] = 1.0
    for spacing in ((1.0, 1.0, 1.0), (0.5, 0.5, 0.25)):
        img = Image(a, origin=(0, 0, 0), spacing=spacing)
        f = ImageField(np.stack([1 - a, a]), img, ("a", "b"), smoothing=1.0)
        b = f.samples[1]
        # the spread of the blurred impulse along each axis, in model units, is 1
        for axis in range(3):
            w = b.sum(axis=tuple(k for k in range(3) if k != axis))
            x = np.arange(41) * spacing[2 - axis]
            mean = (w * x).sum() / w.sum()
            sd = np.sqrt((w * (x - mean) ** 2).sum() / w.sum())
            assert sd == pytest.approx(1.0, rel=0.02)


# ---------------------------------------------------------------------- voxel sampling
def test_voxel_centres_in_tets_brute_force():
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(1)
    P = rng.uniform(-1, 11, (150, 3))
    P[:8] = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1],
                      [0, 1, 1], [1, 1, 1]]) * 10  # some faces through voxel centres
    T = Delaunay(P).simplices
    o, s, shape = np.array([0.0, 0.0, 0.0]), np.array([0.5, 0.625, 1.25]), (9, 17, 21)
    e, v = voxel_centres_in_tets(P, T, o, s, shape, block=3000)
    assert (np.diff(e) >= 0).all()
    nz, ny, nx = shape
    k, j, i = np.meshgrid(range(nz), range(ny), range(nx), indexing="ij")
    C = o + s * np.column_stack([i.ravel(), j.ravel(), k.ravel()])
    want = set()
    for t, tet in enumerate(T):
        x = P[tet]
        lam = np.linalg.solve((x[1:] - x[0]).T, (C - x[0]).T).T
        lam = np.column_stack([1 - lam.sum(1), lam])
        want |= {(t, int(q)) for q in np.flatnonzero((lam >= -1e-9).all(1))}
    assert set(zip(e.tolist(), v.tolist())) == want


def test_voxel_delta_sees_a_sheet_the_vertices_miss():
    a = np.zeros((8, 8, 8))
    a[:, :, 4] = 1.0  # a one-voxel sheet x = 4.5
    f = image_field(Image(a, origin=(0.5, 0.5, 0.5), spacing=(1, 1, 1)), linear_map(0, 1, 1),
                    ("a", "b"))
    P = np.array([[3.7, 1.0, 1.0], [5.3, 1.0, 1.0], [3.7, 7.0, 1.0], [3.7, 1.0, 7.0]])
    T = np.array([[0, 1, 2, 3]])
    c = f.composition(P)[:, 1]
    assert np.ptp(c) < 1e-12 and c[0] == pytest.approx(0.2)  # the vertices see no spread
    # the centres (4.5, j + 0.5, k + 0.5) inside are 1: a spread of 0.8 with the vertices
    assert element_pixel_delta(f, P, T)[0] == pytest.approx(0.8)
    assert f.pixel_delta(P, T)[0] == pytest.approx(0.8)


@pytest.mark.slow  # 10-28 s: the default step stays under 10 minutes
def test_pixel_sampling_meshes_meet_delta_over_every_voxel(tmp_path):
    import hetmesh

    a = 0.5 * np.arange(16)[:, None, None] / 15 * np.ones((16, 16, 16))  # graded along z
    idx = np.random.default_rng(0).integers(2, 14, (12, 3))
    a[tuple(idx.T)] += 0.4  # isolated bright voxels, where the vertices rarely land
    tifffile.imwrite(tmp_path / "s.tif", np.round(a * 65535).astype(np.uint16))
    m = load_model(model_file(tmp_path, 'image = "extent"', "s.tif", "spacing = 0.5"))
    f = m.material
    r = mesh_model(m, 0.2)
    assert r.delta.max() < 0.2
    assert element_pixel_delta(f, r.points, r.tets).max() >= 0.2  # a bright voxel hidden
    g = hetmesh.generate(m, 0.2, sampling="pixels")
    assert g.options["sampling"] == "pixels" and g.mesh.problems() == []
    d = element_pixel_delta(f, g.mesh.points, g.mesh.cells)
    assert d.max() < 0.2 and g.stats.delta_max == pytest.approx(d.max(), abs=1e-12)
    np.testing.assert_allclose(g.mesh.cell_data["delta"], d, atol=1e-12)
    assert g.stats.delta_max_vertices <= g.stats.delta_max


def test_local_sampled_repair_keeps_a_valid_mesh_and_exact_deltas(ball):
    from hetmesh.mesh import Mesh, simplex_measures
    from hetmesh.tet.sampling import repair_sampled, sampled_delta

    m = load_model(model_file(ball, extra="spacing = 0.5"))
    r = mesh_model(m, 0.3)
    f = m.material
    P, T = r.points, r.tets.astype(np.int64)
    d0 = element_pixel_delta(f, P, T)
    assert (d0 >= 0.15).sum() > 10  # a lower threshold: work for the repair
    P2, T2, comp, d, passes, *_ = repair_sampled(P, T, f.composition(P), f, 0.15,
                                             sampled_delta(f, "pixels"))
    assert passes >= 1 and d.max() < 0.15 and len(T2) > len(T)
    np.testing.assert_array_equal(d, element_pixel_delta(f, P2, T2))  # kept deltas exact
    np.testing.assert_allclose(comp, f.composition(P2))
    assert Mesh(P2, T2).problems() == [] and (simplex_measures(P2, T2) > 0).all()
    assert simplex_measures(P2, T2).sum() == pytest.approx(simplex_measures(P, T).sum())


# ---------------------------------------------------------------------- model files
def test_volume_model_meshes_with_tetrahedra(ball, capsys):
    from hetmesh.io.read import read_mesh

    path = model_file(ball, extra="spacing = 0.5\nsmoothing = 0.5\ninterpolation = \"cubic\"")
    m = load_model(path)
    assert m.dim == 3 and m.material.dim == 3 and m.material2d is None
    np.testing.assert_allclose(np.array(m.solid.bounds), [[0, 0, 0], [12, 12, 12]])
    out = ball / "out.vtu"
    assert main(["mesh", str(path), "-d", "0.25", "-o", str(out), "--quiet"]) == 0
    mesh = read_mesh(out)
    assert mesh.cells.shape[1] == 4
    c = m.material.composition(mesh.points)
    dv = (c[mesh.cells].max(axis=1) - c[mesh.cells].min(axis=1)).max(axis=1)
    assert dv.max() < 0.25
    capsys.readouterr()
    for sampling in ("vertices", "pixels"):  # hetmesh stats recomputes either delta
        assert main(["stats", str(out), "-m", str(path), "--sampling", sampling,
                     "--json"]) == 0
        got = json.loads(capsys.readouterr().out)["delta_max"]
        want = dv.max() if sampling == "vertices" else \
            element_pixel_delta(m.material, mesh.points, mesh.cells).max()
        assert got == pytest.approx(want, abs=1e-12)


def test_volume_in_a_given_cylinder(ball):
    m = load_model(model_file(ball, 'type = "cylinder"\ncenter = [6, 6]\nradius = 5\n'
                                    'from = 1\nto = 11', extra="spacing = 0.5"))
    r = mesh_model(m, 0.3)
    assert r.delta.max() < 0.3 and m.material.dim == 3


def test_two_d_images_still_extrude(tmp_path):
    tifffile.imwrite(tmp_path / "p.tif", (ramp3()[0] * 65535).astype(np.uint16))
    text = """
[solid]
type = "extrusion"
length = 2
[domain.outer]
start = [0, 0]
path = [{ to = [7, 0] }, { to = [7, 6] }, { to = [0, 6] }, { to = [0, 0] }]
[material]
type = "image"
constituents = ["ceramic", "metal"]
file = "p.tif"
map = { linear = [0, 65535], constituent = "metal" }
"""
    (tmp_path / "e.toml").write_text(text)
    m = load_model(tmp_path / "e.toml")
    assert m.material2d is not None and m.material2d.dim == 2


# ---------------------------------------------------------------------- the example
def test_example_volume_meshes(tmp_path):
    from hetmesh.material.image import write_examples
    from hetmesh.material.image.synthetic import VOLUME_SIZE, volume_metal

    models = write_examples(tmp_path, shape=(32, 64), volume=32)
    m = load_model(models["graded_volume"])
    np.testing.assert_allclose(np.array(m.solid.bounds), [[0, 0, 0], [VOLUME_SIZE] * 3])
    p = np.array([[10.0, 10.0, 4.0], [10.0, 10.0, 16.0], [1.0, 1.0, 10.0], [10.0, 4.0, 10.0]])
    # the smoothed noisy volume follows the noise-free field (z: the wavy front)
    np.testing.assert_allclose(m.material.composition(p)[:, 1], volume_metal(*p.T), atol=0.03)
    r = mesh_model(m, 0.2)
    assert r.delta.max() < 0.2 and r.mesh.problems() == []


def test_demo_volume(tmp_path, capsys):
    code = main(["demo", "--volume", "--quiet", "-d", "0.25", "--out", str(tmp_path)])
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "graded_volume.vtu").exists() and (tmp_path / "graded_volume.png").exists()


# ---------------------------------------------------------------------- bad input
def _bad_files(folder: Path) -> None:
    tifffile.imwrite(folder / "ball.tif", np.round(sphere_volume() * 65535).astype(np.uint16))
    hot = np.round(sphere_volume() * 65535).astype(np.float32)
    hot[2, 3, 4] = -100.0  # row 3 from the top of page 2: pixel (4, 20, 2)
    tifffile.imwrite(folder / "hot.tif", hot)
    good = (folder / "ball.tif").read_bytes()
    (folder / "trunc.tif").write_bytes(good[:len(good) // 3])
    # an ImageJ stack cut short: tifffile logs the broken stack and falls back to page 0
    tifffile.imwrite(folder / "ij.tif", np.round(sphere_volume() * 65535).astype(np.uint16),
                     imagej=True, metadata={"axes": "ZYX"})
    good = (folder / "ij.tif").read_bytes()
    (folder / "trunc_ij.tif").write_bytes(good[:len(good) // 2])
    (folder / "corrupt.tif").write_bytes(b"II*\x00" + b"\x00" * 40)
    np.save(folder / "complex.npy", np.ones((4, 4, 4), np.complex64))
    np.save(folder / "trunc.npy", np.ones((8, 8, 8)))
    (folder / "trunc.npy").write_bytes((folder / "trunc.npy").read_bytes()[:1000])
    write_vti3(folder / "flat.vti", ramp3(), (0, 0, 0), (1.0, 0.0, 1.0))


BAD = [
    ('image = "extent"', "missing.tif", "", "missing.tif: no such image file"),
    ('image = "extent"', "corrupt.tif", "", "corrupt.tif: cannot read the TIF file"),
    ('image = "extent"', "trunc.tif", "", "trunc.tif: cannot read the TIF file"),
    ('image = "extent"', "trunc_ij.tif", "", "trunc_ij.tif: cannot read the TIF file "
                                             "(corrupt or truncated?): ImageJ series"),
    ('image = "extent"', "trunc.npy", "", "trunc.npy: cannot read the NPY file"),
    ('image = "extent"', "complex.npy", "", "complex.npy: unsupported pixel type complex64"),
    ('image = "extent"', "flat.vti", "", "flat.vti: spacing [1.0, 0.0, 1.0] must be positive"),
    ('image = "extent"', "ball.tif", "spacing = [1, 0, 1]",
     "m.toml: material.spacing: spacing must be positive, got [1.0, 0.0, 1.0]"),
    ('image = "extent"', "ball.tif", "bounds = [0, 0, 0, 1, 1, -1]",
     "m.toml: material.bounds: spacing <= 0"),
    ('image = "extent"', "hot.tif", "",
     "hot.tif: value -100 at pixel (4, 20, 2) maps to 1.00153, outside [0, 1]"),
    ('type = "box"\nmin = [0, 0, 0]\nmax = [30, 20, 20]', "ball.tif", "",
     "ball.tif: the image covers (0, 0, 0) - (24, 24, 24) but the domain reaches "
     "(30, 20, 20)"),
    ('image = "voxels"', "ball.tif", "", "m.toml: solid.image: expected \"extent\""),
    ('image = "extent"', "p.png", "", "m.toml: solid.image: the material's file is not a "
                                      "volume"),
]


@pytest.mark.parametrize("solid,file,extra,message", BAD)
def test_bad_volumes_one_line_exit_2_nothing_written(tmp_path, capsys, solid, file, extra,
                                                     message):
    import imageio.v3 as iio

    _bad_files(tmp_path)
    iio.imwrite(tmp_path / "p.png", np.zeros((4, 4), np.uint8))
    model = model_file(tmp_path, solid, file, extra)
    out = tmp_path / "out.vtu"
    code = main(["mesh", str(model), "-d", "0.2", "-o", str(out)])
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and message in lines[0], err
    assert not out.exists()


def test_volume_errors_from_the_api(tmp_path):
    _bad_files(tmp_path)
    with pytest.raises(MaterialError, match=r"hot.tif: value -100 at pixel \(4, 20, 2\)"):
        load_model(model_file(tmp_path, file="hot.tif"))
