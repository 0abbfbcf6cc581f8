"""``crane-planner`` command line (also ``python -m planner``).

Every sub-command has ``--help``; ``--json FILE`` (``-`` or no value: stdout) writes a
machine-readable result. Plain numbers are SI; angles may be written ``30deg``.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time

from planner.model.spec import SpecError
from planner.units import parse_angle


class CLIError(Exception):
    """A user error: printed as one line, exit status 2."""


def parse_point(text: str) -> tuple[float, float, float]:
    """'r,z,slew' -> floats (m, m, rad); slew may be '30deg'; slew defaults to 0."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) not in (2, 3):
        raise argparse.ArgumentTypeError(f"expected r,z[,slew], got {text!r}")
    try:
        r, z = float(parts[0]), float(parts[1])
        s = parse_angle(parts[2]) if len(parts) == 3 else 0.0
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers in r,z[,slew], got {text!r}") from None
    if not all(math.isfinite(v) for v in (r, z, s)):
        raise argparse.ArgumentTypeError(f"non-finite value in {text!r}")
    return r, z, s


def _json_arg(p):
    p.add_argument("--json", nargs="?", const="-", metavar="FILE",
                   help="write a JSON result to FILE ('-' or no value: stdout)")


def _emit(args, obj):
    from planner.io import write_json
    if getattr(args, "json", None):
        write_json(args.json, obj)


# ----------------------------------------------------------------------------- commands
def cmd_problems_list(args):
    from problems import crane_ids, load_crane
    rows = []
    for cid in crane_ids():
        s = load_crane(cid)
        rows.append(dict(id=s.id, name=s.name, joints=s.joint_names, source=s.source,
                         redundancy=s.redundancy, pump=s.pump.kind))
    _emit(args, rows)
    if not args.json:
        w = max(len(r["id"]) for r in rows)
        for r in rows:
            print(f"{r['id']:<{w}}  {', '.join(r['joints']):<28}  {r['name']}")


def cmd_problems_show(args):
    from problems import load_crane
    spec = load_crane(args.crane)
    d = dataclasses.asdict(spec)
    d.pop("raw", None)
    d.pop("text", None)
    _emit(args, d)
    if args.plot:
        from planner.model import Crane
        from planner.plots import workspace_figure
        info = workspace_figure(Crane(spec), args.plot)
        print(f"workspace figure written to {args.plot} (r_max {info['r_max']:.2f} m)",
              file=sys.stderr if args.json == "-" else sys.stdout)
    if not args.json:
        print(f"{spec.name}  [{spec.id}]\n  source: {spec.source}\n  file:   {spec.path}")
        for j in spec.joints:
            lo, hi = j.limits.q
            unit, f = ("°", math.degrees) if j.revolute else (" m", float)
            print(f"  {j.name:<6} {j.type:<9} q {f(lo):8.2f}{unit} .. {f(hi):8.2f}{unit}   "
                  f"qd [{j.limits.qd[0]:+.2f}, {j.limits.qd[1]:+.2f}]  "
                  f"actuator {j.actuator.kind} ({j.actuator.acting})")
        p = spec.pump
        print(f"  pump {p.kind}: {p.max_flow * 6e4:.0f} L/min, margin {p.margin / 1e5:.0f} bar, "
              f"η {p.efficiency:.2f};  payload {spec.payload.mass:.0f} kg + tool "
              f"{spec.payload.tool_mass:.0f} kg")


def cmd_bound(args):
    from planner.bounds import lower_bound
    from planner.model import Crane
    crane = Crane.from_id(args.crane)
    lb = lower_bound(crane, args.start, args.goal)
    _emit(args, dict(status="ok", crane=crane.spec.id, start=args.start, goal=args.goal,
                     **lb.as_dict()))
    if not args.json:
        print(f"lower bounds for {crane.spec.id} {args.start} -> {args.goal}:\n"
              f"  velocity {lb.velocity_s:.3f} s, rest-to-rest {lb.rest_to_rest_s:.3f} s, "
              f"pump {lb.pump_s:.3f} s, combined {lb.combined_s:.3f} s; "
              f"energy ≥ {lb.energy_J / 1e3:.2f} kJ")


