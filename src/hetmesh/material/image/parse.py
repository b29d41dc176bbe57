"""The ``[material] type = "image"`` parser, and ``[domain] image = "extent" | "mask"``
(schema in docs/model-format.md): model-file tables -> image fields and traced domains.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import replace as _replace
from pathlib import Path

import numpy as np

from ...errors import GeometryError, MaterialError, ModelFileError
from ...io.schema import describe
from ...topology import unique

__all__ = ["parse_image", "parse_image_model", "parse_constituents", "parse_sampling",
           "parse_value_map", "scalar_values", "parse_phases", "check_phases", "label_values",
           "fill_phase"]


#: keys of ``[material] type = "image"``
_IMAGE_KEYS = ("type", "constituents", "file", "labels", "phases", "map", "spacing", "origin",
               "bounds", "first_row", "slice", "array", "interpolation", "smoothing")


def parse_image_model(ctx, dtable, mtable):
    """``[domain] image = "extent" | "mask"``: the domain taken from the material's image."""
    from ...tri.geometry.trace import DEFAULT_TOL, OUTSIDE, extent_domain, label_domain, mask_domain

    t = ctx.table(dtable, "domain", required=("image",), optional=("mask", "tolerance"))
    how = t["image"]
    if how not in ("extent", "mask"):
        raise ctx.fail("domain.image", f"expected \"extent\" or \"mask\", got "
                                       f"{describe(how)}")
    if not isinstance(mtable, Mapping) or mtable.get("type") != "image":
        raise ctx.fail("domain.image", "a domain taken from an image needs [material] "
                                       "type = \"image\"")
    tol = ctx.number(t.get("tolerance", DEFAULT_TOL), "domain.tolerance")
    if not 0 <= tol <= 10:
        raise ctx.fail("domain.tolerance", f"expected pixels in [0, 10], got {tol:g}")
    if "mask" in t and how != "mask":
        raise ctx.fail("domain.mask", "a mask file needs image = \"mask\"")
    src = _image_sources(ctx, mtable)
    shape, geo = src["shape"], src["geometry"]
    labels = src.get("labels")
    if how == "extent" and labels is None:
        lo, hi = geo.extent()
        domain = extent_domain(lo, hi)
        return domain, parse_image(ctx, mtable, domain, None, src)
    if how == "extent":  # the whole image, its label boundaries traced as interfaces
        mask = np.ones(labels.shape, bool)
    elif "mask" in t:
        mimg = _read(ctx, "domain.mask", t["mask"], mtable, shape)
        mask = scalar_values(ctx, "domain.mask", mimg) != 0
    elif labels is not None:
        mask = labels != 0
    else:
        raise ctx.fail("domain.mask", "image = \"mask\" needs a mask file (domain.mask) or a "
                                      "label image (material.labels, label 0 outside)")
    where = f"{ctx.pre}domain"
    try:
        if labels is None:
            domain = mask_domain(mask, geo.origin, geo.spacing, tol=tol, where=where)
            return domain, parse_image(ctx, mtable, domain, None, src)
        lab = np.where(mask, labels, OUTSIDE)
        domain, chains, lab = label_domain(lab, geo.origin, geo.spacing, tol=tol, where=where)
    except (GeometryError, MaterialError) as exc:
        raise ctx.wrap("domain", exc) from None
    return domain, parse_image(ctx, mtable, domain, None, src, (chains, lab, tol))


def _read(ctx, key: str, value, mtable, shape=None):
    """Read one image file named at ``key`` with the geometry keys of ``mtable``."""
    from . import read_image

    if not isinstance(value, str) or not value.strip():
        raise ctx.fail(key, f"expected a file name, got {describe(value)}")
    path = Path(value) if os.path.isabs(value) else ctx.base / value
    array = ctx.string(mtable, "material", "array")
    img = read_image(path, array=array)
    img = _geometry(ctx, mtable, img)
    if shape is not None and img.shape != shape:
        raise MaterialError(f"{img.source}: {img.shape[1]} x {img.shape[0]} pixels, but the "
                            f"other images have {shape[1]} x {shape[0]}")
    return img


