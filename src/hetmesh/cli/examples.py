"""``hetmesh examples``: list the packaged example models, or copy one out to edit and mesh.

The examples live inside the installed package (``hetmesh/examples/*.toml``), so a path
such as ``examples/power_plate.toml`` only exists in a clone of the repository; from
anywhere else ``hetmesh examples power_plate`` writes ``power_plate.toml`` into the current
directory. :func:`check_model_path` gives the commands that read a model file the same
pointer when the file is missing.
"""

from __future__ import annotations

import argparse
from importlib import resources
from pathlib import Path

from rich.table import Table

from ..errors import ModelFileError, OptionError, OutputError
from .progress import result_console

__all__ = ["add_parser", "run", "example_names", "check_model_path"]


def _package_dir():
    return resources.files("hetmesh") / "examples"


def example_names() -> list[str]:
    """The packaged examples' names (file stems), sorted."""
    return sorted(p.name[:-5] for p in _package_dir().iterdir() if p.name.endswith(".toml"))


def _description(name: str) -> str:
    import tomllib

    try:
        data = tomllib.loads((_package_dir() / f"{name}.toml").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return ""
    info = data.get("model", {})
    return str(info.get("description", "")) if isinstance(info, dict) else ""


def check_model_path(path: Path) -> None:
    """Raise :class:`ModelFileError` if the model file ``path`` does not exist, naming the
    packaged example of that name (if there is one) and how to get it."""
    if path.exists():
        return
    hint = "`hetmesh examples` lists the packaged example models"
    if path.stem in example_names():
        hint = (f"{path.stem} is a packaged example: `hetmesh examples {path.stem}` writes "
                f"{path.stem}.toml into the current directory")
    raise ModelFileError(f"no such model file: {path} ({hint})")


def add_parser(subparsers, parents: list[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "examples", parents=parents,
        help="list the packaged example models, or copy one out",
        description="Without NAME, list the example models packaged with hetmesh. With NAME, "
                    "write NAME.toml into --out (default: the current directory), ready for "
                    "`hetmesh mesh NAME.toml -d 0.05 -o NAME.vtu`.",
    )
    p.add_argument("name", nargs="?", metavar="NAME", help="the example to copy out")
    p.add_argument("--out", type=Path, default=Path("."), metavar="DIR",
                   help="directory to write NAME.toml into (default: .)")
    p.add_argument("--force", action="store_true", help="overwrite an existing NAME.toml")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    names = example_names()
    console = result_console()
    if args.name is None:
        table = Table()
        table.add_column("example")
        table.add_column("description")
        for name in names:
            table.add_row(name, _description(name))
        console.print(table)
        console.print("copy one out with: hetmesh examples NAME [--out DIR]")
        return 0
    name = args.name[:-5] if args.name.endswith(".toml") else args.name
    if name not in names:
        raise OptionError(f"no packaged example {args.name!r} (examples: {', '.join(names)})")
    if not args.out.is_dir():
        raise OutputError(f"--out {args.out}: no such directory")
    target = args.out / f"{name}.toml"
    if target.exists() and not args.force:
        raise OutputError(f"{target} exists; use --force to overwrite it")
    from ..io.atomic import atomic_write

    with atomic_write(target) as fh:
        fh.write((_package_dir() / f"{name}.toml").read_text(encoding="utf-8"))
    console.print(f"wrote {target}")
    for extra in (_package_dir() / f"{name}.stl",):  # the surface a model file reads
        if extra.is_file():
            with atomic_write(args.out / extra.name, "wb") as fh:
                fh.write(extra.read_bytes())
            console.print(f"wrote {args.out / extra.name}")
    return 0
