"""JSON-ready values for the documents hetmesh writes (statistics, FEA reports)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["jsonable"]


def jsonable(value: Any, *, infinity_as_string: bool = True) -> Any:
    """``value`` with numpy scalars and arrays, paths and tuples made JSON-serialisable.

    NaN becomes ``null``; an infinity becomes ``"inf"``/``"-inf"``, or ``null`` with
    ``infinity_as_string=False``.

    >>> jsonable({"a": np.float64(1.5), "b": (np.inf, np.nan), 3: Path("x")})
    {'a': 1.5, 'b': ['inf', None], '3': 'x'}
    """
    if isinstance(value, dict):
        return {str(k): jsonable(v, infinity_as_string=infinity_as_string)
                for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v, infinity_as_string=infinity_as_string) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist(), infinity_as_string=infinity_as_string)
    if isinstance(value, np.generic):
        return jsonable(value.item(), infinity_as_string=infinity_as_string)
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        if math.isnan(value) or not infinity_as_string:
            return None
        return "inf" if value > 0 else "-inf"
    return value
