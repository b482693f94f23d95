"""dask.distributed for sweeps: a LocalCluster on this machine or an existing cluster by address.

Thread budget: a task runs PARDISO and dense algebra in MKL's and OpenBLAS's thread pools. With
several tasks on one machine those pools must share its cores, so every task on a host gets
``cores // slots`` threads (at least 1), where ``slots`` is the number of tasks the workers on
that host run at once (the sum of their ``nthreads``). The budget is computed by the client from
the workers present at submission; a worker that joins later uses the budget of its host if
known, else 1 thread. The worker applies it with environment variables (for libraries not yet
loaded) and threadpoolctl (for those already loaded), see :func:`limit_threads`.

dask is an optional dependency (``pip install 'contactopt[cluster]'``); it is imported here only.
"""

from __future__ import annotations

import inspect
import logging
import os
from contextlib import contextmanager
from urllib.parse import urlparse

from ..errors import ContactOptError

log = logging.getLogger(__name__)

THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


class ClusterError(ContactOptError):
    """dask.distributed is missing, or the scheduler cannot be reached."""


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def _require_distributed():
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise ClusterError("sweeps run on dask.distributed, which is not installed: "
                           "pip install 'contactopt[cluster]'") from None


def host_of(address: str) -> str:
    return urlparse(address).hostname or address


@contextmanager
def connect(*, workers: int | None = None, scheduler: str | None = None, threads: int | None = None,
            dashboard_address: str = ":8787"):
    """Yield a ``distributed.Client``: to ``scheduler`` if given, else to a new LocalCluster of
    ``workers`` single-threaded worker processes (default: one per usable core). The cluster made
    here is closed on exit; an existing one is left running."""
    _require_distributed()
    from distributed import Client, LocalCluster
    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise ClusterError(f"cannot reach the dask scheduler at {scheduler}: {exc}") from None
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or usable_cores()
    per_task = threads or max(1, usable_cores() // n)
    # set before MKL and OpenBLAS load in the worker processes; dask puts them into this
    # process's environment to spawn the workers, and they are taken out again afterwards, so
    # that a sweep started from Python (a notebook, a test) leaves the caller's threads alone
    env = {var: str(per_task) for var in THREAD_VARS}
    saved = {var: os.environ.get(var) for var in THREAD_VARS}
    try:
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=dashboard_address, env=env)
    finally:
        _restore_environment(saved)
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()


def _restore_environment(saved: dict) -> None:
    for var, value in saved.items():
        if value is None:
            os.environ.pop(var, None)
        else:
            os.environ[var] = value


def dashboard_link(client) -> str | None:
    """The dashboard's address, or None when the scheduler serves none. Its pages need bokeh
    where the scheduler runs; for a local cluster a missing bokeh is said with the link."""
    try:
        if "dashboard" not in client.scheduler_info().get("services", {}):
            return None
        link = client.dashboard_link
    except Exception:  # pragma: no cover - an old scheduler without the services entry
        return None
    if type(client.cluster).__name__ == "LocalCluster":
        try:
            import bokeh  # noqa: F401
        except ImportError:
            link += " (its pages need bokeh: pip install 'contactopt[cluster]')"
    return link


def thread_budget(client, threads: int | None = None) -> dict:
    """{host: threads per task} for the workers connected now (``threads`` forces one number)."""
    workers = client.scheduler_info(n_workers=-1)["workers"] if _takes_n_workers(client) \
        else client.scheduler_info()["workers"]
    if threads:
        return {host_of(a): int(threads) for a in workers}
    cores = client.run(usable_cores)
    slots: dict = {}
    host_cores: dict = {}
    for addr, info in workers.items():
        h = host_of(addr)
        slots[h] = slots.get(h, 0) + int(info.get("nthreads", 1))
        host_cores[h] = max(host_cores.get(h, 1), int(cores.get(addr, 1)))
    return {h: max(1, host_cores[h] // slots[h]) for h in slots}


def _takes_n_workers(client) -> bool:
    return "n_workers" in inspect.signature(client.scheduler_info).parameters


def limit_threads(n: int) -> int:
    """Limit MKL, OpenMP and OpenBLAS to ``n`` threads in this process (a worker); returns n.

    MKL (PARDISO's library) is loaded first, so threadpoolctl finds it; libraries loaded later
    read the environment variables."""
    for var in THREAD_VARS:
        os.environ[var] = str(n)
    try:
        from ..fem import _pardiso
        _pardiso.available()
    except Exception:  # pragma: no cover - SciPy backend
        pass
    try:
        from threadpoolctl import threadpool_limits
        threadpool_limits(limits=n)
    except Exception as exc:  # pragma: no cover - threadpoolctl is a dependency
        log.warning("cannot limit the thread pools to %d threads: %s", n, exc)
    return n