def cmd_plan(args):
    """Plan one move with a registered method (planner.methods.registry); JSON keys per
    DESIGN.md. Failures come back as a status with a reason."""
    from planner.bounds import lower_bound
    from planner.geometry.obstacles import Wall
    from planner.methods import PlanRequest, UnsupportedRequest, get, plan
    from planner.model import Crane, UnreachableError
    from planner.trajectory import evaluate
    crane = Crane.from_id(args.crane)
    method = args.method
    planner = get(method)
    out = dict(status="ok", crane=crane.spec.id, method=method, objective=args.objective,
               start=list(args.start), goal=list(args.goal))
    args.path = args.path or planner.default_path
    out["path"] = args.path
    walls = tuple(Wall(*w) for w in (args.wall or []))
    try:
        req = PlanRequest(args.start, args.goal, objective=args.objective, path=args.path,
                          duration=args.duration, tip_speed=args.tip_speed, obstacles=walls,
                          options=dict(intervals=args.intervals, step=args.step,
                                       tele_step=args.tele_step, window=args.window,
                                       rate=args.rate, tele0=args.tele0))
        t0 = time.perf_counter()
        res = plan(crane, req, method)
    except UnsupportedRequest as e:
        raise CLIError(str(e)) from None
    if "energy_winner" in res.stats:
        out["energy_winner"] = res.stats["energy_winner"]
    out["solve_time_s"] = time.perf_counter() - t0  # the whole call, set-up included
    try:
        lb = lower_bound(crane, args.start, args.goal)
    except UnreachableError as e:
        lb = None
        if res.ok:
            raise CLIError(str(e)) from None
    if not res.ok:
        out.update(status=res.status, reason=res.reason)
        _emit(args, out)
        print(f"{method}: {res.status}: {res.reason}", file=sys.stderr)
        return 3
    ev = evaluate(crane, res.trajectory)
    checked = set(ev.checked)
    for w in res.warnings:
        print(f"warning: {w}", file=sys.stderr)
    if res.warnings:
        out["warnings"] = list(res.warnings)
    if lb is not None:
        bound = (lb.combined_s if "acceleration" in checked else
                 max(lb.velocity_s, lb.pump_s if "pump_flow" in checked else 0.0))
    out.update(duration_s=ev.duration, energy_J=ev.energy_J,
               peak_pump_flow_m3s=ev.peak_pump_flow, max_limit_violation=ev.max_limit_violation,
               violations=ev.violations, checked_limits=sorted(checked),
               lower_bound_s=bound if lb is not None else None,
               lower_bounds=lb.as_dict() if lb is not None else None)
    if args.out:
        if not str(args.out).endswith(".csv"):
            raise CLIError(f"--out {args.out}: write a trajectory CSV (.csv)")
        res.trajectory.to_csv(args.out)
    if args.plot:
        from planner.plots import trajectory_figure
        trajectory_figure(crane, ev, args.plot,
                          f"{crane.spec.id} {method} ({args.objective}): {ev.duration:.3f} s",
                          walls=walls)
    _emit(args, out)
    if not args.json:
        loose = {k: v for k, v in ev.violations.items() if k not in checked and v > 1e-3}
        print(f"{crane.spec.id} {method} {args.objective}: {ev.duration:.3f} s, "
              f"{ev.energy_J / 1e3:.2f} kJ, peak pump flow {ev.peak_pump_flow * 6e4:.1f} L/min, "
              f"max violation of the {len(checked)} limit kinds it respects "
              f"{100 * ev.max_limit_violation:.3f} %"
              + (f", lower bound {bound:.3f} s" if lb is not None else "")
              + ("".join(f"\n  not respected by {method}: {k} exceeded by {100 * v:.1f} %"
                         for k, v in loose.items())))
    return 0


def _wall(text):
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) not in (3, 4) or v[1] <= v[2] or (len(v) == 4 and v[3] <= 0):
        raise argparse.ArgumentTypeError(f"expected r,z_top,z_bottom[,clearance] with "
                                         f"z_top > z_bottom and clearance > 0, got {text!r}")
    return v


