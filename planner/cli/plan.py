"""``plan CRANE --start --goal``: one move with a registered method (planner.methods), judged
by evaluate(); JSON keys per docs/design.md, "CONTRACT: command line" (all: docs/json-keys.md).

Limits in the result: ``max_limit_violation`` is the largest relative excess over the limit
kinds the method plans with, listed in ``checked_limits`` (e.g. the DP: position, velocity,
pump_flow); ``violations`` has every kind evaluate() measures (pressure, acceleration, jerk, …)
and ``max_violation_all_kinds`` the largest of them, so a clean plan of a velocity-only method
can still show a pressure excess there. ``lower_bound_s`` is the bound for the same limit kinds
(with acceleration limits when the method plans with them — then the pump-aware ramp bound of
:mod:`planner.bounds.ramps` — with jerk limits only when it plans with those too), and
``optimality_gap`` = duration / ``lower_bound_s`` − 1 of a minimum-time plan: how far from the
optimum the plan can at most be.

The command imports what a plan needs when it runs: the model, the one method named (the
registry loads only its module: an NLP plan loads no toppra, and through it no matplotlib),
the evaluator and the bounds; the figures (matplotlib), the animation and the database writer
(h5py) only when asked for."""
from __future__ import annotations

from typing import TYPE_CHECKING

import argparse
import math
import sys
import time

from planner.cli.common import (CLIError, add_animate_args, add_json_arg, emit, method_arg,
                                note_created, output_arg, point_arg)
from planner.cli.wording import cli_text

if TYPE_CHECKING:
    from planner.model import Crane

CONTROL_RATE_HZ = 50.0  # the valve commands of a plan stored with --out FILE.h5 (as a library)


def cmd_plan(args):
    """Plan one move with a registered method (planner.methods.registry); JSON keys per
    docs/design.md, "CONTRACT: command line". Failures come back as a status with a reason."""
    from planner.bounds import lower_bound
    from planner.geometry.obstacles import Wall
    from planner.methods import PlanRequest, UnsupportedRequest, get, plan
    from planner.model import Crane, UnreachableError
    from planner.trajectory import evaluate
    check_outputs(args)   # before a long solve
    crane = Crane.from_id(args.crane)
    method = args.method
    planner = get(method)
    out = dict(status="ok", crane=crane.spec.id, method=method, objective=args.objective,
               start=list(args.start), goal=list(args.goal))
    out["crane_id"] = out["crane"]  # the unified key beside the old one (docs/json-keys.md)
    args.path = args.path or planner.default_path
    out["path"] = args.path
    walls = tuple(Wall(*w) for w in (args.wall or []))
    try:
        req = PlanRequest(args.start, args.goal, objective=args.objective, path=args.path,
                          duration=args.duration, tip_speed=args.tip_speed, obstacles=walls,
                          options=dict(intervals=args.intervals, step=args.step,
                                       tele_step=args.tele_step, window=args.window,
                                       rate=args.rate, tele0=args.tele0,
                                       nlp_cache="build" if args.compile else None,
                                       grapple=args.grapple, grapple_zeta=args.grapple_zeta))
        t0 = time.perf_counter()
        res = plan(crane, req, method)
    except UnsupportedRequest as e:
        raise CLIError(str(e)) from None
    if "energy_winner" in res.stats:
        out["energy_winner"] = res.stats["energy_winner"]
    if "relief" in res.stats:
        out["relief"] = res.stats["relief"]
    # what the call paid: building the method's solver (0 when loaded or reused) and solving
    build = float(res.stats.get("build_time_s", 0.0))
    out["build_time_s"] = build
    out["solve_time_s"] = time.perf_counter() - t0 - build
    if "nlp_cache" in res.stats:
        out["nlp_cache"] = res.stats["nlp_cache"]
    if not res.ok:
        out.update(status=res.status, reason=cli_text(res.reason, "plan"))
        emit(args, out)
        print(f"{method}: {res.status}: {out['reason']}", file=sys.stderr)
        return 3
    ev = evaluate(crane, res.trajectory)
    checked = set(ev.checked)
    try:   # the bound of the limit kinds the method plans with
        lb = lower_bound(crane, args.start, args.goal, jerk="jerk" in checked,
                         ramps="acceleration" in checked and "pump_flow" in checked)
    except UnreachableError as e:
        raise CLIError(str(e)) from None
    bound = (lb.certified_s if "acceleration" in checked else
             max(lb.velocity_s, lb.pump_s if "pump_flow" in checked else 0.0))
    warnings = [cli_text(w, "plan") for w in res.warnings]
    if ev.duration < bound * (1 - 1e-6):   # possible only by exceeding a limit (tolerances)
        warnings.append(f"duration {ev.duration:.4f} s is below the lower bound {bound:.4f} s "
                        f"by {100 * (1 - ev.duration / bound):.3f} %: the plan exceeds a limit "
                        f"it plans with by {100 * ev.max_limit_violation:.3f} %")
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)
    if warnings:
        out["warnings"] = warnings
    out.update(duration_s=ev.duration, energy_J=ev.energy_J,
               peak_pump_flow_m3s=ev.peak_pump_flow, max_limit_violation=ev.max_limit_violation,
               violations=ev.violations, checked_limits=sorted(checked),
               max_violation_all_kinds=max(ev.violations.values(), default=0.0),
               lower_bound_s=bound, lower_bounds=lb.as_dict(),
               optimality_gap=ev.duration / bound - 1.0 if args.objective == "time" and bound > 0
               else None)
    swing = predicted_swing(args, crane, res.trajectory)
    if swing:
        out["swing"] = swing
    refined = _twin_feedforward(args, crane, res.trajectory, out)
    write_outputs(args, crane, res, ev, walls, out, refined)
    emit(args, out)
    if not args.json:
        loose = {k: v for k, v in ev.violations.items() if k not in checked and v > 1e-3}
        print(f"{crane.spec.id} {method} {args.objective}: {ev.duration:.3f} s, "
              f"{ev.energy_J / 1e3:.2f} kJ, peak pump flow {ev.peak_pump_flow * 6e4:.1f} L/min, "
              f"max violation {100 * ev.max_limit_violation:.3f} % of the limits it plans with "
              f"({', '.join(sorted(checked))}), lower bound {bound:.3f} s"
              + "".join(f"\n  {k}: {method} plans without a {k} limit; this move's {k} "
                        f"peaks at {1 + v:.4g} x the machine's {k} limit" for k, v in
                        loose.items()))
    return 0


