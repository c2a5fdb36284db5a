"""The distributed engine: a Dask ``Client`` on a local cluster or an existing scheduler, or
this process for work too small to pay a cluster's start-up.

Each worker process runs one task at a time with one thread (``threads_per_worker=1``), and
the compiled code inside a task is limited to one thread too (`single_threaded`), so
``n`` workers use ``n`` cores without oversubscription.
"""

from __future__ import annotations

import logging
import os
import re
import signal
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import ModelError, SimulationError

#: A scheduler address: ``tcp://HOST:PORT`` (or tls://, or HOST:PORT).
_ADDRESS = re.compile(r"^(?:(tcp|tls)://)?(\[[0-9A-Fa-f:]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")
#: Seconds to wait, after Ctrl-C, for running tasks to stop and write what they have.
STOP_WAIT = 60.0


def check_scheduler(address: str) -> str:
    """``address`` if it is a scheduler address (``tcp://HOST:PORT``), else a one-line
    `ModelError`."""
    m = _ADDRESS.match(address.strip()) if isinstance(address, str) else None
    if not m or not 0 < int(m.group(3)) < 65536:
        raise ModelError("--scheduler", f"{address!r} is not a scheduler address; allowed: "
                         "tcp://HOST:PORT, e.g. tcp://10.0.0.5:8786 (what `dask scheduler` "
                         "prints)")
    return address.strip() if "://" in address else f"tcp://{address.strip()}"


@contextmanager
def connect(client=None, *, workers: int | None = None, scheduler: str | None = None,
            in_process: bool = False) -> Iterator:
    """A ``dask.distributed.Client``: ``client`` itself if given; else one connected to
    ``scheduler`` (``tcp://HOST:PORT``); else, with ``in_process`` (small work), None: the
    tasks run in this process (`run_tasks`), no cluster started; else a new
    ``LocalCluster`` with ``workers`` worker processes (default: one per core) of one thread
    each, closed on exit."""
    if client is not None:
        yield client
        return
    if scheduler is not None:
        from distributed import Client

        address = check_scheduler(scheduler)
        _quiet_dask()
        try:
            remote = Client(address, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise ModelError("--scheduler", f"cannot reach {address!r} "
                             f"({str(exc).splitlines()[0][:120]}); allowed: the address of a "
                             "running `dask scheduler`, e.g. tcp://10.0.0.5:8786") from None
        try:
            yield remote
        finally:
            _close_quietly(remote)
        return
    n = workers or os.cpu_count() or 1
    if not 1 <= n <= 1024:
        raise ModelError("--workers", f"{n}; allowed 1 to 1024")
    if in_process and workers is None:
        yield None
        return
    import dask
    from distributed import Client, LocalCluster

    _quiet_dask()
    # Forked workers start with this process's modules already imported (measured, a
    # 5000-sample sweep command on 2 workers against 1: 1.41-1.46x with spawned workers,
    # 1.52-1.65x with forked ones, benchmarks/bench_batch.py); spawn where there is no fork.
    method = "fork" if hasattr(os, "fork") else "spawn"
    with dask.config.set({"distributed.worker.multiprocessing-method": method}):
        # Workers forked meanwhile ignore Ctrl-C: it reaches the whole process group, and only
        # the client should act on it (cancel, stop, wait, one line), not every worker with
        # a traceback.
        with signals_handled(signal.SIG_IGN, signal.SIGINT):
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=logging.ERROR)
        with cluster, Client(cluster) as local:
            yield local


