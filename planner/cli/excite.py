"""``excite CRANE --separate A[@JOINT],B[@JOINT][,…] --duration T --out FILE.csv``: a test
trajectory within the machine's limits on which the named effects show as differently as
possible (:mod:`planner.calibration.excite`). ``--from RESULT.json`` instead of ``--separate``:
the candidates of an ambiguous ``discrepancy --json`` result, at their fitted values."""
from __future__ import annotations

from planner.cli.common import add_json_arg, emit


def cmd_excite(args):
    """Design (optimised over a family of feasible test sequences), then write."""
    # scipy and the planners: only when the command runs
    from planner.calibration.excite import (candidates_from_result, design_excitation,
                                            lengthen, parse_candidates)
    from planner.model import Crane
    crane = Crane.from_id(args.crane)
    if (args.separate is None) == (args.from_result is None):
        raise ValueError("excite: give --separate A,B[,…] or --from RESULT.json (one of them)")
    if args.from_result is not None:
        effects = candidates_from_result(crane, _read_json(args.from_result),
                                         f"--from {args.from_result}")
    else:
        effects = parse_candidates(crane, args.separate, args.joint, args.seed)
    if not 10.0 <= args.duration <= 600.0:
        raise ValueError(f"--duration {args.duration:g}: allowed 10 ... 600 s")
    max_duration = args.duration if args.max_duration is None else args.max_duration
    if not args.duration <= max_duration <= 600.0:
        raise ValueError(f"--max-duration {max_duration:g}: allowed --duration "
                         f"({args.duration:g}) ... 600 s")
    if not 1 <= args.candidates <= 100:
        raise ValueError(f"--candidates {args.candidates}: allowed 1 ... 100")
    if not 0 <= args.budget <= 2000:
        raise ValueError(f"--budget {args.budget}: allowed 0 ... 2000")
    say = None if args.json == "-" else (lambda s: print(s, flush=True))
    d = design_excitation(crane, effects, duration=args.duration, rate=args.rate,
                          candidates=args.candidates, seed=args.seed, budget=args.budget,
                          method=args.method, moves=args.moves, progress=say)
    lengthened = None
    need = [u["duration_needed_s"] for u in d.unseparated]
    if need and all(need) and max(need) <= max_duration and d.source != "random":
        lengthened = (float(d.plan.duration), max(need))
        d = lengthen(crane, d, max(need))
    # everything computed: now write
    d.ff.to_csv(args.out, d.plan)
    info = dict(status="ok", out=args.out, crane=crane.spec.id, seed=d.seed,
                duration_s=float(d.plan.duration), separation=d.separation,
                default_separation=d.default_separation, pairs=d.pairs,
                effects=[e.to_dict() for e in d.effects],
                tried={str(k): v for k, v in d.tried.items()}, method=d.method,
                source=d.source, optimised_separation=d.optimised_separation,
                evaluations=d.evaluations, runtime_s=d.runtime_s, design_vector=d.z,
                signal=d.signal, unseparated=d.unseparated,
                lengthened_from_s=lengthened[0] if lengthened else None)
    emit(args, info)
    if not args.json:
        print(f"{args.out}: {d.plan.duration:.1f} s test sequence ({d.source}, "
              f"{d.evaluations} designs evaluated in {d.runtime_s:.0f} s); smallest "
              f"separation of the candidates {d.separation:.1f} σ² (default sequence: "
              f"{d.default_separation:.1f} σ²)"
              + (f"; lengthened from {lengthened[0]:.0f} s so that every pair reaches the "
                 "tie floor" if lengthened else ""))
        for k, v in d.pairs.items():
            print(f"  {k}: {v:.1f}")
        for u in d.unseparated:
            need = u["duration_needed_s"]
            print(f"  not separated: {u['why']}"
                  + (f" (--max-duration {need:g})" if need else ""))
    return 0


def _read_json(path) -> dict:
    import json
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except OSError as e:
        raise ValueError(f"--from {path}: cannot read: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"--from {path}: not JSON ({e.msg} at line {e.lineno})") from None


def add_parsers(sub) -> None:
    """``excite``."""
    p = sub.add_parser("excite", help="a test trajectory that tells candidate effects apart")
    p.add_argument("crane", help="machine id or a TOML spec")
    p.add_argument("--separate", metavar="A[@JOINT],B[@JOINT],…",
                   help="catalogue effects to tell apart (per-joint ones with @JOINT), at "
                        "their trial magnitudes")
    p.add_argument("--from", dest="from_result", metavar="RESULT.json",
                   help="instead of --separate: the candidates of an ambiguous `discrepancy "
                        "--json` result, at the values they were fitted to")
    p.add_argument("--joint", help="the joint of per-joint effects written without @JOINT")
    p.add_argument("--duration", type=float, default=60.0, help="seconds (60)")
    p.add_argument("--max-duration", type=float, metavar="S",
                   help="run the design's sequence up to S seconds when a pair needs a longer "
                        "recording to be told apart (default: --duration)")
    p.add_argument("--rate", type=float, default=50.0, help="command rate in Hz (50)")
    p.add_argument("--candidates", type=int, default=6,
                   help="random starting designs (6)")
    p.add_argument("--budget", type=int, default=40,
                   help="Nelder-Mead evaluations of the criterion after the starts (40)")
    p.add_argument("--method", choices=("optimise", "random"), default="optimise",
                   help="optimise (default) or random: best of the trials' random sequences")
    p.add_argument("--moves", type=int, default=3, help="poses of the periodic sequence (3)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, metavar="FILE.csv",
                   help="the trajectory CSV (t, q_*, qd_*, qdd_*, u_*)")
    add_json_arg(p)
    p.set_defaults(func=cmd_excite)