OUT_SUFFIXES = (".csv", ".h5")


def predicted_swing(args, crane: Crane, traj) -> dict | None:
    """The model's swing of the load along the plan (planner.model.pendulum) when the grapple
    is known: ``--grapple LENGTH``, or the spec's ``[dynamics.grapple]``; None otherwise.
    With ``--wall``: ``load_clearance_m``, the swinging load's least distance to the walls on
    a 1 kHz resampling (planner.methods.shaping.load_clearance)."""
    from planner.model.pendulum import predict_swing
    pend = grapple_of_args(args, crane)
    if pend is None:
        return None
    pred = predict_swing(crane, traj, pend)
    out = dict(grapple_m=pend.length, pendulum_hz=pend.omega / (2 * math.pi),
               zeta=pend.zeta, residual_swing_m=pred.residual_m, swing_peak_m=pred.peak_during_m)
    if getattr(args, "wall", None):
        from planner.geometry.obstacles import Wall
        from planner.methods.shaping import load_clearance
        out["load_clearance_m"] = load_clearance(crane, traj, pend,
                                                 tuple(Wall(*w) for w in args.wall))
    return out


def add_grapple_args(p, length_help: str) -> None:
    """``--grapple LENGTH`` (with ``length_help``) and ``--grapple-zeta ZETA`` on parser
    ``p`` (read back by :func:`grapple_of_args`)."""
    p.add_argument("--grapple", type=float, metavar="LENGTH", help=length_help)
    p.add_argument("--grapple-zeta", type=float, metavar="ZETA",
                   help="the grapple pins' damping, a share of critical (default: the spec's, "
                        "else 0)")