def _geometry(ctx, t: Mapping, img):
    """``img`` with the slice, row order, origin, spacing and bounds the model file gives."""
    if "slice" in t:
        k = t["slice"]
        if isinstance(k, bool) or not isinstance(k, int):
            raise ctx.fail("material.slice", f"expected an integer, got {describe(k)}")
        if img.dim != 3:
            raise ctx.fail("material.slice", f"{img.source} is a 2-D image, not a volume")
        if not 0 <= k < img.shape[0]:
            raise ctx.fail("material.slice", f"{k} is outside [0, {img.shape[0]}) (the "
                                             f"number of slices of {img.source})")
        img = _replace(img, values=img.values[k], origin=img.origin[:2],
                       spacing=img.spacing[:2])
    if img.dim == 3:
        raise MaterialError(f"{img.source}: a 3-D volume of {img.shape[0]} slices; 2-D "
                            f"meshing needs one of them (material.slice = k)")
    return place_image(ctx, t, img, ctx.point, npy_raster=True)


def place_image(ctx, t: Mapping, img, coords, npy_raster: bool):
    """``img`` (2-D or a volume) with the row order (``first_row``), origin, spacing or
    bounds the model file's table ``t`` gives. ``coords(value, key)`` parses a point of the
    image's dimension; ``npy_raster``: whether a ``.npy`` file is stored top row first (a
    2-D array of rows is; the slices of a volume are not)."""
    d = img.dim
    if "first_row" in t:
        row = ctx.string(t, "material", "first_row")
        if row not in ("top", "bottom"):
            raise ctx.fail("material.first_row", f"expected \"top\" or \"bottom\", got "
                                                 f"{row!r}")
        from . import RASTER_SUFFIXES

        raster = Path(img.source).suffix.lower() in RASTER_SUFFIXES + (
            (".npy",) if npy_raster else ())
        if (row == "bottom") == raster:  # undo the reader's flip, or flip
            img = _replace(img, values=np.ascontiguousarray(np.flip(img.values, axis=d - 2)))
    n = np.array(img.shape[::-1], float)
    if "bounds" in t:
        if "origin" in t or "spacing" in t:
            raise ctx.fail("material.bounds", "give either bounds or origin/spacing, not both")
        b = t["bounds"]
        ok = isinstance(b, list) and len(b) == 2 * d and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in b)
        names = "xyz"[:d]
        if not ok:
            want = ", ".join([f"{c}0" for c in names] + [f"{c}1" for c in names])
            raise ctx.fail("material.bounds", f"expected [{want}], got {describe(b)}")
        lo, hi = np.array(b[:d], float), np.array(b[d:], float)
        if (hi <= lo).any():
            need = " and ".join([", ".join(f"{c}1 > {c}0" for c in names[:-1]),
                                 f"{names[-1]}1 > {names[-1]}0"])
            raise ctx.fail("material.bounds", f"spacing <= 0: {need} needed, got "
                                              f"{describe(b)}")
        sp = (hi - lo) / n
        return _replace(img, origin=tuple(lo + 0.5 * sp), spacing=tuple(sp))
    sp, org = img.spacing, img.origin
    if "spacing" in t:
        v = t["spacing"]
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            v = [v] * d
        s = coords(v, "material.spacing")
        if min(s) <= 0:
            raise ctx.fail("material.spacing", f"spacing must be positive, got {list(s)}")
        sp = s
        if "origin" not in t and not img.origin_from_file:
            org = tuple(0.5 * np.asarray(s))
    if "origin" in t:
        org = coords(t["origin"], "material.origin")
    return _replace(img, origin=tuple(float(o) for o in org),
                    spacing=tuple(float(s) for s in sp))


def scalar_values(ctx, key: str, img) -> np.ndarray:
    if img.channels:
        raise MaterialError(f"{img.source}: {img.values.shape[-1]} channels; {key} needs a "
                            f"single-channel image")
    return img.values


def _image_sources(ctx, t) -> dict:
    """The images of an image material: ``{"image", "labels", "files", "shape",
    "geometry"}`` (the image whose geometry all share)."""
    t = ctx.table(t, "material", required=("type", "constituents"), optional=_IMAGE_KEYS)
    if "file" not in t and "labels" not in t:
        raise ModelFileError(f"{ctx.pre}missing key 'material.file' (an image material needs "
                             f"file = \"...\", a table of files, or labels = \"...\")")
    out: dict = {}
    shape = None
    if "labels" in t:
        lab = _read(ctx, "material.labels", t["labels"], t)
        out["labels"], shape, out["geometry"] = label_values(ctx, lab), lab.shape, lab
    f = t.get("file")
    if isinstance(f, Mapping):
        out["files"] = {}
        for name, fname in f.items():
            img = _read(ctx, f"material.file.{name}", fname, t, shape)
            out["files"][name] = img
            shape = shape or img.shape
            out.setdefault("geometry", img)
    elif f is not None:
        img = _read(ctx, "material.file", f, t, shape)
        out["image"] = img
        shape = shape or img.shape
        out.setdefault("geometry", img)
    out["shape"] = shape
    return out


