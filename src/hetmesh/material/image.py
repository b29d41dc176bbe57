"""Material fields from images: micrographs, element maps, CT slices, voxel build data.

An image is a regular grid of samples. Here every sample is a *pixel centre*:

* ``values`` holds the samples with the spatial axes in numpy order, ``(ny, nx)`` in 2D
  and ``(nz, ny, nx)`` in 3D (a trailing channel axis for colour images), row 0 at the
  *smallest* y (physical order; raster files, stored top row first, are flipped on reading);
* ``origin`` is the position of the centre of the first pixel and ``spacing`` the distance
  between pixel centres, both in model units and in coordinate order ``(x, y[, z])``;
* the image covers the pixel squares: ``origin - spacing/2`` to
  ``origin + (n - 1/2) spacing`` per axis (:meth:`Image.extent`).

A pixel value becomes a composition through a *value map* (:class:`ValueMap`: linear between
two grey levels, a lookup table, or one channel or file per constituent), checked to lie in
[0, 1] and to sum to 1 pixel by pixel. Between pixel centres :class:`ImageField` interpolates
linearly or with a cubic B-spline, and returns the gradient of that same interpolant;
optional Gaussian pre-smoothing (its standard deviation in model units) removes measurement
noise first. A label image divides the domain into phases, each a subregion of
:class:`LabelField` (constant or graded from a grey image), whose boundaries
(:mod:`hetmesh.geometry.trace`) become curves of the mesh.

Readers: PNG and other raster formats via ``imageio``, TIFF (8/16/32-bit, float, multi-page
stacks, ImageJ calibration) via ``tifffile``, NumPy ``.npy``, VTK ImageData ``.vti`` (a
small XML reader of our own), NRRD via ``pynrrd``. Every problem with a file raises
:class:`~hetmesh.errors.MaterialError` with one line naming the file and the problem.

>>> import numpy as np
>>> img = Image(np.array([[0.0, 1.0], [0.0, 1.0]]), origin=(0.5, 0.5), spacing=(1.0, 1.0))
>>> f = image_field(img, linear_map(0, 1, 1), ("a", "b"))
>>> f.composition([[1.0, 1.0]]).round(3).tolist()
[[0.5, 0.5]]
>>> f.gradient([[1.0, 1.0]])[0, 1].tolist()
[1.0, 0.0]
"""

from __future__ import annotations

import base64
import logging
import math
import os
import struct
import xml.etree.ElementTree as ET
import zlib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import MaterialError
from .field import as_points

__all__ = ["Image", "read_image", "RASTER_SUFFIXES", "SUFFIXES", "ValueMap", "linear_map",
           "table_map", "channel_map", "ImageField", "LabelField", "image_field",
           "INTERPOLATIONS", "pixel_centres_in_triangles", "element_pixel_delta",
           "covers", "MAX_PIXELS"]

log = logging.getLogger(__name__)

#: raster formats (stored top row first) read by imageio / tifffile
RASTER_SUFFIXES = (".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg")
SUFFIXES = RASTER_SUFFIXES + (".npy", ".vti", ".nrrd", ".nhdr")
INTERPOLATIONS = ("linear", "cubic")
#: images larger than this many samples are refused (a 16k x 16k image, a 640^3 volume)
MAX_PIXELS = 1 << 28
#: tolerance of the [0, 1] and sum checks of mapped values
TOL = 1e-9


# ------------------------------------------------------------------------------ the image
@dataclass(frozen=True, eq=False)
class Image:
    """Samples on a regular grid (see the module docstring for the conventions).

    Parameters
    ----------
    values : ndarray
        ``(ny, nx)`` / ``(nz, ny, nx)``, plus a trailing channel axis if ``channels``.
    origin, spacing : sequence of float
        Centre of the first pixel and pixel size, ``(x, y[, z])``.
    channels : bool
        Whether the last axis of ``values`` holds channels (RGB, one per constituent).
    source : str
        The file (for messages).
    origin_from_file : bool
        Whether the file stored the origin (NRRD, VTK), which a spacing given in a model
        file then keeps.
    """

    values: np.ndarray
    origin: tuple
    spacing: tuple
    channels: bool = False
    source: str = "image"
    origin_from_file: bool = False

    @property
    def dim(self) -> int:
        """Number of spatial axes (2 or 3)."""
        return self.values.ndim - int(self.channels)

    @property
    def shape(self) -> tuple[int, ...]:
        """The spatial shape, numpy order (``(ny, nx)``)."""
        return tuple(self.values.shape[:self.dim])

    def extent(self) -> np.ndarray:
        """``(2, d)``: the lower and upper corners of the area the pixels cover."""
        o, s = np.asarray(self.origin, float), np.asarray(self.spacing, float)
        n = np.asarray(self.shape[::-1], float)
        return np.vstack([o - 0.5 * s, o + (n - 0.5) * s])

    def centres(self) -> np.ndarray:
        """Every pixel centre ``(P, d)``, in the order of ``values`` flattened (x fastest)."""
        axes = [o + s * np.arange(n) for o, s, n in
                zip(self.origin, self.spacing, self.shape[::-1])]
        grid = np.meshgrid(*axes[::-1], indexing="ij")
        return np.column_stack([g.ravel() for g in grid[::-1]])


