"""The distributed engine: a Dask ``Client`` on a local cluster or an existing scheduler.

Each worker process runs one task at a time with one thread (``threads_per_worker=1``), and
the compiled code inside a task is limited to one thread too (:func:`single_threaded`), so
``n`` workers use ``n`` cores without oversubscription.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from ..errors import ModelError


@contextmanager
def connect(client=None, *, workers: int | None = None,
            scheduler: str | None = None) -> Iterator:
    """A ``dask.distributed.Client``: ``client`` itself if given; else one connected to
    ``scheduler`` (``tcp://HOST:PORT``); else a new ``LocalCluster`` with ``workers`` worker
    processes (default: one per core) of one thread each, closed on exit."""
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            with Client(scheduler, timeout="10s") as remote:
                yield remote
        except OSError as exc:
            raise ModelError("--scheduler", f"cannot reach {scheduler!r}: {exc}; allowed: the "
                             "address a running `dask scheduler` prints, e.g. "
                             "tcp://10.0.0.5:8786") from None
        return
    n = workers or os.cpu_count() or 1
    if not 1 <= n <= 1024:
        raise ModelError("--workers", f"{n}; allowed 1 to 1024")
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=40) as cluster, \
            Client(cluster) as local:
        yield local


def single_threaded() -> None:
    """Limit Numba's parallel loops to one thread in this process (a Dask worker)."""
    import numba

    numba.set_num_threads(1)


def worker_name() -> str:
    """The Dask worker running this task (its address), or ``local``."""
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return "local"


def run_tasks(client, submissions: list[tuple[Callable, tuple]], on_result: Callable,
              progress=None, retries: int = 2) -> None:
    """Submit every (function, args) and call ``on_result(index, result)`` as each task
    finishes (in completion order). A worker that dies mid-task has its task retried
    elsewhere (``retries``). Ctrl-C cancels what is still queued and re-raises."""
    from distributed import as_completed

    futures = [client.submit(fn, *args, retries=retries, pure=False)
               for fn, args in submissions]
    index = {f.key: i for i, f in enumerate(futures)}
    try:
        for done, future in enumerate(as_completed(futures), 1):
            on_result(index[future.key], future.result())
            if progress:
                progress(done, len(futures))
    except BaseException:
        client.cancel(futures)
        raise
