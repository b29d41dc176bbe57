"""Where the runs of a study execute: this process, a Dask cluster, or any executor.

:func:`open_client` gives a :class:`dask.distributed.Client`: to a :class:`LocalCluster` of
one single-threaded worker process per core by default, or to a running scheduler by address
(a cluster started by dask-jobqueue on SLURM/PBS, dask-kubernetes, ``dask scheduler`` ...).
:func:`map_runs` submits a plain function over plain items to that client, to a
:class:`concurrent.futures.Executor`, or runs them in this process (``client=None``), and
reports every result once, as it arrives.

Reliability is Dask's: a worker that dies (killed, out of memory, its machine gone) has its
runs rescheduled on the other workers by the scheduler, up to
``distributed.scheduler.allowed-failures`` times (3 unless configured); a run lost more often
is reported as ``lost`` (:class:`distributed.KilledWorker`). Every run is submitted under its
content key (``hetmesh-run-<key>``), so a result is received, and counted, once.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import logging
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

from ..errors import OptionError

__all__ = ["open_client", "map_runs", "Counts", "dashboard_link", "LOST"]

log = logging.getLogger(__name__)

#: status of a run whose worker died on every try, or whose cluster went away
LOST = "lost"


@dataclass
class Counts:
    """Progress of a sweep: runs ``done`` (finished or failed), ``running`` now, ``failed``
    (among the done), ``total``, ``cached`` (found done by an earlier sweep, among the done)
    and the Dask ``dashboard`` address (None without one)."""

    total: int
    done: int = 0
    running: int = 0
    failed: int = 0
    cached: int = 0
    dashboard: str | None = None


def dashboard_link(client, *, local: bool = False) -> str | None:
    """The Dask dashboard's address, or None if the scheduler serves none. The dashboard
    needs ``bokeh`` beside the scheduler (``pip install bokeh``); without it a scheduler
    serves only a page saying so, which a ``local`` cluster's link is not given for."""
    if local:
        import importlib.util

        if importlib.util.find_spec("bokeh") is None:
            return None
    try:
        services = client.scheduler_info().get("services", {})
    except Exception:  # a scheduler that does not answer: no link, the sweep goes on
        return None
    if "dashboard" not in services:
        return None
    return client.dashboard_link


@contextlib.contextmanager
def open_client(*, workers: int | None = None, scheduler: str | None = None,
                timeout: float = 30.0) -> Iterator[Any]:
    """A Dask client for a sweep, closed (with its local cluster) on exit.

    Parameters
    ----------
    workers : int, optional
        Worker processes of the local cluster (default: the number of cores); each runs
        one run at a time (``threads_per_worker=1``: meshing holds the GIL).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``, or a scheduler file's
        path ending in ``.json``); ``workers`` must not be given with it.
    timeout : float
        Seconds to wait for the scheduler.

    Raises
    ------
    OptionError
        ``workers`` below 1, both ``workers`` and ``scheduler``, or no scheduler answering at
        the address.
    """
    from dask.distributed import Client, LocalCluster

    if workers is not None and scheduler is not None:
        raise OptionError("--workers and --scheduler exclude each other: the workers of a "
                          "scheduler are the cluster's")
    if workers is not None and (isinstance(workers, bool) or int(workers) < 1):
        raise OptionError(f"--workers must be at least 1, got {workers}")
    if scheduler is not None:
        try:
            if scheduler.endswith(".json"):
                client = Client(scheduler_file=scheduler, timeout=timeout)
            else:
                client = Client(scheduler, timeout=timeout)
        except (OSError, TimeoutError, ValueError) as exc:
            reason = str(exc).splitlines()[0] if str(exc) else "no answer"
            raise OptionError(f"--scheduler {scheduler}: cannot connect "
                              f"({type(exc).__name__}: {reason})") from None
        with client:
            log.info("connected to the Dask scheduler at %s", scheduler)
            yield client
        return
    n = int(workers) if workers is not None else (os.cpu_count() or 1)
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.ERROR)
    try:
        with Client(cluster) as client:
            log.info("local Dask cluster of %d workers", n)
            yield client
    finally:
        cluster.close()


