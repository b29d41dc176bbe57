"""Atomic file writes: write to a temporary file next to the target, rename on success.

Every file hetmesh writes (meshes, plots, statistics) goes through :func:`atomic_path` or
:func:`atomic_write`, so a crash, an exception or Ctrl-C never leaves a half-written file
behind and never clobbers an existing one. The temporary file lives in the target's
directory (``os.replace`` is atomic only within one file system) and keeps the target's
suffix, so tools that choose the format by extension (meshio, matplotlib) still work.
"""

from __future__ import annotations

import contextlib
import logging
import os
import secrets
from pathlib import Path
from typing import IO, Iterator

from ..errors import OptionError, OutputError

__all__ = ["atomic_path", "atomic_write"]

log = logging.getLogger(__name__)

_MODES = ("w", "wb")


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
    tmp = _create_temp(target)
    try:
        yield tmp
        if not tmp.is_file():
            raise OutputError(f"cannot write {target}: the temporary file {tmp.name} vanished")
        _fsync(tmp)
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
        tmp = parent / f".{target.stem}.{secrets.token_hex(4)}.tmp{target.suffix}"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputError(f"cannot write {target}: {_reason(exc)}") from exc
        os.close(fd)
        return tmp
    raise OutputError(f"cannot write {target}: no free temporary file name in {parent}")


def _fsync(tmp: Path) -> None:
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