@contextmanager
def signals_handled(handler, *signals) -> Iterator:
    """``handler`` for ``signals`` while inside (in the main thread; elsewhere nothing
    changes), the previous handlers restored after."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, handler) for sig in signals}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _quiet_dask() -> None:
    """Dask's own log lines (connection retries, closing comms) stay out of the terminal:
    torquesim reports what matters in one line."""
    for name in ("distributed", "distributed.client", "distributed.comm",
                 "distributed.core", "distributed.worker", "distributed.scheduler"):
        logging.getLogger(name).setLevel(logging.CRITICAL)


def _close_quietly(client) -> None:
    try:
        client.close(timeout=5)
    except Exception:  # noqa: BLE001 - a lost scheduler cannot be closed politely
        pass


def workers_of(client) -> int:
    """How many workers ``client`` has (1 in process)."""
    if client is None:
        return 1
    try:
        return max(1, len(client.scheduler_info(n_workers=-1)["workers"]))
    except TypeError:  # older distributed: no n_workers argument
        return max(1, len(client.scheduler_info()["workers"]))


def check_shared_folder(client, folder: Path) -> None:
    """Every worker of ``client`` must see ``folder`` (the same file system as this process):
    a file written here is looked for by each; a one-line `ModelError` names the
    workers that cannot see it. Nothing to check in process or on a local cluster."""
    if client is None:
        return
    marker = Path(folder) / f".torquesim-probe-{uuid.uuid4().hex}"
    marker.write_text("torquesim\n")
    try:
        seen = client.run(_can_see, str(marker))
    finally:
        marker.unlink(missing_ok=True)
    blind = sorted(worker for worker, ok in seen.items() if not ok)
    if blind:
        raise ModelError("--out", f"{len(blind)} of {len(seen)} Dask workers cannot see "
                         f"{str(folder)!r} ({', '.join(blind[:3])}); allowed: a folder on a "
                         "file system every worker shares, at the same path")


def _can_see(path: str) -> bool:
    return os.path.exists(path)


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


def stop_flag(name: str | None) -> Callable[[], bool]:
    """A ``should_stop()`` for a task: True once the client has set the Dask event ``name``
    (Ctrl-C). Asks the scheduler at most every 0.5 s; always False in process (the signal
    reaches the process itself) or without a name."""
    if not name:
        return lambda: False
    try:
        from distributed import Event, get_worker

        get_worker()
    except (ImportError, ValueError):
        return lambda: False
    event = Event(name)
    last = [0.0, False]

    def should_stop() -> bool:
        now = time.monotonic()
        if not last[1] and now - last[0] >= 0.5:
            last[0] = now
            try:
                last[1] = bool(event.is_set())
            except Exception:  # noqa: BLE001 - a lost scheduler: stop and write what we have
                last[1] = True
        return last[1]

    return should_stop


def run_tasks(client, submissions: list[tuple[Callable, tuple]], on_result: Callable,
              progress=None, retries: int = 2, stop_event: str | None = None) -> None:
    """Submit every (function, args) and call ``on_result(index, result)`` as each task
    finishes (in completion order). In process (``client`` None) the tasks run one after the
    other here. A worker that dies mid-task has its task retried elsewhere (``retries``).

    Ctrl-C cancels what is queued, sets the Dask event ``stop_event`` (tasks that poll it,
    `stop_flag`, stop and write what they have), waits up to `STOP_WAIT` s for the
    running ones, and re-raises: nothing keeps writing after the command has returned. A lost
    scheduler or cluster is a one-line `SimulationError`."""
    if client is None:
        for i, (fn, args) in enumerate(submissions):
            on_result(i, fn(*args))
            if progress:
                progress(i + 1, len(submissions))
        return
    from distributed import as_completed

    futures = [client.submit(fn, *args, retries=retries, pure=False)
               for fn, args in submissions]
    index = {f.key: i for i, f in enumerate(futures)}
    try:
        for done, future in enumerate(as_completed(futures), 1):
            on_result(index.pop(future.key), future.result())
            if progress:
                progress(done, len(futures))
    except KeyboardInterrupt:
        _stop_remote(client, futures, stop_event)
        for future in futures:  # the tasks that stopped and returned what they had
            if future.status == "finished" and future.key in index:
                try:
                    on_result(index.pop(future.key), future.result(timeout=5))
                except Exception:  # noqa: BLE001 - best effort while the user waits
                    pass
        raise
    except (ModelError, SimulationError):
        client.cancel(futures)
        raise
    except Exception as exc:  # noqa: BLE001 - the cluster, not a task: tasks report their own
        _quiet_dask()
        try:
            client.cancel(futures)
        except Exception:  # noqa: BLE001
            pass
        raise SimulationError(f"lost the Dask scheduler or its workers ({type(exc).__name__}: "
                              f"{(str(exc).splitlines() or [''])[0][:120]}); what finished is "
                              "kept: run the same command again to continue") from None


def _stop_remote(client, futures, stop_event: str | None) -> None:
    """Cancel queued tasks, ask running ones to stop, and wait for them."""
    _quiet_dask()
    try:
        from distributed import Event, wait

        if stop_event:
            Event(stop_event, client=client).set()
        pending = [f for f in futures if f.status == "pending"]
        running = set()
        try:
            processing = client.processing()
            running = {key for keys in processing.values() for key in keys}
        except Exception:  # noqa: BLE001
            pass
        client.cancel([f for f in pending if f.key not in running])
        wait([f for f in pending if f.key in running], timeout=STOP_WAIT)
    except Exception:  # noqa: BLE001 - best effort while the user waits
        pass
