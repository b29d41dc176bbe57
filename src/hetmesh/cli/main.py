"""The ``hetmesh`` command: argparse subcommands, one module each.

Exit codes: 0 success; 2 bad input (every usage error and every
:class:`hetmesh.errors.HetmeshError` whose ``exit_code`` is 2: model file, geometry,
material, option, output path, FEA setup, and the element budget the user chose); 1 an
operating system error (disk full, ...) or an internal error: a bug (an unexpected
exception) or hetmesh failing on valid input (:class:`~hetmesh.errors.MeshingError`: the
refinement stalled, the final verification failed), with a request to report it; 130
interrupted (Ctrl-C). Output files are only written after the options were checked and
the mesh generated and verified, so a failed run leaves existing files untouched.

What goes to stderr. A failing command prints exactly ONE line, ``hetmesh: error:
<message>``. Warnings (hetmesh's logged warnings, other libraries' logged warnings, Python
warnings such as numpy's RuntimeWarning) are collected while the command runs and, if it
succeeds, printed after it, deduplicated, one line each: ``hetmesh: warning: <message>``
(a repeated one with ``(N times)``), never with a source line. With ``-v``/``-vv`` the log
(and the warnings) stream as they happen instead, as Gmsh's terminal output does; with
``--debug`` too, and an error shows its traceback.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import NoReturn

from ..errors import HetmeshError, OptionError
from ..version import __version__
from . import demo, examples, export, fea, mesh, reproduce, stats, sweep, uniform

__all__ = ["main", "build_parser"]

PROG = "hetmesh"
SUBCOMMANDS = (mesh, uniform, stats, fea, export, reproduce, sweep, demo, examples)


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
        epilog="Run 'hetmesh COMMAND --help' for the options of a command. Exit codes: 0 ok; "
               "2 bad input (model, options, paths, or an element budget too small for the "
               "threshold); 1 system error, or internal error (a bug, e.g. a mesh failing "
               "its final verification: please report it); 130 interrupted. A failing "
               "command prints one line on stderr; a successful one prints its warnings "
               "at the end, as 'hetmesh: warning: ...' lines (with -v the log and warnings "
               "stream as they happen).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in SUBCOMMANDS:
        module.add_parser(sub, [common])
    return parser


class _Stderr(logging.Handler):
    """Log records as one-line ``hetmesh: <level>: ...`` messages on the current stderr,
    streamed (``live``) or collected for :meth:`flush_collected`, deduplicated."""

    def __init__(self, live: bool):
        super().__init__(logging.DEBUG)
        self.live = live
        self.collected: dict[str, int] = {}  # line -> count, in first-seen order

    def emit(self, record: logging.LogRecord) -> None:
        try:
            msg = _one_line(record.getMessage())
        except Exception:  # a bad format string in someone's log call: never fatal
            msg = _one_line(str(record.msg))
        level = record.levelname.lower()
        if record.levelno < logging.WARNING:  # -v, -vv: hetmesh's log, as it happens
            if record.name == PROG or record.name.startswith(PROG + "."):
                self.line(f"{level}: {record.name}: {msg}", live=True)
        else:
            self.line(f"{level}: {msg}")

    def warning(self, message, category, filename, lineno, file=None, line=None) -> None:
        """``warnings.showwarning``: category, message and where, never the source line."""
        self.line(f"warning: {category.__name__}: {_one_line(str(message))} "
                  f"({os.path.basename(str(filename))}:{lineno})")

    def line(self, text: str, *, live: bool | None = None) -> None:
        if self.live if live is None else live:
            sys.stderr.write(f"{PROG}: {text}\n")
            sys.stderr.flush()
        else:
            self.collected[text] = self.collected.get(text, 0) + 1

    def flush_collected(self) -> None:
        for text, n in self.collected.items():
            sys.stderr.write(f"{PROG}: {text}" + (f" ({n} times)" if n > 1 else "") + "\n")
        self.collected.clear()
        sys.stderr.flush()


@contextmanager
def _stderr_policy(verbosity: int, debug: bool) -> Iterator[_Stderr]:
    """Route every logger's records (``hetmesh`` at WARNING, INFO with ``-v``, DEBUG with
    ``-vv``; other libraries at WARNING) and Python warnings through one :class:`_Stderr`
    handler for the duration of a command; everything is restored afterwards."""
    handler = _Stderr(live=debug or verbosity > 0)
    root, ours = logging.getLogger(), logging.getLogger(PROG)
    saved = (ours.level, ours.propagate)
    ours.setLevel(logging.DEBUG if verbosity >= 2 else logging.INFO if verbosity == 1
                  else logging.WARNING)
    ours.propagate = True
    root.addHandler(handler)
    with warnings.catch_warnings():
        warnings.showwarning = handler.warning
        try:
            yield handler
        finally:
            root.removeHandler(handler)
            ours.setLevel(saved[0])
            ours.propagate = saved[1]


def _one_line(text: str) -> str:
    return " ".join(part.strip() for part in str(text).strip().splitlines() if part.strip())


def _fail(message: str, code: int) -> int:
    sys.stderr.write(f"{PROG}: error: {_one_line(message)}\n")
    sys.stderr.flush()
    return code


#: appended to the one line of an internal error
REPORT = ("(a bug in hetmesh: please report it with the model file and the command; "
          "--debug shows the traceback)")


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
    with _stderr_policy(args.verbose, args.debug) as stderr:
        try:
            code = int(args.run(args))
        except KeyboardInterrupt:
            if args.debug:
                raise
            sys.stderr.write(f"{PROG}: interrupted\n")
            return 130
        except HetmeshError as exc:
            if args.debug:
                raise
            if exc.internal:
                return _fail(f"internal error: {exc} {REPORT}", exc.exit_code)
            return _fail(str(exc), exc.exit_code)
        except OSError as exc:
            if args.debug:
                raise
            where = f": {exc.filename}" if getattr(exc, "filename", None) else ""
            return _fail(f"{exc.strerror or exc}{where}", 1)
        except Exception as exc:  # a bug: one line, the traceback under --debug
            if args.debug:
                raise
            return _fail(f"internal error: {type(exc).__name__}: {exc} {REPORT}", 1)
        stderr.flush_collected()
        return code
