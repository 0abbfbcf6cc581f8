"""``discrepancy CRANE --measured …``: measured vs simulated, the missing effect named, the
calibrated model written and the feed-forward re-planned on it."""
from __future__ import annotations

from typing import TYPE_CHECKING

import sys
import tomllib

from planner.cli.common import CLIError, add_json_arg, emit, read_trajectory

if TYPE_CHECKING:
    from planner.model import Crane


def read_recording(args, crane: Crane, plan):
    """``--measured``: the measured-data CSV, or a ROS 2 bag read through ``--map``
    (planner.simulation.bag; the rosbags library only then)."""
    from planner.simulation.recording import Recording
    from planner.simulation.bag import is_bag
    if args.map is None:
        if is_bag(args.measured):
            raise CLIError(f"--measured {args.measured}: a ROS 2 bag needs --map FILE.toml "
                           "(topics and fields -> channels; docs/rosbag.md)")
        from planner.calibration.rate import check_file
        check_file(args.measured)   # the memory it would take, before reading it
        return Recording.from_csv(args.measured, crane, plan)
    from planner.simulation.bag import read_bag_recording
    return read_bag_recording(args.measured, args.map, crane, plan)


def cmd_discrepancy(args):
    """Measured vs simulated -> named effect -> calibrated model (planner.calibration.discrepancy)."""
    # scipy: only when the command runs
    from planner.calibration.compensate import closed_loop
    from planner.calibration.discrepancy import Discrepancy, calibrated_spec_text
    from planner.calibration.report import write_report
    from planner.io import atomic_write_text
    from planner.model import Crane
    from planner.model.spec import parse_spec
    crane = Crane.from_id(args.crane)
    plan = read_trajectory(crane, args.trajectory) if args.trajectory else None
    rec = read_recording(args, crane, plan)
    if args.effects:
        names = [x.strip() for x in args.effects.split(",") if x.strip()]
    else:
        names = None
    res = Discrepancy(crane, candidates=names, threshold=args.threshold).fit(
        rec, progress=not (args.json == "-"))
    closed = None
    if plan is not None and res.effects:
        closed = closed_loop(crane, plan, res.effects)
    # everything computed: now write (nothing is written when anything above failed)
    if args.save_model:
        text = calibrated_spec_text(crane, res.effects, source=f"on {args.measured}")
        parse_spec(tomllib.loads(text), args.save_model, text)  # the written model must load
        atomic_write_text(args.save_model, text)
    if args.report:
        write_report(res, args.report, crane=crane, measured=args.measured, closed=closed)
    js = res.to_json()
    if res.verdict == "ambiguous" and args.json not in (None, "-"):
        # the design at the values the candidates were fitted to: this file is its input
        js["suggest_from"] = (f"crane-planner excite {args.crane} --from {args.json} "
                              "--max-duration 180 --out excitation.csv")
    if closed is not None:
        js["closed_loop"] = closed
    emit(args, js)
    for note in res.notes:
        print(f"crane-planner: {note}", file=sys.stderr)
    if args.json != "-":    # the terminal gets the verdict unless the JSON goes there
        print(f"verdict: {res.verdict}")
        print(res.message)
        for c in res.candidates:
            diff = c.get("differs_most") or []
            print(f"  candidate {c['effect']}" + (f" on {c['joint']}" if c["joint"] else "")
                  + f": score {c['score']:.1f}"
                  + (f"; predictions differ most on {diff[0]['joint']} {diff[0]['condition']} "
                     f"({diff[0]['channel']})" if diff else ""))
        if res.suggest:
            print(f"  to tell them apart, record the sequence of: {res.suggest}")
            print("  (or at the values they were fitted to: rerun with --json R.json, then "
                  f"crane-planner excite {args.crane} --from R.json --max-duration 180 …)")
        for sg in res.signature[:3]:
            print(f"  signature: {sg['kind']} on {sg['channel']} "
                  f"({sg['rms_over_noise']:.1f} x noise)")
        print(f"{'channel':12s} {'noise':>10s} {'RMS before':>11s} {'RMS after':>10s}")
        for c in res.rms_before:
            print(f"{c:12s} {res.noise[c]:10.4g} {res.rms_before[c]:11.4g} "
                  f"{res.rms_after[c]:10.4g}")
        if closed is not None:
            print(f"open-loop tip error (predicted): {1e3 * closed['before']['rms_m']:.1f} mm "
                  f"RMS with the nominal feed-forward -> {1e3 * closed['after']['rms_m']:.1f} "
                  "mm re-planned on the calibrated model")
    return 0


def add_parsers(sub) -> None:
    """``discrepancy``."""
    p = sub.add_parser("discrepancy", help="measured vs simulated: name the missing effect, "
                                           "calibrate, show the gap shrink")
    p.add_argument("crane", help="machine id or a TOML spec (e.g. a calibrated one)")
    p.add_argument("--measured", required=True, metavar="MEASURED.csv|BAG",
                   help="the measured-data CSV, or a ROS 2 bag (.mcap, .db3 or its folder) "
                        "with --map")
    p.add_argument("--map", metavar="MAP.toml",
                   help="bag topics and fields -> measured channels, with their units "
                        "(docs/rosbag.md; needs the ros extra)")
    p.add_argument("--trajectory", metavar="FILE.csv|FILE.h5#ID",
                   help="the commanded trajectory (re-planned on the calibrated model)")
    p.add_argument("--effects", metavar="NAME,…", help="only these catalogue effects")
    p.add_argument("--threshold", type=float, default=30.0,
                   help="least held-out score to name an effect (30)")
    p.add_argument("--report", metavar="DIR", help="markdown report, result.json, figures")
    p.add_argument("--save-model", metavar="FILE.toml",
                   help="the calibrated machine spec (spec + [[effects]])")
    add_json_arg(p)
    p.set_defaults(func=cmd_discrepancy)
