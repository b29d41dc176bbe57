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
from ...topology import unique
from .parse import (
    check_phases,
    fill_phase,
    label_values,
    parse_constituents,
    parse_phases,
    parse_sampling,
    parse_value_map,
    place_image,
    scalar_values,
)

__all__ = ["read_volume", "parse_volume", "volume_solid", "mask_solid", "VOLUME_KEYS"]

#: keys of ``[material] type = "image"`` in a 3D model
VOLUME_KEYS = ("type", "constituents", "file", "labels", "phases", "map", "spacing", "origin",
               "bounds", "first_row", "array", "interpolation", "smoothing")


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
        lab = _read(ctx, "material.labels", table["labels"], table)
        if lab.dim != 3:
            return None  # a 2-D label image: the section of an extrusion
        out = {"labels": label_values(ctx, lab), "geometry": lab}
        f = table.get("file")
        if isinstance(f, Mapping):
            raise ctx.fail("material.file", "the graded phases of a label volume take one "
                                            "grey volume (file = \"...\")")
        if f is not None:
            img = _read(ctx, "material.file", f, table, lab.shape)
            if img.dim != 3:
                raise MaterialError(f"{img.source}: a 2-D image, but the labels are a volume")
            out["image"] = img
        return out
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
    labels = src.get("labels")
    if how == "extent":
        if labels is None:
            lo, hi = geo.extent()
            return box(lo, hi, where=ctx.where), src
        return mask_solid(ctx, np.ones(labels.shape, bool), geo, labels), src
    if "mask" in t:
        mimg = _read(ctx, "solid.mask", t["mask"], mtable, geo.shape)
        if mimg.dim != 3:
            raise MaterialError(f"{mimg.source}: a 2-D image; a solid's mask must be a volume "
                                f"(a TIFF stack, 3-D .npy, .vti or .nrrd)")
        return mask_solid(ctx, scalar_values(ctx, "solid.mask", mimg) != 0, mimg, labels), src
    if labels is None:
        raise ctx.fail("solid.mask", "image = \"mask\" needs a mask volume (solid.mask = "
                                     "\"...\") or a label volume (material.labels, label 0 "
                                     "outside)")
    return mask_solid(ctx, labels != 0, geo, labels), src


def mask_solid(ctx, inside: np.ndarray, img, labels: np.ndarray | None = None):
    """The :class:`~hetmesh.tet.masked.VoxelSolid` of the voxels ``inside`` of ``img``
    (its largest face-connected region), with the phases of ``labels`` inside it."""
    from ...tet.masked import VoxelSolid, largest_component

    kept = largest_component(inside, where=img.source)
    phases = () if labels is None else tuple(unique(labels[kept]).tolist())
    return VoxelSolid(kept, img.origin, img.spacing, source=img.source, where=ctx.where,
                      labels=labels, phases=phases)


def parse_volume(ctx, table, solid, src: dict):
    """``[material] type = "image"`` with a volume: an
    :class:`~hetmesh.material.image.ImageField` of ``dim`` 3 that covers ``solid``."""
    from . import covers, image_field

    t = ctx.table(table, "material", required=("type", "constituents"), optional=VOLUME_KEYS)
    if "labels" not in src and "phases" in t:
        raise ctx.fail("material.phases", "phases need a label volume (material.labels)")
    cons = parse_constituents(ctx, t)
    interp, sigma = parse_sampling(ctx, t)
    geo = src["geometry"]
    lo, hi = solid.bounds
    covers(geo, np.concatenate([lo, hi]), geo.source)
    if "labels" in src:
        return _label_volume(ctx, t, solid, src, cons, dict(interpolation=interp,
                                                            smoothing=sigma))
    if "map" not in t:
        raise ModelFileError(f"{ctx.pre}missing key 'material.map' (how voxel values become "
                             f"volume fractions)")
    vmap = parse_value_map(ctx, "material.map", t["map"], cons, src)
    opts = dict(interpolation=interp, smoothing=sigma)
    if "files" in src:
        stacked = np.stack([scalar_values(ctx, "material.file", im).astype(float)
                            for im in src["files"].values()], axis=-1)
        img = replace(geo, values=stacked, channels=True,
                      source=", ".join(im.source for im in src["files"].values()))
        return image_field(img, vmap, cons, **opts)
    return image_field(src["image"], vmap, cons, **opts)


def _label_volume(ctx, t, solid, src, cons, opts):
    """A label volume's :class:`~hetmesh.material.image.LabelField` of ``dim`` 3: a phase
    per label inside ``solid`` (a :class:`~hetmesh.tet.masked.VoxelSolid`, whose
    :meth:`~hetmesh.tet.masked.VoxelSolid.phase` decides the phase of a point, as its cuts
    do), constant or graded from the grey volume inside the phase."""
    from ...tet.masked import VoxelSolid
    from . import ImageField, LabelField

    if not isinstance(solid, VoxelSolid):
        raise ctx.fail("solid", "a label volume needs [solid] image = \"mask\" or \"extent\" "
                                "(its phases' contours become surfaces of the mesh)")
    if "map" in t:
        raise ctx.fail("material.map", "with a label volume every phase has its own map "
                                       "([[material.phases]] map = ...)")
    phases = t.get("phases", [])
    if not isinstance(phases, list):
        raise ctx.fail("material.phases", f"expected an array of tables ([[material.phases]]),"
                                          f" got {describe(phases)}")
    labels = src["labels"]
    spec = parse_phases(ctx, phases, cons, src)
    check_phases(spec, np.asarray(solid.phases), np.where(solid.inside, labels, -1),
                 src["geometry"].source)
    fields = []
    for lab in solid.phases:
        what = spec[lab][1]
        if isinstance(what, np.ndarray):
            fields.append(what)
            continue
        img = src["image"]
        inside = labels == lab
        frac = what(img.values, img.source, mask=inside)
        fields.append(ImageField(fill_phase(frac, inside), img, cons, **opts))
    return LabelField(solid.phase, fields, [spec[lab][0] for lab in solid.phases], cons,
                      source=src["geometry"].source, dim=3)