def _read_trajectory(crane, ref: str):
    """FILE.csv, or FILE.h5#ID (an entry of a library database)."""
    from planner.trajectory import Trajectory
    path, _, entry = ref.partition("#")
    if path.endswith(".h5"):
        from planner.library.store import LibraryStore
        with LibraryStore.open(path, "r") as db:
            ids = db.ids()
            if not entry:
                if len(ids) != 1:
                    raise CLIError(f"{path} holds {len(ids)} entries: name one as {path}#ID")
                entry = ids[0]
            return db.trajectory(entry)
    try:
        return Trajectory.from_csv(path, joint_names=crane.names)
    except OSError as e:
        raise CLIError(f"cannot read trajectory {path}: {e.strerror}") from None


def _noise(text):
    """--noise [angle=0.1deg,length=0.002,pressure=0.17e6] -> True or a dict of levels."""
    if text is None:
        return None
    if text == "default":
        return True
    out = {}
    for item in filter(None, (x.strip() for x in text.split(","))):
        k, eq, v = item.partition("=")
        if not eq or k.strip() not in ("angle", "length", "pressure"):
            raise CLIError(f"--noise: expected angle=…, length=…, pressure=… (standard "
                           f"deviations; angle may be written 0.1deg), got {item!r}")
        try:
            out[k.strip()] = parse_angle(v.strip()) if v.strip().endswith("deg") else float(v)
        except ValueError:
            raise CLIError(f"--noise: {k.strip()} = {v!r} is not a number") from None
        if not (out[k.strip()] >= 0 and math.isfinite(out[k.strip()])):
            raise CLIError(f"--noise: {k.strip()} must be >= 0, got {v}")
    return out


def cmd_simulate(args):
    """Replay a trajectory's valve commands open loop and write the measured-data CSV."""
    from planner.simulation.effects import parse_effect
    from planner.model import Crane
    from planner.simulation.plant import simulate_to_csv
    from planner.simulation.replay import Plant
    crane = Crane.from_id(args.crane)
    effects = []
    for text in args.effect or []:
        try:
            effects.append(parse_effect(text, crane))
        except ValueError as e:
            raise CLIError(f"--effect {text!r}: {e}") from None
    traj = _read_trajectory(crane, args.trajectory)
    plant = Plant(flow_gain_scale=args.flow_gain, pump_flow_scale=args.pump_flow)
    summary = simulate_to_csv(crane, traj, args.out, plant=plant, rate=args.rate,
                              noise=_noise(args.noise), seed=args.seed, effects=effects)
    _emit(args, summary)
    if not args.json:
        print(f"measured data written to {args.out}: {summary['samples']} samples, "
              f"max tip drift {1e3 * summary['max_tip_error_m']:.1f} mm")
    return 0


def cmd_effects_list(args):
    from planner.simulation.effects import catalogue
    cat = catalogue()
    _emit(args, cat)
    if not args.json:
        for e in cat:
            ps = ", ".join(f"{k} {v if isinstance(v, str) else v}" for k, v in
                           e["parameters"].items())
            print(f"{e['name']:18s} {e['description']}\n{'':18s} parameters: {ps}")
    return 0


