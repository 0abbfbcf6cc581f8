"""``simulate CRANE --trajectory …`` (open-loop replay -> measured-data CSV) and ``effects list``
(the catalogue of model effects).

The plants, the model and its effects are imported when a command runs (the plant names for
``--plant`` when a value is checked or ``simulate --help`` is printed)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import sys
from dataclasses import replace

from planner.cli.common import (CLIError, LazyChoices, add_json_arg, emit, output_arg,
                                read_trajectory, replay_commands)
from planner.units import parse_angle

if TYPE_CHECKING:
    from planner.model import Crane


def noise_levels(text):
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


DEFAULT_RATE = 50.0   # [Hz] command rate of the feed-forward when --rate is not given


def commands_at_rate(traj, rate):
    """(trajectory, note): ``traj`` with its own valve commands (``u`` on a uniform grid, an
    ``excite`` file's or an exported entry's) held at ``rate`` [Hz] when a rate is given that
    differs from theirs — the command in effect at each instant of the new grid (zero-order
    hold, as the valves hold it), the positions sampled on that grid — and a note saying so.
    A trajectory without commands is returned as it is (the feed-forward is computed at the
    rate); so is one whose commands are already at ``rate`` or when no rate is given."""
    if rate is not None and not (math.isfinite(rate) and rate > 0):
        raise CLIError(f"--rate {rate:g}: allowed a command rate > 0 Hz")
    import numpy as np
    t = traj.t
    if traj.u is None or len(t) <= 2 or np.ptp(np.diff(t)) >= 1e-9 or rate is None:
        return traj, None
    own = (len(t) - 1) / (t[-1] - t[0])
    if abs(own - rate) <= 1e-6 * rate:
        return traj, None
    n = int(math.ceil((t[-1] - t[0]) * rate - 1e-9))
    t_new = t[0] + np.arange(n + 1) / rate
    k = np.clip(np.searchsorted(t, t_new + 1e-9 / rate, side="right") - 1, 0, len(t) - 1)
    q, qd, qdd, _ = traj.sample(t_new)
    out = replace(traj, t=t_new, q=q, qd=qd, qdd=qdd, u=traj.u[k])
    return out, (f"--rate {rate:g}: the trajectory's own commands ({own:.6g} Hz) held at "
                 f"{rate:g} Hz ({len(t)} -> {len(t_new)} command samples)")


def cmd_simulate(args):
    """Replay a trajectory's valve commands open loop and write the measured-data CSV."""
    from planner.model import Crane
    from planner.model.effects import parse_effect
    from planner.simulation.plant import simulate_to_csv
    from planner.simulation.plants import applying
    from planner.simulation.replay import Plant
    from planner.simulation.sizes import check_rate
    crane = Crane.from_id(args.crane)
    effects = []
    for text in args.effect or []:
        try:
            effects.append(parse_effect(text, crane))
        except ValueError as e:
            raise CLIError(f"--effect {text!r}: {e}") from None
    for e in effects:
        where = applying(e)
        if args.plant not in where:
            raise CLIError(f"--effect {e.name}: the {args.plant} plant cannot apply it (it acts "
                           f"through {', '.join(e.own_hooks())}); add "
                           + " or ".join(f"--plant {p}" for p in where))
    plan = read_trajectory(crane, args.trajectory)
    traj, which = replay_commands(crane, args.trajectory, plan, args.commands)
    if not (math.isfinite(args.settle) and 0.0 <= args.settle <= 600.0):
        raise CLIError(f"--settle {args.settle:g}: allowed 0 .. 600 s (recorded with the valves "
                       "closed after the last command)")
    # bounded output and memory, before the replay (the file's own rate when not given)
    check_rate(args.rate if args.rate is not None else DEFAULT_RATE,
               traj.duration + args.settle)
    traj, note = commands_at_rate(traj, args.rate)
    if note:
        print(f"crane-planner: note: {note}", file=sys.stderr)
    args.rate = args.rate or DEFAULT_RATE
    landing = args.settle > 0 or which == "refined"
    if args.settle > 0:
        from planner.feedforward import fills_oil, with_settle
        traj = with_settle(crane, traj, args.settle, args.rate,   # a dynamic plant has oil
                           oil=args.plant != "fast" and fills_oil(crane))
    args.landing = dict(plan=plan if landing else None, commands_used=which,
                        settle_s=args.settle)
    if args.plant != "fast":
        return _simulate_dynamic(args, crane, traj, effects, note)
    plant = Plant(flow_gain_scale=args.flow_gain, pump_flow_scale=args.pump_flow)
    summary = simulate_to_csv(crane, traj, args.out, plant=plant, rate=args.rate,
                              noise=noise_levels(args.noise), seed=args.seed, effects=effects,
                              plan=args.landing["plan"])
    if note:
        summary["rate_note"] = note
    _report(args, summary, "")
    return 0


