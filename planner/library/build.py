"""Build a library of ready-to-replay moves for a machine's work cycle.

A task suite (problems/tasks/<name>.toml) expands to moves (id, start tip, goal tip). For every
move and objective a worker plans the move with a registered method (default ``nlp``; ``time``:
the minimum-time move; ``energy``: the least pump energy within 1.2 × the minimum time, for the
NLP :func:`~planner.methods.nlp.energy_optimal`),
judges it with :func:`~planner.trajectory.evaluate`, attaches 50 Hz valve feed-forward, and
scores its open-loop robustness (:func:`~planner.simulation.replay.robustness`). The driver is the single
writer of the HDF5 database (:mod:`planner.library.store`): entries are written one by one as results
arrive, failures are stored with their status and reason, and a rerun of the same command
skips the entries already in the file (a killed build resumes where it stopped).

Executors: in-process (``workers=1``), local processes (``workers=N``), or a Dask cluster
(``scheduler="tcp://host:8786"``; ``"local:N"`` starts a LocalCluster of N workers). Workers
build each solver once per process and reuse it for every move (the method's own cache).
"""
from __future__ import annotations

import time as _time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from planner.methods import PlanRequest, UnsupportedRequest, get, plan
from planner.tasks.suites import Move, load_suite

OBJECTIVES = ("time", "energy")
ENERGY_BUDGET = 1.2  # energy entries: least energy within 1.2 × the minimum time


# ------------------------------------------------------------------------------ worker side
def clear_planner_caches() -> None:
    """Forget the solvers the registered methods built in this process (worker processes
    forked afterwards build their own; benchmarks use it to time a build from scratch)."""
    from planner.methods import available
    for name in available():
        get(name).clear()


def check_method(method: str, moves, objectives, obstacles) -> None:
    """Refuse, before anything is written, a method that cannot plan the suite's requests
    (UnsupportedRequest / KeyError with the reason)."""
    p = get(method)
    if moves:
        for o in objectives:
            p.check(_request(moves[0], o, 40, obstacles, 1.0 if o == "energy" else None))


def _request(move: Move, objective: str, N: int, obstacles, duration=None, time_result=None):
    return PlanRequest(move.start, move.goal, objective=objective, path="free",
                       duration=duration, obstacles=obstacles,
                       options=dict(intervals=N, time_result=time_result))


def plan_entry(crane_id: str, move: Move, objective: str, N: int = 40,
               robustness: bool = True, obstacles: tuple = (), method: str = "nlp") -> dict:
    """Plan one library entry with the registered ``method`` (runs in a worker): ``time`` the
    minimum-time move, ``energy`` the least pump energy within ENERGY_BUDGET × that time. Never
    raises for planning failures: they come back as a status with a reason."""
    from planner.feedforward import commands
    from planner.model import Crane
    from planner.trajectory import evaluate
    t0 = _time.perf_counter()
    out = dict(id=f"{move.id}:{objective}", start=move.start, goal=move.goal,
               objective=objective, method=method)
    try:
        crane = Crane.from_id(crane_id)
        rt = plan(crane, _request(move, "time", N, obstacles), method)
        res = rt
        if rt.ok and objective == "energy":
            res = plan(crane, _request(move, "energy", N, obstacles,
                                       duration=ENERGY_BUDGET * rt.duration_s, time_result=rt),
                       method)
            out["energy_winner"] = res.stats.get("energy_winner")
        if not res.ok:
            return dict(out, status=res.status, reason=res.reason,
                        solve_s=_time.perf_counter() - t0)
        traj = res.trajectory
        verdict = evaluate(crane, traj)  # the judge sees the plan itself
        if verdict.max_limit_violation > 1e-3:
            worst = max(verdict.violations, key=verdict.violations.get)
            return dict(out, status="limits", reason=f"evaluate(): {worst} exceeded by "
                        f"{100 * verdict.max_limit_violation:.2f} %",
                        solve_s=_time.perf_counter() - t0)
        # stored: the plan sampled at the 50 Hz control rate with its valve commands, and the
        # derived channels (strokes, pressures, pump) on those samples
        clear = float("nan")
        if obstacles:  # the tip's least distance to any obstacle, on a 1 kHz resampling
            from planner.geometry.paths import tip_to_xyz
            cyl = crane.tip(traj.sample(traj.resample(1000.0))[0])
            clear = min(float(ob.distance(tip_to_xyz(cyl), cyl).min()) for ob in obstacles)
        # the plan on the 50 Hz control grid plus its own nodes: the stored samples reproduce
        # the plan exactly (the jerk limit holds on the reconstruction, not only on the plan)
        traj_u = commands(crane, traj, 50.0).attach(traj, knots=True)
        ev = evaluate(crane, traj_u)
        rob = float("nan")
        if robustness:
            from planner.simulation.replay import robustness as robust
            rob = float(robust(crane, traj_u)["score_m"])
        return dict(out, status="ok", reason="", trajectory=traj_u, evaluation=ev,
                    robustness=rob, clearance_m=clear, solve_s=_time.perf_counter() - t0,
                    iterations=res.stats.get("iterations", 0))
    except UnsupportedRequest as e:
        return dict(out, status="unsupported", reason=str(e), solve_s=_time.perf_counter() - t0)
    except Exception as e:  # a failed move must never stop the build: record why
        return dict(out, status="error", reason=f"{type(e).__name__}: {e}",
                    solve_s=_time.perf_counter() - t0)


