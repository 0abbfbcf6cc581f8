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
- **Start-up.** A spawned worker imports Dask, CasADi and the planner itself (~2.5 s of CPU
  each, where a forked local worker inherits them): the LocalCluster's workers are forked from
  a fork server that imported them once (:func:`forkserver_with_planner`); its statistical
  profiler is off (it samples every thread every 10 ms).
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
#: the LocalCluster (scheduler and nannies in the driver, workers forked): no statistical
#: profiler (it samples every thread's stack every 10 ms), and Dask's periodic housekeeping
#: slowed down (an event-loop tick every 1 s instead of 20 ms, the system and memory monitors
#: every 5 s and 1 s): idle, the defaults cost the driver ~5 % of a core and each worker
#: ~2 %, CPU the planning never uses; a remote cluster keeps its own settings
LOCAL_CONFIG = {"distributed.worker.profile.enabled": False,
                "distributed.worker.multiprocessing-method": "forkserver",
                "distributed.admin.tick.interval": "1s",
                "distributed.admin.system-monitor.interval": "5s",
                "distributed.worker.memory.monitor-interval": "1s"}
#: what the forkserver imports once, so that every worker forked from it starts with them
PRELOAD = ("planner.library.build", "planner.methods.nlp", "planner.simulation.replay",
           "planner.feedforward", "planner.trajectory")


def forkserver_with_planner() -> None:
    """Start the LocalCluster's workers from a fork server that has imported Dask and the
    planner once (a spawned worker imports them itself: ~2.5 s of CPU per worker)."""
    import multiprocessing
    from distributed.utils import get_mp_context
    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        get_mp_context()     # Dask's own preload list (set once per process)
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(dict.fromkeys(
        ["distributed", "dask", "numpy", "casadi", *PRELOAD])))


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


def chunk_sizes(n: int, workers: int, largest: int = 4) -> list:
    """How many consecutive arguments each Dask task carries: one for each worker's first task
    (the first entries arrive as early as with single tasks), then the remaining work in
    chunks of up to ``largest`` that shrink to one towards the end (guided scheduling: the
    last tasks stay short, so no worker idles long while another finishes a big chunk)."""
    sizes = [1] * min(n, workers)
    left = n - len(sizes)
    while left > 0:
        k = max(1, min(largest, left // (4 * workers)))
        sizes.append(k)
        left -= k
    return sizes


def run_chunk(fn, arglist) -> list:
    """``[fn(*args) for args in arglist]``: one Dask task that plans several entries."""
    return [fn(*a) for a in arglist]


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

    def __init__(self, scheduler: str, setup=None, chunk: int = 4):
        self.scheduler, self._setup, self.chunk = scheduler, setup, chunk
        self.cluster = None
        self.client = None
        self.setup_info: list = []
        self._futures: set = set()

    def start(self) -> "DaskPool":
        try:
            if self.scheduler.startswith("local:"):
                n = int(self.scheduler.split(":", 1)[1])
                forkserver_with_planner()
                with dask.config.set({"distributed.nanny.pre-spawn-environ": worker_environ(),
                                      **LOCAL_CONFIG}):
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
        """Yield ``fn(*args)`` for every args tuple of ``arglist``, in completion order of the
        tasks (each carries :func:`chunk_sizes` arguments, in order). A task's results are
        released on its worker as soon as the driver has them (flat memory)."""
        arglist = list(arglist)
        workers = max(1, len(self.setup_info))
        groups, at = [], 0
        for k in chunk_sizes(len(arglist), workers, self.chunk):
            groups.append(arglist[at:at + k])
            at += k
        self._futures = {self.client.submit(run_chunk, fn, g, pure=False) for g in groups}
        for f in as_completed(list(self._futures)):
            rs = f.result()
            self._futures.discard(f)
            f.release()
            yield from rs

    def close(self) -> None:
        """Cancel what is still queued, disconnect, stop a cluster started here."""
        if self.client is not None:
            try:
                if self._futures:
                    self.client.cancel(list(self._futures))
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


__all__ = ["DaskPool", "SetupPlugin", "chunk_sizes", "run_chunk", "worker_environ"]
