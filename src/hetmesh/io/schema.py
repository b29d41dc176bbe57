"""The checked reading of a model file's tables: one-line errors naming the file and key.

:class:`SchemaContext` checks a table's keys and its values' types and builds the errors
(``<file>: <key path>: <problem>``); :func:`describe` shows a wrong value as the file spells
it. The model file's parser (:mod:`hetmesh.io.model`) and the parsers of its material kinds
share them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping

from ..errors import HetmeshError, ModelFileError

__all__ = ["SchemaContext", "describe", "join_key", "toml_value"]


def toml_value(value) -> str:
    """``value`` written as in a TOML file (``true``, ``"text"``, ``[1, 2]``, ``{ a = 1 }``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + " }"
    return repr(value)


def describe(value) -> str:
    """A short description of a wrong value: ``[0, true] (array)``.

    >>> describe([0, True])
    '[0, true] (array)'
    """
    kind = {bool: "boolean", int: "integer", float: "number", str: "string", list: "array",
            dict: "table"}.get(type(value), type(value).__name__)
    text = toml_value(value)
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{text} ({kind})"


def join_key(prefix: str, key: str) -> str:
    """The key path ``prefix.key`` (``key`` alone at the top level)."""
    return f"{prefix}.{key}" if prefix else key


class SchemaContext:
    """Reads the tables of one file and builds its error messages.

    Every message is ``<where>: <key path>: <problem>``; ``where`` is normally the file name.
    The parsers of the model file's sections (domain, material, ``[fea]``) take one.

    >>> ctx = SchemaContext("plate.toml")
    >>> str(ctx.fail("domain.outer", "expected a table, got 1 (integer)"))
    'plate.toml: domain.outer: expected a table, got 1 (integer)'
    """

    def __init__(self, where: str):
        self.where = where
        self.pre = f"{where}: " if where else ""

    def fail(self, key: str, problem: str, cls=ModelFileError):
        return cls(f"{self.pre}{key}: {problem}" if key else f"{self.pre}{problem}")

    def table(self, value, key: str, required=(), optional=()) -> dict:
        if not isinstance(value, Mapping):
            raise self.fail(key or "model file", f"expected a table, got {describe(value)}")
        allowed = tuple(required) + tuple(optional)
        for k in value:
            if k not in allowed:
                raise ModelFileError(f"{self.pre}unknown key {join_key(key, str(k))!r} "
                                     f"(expected one of: {', '.join(allowed)})")
        for k in required:
            if k not in value:
                raise ModelFileError(f"{self.pre}missing key {join_key(key, k)!r}")
        return dict(value)

    def string(self, table: Mapping, key: str, name: str, default=None) -> str:
        if name not in table:
            return default
        v = table[name]
        if not isinstance(v, str):
            raise self.fail(join_key(key, name), f"expected a string, got {describe(v)}")
        return v

    def number(self, value, key: str, positive: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"expected a number, got {describe(value)}")
        v = float(value)
        if not math.isfinite(v):
            raise self.fail(key, f"expected a finite number, got {value!r}")
        if positive and v <= 0:
            raise self.fail(key, f"expected a positive number, got {value!r}")
        return v

    def point(self, value, key: str) -> tuple[float, float]:
        ok = (isinstance(value, list) and len(value) == 2
              and all(isinstance(c, (int, float)) and not isinstance(c, bool)
                      and math.isfinite(c) for c in value))
        if not ok:
            raise self.fail(key, f"expected a point [x, y] of 2 finite numbers, got "
                                 f"{describe(value)}")
        return (float(value[0]), float(value[1]))

    def ccw(self, table: Mapping, key: str) -> bool:
        """The optional ``direction`` of ``table``: True for ``"ccw"`` (the default)."""
        direction = self.string(table, key, "direction", default="ccw")
        if direction not in ("ccw", "cw"):
            raise self.fail(f"{key}.direction", f"expected \"ccw\" or \"cw\", got "
                                                f"{direction!r}")
        return direction == "ccw"

    def wrap(self, key: str, exc: HetmeshError) -> HetmeshError:
        """Re-raise a geometry/material error with this file's prefix and ``key``."""
        msg = str(exc)
        if self.where and msg.startswith(self.where):
            return exc
        return type(exc)(f"{self.pre}{key}: {msg}" if key else f"{self.pre}{msg}")
