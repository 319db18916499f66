"""A Dask distributed client: a ``LocalCluster`` on this machine, or a running scheduler."""

from __future__ import annotations

import logging
import os
import socket
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from ..errors import MirrorlabError

if TYPE_CHECKING:
    from distributed import Client

#: Seconds to wait for a running scheduler before giving up.
CONNECT_TIMEOUT = 10.0


class ClusterError(MirrorlabError):
    """The Dask scheduler could not be reached or has no workers."""


def _reachable(scheduler: str) -> None:
    """Raise :class:`ClusterError` at once if nothing listens at ``scheduler`` (``tcp://HOST:PORT``, as
    :func:`~mirrorlab.core.batch.options.scheduler_address` gives it): Dask's client retries a refused
    connection until its timeout, 10 s of waiting for an answer that cannot come."""
    host, _, port = scheduler.partition("://")[2].rpartition(":")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=CONNECT_TIMEOUT).close()
    except OSError as exc:
        raise ClusterError(f"no Dask scheduler answers at {scheduler} ({exc.strerror or exc}); start one with "
                           "`dask scheduler` and workers with `dask worker ADDRESS`, or drop --scheduler "
                           "for a local cluster") from None


@contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None) -> Iterator[Client]:
    """A client on the scheduler at ``scheduler``, else on a new ``LocalCluster``.

    Parameters
    ----------
    workers
        Worker processes of the local cluster (default: one per core), one thread each: the
        algorithms are numpy/OpenCV code holding the GIL for much of their time, so processes,
        not threads, scale.
    scheduler
        Address of a running scheduler (``tcp://host:8786``), started with ``dask scheduler`` and
        fed by ``dask worker ADDRESS`` on each machine; its workers must see the session files
        at the same paths (a shared file system).
    """
    if scheduler:
        _reachable(scheduler)  # before importing Dask: an answer in one round trip
    from distributed import Client, LocalCluster

    from .worker_setup import OneLibraryThread

    # Dask logs every worker and connection at INFO; a command's output keeps to its own errors.
    logging.getLogger("distributed").setLevel(logging.ERROR)
    if scheduler:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError) as exc:
            raise ClusterError(f"no Dask scheduler answers at {scheduler} ({exc}); start one with "
                               "`dask scheduler` and workers with `dask worker ADDRESS`, or drop --scheduler "
                               "for a local cluster") from None
        with client:
            try:
                client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
            except TimeoutError:
                raise ClusterError(f"the Dask scheduler at {scheduler} has no workers; start one with "
                                   f"`dask worker {scheduler}`") from None
            client.register_plugin(OneLibraryThread())
            yield client
        return
    # Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536, to hand freed memory back to the
    # OS at once. That also turns off glibc's adaptive mmap threshold, so every large array of a chunk
    # (frames, images, masks) is mapped and page-faulted afresh: 180 000 faults and twice the time per
    # 1000-frame chunk here. The workers keep glibc's defaults.
    # Dask's monitoring wakes every process every 10-100 ms (stack sampling for the dashboard's
    # profile, event-loop ticks, memory polls): on a machine with as many workers as cores that is
    # CPU taken from the work (chunked detection: workers 8.5 -> 8.0 s of CPU each, 9.2 -> 8.6 s wall).
    # A local cluster has no dashboard; its checks run once a second.
    import dask

    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                          "distributed.worker.profile.enabled": False, "distributed.admin.tick.interval": "1s",
                          "distributed.worker.memory.monitor-interval": "1s",
                          "distributed.admin.system-monitor.interval": "2s"}), \
            LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                         dashboard_address=None, silence_logs=logging.CRITICAL) as cluster, Client(cluster) as client:
        client.register_plugin(OneLibraryThread())
        yield client


def describe(client: Client) -> dict[str, Any]:
    """Provenance of work run through ``client``: scheduler address, workers, threads, Dask version."""
    import distributed

    workers = client.scheduler_info(n_workers=-1)["workers"]
    return {"engine": f"dask.distributed {distributed.__version__}", "scheduler": client.scheduler.address,
            "workers": len(workers), "threads": sum(w["nthreads"] for w in workers.values())}
