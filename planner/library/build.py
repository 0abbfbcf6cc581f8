"""Build a library of ready-to-replay moves for a machine's work cycle.

A suite (planner/problems/tasks/<name>.toml) expands to moves (id, start tip, goal tip). For every
move (one task, :func:`plan_move`: the minimum-time solve shared by its objectives) and
objective a worker plans the move with a registered method (default ``nlp``; ``time``:
the minimum-time move; ``energy``: the least pump energy within 1.2 × the minimum time, for the
NLP :func:`~planner.methods.nlp.energy_optimal`),
judges it with :func:`~planner.trajectory.evaluate`, attaches 50 Hz valve feed-forward, and
scores its open-loop robustness (:func:`~planner.simulation.replay.robustness`). The driver is the single
writer of the HDF5 database (:mod:`planner.library.store`): entries are written one by one as results
arrive, failures are stored with their status and reason, and a rerun of the same command
skips the entries already in the file (a killed build resumes where it stopped).

Executors: in-process (``workers=1``), local processes (``workers=N``), or a Dask cluster
(``scheduler="tcp://host:8786"``; ``"local:N"`` starts a LocalCluster of N one-thread workers,
:mod:`planner.library.cluster`). Every worker runs :class:`WorkerSetup` once when it starts
(the machine model and the method's solvers for every objective, built or loaded from the
compiled cache) and reuses them for every move; its seconds are in the summary
(``worker_setup_s``), with ``first_entry_s``, the time from the last worker's set-up to the
first entry written. Tasks carry only the move and the options; the driver gathers results
as they complete and is the only writer.

Records: :class:`BuildSettings` (what is fixed for the whole build), :class:`MoveJob` (one
task: a move and the objectives it lacks) and :class:`EntryResult` (one planned entry, as the
worker returns it), all frozen and picklable. Each method turns the settings into its own
request (:meth:`~planner.methods.base.Planner.library_request`: the plain request by default,
the NLP adds its intervals and the minimum-time result that warm-starts its energy entry).

Faults: one build per file (:mod:`planner.library.lock`: a second one is told the first one's
pid); Ctrl-C or SIGTERM stops the build within seconds, ends the workers, completes the entry
being written and leaves a resumable file; local workers die with a killed driver
(:mod:`planner.library.workers`). Bad options (limit, objectives, a scheduler without Dask) are
refused before any file is created.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import signal
import time as _time
from contextlib import nullcontext
from dataclasses import dataclass, replace
from pathlib import Path

from planner.io import progress
from planner.library.journal import WriteFailed
from planner.library.lock import BuildLock
from planner.library.swing import (GrappleError, grapple_setting, pendulum_of, same_grapple,
                                   swing_attrs)
from planner.library.workers import (Interrupted, SignalGuard, WorkerLost, WorkerPool,
                                     run_setup)
from planner.methods import PlanStatus, UnsupportedRequest, get, plan
from planner.tasks.suites import Move, load_suite

if TYPE_CHECKING:
    from planner.model import Crane

OBJECTIVES = ("time", "energy")
ENERGY_BUDGET = 1.2  # energy entries: least energy within 1.2 × the minimum time


# ------------------------------------------------------------------------------ records
@dataclass(frozen=True)
class BuildSettings:
    """What is fixed for a whole build and every worker of it (picklable: shipped to local
    and Dask workers). ``crane_id``: the machine; ``suite``: the task suite's name (stored
    with every entry); ``method``: the registered planning method; ``objectives``: the build's
    objectives (:data:`OBJECTIVES`); ``intervals``: the NLP's N; ``robustness``: score every
    entry's open-loop robustness; ``obstacles``: the suite's; ``energy_budget``: an energy
    entry's duration limit as a multiple of the move's minimum time; ``grapple``: the link the
    load hangs on, (length [m] or None for the spec's ``[dynamics.grapple]``, pin damping as a
    share of critical or None), or None: no grapple (every entry then carries the swing the
    model predicts, :func:`planner.library.swing.swing_attrs`). Each method turns these
    into its own request (:meth:`~planner.methods.base.Planner.library_request`)."""
    crane_id: str
    suite: str = ""
    method: str = "nlp"
    objectives: tuple = ("time",)
    intervals: int = 40
    robustness: bool = True
    obstacles: tuple = ()
    energy_budget: float = ENERGY_BUDGET
    grapple: tuple | None = None     # (link length [m] or None: the spec's, pin zeta or None)

    def __post_init__(self):
        object.__setattr__(self, "objectives", tuple(self.objectives))
        object.__setattr__(self, "obstacles", tuple(self.obstacles))


@dataclass(frozen=True)
class MoveJob:
    """One task of a build: the entries of ``move`` for ``objectives`` (those the library
    lacks), planned under ``settings`` by :func:`plan_move`."""
    settings: BuildSettings
    move: Move
    objectives: tuple

    def __post_init__(self):
        object.__setattr__(self, "objectives", tuple(self.objectives))


@dataclass(frozen=True)
class EntryResult:
    """One planned entry as a worker hands it to the driver (the single writer): the fields
    of the stored entry (``trajectory`` and ``evaluation`` when ok, else None) and the
    figures stored as its attributes (``solve_s``, ``cpu_s``, ``build_s`` [s],
    ``clearance_m`` [m], ``energy_winner``, and ``swing``: the
    :func:`~planner.library.swing.swing_attrs` of a build with a grapple; None where not
    measured). ``iterations``: the method's own count (not stored)."""
    id: str
    start: tuple
    goal: tuple
    objective: str
    method: str
    status: str = ""
    reason: str = ""
    trajectory: object = None
    evaluation: object = None
    robustness: float = math.nan
    clearance_m: float | None = None
    solve_s: float | None = None
    cpu_s: float | None = None
    build_s: float | None = None
    iterations: int = 0
    energy_winner: str | None = None
    swing: dict | None = None


