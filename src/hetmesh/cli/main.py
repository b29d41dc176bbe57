"""The ``hetmesh`` command: argparse subcommands, one module each.

Exit codes: 0 success; 2 bad input (every :class:`hetmesh.errors.HetmeshError` and every
usage error), reported as ONE line ``hetmesh: error: <message>`` on stderr; 1 an operating
system error (disk full, ...) or an internal error (a bug), also one line, with the
traceback shown under ``--debug``; 130 interrupted (Ctrl-C). Output files are only written
after the options were checked and the mesh generated and verified, so a failed run leaves
existing files untouched.
"""

from __future__ import annotations

import argparse
import logging
import sys
from typing import NoReturn, Sequence

from .. import __version__
from ..errors import HetmeshError, OptionError
from . import demo, fea, mesh, reproduce, stats, uniform

__all__ = ["main", "build_parser"]

PROG = "hetmesh"
SUBCOMMANDS = (mesh, uniform, stats, fea, reproduce, demo)


class _UsageError(OptionError):
    """An argparse usage error, raised instead of argparse's usage dump and exit."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise _UsageError(f"{message} (see '{self.prog} --help')")


def build_parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-v", "--verbose", action="count", default=0,
                        help="log diagnostics to stderr (-v: info, -vv: debug)")
    common.add_argument("--debug", action="store_true",
                        help="show the traceback of any error")
    parser = _Parser(
        prog=PROG,
        description="Material-aware adaptive triangle meshes for heterogeneous "
                    "(functionally graded, multi-material) objects.",
        epilog="Run 'hetmesh COMMAND --help' for the options of a command. Exit codes: 0 ok, "
               "2 bad input, 1 system or internal error, 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in SUBCOMMANDS:
        module.add_parser(sub, [common])
    return parser


def _configure_logging(verbosity: int) -> None:
    """Route the ``hetmesh`` loggers to the current stderr, at WARNING/INFO/DEBUG."""
    logger = logging.getLogger("hetmesh")
    for h in list(logger.handlers):
        if getattr(h, "_hetmesh_cli", False):
            logger.removeHandler(h)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("hetmesh: %(levelname)s: %(name)s: %(message)s"))
    handler._hetmesh_cli = True  # type: ignore[attr-defined]
    logger.addHandler(handler)
    logger.setLevel(logging.DEBUG if verbosity >= 2 else logging.INFO if verbosity == 1 else logging.WARNING)


def _one_line(text: str) -> str:
    return " ".join(part.strip() for part in str(text).strip().splitlines() if part.strip())


def _fail(message: str, code: int) -> int:
    sys.stderr.write(f"{PROG}: error: {_one_line(message)}\n")
    sys.stderr.flush()
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``hetmesh`` command line; returns the exit code.

    >>> main(["--version"])  # doctest: +SKIP
    hetmesh 0.1.0
    0
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help, --version
        return exc.code if isinstance(exc.code, int) else 0
    except HetmeshError as exc:
        if debug:
            raise
        return _fail(str(exc), 2)
    _configure_logging(args.verbose)
    try:
        return int(args.run(args))
    except KeyboardInterrupt:
        if args.debug:
            raise
        sys.stderr.write(f"{PROG}: interrupted\n")
        return 130
    except HetmeshError as exc:
        if args.debug:
            raise
        return _fail(str(exc), 2)
    except OSError as exc:
        if args.debug:
            raise
        where = f": {exc.filename}" if getattr(exc, "filename", None) else ""
        return _fail(f"{exc.strerror or exc}{where}", 1)
    except Exception as exc:  # a bug: one line, the traceback under --debug
        if args.debug:
            raise
        return _fail(f"internal error: {type(exc).__name__}: {exc} "
                     "(run with --debug for the traceback)", 1)
