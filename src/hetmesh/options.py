"""The meshing options and their rules, in one place for the API and the CLI.

Light on purpose (numpy only), so the CLI can validate before importing the mesher. Messages
name the option the way the caller knows it: ``names`` maps an option to its label
(``{"min_angle": "--min-angle"}`` for the CLI; the plain words by default).
"""

from __future__ import annotations

import math
from typing import Mapping

from .errors import OptionError

__all__ = ["check_options", "DEFAULT_MAX_ELEMENTS", "SAMPLINGS", "LABELS"]

DEFAULT_MAX_ELEMENTS = 5_000_000
SAMPLINGS = ("vertices", "dense")
LABELS = {"threshold": "threshold", "min_angle": "min angle", "max_elements": "max elements",
          "max_size": "max size", "sampling": "sampling", "min_quality": "min quality",
          "seed": "seed"}


def check_options(threshold, *, min_angle: float = 30.0,
                  max_elements: int = DEFAULT_MAX_ELEMENTS, max_size: float | None = None,
                  sampling: str = "vertices", min_quality: float = 0.0, seed: int = 0,
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
    return thr
