"""Worker processes and signals of a library build: Ctrl-C stops promptly, no orphan survives.

:class:`WorkerPool` wraps a ``ProcessPoolExecutor`` whose workers

- ignore SIGINT (a terminal's Ctrl-C reaches the whole process group: the driver alone decides,
  and the workers print no tracebacks),
- die with the driver: Linux ``PR_SET_PDEATHSIG`` (SIGKILL) set through ctypes, elsewhere a
  watchdog thread polling ``os.getppid()``; a worker whose driver is already gone exits at once,
- are all started before the driver opens the database or takes its lock (a forked child
  would share those file handles and keep the file locked after the driver died).

:meth:`WorkerPool.terminate` ends them (SIGTERM, then SIGKILL after a grace period). A pool
may be given a ``setup`` callable that every worker runs once at start (build the planner it
will reuse for every task) and whose result (e.g. its set-up seconds) the driver collects in
:attr:`WorkerPool.setup_info`; :func:`tune_malloc` is the allocator setting every worker of a
build gets (see there why).
:class:`SignalGuard` turns SIGINT / SIGTERM in the driver into :class:`Interrupted`, held back
while an entry is being written so that the database is never left half-written.
"""
from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager

PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # <malloc.h> mallopt parameters
MMAP_THRESHOLD = 32 << 20  # glibc's largest (HEAP_MAX_SIZE / 2 on 64-bit)
START_TIMEOUT_S = 120.0  # every worker must have started within this
GRACE_S = 2.0  # SIGTERM -> SIGKILL


class Interrupted(KeyboardInterrupt):
    """A build stopped by a signal. ``signum`` is the signal; ``summary`` (set by the build) says
    what was written. A KeyboardInterrupt, so ``except Exception`` never swallows it."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.summary: dict = {}

    @property
    def exit_code(self) -> int:
        """The shell convention for a process ended by a signal: 128 + signal number."""
        return 128 + self.signum


class WorkerLost(RuntimeError):
    """A worker process ended while it worked (killed by the OOM killer or a process manager,
    or crashed): ``pid``, ``exitcode`` (negative: the signal), ``task`` (the label of the task it
    was running, "" when unknown), ``how`` (in words); ``summary`` is set by the build."""

    def __init__(self, pid: int, exitcode: int | None, task: str):
        if exitcode is not None and exitcode < 0:
            try:
                how = f"killed by {signal.Signals(-exitcode).name}"
            except ValueError:
                how = f"killed by signal {-exitcode}"
        else:
            how = f"exit code {exitcode}"
        super().__init__(f"worker process {pid} ended ({how})"
                         + (f" while running {task}" if task else ""))
        self.pid, self.exitcode, self.task, self.how = pid, exitcode, task, how
        self.summary: dict = {}


_STARTED = None  # in a worker: the queue on which it says which task it starts (pid, index)


def _tracked(index: int, fn, *args):
    """Run one task in a worker, after telling the driver that this process runs it."""
    if _STARTED is not None:
        _STARTED.put((os.getpid(), index))
    return fn(*args)


def die_with_parent(parent_pid: int) -> None:
    """Make this process end when the process ``parent_pid`` ends (call it in the child)."""
    armed = False
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent_pid:  # the parent died before the death signal was armed
        os._exit(1)
    if not armed:
        def watch():
            while os.getppid() == parent_pid:
                time.sleep(1.0)
            os._exit(1)
        threading.Thread(target=watch, name="parent-watchdog", daemon=True).start()


def tune_malloc() -> bool:
    """Keep glibc's allocator from handing memory back to the kernel after every solve.

    A Dask nanny starts its workers with ``MALLOC_TRIM_THRESHOLD_=65536`` (so that freed memory
    shows in its memory monitor). Any such setting also switches off glibc's dynamic mmap
    threshold: every block over 128 KiB then comes from a fresh ``mmap`` and page-faults on
    first touch. IPOPT/MUMPS allocate and free such blocks in every iteration; measured on the
    library's minimum-time moves (s100f), each solve took 25-35 % longer in a Dask worker than
    in a plain process, and the same in a plain process given that variable. Raising the mmap
    threshold to glibc's largest (and the trim threshold to twice it, glibc's own ratio)
    restores the plain process's speed. Linux/glibc only; elsewhere (or without ``mallopt``)
    nothing is changed. Returns whether the setting took."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)
        return bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)
                    and libc.mallopt(M_TRIM_THRESHOLD, 2 * MMAP_THRESHOLD))
    except (OSError, AttributeError):
        return False


def run_setup(setup) -> dict:
    """Run a worker's ``setup()`` (None: nothing) and time it. Never raises: a failed set-up is
    reported (``error``) and the worker goes on (its tasks build what they need, or fail with
    their own reason)."""
    t0 = time.perf_counter()
    info: dict = dict(pid=os.getpid(), error="")
    try:
        info.update((setup() if setup is not None else None) or {})
    except Exception as e:  # reported to the driver, the build goes on
        info["error"] = f"{type(e).__name__}: {e}"
    info["setup_s"] = time.perf_counter() - t0
    return info


