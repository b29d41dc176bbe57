"""``hetmesh uniform``: the coarsest quality uniform mesh meeting delta_max < D.

The baseline the paper compares against (its Tables 1, 3, 5); options as for ``mesh``.
"""

from __future__ import annotations

import argparse

from .mesh import add_meshing_options, run_meshing

__all__ = ["add_parser", "run"]


def add_parser(subparsers, parents: list[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "uniform", parents=parents,
        help="coarsest quality uniform mesh meeting delta_max < D",
        description="Mesh a model with elements of one size: the coarsest quality uniform "
                    "mesh whose material variation delta is below the threshold in every "
                    "element. The baseline the adaptive mesh is compared against.",
    )
    add_meshing_options(p, adaptive=False)
    p.set_defaults(run=run)
    return p


def _uniform():
    from ..tri.uniform import uniform

    return uniform


def run(args: argparse.Namespace) -> int:
    return run_meshing(args, _uniform)