def _report(args, summary: dict, what: str) -> None:
    """The summary (JSON) or its line, with which commands ran and, where the landing was
    recorded, how the tip came to rest."""
    summary.update(commands_used=args.landing["commands_used"], settle_s=args.landing["settle_s"])
    emit(args, summary)
    if not args.json:
        line = (f"measured data written to {args.out}{what}: {summary['samples']} samples, "
                f"max tip drift {1e3 * summary['max_tip_error_m']:.1f} mm")
        if "rest_offset_m" in summary:
            line += (f"; {summary['commands_used']} commands: at rest "
                     f"{1e3 * summary['rest_offset_m']:.1f} mm from the goal, ringing "
                     f"{1e3 * summary['residual_oscillation_m']:.1f} mm")
        print(line)


def _simulate_dynamic(args, crane: Crane, traj, effects, note=None):
    """``--plant exudyn`` (or another registered dynamic plant); a run that diverges or times
    out writes nothing and exits with status 3 (its status and failure time in the JSON)."""
    if args.flow_gain != 1.0 or args.pump_flow != 1.0:
        raise CLIError(f"--flow-gain/--pump-flow apply to the fast plant; with --plant "
                       f"{args.plant} use --effect flow_gain:… or --effect pump_flow_limit:…")
    from planner.simulation.plants import PlantDiverged, plant_to_csv
    try:
        summary = plant_to_csv(crane, traj, args.out, args.plant, rate=args.rate,
                               noise=noise_levels(args.noise), seed=args.seed, effects=effects,
                               plan=args.landing["plan"])
    except PlantDiverged as e:
        emit(args, dict(status=e.status, reason=e.reason, t_fail_s=e.t_fail, plant=args.plant))
        print(f"error: {e}; nothing written", file=sys.stderr)
        return 3
    if note:
        summary["rate_note"] = note
    _report(args, summary, f" ({args.plant} plant)")
    return 0


def cmd_effects_list(args):
    from planner.model.effects import CATALOGUE, catalogue
    from planner.simulation.plants import applying
    cat = [dict(e, plants=applying(CATALOGUE[e["name"]])) for e in catalogue()]
    emit(args, cat)
    if not args.json:
        for e in cat:
            ps = ", ".join(f"{k} {v if isinstance(v, str) else v}" for k, v in
                           e["parameters"].items())
            only = "" if "fast" in e["plants"] else (
                f" (--plant {' / '.join(e['plants'])} only)")
            print(f"{e['name']:18s} {e['description']}{only}\n{'':18s} parameters: {ps}")
    return 0


def plant_names() -> list[str]:
    """The registered plants, sorted (``--plant``'s choices)."""
    from planner.simulation.plants import PLANTS
    return sorted(PLANTS)


def add_parsers(sub) -> None:
    """``simulate`` and ``effects`` (list)."""
    p = sub.add_parser("simulate", help="replay a trajectory open loop; write measured data")
    p.add_argument("crane")
    p.add_argument("--trajectory", required=True, metavar="FILE.csv|FILE.h5#ID")
    p.add_argument("--out", required=True, metavar="MEASURED.csv", type=output_arg)
    p.add_argument("--noise", nargs="?", const="default", metavar="angle=…,pressure=…",
                   help="sensor noise: seed 001's levels (0.1°, 2 mm, 0.17 MPa standard "
                        "deviations) or the given ones (e.g. angle=0.05deg,pressure=5e4)")
    p.add_argument("--effect", action="append", metavar="NAME:key=value,…",
                   help="hidden effect in the plant (repeatable), e.g. "
                        "coulomb_friction:joint=boom,force=3000 (see 'effects list')")
    p.add_argument("--seed", type=int, default=0, help="noise seed (0)")
    p.add_argument("--rate", type=float, metavar="HZ",
                   help="command rate [Hz] of the feed-forward (50); a trajectory that "
                        "carries its own commands (u_*) is replayed at their rate, or held at "
                        "this one when given")
    plant = p.add_argument("--plant", default="fast",
                           help="fast: the quasi-static replay (default); exudyn: the "
                                "independent dynamic plant (multibody + pressure dynamics, "
                                "needs [dynamics])")
    # given after add_argument, which formats (and so would read) the choices at once
    plant.choices = LazyChoices(plant_names)
    p.add_argument("--commands", choices=("auto", "nominal", "refined"), default="auto",
                   help="a library entry's commands: refined (`library refine`) when present "
                        "(auto, default), or nominal / refined")
    p.add_argument("--settle", type=float, default=0.0, metavar="S",
                   help="record S more seconds with the valves closed after the last command; "
                        "the JSON then reports rest_offset_m and residual_oscillation_m")
    p.add_argument("--flow-gain", type=float, default=1.0, help="plant valve gain scale (1.0)")
    p.add_argument("--pump-flow", type=float, default=1.0, help="plant pump flow scale (1.0)")
    add_json_arg(p)
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("effects", help="the catalogue of model effects")
    esub = p.add_subparsers(dest="what", required=True)
    p = esub.add_parser("list", help="name, description, parameters with plausible ranges")
    add_json_arg(p)
    p.set_defaults(func=cmd_effects_list)
