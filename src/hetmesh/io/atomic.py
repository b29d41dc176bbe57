"""Atomic file writes: write to a temporary file next to the target, rename on success.

Every file hetmesh writes (meshes, plots, statistics) goes through :func:`atomic_path` or
:func:`atomic_write`, so a crash, an exception, Ctrl-C or ``kill`` (SIGTERM) never leaves a
half-written file behind and never clobbers an existing one. The temporary file lives in the
target's directory (``os.replace`` is atomic only within one file system), is named
``.<stem>.<pid>-<hex>.tmp<suffix>`` and keeps the target's suffix, so tools that choose the
format by extension (meshio, matplotlib) still work.

* SIGTERM while a temporary file exists (in the main thread, when no other handler is
  installed) raises ``SystemExit(143)``: the file is removed as on any exception, and the
  process exits with the status of a terminated process.
* What no handler can clean up (SIGKILL, a power cut) is removed by the next write to the
  same path: temporary files of that path whose process is gone (or, named without a
  process id, older than :data:`STALE_AGE` seconds).
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import secrets
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from ..errors import OptionError, OutputError

__all__ = ["atomic_path", "atomic_write", "output_dir", "STALE_AGE", "TERMINATED"]

log = logging.getLogger(__name__)

_MODES = ("w", "wb")
#: a temporary file of ours without a process id in its name is stale after this (seconds)
STALE_AGE = 3600.0
#: the exit status after SIGTERM during a write (128 + the signal's number)
TERMINATED = 128 + int(signal.SIGTERM)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path that replaces ``path`` when the block succeeds.

    The temporary file is created (empty, with the default permissions of a new file) in
    the directory of ``path`` and with the same suffix. When the block finishes normally it
    is flushed to disk and renamed onto ``path`` with :func:`os.replace`; when the block
    raises, it is removed and an existing ``path`` is left untouched.

    Parameters
    ----------
    path : str or path-like
        The file to (over)write.

    Yields
    ------
    Path
        The temporary file to write to.

    Raises
    ------
    OutputError
        If ``path`` is a directory, its parent directory is missing or not writable, or
        writing fails with an ``OSError`` (disk full, ...).

    Examples
    --------
    >>> with atomic_path("out.vtu") as tmp:          # doctest: +SKIP
    ...     meshio.write(tmp, mesh)
    """
    target = Path(path)
    _remove_stale(target)
    with _exit_on_sigterm():
        tmp = _create_temp(target)
        try:
            yield tmp
            if not tmp.is_file():
                raise OutputError(f"cannot write {target}: the temporary file {tmp.name} "
                                  f"vanished")
            fsync(tmp)
            os.replace(tmp, target)
        except OSError as exc:
            _discard(tmp)
            raise OutputError(f"cannot write {target}: {_reason(exc)}") from exc
        except BaseException:
            _discard(tmp)
            raise
    log.debug("wrote %s", target)


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w", *,
                 encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open a temporary file for writing that replaces ``path`` when the block succeeds.

    Parameters
    ----------
    path : str or path-like
        The file to (over)write.
    mode : {"w", "wb"}
        Text or binary.
    encoding : str, optional
        Text encoding (ignored in binary mode).

    Yields
    ------
    file object

    Raises
    ------
    OutputError
        As :func:`atomic_path`.
    OptionError
        If ``mode`` is not ``"w"`` or ``"wb"``.

    Examples
    --------
    >>> with atomic_write(tmp_path / "stats.json") as f:   # doctest: +SKIP
    ...     json.dump(stats, f)
    """
    if mode not in _MODES:
        raise OptionError(f"atomic_write mode must be 'w' or 'wb', got {mode!r}")
    with atomic_path(path) as tmp:
        if mode == "wb":
            f = open(tmp, "wb")
        else:
            f = open(tmp, "w", encoding=encoding)
        with f:
            yield f


def _create_temp(target: Path) -> Path:
    """Create an empty, uniquely named file next to ``target`` (same suffix)."""
    parent = target.parent
    if target.is_dir():
        raise OutputError(f"cannot write {target}: it is a directory")
    if not parent.exists():
        raise OutputError(f"cannot write {target}: directory {parent} does not exist")
    if not parent.is_dir():
        raise OutputError(f"cannot write {target}: {parent} is not a directory")
    for _ in range(100):
        tmp = parent / f".{target.stem}.{os.getpid()}-{secrets.token_hex(4)}.tmp{target.suffix}"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputError(f"cannot write {target}: {_reason(exc)}") from exc
        os.close(fd)
        return tmp
    raise OutputError(f"cannot write {target}: no free temporary file name in {parent}")


@contextlib.contextmanager
def _exit_on_sigterm() -> Iterator[None]:
    """While the block runs, SIGTERM raises ``SystemExit(TERMINATED)`` (so that the
    temporary file is removed) -- in the main thread, if SIGTERM has its default action."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return

    def terminate(signum, frame):
        raise SystemExit(TERMINATED)

    signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _alive(pid: int) -> bool:
    """Whether process ``pid`` may still be writing (True when it cannot be told)."""
    if pid == os.getpid() or os.name != "posix":  # os.kill(pid, 0) terminates on Windows
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # exists (another user's), or cannot tell: keep its file
    return True


def _remove_stale(target: Path) -> None:
    """Remove the temporary files a killed writer of ``target`` left behind."""
    pattern = re.compile(rf"\.{re.escape(target.stem)}\.(?:(\d+)-)?[0-9a-f]{{8}}"
                         rf"\.tmp{re.escape(target.suffix)}")
    try:
        names = os.listdir(target.parent)
    except OSError:
        return
    now = time.time()
    for name in names:
        m = pattern.fullmatch(name)
        if m is None:
            continue
        path = target.parent / name
        try:
            age = now - path.stat().st_mtime
            stale = age > STALE_AGE if not m.group(1) else \
                not _alive(int(m.group(1))) or (os.name != "posix" and age > STALE_AGE)
        except OSError:
            continue
        if stale:
            log.info("removing %s, left by an interrupted write of %s", path, target.name)
            _discard(path)


def fsync(tmp: Path) -> None:
    """Flush the written temporary file ``tmp`` to disk before its rename.

    :func:`atomic_path` calls it through this module's global name: a test may replace
    ``hetmesh.io.atomic.fsync`` to act at the moment the data is written but not renamed.
    """
    fd = os.open(tmp, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _discard(tmp: Path) -> None:
    try:
        tmp.unlink()
    except FileNotFoundError:
        pass
    except OSError as exc:  # pragma: no cover - nothing more we can do
        log.warning("could not remove temporary file %s: %s", tmp, exc)


def _reason(exc: OSError) -> str:
    """A short reason for an OSError, without repeating the path."""
    return (exc.strerror or str(exc)).lower().rstrip(".")


def output_dir(out: Path, sub: str | None = None) -> Path:
    """Create the output directory ``out`` (and ``out/sub``) if missing; ``out``.

    Raises :class:`OutputError` naming ``--out`` when ``out`` is a file or cannot be created.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} is not a directory")
    try:
        (out / sub if sub else out).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"--out {out}: cannot create the directory ({exc.strerror})") from None
    return out
