"""Frozen dataclasses of parallel arrays: one concept, one entry per element of each array."""

from __future__ import annotations

from dataclasses import fields, replace
from typing import TypeVar

import numpy as np

R = TypeVar("R", bound="Records")


class Records:
    """Mixin of a frozen dataclass whose fields are arrays of equal length (one entry per
    record): :meth:`take` selects records, :meth:`concat` joins sets of them."""

    def __len__(self) -> int:
        return len(getattr(self, fields(self)[0].name))

    def take(self: R, index) -> R:
        """The records at ``index`` (an index array or a boolean mask)."""
        return replace(self, **{f.name: getattr(self, f.name)[index] for f in fields(self)})

    @classmethod
    def concat(cls: type[R], parts: list[R]) -> R:
        """The records of ``parts`` one after the other."""
        return cls(**{f.name: np.concatenate([getattr(p, f.name) for p in parts])
                      for f in fields(cls)})