def _fail(where: str, problem: str) -> MaterialError:
    return MaterialError(f"{where}: {problem}")


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def read_image(path: str | os.PathLike, *, array: str | None = None) -> Image:
    """Read an image or volume file (format by suffix, see :data:`SUFFIXES`).

    Raster files (PNG, TIFF, ...) are flipped so that row 0 is the bottom row. Origin and
    spacing come from the file where the format stores them (NRRD ``space origin`` and
    ``space directions``/``spacings``, VTK ``Origin``/``Spacing``, ImageJ TIFF calibration);
    otherwise spacing 1 and the first pixel's corner at 0. ``array`` names the VTK data array
    (default: the active scalars, else the first).

    Raises
    ------
    MaterialError
        Missing or unreadable file, corrupt or truncated data, unsupported dtype or format,
        spacing <= 0: one line naming the file.
    """
    p = Path(path)
    where = os.fspath(path)
    if not p.exists():
        raise _fail(where, "no such image file")
    if p.is_dir():
        raise _fail(where, "is a directory, not an image file")
    suffix = p.suffix.lower()
    if suffix not in SUFFIXES:
        raise _fail(where, f"unsupported image format {suffix or '(no suffix)'!r} (expected "
                           f"one of: {', '.join(SUFFIXES)})")
    try:
        if suffix in (".tif", ".tiff"):
            img = _read_tiff(p, where)
        elif suffix in RASTER_SUFFIXES:
            img = _read_raster(p, where)
        elif suffix == ".npy":
            img = _read_npy(p, where)
        elif suffix == ".vti":
            img = _read_vti(p, where, array)
        else:
            img = _read_nrrd(p, where)
    except MaterialError:
        raise
    except MemoryError:
        raise _fail(where, "image too large for memory") from None
    except Exception as exc:  # noqa: BLE001 - any reader failure is a bad file
        raise _fail(where, f"cannot read the {suffix[1:].upper()} file (corrupt or "
                           f"truncated?): {_first_line(exc)}") from None
    return _checked(img, where)


def _checked(img: Image, where: str) -> Image:
    v = img.values
    if v.dtype.kind == "b":
        v = v.astype(np.uint8)
    if v.dtype.kind not in "uif" or v.dtype.itemsize > 8:
        raise _fail(where, f"unsupported pixel type {v.dtype} (expected integers or floats)")
    if img.dim not in (2, 3):
        raise _fail(where, f"expected a 2-D image or a 3-D volume, got an array of shape "
                           f"{v.shape}")
    if v.size > MAX_PIXELS:
        raise _fail(where, f"{v.size:,} samples, more than the {MAX_PIXELS:,} accepted")
    if min(img.shape) < 1:
        raise _fail(where, f"the image is empty (shape {v.shape})")
    if v.dtype.kind == "f" and not np.isfinite(v).all():
        idx = np.argwhere(~np.isfinite(v))[0]
        raise _fail(where, f"pixel {_index(idx[:img.dim])} is not finite ({v[tuple(idx)]})")
    _check_geometry(img.origin, img.spacing, img.dim, where)
    return replace(img, values=v, origin=tuple(float(o) for o in img.origin),
                   spacing=tuple(float(s) for s in img.spacing), source=where)


def _check_geometry(origin, spacing, dim: int, where: str) -> None:
    if len(spacing) != dim or len(origin) != dim:
        raise _fail(where, f"spacing {list(spacing)} and origin {list(origin)} must have "
                           f"{dim} values each")
    for s in spacing:
        if not (math.isfinite(float(s)) and float(s) > 0.0):
            raise _fail(where, f"spacing {[float(v) for v in spacing]} must be positive and "
                               f"finite")
    if not all(math.isfinite(float(o)) for o in origin):
        raise _fail(where, f"origin {[float(v) for v in origin]} must be finite")


def _index(idx) -> str:
    """A pixel index as ``(i, j)`` (x first), from numpy order."""
    return "(" + ", ".join(str(int(v)) for v in list(idx)[::-1]) + ")"


def _default(values: np.ndarray, channels: bool, spacing=None) -> Image:
    dim = values.ndim - int(channels)
    s = tuple(spacing) if spacing is not None else (1.0,) * dim
    return Image(values, origin=tuple(0.5 * v for v in s), spacing=s, channels=channels)


def _raster(values: np.ndarray, channels: bool) -> np.ndarray:
    """Flip the row axis of a raster (top row first) into physical order."""
    axis = values.ndim - (2 if channels else 1) - 1
    return np.ascontiguousarray(np.flip(values, axis=axis))


def _read_raster(p: Path, where: str) -> Image:
    import imageio.v3 as iio

    v = np.asarray(iio.imread(p))
    channels = v.ndim == 3 and v.shape[-1] in (2, 3, 4)
    return _default(_raster(v, channels), channels)


def _read_tiff(p: Path, where: str) -> Image:
    import tifffile

    with tifffile.TiffFile(p) as tif:
        series = tif.series[0]
        axes = series.axes
        v = np.asarray(series.asarray())
        page = tif.pages[0]
        ij = tif.imagej_metadata or {}
        tags = page.tags
        spacing = None
        unit = str(ij.get("unit", "")).strip().lower()
        if unit and unit not in ("pixel", "pixels", "none") and "XResolution" in tags:
            xr, yr = tags["XResolution"].value, tags["YResolution"].value
            sx, sy = xr[1] / xr[0], yr[1] / yr[0]
            spacing = [sx, sy]
    chan = [i for i, a in enumerate(axes) if a in "CS"]
    if len(chan) > 1:
        raise _fail(where, f"TIFF axes {axes!r}: more than one channel axis")
    if chan:
        v = np.moveaxis(v, chan[0], -1)
    channels = bool(chan)
    dim = v.ndim - int(channels)
    if spacing is not None and dim == 3:
        spacing = spacing + [float(ij.get("spacing", 1.0))]
    return _default(_raster(v, channels), channels, spacing)


