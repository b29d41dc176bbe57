"""``[material] type = "image"`` in a 3D model (a ``[solid]`` table): a volume (TIFF stack,
3-D ``.npy``, ``.vti``, NRRD) as an :class:`~hetmesh.material.image.ImageField` on
``(N, 3)`` points, ``[solid] image = "extent"``, the box the voxels cover, and
``[solid] image = "mask"``, the non-zero voxels of a mask volume (schema in
docs/model-format.md, "Volumes").
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from ...errors import MaterialError, ModelFileError
from ...io.schema import describe
from .parse import parse_constituents, parse_value_map, place_image, scalar_values

__all__ = ["read_volume", "parse_volume", "volume_solid", "mask_solid", "VOLUME_KEYS"]

#: keys of ``[material] type = "image"`` in a 3D model
VOLUME_KEYS = ("type", "constituents", "file", "map", "spacing", "origin", "bounds",
               "first_row", "array", "interpolation", "smoothing")


def _read(ctx, key: str, value, t: Mapping, shape=None):
    from . import read_image

    if not isinstance(value, str) or not value.strip():
        raise ctx.fail(key, f"expected a file name, got {describe(value)}")
    path = Path(value) if os.path.isabs(value) else ctx.base / value
    img = read_image(path, array=ctx.string(t, "material", "array"))
    if img.dim != 3:
        return img
    img = _geometry3d(ctx, t, img)
    if shape is not None and img.shape != shape:
        raise MaterialError(f"{img.source}: {' x '.join(map(str, img.shape[::-1]))} voxels, "
                            f"but the other volumes have {' x '.join(map(str, shape[::-1]))}")
    return img


def _triple(ctx, v, key: str) -> tuple[float, float, float]:
    ok = isinstance(v, list) and len(v) == 3 and all(
        isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in v)
    if not ok:
        raise ctx.fail(key, f"expected [x, y, z], 3 finite numbers, got {describe(v)}")
    return tuple(float(c) for c in v)


def _geometry3d(ctx, t: Mapping, img):
    """``img`` with the row order, origin, spacing and bounds the model file gives."""
    return place_image(ctx, t, img, lambda v, key: _triple(ctx, v, key), npy_raster=False)


def read_volume(ctx, table) -> dict | None:
    """The volumes of ``[material] type = "image"`` in a 3D model: ``{"image" or "files",
    "geometry"}``, or None if ``file`` is a 2-D image (the model is then an extruded or
    revolved 2D image model) or a ``slice`` is asked for."""
    if not isinstance(table, Mapping) or "slice" in table:
        return None
    if "labels" in table:
        if _read(ctx, "material.labels", table["labels"], table).dim == 3:
            raise ctx.fail("material.labels", "label volumes are not available for 3D "
                                              "models yet (a 2-D label image can be extruded)",
                           MaterialError)
        return None
    f = table.get("file")
    if f is None:
        return None
    if isinstance(f, Mapping):
        files, shape = {}, None
        for name, fname in f.items():
            img = _read(ctx, f"material.file.{name}", fname, table, shape)
            if img.dim != 3:
                if files:
                    raise MaterialError(f"{img.source}: a 2-D image, but the other files are "
                                        f"volumes")
                return None
            files[name] = img
            shape = img.shape
        return {"files": files, "geometry": next(iter(files.values()))}
    img = _read(ctx, "material.file", f, table)
    if img.dim != 3:
        return None
    return {"image": img, "geometry": img}


def volume_solid(ctx, value: Mapping, mtable):
    """``[solid] image = "extent"``: the box the voxels of the material's volume cover;
    ``image = "mask"``: the non-zero voxels of a mask volume
    (:class:`~hetmesh.tet.masked.VoxelSolid`). Returns the solid and the volumes read (for
    :func:`parse_volume`)."""
    from ...tet.solid import box

    t = ctx.table(value, "solid", required=("image",), optional=("mask",))
    how = t["image"]
    if how not in ("extent", "mask"):
        raise ctx.fail("solid.image", f"expected \"extent\" (the box the voxels cover) or "
                                      f"\"mask\" (the non-zero voxels of a mask), got "
                                      f"{describe(how)}")
    if not isinstance(mtable, Mapping) or mtable.get("type") != "image":
        raise ctx.fail("solid.image", "a solid taken from a volume needs [material] type = "
                                      "\"image\"")
    if "mask" in t and how != "mask":
        raise ctx.fail("solid.mask", "a mask file needs image = \"mask\"")
    src = read_volume(ctx, mtable)
    if src is None:
        raise ctx.fail("solid.image", "the material's file is not a volume (a TIFF stack, "
                                      "3-D .npy, .vti or .nrrd)", MaterialError)
    geo = src["geometry"]
    if how == "extent":
        lo, hi = geo.extent()
        return box(lo, hi, where=ctx.where), src
    if "mask" not in t:
        raise ctx.fail("solid.mask", "image = \"mask\" needs a mask volume (solid.mask = "
                                     "\"...\")")
    mimg = _read(ctx, "solid.mask", t["mask"], mtable, geo.shape)
    if mimg.dim != 3:
        raise MaterialError(f"{mimg.source}: a 2-D image; a solid's mask must be a volume "
                            f"(a TIFF stack, 3-D .npy, .vti or .nrrd)")
    return mask_solid(ctx, scalar_values(ctx, "solid.mask", mimg) != 0, mimg), src


def mask_solid(ctx, inside: np.ndarray, img):
    """The :class:`~hetmesh.tet.masked.VoxelSolid` of the voxels ``inside`` of ``img``
    (its largest face-connected region)."""
    from ...tet.masked import VoxelSolid, largest_component

    kept = largest_component(inside, where=img.source)
    return VoxelSolid(kept, img.origin, img.spacing, source=img.source, where=ctx.where)


def parse_volume(ctx, table, solid, src: dict):
    """``[material] type = "image"`` with a volume: an
    :class:`~hetmesh.material.image.ImageField` of ``dim`` 3 that covers ``solid``."""
    from . import covers, image_field

    t = ctx.table(table, "material", required=("type", "constituents"), optional=VOLUME_KEYS)
    cons = parse_constituents(ctx, t)
    interp = ctx.string(t, "material", "interpolation", default="linear")
    if interp not in ("linear", "cubic"):
        raise ctx.fail("material.interpolation", f"expected \"linear\" or \"cubic\", got "
                                                 f"{interp!r}")
    sigma = ctx.number(t.get("smoothing", 0.0), "material.smoothing")
    if sigma < 0:
        raise ctx.fail("material.smoothing", f"expected a number >= 0, got {sigma:g}")
    if "map" not in t:
        raise ModelFileError(f"{ctx.pre}missing key 'material.map' (how voxel values become "
                             f"volume fractions)")
    geo = src["geometry"]
    lo, hi = solid.bounds
    covers(geo, np.concatenate([lo, hi]), geo.source)
    vmap = parse_value_map(ctx, "material.map", t["map"], cons, src)
    opts = dict(interpolation=interp, smoothing=sigma)
    if "files" in src:
        stacked = np.stack([scalar_values(ctx, "material.file", im).astype(float)
                            for im in src["files"].values()], axis=-1)
        img = replace(geo, values=stacked, channels=True,
                      source=", ".join(im.source for im in src["files"].values()))
        return image_field(img, vmap, cons, **opts)
    return image_field(src["image"], vmap, cons, **opts)