# ------------------------------------------------------------------------------ driver side
def build(crane_id: str, suite: str, out, *, objectives=("time",), workers: int = 1,
          scheduler: str | None = None, limit: int | None = None, N: int = 40,
          robustness: bool = True, progress: bool = True, method: str = "nlp") -> dict:
    """Build (or resume) the library ``out`` (HDF5) with the registered planning ``method``
    (default: the NLP). Returns a summary dict."""
    from tqdm import tqdm

    from planner.model import Crane
    from planner.library.store import LibraryStore
    bad = [o for o in objectives if o not in OBJECTIVES]
    if bad:
        raise ValueError(f"objectives: unknown {bad}; allowed: {', '.join(OBJECTIVES)}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    crane = Crane.from_id(crane_id)
    meta, moves = load_suite(suite)
    obstacles = meta["obstacles"]
    if limit is not None:
        if limit < 1:
            raise ValueError(f"limit: {limit}: must be a whole number of moves >= 1")
        moves = moves[:limit]
    check_method(method, moves, objectives, obstacles)
    out = Path(out)
    db = (LibraryStore.open(out, "a", spec=crane.spec) if out.exists()
          else LibraryStore.create(out, crane.spec))
    t0 = _time.perf_counter()
    with db:
        done = set(db.ids())
        todo = [(m, o) for m in moves for o in objectives if f"{m.id}:{o}" not in done]
        # the slow energy entries first (longest-first packing: less idle tail on the workers)
        todo.sort(key=lambda mo: mo[1] != "energy")
        skipped = len(moves) * len(objectives) - len(todo)
        bar = tqdm(total=len(todo), desc=f"library {crane.spec.id}", unit="entry",
                   disable=not progress)
        counts: dict = {}

        def write(r):
            traj = r.pop("trajectory", None)
            ev = r.pop("evaluation", None)
            db.add(r["id"], traj, start=r["start"], goal=r["goal"], objective=r["objective"],
                   method=r["method"], status=r["status"], reason=r.get("reason", ""),
                   evaluation=ev, robustness=r.get("robustness", float("nan")),
                   attrs=dict(solve_s=r.get("solve_s"), suite=suite,
                              energy_winner=r.get("energy_winner"),
                              clearance_m=r.get("clearance_m")))
            counts[r["status"]] = counts.get(r["status"], 0) + 1
            bar.update(1)

        if scheduler:
            _run_dask(scheduler, crane_id, todo, N, robustness, obstacles, method, write)
        elif workers == 1:
            for m, o in todo:
                write(plan_entry(crane_id, m, o, N, robustness, obstacles, method))
        else:
            with ProcessPoolExecutor(max_workers=workers) as ex:
                futs = [ex.submit(plan_entry, crane_id, m, o, N, robustness, obstacles, method)
                        for m, o in todo]
                for f in as_completed(futs):
                    write(f.result())
        bar.close()
        info = db.info()
    return dict(status="ok", library=str(out), crane=crane.spec.id, suite=suite,
                moves=len(moves), objectives=list(objectives), planned=len(todo),
                skipped_existing=skipped, statuses=counts, seconds=_time.perf_counter() - t0,
                info=info)


def _run_dask(scheduler, crane_id, todo, N, robustness, obstacles, method, write):
    try:
        from dask.distributed import Client, LocalCluster, as_completed as dask_completed
    except ImportError:
        raise RuntimeError("a Dask scheduler needs the 'cluster' extra: "
                           "pip install 'crane-planner[cluster]'") from None
    cluster = None
    if scheduler.startswith("local:"):
        cluster = LocalCluster(n_workers=int(scheduler.split(":", 1)[1]), threads_per_worker=1,
                               processes=True, dashboard_address=None)
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        futs = [client.submit(plan_entry, crane_id, m, o, N, robustness, obstacles, method,
                              pure=False)
                for m, o in todo]
        for f in dask_completed(futs):
            write(f.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


__all__ = ["plan_entry", "build", "check_method", "clear_planner_caches", "OBJECTIVES"]