def _read_npy(p: Path, where: str) -> Image:
    try:
        v = np.load(p, allow_pickle=False, mmap_mode=None)
    except ValueError as exc:
        if "pickle" in str(exc).lower():
            raise _fail(where, "holds Python objects, not numbers (refused: a .npy image "
                               "must be a plain numeric array)") from None
        raise
    v = np.asarray(v)
    if v.dtype.kind not in "uifb":
        raise _fail(where, f"unsupported pixel type {v.dtype} (expected integers or floats)")
    channels = v.ndim == 3 and v.shape[-1] in (2, 3, 4) and min(v.shape[:2]) > 4
    return _default(_raster(v, channels) if v.ndim - int(channels) == 2 else v, channels)


def _read_nrrd(p: Path, where: str) -> Image:
    import nrrd

    v, hdr = nrrd.read(os.fspath(p), index_order="C")
    kinds = [str(k).lower() for k in hdr.get("kinds", [])]
    channels = False
    if kinds and kinds[0] in ("vector", "rgb-color", "rgba-color", "list", "point",
                              "covariant-vector", "3-vector", "4-vector"):
        # C order: the fastest (first NRRD) axis is last
        channels = True
    dim = v.ndim - int(channels)
    spacing, origin = [1.0] * dim, None
    dirs = hdr.get("space directions")
    if dirs is not None:
        rows = [np.asarray(r, float) for r in dirs if r is not None and
                not (isinstance(r, np.ndarray) and np.isnan(r).all())]
        if len(rows) == dim:
            m = np.vstack(rows)
            if np.abs(m - np.diag(np.diag(m))).max() > 1e-12 * np.abs(m).max():
                raise _fail(where, "the NRRD 'space directions' are not along the axes; "
                                   "rotated images are not supported")
            spacing = list(np.diag(m))
    elif hdr.get("spacings") is not None:
        sp = [float(s) for s in hdr["spacings"] if not math.isnan(float(s))]
        if len(sp) == dim:
            spacing = sp
    if hdr.get("space origin") is not None:
        origin = [float(o) for o in np.asarray(hdr["space origin"], float)][:dim]
    if origin is None:
        origin = [0.5 * s for s in spacing]
    return Image(v, origin=tuple(origin), spacing=tuple(spacing), channels=channels,
                 origin_from_file=hdr.get("space origin") is not None)


# ---------------------------------------------------------------------------- VTK .vti
_VTK_TYPES = {"Int8": "i1", "UInt8": "u1", "Int16": "i2", "UInt16": "u2", "Int32": "i4",
              "UInt32": "u4", "Int64": "i8", "UInt64": "u8", "Float32": "f4",
              "Float64": "f8"}


def _read_vti(p: Path, where: str, array: str | None) -> Image:
    raw = p.read_bytes()
    head, sep, tail = raw.partition(b"<AppendedData")
    appended = b""
    if sep:  # raw appended data is not XML: parse the header part, keep the bytes
        start = tail.index(b"_") + 1
        end = tail.rfind(b"</AppendedData>")
        appended = tail[start:end].rstrip()
        raw = head + b"<AppendedData/></VTKFile>"
    root = ET.fromstring(raw)
    if root.tag != "VTKFile" or root.get("type") != "ImageData":
        raise _fail(where, f"not a VTK ImageData file (type {root.get('type')!r})")
    order = "<" if root.get("byte_order", "LittleEndian") == "LittleEndian" else ">"
    header = "u8" if root.get("header_type", "UInt32") == "UInt64" else "u4"
    compressed = root.get("compressor") is not None
    if compressed and "ZLib" not in root.get("compressor", ""):
        raise _fail(where, f"unsupported compressor {root.get('compressor')!r} (zlib only)")
    enc = root.find("AppendedData")
    img = root.find("ImageData")
    if img is None:
        raise _fail(where, "no <ImageData> element")
    ext = [int(v) for v in img.get("WholeExtent", "").split()]
    origin = [float(v) for v in img.get("Origin", "0 0 0").split()]
    spacing = [float(v) for v in img.get("Spacing", "1 1 1").split()]
    if len(ext) != 6 or len(origin) != 3 or len(spacing) != 3:
        raise _fail(where, "WholeExtent, Origin or Spacing is malformed")
    direction = img.get("Direction")
    if direction and not np.allclose(np.array(direction.split(), float).reshape(3, 3),
                                     np.eye(3)):
        raise _fail(where, "a Direction other than the identity (rotated image) is not "
                           "supported")
    arrays, cell = _vti_arrays(img)
    if not arrays:
        raise _fail(where, "no PointData or CellData array")
    names = [a.get("Name", f"array {i}") for i, a in enumerate(arrays)]
    if array is None:
        pick = 0
    elif array in names:
        pick = names.index(array)
    else:
        raise _fail(where, f"no data array {array!r} (it has: {', '.join(names)})")
    da = arrays[pick]
    dims = [ext[1] - ext[0] + 1, ext[3] - ext[2] + 1, ext[5] - ext[4] + 1]
    if cell:  # values at cell centres
        dims = [max(d - 1, 1) for d in dims]
        origin = [o + 0.5 * s for o, s in zip(origin, spacing)]
    ncomp = int(da.get("NumberOfComponents", "1"))
    dtype = _VTK_TYPES.get(da.get("type", ""))
    if dtype is None:
        raise _fail(where, f"unsupported data type {da.get('type')!r}")
    count = dims[0] * dims[1] * dims[2] * ncomp
    data = _vti_data(da, np.dtype(order + dtype), count, header, order, compressed,
                     appended, enc.get("encoding", "raw") if enc is not None else "", where)
    v = data.reshape(dims[2], dims[1], dims[0], ncomp)
    if ncomp == 1:
        v = v[..., 0]
    dim = 2 if dims[2] == 1 else 3
    if dim == 2:
        v = v[0]
    return Image(np.ascontiguousarray(v), origin=tuple(origin[:dim]),
                 spacing=tuple(spacing[:dim]), channels=ncomp > 1, origin_from_file=True)