def cmd_discrepancy(args):
    """Measured vs simulated -> named effect -> calibrated model (planner.calibration.discrepancy)."""
    from planner.calibration.compensate import closed_loop
    from planner.calibration.discrepancy import Discrepancy, calibrated_spec_text
    from planner.calibration.report import write_report
    from planner.io import atomic_write_text
    from planner.model import Crane
    from planner.simulation.recording import Recording
    crane = Crane.from_id(args.crane)
    plan = _read_trajectory(crane, args.trajectory) if args.trajectory else None
    rec = Recording.from_csv(args.measured, crane, plan)
    if args.effects:
        names = [x.strip() for x in args.effects.split(",") if x.strip()]
    else:
        names = None
    res = Discrepancy(crane, candidates=names, threshold=args.threshold).fit(
        rec, progress=not (args.json == "-"))
    closed = None
    if plan is not None and res.effects:
        closed = closed_loop(crane, plan, res.effects)
    # everything computed: now write (nothing is written when anything above failed)
    if args.save_model:
        text = calibrated_spec_text(crane, res.effects, source=f"on {args.measured}")
        from planner.model.spec import parse_spec  # the written model must load
        import tomllib
        parse_spec(tomllib.loads(text), args.save_model, text)
        atomic_write_text(args.save_model, text)
    if args.report:
        write_report(res, args.report, crane=crane, measured=args.measured, closed=closed)
    js = res.to_json()
    if closed is not None:
        js["closed_loop"] = closed
    _emit(args, js)
    if not args.json:
        print(res.message)
        print(f"{'channel':12s} {'noise':>10s} {'RMS before':>11s} {'RMS after':>10s}")
        for c in res.rms_before:
            print(f"{c:12s} {res.noise[c]:10.4g} {res.rms_before[c]:11.4g} "
                  f"{res.rms_after[c]:10.4g}")
        if closed is not None:
            print(f"open-loop tip error (predicted): {1e3 * closed['before']['rms_m']:.1f} mm "
                  f"RMS with the nominal feed-forward -> {1e3 * closed['after']['rms_m']:.1f} "
                  "mm re-planned on the calibrated model")
    return 0


def cmd_library_build(args):
    from planner.library.build import build
    objectives = tuple(o.strip() for o in args.objectives.split(",") if o.strip())
    summary = build(args.crane, args.tasks, args.out, objectives=objectives,
                    workers=args.workers, scheduler=args.scheduler, limit=args.limit,
                    N=args.intervals, robustness=not args.no_robustness,
                    progress=not (args.json == "-"), method=args.method)
    _emit(args, summary)
    if not args.json:
        print(f"{summary['library']}: planned {summary['planned']} entries "
              f"({summary['statuses'] or 'none'}), {summary['skipped_existing']} already there, "
              f"{summary['seconds']:.1f} s")
    return 0


def cmd_library_info(args):
    from planner.library.store import LibraryStore
    with LibraryStore.open(args.library, "r") as db:
        info = db.info()
    _emit(args, info)
    if not args.json:
        d = info.get("duration_s") or {}
        print(f"{args.library}: {info['entries']} entries ({info['ok']} ok), failures "
              f"{info['failures'] or 'none'}; duration mean {d.get('mean', float('nan')):.3f} s")
    return 0


def cmd_library_query(args):
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
    if args.q_from:
        traj, join_s = _join_from(spec_toml, args.q_from, traj)
        result["join_duration_s"] = join_s
    if args.out:
        traj.to_csv(args.out)
    _emit(args, result)
    if not args.json:
        print(f"nearest entry {eid} ({row['objective']}, {row['method']}): "
              f"{dist:.3f} m from the request (start + goal), {row['duration_s']:.3f} s"
              + (f"; joined from the current state in {result['join_duration_s']:.3f} s"
                 if args.q_from else ""))
    return 0


def _join_from(spec_toml, text, traj):
    """Prepend a Ruckig rest-to-rest join from the joint state ``text`` (comma list; angles
    may be '30deg') to the entry's start. Returns (joined trajectory, join duration [s])."""
    import tomllib

    import numpy as np

    from planner.methods.ruckig import rest_to_rest
    from planner.model import Crane
    from planner.model.spec import parse_spec
    from planner.trajectory import Trajectory
    crane = Crane(parse_spec(tomllib.loads(spec_toml), "<library spec>"))
    try:
        q = np.array([parse_angle(v) for v in text.split(",")], float)
    except ValueError:
        raise CLIError(f"--from {text!r}: expected {crane.n} joint values "
                       f"({', '.join(crane.names)})") from None
    if q.shape != (crane.n,):
        raise CLIError(f"--from needs {crane.n} joint values ({', '.join(crane.names)}), "
                       f"got {q.size}")
    j = rest_to_rest(crane, q, traj.q[0])
    if not j.ok:
        raise CLIError(f"--from: {j.reason}")
    a, b = j.trajectory, traj
    t = np.concatenate([a.t, a.t[-1] + b.t[1:]])
    def cat(x, y):
        return np.vstack([x, y[1:]])
    joined = Trajectory(t, cat(a.q, b.q), cat(a.qd, b.qd), cat(a.qdd, b.qdd),
                        joint_names=b.joint_names, method=f"ruckig+{b.method}",
                        objective=b.objective)
    # valve feed-forward for the whole joined move at the control rate (50 Hz)
    from planner.feedforward import commands
    return commands(crane, joined, 50.0).attach(joined), float(a.duration)


