"""Study files: the TOML schema of a parameter sweep, its validation and its runs.

A study file lists meshing runs as a grid (every combination of the listed values) and/or as
explicit runs; ``docs/sweep.md`` is the reference. Every error is one line that starts with
the file name and the key, e.g. ``sweep.toml: grid.threshold[2]: 1.5 is outside (0, 1)``.

:func:`load_study` reads a file, :func:`parse_study` a dict as :mod:`tomllib` gives; both
return a :class:`Study` whose :attr:`Study.specs` are the runs as plain data (dicts of
strings, numbers, lists), each with its content key (:mod:`hetmesh.study.keys`), ready for
:func:`hetmesh.study.run_one` in any process.
"""

from __future__ import annotations

import itertools
import logging
import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import OptionError
from ..options import (
    DEFAULT_CHORD_TOL,
    DEFAULT_GRADATION,
    DEFAULT_MAX_ELEMENTS,
    DEFAULT_ROW_SPACING,
    SAMPLINGS,
    check_options,
)
from .keys import content_key, text_digest

__all__ = ["Study", "load_study", "parse_study", "METHODS", "RUN_KEYS", "MESH_FORMATS",
           "resolve_model"]

log = logging.getLogger(__name__)

#: the mesher of a run: :func:`hetmesh.generate`'s placements, or the uniform baseline
#: (:func:`hetmesh.uniform`)
METHODS = ("auto", "layers", "springs", "cvt", "uniform")

#: the keys of a run and their defaults (``None``: required, or :func:`hetmesh.generate`'s
#: own default); the options that do not apply to ``method = "uniform"`` are ignored there
DEFAULTS: dict[str, Any] = {
    "model": None, "threshold": None, "method": "auto", "sampling": "vertices", "seed": 0,
    "min_angle": 30.0, "max_size": None, "max_elements": DEFAULT_MAX_ELEMENTS,
    "min_quality": 0.6, "optimize": True, "chord_tol": DEFAULT_CHORD_TOL,
    "row_spacing": DEFAULT_ROW_SPACING, "gradation": DEFAULT_GRADATION,
}
RUN_KEYS = tuple(DEFAULTS)
#: options that :func:`hetmesh.uniform` takes (the others belong to the adaptive mesher)
UNIFORM_KEYS = ("min_angle", "max_elements", "sampling", "min_quality", "chord_tol")

#: mesh file formats a study may write (the extension of the file)
MESH_FORMATS = ("vtu", "msh", "xdmf", "inp", "vtk", "mesh")

_TOP = ("study", "defaults", "grid", "runs", "fea", "output")
_FEA_KEYS = ("probes", "order")
_OUTPUT_KEYS = ("mesh",)
_STUDY_KEYS = ("name", "description")


@dataclass(frozen=True)
class Study:
    """A validated study.

    Attributes
    ----------
    name : str
        ``study.name`` (default: the file's stem).
    specs : list of dict
        One plain-data run per grid point and explicit run, in file order (grid first),
        duplicates (same content key) dropped. Keys: ``index``, ``key``, ``model`` (name),
        ``model_file``, ``model_text``, ``method``, ``threshold``, ``options`` (the other
        run keys, defaults filled in), ``fea`` (None or ``{"probes": [...] | None, "order":
        int | None}``), ``mesh_format`` (None or an extension), ``cost`` (the a-priori
        element estimate: the longest runs are started first; not part of the key).
    source : Path or None
        The study file.
    description : str
    """

    name: str
    specs: list[dict] = field(default_factory=list)
    source: Path | None = None
    description: str = ""

    def __len__(self) -> int:
        return len(self.specs)