def _is_dask(client) -> bool:
    try:
        from dask.distributed import Client
    except ImportError:  # pragma: no cover - dask is a dependency
        return False
    return isinstance(client, Client)


def _nthreads(client) -> int:
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # the scheduler is busy or gone: the count is for display only
        return 1


def map_runs(func: Callable, items: Sequence[Any], keys: Sequence[str], *, client=None,
             args: tuple = (), on_result: Callable[[int, Any, str | None], None] | None = None,
             on_progress: Callable[[int, int], None] | None = None,
             prefix: str = "hetmesh-run", costs: Sequence[float] | None = None) -> list:
    """``[func(item, *args) for item in items]``, on ``client`` if given.

    Parameters
    ----------
    func : callable
        A plain, importable function of plain data (it is pickled by reference).
    items, keys : sequences of the same length
        The arguments, and a unique key of each (the Dask task key is ``prefix-key``).
    client : dask.distributed.Client, concurrent.futures.Executor or None
        Where to run; None: in this process, one after the other.
    on_result : callable ``(i, result, error)``, optional
        Called once per item, as it finishes: ``error`` is None, or the one-line message of
        an exception the run raised or of a lost run (``"lost: ..."``); ``result`` is then
        None.
    on_progress : callable ``(running, pending)``, optional
        Called after every result with the runs running now and not yet finished.
    costs : sequence of float, optional
        Expected cost of each item: on a client, the costliest are started first (Dask
        priorities; submission order for an executor), so that the last runs to finish are
        short ones. Results are still returned in the order of ``items``.

    Returns
    -------
    list
        The results in the order of ``items`` (None for a run that raised or was lost).
    """
    if len(items) != len(keys):
        raise ValueError("items and keys differ in length")
    results: list = [None] * len(items)

    def deliver(i: int, value, error: str | None) -> None:
        results[i] = value
        if on_result is not None:
            on_result(i, value, error)

    if client is None:
        for i, item in enumerate(items):
            if on_progress is not None:
                on_progress(1, len(items) - i)
            try:
                value, error = func(item, *args), None
            except Exception as exc:  # recorded like a worker's exception
                value, error = None, _message(exc)
            deliver(i, value, error)
        return results
    rank = list(range(len(items)))
    if costs is not None:  # costliest first; ties in the given order
        rank = sorted(rank, key=lambda i: (-float(costs[i]), i))
    futures: list = [None] * len(items)
    if _is_dask(client):
        from dask.distributed import as_completed

        for r, i in enumerate(rank):
            futures[i] = client.submit(func, items[i], *args, key=f"{prefix}-{keys[i]}",
                                       pure=False, priority=len(items) - r)
        completed = as_completed([futures[i] for i in rank])
        nthreads = _nthreads(client)
    else:
        for i in rank:
            futures[i] = client.submit(func, items[i], *args)
        completed = cf.as_completed(futures)
        nthreads = getattr(client, "_max_workers", 1) or 1
    index = {id(f): i for i, f in enumerate(futures)}
    pending = len(futures)
    if on_progress is not None:
        on_progress(min(nthreads, pending), pending)
    try:
        for fut in completed:
            i = index[id(fut)]
            try:
                value, error = fut.result(), None
            except Exception as exc:
                value, error = None, _message(exc)
            pending -= 1
            deliver(i, value, error)
            if on_progress is not None:
                if _is_dask(client) and pending:
                    nthreads = _nthreads(client)
                on_progress(min(nthreads, pending), pending)
    finally:
        for fut in futures:
            if not fut.done():
                fut.cancel()
    return results


def _message(exc: BaseException) -> str:
    """One line for an exception out of a worker; lost runs start with ``lost:``."""
    name = type(exc).__name__
    text = " ".join(str(exc).split())
    if name in ("KilledWorker", "CancelledError", "FutureCancelledError") or \
            isinstance(exc, (cf.CancelledError, BrokenProcessPool)):
        return f"{LOST}: {name}: {text}" if text else f"{LOST}: {name}"
    return f"internal error: {name}: {text}" if text else f"internal error: {name}"