# ------------------------------------------------------------------------------ worker side
def clear_planner_caches() -> None:
    """Forget the solvers the registered methods built in this process (worker processes
    forked afterwards build their own; benchmarks use it to time a build from scratch)."""
    from planner.methods import available
    for name in available():
        get(name).clear()


def check_method(settings: BuildSettings, crane: Crane, moves) -> None:
    """Refuse, before anything is written, a method that cannot plan the suite's requests
    (UnsupportedRequest / KeyError with the reason)."""
    p = get(settings.method)
    if moves:
        for o in settings.objectives:
            p.check(p.library_request(crane, moves[0], o, settings=settings))


@dataclass(frozen=True)
class WorkerSetup:
    """What a worker builds once, before its first task: the machine model and the planning
    method's solvers for every objective of the build (:meth:`Planner.prepare`: loaded from the
    compiled cache when there is an entry, built otherwise) for requests like ``move``'s (None:
    nothing to prepare). Picklable: it is shipped to every worker, local or remote."""
    settings: BuildSettings
    move: Move | None = None

    def __call__(self) -> dict:
        from planner.model import Crane
        crane = Crane.from_id(self.settings.crane_id)
        p = get(self.settings.method)
        built = 0.0
        if self.move is not None:
            for o in self.settings.objectives:
                built += p.prepare(crane, p.library_request(crane, self.move, o,
                                                            settings=self.settings))
        return dict(solver_build_s=built)


def plan_entry(settings: BuildSettings, move: Move, objective: str) -> EntryResult:
    """Plan one library entry with the registered ``settings.method`` (runs in a worker):
    ``time`` the minimum-time move, ``energy`` the least pump energy within
    ``settings.energy_budget`` × that time. Never raises for planning failures: they come back
    as a status with a reason."""
    return plan_move(MoveJob(settings, move, (objective,)))[0]


def plan_move(job: MoveJob) -> list:
    """The entries of ``job.move`` for each of ``job.objectives`` (:class:`EntryResult`, in
    that order). The minimum-time move is solved once and serves every objective: the time
    entry is it, the energy entry's budget and warm start come from it (a move with both
    entries used to solve it twice). ``solve_s`` and ``cpu_s`` of each entry count from the
    move's start, so the shared minimum-time solve is in each."""
    from planner.model import Crane
    t0, c0 = _time.perf_counter(), _time.process_time()
    st, move = job.settings, job.move
    outs = [EntryResult(id=f"{move.id}:{o}", start=move.start, goal=move.goal, objective=o,
                        method=st.method) for o in job.objectives]
    try:
        crane = Crane.from_id(st.crane_id)
        p = get(st.method)
        rt = plan(crane, p.library_request(crane, move, "time", settings=st), st.method)
    except Exception as e:  # a failed move must never stop the build: record why
        return [_failed(out, e, t0) for out in outs]
    done = []
    for out in outs:
        try:
            res = rt
            if rt.ok and out.objective == "energy":
                res = plan(crane, p.library_request(crane, move, "energy", time_result=rt,
                                                    settings=st), st.method)
                out = replace(out, energy_winner=res.stats.get("energy_winner"))
            done.append(_entry(crane, st, out, rt, res, t0, c0))
        except Exception as e:
            done.append(_failed(out, e, t0))
    return done


