"""``crane-planner`` command line (also ``python -m planner``).

Every sub-command has ``--help``; ``--json FILE`` (``-`` or no value: stdout) writes a
machine-readable result. Plain numbers are SI; angles may be written ``30deg``.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

from .spec import SpecError, parse_angle


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
    from .io import write_json
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
        from .model import Crane
        from .plots import workspace_figure
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
    from .bounds import lower_bound
    from .model import Crane
    crane = Crane.from_id(args.crane)
    lb = lower_bound(crane, args.start, args.goal)
    _emit(args, dict(status="ok", crane=crane.spec.id, start=args.start, goal=args.goal,
                     **lb.as_dict()))
    if not args.json:
        print(f"lower bounds for {crane.spec.id} {args.start} -> {args.goal}:\n"
              f"  velocity {lb.velocity_s:.3f} s, rest-to-rest {lb.rest_to_rest_s:.3f} s, "
              f"pump {lb.pump_s:.3f} s, combined {lb.combined_s:.3f} s; "
              f"energy ≥ {lb.energy_J / 1e3:.2f} kJ")


def cmd_demo(args):
    from tqdm import tqdm

    from problems import crane_ids
    from .bounds import lower_bound
    from .model import Crane
    from .plots import workspace_figure
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lines = ["# crane-planner demo", "", "| machine | joints | max reach [m] | pump [L/min] | "
             "figure |", "| --- | --- | --- | --- | --- |"]
    summary = []
    for cid in tqdm(crane_ids(), desc="machines", unit="machine"):
        crane = Crane.from_id(cid)
        fig = out / f"workspace_{cid}.png"
        info = workspace_figure(crane, fig)
        s = crane.spec
        lines.append(f"| {s.name} | {', '.join(s.joint_names)} | {info['r_max']:.2f} | "
                     f"{s.pump.max_flow * 6e4:.0f} | [{fig.name}]({fig.name}) |")
        summary.append(dict(id=cid, figure=str(fig), **info))
    crane = Crane.from_id("cranab850")
    lines += ["", "## Seed 000 moves on cranab850: analytic lower bounds", "",
              "| move | velocity [s] | rest-to-rest [s] | pump [s] | seed DP (Table 8.1) [s] |",
              "| --- | --- | --- | --- | --- |"]
    pts = dict(A=(1.5, 1.0, 0.0), B=(5.5, 1.0, 0.0), C=(5.5, -3.0, 0.0))
    for (a, b), dp in zip((("A", "B"), ("B", "C"), ("A", "C")), (1.15, 0.89, 1.18)):
        lb = lower_bound(crane, pts[a], pts[b])
        lines.append(f"| {a}–{b} | {lb.velocity_s:.3f} | {lb.rest_to_rest_s:.3f} | "
                     f"{lb.pump_s:.3f} | {dp:.2f} |")
        summary.append(dict(move=f"{a}-{b}", **lb.as_dict()))
    from .io import atomic_write_text
    atomic_write_text(out / "summary.md", "\n".join(lines) + "\n")
    _emit(args, summary)
    print(f"demo written to {out}/ (summary.md and {len(crane_ids())} workspace figures)")


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
    p = sub.add_parser("demo", help="the main job: machines, workspaces, bounds")
    p.add_argument("--out", default="demo-output", help="output folder (default demo-output)")
    _json_arg(p)
    p.set_defaults(func=cmd_demo)
    return ap


def main(argv=None) -> int:
    from .model import UnreachableError
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except (SpecError, UnreachableError, CLIError) as e:
        print(f"crane-planner: error: {e}", file=sys.stderr)
        return 2
    except KeyError as e:
        print(f"crane-planner: error: {e.args[0]}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
