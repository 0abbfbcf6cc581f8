#!/usr/bin/env python3
"""Sway-free moves on the Exudyn plant with the grapple on its link (issue 29): the residual
swing after arrival and the duration of the sway-blind minimum-time plan (``nlp``), its ZV and
ZVD shaping (``zv``, ``zvd``) and the sway-free NLP (``nlp-sway``), side by side. s100f.

    python benchmarks/bench_sway.py [--moves 12 | --only ID,ID] [--suite claims|full]
                                    [--length 1.5] [--zeta 0.05]
                                    [--settle 6] [--methods nlp,zv,zvd,nlp-sway,nlp-sway+ffs]
                                    [--plant-length 1.8] [--plant-mass 1.2]
                                    [--plant-machine SEED [--calibrate SECONDS]]
                                    [--ff-iterations 150] [--swing-weight 10]
                                    [--out benchmarks/results] [--tag sway]
    python benchmarks/bench_sway.py --merge A.json B.json --tag NAME   # split runs, one table

Forwarder moves over the headboard (the library subset of the shipped forwarder cycle, half
pick-ups, half drops); every method plans with the headboard and the grapple it is told
(``--length``, ``--zeta``: share of critical damping at each pin); its 50 Hz nominal
feed-forward is replayed open loop on the Exudyn plant with the ``grapple_swing`` effect of the
same link, then ``--settle`` s with the valves closed. Measured from the plant's own tree
(:func:`planner.simulation.plants.load_swing`): the load's horizontal offset from under the
tip — its peak during the move, after arrival (the residual swing) and in the last second.
Beside them: the model's prediction (:func:`planner.model.pendulum.predict_swing`), the tip's
clearance from the headboard at 1 kHz and the load's (tip + the model's link) in the plan,
solve times. A method name may end in ``+ff`` (its commands refined on the dynamic twin,
:func:`planner.refine.refine_commands`, tip tracking and landing only) or ``+ffs`` (refined with
the swing term on the twin that carries the load on its link, :mod:`planner.model.twin.coupled`);
one plan per method and move serves all its variants. Beside the plant's swing: the twin's
predicted swing for the refined commands, the load's clearance from the headboard on the
plant's own grid (the load's centre of mass from the plant's tree) and the tip's distance from
the goal at the end of the record. Judge: the Exudyn plant.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for p in (str(ROOT), str(HERE)):
    if p not in sys.path:
        sys.path.insert(0, p)

from bench_exudyn_claims import subset_suite  # noqa: E402
from planner import Crane  # noqa: E402
from planner.bench.context import Settings  # noqa: E402
from planner.bench.suites import build_suite  # noqa: E402
from planner.feedforward import commands, with_settle  # noqa: E402
from planner.geometry.paths import tip_to_xyz, xyz_to_tip  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.methods import PlanRequest, plan  # noqa: E402
from planner.model.effects import make  # noqa: E402
from planner.model.pendulum import Pendulum, predict_swing  # noqa: E402
from planner.problems import task_path  # noqa: E402
from planner.tasks.suites import load_task_file  # noqa: E402
from planner.refine import RefineOptions, refine_commands  # noqa: E402
from planner.simulation.plants import load_swing, make_plant  # noqa: E402


#: method-name suffixes that replay the twin's refined commands instead of the nominal ones
FF = ("ff", "ffs")


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def sway_moves(work: Path, n: int, only: str | None = None, full: bool = False,
               tasks: str | None = None):
    """(suite, moves): the claims subset of the forwarder cycle (its suite file in ``work``;
    ``full``: the shipped forwarder cycle itself, 200 moves) and ``n`` of its moves spread
    evenly over the pick-up → drop and the drop → pick-up ones, or the ids of ``only`` (a
    comma list); ``tasks``: another suite file (e.g. ``random_suite.py``'s), ``n`` of its
    moves spread evenly."""
    work.mkdir(parents=True, exist_ok=True)
    if tasks:
        suite = load_task_file(tasks)
        ms = list(suite.moves)
        if only:
            return suite, [m for m in ms if m.id in only.split(",")]
        if n > len(ms):
            raise SystemExit(f"--moves {n}: {tasks} has {len(ms)} moves")
        return suite, [ms[int(i)] for i in np.linspace(0, len(ms) - 1, n).round()]
    src = (str(task_path("forwarder-cycle")) if full
           else str(subset_suite(work / "forwarder-cycle-claims.toml")))
    suite = build_suite(src, Settings(forwarder_moves=10 ** 6))
    moves = []
    for first in ("p", "d"):
        ms = sorted((m for m in suite.moves if m.id.startswith(first)), key=lambda m: m.id)
        want = n // 2 if first == "p" else n - n // 2
        if want > len(ms):
            raise SystemExit(f"--moves {n}: the suite has {len(ms)} moves from "
                             f"{'pick-up' if first == 'p' else 'drop'} points; use --suite full")
        moves += [ms[int(i)] for i in np.linspace(0, len(ms) - 1, want).round()]
    if only:
        moves = [m for m in suite.moves if m.id in only.split(",")]
    return suite, moves


def clearances(crane, traj, pend, obstacles):
    """(tip, load) smallest distance minus clearance [m] over the obstacles at 1 kHz; the load
    at the model's predicted swing."""
    if not obstacles:
        return float("nan"), float("nan")
    pred = predict_swing(crane, traj, pend, rate=1000.0)
    q = traj.sample(pred.t)[0]
    cyl = crane.tip(q)
    xyz = tip_to_xyz(cyl)
    off = pred.offset
    dz = -np.sqrt(np.maximum(pend.length ** 2 - np.sum(off ** 2, axis=1), 0.0))
    load = xyz + np.column_stack([off, dz])
    lcyl = xyz_to_tip(load)
    tip = min(float(ob.distance(xyz, cyl).min() - ob.clearance) for ob in obstacles)
    ld = min(float(ob.distance(load, lcyl).min() - ob.clearance) for ob in obstacles)
    return tip, ld


def plant_load_clearance(plant, rec, obstacles):
    """(smallest distance minus clearance of the plant's load centre of mass from the
    obstacles [m] on the plant's own grid, largest distance of the plant's tip frame from the
    model's forward kinematics [m]: the check that both use one frame)."""
    run = rec.meta.get("run")
    if not obstacles or getattr(run, "grapple_q", None) is None:
        return float("nan"), float("nan")
    from planner.simulation.dynamic.grapple import link_frames
    tree = plant.tree
    n = tree["crane_links"]
    _, links = link_frames(tree, np.hstack([run.q, run.grapple_q]))
    com = (links[-1] @ np.array([tree["grapple"].length, 0.0, 0.0, 1.0]))[:, :3]
    frame = float(np.max(np.linalg.norm(links[n][:, :3, 3] - plant.crane.fk(run.q), axis=1)))
    cyl = xyz_to_tip(com)
    return min(float(ob.distance(com, cyl).min() - ob.clearance) for ob in obstacles), frame


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--moves", type=int, default=12)
    ap.add_argument("--crane", default="s100f", help="the machine (s100f)")
    ap.add_argument("--tasks", default=None, metavar="FILE",
                    help="another suite file of the machine (benchmarks/random_suite.py's), "
                         "instead of the forwarder cycle")
    ap.add_argument("--suite", choices=("claims", "full"), default="claims",
                    help="the moves' suite: the forwarder cycle's claims subset (36 moves) or "
                         "the whole shipped cycle (200)")
    ap.add_argument("--length", type=float, default=1.5, help="link length [m]")
    ap.add_argument("--plant-length", type=float, default=None,
                    help="the plant's link length [m] when it differs from the one planned "
                         "with (robustness; default --length)")
    ap.add_argument("--plant-mass", type=float, default=None, metavar="SCALE",
                    help="the plant's load + tool mass as a multiple of the spec's, while the "
                         "planners assume the spec's (robustness; the payload_mass effect)")
    ap.add_argument("--plant-machine", type=int, default=None, metavar="SEED",
                    help="judge on an Exudyn machine whose dynamic parameters are drawn within "
                         "±30 %% of the spec's with this seed, with a pressure-dependent bulk "
                         "modulus, leakage and dead bands (bench_refine_robust.py's draw)")
    ap.add_argument("--calibrate", type=float, default=0.0, metavar="SECONDS",
                    help="with --plant-machine: first log SECONDS of excitation on that machine "
                         "(the grapple hanging, seed 001's sensor noise), calibrate the twin on "
                         "the log (planner.calibration.twin_fit) and refine the +ff / +ffs "
                         "commands on the calibrated twin (kept in --work)")
    ap.add_argument("--zeta", type=float, default=0.05, help="pin damping, share of critical")
    ap.add_argument("--settle", type=float, default=6.0, help="valves closed after arrival [s]")
    ap.add_argument("--methods", default="nlp,zv,zvd,nlp-sway",
                    help="registered methods, each with +OPTION=VALUE for its request options "
                         "(e.g. nlp-sway+swing_robust=0.1)")
    ap.add_argument("--refine", type=int, default=0, metavar="ITER",
                    help="replay the twin's refined feed-forward (planner.refine, ITER "
                         "L-BFGS-B iterations) instead of the nominal one")
    ap.add_argument("--ff-iterations", type=int, default=150,
                    help="L-BFGS-B iterations of the +ff / +ffs refinements")
    ap.add_argument("--swing-weight", type=float, default=10.0,
                    help="the refiner's swing weight for the +ffs methods (RefineOptions)")
    ap.add_argument("--only", default="", help="comma-separated move ids (instead of --moves)")
    ap.add_argument("--merge", nargs="+", type=Path, default=None, metavar="JSON",
                    help="write one table of these runs' rows (the same options, moves split "
                         "between processes with --only) under --tag, and stop")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--tag", default="sway", help="result file name stem")
    ap.add_argument("--work", type=Path, default=Path(os.environ.get("TMPDIR", "/tmp"))
                    / "crane-sway")
    args = ap.parse_args(argv)
    if args.merge:
        return merge(args.merge, args.out, args.tag)
    t_start = time.perf_counter()
    commit = _commit()        # the code this process imported, not a later checkout's
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    crane = Crane.from_id(args.crane)
    pend = Pendulum.of(crane, args.length, zeta=args.zeta)
    plant_length = args.plant_length or args.length    # the plant's link: off when asked
    effect = make("grapple_swing", length=plant_length, damping=round(pend.damping, 1))
    effects = [effect]
    if args.plant_mass is not None:   # the plant's load off from the planners' assumption
        effects.append(make("payload_mass", mass=round((args.plant_mass - 1.0)
                                                       * crane.spec.payload.total, 1)))
    if args.plant_machine is None:
        plant = make_plant("exudyn", crane, effects)
    else:   # a machine the planners and the twin were not told: its dynamics drawn ±30 %
        from bench_refine_robust import draw_machines, machine_plant
        drawn = draw_machines(crane.spec.dynamics, 1, args.plant_machine, 0.3)[-1]
        plant = machine_plant(crane, drawn, effects)
        args.machine_drawn = drawn
    ff_crane = crane                  # the twin the +ff / +ffs commands are refined on
    if args.calibrate:
        if args.plant_machine is None:
            ap.error("--calibrate needs --plant-machine (the machine whose log is fitted)")
        ff_crane, args.calibration = calibrated_crane(crane, plant, pend, args)
    suite, moves = sway_moves(args.work, args.moves, args.only, args.suite == "full",
                              args.tasks)
    obstacles = tuple(suite.obstacles)
    opts = {"grapple": args.length, "grapple_zeta": args.zeta}
    rows = []
    def save(done):
        """The result of the moves ``done`` so far (written after every move)."""
        res = dict(date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                   commit=commit,
                   machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                                load=list(os.getloadavg())),
                   args={k: (str(v) if isinstance(v, Path) else v)
                         for k, v in vars(args).items()},
                   effect=dict(effect.values), pendulum_hz=pend.omega / (2 * np.pi),
                   moves=[m.id for m in done], rows=rows,
                   wall_s=time.perf_counter() - t_start)
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out / f"{args.tag}.json", dumps(res))
        atomic_write_text(args.out / f"{args.tag}.md", "\n".join(markdown(res)) + "\n")
        return res

    for i_mv, mv in enumerate(moves):
        if i_mv:
            save(moves[:i_mv])
        planned = {}                          # one plan per (method, options) and move
        for name in args.methods.split(","):
            method, *extra = name.split("+")        # e.g. nlp-sway+swing_robust=0.1+ff
            ff = [e for e in extra if e in FF]       # +ff / +ffs: refined on the twin
            extra = {k: float(v) for k, _, v in (e.partition("=") for e in extra if e not in FF)}
            key = (method, tuple(sorted(extra.items())))
            req = PlanRequest(mv.start, mv.goal, obstacles=obstacles,
                              options={} if method == "nlp" else dict(opts, **extra))
            t0 = time.perf_counter()
            try:
                if key not in planned:
                    planned[key] = plan(crane, req, method)
                res = planned[key]
            except Exception as e:            # a method's failure is a row, not a crash
                rows.append(dict(method=name, move=mv.id, status="error", reason=str(e)))
                continue
            row = dict(method=name, move=mv.id, status=str(res.status),
                       wall_s=time.perf_counter() - t0,
                       solve_time_s=float(res.solve_time_s),
                       build_time_s=float(res.stats.get("build_time_s", 0.0)))
            if not res.ok:
                row["reason"] = res.reason
                rows.append(row)
                log(f"{mv.id:28s} {name:9s} {res.status}: {res.reason}")
                continue
            tr = res.trajectory
            pred = predict_swing(crane, tr, pend)
            tip_c, load_c = clearances(crane, tr, pend, obstacles)
            if args.refine or ff:   # the twin's feed-forward (planner.refine), not the nominal
                nom = commands(crane, tr, 50.0)
                w = args.swing_weight if "ffs" in ff else 0.0   # +ffs: with the swing term
                ref = refine_commands(ff_crane, tr, nom.t, nom.u, pendulum=pend,
                                      options=RefineOptions(iterations=args.refine
                                                            or args.ff_iterations,
                                                            swing_weight=w))
                k = int(round(args.settle * 50.0))
                t_u = np.concatenate([ref.t_u, ref.t_u[-1] + 0.02 * np.arange(1, k + 1)])
                u = np.vstack([ref.u, np.zeros((k, crane.n))])
                row.update(refine=str(ref.status), refine_s=ref.wall_s,
                           lengthened_s=ref.lengthened_s,
                           twin_swing_after_m=ref.predicted["refined"].get("swing_after_m"),
                           twin_swing_nominal_m=ref.predicted["nominal"].get("swing_after_m"),
                           twin_rest_offset_m=ref.predicted["refined"].get("rest_offset_m"))
            else:
                run_tr = with_settle(crane, tr, args.settle)
                t_u, u = run_tr.t, run_tr.u
            rec = plant.run(t_u, u, tr.q[0], t_end=float(t_u[-1]), rate=50.0)
            row.update(duration_s=float(tr.duration), model_residual_m=pred.residual_m,
                       model_peak_m=pred.peak_during_m, tip_clearance_m=tip_c,
                       load_clearance_m=load_c, plant=rec.status,
                       plant_reason=getattr(rec, "reason", "") or "",
                       plant_t_fail=getattr(rec, "t_fail", None))
            if rec.ok:
                lc, frame = plant_load_clearance(plant, rec, obstacles)
                row.update(plant_load_clearance_m=lc, plant_frame_m=frame)
                ts, sw = load_swing(plant, rec)
                r = np.linalg.norm(sw, axis=1)
                T = float(tr.duration)
                row.update(swing_during_m=float(r[ts <= T].max()),
                           swing_after_m=float(r[ts >= T].max()),
                           swing_left_m=float(r[ts >= T + args.settle - 1.0].max()),
                           tip_end_error_m=float(np.linalg.norm(
                               crane.fk(rec.q_true[-1]) - crane.fk(tr.q[-1]))))
            rows.append(row)
            log(f"{mv.id:28s} {name:9s} T={row['duration_s']:.2f} s  after "
                f"{row.get('swing_after_m', float('nan')) * 1e3:5.0f} mm  model "
                f"{pred.residual_m * 1e3:5.0f} mm  solve {row['solve_time_s']:.1f} s"
                + (f"  twin {row['twin_swing_nominal_m'] * 1e3:.0f} -> "
                   f"{row['twin_swing_after_m'] * 1e3:.0f} mm, refine {row['refine_s']:.0f} s"
                   if row.get("twin_swing_after_m") is not None else ""))
    res = save(moves)
    log(f"wrote {args.out / (args.tag + '.md')} ({res['wall_s'] / 60:.1f} min)")


