"""Runs a function over many independent items: in this process, over the local cores, or on a Dask
distributed cluster.

    scheduler=None        a process pool over `workers` local cores (default: all)
    scheduler="local"     a Dask LocalCluster started for the sweep (`workers` worker processes)
    scheduler="HOST:PORT" an existing Dask scheduler; its workers need the harness installed, not the
                          project's files

On Dask the FMU files the items name travel with the sweep (`harness.studies.shipping`): each goes
to each worker once, into the worker's local directory, and the item function gets that copy's
path. Results come back in the order of the items. Every item is computed in a worker process, so a
crash in one FMU run cannot take the caller down.
"""
from __future__ import annotations

import logging
import os
import signal
import tempfile
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Iterable, TypeVar

from harness.errors import HarnessError

Item = TypeVar("Item")
Result = TypeVar("Result")


def local_cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def run_sweep(function: Callable[[Item], Result], items: Iterable[Item], scheduler: str | None = None,
              workers: int | None = None) -> list[Result]:
    items = list(items)
    if workers is not None and workers < 1:
        raise HarnessError(f"--workers {workers}: need at least 1")
    if scheduler is None:
        workers = workers or local_cores()
        if workers == 1:
            return [function(item) for item in items]
        # the workers' temporary files go into one folder the sweep owns: a worker ended in the middle
        # of an item cannot remove what it extracted, so the parent removes it after the pool
        with tempfile.TemporaryDirectory(prefix="sweep-") as scratch:
            pool = ProcessPoolExecutor(max_workers=workers, initializer=_worker_setup, initargs=(scratch,))
            try:
                return list(pool.map(function, items))
            except BaseException:  # an interrupt or a failed item: the items still running are not waited for
                _terminate_workers(pool)
                raise
            finally:
                pool.shutdown(wait=True, cancel_futures=True)
    return _dask_map(function, items, scheduler, workers)


def _worker_setup(scratch: str) -> None:
    """Ctrl-C reaches every process of the terminal's group: the workers ignore it, the parent stops
    the sweep (and the pool with it), so that an interrupt is one line, not one traceback per worker.
    SIGTERM gets its default action back (a worker inherits the parent's handler, which would wait
    for a long call into an FMU to return before it acted)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    tempfile.tempdir = scratch


def _terminate_workers(pool: ProcessPoolExecutor) -> None:
    """Ends the pool's worker processes at once: an item may sit in an FMU call for minutes, and
    shutdown() alone waits for it. The executor has no public way to do this before Python 3.14."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        if process.is_alive():
            process.terminate()


def _dask_map(function, items, scheduler: str, workers: int | None):
    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - a dependency of the package
        raise HarnessError("a Dask scheduler needs the 'distributed' package") from None
    if scheduler == "local":
        # its late clean-up of the scratch space this sweep already removed is not news
        logging.getLogger("distributed.diskutils").setLevel(logging.CRITICAL)
        with tempfile.TemporaryDirectory(prefix="dask-") as scratch:  # Dask's scratch space, removed with the sweep
            # signals wait until the cluster exists, so that an interrupt closes it instead of leaving it half made
            held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
            try:
                with dask.config.set({"temporary-directory": scratch}):
                    cluster = LocalCluster(n_workers=workers or local_cores(), threads_per_worker=1, processes=True,
                                           dashboard_address=None, local_directory=scratch)
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
            with cluster, Client(cluster) as client, dask.config.set({"temporary-directory": scratch}):
                return _map_on(client, function, items, scheduler)
    try:
        client = Client(scheduler, timeout="5s")
    except Exception as error:  # refused, timed out, or something that is not a Dask scheduler answered
        detail = (str(error).strip().splitlines() or [type(error).__name__])[0]
        raise HarnessError(f"--scheduler {scheduler}: cannot connect ({detail})") from None
    with client:
        return _map_on(client, function, items, scheduler)


def _map_on(client, function, items: list, scheduler: str) -> list:
    """The items on the client's workers, their FMUs sent along (once per worker: see `shipping`)."""
    from dask.utils import funcname
    from harness.studies.shipping import LocalFmus, ship
    shipped = ship(client, items, scheduler)
    return client.gather(client.map(LocalFmus(function), shipped, pure=False, key=funcname(function)))
