"""Image and volume readers: PNG and other rasters (imageio), TIFF (tifffile), NumPy
``.npy``, VTK ImageData ``.vti`` (a small XML reader of our own) and NRRD (pynrrd), into
:class:`Image` (conventions in :mod:`hetmesh.material.image`).
"""

from __future__ import annotations

import base64
import logging
import math
import os
import xml.etree.ElementTree as ET
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ...errors import MaterialError

__all__ = ["Image", "read_image", "RASTER_SUFFIXES", "SUFFIXES", "MAX_PIXELS"]

log = logging.getLogger(__name__)

RASTER_SUFFIXES = (".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg")
SUFFIXES = RASTER_SUFFIXES + (".npy", ".vti", ".nrrd", ".nhdr")
#: images larger than this many samples are refused (a 16k x 16k image, a 640^3 volume)
MAX_PIXELS = 1 << 28


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


def image_error(where: str, problem: str) -> MaterialError:
    """The error ``<where>: <problem>`` of an image that cannot serve as a field."""
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
        raise image_error(where, "no such image file")
    if p.is_dir():
        raise image_error(where, "is a directory, not an image file")
    suffix = p.suffix.lower()
    if suffix not in SUFFIXES:
        raise image_error(where, f"unsupported image format {suffix or '(no suffix)'!r} (expected "
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
        raise image_error(where, "image too large for memory") from None
    except Exception as exc:  # noqa: BLE001 - any reader failure is a bad file
        raise image_error(where, f"cannot read the {suffix[1:].upper()} file (corrupt or "
                                 f"truncated?): {_first_line(exc)}") from None
    return _checked(img, where)


def _checked(img: Image, where: str) -> Image:
    v = img.values
    if v.dtype.kind == "b":
        v = v.astype(np.uint8)
    if v.dtype.kind not in "uif" or v.dtype.itemsize > 8:
        raise image_error(where, f"unsupported pixel type {v.dtype} (expected integers or floats)")
    if img.dim not in (2, 3):
        raise image_error(where, f"expected a 2-D image or a 3-D volume, got an array of shape "
                                 f"{v.shape}")
    if v.size > MAX_PIXELS:
        raise image_error(where, f"{v.size:,} samples, more than the {MAX_PIXELS:,} accepted")
    if min(img.shape) < 1:
        raise image_error(where, f"the image is empty (shape {v.shape})")
    if v.dtype.kind == "f" and not np.isfinite(v).all():
        idx = np.argwhere(~np.isfinite(v))[0]
        raise image_error(where, f"pixel {pixel_index(idx[:img.dim])} is not finite "
                                 f"({v[tuple(idx)]})")
    _check_geometry(img.origin, img.spacing, img.dim, where)
    return replace(img, values=v, origin=tuple(float(o) for o in img.origin),
                   spacing=tuple(float(s) for s in img.spacing), source=where)


def _check_geometry(origin, spacing, dim: int, where: str) -> None:
    if len(spacing) != dim or len(origin) != dim:
        raise image_error(where, f"spacing {list(spacing)} and origin {list(origin)} must have "
                                 f"{dim} values each")
    for s in spacing:
        if not (math.isfinite(float(s)) and float(s) > 0.0):
            raise image_error(where, f"spacing {[float(v) for v in spacing]} must be positive and "
                                     f"finite")
    if not all(math.isfinite(float(o)) for o in origin):
        raise image_error(where, f"origin {[float(v) for v in origin]} must be finite")


def pixel_index(idx) -> str:
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


class _Errors(logging.Handler):
    """Collects the error records a reader logs instead of raising (tifffile logs a broken
    page chain or an ImageJ stack cut short, and falls back to the pages it could read)."""

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage().strip().splitlines() or [record.levelname]
        self.messages.append(text[0].split("> ", 1)[-1] if text[0].startswith("<") else text[0])


def _read_tiff(p: Path, where: str) -> Image:
    import tifffile

    errors = _Errors()
    tlog = logging.getLogger("tifffile")
    tlog.addHandler(errors)
    try:
        with tifffile.TiffFile(p) as tif:
            series = tif.series[0]
            axes = series.axes
            v = np.asarray(series.asarray())
            page = tif.pages[0]
            ij = tif.imagej_metadata or {}
            tags = page.tags
    finally:
        tlog.removeHandler(errors)
    if errors.messages:
        raise image_error(where, f"cannot read the TIF file (corrupt or truncated?): "
                                 f"{errors.messages[0]}")
    spacing = None
    unit = str(ij.get("unit", "")).strip().lower()
    if unit and unit not in ("pixel", "pixels", "none") and "XResolution" in tags:
        xr, yr = tags["XResolution"].value, tags["YResolution"].value
        spacing = [xr[1] / xr[0], yr[1] / yr[0]]
    if "C" in axes and "Z" not in axes and v.shape[axes.index("C")] > 4:
        # tifffile's ImageJ writer files an unlabelled 3-D array as channels (CYX); more than
        # four of them are a stack of slices, as the other readers take them
        axes = axes.replace("C", "Z")
    chan = [i for i, a in enumerate(axes) if a in "CS"]
    if len(chan) > 1:
        raise image_error(where, f"TIFF axes {axes!r}: more than one channel axis")
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
            raise image_error(where, "holds Python objects, not numbers (refused: a .npy image "
                                     "must be a plain numeric array)") from None
        raise
    v = np.asarray(v)
    if v.dtype.kind not in "uifb":
        raise image_error(where, f"unsupported pixel type {v.dtype} (expected integers or floats)")
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
                raise image_error(where, "the NRRD 'space directions' are not along the axes; "
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
        raise image_error(where, f"not a VTK ImageData file (type {root.get('type')!r})")
    order = "<" if root.get("byte_order", "LittleEndian") == "LittleEndian" else ">"
    header = "u8" if root.get("header_type", "UInt32") == "UInt64" else "u4"
    compressed = root.get("compressor") is not None
    if compressed and "ZLib" not in root.get("compressor", ""):
        raise image_error(where, f"unsupported compressor {root.get('compressor')!r} (zlib only)")
    enc = root.find("AppendedData")
    img = root.find("ImageData")
    if img is None:
        raise image_error(where, "no <ImageData> element")
    ext = [int(v) for v in img.get("WholeExtent", "").split()]
    origin = [float(v) for v in img.get("Origin", "0 0 0").split()]
    spacing = [float(v) for v in img.get("Spacing", "1 1 1").split()]
    if len(ext) != 6 or len(origin) != 3 or len(spacing) != 3:
        raise image_error(where, "WholeExtent, Origin or Spacing is malformed")
    direction = img.get("Direction")
    if direction and not np.allclose(np.array(direction.split(), float).reshape(3, 3),
                                     np.eye(3)):
        raise image_error(where, "a Direction other than the identity (rotated image) is not "
                                 "supported")
    arrays, cell = _vti_arrays(img)
    if not arrays:
        raise image_error(where, "no PointData or CellData array")
    names = [a.get("Name", f"array {i}") for i, a in enumerate(arrays)]
    if array is None:
        pick = 0
    elif array in names:
        pick = names.index(array)
    else:
        raise image_error(where, f"no data array {array!r} (it has: {', '.join(names)})")
    da = arrays[pick]
    dims = [ext[1] - ext[0] + 1, ext[3] - ext[2] + 1, ext[5] - ext[4] + 1]
    if cell:  # values at cell centres
        dims = [max(d - 1, 1) for d in dims]
        origin = [o + 0.5 * s for o, s in zip(origin, spacing)]
    ncomp = int(da.get("NumberOfComponents", "1"))
    dtype = _VTK_TYPES.get(da.get("type", ""))
    if dtype is None:
        raise image_error(where, f"unsupported data type {da.get('type')!r}")
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
            raise image_error(where, f"data array holds {len(vals)} values, expected {count}")
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
            raise image_error(where, "base64-encoded appended data is not supported (use raw or "
                                     "inline binary)")
        blob = appended[off:]
        if compressed:
            nblocks = int(np.frombuffer(blob[:hsize], hdt)[0])
            hdr = np.frombuffer(blob[:(3 + nblocks) * hsize], hdt)
            return _inflate(hdr, blob[(3 + nblocks) * hsize:], dtype, count, where)
        nbytes = int(np.frombuffer(blob[:hsize], hdt)[0])
        return _exact(blob[hsize:hsize + nbytes], dtype, count, where)
    raise image_error(where, f"unsupported data array format {fmt!r}")


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
        raise image_error(where, f"truncated data: {len(blob)} bytes, expected {need}")
    return np.frombuffer(blob[:need], dtype).astype(dtype.newbyteorder("="))