def _failed(out: EntryResult, e: Exception, t0: float) -> EntryResult:
    if isinstance(e, UnsupportedRequest):
        return replace(out, status=PlanStatus.UNSUPPORTED, reason=str(e),
                       solve_s=_time.perf_counter() - t0)
    return replace(out, status=PlanStatus.ERROR, reason=f"{type(e).__name__}: {e}",
                   solve_s=_time.perf_counter() - t0)


def _entry(crane: Crane, st: BuildSettings, out: EntryResult, rt, res, t0, c0) -> EntryResult:
    """One entry of :func:`plan_move`: the plan ``res`` of its objective (``rt``, the move's
    minimum-time result, for the time entry) judged, with its feed-forward and robustness."""
    from planner.feedforward import commands, fills_oil
    from planner.trajectory import evaluate
    if not res.ok:
        return replace(out, status=res.status, reason=res.reason,
                       solve_s=_time.perf_counter() - t0)
    traj = res.trajectory
    verdict = evaluate(crane, traj)  # the judge sees the plan itself
    if verdict.max_limit_violation > 1e-3:
        worst = max(verdict.violations, key=verdict.violations.get)
        return replace(out, status=PlanStatus.LIMITS, reason=f"evaluate(): {worst} exceeded by "
                       f"{100 * verdict.max_limit_violation:.2f} %",
                       solve_s=_time.perf_counter() - t0)
    # stored: the plan sampled at the 50 Hz control rate with its valve commands, and the
    # derived channels (strokes, pressures, pump) on those samples
    clear = float("nan")
    if st.obstacles:  # the tip's least distance to any obstacle, on a 1 kHz resampling
        from planner.geometry.obstacles import tip_clearance
        clear = tip_clearance(crane.tip(traj.sample(traj.resample(1000.0))[0]), st.obstacles)
    # the plan on the 50 Hz control grid plus its own nodes: the stored samples reproduce
    # the plan exactly (the jerk limit holds on the reconstruction, not only on the plan)
    swing = swing_attrs(crane, st.grapple, st.obstacles, traj)
    # the machine's feed-forward: the oil springs filled where the crane has [dynamics]
    traj_u = commands(crane, traj, 50.0, oil=fills_oil(crane)).attach(traj, knots=True)
    ev = evaluate(crane, traj_u).at(traj_u.t)   # what the store keeps: small to ship
    rob = float("nan")
    if st.robustness:
        from planner.simulation.replay import robustness as robust
        rob = float(robust(crane, traj_u)["score_m"])
    return replace(out, status=PlanStatus.OK, reason="", trajectory=traj_u, evaluation=ev,
                   robustness=rob, clearance_m=clear, swing=swing,
                   solve_s=_time.perf_counter() - t0,
                   iterations=res.stats.get("iterations", 0),
                   # CPU seconds of the worker process (its own threads included) and the
                   # seconds spent building solvers (0: the worker's set-up had built them)
                   cpu_s=_time.process_time() - c0,
                   build_s=float(rt.stats.get("build_time_s", 0.0)
                                 + (res.stats.get("build_time_s", 0.0) if res is not rt else 0)))


# ------------------------------------------------------------------------------ driver side
class BuildError(ValueError):
    """A build request that cannot run (bad option, missing Dask): refused before any file is
    created."""


def check_scheduler(scheduler: str) -> None:
    """Refuse, before anything is written, a scheduler that cannot work: ``local:N`` with N not a
    positive integer, or any scheduler when Dask (the 'cluster' extra) is not installed."""
    if scheduler.startswith("local:"):
        n = scheduler.split(":", 1)[1]
        if not n.isdigit() or int(n) < 1:
            raise BuildError(f"`scheduler` {scheduler!r}: local:N needs N >= 1 workers")
    try:
        import dask.distributed  # noqa: F401  (only checked here; used by library.cluster)
    except ImportError:
        raise BuildError(f"`scheduler` {scheduler}: Dask is not installed; install the "
                         "'cluster' extra: pip install 'crane-planner[cluster]'") from None