def grapple_of_args(args, crane: Crane):
    """The grapple's pendulum (:class:`planner.model.pendulum.Pendulum`) of ``--grapple``
    / ``--grapple-zeta`` or the spec's ``[dynamics.grapple]``; None when neither."""
    from planner.model.pendulum import Pendulum
    dyn = crane.spec.dynamics
    if args.grapple is None and (dyn is None or dyn.grapple is None):
        return None
    try:
        return Pendulum.of(crane, args.grapple, zeta=args.grapple_zeta)
    except ValueError as e:
        raise CLIError(str(e).replace("pendulum `length`", "--grapple")
                       .replace("pendulum `zeta`", "--grapple-zeta")) from None


def check_outputs(args) -> None:
    """Refuse bad ``--out`` / ``--plot`` / ``--out-rate`` / ``--units-row`` before planning."""
    out = str(args.out or "")
    if out and not out.lower().endswith(OUT_SUFFIXES):
        raise CLIError(f"--out {out}: unknown file type; allowed: a trajectory CSV (.csv) or a "
                       "one-entry database (.h5)")
    if args.plot:
        from planner.plots import FigureFormatError, figure_format  # matplotlib: only to draw
        try:
            figure_format(args.plot)
        except FigureFormatError as e:
            raise CLIError(f"--plot {args.plot}: {str(e).split(': ', 1)[1]}") from None
    check_animation(args)
    rate = args.out_rate
    if rate is not None and not (math.isfinite(rate) and rate > 0):
        raise CLIError(f"--out-rate {rate}: must be a positive number of Hz")
    if (rate is not None or args.units_row) and not out:
        raise CLIError("--out-rate / --units-row shape the --out file: give --out FILE")
    if args.units_row and not out.lower().endswith(".csv"):
        raise CLIError(f"--units-row applies to a CSV --out, not {out}")


def check_animation(args) -> None:
    """Refuse a bad ``--animate`` suffix (or .mp4 without ffmpeg) and ``--fps`` before any
    work is done (planner.animate; matplotlib is imported only for .mp4's writer check)."""
    if not args.animate:
        return
    from planner.animate import MAX_FPS, AnimationError, animation_format, check_fps
    try:
        animation_format(args.animate)
    except AnimationError as e:
        raise CLIError(f"--animate {args.animate}: {str(e).split(': ', 1)[1]}") from None
    try:
        check_fps(args.fps)
    except AnimationError:
        raise CLIError(f"--fps {args.fps:g}: allowed 0 < fps <= {MAX_FPS:g}") from None


def _twin_feedforward(args, crane: Crane, traj, out: dict):
    """``--feedforward twin``: the plan's 50 Hz commands refined on the dynamic twin
    (:func:`planner.refine.refine_commands`); its provenance and predicted landing go into
    ``out["feedforward"]``. None for the nominal feed-forward."""
    if args.feedforward != "twin":
        out["feedforward"] = dict(commands="nominal")
        return None
    if args.out_rate is not None and abs(args.out_rate - CONTROL_RATE_HZ) > 1e-9:
        raise CLIError(f"--out-rate {args.out_rate:g}: refined commands are computed on the "
                       f"{CONTROL_RATE_HZ:g} Hz control grid; leave --out-rate out or give "
                       f"{CONTROL_RATE_HZ:g}")
    if crane.spec.dynamics is None:
        raise CLIError(f"--feedforward twin: crane '{crane.spec.id}' has no [dynamics] section "
                       "(the twin needs bulk modulus, hose volumes, …)")
    from planner.feedforward import commands, fills_oil
    from planner.refine import SWING_WEIGHT, RefineOptions, for_objective, refine_commands
    from planner.simulation.twin_plant import twin_of
    ff = commands(crane, traj, CONTROL_RATE_HZ, oil=fills_oil(crane))   # the machine's
    pend = grapple_of_args(args, crane)
    if pend is not None and not crane.spec.effects:   # the load at rest on its link too
        from planner.model.twin import Twin
        r = refine_commands(crane, traj, ff.t, ff.u, twin=Twin(crane, grapple=pend),
                            options=for_objective(RefineOptions(swing_weight=SWING_WEIGHT),
                                                  args.objective))
    else:
        if pend is not None:   # said, not dropped silently
            print(f"crane-planner: note: --feedforward twin: crane '{crane.spec.id}' carries "
                  "[[effects]], which the twin with the grapple link does not take; the "
                  "commands are refined for the tip alone (no swing cost)", file=sys.stderr)
        r = refine_commands(crane, traj, ff.t, ff.u, twin=twin_of(crane),
                            options=for_objective(RefineOptions(), args.objective))
    out["feedforward"] = dict(commands="refined" if r.status == "improved" else "nominal",
                              **r.info())
    return r if r.status == "improved" else None