def label_values(ctx, img) -> np.ndarray:
    """The labels of a label image or volume ``img`` as int64, checked: integers >= 0."""
    v = scalar_values(ctx, "material.labels", img)
    what = "pixel" if v.ndim == 2 else "voxel"
    if v.dtype.kind not in "ui":
        raise MaterialError(f"{img.source}: a label {'image' if v.ndim == 2 else 'volume'} "
                            f"needs integer {what}s, got {v.dtype}")
    if v.size and v.min() < 0:
        idx = np.argwhere(v < 0)[0]
        at = ", ".join(str(int(c)) for c in idx[::-1])
        raise MaterialError(f"{img.source}: label {v[tuple(idx)]} at {what} ({at}): labels "
                            f"must be >= 0")
    return v.astype(np.int64)


def parse_sampling(ctx, t) -> tuple[str, float]:
    """``material.interpolation`` ("linear" or "cubic") and ``material.smoothing`` (>= 0,
    model units) of an image material."""
    interp = ctx.string(t, "material", "interpolation", default="linear")
    if interp not in ("linear", "cubic"):
        raise ctx.fail("material.interpolation", f"expected \"linear\" or \"cubic\", got "
                                                 f"{interp!r}")
    sigma = ctx.number(t.get("smoothing", 0.0), "material.smoothing")
    if sigma < 0:
        raise ctx.fail("material.smoothing", f"expected a number >= 0, got {sigma:g}")
    return interp, sigma


def parse_constituents(ctx, t) -> tuple[str, ...]:
    from ..analytic import check_constituents

    cons = t["constituents"]
    if not isinstance(cons, list) or not all(isinstance(c, str) for c in cons):
        raise ctx.fail("material.constituents", f"expected an array of names, got "
                                                f"{describe(cons)}")
    try:
        return check_constituents(cons)
    except MaterialError as exc:
        raise ctx.fail("material.constituents", str(exc).split(": ", 1)[-1]) from None


def parse_value_map(ctx, key: str, value, cons, src):
    """A ``map = {...}`` table -> :class:`~hetmesh.material.image.ValueMap`."""
    from . import channel_map, linear_map, table_map

    if not isinstance(value, Mapping):
        raise ctx.fail(key, f"expected a table, got {describe(value)}")
    kinds = [k for k in ("linear", "levels", "channels") if k in value]
    if "files" in src:
        kinds = ["files"]
    if len(kinds) != 1:
        raise ctx.fail(key, "give one of: linear = [g0, g1], levels = [...] with fractions, "
                            "channels = {...} (with range)")
    kind = kinds[0]
    m = len(cons)
    if kind == "linear":
        t = ctx.table(value, key, required=("linear", "constituent"))
        g = ctx.point(t["linear"], f"{key}.linear")
        c = ctx.string(t, key, "constituent")
        if c not in cons:
            raise ctx.fail(f"{key}.constituent", f"{c!r} is not a constituent (expected one "
                                                 f"of: {', '.join(cons)})")
        if m != 2:
            raise ctx.fail(key, f"a linear map needs 2 constituents, got {m}; use levels")
        if g[0] == g[1]:
            raise ctx.fail(f"{key}.linear", "the two grey levels must differ")
        return linear_map(g[0], g[1], cons.index(c), m)
    if kind == "levels":
        t = ctx.table(value, key, required=("levels", "fractions"))
        lv = t["levels"]
        if not (isinstance(lv, list) and len(lv) >= 2):
            raise ctx.fail(f"{key}.levels", f"expected at least 2 grey levels, got "
                                            f"{describe(lv)}")
        levels = [ctx.number(v, f"{key}.levels[{i}]") for i, v in enumerate(lv)]
        fr = _per_constituent(ctx, f"{key}.fractions", t["fractions"], cons,
                              lambda v, k: _numbers(ctx, v, k, len(levels)))
        try:
            return table_map(levels, _complete(fr, cons, len(levels)).T)
        except MaterialError as exc:
            raise ctx.fail(key, str(exc), MaterialError) from None
    t = ctx.table(value, key, required=("range",) + (("channels",) if kind == "channels"
                                                       else ()))
    r = ctx.point(t["range"], f"{key}.range")
    if kind == "channels":
        ch = _per_constituent(ctx, f"{key}.channels", t["channels"], cons,
                              lambda v, k: _channel(ctx, v, k))
        img = src.get("image")
        if img is None or not img.channels:
            raise ctx.fail(f"{key}.channels", "the image has one channel; channels need a "
                                              "colour or multi-channel image")
        integer = img.values.dtype.kind in "ui"
    else:
        ch = {name: i for i, name in enumerate(src["files"])}
        integer = all(im.values.dtype.kind in "ui" for im in src["files"].values())
    index = [ch.get(c, -1) for c in cons]
    try:
        return channel_map(index, r[0], r[1], integer=integer)
    except MaterialError as exc:
        raise ctx.fail(f"{key}.range", str(exc), MaterialError) from None


