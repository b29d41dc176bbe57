"""The meshing options and their rules, in one place for the API and the CLI.

Light on purpose (numpy only), so the CLI can validate before importing the mesher. Messages
name the option the way the caller knows it: ``names`` maps an option to its label
(``{"min_angle": "--min-angle"}`` for the CLI; the plain words by default).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from .errors import OptionError

__all__ = ["check_options", "DEFAULT_MAX_ELEMENTS", "DEFAULT_CHORD_TOL", "MIN_CHORD_TOL",
           "MAX_CHORD_TOL", "DEFAULT_ROW_SPACING", "ROW_SPACING_RANGE", "DEFAULT_GRADATION",
           "MAX_GRADATION", "SAMPLINGS", "LABELS",
           "check_sampling"]

DEFAULT_MAX_ELEMENTS = 5_000_000
#: the largest distance between a curved boundary or interface and its chords (its edges in
#: the mesh), relative to the domain's diameter
DEFAULT_CHORD_TOL = 1e-3
#: the chord tolerances accepted: a chord may stray at most 5 % of the diameter from its
#: curve, and at least 1e-7 of it (nodes are verified on their curves to 1e-8 x diameter)
MIN_CHORD_TOL, MAX_CHORD_TOL = 1e-7, 0.05
#: the step in composition between the rows of nodes of the layers placement, as a fraction
#: of delta_0. Rows just under delta_0 apart (0.985) give the fewest elements, all of them
#: near delta_0; rows 0.85 delta_0 apart leave every element slack that the quality pass
#: spends on shape (q_avg +0.01 to +0.015 on the examples, for 15-35 % more elements)
DEFAULT_ROW_SPACING = 0.85
ROW_SPACING_RANGE = (0.3, 0.99)
#: growth of the placement's element size per unit length (``gradation``; 0: not graded)
DEFAULT_GRADATION = 0.3
MAX_GRADATION = 10.0
#: how delta(T) is measured: at the vertices (the paper's Eqs. 14-15), also on a lattice inside
#: every element, as a certified upper bound, or (image fields) also at every pixel centre
#: an element covers
SAMPLINGS = ("vertices", "dense", "certified", "pixels")
LABELS = {"threshold": "threshold", "min_angle": "min angle", "max_elements": "max elements",
          "max_size": "max size", "sampling": "sampling", "min_quality": "min quality",
          "seed": "seed", "chord_tol": "chord tolerance", "row_spacing": "row spacing",
          "gradation": "gradation"}


def check_options(threshold, *, min_angle: float = 30.0,
                  max_elements: int = DEFAULT_MAX_ELEMENTS, max_size: float | None = None,
                  sampling: str = "vertices", min_quality: float = 0.0, seed: int = 0,
                  chord_tol: float = DEFAULT_CHORD_TOL,
                  row_spacing: float = DEFAULT_ROW_SPACING,
                  gradation: float = DEFAULT_GRADATION,
                  names: Mapping[str, str] | None = None) -> float:
    """Validate the options of ``generate``/``uniform``; returns the threshold as a float.

    Raises :class:`OptionError` with a one-line message naming the option and its value.

    >>> check_options(0.05)
    0.05
    >>> check_options(0.05, min_angle=40, names={"min_angle": "--min-angle"})
    Traceback (most recent call last):
    ...
    hetmesh.errors.OptionError: --min-angle 40 is outside (0, 34] degrees
    """
    label = {**LABELS, **(names or {})}
    try:
        thr = float(threshold)
    except (TypeError, ValueError):
        raise OptionError(f"{label['threshold']} must be a number, got {threshold!r}") from None
    if not 0.0 < thr < 1.0:  # also rejects nan
        raise OptionError(f"{label['threshold']} {thr:g} is outside (0, 1): delta_0 must be "
                          "positive and below the largest possible composition difference")
    if not 0.0 < float(min_angle) <= 34.0:
        raise OptionError(f"{label['min_angle']} {min_angle:g} is outside (0, 34] degrees")
    if int(max_elements) != max_elements or max_elements < 1:
        raise OptionError(f"{label['max_elements']} {max_elements} must be a positive integer")
    if max_size is not None and not 0.0 < float(max_size) < math.inf:
        raise OptionError(f"{label['max_size']} {max_size:g} must be a positive length")
    if sampling not in SAMPLINGS:
        raise OptionError(f"{label['sampling']} {sampling!r} is not one of {', '.join(SAMPLINGS)}")
    if not 0.0 <= float(min_quality) < 0.9:
        raise OptionError(f"{label['min_quality']} {min_quality:g} is outside [0, 0.9)")
    if int(seed) != seed or seed < 0:
        raise OptionError(f"{label['seed']} {seed} must be a non-negative integer")
    try:
        ct = float(chord_tol)
    except (TypeError, ValueError):
        raise OptionError(f"{label['chord_tol']} must be a number, got {chord_tol!r}") from None
    if not MIN_CHORD_TOL <= ct <= MAX_CHORD_TOL:  # also rejects nan
        raise OptionError(f"{label['chord_tol']} {ct:g} is outside [{MIN_CHORD_TOL:g}, "
                          f"{MAX_CHORD_TOL:g}] (relative to the domain's diameter)")
    try:
        rs = float(row_spacing)
    except (TypeError, ValueError):
        raise OptionError(f"{label['row_spacing']} must be a number, got {row_spacing!r}") from None
    lo, hi = ROW_SPACING_RANGE
    if not lo <= rs <= hi:  # also rejects nan
        raise OptionError(f"{label['row_spacing']} {rs:g} is outside [{lo:g}, {hi:g}] (a "
                          "fraction of the threshold)")
    try:
        gr = float(gradation)
    except (TypeError, ValueError):
        raise OptionError(f"{label['gradation']} must be a number, got {gradation!r}") from None
    if not 0.0 <= gr <= MAX_GRADATION:  # also rejects nan
        raise OptionError(f"{label['gradation']} {gr:g} is outside [0, {MAX_GRADATION:g}] (the "
                          "growth of the element size per unit length; 0: not graded)")
    return thr

#: how :func:`check_sampling` names the fields without pixels
_KINDS = {"AnalyticField": "formula", "CallableField": "Python function",
          "HFTField": "feature tree"}


def check_sampling(field, sampling: str, names: Mapping[str, str] | None = None) -> None:
    """Raise :class:`OptionError` unless ``field`` supports ``sampling``: ``"pixels"`` needs
    a field sampled on pixels (one with a ``pixel_delta`` method: an image or label image).

    >>> check_sampling(object(), "pixels", names={"sampling": "--sampling"})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hetmesh.errors.OptionError: --sampling pixels needs a material from an image ...
    """
    if sampling == "pixels" and not callable(getattr(field, "pixel_delta", None)):
        label = {**LABELS, **(names or {})}["sampling"]
        user = getattr(field, "base", field) if type(field).__name__ == "_LocalField" else field
        kind = _KINDS.get(type(user).__name__, type(user).__name__)
        raise OptionError(f"{label} pixels needs a material from an image ([material] type = "
                          f"\"image\"); this material ({kind}) has no pixels")