def calibrated_crane(crane, plant, pend, args):
    """(The crane of the twin calibrated on ``args.calibrate`` s of excitation logged on
    ``plant``, its fit summary): the trials' excitation (seed 1) replayed open loop at 50 Hz
    with the load hanging on its link (the machine as it is), seed 001's sensor noise on the log
    (seed 2), every twin parameter fitted on the twin that carries the load on ``pend``
    (:class:`planner.calibration.twin_fit.TwinFit`, 12 iterations: the swinging load moves the
    slew's pressures by 20 σ, a bare twin fits it with wrong oil); the calibrated spec kept in
    ``--work`` and read back from there on the next run with the same machine and link."""
    import json

    from planner.calibration.trials import excitation
    from planner.calibration.twin_fit import TwinFit
    from planner.calibration.twin_spec import calibrated_twin_text
    from planner.library.twins import model_crane
    from planner.simulation.recording import Recording
    args.work.mkdir(parents=True, exist_ok=True)
    stem = args.work / (f"cal-{args.crane}-m{args.plant_machine}-{args.calibrate:g}s"
                        f"-L{pend.length:g}")
    path, info = stem.with_name(stem.name + ".toml"), stem.with_name(stem.name + ".json")
    if not path.exists():
        plan_x, ff = excitation(crane, duration=args.calibrate, seed=1)
        rec = plant.run(ff.t, ff.u, plan_x.q[0], t_end=float(ff.t[-1]), rate=50.0)
        if not rec.ok:
            sys.exit(f"calibrate: the excitation failed on the machine: {rec.reason}")
        log_ = Recording(rec.t, rec.u, rec.q_true, rec.p_a_true, rec.p_b_true).with_noise(
            crane, True, seed=2)
        res = TwinFit(crane, [log_], workers=2, grapple=pend).solve(12)
        atomic_write_text(info, dumps(dict(log_s=float(log_.t[-1] - log_.t[0]),
                                           fit=res.to_dict())))
        atomic_write_text(path, calibrated_twin_text(
            crane, res, f"on {args.calibrate:g} s of excitation on machine seed "
                        f"{args.plant_machine}"))
        log(f"calibrated on {args.calibrate:g} s: {res.rms_before} -> {res.rms_after}, "
            f"{res.runtime_s:.0f} s")
    return model_crane(path.read_text(encoding="utf-8"), str(path)), \
        dict(json.loads(info.read_text()), spec=str(path))


