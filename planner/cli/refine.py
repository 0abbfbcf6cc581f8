"""``library refine LIB.h5``: the library's feed-forward re-computed on the dynamic twin
(:mod:`planner.library.refine`), stored beside the nominal commands of every entry."""
from __future__ import annotations

import math
import shlex
import sys

from planner.cli.common import CLIError, add_json_arg, emit


def cmd_library_refine(args):
    from planner.library.refine import refine_library
    from planner.library.workers import Interrupted
    from planner.refine import RefineOptions
    if args.workers < 1:
        raise CLIError(f"--workers {args.workers}: allowed >= 1")
    if args.limit is not None and args.limit < 1:
        raise CLIError(f"--limit {args.limit}: allowed >= 1 (the first N ok entries)")
    try:
        opts = RefineOptions(iterations=args.iterations, tail=args.tail,
                             energy_weight=args.energy_weight,
                             energy_entries=args.energy_entries,
                             time_entries=args.time_entries)
    except ValueError as e:
        raise CLIError(str(e).replace("refine option 'iterations'", "--iterations")
                       .replace("refine option 'tail'", "--tail")
                       .replace("refine option 'energy_weight'", "--energy-weight")) from None
    if args.cycle is not None:
        if args.start != "nominal":
            raise CLIError(f"--start {args.start}: not with --cycle (a cycle's moves are "
                           "refined from their nominal commands)")
        return _cycle(args, opts)
    if args.gap is not None:
        raise CLIError("--gap: only with --cycle (the valves closed between a cycle's moves)")
    if args.swing_weight is not None and not (math.isfinite(args.swing_weight)
                                              and args.swing_weight >= 0):
        raise CLIError(f"--swing-weight {args.swing_weight:g}: allowed >= 0 (0: the tip alone)")
    try:
        s = refine_library(args.library, model=args.model, workers=args.workers,
                           scheduler=args.scheduler, limit=args.limit, options=opts,
                           force=args.force, show_progress=not (args.json == "-"),
                           swing_weight=args.swing_weight, start=args.start)
    except Interrupted as e:
        s = getattr(e, "summary", None)
        if s:
            emit(args, s)
            print(f"crane-planner: interrupted ({s['signal']}): {s['refined']} entries refined "
                  f"in {s['library']}; rerun `{_rerun(args)}` to resume", file=sys.stderr)
        else:
            print(f"crane-planner: interrupted ({e}) before the refine started", file=sys.stderr)
        return e.exit_code
    except FileNotFoundError as e:
        raise CLIError(str(e)) from None
    emit(args, s)
    if not args.json:
        c = s["cpu_per_entry_s"]
        cost = (f", {c['median']:.1f} s CPU per entry (median; p90 {c['p90']:.1f} s)"
                if c["median"] is not None else "")
        swing = (f"; {s['with_swing']} with the load on its grapple link"
                 if s.get("with_swing") else "")
        swing += (f"; {s['started_from_refined']} started from their stored refined commands"
                  if s.get("started_from_refined") else "")
        swing += (f", {s['restarted']} of them predicted off and refined again from the "
                  f"nominal commands ({s['restart_taken']} kept)" if s.get("restarted") else "")
        print(f"{s['library']}: {s['refined']} entries refined on the twin of {s['model']} "
              f"(fingerprint {s['twin_fingerprint']}; {s['statuses'] or 'none'}{swing}), "
              f"{s['skipped_existing']} already refined, {s['seconds']:.1f} s{cost}")
        pr = s.get("energy_pairs")
        if pr and pr["checked"]:
            print(f"  energy entries against their time entries on the twin: {pr['checked']} "
                  f"checked, {pr['dearer']} dearer, {pr['made_cheaper']} refined again with "
                  f"a heavier price and now cheaper")
        for i in (pr or {}).get("costlier", []):
            print(f"  warning: entry {i}: costs more pump work on the twin than its time entry "
                  "(no heavier price made it cheaper and kept it landing)", file=sys.stderr)
        for f in s["failed"]:
            print(f"  warning: entry {f['id']}: {f['reason']}", file=sys.stderr)
    return 0


def _cycle(args, opts) -> int:
    """``--cycle ID,ID,…``: the entries refined as one work cycle (planner.library.cycle)."""
    import numpy as np

    from planner.library.cycle import refine_cycle_library
    from planner.library.workers import Interrupted
    ids = [i.strip() for i in args.cycle.split(",") if i.strip()]
    try:
        s = refine_cycle_library(args.library, ids, model=args.model,
                                 gap=3.0 if args.gap is None else args.gap, options=opts,
                                 force=args.force)
    except Interrupted as e:
        print(f"crane-planner: interrupted ({e}); the moves refined so far are kept: rerun "
              "the same command to resume", file=sys.stderr)
        return e.exit_code
    except (ValueError, FileNotFoundError) as e:
        msg = str(e)
        msg = ("--" + msg if msg.startswith("cycle:") else
               msg.replace("gap = ", "--gap ", 1) if msg.startswith("gap = ") else msg)
        raise CLIError(msg) from None
    emit(args, s)
    if not args.json:
        offs = [e["rest_offset_m"] for e in s["entries"] if e["rest_offset_m"] is not None]
        med = f"; the twin's rest offset median {1e3 * np.median(offs):.1f} mm" if offs else ""
        print(f"{s['library']}: a cycle of {len(s['cycle'])} entries refined on the twin of "
              f"{s['model']} ({s['refined']} refined, {s['kept']} kept), gap "
              f"{s['gap_s']:g} s, {s['seconds']:.1f} s{med}")
    return 0