class _Where:
    """Error messages ``<file>: <key>: <problem>``."""

    def __init__(self, where: str):
        self.where = where

    def fail(self, key: str, problem: str) -> OptionError:
        return OptionError(f"{self.where}: {key}: {problem}" if key else f"{self.where}: {problem}")

    def table(self, value, key: str, allowed: tuple[str, ...]) -> dict:
        if not isinstance(value, dict):
            raise self.fail(key, f"expected a table, got {_describe(value)}")
        unknown = [k for k in value if k not in allowed]
        if unknown:
            raise self.fail(_join(key, unknown[0]),
                            f"unknown key (expected one of: {', '.join(allowed)})")
        return value


def _join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def _describe(value) -> str:
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, (list, tuple)):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return f"{type(value).__name__} {value!r}"


def load_study(path: str | os.PathLike) -> Study:
    """Read and validate a study file (TOML, ``docs/sweep.md``).

    Raises
    ------
    OptionError
        One line naming the file and the key: not TOML, unknown keys, wrong types, values
        out of range, a model that cannot be found or loaded.

    Examples
    --------
    >>> study = load_study("examples/studies/sweep.toml")     # doctest: +SKIP
    >>> len(study.specs)                               # doctest: +SKIP
    6
    """
    p = Path(path)
    where = os.fspath(path)
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise OptionError(f"no such study file: {where}") from None
    except IsADirectoryError:
        raise OptionError(f"{where}: is a directory, not a study file") from None
    except OSError as exc:
        raise OptionError(f"{where}: cannot read the study file: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise OptionError(f"{where}: not UTF-8 text (offset {exc.start})") from None
    except tomllib.TOMLDecodeError as exc:
        raise OptionError(f"{where}: not valid TOML: {exc}") from None
    return parse_study(data, where, base=p.parent, default_name=p.stem, source=p)


def parse_study(data: Mapping, where: str = "study", *, base: str | os.PathLike | None = None,
                default_name: str = "study", source: Path | None = None) -> Study:
    """Validate a parsed study (a dict as :mod:`tomllib` gives) and expand its runs.

    ``base`` is the directory model paths are relative to (default: the current one);
    ``where`` starts every error message.

    >>> s = parse_study({"grid": {"model": ["unit_square"], "threshold": [0.2, 0.1]}})
    >>> [(r["model"], r["threshold"]) for r in s.specs]
    [('unit_square', 0.2), ('unit_square', 0.1)]
    """
    w = _Where(where)
    top = w.table(dict(data), "", _TOP)
    info = w.table(top.get("study", {}), "study", _STUDY_KEYS)
    name = info.get("name", default_name)
    description = info.get("description", "")
    for k, v in (("name", name), ("description", description)):
        if not isinstance(v, str):
            raise w.fail(f"study.{k}", f"expected a string, got {_describe(v)}")
    defaults = _run_table(w, top.get("defaults", {}), "defaults")
    fea = _fea(w, top["fea"]) if "fea" in top else None
    output = w.table(top.get("output", {}), "output", _OUTPUT_KEYS)
    mesh_format = _mesh_format(w, output.get("mesh", False))
    base_dir = Path(base) if base is not None else Path.cwd()

    raw_runs: list[tuple[str, dict]] = []
    if "grid" in top:
        raw_runs += _grid(w, top["grid"], defaults)
    runs = top.get("runs", [])
    if not isinstance(runs, list):
        raise w.fail("runs", f"expected an array of tables ([[runs]]), got {_describe(runs)}")
    for i, r in enumerate(runs):
        key = f"runs[{i}]"
        raw_runs.append((key, {**defaults, **_run_table(w, r, key)}))
    if not raw_runs:
        raise w.fail("", "no runs: give a [grid] table or [[runs]] tables")

    models: dict[str, tuple[str, Path | None, str]] = {}
    costs: dict[str, Any] = {}
    specs: list[dict] = []
    seen: dict[str, str] = {}
    for key, run in raw_runs:
        for req in ("model", "threshold"):
            if req not in run:
                raise w.fail(_join(key, req), "missing (set it here, in [defaults] or [grid])")
        model_ref = run["model"]
        if model_ref not in models:
            models[model_ref] = resolve_model(model_ref, base_dir, w, f"{key}.model")
        model_name, model_file, text = models[model_ref]
        spec = _spec(w, key, run, model_name, model_file, text, fea, mesh_format)
        if model_ref not in costs:
            costs[model_ref] = _cost_model(base_dir, model_ref)
        spec["cost"] = costs[model_ref](spec["threshold"], spec["options"].get("max_size"))
        if spec["key"] in seen:
            log.warning("%s: %s repeats %s; it runs once", where, key, seen[spec["key"]])
            continue
        seen[spec["key"]] = key
        spec["index"] = len(specs)
        specs.append(spec)
    return Study(name=name, specs=specs, source=source, description=description)


def _grid(w: _Where, value, defaults: dict) -> list[tuple[str, dict]]:
    grid = w.table(value, "grid", RUN_KEYS)
    axes: list[tuple[str, list]] = []
    for k, v in grid.items():
        values = v if isinstance(v, list) else [v]
        if not values:
            raise w.fail(f"grid.{k}", "empty array: the grid would have no runs")
        for i, item in enumerate(values):
            _check_value(w, f"grid.{k}[{i}]" if isinstance(v, list) else f"grid.{k}", k, item)
        axes.append((k, values))
    out = []
    for combo in itertools.product(*(vals for _, vals in axes)):
        point = dict(zip((k for k, _ in axes), combo))
        label = "grid(" + ", ".join(f"{k}={_short(v)}" for k, v in point.items()) + ")"
        out.append((label, {**defaults, **point}))
    return out


def _short(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _run_table(w: _Where, value, key: str) -> dict:
    table = w.table(value, key, RUN_KEYS)
    for k, v in table.items():
        _check_value(w, _join(key, k), k, v)
    return dict(table)


def _check_value(w: _Where, key: str, name: str, v) -> None:
    """Types of one run key (ranges are checked on the whole run by :func:`_spec`)."""
    if name in ("model", "method", "sampling"):
        if not isinstance(v, str) or not v:
            raise w.fail(key, f"expected a non-empty string, got {_describe(v)}")
        if name == "method" and v not in METHODS:
            raise w.fail(key, f"unknown method {v!r} (expected one of: {', '.join(METHODS)})")
        if name == "sampling" and v not in SAMPLINGS:
            raise w.fail(key, f"unknown sampling {v!r} (expected one of: {', '.join(SAMPLINGS)})")
    elif name == "optimize":
        if not isinstance(v, bool):
            raise w.fail(key, f"expected true or false, got {_describe(v)}")
    elif name in ("seed", "max_elements"):
        if isinstance(v, bool) or not isinstance(v, int):
            raise w.fail(key, f"expected an integer, got {_describe(v)}")
    else:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise w.fail(key, f"expected a number, got {_describe(v)}")


def _fea(w: _Where, value) -> dict | None:
    if value is False:
        return None
    if value is True:
        return {"probes": None, "order": None}
    table = w.table(value, "fea", _FEA_KEYS)
    probes = table.get("probes", "all")
    if probes == "all":
        probes = None
    elif not (isinstance(probes, list) and probes and all(isinstance(p, str) for p in probes)):
        raise w.fail("fea.probes", f"expected \"all\" or an array of probe names, "
                                   f"got {_describe(probes)}")
    order = table.get("order")
    if order is not None and (isinstance(order, bool) or order not in (1, 2)):
        raise w.fail("fea.order", f"expected 1 or 2, got {_describe(order)}")
    return {"probes": list(probes) if probes else None, "order": order}


def _mesh_format(w: _Where, value) -> str | None:
    if value is False:
        return None
    if value is True:
        return "vtu"
    if not isinstance(value, str) or value.lstrip(".") not in MESH_FORMATS:
        raise w.fail("output.mesh", f"expected false, true or one of {', '.join(MESH_FORMATS)}"
                                    f", got {_describe(value)}")
    return value.lstrip(".")


def resolve_model(ref: str, base: Path, w: _Where | None = None,
                  key: str = "model") -> tuple[str, Path | None, str]:
    """``(name, path, text)`` of a study's model: a packaged example's name (``power_plate``)
    or a path to a model file, relative to ``base`` (the study file's directory).

    The model is loaded once here, so that a bad model fails the study before any run.
    """
    from ..errors import HetmeshError
    from ..io.model import example_path, load_model

    w = w or _Where("study")
    is_path = ref.endswith(".toml") or "/" in ref or os.sep in ref
    path = (base / ref) if is_path else example_path(ref)
    if not path.is_file():
        if is_path:
            raise w.fail(key, f"no such model file: {path}")
        from importlib.resources import files

        names = sorted(p.name[:-5] for p in (files("hetmesh") / "examples").iterdir()
                       if p.name.endswith(".toml"))
        raise w.fail(key, f"{ref!r} is neither a model file nor an example "
                          f"(examples: {', '.join(names)})")
    try:
        text = path.read_text(encoding="utf-8")
        model = load_model(path)
    except (OSError, UnicodeDecodeError) as exc:
        raise w.fail(key, f"cannot read {path}: {exc}") from None
    except HetmeshError as exc:
        raise w.fail(key, str(exc).splitlines()[0]) from None
    return model.name, (path.resolve() if is_path else None), text


def _cost_model(base: Path, ref: str):
    """``(threshold, max_size) -> expected elements`` of a model (the a-priori count of
    equilateral elements of side ``min(delta_0 / |grad f|, max_size)``), so that a cluster can
    start the longest runs first and no long run is left alone at the end."""
    from ..density import background_points, gradient_norm, integrate, size_at
    from ..io.model import example_path, load_model

    is_path = ref.endswith(".toml") or "/" in ref or os.sep in ref
    model = load_model(base / ref if is_path else example_path(ref), check=False)
    if getattr(model, "dim", 2) == 3:  # a solid: the tetrahedral kernel's a-priori count
        from ..tet.mesher import estimate_tets

        return lambda threshold, max_size: float(
            estimate_tets(model.solid, model.material, threshold))
    domain = model.domain
    g = gradient_norm(model.material, background_points(domain, 100))
    default = domain.diameter / 8.0

    def cost(threshold: float, max_size: float | None) -> float:
        h = size_at(g, threshold, max_size or default)
        return float(4.0 / math.sqrt(3.0) * integrate(1.0 / h ** 2, domain))

    return cost


def _spec(w: _Where, key: str, run: dict, model_name: str, model_file: Path | None, text: str,
          fea: dict | None, mesh_format: str | None) -> dict:
    """One run as plain data, its options checked and defaults filled in."""
    options = {k: run.get(k, DEFAULTS[k]) for k in RUN_KEYS if k not in ("model", "threshold")}
    method = options.pop("method")
    threshold = run["threshold"]
    try:
        threshold = check_options(threshold, **{k: options[k] for k in (
            "min_angle", "max_elements", "max_size", "sampling", "min_quality", "seed",
            "chord_tol", "row_spacing", "gradation")})
    except OptionError as exc:
        raise w.fail(key, str(exc)) from None
    for k in ("min_angle", "min_quality", "chord_tol", "row_spacing", "gradation"):
        options[k] = float(options[k])
    if options["max_size"] is not None:
        options["max_size"] = float(options["max_size"])
    if method == "uniform":  # options of the adaptive mesher do not change a uniform mesh
        options = {k: options[k] for k in UNIFORM_KEYS}
    spec = {"model": model_name, "model_file": str(model_file) if model_file else "",
            "model_text": text, "method": method, "threshold": float(threshold),
            "options": options, "fea": fea, "mesh_format": mesh_format}
    spec["key"] = content_key(text_digest(text), {k: spec[k] for k in (
        "model", "method", "threshold", "options", "fea", "mesh_format")})
    return spec
