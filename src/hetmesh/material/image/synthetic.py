"""Synthetic images for the examples, the demo and the benchmarks (nothing is downloaded).

* :func:`graded_part`: a 40 x 20 mm plate whose metal fraction rises from the bottom edge to
  the top along a wavy front, as a 16-bit grey image (0 = all ceramic, 65535 = all metal)
  with optional Gaussian grey-level noise (``noise`` is its standard deviation as a fraction
  of the grey range: 0.02 is "2 % noise", the scatter of a good EDS map or CT slice);
* :func:`two_phase`: a label image of a matrix (label 1) with a round inclusion (label 2,
  graded: its metal fraction follows a grey image), a small fully-metal particle (label 3)
  and a hole (label 0: outside the domain when the domain is the mask);
* :func:`graded_volume`: a 20 mm cube whose ceramic core grades into a metal shell across a
  3 mm wide front around a sphere whose radius waves along z, as a 16-bit volume
  ``(nz, ny, nx)`` with optional grey-level noise, written as a calibrated TIFF stack;
* :func:`masked_part`: a mask volume (a cylinder with a spherical cavity inside a 24 mm
  cube of voxels) and a 16-bit grey volume grading it from ceramic at the bottom to metal
  at the top: the solid of a part taken from its CT mask;
* :func:`phase_volume`: a label volume of a 16 mm cube: a matrix (label 1) with a graded
  spherical inclusion (label 2, its metal fraction from a grey volume), a metal fibre
  (label 3) and a through-hole (label 0: outside the solid).

:func:`write_examples` writes them as TIFF/PNG files with the model files that use them
(``examples/images/make_images.py`` calls it).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["graded_part", "two_phase", "graded_volume", "volume_metal", "write_examples",
           "write_volume", "masked_part", "masked_metal", "phase_volume", "MODELS",
           "PART_SIZE", "VOLUME_SIZE", "MASKED_SIZE", "PHASE_SIZE"]

#: the physical size of the synthetic part (width, height), mm
PART_SIZE = (40.0, 20.0)
#: the edge of the synthetic cube, mm
VOLUME_SIZE = 20.0
#: the edge of the cube of voxels around the masked part, mm
MASKED_SIZE = 24.0
#: the edge of the cube of the label volume, mm
PHASE_SIZE = 16.0


def _centres(shape: tuple[int, int], size=PART_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-centre coordinates ``(x, y)`` of an image stored top row first."""
    ny, nx = shape
    x = (np.arange(nx) + 0.5) * size[0] / nx
    y = size[1] - (np.arange(ny) + 0.5) * size[1] / ny
    return np.meshgrid(x, y)