def _vti_arrays(img):
    piece = img.find("Piece")
    if piece is None:
        return [], False
    for tag, cell in (("PointData", False), ("CellData", True)):
        block = piece.find(tag)
        if block is None or not len(block):
            continue
        arrays = list(block.findall("DataArray"))
        active = block.get("Scalars")
        if active:
            arrays.sort(key=lambda a: a.get("Name") != active)
        return arrays, cell
    return [], False


def _vti_data(da, dtype, count, header, order, compressed, appended, encoding, where):
    fmt = da.get("format", "ascii")
    if fmt == "ascii":
        vals = np.array((da.text or "").split(), dtype=float)
        if len(vals) != count:
            raise _fail(where, f"data array holds {len(vals)} values, expected {count}")
        return vals.astype(dtype)
    hsize = np.dtype(header).itemsize
    hdt = np.dtype(order + header)
    if fmt == "binary":
        text = (da.text or "").strip().encode()
        if compressed:
            n0 = base64.b64decode(text[:_b64len(3 * hsize)])
            nblocks = int(np.frombuffer(n0[:hsize], hdt)[0])
            hlen = _b64len((3 + nblocks) * hsize)
            hdr = np.frombuffer(base64.b64decode(text[:hlen]), hdt)
            body = base64.b64decode(text[hlen:])
            return _inflate(hdr, body, dtype, count, where)
        blob = base64.b64decode(text)
        nbytes = int(np.frombuffer(blob[:hsize], hdt)[0])
        return _exact(blob[hsize:hsize + nbytes], dtype, count, where)
    if fmt == "appended":
        off = int(da.get("offset", "0"))
        if encoding == "base64":
            raise _fail(where, "base64-encoded appended data is not supported (use raw or "
                               "inline binary)")
        blob = appended[off:]
        if compressed:
            nblocks = int(np.frombuffer(blob[:hsize], hdt)[0])
            hdr = np.frombuffer(blob[:(3 + nblocks) * hsize], hdt)
            return _inflate(hdr, blob[(3 + nblocks) * hsize:], dtype, count, where)
        nbytes = int(np.frombuffer(blob[:hsize], hdt)[0])
        return _exact(blob[hsize:hsize + nbytes], dtype, count, where)
    raise _fail(where, f"unsupported data array format {fmt!r}")


