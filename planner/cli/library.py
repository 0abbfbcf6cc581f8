"""``library build | refine | info | show | query | export``: trajectory databases (HDF5).

The store and the export need h5py, the build the planners (CasADi, scipy) and the process
pool or Dask, a query with ``--from`` Ruckig; they are imported inside the commands so that
``crane-planner --help`` and the other commands do not load them."""
from __future__ import annotations

from typing import TYPE_CHECKING

import os
import shlex
import sys

from planner.cli.common import (CLIError, add_animate_args, add_json_arg, emit, entry_of,
                                method_arg, note_created, output_arg, point_arg, split_ref)
from planner.units import parse_angle

if TYPE_CHECKING:
    import numpy as np

    from planner.model import Crane


def build(crane_id: str, suite: str, out, **kw) -> dict:
    """:func:`planner.library.build.build` (imported when a build runs; the name the command
    calls, so a test can stand in for the builder)."""
    from planner.library.build import build as run
    return run(crane_id, suite, out, **kw)


def cpu_count() -> int:
    """The CPUs this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def checked_suite(args) -> int:
    """The moves ``library build`` will plan (the suite's, after ``--limit``), after refusing
    a suite without moves (an empty pick-up/drop grid) and one declared for another machine
    (``[suite] crane``) unless ``--force`` is given (then a warning)."""
    from planner.model import Crane
    from planner.tasks.suites import load_task_file
    tf = load_task_file(args.tasks)
    if not tf.moves:
        raise CLIError(f"--tasks {args.tasks}: suite '{tf.id}' ({tf.path}) has no moves (an "
                       "empty pick-up/drop grid and no [[moves]]); allowed: a suite with at "
                       "least one move")
    machine = Crane.from_id(args.crane).spec.id
    if tf.crane and tf.crane != machine:
        what = (f"--tasks {args.tasks}: suite '{tf.id}' is declared for crane '{tf.crane}' "
                f"([suite] crane in {tf.path}), not '{machine}'")
        if not args.force:
            raise CLIError(f"{what}; allowed: a suite of {machine}, or --force to plan its "
                           f"moves for {machine} anyway")
        print(f"crane-planner: warning: {what}; planned for {machine} (--force)",
              file=sys.stderr)
    return len(tf.moves) if args.limit is None else max(1, min(args.limit, len(tf.moves)))


def capped_workers(workers: int, moves: int) -> int:
    """``--workers``: never more processes than moves to plan, nor than CPUs; a note on
    stderr when the request is lowered."""
    cap = min(moves, cpu_count())
    if workers <= cap:
        return workers
    print(f"crane-planner: note: --workers {workers}: {cap} started (at most one per move, "
          f"{moves}, and one per CPU, {cpu_count()})", file=sys.stderr)
    return cap


def cmd_library_build(args):
    from planner.io import missing_dirs
    from planner.library.workers import Interrupted, WorkerLost
    objectives = tuple(o.strip() for o in args.objectives.split(",") if o.strip())
    moves = checked_suite(args)
    if args.scheduler is None:
        args.workers = capped_workers(args.workers, moves)
    grapple = build_grapple(args, objectives)
    created = missing_dirs(args.out)
    try:
        summary = build(args.crane, args.tasks, args.out, objectives=objectives,
                        workers=args.workers, scheduler=args.scheduler, limit=args.limit,
                        N=args.intervals, robustness=not args.no_robustness,
                        progress=not (args.json == "-"), method=args.method,
                        compile=args.compile, grapple=grapple, grapple_zeta=args.grapple_zeta)
    except Interrupted as e:  # Ctrl-C / SIGTERM: one line, the shell's 128 + signal code
        s = e.summary
        if s:
            emit(args, s)
            left = s["planned"] - s["written"]
            if s["planned"] == 0 and s["written"] == 0:   # while the workers were starting
                print(f"crane-planner: interrupted ({s['signal']}) while starting the workers, "
                      f"before any entry; nothing written to {s['library']}", file=sys.stderr)
            else:
                print(f"crane-planner: interrupted ({s['signal']}): {s['written']} entries "
                      f"written to {s['library']}, {left} left; rerun the same command to "
                      "resume", file=sys.stderr)
        else:
            print(f"crane-planner: interrupted ({e}) before the build started", file=sys.stderr)
        note_created(d for d in created if d.exists())
        return e.exit_code
    except WorkerLost as e:   # killed by the OOM killer, a process manager: one line, exit 3
        s = e.summary
        emit(args, s)
        print(f"crane-planner: error: a worker of the build {e.how} while planning "
              f"{e.task or 'a move'}; {s['written']} entries written to {s['library']} this run "
              f"are kept (every earlier one too): rerun `{rerun_command(args)}` to resume"
              + (" (with fewer --workers if memory ran out)" if args.workers > 1 else ""),
              file=sys.stderr)
        return 3
    except KeyboardInterrupt:  # before the build installed its own handling
        print("crane-planner: interrupted (SIGINT) before the build started", file=sys.stderr)
        return 130
    note_created(created)
    # the unified keys beside the old ones (docs/json-keys.md)
    summary.update(crane_id=summary["crane"], solve_time_s=summary["seconds"])
    if args.feedforward == "twin":   # every entry's commands refined on the twin, in the build
        from planner.cli.refine import build_refine
        code = build_refine(args, summary)
        if code:
            return code
    emit(args, summary)
    if not args.json:
        print(f"{summary['library']}: planned {summary['planned']} entries "
              f"({summary['statuses'] or 'none'}), {summary['skipped_existing']} already there, "
              f"{summary['seconds']:.1f} s")
        if "refine" in summary:
            r = summary["refine"]
            print(f"  refined on the twin: {r['refined']} entries ({r['statuses'] or 'none'}), "
                  f"{r['skipped_existing']} already refined, {r['seconds']:.1f} s")
        ws = summary.get("workers") or []
        if ws and summary.get("planned"):
            setup = "/".join(f"{w['setup_s']:.1f}" for w in ws)
            first = summary.get("first_entry_s")
            print(f"  {len(ws)} worker(s) set up in {setup} s"
                  + (f"; first entry {first:.1f} s later" if first is not None else ""))
            for w in ws:
                if w.get("error"):
                    print(f"  warning: worker {w.get('worker', w['pid'])} set-up failed "
                          f"({w['error']}); its tasks build what they need", file=sys.stderr)
    return 0


def build_grapple(args, objectives) -> float | bool | None:
    """``library build``'s grapple (:func:`planner.library.build.build`'s ``grapple``): the
    link of ``--grapple LENGTH``, else the spec's ``[dynamics.grapple]`` (True) unless
    ``--no-grapple``, else None; and the method when ``--method`` is not given: ``nlp-sway``
    (sway-free entries) with a grapple, ``nlp`` without. Bad input: CLIError, one line."""
    import math

    from planner.methods import get
    from planner.model import Crane
    spec = Crane.from_id(args.crane).spec
    if args.grapple is not None:
        if args.no_grapple:
            raise CLIError(f"--grapple {args.grapple:g} and --no-grapple: allowed one of them")
        if not (math.isfinite(args.grapple) and 0 < args.grapple <= 20):
            raise CLIError(f"--grapple {args.grapple:g}: allowed a link length in (0, 20] m")
    if args.grapple_zeta is not None and not (math.isfinite(args.grapple_zeta)
                                              and 0 <= args.grapple_zeta <= 1):
        raise CLIError(f"--grapple-zeta {args.grapple_zeta:g}: allowed a share of critical "
                       "damping in [0, 1]")
    has = spec.dynamics is not None and spec.dynamics.grapple is not None
    grapple = (args.grapple if args.grapple is not None
               else True if has and not args.no_grapple else None)
    if grapple is None and args.grapple_zeta is not None:
        raise CLIError(f"--grapple-zeta {args.grapple_zeta:g}: needs a grapple link "
                       f"(--grapple LENGTH; {spec.id} has no [dynamics.grapple]"
                       + (", and --no-grapple was given)" if args.no_grapple else ")"))
    if args.method is None:
        args.method = "nlp-sway" if grapple is not None else "nlp"
        if grapple is not None and "energy" in objectives:
            raise CLIError(f"--objectives {args.objectives}: sway-free entries (nlp-sway, the "
                           "default with a grapple) are minimum-time only; allowed: --objectives "
                           "time, --method nlp (sway-blind, the swing predicted per entry) or "
                           "--no-grapple")
    elif grapple is None and getattr(get(args.method), "grapple", False):
        raise CLIError(f"--method {args.method} plans with the grapple: {spec.id} has no "
                       "[dynamics.grapple]" + (" and --no-grapple was given" if args.no_grapple
                                               else "") + "; allowed: --grapple LENGTH [m]")
    return grapple


def rerun_command(args) -> str:
    """The ``library build`` command line that resumes this build."""
    words = ["crane-planner", "library", "build", args.crane, "--tasks", args.tasks, "--out",
             args.out, "--objectives", args.objectives, "--workers", str(args.workers),
             "--intervals", str(args.intervals), "--method", args.method]
    words += ["--limit", str(args.limit)] if args.limit is not None else []
    words += ["--scheduler", args.scheduler] if args.scheduler else []
    words += ["--no-robustness"] if args.no_robustness else []
    words += ["--grapple", f"{args.grapple:g}"] if args.grapple is not None else []
    words += ["--grapple-zeta", f"{args.grapple_zeta:g}"] if args.grapple_zeta is not None else []
    words += ["--no-grapple"] if args.no_grapple else []
    return shlex.join(words)


def cmd_library_info(args):
    from planner.library.store import LibraryStore
    with LibraryStore.open(args.library, "r") as db:
        info = db.info()
    emit(args, info)
    if not args.json:
        mean = (info.get("duration_s") or {}).get("mean")
        print(f"{args.library}: {info['entries']} entries ({info['ok']} ok), failures "
              f"{info['failures'] or 'none'}; duration mean "
              + (f"{mean:.3f} s" if mean is not None else "- (no ok entry)"))
    return 0


def cmd_library_query(args):
    from planner.io import missing_dirs
    from planner.library.query import JoinError, far_warning, join_from, library_crane
    from planner.library.store import LibraryStore
    with LibraryStore.open(args.library, "r") as db:
        try:
            eid, dist = db.nearest(args.start, args.goal, objective=args.objective)
        except LookupError as e:
            raise CLIError(str(e)) from None
        row = next(r for r in db.index_rows() if r["id"] == eid)
        traj = db.trajectory(eid)
        spec_toml = db.spec_toml
    result = dict(status="ok", id=eid, distance_m=dist, entry=row)
    warning = far_warning(dist, args.start, args.goal)
    if warning:
        result["warning"] = warning
        print(f"warning: {warning}", file=sys.stderr)
    if args.q_from:
        crane = library_crane(spec_toml)
        try:
            traj, result["join_duration_s"] = join_from(crane, joint_state(crane, args.q_from),
                                                        traj)
        except JoinError as e:
            raise CLIError(f"--from: {e}") from None
    if args.out:
        created = missing_dirs(args.out)
        traj.to_csv(args.out)
        note_created(created)
    emit(args, result)
    if not args.json:
        print(f"nearest entry {eid} ({row['objective']}, {row['method']}): "
              f"{dist:.3f} m from the request (start + goal), {row['duration_s']:.3f} s"
              + (f"; joined from the current state in {result['join_duration_s']:.3f} s"
                 if args.q_from else ""))
    return 0


def joint_state(crane: Crane, text: str) -> np.ndarray:
    """``--from q1,q2,...`` -> one value per joint of ``crane`` (SI; angles may be '30deg')."""
    import numpy as np
    try:
        q = np.array([parse_angle(v) for v in text.split(",")], float)
    except ValueError:
        raise CLIError(f"--from {text!r}: expected {crane.n} joint values "
                       f"({', '.join(crane.names)})") from None
    if q.shape != (crane.n,):
        raise CLIError(f"--from needs {crane.n} joint values ({', '.join(crane.names)}), "
                       f"got {q.size}")
    bad = [f"{n} = {v}" for n, v in zip(crane.names, q) if not np.isfinite(v)]
    if bad:
        raise CLIError(f"--from {text!r}: joint values must be finite numbers ({', '.join(bad)})")
    return q


def entry_summary(db, eid: str) -> dict:
    """``library show``: the entry's index row, its attributes (provenance, solver statistics,
    evaluation summary) and the shape of its trajectory."""
    row = next(r for r in db.index_rows() if r["id"] == eid)
    attrs = db.entry_attrs(eid)
    out = dict(row, reason=attrs.get("reason", ""), library=str(db.path),
               crane_id=db.crane_id, attrs=attrs)
    if db.has_trajectory(eid):
        tr = db.trajectory(eid)
        out.update(samples=len(tr.t), t0_s=float(tr.t[0]), t_end_s=float(tr.t[-1]),
                   joint_names=list(tr.joint_names), has_commands=tr.u is not None)
    return out


def entry_obstacles(attrs: dict) -> tuple:
    """The obstacles of the task suite an entry was built from (its ``suite`` attribute);
    none when it names no suite or the suite is not found."""
    suite = attrs.get("suite")
    if not suite:
        return ()
    from planner.tasks.suites import load_suite
    try:
        return tuple(load_suite(suite)[0]["obstacles"])
    except (OSError, ValueError, KeyError):
        return ()


def cmd_library_show(args):
    import numpy as np

    from planner.cli.plan import check_animation
    from planner.io import missing_dirs
    from planner.library.store import LibraryStore
    check_animation(args)
    path, eid = split_ref(args.entry)
    with LibraryStore.open(path, "r") as db:
        eid = entry_of(db, path, eid)
        summary = entry_summary(db, eid)
        traj = db.trajectory(eid) if args.animate else None
        spec_toml = db.spec_toml
    if args.animate:
        from planner.animate import animate  # matplotlib: only to draw
        from planner.library.query import library_crane
        created = missing_dirs(args.animate)
        summary["animation"] = animate(
            library_crane(spec_toml), traj, args.animate,
            obstacles=entry_obstacles(summary["attrs"]), fps=args.fps,
            title=f"{summary['crane_id']} {eid} ({summary['method']}, {summary['objective']}):"
                  f" {summary['duration_s']:.3f} s")
        note_created(created)
    emit(args, summary)
    if not args.json:
        s = summary
        print(f"{eid}: {s['status']}" + (f" ({s['reason']})" if s["reason"] else "")
              + f", {s['method']} / {s['objective']}, crane {s['crane_id']}")
        print(f"  start r,z,slew {', '.join(f'{v:.3f}' for v in s['start'])}  goal "
              f"{', '.join(f'{v:.3f}' for v in s['goal'])}")
        def num(v, scale=1.0, fmt=".3f"):
            return "-" if v is None or not np.isfinite(v) else format(v * scale, fmt)
        print(f"  duration {num(s['duration_s'])} s, energy {num(s['energy_J'], 1e-3, '.2f')} "
              f"kJ, robustness {num(s['robustness'], fmt='.4f')} m")
        a = s["attrs"]
        if a.get("swing_residual_m") is not None:
            print(f"  grapple {a['grapple_m']:g} m ({a['pendulum_hz']:.2f} Hz): the model's "
                  f"residual swing {num(a['swing_residual_m'], 1e3, '.0f')} mm, peak "
                  f"{num(a['swing_peak_m'], 1e3, '.0f')} mm during the move"
                  + (f"; load clearance {num(a['load_clearance_m'], 1e3, '.0f')} mm, tip "
                     f"{num(a.get('clearance_m'), 1e3, '.0f')} mm (1 kHz)"
                     if a.get("load_clearance_m") is not None else ""))
        if "samples" in s:
            print(f"  {s['samples']} samples, t {s['t0_s']:.3f} .. {s['t_end_s']:.3f} s, joints "
                  f"{', '.join(s['joint_names'])}"
                  + ("" if s["has_commands"] else " (no valve commands stored)"))
        if "animation" in s:
            a = s["animation"]
            print(f"  animation written to {a['file']}: {a['frames']} frames at {a['fps']:g} fps"
                  + (f", played {a['speedup']:.1f}x" if a["speedup"] > 1 else ""))
    return 0


def cmd_library_export(args):
    from planner.io import check_output_dir
    from planner.library.export import export
    if args.format == "rosbag2" and args.units_row:
        raise CLIError("--units-row applies to the csv format, not 'rosbag2'")
    created = check_output_dir(args.out)
    if args.format == "rosbag2":
        from planner.library.rosbag import export_rosbag2  # rosbags (the ros extra): only here
        files = export_rosbag2(args.library, args.out, rate=args.out_rate)
    else:
        files = export(args.library, args.out, args.format, rate=args.out_rate,
                       units_row=args.units_row, commands=args.commands)
    note_created(created)
    emit(args, dict(status="ok", files=[str(f) for f in files]))
    if not args.json:
        print(f"{len(files)} file(s) written to {args.out}")
    return 0


def add_parsers(sub) -> None:
    """``library`` (build, info, show, query, export)."""
    lib = sub.add_parser("library", help="trajectory databases (HDF5): info, query, export")
    lsub = lib.add_subparsers(dest="what", required=True)
    p = lsub.add_parser("build", help="plan every move of a task suite into LIB.h5 "
                                      "(resumes an interrupted build)")
    p.add_argument("crane")
    p.add_argument("--tasks", required=True, help="task suite id or path (forwarder-cycle)")
    p.add_argument("--out", required=True, metavar="LIB.h5", type=output_arg)
    p.add_argument("--objectives", default="time", help="comma list of time, energy (time)")
    p.add_argument("--workers", type=int, default=1,
                   help="local worker processes (1); at most one per move and one per CPU")
    p.add_argument("--force", action="store_true",
                   help="plan a suite declared for another machine ([suite] crane) anyway")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler (tcp://host:8786), or local:N for a LocalCluster")
    p.add_argument("--limit", type=int, help="only the first N moves of the suite")
    p.add_argument("--intervals", type=int, default=40, help="NLP intervals N (40)")
    p.add_argument("--method", type=method_arg, default=None,
                   help="registered planning method of every entry (nlp; nlp-sway with a "
                        "grapple); see plan --help")
    p.add_argument("--no-robustness", action="store_true", help="skip the replay scores")
    p.add_argument("--grapple", type=float, metavar="LENGTH",
                   help="the load hangs on a grapple link of LENGTH m (default: the spec's "
                        "[dynamics.grapple]): entries planned sway-free (nlp-sway) unless "
                        "--method says otherwise, each with the model's predicted swing and "
                        "the load's clearance (library show)")
    p.add_argument("--grapple-zeta", type=float, metavar="ZETA",
                   help="the grapple pins' damping, a share of critical (default: the spec's, "
                        "or none)")
    p.add_argument("--no-grapple", action="store_true",
                   help="ignore the spec's [dynamics.grapple]: the load a point at the tip")
    p.add_argument("--feedforward", choices=("nominal", "twin"), default="nominal",
                   help="twin: refine every entry's commands on the dynamic twin after planning "
                        "(as `library refine` does; resumable the same way)")
    p.add_argument("--compile", action="store_true",
                   help="build the method's solvers once in this process and store them compiled "
                        "in the per-user cache before the workers start (they load them instead "
                        "of building their own); see plan --compile")
    add_json_arg(p)
    p.set_defaults(func=cmd_library_build)
    from planner.cli.refine import add_refine_parser
    add_refine_parser(lsub)
    p = lsub.add_parser("info", help="entries, failures, time/energy statistics")
    p.add_argument("library", metavar="LIB.h5")
    add_json_arg(p)
    p.set_defaults(func=cmd_library_info)
    p = lsub.add_parser("show", help="one entry's summary; --animate draws its move")
    p.add_argument("entry", metavar="LIB.h5#ID",
                   help="the entry (the ID may be left out when the library holds one)")
    add_animate_args(p, "the suite's obstacles")
    add_json_arg(p)
    p.set_defaults(func=cmd_library_show)
    p = lsub.add_parser("query", help="the entry nearest to a requested move")
    p.add_argument("library", metavar="LIB.h5")
    p.add_argument("--start", type=point_arg, required=True, metavar="r,z,slew")
    p.add_argument("--goal", type=point_arg, required=True, metavar="r,z,slew")
    p.add_argument("--objective", help="only entries with this objective")
    p.add_argument("--from", dest="q_from", metavar="q1,q2,...",
                   help="current joint configuration: prepend a Ruckig rest-to-rest join to "
                        "the entry's start (angles may be written 30deg)")
    p.add_argument("--out", metavar="FILE.csv", type=output_arg,
                   help="write the entry's trajectory CSV")
    add_json_arg(p)
    p.set_defaults(func=cmd_library_query)
    p = lsub.add_parser("export", help="CSV (one file per entry + index), MAT, JSON, ROS "
                                       "JointTrajectory documents (JSON / YAML) or ROS 2 bags")
    p.add_argument("library", metavar="LIB.h5")
    p.add_argument("--format", choices=("csv", "mat", "json", "ros", "ros-yaml", "rosbag2"),
                   required=True,
                   help="ros / ros-yaml: one trajectory_msgs/JointTrajectory-shaped file per "
                        "entry; rosbag2: one ROS 2 bag (MCAP) per entry with the trajectory, "
                        "joint states, valve commands and pressures (docs/rosbag.md; needs "
                        "the ros extra)")
    p.add_argument("--rate", "--out-rate", dest="out_rate", type=float, metavar="HZ",
                   help="csv, ros, rosbag2: resample every entry at a fixed control rate, with the valve "
                        "commands u_* at that rate")
    p.add_argument("--commands", choices=("auto", "nominal", "refined"), default="auto",
                   help="csv / ros: each entry's valve commands — refined (`library refine`) "
                        "where present (auto, default), or nominal / refined")
    p.add_argument("--units-row", action="store_true",
                   help="csv: a second line '# s,rad,...' with every column's unit")
    p.add_argument("--out", required=True, metavar="DIR")
    add_json_arg(p)
    p.set_defaults(func=cmd_library_export)