def graded_metal(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The noise-free metal fraction of the graded part: 0 at the bottom, 1 at the top, a
    smooth (tanh) front around y = 10 + 2 sin(2 pi x / 40) mm, 8 mm wide."""
    front = 10.0 + 2.0 * np.sin(2.0 * np.pi * x / PART_SIZE[0])
    return 0.5 * (1.0 + np.tanh((y - front) / 4.0))


def graded_part(shape: tuple[int, int] = (256, 512), noise: float = 0.02,
                seed: int = 0, size: tuple[float, float] = PART_SIZE) -> np.ndarray:
    """The graded part as a 16-bit image ``(ny, nx)``, top row first (as stored in a file),
    with Gaussian grey-level noise of standard deviation ``noise`` x 65535 (clipped to the
    16-bit range; ``seed`` fixes it). ``size``: the physical size it covers (a window of
    the part from its lower-left corner).

    >>> g = graded_part((32, 64), noise=0.0)
    >>> g.dtype.name, g.shape, bool(g[0].mean() > g[-1].mean())
    ('uint16', (32, 64), True)
    """
    x, y = _centres(shape, size)
    f = graded_metal(x, y)
    if noise > 0:
        f = f + noise * np.random.default_rng(seed).standard_normal(f.shape)
    return np.round(np.clip(f, 0.0, 1.0) * 65535).astype(np.uint16)


def two_phase(shape: tuple[int, int] = (200, 400)) -> tuple[np.ndarray, np.ndarray]:
    """``(labels uint8, grey uint8)``, top row first: labels 1 matrix, 2 a round inclusion of
    radius 6 mm at (20, 10), 3 a particle of radius 3 mm at (8, 10), 0 a hole of radius 3 mm
    at (33, 6); grey rises from 0 at x = 0 to 255 at x = 40 mm (the inclusion's gradient)."""
    x, y = _centres(shape)
    lab = np.ones(shape, np.uint8)
    lab[(x - 20) ** 2 + (y - 10) ** 2 < 6 ** 2] = 2
    lab[(x - 8) ** 2 + (y - 10) ** 2 < 3 ** 2] = 3
    lab[(x - 33) ** 2 + (y - 6) ** 2 < 3 ** 2] = 0
    grey = np.round(np.clip(x / PART_SIZE[0], 0, 1) * 255).astype(np.uint8)
    return lab, grey


def volume_metal(x, y, z) -> np.ndarray:
    """The noise-free metal fraction of the graded cube: 0 in the core, 1 in the shell,
    across a smooth (tanh) front 3 mm wide around the sphere of radius
    6 + 1.5 sin(2 pi z / 20) mm about the cube's centre (10, 10, 10)."""
    r = np.sqrt((x - 10.0) ** 2 + (y - 10.0) ** 2 + (z - 10.0) ** 2)
    front = 6.0 + 1.5 * np.sin(2.0 * np.pi * z / VOLUME_SIZE)
    return 0.5 * (1.0 + np.tanh((r - front) / 3.0))


def graded_volume(n: int = 96, noise: float = 0.02, seed: int = 0) -> np.ndarray:
    """The graded cube as a 16-bit volume ``(n, n, n)`` (axes z, y, x; each slice stored
    top row first, as a TIFF page), with Gaussian grey-level noise of standard deviation
    ``noise`` x 65535 (clipped; ``seed`` fixes it). Slice by slice, so memory stays at the
    volume's 2 bytes per voxel.

    >>> v = graded_volume(16, noise=0.0)
    >>> v.dtype.name, v.shape, int(v[8, 8, 8]) < int(v[0, 0, 0])
    ('uint16', (16, 16, 16), True)
    """
    h = VOLUME_SIZE / n
    c = (np.arange(n) + 0.5) * h
    x, y = np.meshgrid(c, c[::-1])  # rows top first
    rng = np.random.default_rng(seed)
    out = np.empty((n, n, n), np.uint16)
    for k in range(n):
        f = volume_metal(x, y, c[k])
        if noise > 0:
            f = f + noise * rng.standard_normal(f.shape)
        out[k] = np.round(np.clip(f, 0.0, 1.0) * 65535)
    return out


def masked_metal(x, y, z) -> np.ndarray:
    """The metal fraction of the masked part: 0 at the bottom, 1 at the top, a smooth (tanh)
    front 4 mm wide around z = 12 + 2 sin(2 pi x / 24) mm."""
    front = 12.0 + 2.0 * np.sin(2.0 * np.pi * x / MASKED_SIZE)
    return 0.5 * (1.0 + np.tanh((z - front) / 4.0))


def masked_inside(x, y, z) -> np.ndarray:
    """The masked part: the cylinder of radius 10 mm about the line x = y = 12, from z = 2
    to 22 mm, minus the ball of radius 4 mm about (12, 12, 13) (an enclosed cavity)."""
    r2 = (x - 12.0) ** 2 + (y - 12.0) ** 2
    cyl = (r2 < 10.0 ** 2) & (z > 2.0) & (z < 22.0)
    return cyl & ~(r2 + (z - 13.0) ** 2 < 4.0 ** 2)


def masked_part(n: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """The masked part on ``n``^3 voxels covering the 24 mm cube: ``(mask, grey)``, each
    ``(n, n, n)`` (axes z, y, x; every slice stored top row first, as a TIFF page), the mask
    ``uint8`` (255 in the part, 0 outside and in the cavity), the grey ``uint16``
    (65535 x :func:`masked_metal`, everywhere, so it covers the part).

    >>> m, g = masked_part(16)
    >>> m.shape, g.dtype.name, int(m[8, 8, 8]), int(m[8, 8, 2]), int(m[0, 8, 8])
    ((16, 16, 16), 'uint16', 0, 255, 0)
    """
    c = (np.arange(n) + 0.5) * MASKED_SIZE / n
    z, y, x = np.meshgrid(c, c[::-1], c, indexing="ij")  # rows top first
    mask = np.where(masked_inside(x, y, z), 255, 0).astype(np.uint8)
    grey = np.round(masked_metal(x, y, z) * 65535).astype(np.uint16)
    return mask, grey


def phase_volume(n: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """The label volume on ``n``^3 voxels covering the 16 mm cube: ``(labels, grey)``, each
    ``(n, n, n)`` (axes z, y, x; every slice stored top row first), ``labels`` ``uint8``:
    1 the matrix; 2 the inclusion, the ball of radius 5 mm about (7, 8, 8); 3 the fibre,
    the cylinder of radius 1.5 mm about the line y = 12, z = 4 along x; 0 the hole, the
    cylinder of radius 2 mm about the line x = y = 3 along z. ``grey`` ``uint8``:
    255 x the inclusion's metal fraction, 0.2 + 0.6 (distance to its centre / 5 mm).

    >>> lab, g = phase_volume(16)
    >>> lab.shape, sorted(set(lab.ravel().tolist())), g.dtype.name
    ((16, 16, 16), [0, 1, 2, 3], 'uint8')
    """
    c = (np.arange(n) + 0.5) * PHASE_SIZE / n
    z, y, x = np.meshgrid(c, c[::-1], c, indexing="ij")  # rows top first
    lab = np.ones((n, n, n), np.uint8)
    r = np.sqrt((x - 7.0) ** 2 + (y - 8.0) ** 2 + (z - 8.0) ** 2)
    lab[r < 5.0] = 2
    lab[(y - 12.0) ** 2 + (z - 4.0) ** 2 < 1.5 ** 2] = 3
    lab[(x - 3.0) ** 2 + (y - 3.0) ** 2 < 2.0 ** 2] = 0
    grey = np.round(255 * np.clip(0.2 + 0.6 * r / 5.0, 0.0, 1.0)).astype(np.uint8)
    return lab, grey


def write_volume(path: str | Path, volume: np.ndarray, spacing: float) -> Path:
    """Write ``volume`` ``(nz, ny, nx)`` as a TIFF stack with ImageJ calibration (unit mm,
    pixel size and slice spacing ``spacing``), atomically."""
    import tifffile

    from ...io.atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        tifffile.imwrite(tmp, volume, imagej=True, resolution=(1.0 / spacing, 1.0 / spacing),
                         metadata={"unit": "mm", "spacing": spacing, "axes": "ZYX"})
    return path


#: the example model files, by name (the images they read are written next to them)
MODELS = {
    "graded_part": '''\
# A graded plate measured as a 16-bit grey image (examples/images/make_images.py).
# The image is 40 x 20 mm; grey 0 is all ceramic, 65535 all metal.
[model]
name = "graded_part"
units = "mm"

[domain]
image = "extent"            # the domain is the image's rectangle

[material]
type = "image"
constituents = ["ceramic", "metal"]
file = "graded_part_clean.tif"
bounds = [0, 0, 40, 20]     # the outer edges of the pixels, in mm
map = { linear = [0, 65535], constituent = "metal" }
''',
    "graded_part_noisy": '''\
# The same plate with 2 % grey-level noise, smoothed before meshing: a Gaussian of
# standard deviation 0.25 mm (3.2 pixels) leaves 0.02 / (2 sqrt(pi) 3.2) = 0.0018 of noise,
# well below delta_0, and blurs the 8 mm wide front by less than 1 %.
[model]
name = "graded_part_noisy"
units = "mm"

[domain]
image = "extent"

[material]
type = "image"
constituents = ["ceramic", "metal"]
file = "graded_part.tif"
bounds = [0, 0, 40, 20]
map = { linear = [0, 65535], constituent = "metal" }
smoothing = 0.25            # mm
interpolation = "linear"
''',
    "two_phase": '''\
# A two-phase part from a label image: a matrix (label 1) with a graded round inclusion
# (label 2, its metal fraction from a grey image), a metal particle (label 3) and a hole
# (label 0). The domain is the non-zero pixels; the label boundaries are embedded in the
# mesh, so no element straddles two phases.
[model]
name = "two_phase"
units = "mm"

[domain]
image = "mask"              # label 0 is outside: the hole

[material]
type = "image"
constituents = ["matrix", "metal"]
labels = "two_phase_labels.png"
file = "two_phase_grey.png"
spacing = 0.1               # mm per pixel

[[material.phases]]
label = 1
name = "matrix"
composition = { metal = 0.0 }

[[material.phases]]
label = 2
name = "inclusion"
map = { linear = [0, 255], constituent = "metal" }

[[material.phases]]
label = 3
name = "particle"
composition = { metal = 1.0 }
''',
    "masked_part": '''\
# A graded part taken from its CT mask (examples/images/make_images.py): the solid is the
# non-zero voxels of masked_part_mask.tif, a cylinder (radius 10 mm, height 20 mm) with a
# spherical cavity (radius 4 mm) inside it, on 48^3 voxels of 0.5 mm; its boundary is the
# mask's contour, within half a voxel of the voxel faces. The metal fraction comes from the
# grey volume masked_part.tif: ceramic at the bottom, metal at the top.
[model]
name = "masked_part"
units = "mm"

[solid]
image = "mask"              # the non-zero voxels: the cavity is a hole
mask = "masked_part_mask.tif"

[material]
type = "image"
constituents = ["ceramic", "metal"]
file = "masked_part.tif"
map = { linear = [0, 65535], constituent = "metal" }
''',
    "phase_volume": '''\
# A three-phase part from a label volume (examples/images/make_images.py): a 16 mm cube of
# 32^3 voxels with a matrix (label 1), a graded spherical inclusion (label 2, its metal
# fraction from the grey volume), a metal fibre (label 3) and a through-hole (label 0,
# outside the solid). Every label's contour becomes a surface of the mesh: no tetrahedron
# straddles two phases.
[model]
name = "phase_volume"
units = "mm"

[solid]
image = "mask"              # label 0 is outside: the hole

[material]
type = "image"
constituents = ["matrix", "metal"]
labels = "phase_volume_labels.tif"
file = "phase_volume_grey.tif"

[[material.phases]]
label = 1
name = "matrix"
composition = { metal = 0.0 }

[[material.phases]]
label = 2
name = "inclusion"
map = { linear = [0, 255], constituent = "metal" }

[[material.phases]]
label = 3
name = "fibre"
composition = { metal = 1.0 }
''',
    "graded_volume": '''\
# A graded cube scanned as a 16-bit TIFF stack (examples/images/make_images.py): a ceramic
# core grading into a metal shell across a 3 mm wide front, with 2 % grey-level noise. The
# stack carries its calibration (ImageJ: unit mm, pixel size, slice spacing), so the voxels
# are placed in mm without a spacing key: 96^3 voxels cover the cube 0 <= x, y, z <= 20.
# The Gaussian of 0.6 mm (2.9 voxels) leaves 0.02 / (2 sqrt(pi) 2.9)^(3/2) = 0.0006 of noise.
[model]
name = "graded_volume"
units = "mm"

[solid]
image = "extent"            # the box the voxels cover

[material]
type = "image"
constituents = ["ceramic", "metal"]
file = "graded_volume.tif"
map = { linear = [0, 65535], constituent = "metal" }
smoothing = 0.6             # mm
''',
}


def write_examples(folder: str | Path, *, shape: tuple[int, int] = (256, 512),
                   noise: float = 0.02, seed: int = 0, volume: int = 96,
                   masked: int = 48, phases: int = 32) -> dict[str, Path]:
    """Write the example images (the graded cube: ``volume``^3 voxels; the masked part:
    ``masked``^3; the label volume: ``phases``^3) and :data:`MODELS`
    into ``folder`` (created if missing); returns the model files by name. Files are
    written atomically."""
    import imageio.v3 as iio
    import tifffile

    from ...io.atomic import atomic_path

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    lab, grey = two_phase((shape[0] * 200 // 256, shape[1] * 400 // 512))
    images = {"graded_part.tif": graded_part(shape, noise, seed),
              "graded_part_clean.tif": graded_part(shape, 0.0, seed),
              "two_phase_labels.png": lab, "two_phase_grey.png": grey}
    for name, arr in images.items():
        with atomic_path(out / name) as tmp:
            if name.endswith(".tif"):
                tifffile.imwrite(tmp, arr)
            else:
                iio.imwrite(tmp, arr, extension=".png")
    write_volume(out / "graded_volume.tif", graded_volume(volume, noise, seed),
                 VOLUME_SIZE / volume)
    mask, grey = masked_part(masked)
    write_volume(out / "masked_part_mask.tif", mask, MASKED_SIZE / masked)
    write_volume(out / "masked_part.tif", grey, MASKED_SIZE / masked)
    lab, grey = phase_volume(phases)
    write_volume(out / "phase_volume_labels.tif", lab, PHASE_SIZE / phases)
    write_volume(out / "phase_volume_grey.tif", grey, PHASE_SIZE / phases)
    models = {}
    for name, text in MODELS.items():
        models[name] = out / f"{name}.toml"
        with atomic_path(models[name]) as tmp:
            tmp.write_text(text, encoding="utf-8")
    return models