def write_outputs(args, crane: Crane, res, ev, walls, out: dict, refined=None) -> None:
    """``--out`` (trajectory CSV, fixed-rate controller CSV, or a one-entry database) and
    ``--plot`` (figure; format from the suffix). Adds the written names to ``out``. With
    ``refined`` (a :class:`~planner.refine.Refinement`): a CSV carries the refined commands on
    their grid, a database keeps them beside the nominal ones."""
    from planner.io import missing_dirs
    traj = res.trajectory
    path = str(args.out or "")
    note_created(d for p in (args.out, args.plot, args.animate) if p
                 for d in missing_dirs(p))
    if path.lower().endswith(".csv") and refined is not None:
        from planner.feedforward import on_command_grid
        from planner.library.export import write_trajectory_csv  # h5py: only when needed
        write_trajectory_csv(path, crane, on_command_grid(traj, refined.t_u, refined.u),
                             units_row=args.units_row)
    elif path.lower().endswith(".csv"):
        if args.out_rate is None and not args.units_row:
            traj.to_csv(path)  # the method's own samples (CONTRACT: trajectory CSV)
        else:
            from planner.library.export import write_trajectory_csv  # h5py: only when needed
            write_trajectory_csv(path, crane, traj, rate=args.out_rate, units_row=args.units_row)
    elif path:
        from planner.feedforward import commands, fills_oil
        from planner.library.export import write_single_entry  # h5py: only when needed
        from planner.trajectory import evaluate
        # stored like a library entry: the plan on the control grid (50 Hz, plus its own
        # nodes: the quintic through the rows reproduces it) with its valve commands; at
        # --out-rate the fixed-rate rows; a piecewise-linear plan (DP, laws) at its own nodes
        if args.out_rate is not None:
            stored = commands(crane, traj, args.out_rate, oil=fills_oil(crane)).attach(traj)
        elif traj.interpolation == "quintic":
            stored = commands(crane, traj, CONTROL_RATE_HZ, oil=fills_oil(crane)).attach(
                traj, knots=True)
        else:
            stored = traj
        entry = f"plan:{args.objective}"
        write_single_entry(path, crane, stored, entry_id=entry, start=args.start,
                           goal=args.goal, objective=args.objective, method=args.method,
                           evaluation=ev if stored is traj else evaluate(crane, stored),
                           attrs=dict(solve_time_s=out["solve_time_s"], path=out["path"],
                                      source="crane-planner plan"))
        if refined is not None:
            from planner.library.refined import write_refined
            from planner.library.store import LibraryStore
            with LibraryStore.open(path, "a") as db:
                write_refined(db, entry, refined.t_u, refined.u, refined.info())
        out["entry"] = entry
    if args.animate:
        from planner.animate import animate  # matplotlib: only to draw
        out["animation"] = animate(crane, traj, args.animate, obstacles=walls, fps=args.fps,
                                   title=f"{crane.spec.id} {args.method} ({args.objective}): "
                                         f"{ev.duration:.3f} s")
    if args.plot:
        from planner.plots import trajectory_figure  # matplotlib: only to draw
        trajectory_figure(crane, ev, args.plot,
                          f"{crane.spec.id} {args.method} ({args.objective}): "
                          f"{ev.duration:.3f} s", walls=walls)


def wall_arg(text):
    """argparse type of ``--wall``: r,z_top,z_bottom[,clearance] [m] -> list of floats."""
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) not in (3, 4) or not all(math.isfinite(x) for x in v) or v[1] <= v[2] or \
            (len(v) == 4 and v[3] <= 0):
        raise argparse.ArgumentTypeError(f"expected r,z_top,z_bottom[,clearance]: finite "
                                         f"numbers with z_top > z_bottom and clearance > 0, "
                                         f"got {text!r}")
    return v