def cmd_library_export(args):
    from planner.library.store import export
    files = export(args.library, args.out, args.format)
    _emit(args, dict(status="ok", files=[str(f) for f in files]))
    if not args.json:
        print(f"{len(files)} file(s) written to {args.out}")
    return 0


def _method(text):
    from planner.methods import available
    names = available()
    if text in names:
        return text
    raise argparse.ArgumentTypeError(f"unknown method {text!r}; available: {', '.join(names)}")


def cmd_bench(args):
    """DP vs NLP vs local laws on the seeds' suites (planner/bench.py): bench.md, bench.json
    and figures in --out."""
    from planner.bench.run import parse_suites, run_bench
    try:
        suites = parse_suites(args.suite)
    except ValueError as e:
        raise CLIError(str(e)) from None
    if args.repeats is not None and args.repeats < 1:
        raise CLIError(f"--repeats must be >= 1, got {args.repeats}")
    res = run_bench(suites, args.out, repeats=args.repeats, quick=args.quick)
    _emit(args, res)
    if args.json != "-":
        print(f"bench written to {args.out}/ (bench.md, bench.json, figures): "
              + "; ".join(f"{n} {s['wall_time_s']:.0f} s" for n, s in res["suites"].items())
              + f"; total {res['wall_time_s']:.0f} s")
    return 0

def cmd_demo(args):
    """The main job (planner/demo.py): machines, seed 000, a small library, the short
    benchmark and a calibration, into ``--out``."""
    from planner.demo import run_demo
    if args.library_moves < 1 or args.workers < 1:
        raise CLIError("--library-moves and --workers must be >= 1")
    summary = run_demo(args.out, library_moves=args.library_moves, workers=args.workers,
                       progress=not (args.json == "-"))
    _emit(args, summary)
    if not args.json:
        print(f"demo written to {args.out}/ (summary.md and figures)")
    return 0