def build(crane_id: str, suite: str, out, *, objectives=("time",), workers: int = 1,
          scheduler: str | None = None, limit: int | None = None, N: int = 40,
          robustness: bool = True, progress: bool = True, method: str = "nlp",
          compile: bool = False, grapple: float | bool | None = None,
          grapple_zeta: float | None = None) -> dict:
    """Build (or resume) the library ``out`` (HDF5) with the registered planning ``method``
    (default: the NLP). Returns a summary dict.

    ``grapple``: the load hangs on a link of that length [m] (True: the spec's
    ``[dynamics.grapple]``; None: no link, the load a point at the tip), its pins damped at
    ``grapple_zeta`` of critical (None: the spec's damping, or none); the methods that read it
    (``nlp-sway``, ``zv``, ``zvd``) plan with it, and every entry stores the swing the model
    predicts along it (:func:`planner.library.swing.swing_attrs`). A resumed build must name
    the same link as the entries already there.

    One build per file: another build on ``out`` is refused with the holder's pid
    (:class:`~planner.library.lock.LibraryBusy`). SIGINT / SIGTERM stop the build promptly
    (workers ended, the entry being written completed, the file closed and resumable) and
    raise :class:`~planner.library.workers.Interrupted` with the summary so far."""
    from planner.model import Crane
    from planner.library.store import LibraryStore
    bad = [o for o in objectives if o not in OBJECTIVES]
    if bad:
        raise BuildError(f"objectives: unknown {bad}; allowed: {', '.join(OBJECTIVES)}")
    if not objectives:
        raise BuildError(f"objectives: none given; allowed: {', '.join(OBJECTIVES)}")
    if workers < 1:
        raise BuildError(f"workers must be >= 1, got {workers}")
    if limit is not None and limit < 1:
        raise BuildError(f"limit must be >= 1 (the first N moves of the suite), got {limit}")
    if scheduler:
        check_scheduler(scheduler)
    crane = Crane.from_id(crane_id)
    meta, moves = load_suite(suite)
    if limit is not None:
        moves = moves[:limit]
    try:
        link = grapple_setting(crane, grapple, grapple_zeta)
    except GrappleError as e:
        raise BuildError(str(e)) from None
    settings = BuildSettings(crane.spec.id, suite, method, objectives, N, robustness,
                             meta["obstacles"], grapple=link)
    check_method(settings, crane, moves)
    prepared_s = 0.0
    if compile and moves:   # the solvers built (and stored) once, before any worker starts
        p = get(method)
        for o in objectives:
            prepared_s += p.prepare(crane, p.library_request(crane, moves[0], o,
                                                             settings=settings), compile=True)
    out = Path(out)
    if out.exists() and not out.is_file():
        raise BuildError(f"`out` {out}: not a regular file (a library is an HDF5 file)")
    out.parent.mkdir(parents=True, exist_ok=True)  # the lock file lives next to it
    t0 = _time.perf_counter()
    state = dict(todo=[], counts={}, written=0, skipped=0, setup=[], first_entry_t=None,
                 setup_done_t=None)
    setup = WorkerSetup(settings, moves[0] if moves else None)
    with SignalGuard() as guard:
        if scheduler:   # connected (and its workers set up) before any file is touched
            from planner.library.cluster import DaskPool
            pool = DaskPool(scheduler, setup)
        else:
            pool = WorkerPool(workers, setup) if workers > 1 else None
        try:
            # workers first: a forked worker must not inherit the lock or the open file
            with (pool or nullcontext()):
                if pool is not None:
                    state["setup"], state["setup_done_t"] = pool.setup_info, _time.perf_counter()
                with BuildLock(out):
                    db = (LibraryStore.open(out, "a", spec=crane.spec) if out.exists()
                          else LibraryStore.create(out, crane.spec))
                    with db:
                        try:
                            same_grapple(db, out, pendulum_of(crane, settings.grapple))
                        except GrappleError as e:
                            raise BuildError(str(e)) from None
                        _fill(db, settings, moves, pool, guard, state, setup,
                              show_progress=progress)
                        info = db.info()
        except Interrupted as e:
            e.summary = _summary(out, settings, moves, state, t0, status="interrupted",
                                 signal=signal.Signals(e.signum).name)
            raise
        except WorkerLost as e:   # the file holds every entry written: the rerun resumes
            e.summary = _summary(out, settings, moves, state, t0, status="worker_lost",
                                 reason=str(e), move=e.task.removeprefix("move "),
                                 exit_code=e.exitcode)
            raise
        except WriteFailed as e:   # the store rolled the file back to its last entry
            raise WriteFailed(out, OSError(e.errno, f"{e.why}; the entries finished before it "
                                                    f"are kept ({state['written']} of this run): "
                                                    "make room and rerun the same command to "
                                                    "resume")) from None
    return _summary(out, settings, moves, state, t0, status="ok", info=info,
                    prepare_s=prepared_s)