def merge(paths, out: Path, tag: str) -> None:
    """One result of several runs of the same options over different moves (``--only``,
    parallel processes): rows and moves joined, wall times summed, the first run's date,
    machine and options (``only`` the union)."""
    import json
    runs = [json.loads(Path(p).read_text()) for p in paths]
    res = dict(runs[0])
    rows, rerun = {}, []
    for i, run in enumerate(runs):      # a later run's row replaces an earlier one's
        for r in run["rows"]:
            key = (r["method"], r["move"])
            if key in rows:
                rerun.append(f"{r['method']} {r['move']} ({Path(paths[i]).stem}"
                             + (f", at {run['commit']}" if run.get("commit") else "") + ")")
            rows[key] = r
    res["rows"] = list(rows.values())
    res["moves"] = list(dict.fromkeys(m for run in runs for m in run["moves"]))
    res["rerun"] = rerun
    commits = {Path(p).stem: run.get("commit") for p, run in zip(paths, runs)}
    if len(set(commits.values())) > 1:
        res["commit"] = ", ".join(f"{k} at {v}" for k, v in commits.items())
    res["wall_s"] = sum(run["wall_s"] for run in runs)
    methods = dict.fromkeys(m for run in runs for m in run["args"]["methods"].split(","))
    res["args"] = dict(res["args"], only=",".join(res["moves"]), tag=tag,
                       processes=len(runs), methods=",".join(methods))
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / f"{tag}.json", dumps(res))
    atomic_write_text(out / f"{tag}.md", "\n".join(markdown(res)) + "\n")
    log(f"wrote {out / (tag + '.md')} ({len(res['rows'])} rows of {len(runs)} runs)")


