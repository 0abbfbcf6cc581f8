"""``problems list`` · ``problems show ID`` · ``problems urdf ID`` · ``bound CRANE --start
--goal``: the shipped machines, their URDF, and the analytic lower bounds of a move.

The model (CasADi), the bounds and the figures (matplotlib) are imported by the commands that
use them."""
from __future__ import annotations

import dataclasses
import math
import sys

from planner.cli.common import CLIError, add_json_arg, emit, output_arg, point_arg


def plot_path(path) -> None:
    """Refuse a ``--plot`` path whose suffix is no figure format (before any work)."""
    from planner.plots import FigureFormatError, figure_format
    try:
        figure_format(path)
    except FigureFormatError as e:
        raise CLIError(f"--plot {path}: {str(e).split(': ', 1)[1]}") from None


def cmd_problems_list(args):
    from planner.model import load_crane
    from planner.problems import crane_ids
    rows = []
    for cid in crane_ids():
        s = load_crane(cid)
        rows.append(dict(id=s.id, name=s.name, joints=s.joint_names, source=s.source,
                         redundancy=s.redundancy, pump=s.pump.kind))
    emit(args, rows)
    if not args.json:
        w = max(len(r["id"]) for r in rows)
        for r in rows:
            print(f"{r['id']:<{w}}  {', '.join(r['joints']):<28}  {r['name']}")


def cmd_problems_show(args):
    from planner.model import Crane, load_crane
    if args.plot:
        plot_path(args.plot)
    spec = load_crane(args.crane)
    d = dataclasses.asdict(spec)
    d.pop("raw", None)
    d.pop("text", None)
    emit(args, d)
    if args.plot:
        from planner.plots import workspace_extent, workspace_figure  # matplotlib: only to draw
        crane = Crane(spec)
        workspace_figure(crane, args.plot)
        info = workspace_extent(crane)
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


def cmd_problems_urdf(args):
    from planner.io import atomic_write_text
    from planner.model import Crane
    from planner.model.urdf import urdf_xml
    crane = Crane.from_id(args.crane)
    text = urdf_xml(crane)
    if args.out:
        atomic_write_text(args.out, text)
    else:
        sys.stdout.write(text)
    emit(args, dict(status="ok", crane=crane.spec.id, crane_id=crane.spec.id,
                    file=str(args.out) if args.out else None,
                    joints=list(crane.names), links=["base_link", *crane.names, "tip"]))
    if args.out and not args.json:
        print(f"URDF of {crane.spec.id} written to {args.out}")
    return 0


def cmd_bound(args):
    from planner.bounds import lower_bound
    from planner.model import Crane
    crane = Crane.from_id(args.crane)
    lb = lower_bound(crane, args.start, args.goal, ramps=True)
    emit(args, dict(status="ok", crane=crane.spec.id, crane_id=crane.spec.id, start=args.start,
                    goal=args.goal, **lb.as_dict()))
    if not args.json:
        print(f"lower bounds for {crane.spec.id} {args.start} -> {args.goal}:\n"
              f"  velocity {lb.velocity_s:.3f} s, rest-to-rest {lb.rest_to_rest_s:.3f} s, "
              f"pump {lb.pump_s:.3f} s, combined {lb.combined_s:.3f} s, with the pump's "
              f"ramps {lb.certified_s:.3f} s; "
              f"energy ≥ {lb.energy_J / 1e3:.2f} kJ")


def add_parsers(sub) -> None:
    """``problems`` (list, show) and ``bound``."""
    pr = sub.add_parser("problems", help="machine specifications shipped with the package")
    psub = pr.add_subparsers(dest="what", required=True)
    p = psub.add_parser("list", help="list the machines")
    add_json_arg(p)
    p.set_defaults(func=cmd_problems_list)
    p = psub.add_parser("show", help="show one machine (id or path to a TOML file)")
    p.add_argument("crane")
    add_json_arg(p)
    p.add_argument("--plot", metavar="FILE.png|.pdf|.svg", type=output_arg,
                   help="draw the workspace figure (format from the suffix)")
    p.set_defaults(func=cmd_problems_show)
    p = psub.add_parser("urdf", help="a URDF of one machine (DH kinematics, limits, inertias) "
                                     "for ROS / MoveIt tools")
    p.add_argument("crane")
    p.add_argument("--out", metavar="FILE.urdf", type=output_arg,
                   help="write it to FILE (default: stdout)")
    add_json_arg(p)
    p.set_defaults(func=cmd_problems_urdf)
    p = sub.add_parser("bound", help="analytic minimum-time lower bounds for a move")
    p.add_argument("crane")
    p.add_argument("--start", type=point_arg, required=True, metavar="r,z,slew")
    p.add_argument("--goal", type=point_arg, required=True, metavar="r,z,slew")
    add_json_arg(p)
    p.set_defaults(func=cmd_bound)