def _channel(ctx, v, k) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise ctx.fail(k, f"expected a channel number >= 0, got {describe(v)}")
    return v


def _numbers(ctx, v, k, n) -> list[float]:
    if not isinstance(v, list) or len(v) != n:
        raise ctx.fail(k, f"expected {n} numbers (one per level), got {describe(v)}")
    return [ctx.number(x, f"{k}[{i}]") for i, x in enumerate(v)]


def _per_constituent(ctx, key, value, cons, item) -> dict:
    """A table keyed by constituent names, all of them or all but one."""
    if not isinstance(value, Mapping):
        raise ctx.fail(key, f"expected a table keyed by constituent, got {describe(value)}")
    out = {}
    for name, v in value.items():
        if name not in cons:
            raise ModelFileError(f"{ctx.pre}unknown key '{key}.{name}': not a constituent "
                                 f"(expected one of: {', '.join(cons)})")
        out[name] = item(v, f"{key}.{name}")
    missing = [c for c in cons if c not in out]
    if len(missing) > 1:
        raise ModelFileError(f"{ctx.pre}missing key '{key}.{missing[-1]}' (give all "
                             f"{len(cons)} constituents, or all but one: it is then 1 - the "
                             f"sum of the others)")
    return out


def _complete(fr: dict, cons, n: int) -> np.ndarray:
    """``(m, n)`` fractions, the missing constituent 1 - the others."""
    rows = [np.asarray(fr[c], float) if c in fr else None for c in cons]
    given = sum(r for r in rows if r is not None)
    return np.vstack([r if r is not None else 1.0 - given for r in rows])


def parse_image(ctx, table, domain, parameters=None, src=None, traced=None):
    """``[material] type = "image"``: an :class:`~hetmesh.material.image.ImageField` or,
    with ``labels``, a :class:`~hetmesh.material.image.LabelField`."""
    from . import covers, image_field

    t = ctx.table(table, "material", required=("type", "constituents"), optional=_IMAGE_KEYS)
    cons = parse_constituents(ctx, t)
    src = src if src is not None else _image_sources(ctx, t)
    interp, sigma = parse_sampling(ctx, t)
    geo = src["geometry"]
    covers(geo, domain.bounds, geo.source)
    opts = dict(interpolation=interp, smoothing=sigma)
    if "labels" not in src:
        if "phases" in t:
            raise ctx.fail("material.phases", "phases need a label image (material.labels)")
        if "map" not in t:
            raise ModelFileError(f"{ctx.pre}missing key 'material.map' (how pixel values "
                                 f"become volume fractions)")
        vmap = parse_value_map(ctx, "material.map", t["map"], cons, src)
        if "files" in src:
            stacked = np.stack([scalar_values(ctx, "material.file", im).astype(float)
                                for im in src["files"].values()], axis=-1)
            img = _replace(geo, values=stacked, channels=True,
                           source=", ".join(im.source for im in src["files"].values()))
            return image_field(img, vmap, cons, **opts)
        return image_field(src["image"], vmap, cons, **opts)
    if "map" in t:
        raise ctx.fail("material.map", "with a label image every phase has its own map "
                                       "([[material.phases]] map = ...)")
    return _label_field(ctx, t, domain, src, traced, cons, opts)


