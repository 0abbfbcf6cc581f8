"""``discrepancy CRANE --measured …``: measured vs simulated, the missing effect named, the
calibrated model written and the feed-forward re-planned on it. ``--model twin`` asks the same
question of the dynamic twin (:mod:`planner.calibration.twin_diagnosis`); a quasi-static
``unexplained`` whose residual looks like the machine's dynamics says so and gives that
command (:func:`dynamic_signature`)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import sys
import tomllib

from planner.cli.common import CLIError, add_json_arg, emit, read_trajectory

if TYPE_CHECKING:
    from planner.model import Crane

MODELS = ("quasi-static", "twin")
#: [Hz] where a periodic pressure residual is read as a hydraulic mode (the oil against the
#: links: the slews' 0.7 Hz to the booms' few Hz on the machines here)
MODE_BAND_HZ = (0.3, 6.0)


def dynamic_signature(result) -> str | None:
    """A quasi-static ``unexplained`` verdict whose residual looks like the machine's
    dynamics — a periodic residual on a pressure channel within :data:`MODE_BAND_HZ` (a
    hydraulic mode), or a step on a pressure channel (trapped pressure after a hold) — in
    one line; else None."""
    if result.verdict != "unexplained":
        return None
    for s in result.signature:
        ch, f = s.get("channel", ""), s.get("frequency_hz")
        if not ch.startswith("p_"):
            continue
        if s.get("kind") == "periodic" and f and MODE_BAND_HZ[0] <= f <= MODE_BAND_HZ[1]:
            return f"a periodic residual at {f:.2f} Hz on {ch} (a hydraulic mode's band)"
        if s.get("kind") == "step":
            return f"a step on {ch} (trapped pressure the quasi-static model does not hold)"
    return None


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
    if args.model not in MODELS:
        raise CLIError(f"--model {args.model!r}: unknown; allowed: {', '.join(MODELS)}")
    twin = args.model == "twin"
    if twin and args.save_model:
        raise CLIError("--save-model with --model twin: not written (a twin diagnosis names "
                       "a twin parameter; calibrate the twin with crane-planner calibrate)")
    crane = Crane.from_id(args.crane)
    plan = read_trajectory(crane, args.trajectory) if args.trajectory else None
    rec = read_recording(args, crane, plan)
    if args.effects:
        names = [x.strip() for x in args.effects.split(",") if x.strip()]
    else:
        names = None
    if twin:
        from planner.calibration.twin_diagnosis import TwinDiagnosis
        res = TwinDiagnosis(crane, candidates=names, threshold=args.threshold).fit(
            rec, progress=not (args.json == "-"))
    else:
        res = Discrepancy(crane, candidates=names, threshold=args.threshold).fit(
            rec, progress=not (args.json == "-"))
        dyn = dynamic_signature(res)
        if dyn and crane.spec.dynamics is not None:
            cmd = (f"crane-planner discrepancy {args.crane} --measured {args.measured}"
                   + (f" --trajectory {args.trajectory}" if args.trajectory else "")
                   + " --model twin")
            res.notes.append(f"the residual looks like the machine's dynamics, which the "
                             f"quasi-static model lacks: {dyn}; ask the dynamic twin: {cmd}")
    closed = None
    if plan is not None and res.effects and not twin:
        closed = closed_loop(crane, plan, res.effects)
    # everything computed: now write (nothing is written when anything above failed)
    if args.save_model:
        text = calibrated_spec_text(crane, res.effects, source=f"on {args.measured}")
        parse_spec(tomllib.loads(text), args.save_model, text)  # the written model must load
        atomic_write_text(args.save_model, text)
    if args.report:
        write_report(res, args.report, crane=crane, measured=args.measured, closed=closed)
    js = res.to_json()
    js["model"] = args.model
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
    p.add_argument("--model", default="quasi-static", metavar="|".join(MODELS),
                   help="the diagnosing model: the fast quasi-static one (default) or the "
                        "dynamic twin (oil, hoses, spools, pump: names bulk_modulus, "
                        "hose_volume, spool_lag, ... too; needs the spec's [dynamics])")
    add_json_arg(p)
    p.set_defaults(func=cmd_discrepancy)
