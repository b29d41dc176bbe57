"""The package's version (one place, read by the CLI, the reports and the sweep keys)."""

from __future__ import annotations

__version__ = "0.1.0"
