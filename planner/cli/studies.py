"""``bench`` (DP vs NLP vs local laws: markdown + JSON + figures) and ``demo`` (the main job).

Both import the benchmark (every planner, matplotlib) only when they run."""
from __future__ import annotations

from planner.cli.common import CLIError, add_json_arg, emit


def cmd_bench(args):
    """DP vs NLP vs local laws on the seeds' suites (planner.bench): bench.md, bench.json
    and figures in --out."""
    from planner.bench.run import parse_suites, run_bench
    try:
        suites = parse_suites(args.suite)
    except ValueError as e:
        raise CLIError(str(e)) from None
    if args.repeats is not None and args.repeats < 1:
        raise CLIError(f"--repeats must be >= 1, got {args.repeats}")
    methods = ([m.strip() for m in args.methods.split(",") if m.strip()]
               if args.methods else None)
    res = run_bench(suites, args.out, repeats=args.repeats, quick=args.quick,
                    results=args.results, methods=methods)
    emit(args, res)
    if args.json != "-":
        print(f"bench written to {args.out}/ (bench.md, bench.json, figures): "
              + "; ".join(f"{n} {s['wall_time_s']:.0f} s" for n, s in res["suites"].items())
              + f"; total {res['wall_time_s']:.0f} s")
    return 0


def cmd_demo(args):
    """The main job (planner.demo): machines, seed 000, a small library, the short
    benchmark and a calibration, into ``--out``."""
    from planner.demo import run_demo
    if args.library_moves < 1 or args.workers < 1:
        raise CLIError("--library-moves and --workers must be >= 1")
    summary = run_demo(args.out, library_moves=args.library_moves, workers=args.workers,
                       progress=not (args.json == "-"))
    emit(args, summary)
    if not args.json:
        print(f"demo written to {args.out}/ (summary.md and figures)")
    return 0


def add_parsers(sub) -> None:
    """``bench`` and ``demo``."""
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
    p.add_argument("--methods", metavar="NAME[,NAME]",
                   help="only these bench methods (default: every variant and registered method)")
    p.add_argument("--results", default="benchmarks/results", metavar="DIR",
                   help="folder of the committed reports the seed tables compare with "
                        "(default benchmarks/results)")
    add_json_arg(p)
    p.set_defaults(func=cmd_bench)
    p = sub.add_parser("demo", help="the main job: machines, seed 000, a small library, a short "
                                    "benchmark, a calibration")
    p.add_argument("--out", default="demo-output", help="output folder (default demo-output)")
    p.add_argument("--library-moves", type=int, default=6,
                   help="moves of the forwarder cycle in the demo library (6)")
    p.add_argument("--workers", type=int, default=2, help="library build processes (2)")
    add_json_arg(p)
    p.set_defaults(func=cmd_demo)