def add_parsers(sub) -> None:
    """``plan``."""
    what = ("plan one move (NLP, DP, DP + TOPP-RA, Ruckig, a local law or a plug-in's "
            "method)")
    p = sub.add_parser("plan", help=what, description=what[0].upper() + what[1:] + ".")
    p.add_argument("crane")
    p.add_argument("--start", type=point_arg, required=True, metavar="r,z,slew")
    p.add_argument("--goal", type=point_arg, required=True, metavar="r,z,slew")
    p.add_argument("--method", type=method_arg, default="dp",
                   help="a registered method: nlp (CasADi/IPOPT; --path free|line), dp (Bellman "
                        "along the line), topp (the DP path retimed with acceleration and pump "
                        "limits), ruckig (jerk-limited joint move, free path), law:NAME "
                        "(least_norm, max_velocity, max_lift, jla, q_optimal, p_optimal), or a "
                        "plug-in's")
    p.add_argument("--objective", choices=("time", "energy"), default="time")
    p.add_argument("--path", choices=("line", "free"), default=None,
                   help="tip path (default: free for nlp and ruckig, line for the others)")
    p.add_argument("--tip-speed", type=float,
                   help="commanded tip speed [m/s] (laws, default 1; dp --objective energy)")
    p.add_argument("--duration", type=float,
                   help="move duration [s]: dp --objective energy (fixed), topp (fixed), "
                        "nlp --objective energy (maximum); refused where a method ignores it")
    p.add_argument("--step", type=float, default=0.01, help="DP stage spacing [m] (0.01)")
    p.add_argument("--tele-step", type=float, default=0.01, help="DP telescope grid [m] (0.01)")
    p.add_argument("--window", type=int, default=5, help="DP telescope steps per stage (5)")
    p.add_argument("--rate", type=float, default=100.0, help="law control rate [Hz] (100)")
    p.add_argument("--intervals", type=int, default=40, help="NLP intervals N (40)")
    p.add_argument("--compile", action="store_true",
                   help="NLP: compile the built solver into the per-user cache if it is not "
                        "there (once per machine and formulation: 16 s of CPU for s100f at "
                        "N = 40, more wall time on a loaded machine); later calls load it in "
                        "milliseconds (planner.methods.nlp.cache)")
    p.add_argument("--wall", type=wall_arg, action="append", metavar="r,z_top,z_bottom[,clear]",
                   help="NLP obstacle: a vertical wall (e.g. the bunk headboard) at distance r "
                        "from the slew axis, kept clear by `clear` m (0.3); repeatable")
    p.add_argument("--tele0", type=float, help="law start telescope [m] (default: law's choice)")
    p.add_argument("--feedforward", choices=("nominal", "twin"), default="nominal",
                   help="valve commands: nominal (the quasi-static inverse, default) or twin "
                        "(refined on the dynamic twin so that the machine lands, and with the "
                        "grapple known the load at rest under the tip: --out keeps them, the "
                        "JSON reports the predicted landing and swing)")
    add_grapple_args(p, "the grapple hangs on a link of LENGTH m (default: the spec's "
                        "[dynamics.grapple]): zv, zvd and nlp-sway plan with it, and the JSON "
                        "gets the model's predicted swing (swing.residual_swing_m)")
    p.add_argument("--out", metavar="FILE.csv|FILE.h5", type=output_arg,
                   help="write the trajectory CSV, or a one-entry database (.h5; read it back "
                        "as FILE.h5 or FILE.h5#plan:OBJECTIVE)")
    p.add_argument("--out-rate", type=float, metavar="HZ",
                   help="--out at a fixed control rate: resampled rows t0 + k/HZ with the valve "
                        "commands u_* and the hydraulic channels")
    p.add_argument("--units-row", action="store_true",
                   help="CSV --out: a second line '# s,rad,...' with every column's unit")
    p.add_argument("--plot", metavar="FILE.png|.pdf|.svg", type=output_arg,
                   help="draw joints, rates, tip path, pump (format from the suffix)")
    add_animate_args(p, "the walls")
    add_json_arg(p)
    p.epilog = ("JSON: max_limit_violation covers the limit kinds the method plans with "
                "(checked_limits); violations and max_violation_all_kinds cover every kind "
                "evaluated, pressures included.")
    p.set_defaults(func=cmd_plan)