def build_refine(args, summary: dict) -> int:
    """``library build --feedforward twin``: refine the built library's entries (same workers
    or scheduler); the refine summary goes into the build's as ``refine``. Returns an exit
    code (0, or the signal's when interrupted: the rerun resumes both)."""
    from planner.library.refine import refine_library
    from planner.library.workers import Interrupted
    try:
        summary["refine"] = refine_library(args.out, workers=args.workers,
                                           scheduler=args.scheduler,
                                           show_progress=not (args.json == "-"))
    except Interrupted as e:
        s = getattr(e, "summary", None) or {}
        summary["refine"] = s
        emit(args, summary)
        print(f"crane-planner: interrupted ({s.get('signal', e)}) while refining: "
              f"{s.get('refined', 0)} entries refined in {args.out}; rerun the same command to "
              "resume", file=sys.stderr)
        return e.exit_code
    return 0


def _rerun(args) -> str:
    words = ["crane-planner", "library", "refine", args.library, "--workers", str(args.workers),
             "--iterations", str(args.iterations), "--tail", str(args.tail)]
    words += ["--energy-weight", str(args.energy_weight)] if args.energy_weight else []
    words += (["--energy-entries", args.energy_entries] if args.energy_entries != "priced"
              else [])
    words += ["--time-entries", args.time_entries] if args.time_entries != "priced" else []
    words += ["--swing-weight", f"{args.swing_weight:g}"] if args.swing_weight is not None \
        else []
    words += ["--model", args.model] if args.model else []
    words += ["--limit", str(args.limit)] if args.limit is not None else []
    words += ["--scheduler", args.scheduler] if args.scheduler else []
    return shlex.join(words)


def add_refine_parser(lsub) -> None:
    p = lsub.add_parser("refine", help="re-compute every entry's feed-forward on the dynamic "
                                       "twin (stored beside the nominal commands)")
    p.add_argument("library", metavar="LIB.h5")
    p.add_argument("--model", metavar="SPEC.toml",
                   help="the twin's machine (default: the spec stored in the library), e.g. a "
                        "calibrated spec of the same machine")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (1)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler (tcp://host:8786), or local:N for a LocalCluster")
    p.add_argument("--limit", type=int, help="only the first N ok entries")
    p.add_argument("--iterations", type=int, default=150,
                   help="L-BFGS-B iterations per entry at most (150)")
    p.add_argument("--tail", type=float, default=0.5,
                   help="seconds the commands may act past the plan's end (0.5)")
    p.add_argument("--energy-weight", type=float, default=0.0, metavar="W",
                   help="weight of the twin's pump work in the refine cost, mm²·s per kJ "
                        "(0: tracking and landing only; energy entries: see planner/refine/__init__.py)")
    p.add_argument("--energy-entries", choices=("priced", "plain"), default="priced",
                   help="entries planned for least energy: 'priced' (default: their pump work "
                        "in the cost — weight --energy-weight, else 30 — and each joint kept "
                        "to the direction the plan moves it until the landing window; where "
                        "the twin then predicts it more than 4 mm from landed, it is refined "
                        "plain too and the commands nearer to landed kept; one that then "
                        "costs the twin more pump work than its own time entry is refined "
                        "again with the price x3, then x10, and the first that is cheaper "
                        "and lands as well kept, else it is named costlier) or 'plain' "
                        "(refined as time entries are)")
    p.add_argument("--time-entries", choices=("priced", "plain"), default="priced",
                   help="entries planned for least time: 'priced' (default: their pump work "
                        "in the cost too — weight --energy-weight, else 10 — so that landing "
                        "does not cost the pump more than it must) or 'plain' (tracking and "
                        "landing only)")
    p.add_argument("--swing-weight", type=float, metavar="W",
                   help="entries planned with a grapple (library build --grapple): the weight "
                        "of the load's swing after the plan's end, refined on the twin that "
                        "carries the load on its link (default 10: a swing costs a third of a "
                        "tip error of its size; 0: the tip alone)")
    p.add_argument("--cycle", metavar="ID,ID,...",
                   help="refine these entries as one work cycle, in this order: each from the "
                        "state (trapped pressures, residual motion) the one before leaves on "
                        "the twin; they must chain (see planner/library/cycle.py)")
    p.add_argument("--gap", type=float, metavar="S",
                   help="with --cycle: seconds with the valves closed between moves (3)")
    p.add_argument("--start", choices=("nominal", "refined"), default="nominal",
                   help="where each entry's search starts: 'nominal' (default: its nominal "
                        "commands) or 'refined' (its stored refined commands where it has "
                        "them, e.g. refined on the spec's twin before a calibration, when the "
                        "new twin prices them lower; with fewer --iterations a library is "
                        "refined again on a calibrated twin in a fraction of the time; an "
                        "entry the twin then predicts off is refined again from its nominal "
                        "commands, the better kept)")
    p.add_argument("--force", action="store_true",
                   help="refine entries already refined by the same twin again")
    add_json_arg(p)
    p.set_defaults(func=cmd_library_refine)
