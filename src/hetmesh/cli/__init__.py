"""The ``hetmesh`` command line: ``hetmesh {mesh,uniform,stats,demo} ...``.

Only this package prints; see :func:`hetmesh.cli.main.main` for the exit codes.
"""

from __future__ import annotations

from .main import main

__all__ = ["main"]