def _b64len(nbytes: int) -> int:
    return 4 * ((nbytes + 2) // 3)


def _inflate(hdr, body: bytes, dtype, count, where):
    nblocks = int(hdr[0])
    sizes = [int(s) for s in hdr[3:3 + nblocks]]
    out, pos = [], 0
    for s in sizes:
        out.append(zlib.decompress(body[pos:pos + s]))
        pos += s
    return _exact(b"".join(out), dtype, count, where)


def _exact(blob: bytes, dtype, count, where):
    need = count * dtype.itemsize
    if len(blob) < need:
        raise _fail(where, f"truncated data: {len(blob)} bytes, expected {need}")
    return np.frombuffer(blob[:need], dtype).astype(dtype.newbyteorder("="))


# ---------------------------------------------------------------------------- value maps
@dataclass(frozen=True)
class ValueMap:
    """How stored pixel values become volume fractions.

    ``kind`` is ``"table"`` (piecewise linear in one grey value: ``levels`` ``(K,)``
    increasing, ``fractions`` ``(K, m)``; :func:`linear_map` is a table of two rows) or
    ``"channels"`` (fraction of constituent ``k`` = (channel ``index[k]`` - lo) / (hi - lo);
    ``index[k] = -1`` for the one constituent that is 1 - the others).
    """

    kind: str
    levels: np.ndarray | None = None
    fractions: np.ndarray | None = None
    index: tuple[int, ...] = ()
    lo: float = 0.0
    hi: float = 1.0
    sum_tol: float = 1e-6

    def __call__(self, values: np.ndarray, where: str = "image",
                 mask: np.ndarray | None = None) -> np.ndarray:
        """Fractions ``(m, *shape)`` of the pixel values ``values`` (``(*shape)`` or
        ``(*shape, c)``); only the pixels where ``mask`` is True are checked (others 0).
        Raises :class:`MaterialError` naming the first bad pixel."""
        return (_apply_table if self.kind == "table" else _apply_channels)(self, values,
                                                                           where, mask)


def linear_map(g0: float, g1: float, k: int, m: int = 2) -> ValueMap:
    """Constituent ``k`` of ``m`` (``m == 2``) varies linearly from 0 at grey level ``g0``
    to 1 at ``g1``; the other is 1 minus it. Values beyond ``[g0, g1]`` map outside [0, 1],
    an error."""
    if m != 2:
        raise MaterialError(f"a linear map needs 2 constituents, got {m} (use a table)")
    if not (math.isfinite(g0) and math.isfinite(g1)) or g0 == g1:
        raise MaterialError(f"linear map: grey levels {g0:g} and {g1:g} must differ")
    f = np.zeros((2, 2))
    f[0, k], f[1, k] = 0.0, 1.0
    f[:, 1 - k] = 1.0 - f[:, k]
    lv = np.array([g0, g1], float)
    if g1 < g0:
        lv, f = lv[::-1].copy(), f[::-1].copy()
    return ValueMap("table", levels=lv, fractions=f, sum_tol=TOL)


def table_map(levels: Sequence[float], fractions: np.ndarray) -> ValueMap:
    """A lookup table: grey ``levels`` ``(K,)`` strictly increasing, ``fractions``
    ``(K, m)`` in [0, 1] with rows summing to 1; linear between the levels."""
    lv = np.asarray(levels, float)
    f = np.asarray(fractions, float)
    if lv.ndim != 1 or len(lv) < 2 or f.shape[0] != len(lv) or f.ndim != 2:
        raise MaterialError(f"a table needs at least 2 levels and one row of fractions per "
                            f"level, got {lv.shape} levels and fractions {f.shape}")
    if not np.all(np.diff(lv) > 0):
        raise MaterialError(f"table levels must increase strictly: {lv.tolist()}")
    if (f < -TOL).any() or (f > 1 + TOL).any():
        raise MaterialError(f"table fractions must lie in [0, 1], got {f.min():g} .. "
                            f"{f.max():g}")
    s = f.sum(axis=1)
    if np.abs(s - 1).max() > TOL:
        i = int(np.argmax(np.abs(s - 1)))
        raise MaterialError(f"table fractions at level {lv[i]:g} sum to {s[i]:g}, not 1")
    return ValueMap("table", levels=lv, fractions=f, sum_tol=TOL)


def channel_map(index: Sequence[int], lo: float, hi: float, *, integer: bool) -> ValueMap:
    """One channel per constituent (``-1``: the constituent that is 1 - the others), scaled
    from ``[lo, hi]`` to [0, 1]. Sums must be 1 within 1e-6, or for integer images within
    the quantisation ``1.5 / (hi - lo)`` per channel (then renormalised)."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        raise MaterialError(f"channel range [{lo:g}, {hi:g}] must increase")
    tol = 1e-6 + (1.5 * len(index) / (hi - lo) if integer else 0.0)
    return ValueMap("channels", index=tuple(int(i) for i in index), lo=float(lo),
                    hi=float(hi), sum_tol=tol)


def _first_bad(bad: np.ndarray) -> tuple:
    return tuple(np.argwhere(bad)[0])


def _apply_table(vm: ValueMap, values, where, mask):
    v = np.asarray(values, float)
    sel = np.ones(v.shape, bool) if mask is None else mask
    lo, hi = vm.levels[0], vm.levels[-1]
    below = np.where(sel, lo - v, -np.inf)
    above = np.where(sel, v - hi, -np.inf)
    worst = np.maximum(below, above)
    if worst.size and worst.max() > TOL * max(1.0, abs(lo), abs(hi)):
        idx = np.unravel_index(int(np.argmax(worst)), v.shape)
        f = vm.fractions
        t = (v[idx] - lo) / (hi - lo)
        row = f[0] + t * (f[-1] - f[0])  # the linear map extended
        k = int(np.argmax(np.maximum(row - 1.0, -row) + 1e-9 * (row > 1)))
        how = (f"maps to {row[k]:.6g}, outside [0, 1]" if len(vm.levels) == 2
               else f"is outside the table's levels [{lo:g}, {hi:g}]")
        raise _fail(where, f"value {v[idx]:g} at pixel {_index(idx)} {how}")
    vc = np.clip(v, lo, hi)
    m = vm.fractions.shape[1]
    res = np.empty((m,) + v.shape)
    for k in range(m):
        res[k] = np.interp(vc, vm.levels, vm.fractions[:, k])
    if mask is not None:
        res[:, ~mask] = 0.0
    return res


def _apply_channels(vm: ValueMap, values, where, mask):
    v = np.asarray(values, float)
    nc = v.shape[-1]
    bad = [i for i in vm.index if i >= nc]
    if bad:
        raise _fail(where, f"channel {bad[0]} does not exist (the image has {nc} channels)")
    shape = v.shape[:-1]
    sel = np.ones(shape, bool) if mask is None else mask
    m = len(vm.index)
    res = np.empty((m,) + shape)
    derived = [k for k in range(m) if vm.index[k] < 0]
    for k, c in enumerate(vm.index):
        if c >= 0:
            res[k] = (v[..., c] - vm.lo) / (vm.hi - vm.lo)
            out = ((res[k] < -TOL) | (res[k] > 1 + TOL)) & sel
            if out.any():
                idx = _first_bad(out)
                raise _fail(where, f"channel {c} value {v[idx + (c,)]:g} at pixel "
                                   f"{_index(idx)} maps to {res[k][idx]:.6g}, outside [0, 1]")
    given = [k for k in range(m) if k not in derived]
    total = res[given].sum(axis=0)
    if derived:
        k = derived[0]
        res[k] = 1.0 - total
        bad = (res[k] < -vm.sum_tol) & sel
        if bad.any():
            idx = _first_bad(bad)
            raise _fail(where, f"fractions at pixel {_index(idx)} sum to {total[idx]:.6g}, "
                               f"more than 1")
        res[k] = np.maximum(res[k], 0.0)
        total = res.sum(axis=0)
    err = (np.abs(total - 1.0) > vm.sum_tol) & sel
    if err.any():
        idx = _first_bad(err)
        raise _fail(where, f"fractions at pixel {_index(idx)} sum to {total[idx]:.6g}, not 1")
    res = np.clip(res, 0.0, 1.0)
    res /= np.where(total > 0, res.sum(axis=0), 1.0)
    if mask is not None:
        res[:, ~mask] = 0.0
    return res


# ---------------------------------------------------------------------------- the field
def _bspline_weights(t: np.ndarray):
    """Cubic B-spline weights ``(4, N)`` for offsets -1..2 and their derivatives."""
    t2, t3 = t * t, t * t * t
    w = np.stack([(1 - t) ** 3 / 6.0, (3 * t3 - 6 * t2 + 4) / 6.0,
                  (-3 * t3 + 3 * t2 + 3 * t + 1) / 6.0, t3 / 6.0])
    dw = np.stack([-(1 - t) ** 2 / 2.0, (3 * t2 - 4 * t) / 2.0,
                   (-3 * t2 + 2 * t + 1) / 2.0, t2 / 2.0])
    return w, dw


def _mirror(i: np.ndarray, n: int) -> np.ndarray:
    """Indices reflected about the end samples (scipy's ``mode="mirror"``)."""
    if n == 1:
        return np.zeros_like(i)
    period = 2 * (n - 1)
    i = np.abs(i) % period
    return np.where(i > n - 1, period - i, i)


class ImageField:
    """A material field interpolated from per-pixel fractions.

    Parameters
    ----------
    fractions : ndarray ``(m, *shape)``
        Volume fractions at the pixel centres (rows summing to 1).
    image : Image
        The geometry (origin, spacing); its values are not used.
    constituents : sequence of str
    interpolation : ``"linear"`` or ``"cubic"``
        Multilinear, or the interpolating cubic B-spline (scipy's ``spline_filter``,
        mirrored at the edges). Outside the pixel centres (the half-pixel rim of the
        image) the value of the nearest centre line is kept.
    smoothing : float
        Standard deviation of a Gaussian applied to the fractions first, in model units
        (0: none).

    The composition is the interpolant clipped to [0, 1] and renormalised to sum 1 (neither
    acts for linear interpolation of valid fractions; a cubic spline can overshoot at sharp
    edges); the gradient is the exact derivative of that function, so a mesher's Newton
    steps and size fields see the same field as the delta checks.
    """

    def __init__(self, fractions: np.ndarray, image: Image, constituents: Sequence[str], *,
                 interpolation: str = "linear", smoothing: float = 0.0):
        if interpolation not in INTERPOLATIONS:
            raise MaterialError(f"interpolation {interpolation!r} is not one of "
                                f"{', '.join(INTERPOLATIONS)}")
        f = np.asarray(fractions, float)
        self.constituents = tuple(constituents)
        if f.shape[0] != len(self.constituents) or f.ndim - 1 != image.dim:
            raise MaterialError(f"fractions of shape {f.shape} do not fit "
                                f"{len(self.constituents)} constituents on a {image.dim}-D "
                                f"image")
        self.dim = image.dim
        self.origin = np.asarray(image.origin, float)
        self.spacing = np.asarray(image.spacing, float)
        self.shape = f.shape[1:]
        self.interpolation = interpolation
        self.smoothing = float(smoothing)
        self.source = image.source
        if smoothing > 0:
            from scipy.ndimage import gaussian_filter

            sigma = [0.0] + [self.smoothing / s for s in self.spacing[::-1]]
            f = gaussian_filter(f, sigma=sigma, mode="nearest", truncate=4.0)
        self.samples = f  # the field at the pixel centres
        if interpolation == "cubic":
            from scipy.ndimage import spline_filter

            self._coef = np.stack([spline_filter(c, order=3, mode="mirror") for c in f])
        else:
            self._coef = f
        self._offset = np.zeros(self.dim)
        self._cache = None

    def __repr__(self) -> str:
        return (f"ImageField({self.source!r}, shape={self.shape}, "
                f"interpolation={self.interpolation!r}, smoothing={self.smoothing:g})")

    # -- the MaterialField interface
    def shifted(self, offset) -> "ImageField":
        """The same field evaluated at ``points + offset``."""
        import copy

        new = copy.copy(self)
        new._offset = self._offset + np.asarray(offset, float).reshape(self.dim)
        new._cache = None
        return new

    def composition(self, points, region=None) -> np.ndarray:
        """Volume fractions ``(N, m)``."""
        return self.evaluate(points)[0].copy()

    def gradient(self, points, region=None) -> np.ndarray:
        """Gradients ``(N, m, d)`` of the interpolant (exact)."""
        return self.evaluate(points)[1].copy()

    def evaluate(self, points) -> tuple[np.ndarray, np.ndarray]:
        """``(composition (N, m), gradient (N, m, d))``, cached for the last points."""
        p = self._points(points)
        key = (p.shape, hash(p.tobytes()))
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        out = self._evaluate(p)
        self._cache = (key, out)
        return out

    def _points(self, points) -> np.ndarray:
        if self.dim == 2:
            p = as_points(points, repr(self))
        else:
            p = np.asarray(points, float).reshape(-1, self.dim)
        return p + self._offset if self._offset.any() else p

    def _evaluate(self, p: np.ndarray, block: int = 1 << 17):
        n = len(p)
        m = len(self.constituents)
        comp = np.empty((n, m))
        grad = np.empty((n, m, self.dim))
        for s in range(0, n, block):
            c, g = self._raw(p[s:s + block])
            comp[s:s + block], grad[s:s + block] = _normalise(c, g)
        return comp, grad

    def _raw(self, p: np.ndarray):
        """Interpolated (unclipped) values ``(N, m)`` and gradients ``(N, m, d)``."""
        u = (p - self.origin) / self.spacing  # index coordinates, x first
        nax = np.asarray(self.shape[::-1])
        inside = (u >= 0) & (u <= nax - 1)
        u = np.clip(u, 0, nax - 1)
        if self.interpolation == "linear":
            i0 = np.minimum(np.floor(u).astype(np.int64), np.maximum(nax - 2, 0))
            t = u - i0
            offs = (0, 1)
            w = [np.stack([1 - t[:, k], t[:, k]]) for k in range(self.dim)]
            dw = [np.stack([-np.ones(len(t)), np.ones(len(t))]) for _ in range(self.dim)]
            idx = [[np.minimum(i0[:, k] + o, nax[k] - 1) for o in offs]
                   for k in range(self.dim)]
        else:
            i0 = np.floor(u).astype(np.int64)
            t = u - i0
            offs = (-1, 0, 1, 2)
            w, dw = zip(*[_bspline_weights(t[:, k]) for k in range(self.dim)])
            idx = [[_mirror(i0[:, k] + o, int(nax[k])) for o in offs]
                   for k in range(self.dim)]
        m = len(self.constituents)
        val = np.zeros((len(p), m))
        der = np.zeros((len(p), m, self.dim))
        flat = self._coef.reshape(m, -1)
        strides = np.cumprod([1] + list(nax[:-1]))  # flat index = sum idx_k * stride_k
        for combo in np.ndindex(*(len(offs),) * self.dim):
            lin = sum(idx[k][combo[k]] * strides[k] for k in range(self.dim))
            vals = flat[:, lin].T  # (N, m)
            ws = [w[k][combo[k]] for k in range(self.dim)]
            prod = np.prod(ws, axis=0)
            val += prod[:, None] * vals
            for k in range(self.dim):
                others = np.prod([ws[j] for j in range(self.dim) if j != k], axis=0) \
                    if self.dim > 1 else 1.0
                der[:, :, k] += (dw[k][combo[k]] * others)[:, None] * vals
        der /= self.spacing
        der *= inside[:, None, :]
        return val, der


def _normalise(c: np.ndarray, g: np.ndarray):
    """Clip to [0, 1] and renormalise to sum 1, with the derivative of that map."""
    clipped = (c < 0) | (c > 1)
    if not clipped.any() and np.abs(c.sum(axis=1) - 1).max() < 1e-12:
        return c, g
    cc = np.clip(c, 0.0, 1.0)
    gg = np.where(clipped[:, :, None], 0.0, g)
    s = cc.sum(axis=1)
    s = np.where(s > 0, s, 1.0)
    ds = gg.sum(axis=1)
    comp = cc / s[:, None]
    grad = (gg * s[:, None, None] - cc[:, :, None] * ds[:, None, :]) / (s * s)[:, None, None]
    return comp, grad


def image_field(image: Image, vmap: ValueMap, constituents: Sequence[str], *,
                interpolation: str = "linear", smoothing: float = 0.0) -> ImageField:
    """Map ``image``'s values with ``vmap`` and interpolate them (:class:`ImageField`)."""
    frac = vmap(image.values, image.source)
    return ImageField(frac, image, constituents, interpolation=interpolation,
                      smoothing=smoothing)


def covers(image: Image, bounds, where: str = "") -> None:
    """Raise :class:`MaterialError` unless the pixels of ``image`` cover the box ``bounds``
    ``(x0, y0, x1, y1)`` (up to 1e-9 of its size)."""
    lo, hi = image.extent()
    b = np.asarray(bounds, float).reshape(2, -1)
    tol = 1e-9 * float(np.abs(b).max() + np.ptp(b))
    if (b[0] < lo - tol).any() or (b[1] > hi + tol).any():
        def fmt(v):
            return "(" + ", ".join(f"{x:.6g}" for x in v) + ")"
        bad = b[0] if (b[0] < lo - tol).any() else b[1]
        raise _fail(where or image.source,
                    f"the image covers {fmt(lo)} - {fmt(hi)} but the domain reaches "
                    f"{fmt(bad)}: it must lie inside the image (check origin and spacing)")


# ---------------------------------------------------------------------------- label fields
class LabelField:
    """Phases of a label image, each a subregion with its own composition.

    Parameters
    ----------
    regions : callable ``points (N, 2) -> (N,) int``
        The subregion of each point (phase index into ``phases``), normally the traced,
        simplified label polygons (:func:`hetmesh.geometry.trace.region_lookup`).
    phases : list
        Per subregion, either a composition ``(m,)`` (a constant phase) or an
        :class:`ImageField` (a graded phase, its pixels outside the phase filled with the
        nearest pixel of the phase so that interpolation never mixes phases).
    names : list of str
        The subregion names (``"label 3"``).
    """

    def __init__(self, regions, phases: list, names: list[str],
                 constituents: Sequence[str], source: str = "labels"):
        self._regions = regions
        self.phases = phases
        self.region_names = list(names)
        self.constituents = tuple(constituents)
        self.source = source
        self._offset = np.zeros(2)

    def __repr__(self) -> str:
        return f"LabelField({self.source!r}, {self.n_regions} phases)"

    @property
    def n_regions(self) -> int:
        return len(self.phases)

    def describe_jump(self, a: int, b: int) -> str:
        return f"{self.source}: between {self.region_names[a]} and {self.region_names[b]}"

    def shifted(self, offset) -> "LabelField":
        import copy

        new = copy.copy(self)
        new._offset = self._offset + np.asarray(offset, float).reshape(2)
        return new

    def _points(self, points):
        p = as_points(points, repr(self))
        return p + self._offset if self._offset.any() else p

    def region(self, points) -> np.ndarray:
        """The phase (subregion id) of each point."""
        return np.asarray(self._regions(self._points(points)), dtype=np.int64)

    def _evaluate(self, points, region):
        p = self._points(points)
        r = self._regions(p) if region is None else np.broadcast_to(
            np.asarray(region, np.int64), (len(p),))
        m = len(self.constituents)
        comp = np.empty((len(p), m))
        grad = np.zeros((len(p), m, 2))
        for k, ph in enumerate(self.phases):
            sel = np.flatnonzero(r == k)
            if not len(sel):
                continue
            if isinstance(ph, ImageField):
                comp[sel], grad[sel] = ph.evaluate(p[sel])
            else:
                comp[sel] = ph
        return comp, grad

    def composition(self, points, region=None) -> np.ndarray:
        """Volume fractions ``(N, m)``; with ``region``, those of the given phases."""
        return self._evaluate(points, region)[0]

    def gradient(self, points, region=None) -> np.ndarray:
        """Gradients ``(N, m, 2)`` (zero in a constant phase)."""
        return self._evaluate(points, region)[1]


# ---------------------------------------------------------------------- pixel sampling
def pixel_centres_in_triangles(points: np.ndarray, triangles: np.ndarray, origin,
                               spacing, shape, *, block: int = 1 << 15):
    """The pixel centres each triangle covers.

    Parameters
    ----------
    points : ``(N, 2)``; triangles : ``(M, 3)``
    origin, spacing : ``(2,)`` centre of the first pixel and pixel size, x first
    shape : ``(ny, nx)``

    Returns
    -------
    element : ``(K,)`` int64
        The triangle of each (triangle, pixel) pair, ascending.
    pixel : ``(K,)`` int64
        The flat index ``j * nx + i`` of the pixel centre (closed triangles: a centre on a
        shared edge counts for both).

    Examples
    --------
    >>> e, p = pixel_centres_in_triangles(np.array([[0., 0], [4, 0], [0, 4]]),
    ...                                   np.array([[0, 1, 2]]), (0.5, 0.5), (1, 1), (4, 4))
    >>> p.tolist()
    [0, 1, 2, 3, 4, 5, 6, 8, 9, 12]
    """
    P = np.asarray(points, float)
    T = np.asarray(triangles, np.int64)
    o, s = np.asarray(origin, float), np.asarray(spacing, float)
    ny, nx = (int(v) for v in shape)
    out_e, out_p = [], []
    for b in range(0, len(T), block):
        tri = T[b:b + block]
        u = (P[tri] - o) / s  # (B, 3, 2) in index units
        lo = np.maximum(np.ceil(u.min(axis=1) - 1e-9).astype(np.int64), 0)
        hi = np.minimum(np.floor(u.max(axis=1) + 1e-9).astype(np.int64), [nx - 1, ny - 1])
        cnt = np.maximum(hi - lo + 1, 0)
        tot = cnt[:, 0] * cnt[:, 1]
        if not tot.sum():
            continue
        e = np.repeat(np.arange(len(tri)), tot)
        start = np.cumsum(tot) - tot
        k = np.arange(int(tot.sum())) - np.repeat(start, tot)
        i = lo[e, 0] + k % cnt[e, 0]
        j = lo[e, 1] + k // cnt[e, 0]
        q = np.column_stack([i, j]).astype(float)
        a, bb, c = u[e, 0], u[e, 1], u[e, 2]
        d = _cross(bb - a, c - a)
        eps = 1e-12 * np.abs(d)
        l1 = _cross(bb - q, c - q) * np.sign(d)
        l2 = _cross(c - q, a - q) * np.sign(d)
        l3 = _cross(a - q, bb - q) * np.sign(d)
        ins = (l1 >= -eps) & (l2 >= -eps) & (l3 >= -eps)
        out_e.append(e[ins] + b)
        out_p.append(j[ins] * nx + i[ins])
    if not out_e:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(out_e), np.concatenate(out_p)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def element_pixel_delta(field: ImageField, points: np.ndarray, triangles: np.ndarray,
                        vertex_composition: np.ndarray | None = None) -> np.ndarray:
    """delta(T) ``(M,)`` over every pixel centre each element covers *and* its vertices.

    The values at the pixel centres are the field's samples there (``field.samples``, the
    mapped and smoothed pixels); an element that covers no pixel centre is judged by its
    vertices alone (vertex interpolation complements the pixel sampling). delta is the
    largest spread (max - min) of a constituent's fraction over those samples.
    """
    P = np.asarray(points, float)
    T = np.asarray(triangles, np.int64)
    vc = field.composition(P) if vertex_composition is None else vertex_composition
    corners = vc[T]  # (M, 3, m)
    hi, lo = corners.max(axis=1), corners.min(axis=1)
    e, pix = pixel_centres_in_triangles(P, T, field.origin - field._offset, field.spacing,
                                        field.shape)
    if len(e):
        vals = field.samples.reshape(len(field.constituents), -1)[:, pix].T  # (K, m)
        np.maximum.at(hi, e, vals)
        np.minimum.at(lo, e, vals)
    return (hi - lo).max(axis=1)
