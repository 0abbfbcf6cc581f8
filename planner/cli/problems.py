"""``problems list`` · ``problems show ID`` · ``bound CRANE --start --goal``: the shipped
machines and the analytic lower bounds of a move."""
from __future__ import annotations

import dataclasses
import math
import sys

from problems import crane_ids, load_crane

from planner.bounds import lower_bound
from planner.cli.common import add_json_arg, emit, point_arg
from planner.model import Crane


def cmd_problems_list(args):
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
    spec = load_crane(args.crane)
    d = dataclasses.asdict(spec)
    d.pop("raw", None)
    d.pop("text", None)
    emit(args, d)
    if args.plot:
        from planner.plots import workspace_figure  # matplotlib: only when drawing
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
    crane = Crane.from_id(args.crane)
    lb = lower_bound(crane, args.start, args.goal)
    emit(args, dict(status="ok", crane=crane.spec.id, start=args.start, goal=args.goal,
                    **lb.as_dict()))
    if not args.json:
        print(f"lower bounds for {crane.spec.id} {args.start} -> {args.goal}:\n"
              f"  velocity {lb.velocity_s:.3f} s, rest-to-rest {lb.rest_to_rest_s:.3f} s, "
              f"pump {lb.pump_s:.3f} s, combined {lb.combined_s:.3f} s; "
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
    p.add_argument("--plot", metavar="FILE.png", help="draw the workspace figure")
    p.set_defaults(func=cmd_problems_show)
    p = sub.add_parser("bound", help="analytic minimum-time lower bounds for a move")
    p.add_argument("crane")
    p.add_argument("--start", type=point_arg, required=True, metavar="r,z,slew")
    p.add_argument("--goal", type=point_arg, required=True, metavar="r,z,slew")
    add_json_arg(p)
    p.set_defaults(func=cmd_bound)