def worker_init(parent_pid: int, barrier, setup=None, report=None, started=None) -> None:
    """Initializer of every pool worker: ignore SIGINT, SIGTERM ends it (not the driver's
    handler it inherited), die with the driver, run ``setup`` (its timing goes to the
    ``report`` queue), then wait until all workers have started (so that none is forked later,
    after the driver opened files)."""
    global _STARTED
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _STARTED = started
    die_with_parent(parent_pid)
    info = run_setup(setup)
    if report is not None:
        report.put(info)
    barrier.wait(START_TIMEOUT_S)


def _pid() -> int:
    return os.getpid()


class WorkerPool:
    """``workers`` local processes running one function over many argument tuples; each runs
    ``setup()`` (a picklable callable returning a dict, or None) once when it starts."""

    def __init__(self, workers: int, setup=None):
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.workers = workers
        self.setup = setup
        self.setup_info: list = []  # one dict per worker: pid, setup_s, error, setup's own keys
        self._ex: ProcessPoolExecutor | None = None
        self.processes: list = []

    def start(self) -> "WorkerPool":
        """Start all workers now (returns when every worker has run its set-up and is waiting
        for tasks)."""
        ctx = mp.get_context()
        before = set(mp.active_children())
        barrier = ctx.Barrier(self.workers)
        report = ctx.SimpleQueue()
        self._started = ctx.SimpleQueue()
        self._ex = ProcessPoolExecutor(self.workers, mp_context=ctx, initializer=worker_init,
                                       initargs=(os.getpid(), barrier, self.setup, report,
                                                 self._started))
        # one trivial task per worker: each submit starts one process (none can finish before
        # the barrier lets all of them through, so no worker is left to be forked later)
        try:
            warm = [self._ex.submit(_pid) for _ in range(self.workers)]
            self.processes = [p for p in mp.active_children() if p not in before]
            for f in warm:
                f.result(timeout=START_TIMEOUT_S)
            # every initializer reported before passing the barrier that the warm tasks waited on
            self.setup_info = sorted((report.get() for _ in range(self.workers)),
                                     key=lambda d: d["pid"])
        except BaseException:  # an interrupt while starting: no worker is left behind
            self.processes = [p for p in mp.active_children() if p not in before]
            self.terminate()
            raise
        return self

    def imap_unordered(self, fn, arglist, label=repr):
        """Yield ``fn(*args)`` for every args tuple of ``arglist``, in completion order. A
        result is held only until it is yielded (a long build's memory stays flat). A worker
        that dies raises :class:`WorkerLost` naming the task it ran (``label(args)``)."""
        arglist = list(arglist)
        pending = {self._ex.submit(_tracked, i, fn, *args) for i, args in enumerate(arglist)}
        # no cancel() on the way out: after terminate() the executor fails the pending futures
        # itself (cancelling them as well races with that: InvalidStateError on Python 3.11)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            while done:
                try:
                    yield done.pop().result()
                except BrokenProcessPool:
                    raise self._lost(arglist, label) from None

    def _lost(self, arglist, label) -> WorkerLost:
        """Which worker died (the one not ended by the executor's own SIGTERM, if any), how,
        and the task it had started last."""
        last: dict = {}
        while not self._started.empty():
            pid, i = self._started.get()
            last[pid] = i
        for p in self.processes:
            p.join(1.0)
        dead = [p for p in self.processes if p.exitcode not in (None, 0)]
        dead.sort(key=lambda p: p.exitcode == -signal.SIGTERM)
        if not dead:
            return WorkerLost(0, None, "")
        p = dead[0]
        i = last.get(p.pid)
        return WorkerLost(p.pid, p.exitcode, "" if i is None else label(arglist[i]))

    def terminate(self) -> None:
        """End the workers now: SIGTERM, SIGKILL after GRACE_S; then shut the executor down."""
        for p in self.processes:
            if p.is_alive():
                p.terminate()
        deadline = time.monotonic() + GRACE_S
        for p in self.processes:
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join(GRACE_S)
        if self._ex is not None:
            self._ex.shutdown(wait=False)
            self._ex = None

    def close(self, wait: bool = True) -> None:
        """Shut the executor down (``wait``: let the workers finish their current task)."""
        if self._ex is not None:
            self._ex.shutdown(wait=wait, cancel_futures=True)
            self._ex = None

    def __enter__(self) -> "WorkerPool":
        return self.start()

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            self.close()
        else:  # an error or an interrupt: do not wait for the tasks in flight
            self.terminate()
        return False


class SignalGuard:
    """While active (in the main thread only; elsewhere it does nothing), SIGINT and SIGTERM
    raise :class:`Interrupted` at once, except inside :meth:`critical` where the first one is
    held until the block ends. After the first, further signals are ignored so that the cleanup
    (ending workers, closing the file) runs to its end."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self._old: dict = {}
        self._depth = 0
        self.pending: int | None = None
        self.fired = False

    def _handler(self, signum, frame):
        if self.fired:
            return
        if self._depth:
            self.pending = self.pending or signum
            return
        self.fired = True
        raise Interrupted(signum)

    @contextmanager
    def critical(self):
        """A block that a signal must not cut in half (writing one entry)."""
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            if self._depth == 0 and self.pending and not self.fired:
                self.fired = True
                raise Interrupted(self.pending)

    def __enter__(self) -> "SignalGuard":
        if threading.current_thread() is threading.main_thread():
            self._old = {s: signal.signal(s, self._handler) for s in self.SIGNALS}
        return self

    def __exit__(self, *exc) -> bool:
        for s, h in self._old.items():
            signal.signal(s, h)
        self._old = {}
        return False
