"""``calibrate CRANE --measured LOG.csv [--measured …] --out calibrated.toml``: the dynamic
twin's physical parameters fitted to logs (planner.calibration.twin_fit), written as a complete
machine spec whose ``[dynamics]`` and dead bands hold the fitted values; then ``library refine
LIB.h5 --model calibrated.toml`` re-computes the feed-forward on it."""
from __future__ import annotations

import sys

from planner.cli.common import CLIError, add_json_arg, emit


def cmd_calibrate(args):
    import tomllib

    from planner.calibration.rate import check_file
    from planner.calibration.twin_fit import TwinFit
    from planner.calibration.twin_spec import calibrated_twin_text
    from planner.io import atomic_write_text
    from planner.model import Crane
    from planner.model.spec import parse_spec
    from planner.simulation.recording import Recording
    if not 1 <= args.iterations <= 200:
        raise CLIError(f"--iterations {args.iterations}: allowed 1 … 200")
    if not 0.1 <= args.hold <= 10.0:
        raise CLIError(f"--hold {args.hold}: allowed 0.1 … 10 s")
    crane = Crane.from_id(args.crane)
    if crane.spec.dynamics is None:
        raise CLIError(f"crane '{crane.spec.id}' ({crane.spec.path}): field 'dynamics': "
                       "missing section; calibrating the twin needs [dynamics]")
    recs = []
    for path in args.measured:
        check_file(path)
        rec = Recording.from_csv(path, crane, None)
        if rec.p_a is None and not args.positions_only:
            print(f"crane-planner: --measured {path}: no pressure columns; fitting positions "
                  "only (the oil and hoses show mostly in the pressures)", file=sys.stderr)
        recs.append(rec)
    if not 1 <= args.workers <= 64:
        raise CLIError(f"--workers {args.workers}: allowed 1 … 64 processes")
    from planner.cli.plan import grapple_of_args
    pend = None if args.grapple == 0 else grapple_of_args(args, crane)
    fit = TwinFit(crane, recs, args.parameters, hold=args.hold,
                  pressures=not args.positions_only, workers=args.workers, grapple=pend,
                  anchor=args.anchor)
    if args.json != "-":
        print(f"calibrating {len(fit.params)} parameters of the {crane.spec.id} twin on "
              f"{len(recs)} log(s), {len(fit.segs)} segments"
              + (f", the load hanging on its {pend.length:g} m link" if pend else "")
              + " …", file=sys.stderr)
    res = fit.solve(max_iterations=args.iterations)
    src = "on " + ", ".join(args.measured)
    text = calibrated_twin_text(crane, res, src)
    parse_spec(tomllib.loads(text), args.out, text)   # the written machine must load
    atomic_write_text(args.out, text)
    js = dict(res.to_dict(), crane_id=crane.spec.id, measured=list(args.measured),
              out=args.out, judge="twin vs the logs",
              grapple_m=pend.length if pend else None,
              next=f"crane-planner library refine LIB.h5 --model {args.out}")
    emit(args, js)
    if args.json != "-":
        print(f"{'parameter':24s} {'spec':>10s} {'fitted':>10s}  95 % interval")
        for k, v in res.values.items():
            lo, hi = res.interval[k]
            unit = res.units.get(k, "")
            print(f"{k:24s} {res.nominal[k]:10.4g} {v:10.4g}  {lo:.4g} … {hi:.4g}"
                  + (f" {unit}" if unit not in ("", "1") else "")
                  + ("" if res.identified[k] else
                                               "  (not identified by these logs)"))
        rb, ra = res.rms_before, res.rms_after
        print(f"misfit (RMS, noise units): positions {rb['positions']:.2f} -> "
              f"{ra['positions']:.2f}" + (f", pressures {rb['pressures']:.2f} -> "
                                          f"{ra['pressures']:.2f}" if rb["pressures"] else ""))
        print(f"{res.status} after {res.runs} twin runs, {res.runtime_s:.0f} s; wrote "
              f"{args.out}; next: crane-planner library refine LIB.h5 --model {args.out}")
    return 0


def add_parsers(sub) -> None:
    """``calibrate``."""
    p = sub.add_parser("calibrate", help="fit the dynamic twin's oil, hoses, valves, "
                                         "friction and leakage to logs; write the machine")
    p.add_argument("crane", help="machine id or a TOML spec with [dynamics]")
    p.add_argument("--measured", required=True, action="append", metavar="LOG.csv",
                   help="a measured-data CSV with the logged commands (u_<joint> columns); "
                        "repeat for several logs")
    p.add_argument("--out", required=True, metavar="FILE.toml",
                   help="the calibrated machine spec (the spec with the fitted [dynamics] "
                        "and dead bands)")
    p.add_argument("--parameters", default=None, metavar="NAME,…",
                   help="what to fit: all (default), groups oil, hoses, valves, pump, "
                        "friction, leakage, kinds (hose_a, coulomb, deadband, …) or names "
                        "(coulomb.boom)")
    p.add_argument("--iterations", type=int, default=12,
                   help="least-squares iterations (each a twin run per parameter; 12); up to "
                   "2 more rounds of them while the fit ends above the noise (1.1 σ), "
                   "then up to 2 × as many on the whole log while that stage has not converged")
    p.add_argument("--hold", type=float, default=0.5,
                   help="the log is cut at holds (all commands 0) at least this long [s] "
                        "(0.5)")
    p.add_argument("--workers", type=int, default=1,
                   help="processes for the twin runs of each Jacobian (1)")
    p.add_argument("--anchor", choices=("twin", "log"), default="twin",
                   help="where each segment after a hold starts: twin — the twin's own state "
                        "(default: the whole log open loop, unbiased when the twin's family "
                        "holds the machine); log — the logged positions and quiet pressures")
    from planner.cli.plan import add_grapple_args
    add_grapple_args(p, "the load hung on a grapple link of LENGTH m while the logs were made "
                        "(default: the spec's [dynamics.grapple]; 0: none): the twin carries "
                        "it, its swing loading the boom as on the machine")
    p.add_argument("--positions-only", action="store_true",
                   help="fit to the positions only (ignore logged pressures)")
    add_json_arg(p)
    p.set_defaults(func=cmd_calibrate)