def _label_field(ctx, t, domain, src, traced, cons, opts):
    from ...tri.geometry.trace import DEFAULT_TOL, OUTSIDE, label_chains, region_lookup
    from . import ImageField, LabelField

    lab_img = src["geometry"]
    labels = src["labels"]
    phases = t.get("phases", [])
    if not isinstance(phases, list):
        raise ctx.fail("material.phases", f"expected an array of tables ([[material.phases]]),"
                                          f" got {describe(phases)}")
    if traced is None:  # the domain is given: the labels of the pixels in its bounding box
        chains_lab = None
        lo = np.floor((np.asarray(domain.bounds[:2]) - lab_img.origin) /
                      lab_img.spacing + 0.5).astype(int)
        hi = np.floor((np.asarray(domain.bounds[2:]) - lab_img.origin) /
                      lab_img.spacing + 0.5).astype(int)
        ny, nx = labels.shape
        sub = labels[max(lo[1], 0):min(hi[1], ny - 1) + 1, max(lo[0], 0):min(hi[0], nx - 1) + 1]
        present = unique(sub)
    else:
        chains_lab = traced
        present = unique(traced[1][traced[1] != OUTSIDE])
    spec = parse_phases(ctx, phases, cons, src)
    check_phases(spec, present, labels, lab_img.source)
    used = [lab for lab in sorted(spec) if lab in set(present.tolist())]
    index = {lab: k for k, lab in enumerate(used)}
    fields = []
    for lab in used:
        name, what = spec[lab]
        if isinstance(what, np.ndarray):
            fields.append(what)
            continue
        inside = labels == lab
        img = src.get("image")
        values = img.values
        frac = what(values, img.source, mask=inside)
        fields.append(ImageField(fill_phase(frac, inside), img, cons, **opts))
    if chains_lab is None:
        tol = DEFAULT_TOL
        chains = label_chains(labels, tol)
        lab_arr = labels
    else:
        chains, lab_arr, tol = chains_lab
    region = region_lookup(chains, lab_arr, index, lab_img.origin, lab_img.spacing, tol)
    return LabelField(region, fields, [spec[lab][0] for lab in used], cons,
                      source=lab_img.source)


def parse_phases(ctx, phases, cons, src) -> dict:
    """``[[material.phases]]`` -> ``{label: (name, composition (m,) or ValueMap)}``."""
    spec: dict[int, tuple[str, object]] = {}
    for i, item in enumerate(phases):
        key = f"material.phases[{i}]"
        p = ctx.table(item, key, required=("label",), optional=("composition", "map", "name"))
        lab = p["label"]
        if isinstance(lab, bool) or not isinstance(lab, int):
            raise ctx.fail(f"{key}.label", f"expected an integer label, got {describe(lab)}")
        if lab in spec:
            raise ctx.fail(f"{key}.label", f"label {lab} is given twice")
        name = ctx.string(p, key, "name", default=f"label {lab}")
        if ("composition" in p) == ("map" in p):
            raise ctx.fail(key, "give either composition = {...} (a constant phase) or "
                                "map = {...} (graded from material.file)")
        if "composition" in p:
            fr = _per_constituent(ctx, f"{key}.composition", p["composition"], cons,
                                  lambda v, k: ctx.number(v, k))
            c = _complete({k: [v] for k, v in fr.items()}, cons, 1)[:, 0]
            if (c < -1e-12).any() or (c > 1 + 1e-12).any():
                raise ctx.fail(f"{key}.composition", f"fractions {c.tolist()} must lie in "
                                                     f"[0, 1] and sum to 1", MaterialError)
            spec[lab] = (name, np.clip(c, 0.0, 1.0))
        else:
            if "image" not in src and "files" not in src:
                raise ctx.fail(f"{key}.map", "a graded phase needs a grey image "
                                             "(material.file)")
            spec[lab] = (name, parse_value_map(ctx, f"{key}.map", p["map"], cons, src))
    return spec


def check_phases(spec: dict, present, labels: np.ndarray, source: str) -> None:
    """A :class:`MaterialError` naming the first label in ``present`` without a phase."""
    for lab in present.tolist():
        if lab not in spec:
            count = int((labels == lab).sum())
            first = ", ".join(str(int(v)) for v in np.argwhere(labels == lab)[0][::-1])
            what = "pixel" if labels.ndim == 2 else "voxel"
            raise MaterialError(f"{source}: label {lab} ({count:,} {what}s, the first "
                                f"at {what} ({first})) has no composition: add a "
                                f"[[material.phases]] entry with label = {lab}")


def fill_phase(frac: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """``frac`` ``(m, ny, nx)`` with the pixels outside ``inside`` set to the nearest pixel
    inside, so that interpolation within a phase never mixes in another phase's pixels."""
    from scipy.ndimage import distance_transform_edt

    if inside.all():
        return frac
    idx = distance_transform_edt(~inside, return_distances=False, return_indices=True)
    return frac[(slice(None),) + tuple(idx)]
