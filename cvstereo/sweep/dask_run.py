"""Cells on Dask distributed: a local cluster or an existing scheduler, started and stopped cleanly.

A stop (Ctrl-C, SIGTERM) may come at any moment, also while the cluster starts: the start is held whole
(:func:`cvstereo._signals.held_stop_signals`), so that the cluster exists and can be closed, and the close is
quiet, since the workers' cancelled cells and the nanny killing a busy worker are the stop itself, not news.
The worker processes start with SIGINT blocked (:func:`cvstereo._signals.sigint_blocked_for_children`): a
terminal's Ctrl-C reaches the whole process group, and the sweep, not each worker, answers it. Cells that
finished before the stop are written already (by ``finished``, which keeps a row being written).
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Callable

from cvstereo._signals import held_stop_signals, sigint_blocked_for_children
from cvstereo.sweep.cells import empty_row, error_text

__all__ = ["DASK_LOGGER", "SCHEDULER_TIMEOUT_S", "WORKER_LOG_LEVELS", "run_on_dask"]

#: Seconds to wait for an existing scheduler to answer (Dask's own default, 30 s, looks like a hang).
SCHEDULER_TIMEOUT_S = 5
#: Dask's loggers: quiet while a stopped sweep closes its cluster.
DASK_LOGGER = "distributed"
#: Log levels of our local workers' loggers (their output is our stderr). What they say when a stop closes them
#: (each cell cancelled, a heartbeat to the closed scheduler failed, with a traceback) is the stop itself, said
#: once by the sweep, and a cell's own failure is in its row; memory pressure is still worth a warning.
WORKER_LOG_LEVELS = {DASK_LOGGER: logging.CRITICAL, "distributed.worker.memory": logging.WARNING}


def run_on_dask(todo, finished: Callable, *, run: Callable, workers: int | None, scheduler: str | None,
                score: Callable | None, log: Callable[[str], None] | None = None) -> None:
    """Run ``todo`` (key, cell) pairs on a cluster, ``run(cell, score)`` each (a module-level function Dask sends
    to the workers), calling ``finished(key, cell, row)`` as each ends.

    Raises
    ------
    ImportError
        Dask is not installed (the message names the extra).
    OSError, ValueError
        ``scheduler`` does not answer within :data:`SCHEDULER_TIMEOUT_S`, or is no address.
    """
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise ImportError("cvstereo sweep needs Dask: pip install 'cvstereo[sweep]'.") from None
    with contextlib.ExitStack() as stack:
        with held_stop_signals(), sigint_blocked_for_children():
            if scheduler is None:
                n = workers or os.cpu_count() or 1
                if log is not None:
                    log(f"starting a local Dask cluster: {n} worker process{'es' if n > 1 else ''}")
                # One single-threaded process per worker: the matchers are single-threaded numba/numpy code, and
                # processes keep each cell's memory apart. No dashboard: it needs bokeh and a free port. The
                # scheduler still serves /health on HTTP, by default on port 8787: on a free port instead (":0"),
                # so that another cluster on the machine holding 8787 does not make it warn.
                cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                       scheduler_kwargs={"dashboard_address": ":0"})
                stack.push(_closing(cluster))
                client = Client(cluster)
                stack.push(_closing(client))
                client.run(_quiet_worker)
            else:
                client = _connect(Client, scheduler)
                stack.push(_closing(client))
        futures = {client.submit(run, cell, score, key=f"cell-{key}", pure=False): (key, cell)
                   for key, cell in todo}
        for future in as_completed(futures):  # a stop lands here, waiting, or is held until the result is in
            key, cell = futures[future]
            # Fetching a finished cell's small row is quick, and Dask's sync() must not be cut: cut before its
            # coroutine starts, its cancel callback fails on the loop thread and logs a traceback.
            with held_stop_signals():
                try:
                    row = future.result()
                except Exception as exc:  # the worker died under the cell (out of memory, a crash): it failed
                    row = empty_row(error=error_text(exc))
            finished(key, cell, row)


def _quiet_worker() -> None:
    """On a worker of our local cluster: :data:`WORKER_LOG_LEVELS`."""
    for name, level in WORKER_LOG_LEVELS.items():
        logging.getLogger(name).setLevel(level)


def _connect(client_class, scheduler: str):
    try:
        return client_class(scheduler, timeout=SCHEDULER_TIMEOUT_S)
    except (OSError, ValueError) as exc:
        kind = ValueError if isinstance(exc, ValueError) else OSError
        raise kind(f"--scheduler {scheduler}: {exc}") from None


def _closing(resource):
    """An exit callback closing a Dask client or cluster; with the signals held, and quietly after a stop
    (a KeyboardInterrupt, which the CLI's SIGTERM is too)."""

    def close(exc_type, exc, tb) -> bool:
        stopping = exc_type is not None and issubclass(exc_type, KeyboardInterrupt)
        logger = logging.getLogger(DASK_LOGGER)
        level = logger.level
        if stopping:
            logger.setLevel(logging.CRITICAL)
        try:
            with held_stop_signals():
                resource.close()
        finally:
            logger.setLevel(level)
        return False

    return close
