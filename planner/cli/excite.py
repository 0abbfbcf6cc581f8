"""``excite CRANE --separate A[@JOINT],B[@JOINT][,…] --duration T --out FILE.csv``: a test
trajectory within the machine's limits on which the named effects show as differently as
possible (:mod:`planner.calibration.excite`). ``--from RESULT.json`` instead of ``--separate``:
the candidates of an ambiguous ``discrepancy --json`` result, at their fitted values.

``excite CRANE --for dynamics --duration T --out FILE.csv``: a test trajectory on which the
dynamic twin's parameters (oil, hoses, valves, pump, friction, leakage) show as separately as
possible, with the predicted standard deviation of each and the recording length the
calibration needs (:mod:`planner.calibration.excite_dynamics`); ``simulate CRANE --trajectory
FILE.csv`` replays it, and ``calibrate`` fits the twin to the log."""
from __future__ import annotations

from planner.cli.common import add_json_arg, emit


def cmd_excite(args):
    """Design (optimised over a family of feasible test sequences), then write."""
    # scipy and the planners: only when the command runs
    from planner.calibration.excite import (candidates_from_result, design_excitation,
                                            lengthen, parse_candidates)
    from planner.model import Crane
    if args.mode == "dynamics":
        return _dynamics(args)
    if args.parameters is not None or args.compare:
        flag = "--parameters" if args.parameters is not None else "--compare"
        raise ValueError(f"excite: {flag} is for --for dynamics; allowed with --for effects: "
                         "--separate, --from, --joint, --max-duration, --budget, --method, "
                         "--moves")
    args.duration = 60.0 if args.duration is None else args.duration
    args.candidates = 6 if args.candidates is None else args.candidates
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
    args.budget = 40 if args.budget is None else args.budget
    args.method = args.method or "optimise"
    args.moves = 3 if args.moves is None else args.moves
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


