"""A library build on a Dask cluster, as lean as the local process pool (issue 18).

:class:`DaskPool` has the face of :class:`~planner.library.workers.WorkerPool`: a context that
starts (``local:N``: a LocalCluster of N one-thread worker processes) or joins
(``tcp://host:port``) a cluster, gives every worker the build's set-up once, and yields task
results in completion order to the driver, which is the only writer of the database.

Where the Dask path used to lose time, and what is done here:

- **Allocator.** A Dask nanny starts each worker with ``MALLOC_TRIM_THRESHOLD_=65536``; that
  made every IPOPT solve 25-35 % slower than in a plain process
  (:func:`~planner.library.workers.tune_malloc` explains why). The LocalCluster started here
  leaves the variable out of the workers' environment, and every worker, local or remote,
  restores glibc's fast setting when it is set up.
- **Per-worker set-up.** A :class:`SetupPlugin` (a Dask ``WorkerPlugin``) runs the build's
  set-up (the machine model, the method's solvers for every objective) once in every worker,
  including workers that join later; the driver waits for it on the workers there are and
  collects each one's seconds.
- **Threads.** One thread per worker: the solvers hold the GIL, a second thread only contends.
- **Payloads and order.** Tasks carry the move and the options (the worker has the rest);
  results are taken with ``as_completed``; a task's failure comes back as a status (the task
  itself never raises).
"""
from __future__ import annotations

import os
import socket

import dask
from dask.distributed import Client, LocalCluster, WorkerPlugin, as_completed

from planner.library.workers import run_setup, tune_malloc

SETUP_ATTR = "crane_planner_setup"  # where a worker keeps its set-up report


class SetupPlugin(WorkerPlugin):
    """Runs ``setup`` once in every worker (after :func:`tune_malloc`) and keeps the report
    (pid, host, seconds, error) on the worker for :meth:`DaskPool.setup_info`."""

    name = "crane-planner-setup"

    def __init__(self, task_setup):
        self.task_setup = task_setup

    def setup(self, worker):
        fn = self.task_setup
        info = run_setup(lambda: dict(fn() if fn is not None else {}, malloc_tuned=tune_malloc(),
                                      host=socket.gethostname(),
                                      malloc_env=os.environ.get("MALLOC_TRIM_THRESHOLD_")))
        info["worker"] = worker.address
        setattr(worker, SETUP_ATTR, info)


def _setup_report(dask_worker) -> dict:
    return getattr(dask_worker, SETUP_ATTR, dict(pid=os.getpid(), setup_s=float("nan"),
                                                 error="not set up"))


def worker_environ() -> dict:
    """The environment a LocalCluster's nanny gives its workers: Dask's default without
    ``MALLOC_TRIM_THRESHOLD_`` (the BLAS/OpenMP one-thread settings stay)."""
    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {})
    env.pop("MALLOC_TRIM_THRESHOLD_", None)
    return env


class DaskPool:
    """A Dask cluster running one function over many argument tuples, each worker set up once.

    ``scheduler``: ``local:N`` (a LocalCluster of N processes with one thread each, started and
    stopped here) or the address of a running scheduler. ``setup``: a picklable callable
    returning a dict (or None), run once per worker."""

    def __init__(self, scheduler: str, setup=None):
        self.scheduler, self._setup = scheduler, setup
        self.cluster = None
        self.client = None
        self.setup_info: list = []
        self._futures: list = []

    def start(self) -> "DaskPool":
        try:
            if self.scheduler.startswith("local:"):
                n = int(self.scheduler.split(":", 1)[1])
                with dask.config.set({"distributed.nanny.pre-spawn-environ": worker_environ()}):
                    self.cluster = LocalCluster(n_workers=n, threads_per_worker=1,
                                                processes=True, dashboard_address=None)
                self.client = Client(self.cluster)
            else:
                self.client = Client(self.scheduler)
            self.client.register_plugin(SetupPlugin(self._setup))
            reports = self.client.run(_setup_report)
            self.setup_info = [dict(r, worker=a) for a, r in sorted(reports.items())]
        except BaseException:
            self.close()
            raise
        return self

    def imap_unordered(self, fn, arglist):
        """Yield ``fn(*args)`` for every args tuple of ``arglist``, in completion order."""
        self._futures = [self.client.submit(fn, *a, pure=False) for a in arglist]
        for f in as_completed(self._futures):
            yield f.result()

    def close(self) -> None:
        """Cancel what is still queued, disconnect, stop a cluster started here."""
        if self.client is not None:
            try:
                if self._futures:
                    self.client.cancel(self._futures)
            finally:
                self.client.close()
                self.client = None
        if self.cluster is not None:
            self.cluster.close()
            self.cluster = None

    def __enter__(self) -> "DaskPool":
        return self.start()

    def __exit__(self, *exc) -> bool:
        self.close()
        return False


__all__ = ["DaskPool", "SetupPlugin", "worker_environ"]