def _commit() -> str | None:
    """The checkout's commit (short), the judge's code this run used; None outside git."""
    import subprocess
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, text=True,
                              capture_output=True, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


def _fitmsg(c) -> str:
    if not c:
        return "–"
    f = c["fit"]
    return (f"positions {f['rms_before']['positions']:.2f} → {f['rms_after']['positions']:.2f}, "
            f"pressures {f['rms_before']['pressures']:.2f} → {f['rms_after']['pressures']:.2f}, "
            f"{f['runtime_s']:.0f} s")


def _q(v, p):
    return float(np.percentile(v, p)) if len(v) else float("nan")


def _vals(rows, key):
    return [r[key] * 1e3 for r in rows if r.get(key) is not None and np.isfinite(r[key])]


def _min_mm(rows, key):
    v = _vals(rows, key)
    return f"{min(v):.0f}" if v else "–"


def _med_mm(rows, key):
    v = _vals(rows, key)
    return f"{np.median(v):.0f}" if v else "–"


def markdown(res) -> list:
    a, rows = res["args"], res["rows"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    L = ["# Sway-free moves on the Exudyn plant with the grapple (issue 29)", "",
         f"{res['date']}" + (f", commit {res['commit']}" if res.get("commit") else "")
         + f", {res['machine']['platform']}, {res['machine']['cpus']} CPUs, load "
         f"{res['machine']['load'][0]:.1f}. `python benchmarks/bench_sway.py"
         + ("" if a.get("only") else f" --moves {a['moves']}")
         + f" --length {a['length']:g} --zeta {a['zeta']:g} --settle "
         f"{a['settle']:g} --methods {a['methods']}"
         + (f" --refine {a['refine']}" if a.get("refine") else "")
         + (f" --plant-length {a['plant_length']:g}" if a.get("plant_length") else "")
         + (f" --plant-mass {a['plant_mass']:g}" if a.get("plant_mass") else "")
         + (f" --plant-machine {a['plant_machine']}" if a.get("plant_machine") is not None
            else "")
         + (f" --calibrate {a['calibrate']:g}" if a.get("calibrate") else "")
         + (f" --ff-iterations {a.get('ff_iterations', 150)} --swing-weight "
            f"{a.get('swing_weight', 10.0):g}"
            if "+ff" in a["methods"] else "")
         + (f" --crane {a['crane']}" if a.get("crane", "s100f") != "s100f" else "")
         + (f" --tasks {a['tasks']}" if a.get("tasks") else "")
         + (f" --suite {a['suite']}" if a.get("suite", "claims") != "claims" else "")
         + (f" --only {a['only']}" if a.get("only") else "")
         + f" --tag {a.get('tag', 'sway')}` ({res['wall_s'] / 60:.1f} min"
         + (f" of CPU-bound wall time summed over {a['processes']} parallel processes"
            if a.get("processes") else "") + f"). {a.get('crane', 's100f')}, "
         f"its {res['effect'].get('length', a['length'])} m grapple link "
         + (f"(the planners assume {a['length']:g} m) " if a.get("plant_length") else "")
         + (f"and {a['plant_mass']:g} × the spec's load + tool mass (the planners and the "
            "twin assume the spec's) " if a.get("plant_mass") else "")
         + (f"on an Exudyn machine drawn with seed {a['plant_machine']} (bulk modulus, hoses, "
            "spool and pump lags, friction within ±30 % of the spec's, leakage, dead bands, "
            "β(p); the values in the JSON's args.machine_drawn; the planners and the twin "
            "were given the spec's) " if a.get("plant_machine") is not None else "")
         + (f"— the `+ff`/`+ffs` commands refined on the twin calibrated from "
            f"{a['calibrate']:g} s of excitation logged on that machine (`--calibrate "
            f"{a['calibrate']:g}`; the fit's misfit in noise units "
            f"{_fitmsg(a.get('calibration'))}) " if a.get("calibrate") else "")
         + f"(planned: {res['pendulum_hz']:.2f} Hz, {a['zeta']:g} of critical damping at each pin), "
         + (f"{len(res['moves'])} moves of `{a['tasks']}` (no headboard); every plan's "
            if a.get("tasks") else
            f"{len(res['moves'])} forwarder moves over the headboard; every plan's ")
         + ("valve commands refined on the dynamic twin (planner.refine)" if a.get("refine")
            else "nominal 50 Hz feed-forward (`+ff`: its valve commands refined on the dynamic "
                 "twin, planner.refine, tip tracking and landing only; `+ffs`: with the swing "
                 f"term, swing_weight {a.get('swing_weight', 10.0):g}, on the twin carrying "
                 "the load on its link; "
                 f"{a.get('ff_iterations', 150)} L-BFGS-B iterations)")
         + " replayed open loop, then the valves closed. Swing: the horizontal "
         "distance of the load's centre of mass from under the tip (the plant's tree). "
         "Judge: the Exudyn plant; 'model': the planner's own pendulum along the plan.", "",
         "| method | ok / moves | duration s (median) | duration ratio to nlp (median) | "
         "residual swing mm (median / p90 / max) | swing left after "
         f"{a['settle']:g} s mm (median) | model residual mm (median / p90) | swing during "
         "mm (median) | tip clearance mm (min) | load clearance mm (min, model) | load "
         "clearance mm (min, plant) | twin swing after mm (median, +ff) | tip end error mm "
         "(median, plant) | solve s (median / p90) |",
         "| --- | ---: | ---: | ---: | --- | ---: | --- | ---: | ---: | ---: | ---: | ---: "
         "| ---: | --- |"]
    by = {m: {r["move"]: r for r in rows if r["method"] == m and "swing_after_m" in r}
          for m in methods}
    for m in methods:
        ok = list(by[m].values())
        n_all = sum(r["method"] == m for r in rows)
        if not ok:
            L.append(f"| {m} | 0 / {n_all} |" + " |" * 12)
            continue
        aft = [r["swing_after_m"] * 1e3 for r in ok]
        mod = [r["model_residual_m"] * 1e3 for r in ok]
        base = next((by[b] for b in ("nlp", "nlp+ff") if b in by), {})
        ratio = [r["duration_s"] / base[r["move"]]["duration_s"] for r in ok if r["move"] in base]
        sol = [r["solve_time_s"] for r in ok]
        L.append(f"| {m} | {len(ok)} / {n_all} | {np.median([r['duration_s'] for r in ok]):.2f} "
                 f"| {np.median(ratio) if ratio else float('nan'):.2f} | "
                 f"{np.median(aft):.0f} / {_q(aft, 90):.0f} / {max(aft):.0f} | "
                 f"{np.median([r['swing_left_m'] for r in ok]) * 1e3:.0f} | "
                 f"{np.median(mod):.0f} / {_q(mod, 90):.0f} | "
                 f"{np.median([r['swing_during_m'] for r in ok]) * 1e3:.0f} | "
                 f"{_min_mm(ok, 'tip_clearance_m')} | "
                 f"{_min_mm(ok, 'load_clearance_m')} | "
                 f"{_min_mm(ok, 'plant_load_clearance_m')} | "
                 f"{_med_mm(ok, 'twin_swing_after_m')} | "
                 f"{_med_mm(ok, 'tip_end_error_m')} | "
                 f"{np.median(sol):.2f} / {_q(sol, 90):.2f} |")
    if res.get("rerun"):
        L += ["", "Re-run, the later row kept: " + "; ".join(res["rerun"])]
    fails = [r for r in rows if "swing_after_m" not in r]
    if fails:
        L += ["", "Not replayed: " + "; ".join(f"{r['method']} {r['move']}: {r['status']} "
                                               f"({r.get('reason', r.get('plant', ''))})"
                                               for r in fails)]
    return L


if __name__ == "__main__":
    main()