def _dynamics(args):
    """``--for dynamics``: design for the twin's parameters (module doc), then write."""
    from planner.calibration.excite_dynamics import MAX_NEEDED_S, design_dynamics
    from planner.model import Crane
    for flag, value in (("--separate", args.separate), ("--from", args.from_result),
                        ("--joint", args.joint), ("--max-duration", args.max_duration),
                        ("--budget", args.budget), ("--method", args.method),
                        ("--moves", args.moves)):
        if value is not None:
            raise ValueError(f"excite: {flag} is for --for effects; allowed with --for "
                             "dynamics: --duration, --candidates, --parameters, --compare, "
                             "--rate, --seed")
    duration = 120.0 if args.duration is None else args.duration
    if not 10.0 <= duration <= MAX_NEEDED_S:
        raise ValueError(f"--duration {duration:g}: allowed 10 ... {MAX_NEEDED_S:g} s")
    candidates = 2 if args.candidates is None else args.candidates
    if not 0 <= candidates <= 20:
        raise ValueError(f"--candidates {candidates}: allowed 0 ... 20")
    if not 5.0 <= args.rate <= 1000.0:
        raise ValueError(f"--rate {args.rate:g}: allowed 5 ... 1000 Hz")
    crane = Crane.from_id(args.crane)
    if crane.spec.dynamics is None:
        raise ValueError(f"crane '{crane.spec.id}' ({crane.spec.path}): field 'dynamics': "
                         "missing section; designing for the twin needs [dynamics]")
    if args.parameters is not None:      # an unknown name: refused before any twin runs
        from planner.calibration.twin_params import select, twin_parameters
        select(twin_parameters(crane), args.parameters)
    say = None if args.json == "-" else (lambda s: print(s, flush=True))
    d = design_dynamics(crane, duration, seed=args.seed, candidates=candidates,
                        parameters=args.parameters, rate=args.rate, compare=args.compare,
                        progress=say)
    # everything computed: now write
    d.ff.to_csv(args.out, d.plan)
    emit(args, dict(status="ok", out=args.out, crane=crane.spec.id, mode="dynamics",
                    **d.to_dict()))
    if args.json:
        return 0
    print(f"{args.out}: {d.plan.duration:.1f} s test sequence for the {crane.spec.id} twin's "
          f"dynamics ({len(d.order)} blocks of the pool of seed {d.seed}; {d.runs} twin runs "
          f"in {d.runtime_s:.0f} s); ln det(JᵀJ) {d.logdet:.1f}"
          + (f" (plain excitation of the same length: {d.plain['logdet']:.1f})"
             if d.plain else ""))
    print(f"{'parameter':24s} {'sd (scaled)':>12s}" + (f" {'plain':>10s}" if d.plain else ""))
    for k, v in d.sd.items():
        print(f"{k:24s} {v:12.3g}" + (f" {d.plain['sd_scaled'][k]:10.3g}" if d.plain else ""))
    if d.needed_s is not None and d.needed_s <= d.plan.duration:
        print(f"needed: the first {d.needed_s:.0f} s identify every parameter (predicted "
              f"scaled sd at most {d.threshold:g})")
    elif d.needed_s is not None:
        print(f"needed: {d.needed_s:.0f} s of this sequence (--duration "
              f"{10 * -(-d.needed_s // 10):g}) to identify every parameter; "
              f"{d.plan.duration:.0f} s leave unidentified:")
    else:
        print(f"not every parameter is identified by {MAX_NEEDED_S:g} s of this sequence; "
              f"{d.plan.duration:.0f} s leave unidentified:")
    for k, why in d.unidentified.items():
        print(f"  {k}: {why}")
    for k, why in d.unidentified_at_limit.items():
        print(f"  at {MAX_NEEDED_S:g} s still {k}: {why}")
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
    p = sub.add_parser("excite", help="a test trajectory that tells candidate effects apart, "
                                      "or that calibrates the dynamic twin (--for dynamics)")
    p.add_argument("crane", help="machine id or a TOML spec")
    p.add_argument("--for", dest="mode", choices=("effects", "dynamics"), default="effects",
                   help="effects (default): tell the candidate effects apart; dynamics: "
                        "identify the dynamic twin's oil, hoses, valves, pump, friction and "
                        "leakage, and say how long a recording that needs")
    p.add_argument("--separate", metavar="A[@JOINT],B[@JOINT],…",
                   help="catalogue effects to tell apart (per-joint ones with @JOINT), at "
                        "their trial magnitudes")
    p.add_argument("--from", dest="from_result", metavar="RESULT.json",
                   help="instead of --separate: the candidates of an ambiguous `discrepancy "
                        "--json` result, at the values they were fitted to")
    p.add_argument("--joint", help="the joint of per-joint effects written without @JOINT")
    p.add_argument("--duration", type=float, default=None,
                   help="seconds (60; --for dynamics: 120)")
    p.add_argument("--max-duration", type=float, metavar="S",
                   help="run the design's sequence up to S seconds when a pair needs a longer "
                        "recording to be told apart (default: --duration)")
    p.add_argument("--rate", type=float, default=50.0, help="command rate in Hz (50)")
    p.add_argument("--candidates", type=int, default=None,
                   help="random starting designs (6; --for dynamics: random tours in the "
                        "pool besides the structured ones, 2)")
    p.add_argument("--budget", type=int, default=None,
                   help="Nelder-Mead evaluations of the criterion after the starts (40)")
    p.add_argument("--method", choices=("optimise", "random"), default=None,
                   help="optimise (default) or random: best of the trials' random sequences")
    p.add_argument("--moves", type=int, default=None,
                   help="poses of the periodic sequence (3)")
    p.add_argument("--parameters", default=None, metavar="NAME,…",
                   help="--for dynamics: the twin's parameters to design for: all (default), "
                        "groups oil, hoses, valves, pump, friction, leakage, kinds or names")
    p.add_argument("--compare", action="store_true",
                   help="--for dynamics: score the plain excitation of the same length too")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, metavar="FILE.csv",
                   help="the trajectory CSV (t, q_*, qd_*, qdd_*, u_*)")
    add_json_arg(p)
    p.set_defaults(func=cmd_excite)