# ----------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crane-planner",
                                 description="Trajectory planning for hydraulic knuckle-boom "
                                             "cranes (SI units; angles may be written 30deg).")
    sub = ap.add_subparsers(dest="command", required=True)
    pr = sub.add_parser("problems", help="machine specifications shipped with the package")
    psub = pr.add_subparsers(dest="what", required=True)
    p = psub.add_parser("list", help="list the machines")
    _json_arg(p)
    p.set_defaults(func=cmd_problems_list)
    p = psub.add_parser("show", help="show one machine (id or path to a TOML file)")
    p.add_argument("crane")
    _json_arg(p)
    p.add_argument("--plot", metavar="FILE.png", help="draw the workspace figure")
    p.set_defaults(func=cmd_problems_show)
    p = sub.add_parser("bound", help="analytic minimum-time lower bounds for a move")
    p.add_argument("crane")
    p.add_argument("--start", type=parse_point, required=True, metavar="r,z,slew")
    p.add_argument("--goal", type=parse_point, required=True, metavar="r,z,slew")
    _json_arg(p)
    p.set_defaults(func=cmd_bound)
    p = sub.add_parser("plan", help="plan one move (DP, DP + TOPP-RA, Ruckig, or a local law)")
    p.add_argument("crane")
    p.add_argument("--start", type=parse_point, required=True, metavar="r,z,slew")
    p.add_argument("--goal", type=parse_point, required=True, metavar="r,z,slew")
    p.add_argument("--method", type=_method, default="dp",
                   help="a registered method: nlp (CasADi/IPOPT; --path free|line), dp (Bellman "
                        "along the line), topp (the DP path retimed with acceleration and pump "
                        "limits), ruckig (jerk-limited joint move, free path), law:NAME "
                        "(least_norm, max_velocity, max_lift, jla, q_optimal, p_optimal), or a "
                        "plug-in's")
    p.add_argument("--objective", choices=("time", "energy"), default="time")
    p.add_argument("--path", choices=("line", "free"), default=None,
                   help="tip path (default: free for nlp and ruckig, line for the others)")
    p.add_argument("--tip-speed", type=float, help="commanded tip speed [m/s] (laws; DP energy)")
    p.add_argument("--duration", type=float, help="move duration [s] (DP energy)")
    p.add_argument("--step", type=float, default=0.01, help="DP stage spacing [m] (0.01)")
    p.add_argument("--tele-step", type=float, default=0.01, help="DP telescope grid [m] (0.01)")
    p.add_argument("--window", type=int, default=5, help="DP telescope steps per stage (5)")
    p.add_argument("--rate", type=float, default=100.0, help="law control rate [Hz] (100)")
    p.add_argument("--intervals", type=int, default=40, help="NLP intervals N (40)")
    p.add_argument("--wall", type=_wall, action="append", metavar="r,z_top,z_bottom[,clear]",
                   help="NLP obstacle: a vertical wall (e.g. the bunk headboard) at distance r "
                        "from the slew axis, kept clear by `clear` m (0.3); repeatable")
    p.add_argument("--tele0", type=float, help="law start telescope [m] (default: law's choice)")
    p.add_argument("--out", metavar="FILE.csv", help="write the trajectory CSV")
    p.add_argument("--plot", metavar="FILE.png", help="draw joints, rates, tip path, pump")
    _json_arg(p)
    p.set_defaults(func=cmd_plan)
    lib = sub.add_parser("library", help="trajectory databases (HDF5): info, query, export")
    lsub = lib.add_subparsers(dest="what", required=True)
    p = lsub.add_parser("build", help="plan every move of a task suite into LIB.h5 "
                                      "(resumes an interrupted build)")
    p.add_argument("crane")
    p.add_argument("--tasks", required=True, help="task suite id or path (forwarder-cycle)")
    p.add_argument("--out", required=True, metavar="LIB.h5")
    p.add_argument("--objectives", default="time", help="comma list of time, energy (time)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (1)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler (tcp://host:8786), or local:N for a LocalCluster")
    p.add_argument("--limit", type=int, help="only the first N moves of the suite")
    p.add_argument("--intervals", type=int, default=40, help="NLP intervals N (40)")
    p.add_argument("--method", type=_method, default="nlp",
                   help="registered planning method of every entry (nlp); see plan --help")
    p.add_argument("--no-robustness", action="store_true", help="skip the replay scores")
    _json_arg(p)
    p.set_defaults(func=cmd_library_build)
    p = lsub.add_parser("info", help="entries, failures, time/energy statistics")
    p.add_argument("library", metavar="LIB.h5")
    _json_arg(p)
    p.set_defaults(func=cmd_library_info)
    p = lsub.add_parser("query", help="the entry nearest to a requested move")
    p.add_argument("library", metavar="LIB.h5")
    p.add_argument("--start", type=parse_point, required=True, metavar="r,z,slew")
    p.add_argument("--goal", type=parse_point, required=True, metavar="r,z,slew")
    p.add_argument("--objective", help="only entries with this objective")
    p.add_argument("--from", dest="q_from", metavar="q1,q2,...",
                   help="current joint configuration: prepend a Ruckig rest-to-rest join to "
                        "the entry's start (angles may be written 30deg)")
    p.add_argument("--out", metavar="FILE.csv", help="write the entry's trajectory CSV")
    _json_arg(p)
    p.set_defaults(func=cmd_library_query)
    p = lsub.add_parser("export", help="CSV (one file per entry + index), MAT or JSON")
    p.add_argument("library", metavar="LIB.h5")
    p.add_argument("--format", choices=("csv", "mat", "json"), required=True)
    p.add_argument("--out", required=True, metavar="DIR")
    _json_arg(p)
    p.set_defaults(func=cmd_library_export)
    p = sub.add_parser("simulate", help="replay a trajectory open loop; write measured data")
    p.add_argument("crane")
    p.add_argument("--trajectory", required=True, metavar="FILE.csv|FILE.h5#ID")
    p.add_argument("--out", required=True, metavar="MEASURED.csv")
    p.add_argument("--noise", nargs="?", const="default", metavar="angle=…,pressure=…",
                   help="sensor noise: seed 001's levels (0.1°, 2 mm, 0.17 MPa standard "
                        "deviations) or the given ones (e.g. angle=0.05deg,pressure=5e4)")
    p.add_argument("--effect", action="append", metavar="NAME:key=value,…",
                   help="hidden effect in the plant (repeatable), e.g. "
                        "coulomb_friction:joint=boom,force=3000 (see 'effects list')")
    p.add_argument("--seed", type=int, default=0, help="noise seed (0)")
    p.add_argument("--rate", type=float, default=50.0, help="command rate [Hz] (50)")
    p.add_argument("--flow-gain", type=float, default=1.0, help="plant valve gain scale (1.0)")
    p.add_argument("--pump-flow", type=float, default=1.0, help="plant pump flow scale (1.0)")
    _json_arg(p)
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("effects", help="the catalogue of model effects")
    esub = p.add_subparsers(dest="what", required=True)
    p = esub.add_parser("list", help="name, description, parameters with plausible ranges")
    _json_arg(p)
    p.set_defaults(func=cmd_effects_list)
    p = sub.add_parser("discrepancy", help="measured vs simulated: name the missing effect, "
                                           "calibrate, show the gap shrink")
    p.add_argument("crane", help="machine id or a TOML spec (e.g. a calibrated one)")
    p.add_argument("--measured", required=True, metavar="MEASURED.csv")
    p.add_argument("--trajectory", metavar="FILE.csv|FILE.h5#ID",
                   help="the commanded trajectory (re-planned on the calibrated model)")
    p.add_argument("--effects", metavar="NAME,…", help="only these catalogue effects")
    p.add_argument("--threshold", type=float, default=30.0,
                   help="least held-out score to name an effect (30)")
    p.add_argument("--report", metavar="DIR", help="markdown report, result.json, figures")
    p.add_argument("--save-model", metavar="FILE.toml",
                   help="the calibrated machine spec (spec + [[effects]])")
    _json_arg(p)
    p.set_defaults(func=cmd_discrepancy)
    p = sub.add_parser("bench", help="DP vs NLP vs local laws on the seeds' suites "
                                     "(markdown + JSON + figures)")
    p.add_argument("--suite", action="append", metavar="NAME[,NAME]",
                   help="suite to run, repeatable or a comma list: seed000-abc, seed002-hvd, "
                        "seed003-paths, forwarder-cycle (default: all)")
    p.add_argument("--out", default="benchmarks/results/bench",
                   help="output folder (default benchmarks/results/bench)")
    p.add_argument("--repeats", type=int,
                   help="timed solves of every method faster than 2 s (3; --quick: 1)")
    p.add_argument("--quick", action="store_true",
                   help="small settings for tests and the demo: fewer moves, coarser grids")
    _json_arg(p)
    p.set_defaults(func=cmd_bench)
    p = sub.add_parser("demo", help="the main job: machines, seed 000, a small library, a short "
                                    "benchmark, a calibration")
    p.add_argument("--out", default="demo-output", help="output folder (default demo-output)")
    p.add_argument("--library-moves", type=int, default=6,
                   help="moves of the forwarder cycle in the demo library (6)")
    p.add_argument("--workers", type=int, default=2, help="library build processes (2)")
    _json_arg(p)
    p.set_defaults(func=cmd_demo)
    return ap


def main(argv=None) -> int:
    from planner.model import UnreachableError
    args = build_parser().parse_args(argv)
    try:
        rc = args.func(args)
    except (SpecError, UnreachableError, CLIError, ValueError, OSError) as e:
        print(f"crane-planner: error: {e}", file=sys.stderr)
        return 2
    except KeyError as e:
        print(f"crane-planner: error: {e.args[0]}", file=sys.stderr)
        return 2
    return rc or 0


if __name__ == "__main__":
    raise SystemExit(main())
