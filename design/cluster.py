"""Dask for the design studies (the atlas, the layout study): one way to run a list of
independent tasks on a ``LocalCluster``, a scheduler address, or in this process.

``scheduler``: None starts a ``dask.distributed.LocalCluster`` of ``workers``
single-threaded worker processes (they ignore SIGINT: Ctrl-C reaches only this process,
which closes the cluster); ``"synchronous"`` runs the tasks here (tests, debugging);
anything else is a scheduler address (``tcp://host:8786``), checked by
:func:`check_scheduler` before a cluster is touched.
"""

from __future__ import annotations

import logging
import re
import signal
import threading
from collections.abc import Callable, Sequence
from typing import Any

from tqdm import tqdm

from sixplus3.errors import InputError

#: Most LocalCluster worker processes: each holds ~0.3 GB (numba, Pinocchio, its task),
#: so 4 stay under 2 GB; a real cluster is a --scheduler address.
MAX_WORKERS = 4


def check_scheduler(scheduler: str | None) -> None:
    """None (a LocalCluster), ``"synchronous"``, or a Dask scheduler address
    ``PROTOCOL://HOST:PORT``; anything else is refused before a cluster is touched."""
    if scheduler is None or scheduler == "synchronous":
        return
    ok = isinstance(scheduler, str) and re.fullmatch(
        r"(tcp|tls|ucx|inproc)://[A-Za-z0-9._\-\[\]:]+:[0-9]{1,5}", scheduler)
    if not ok:
        raise InputError(f"scheduler must be a Dask address such as tcp://host:8786 (or "
                         f"'synchronous'), got {str(scheduler)[:80]!r}",
                         value=str(scheduler)[:80], valid="PROTOCOL://HOST:PORT")


def check_workers(workers: int) -> None:
    """Refuse a local worker count out of [1, MAX_WORKERS]."""
    if isinstance(workers, bool) or not (isinstance(workers, int)
                                         and 1 <= workers <= MAX_WORKERS):
        raise InputError(f"workers must be an integer in [1, {MAX_WORKERS}] (each local "
                         f"worker process holds ~0.3 GB; a bigger run belongs on a Dask "
                         f"scheduler), got {workers!r}", value=workers,
                         valid=f"[1, {MAX_WORKERS}]")


def _local_cluster(workers: int) -> Any:

    # deferred: Dask (optional) loads only when this runs
    from dask.distributed import LocalCluster

    main = threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                            dashboard_address=None, silence_logs=50)
    finally:
        if main:
            signal.signal(signal.SIGINT, old)


def _quiet_close(client: Any, cluster: Any) -> None:
    """Close the client, then the local cluster, with Dask's and asyncio's loggers
    silenced: a worker connection closing while the cluster shuts down is logged by
    ``distributed`` as a CommClosedError with its traceback, which is no error of the
    run (the results are in)."""

    names = ("distributed", "distributed.core", "distributed.comm", "distributed.nanny",
             "distributed.worker", "distributed.scheduler", "distributed.client",
             "tornado", "asyncio")
    saved = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL + 1)
    try:
        client.close()
        if cluster is not None:
            cluster.close()
    finally:
        for n, level in saved.items():
            logging.getLogger(n).setLevel(level)


def map_tasks(fn: Callable[..., Any], items: Sequence[Any], shared: Any,
              scheduler: str | None, workers: int,
              progress: Callable[[int, int], None] | bool = False,
              desc: str = "tasks") -> list[Any]:
    """[fn(shared, item) for item in items], in order, on Dask (module doc).  ``shared``
    is sent to every worker once; ``progress``: True for a tqdm bar, or a
    callback(done, total)."""
    check_scheduler(scheduler)
    check_workers(workers)
    bar = None
    total = len(items)
    if progress is True:
        bar = tqdm(total=total, unit="task", desc=desc, leave=False)

    def tick(done: int) -> None:
        if bar is not None:
            bar.update(1)
        elif callable(progress):
            progress(done, total)

    out: list[Any] = [None] * total
    try:
        if scheduler == "synchronous":
            for i, item in enumerate(items):
                out[i] = fn(shared, item)
                tick(i + 1)
            return out
        # deferred: Dask (optional) loads only when this runs
        from dask.distributed import Client, as_completed

        cluster = _local_cluster(workers) if scheduler is None else None
        client = Client(cluster) if cluster is not None else Client(scheduler, timeout=30)
        try:
            s = client.scatter(shared, broadcast=True)
            futs = [client.submit(fn, s, item, pure=False) for item in items]
            index = {f.key: i for i, f in enumerate(futs)}
            for done, f in enumerate(as_completed(futs), 1):
                out[index[f.key]] = f.result()
                tick(done)
        finally:
            _quiet_close(client, cluster)
        return out
    finally:
        if bar is not None:
            bar.close()