def _summary(out, settings: BuildSettings, moves, state, t0, **kw) -> dict:
    status = kw.pop("status")
    first = state.get("first_entry_t")
    done = state.get("setup_done_t")
    return dict(status=status, library=str(out), crane=settings.crane_id, suite=settings.suite,
                moves=len(moves), objectives=list(settings.objectives),
                planned=len(state["todo"]),
                skipped_existing=state["skipped"], written=state["written"],
                statuses=state["counts"], seconds=_time.perf_counter() - t0,
                workers=state.get("setup", []),
                worker_setup_s=[w["setup_s"] for w in state.get("setup", [])],
                setup_done_s=None if done is None else done - t0,
                first_entry_s=None if first is None or done is None else first - done, **kw)


def _move_label(args) -> str:
    """What a killed worker was doing: its task's move (WorkerPool.imap_unordered)."""
    return f"move {args[0].move.id}"


def _fill(db, settings: BuildSettings, moves, pool, guard, state, setup=None, *,
          show_progress: bool = True) -> None:
    """Plan the entries ``db`` lacks (one :class:`MoveJob` per move, on ``pool`` or, None, in
    this process after its ``setup``) and write each as it arrives (``state`` is kept current
    so that an interrupted build can still say what it wrote)."""
    objectives = settings.objectives
    done = set(db.ids())
    todo = [(m, o) for m in moves for o in objectives if f"{m.id}:{o}" not in done]
    # one task per move with all its missing objectives (the minimum-time solve shared); the
    # slow moves with an energy entry first (longest-first packing: less idle tail)
    per_move: dict = {}
    for m, o in todo:
        per_move.setdefault(m.id, (m, []))[1].append(o)
    tasks = sorted(per_move.values(), key=lambda mo: "energy" not in mo[1])
    state["todo"] = todo
    state["skipped"] = len(moves) * len(objectives) - len(todo)
    bar = progress(len(todo), f"library {settings.crane_id}", "entry",
                   enabled=show_progress)
    counts = state["counts"]

    def write(r: EntryResult):
        with guard.critical():  # a signal waits until the entry is complete
            if state["first_entry_t"] is None:
                state["first_entry_t"] = _time.perf_counter()
            db.add(r.id, r.trajectory, start=r.start, goal=r.goal, objective=r.objective,
                   method=r.method, status=r.status, reason=r.reason,
                   evaluation=r.evaluation, robustness=r.robustness,
                   attrs=dict(solve_s=r.solve_s, cpu_s=r.cpu_s, build_s=r.build_s,
                              suite=settings.suite, energy_winner=r.energy_winner,
                              clearance_m=r.clearance_m, **(r.swing or {})))
            state["written"] += 1
            counts[r.status] = counts.get(r.status, 0) + 1
            bar.update(1)

    jobs = [MoveJob(settings, m, tuple(objs)) for m, objs in tasks]
    if not jobs:
        bar.close()
        return
    try:
        if pool is None:   # in this process: its set-up first, timed like a worker's
            state["setup"] = [run_setup(setup)]
            state["setup_done_t"] = _time.perf_counter()
            for job in jobs:
                for r in plan_move(job):
                    write(r)
        else:
            kw = dict(label=_move_label) if isinstance(pool, WorkerPool) else {}
            for rs in pool.imap_unordered(plan_move, [(job,) for job in jobs], **kw):
                for r in rs:
                    write(r)
    finally:
        bar.close()


__all__ = ["BuildSettings", "MoveJob", "EntryResult", "plan_entry", "plan_move", "WorkerSetup",
           "build", "check_method", "check_scheduler", "clear_planner_caches", "BuildError",
           "OBJECTIVES", "ENERGY_BUDGET"]
