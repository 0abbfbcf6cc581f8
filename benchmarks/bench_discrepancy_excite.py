"""Do designed excitations resolve ambiguous pairs? (issue 14, item 4)

The population the acceptance is about is the trials where the *default* excitation was
ambiguous, so the default here is made to be weak, as the issue's confusions were: a short,
slow, small test sequence (:func:`planner.calibration.trials.excitation` with poses in the
middle ``1 − 2·margin`` of every joint range, speed fractions ``--speed`` and no full-speed
first move) and the hidden effect at a factor of its trial magnitude drawn log-uniformly in
``--magnitude LO HI`` (weak effects are where names tie). For each pair the
issue found confused (viscous vs Coulomb friction, payload vs telescope actuator mass,
pressure offset vs actuator mass) and sensor_gain vs flow_gain, on several machines and
seeds, one effect of the pair is hidden in the plant (the first for even seeds, the second for
odd ones), the default sequence is recorded and fitted. Where the verdict is ``ambiguous``,
the command the verdict suggests is followed: its ``--separate`` list (the candidates at
trial magnitudes drawn from the seed, as ``crane-planner excite`` does) is designed for by
:func:`planner.calibration.excite.design_excitation` (optimised: random starts, then
Nelder–Mead), the design recorded on the same plant with fresh noise and fitted again: right
name or not. Where the default names the wrong effect, the pair (truth, named) is designed
for the same way and counted apart. The judge is the fast plant (the recordings are made with
it): nothing here speaks for unmodelled dynamics.

    python benchmarks/bench_discrepancy_excite.py [--seeds 2] [--workers 2] [--budget 12]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

PAIRS = (("cat215b", "viscous_friction", "coulomb_friction", "swing"),
         ("s100f", "viscous_friction", "coulomb_friction", "boom"),
         ("umea-lab", "coulomb_friction", "viscous_friction", "jib"),
         ("cranab850", "viscous_friction", "coulomb_friction", "slew"),
         ("umea-lab", "payload_mass", "actuator_mass", "tele"),
         ("s100f", "payload_mass", "actuator_mass", "tele"),
         ("cranab850", "actuator_mass", "payload_mass", "tele"),
         ("cat215b", "actuator_mass", "pressure_offset", "stick"),
         ("s100f", "pressure_offset", "actuator_mass", "jib"),
         ("cat215b", "sensor_gain", "flow_gain", "boom"))


def weak_default(crane, seed, duration, speed):
    """The short, slow, small default sequence (module doc)."""
    from planner.calibration.trials import excitation
    return excitation(crane, duration, seed=seed, margin=0.35, speed=speed, first_full=False)


def scaled(crane, e, f):
    """Effect ``e`` with its departure from the neutral values × ``f``."""
    v0 = e.neutral_vector(crane)
    return e.with_vector(v0 + f * (np.asarray(e.vector(), float) - v0))


def trial(machine, first, second, joint, seed, args):
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from planner import Crane, evaluate
    from planner.calibration.discrepancy import Discrepancy
    from planner.calibration.excite import (candidates_from_result, design_excitation,
                                            lengthen, parse_candidates)
    from planner.calibration.trials import TrialSequence, draw, record
    from planner.model.effects import CATALOGUE
    crane = Crane.from_id(machine)
    hidden, other = (first, second) if seed % 2 == 0 else (second, first)
    j = joint if CATALOGUE[hidden].per_joint else None
    plan, ff = weak_default(crane, seed, args.default_duration, tuple(args.speed))
    rng = np.random.default_rng(seed + 7919)
    truth = draw(crane, hidden, rng, j, TrialSequence(crane, plan, ff))
    factor = float(np.exp(rng.uniform(*np.log(args.magnitude))))
    truth = scaled(crane, truth, factor)
    res = Discrepancy(crane).fit(record(crane, plan, ff, (truth,), seed=seed))
    key = (truth.name, truth.joint)
    named_right = res.verdict == "named" and (res.effect, res.joint) == key
    out = dict(machine=machine, hidden=hidden, other=other, joint=joint, seed=seed,
               truth=truth.to_dict(), factor=factor, default_verdict=res.verdict, default_named=res.effect,
               default_joint=res.joint, default_right=bool(named_right),
               default_candidates=[(c["effect"], c["joint"]) for c in res.candidates],
               suggest=res.suggest, default_s=res.runtime_s)
    if res.verdict == "ambiguous":
        sep = res.suggest.split("--separate ")[1].split()[0]
        out["group"] = "ambiguous"
    elif res.verdict == "named" and not named_right:
        sep = ",".join(f"{n}@{jj}" if jj else n for n, jj in (key, (res.effect, res.joint)))
        out["group"] = "wrong"
    else:
        out["group"] = "right" if named_right else res.verdict
        return out
    if args.fitted and res.verdict == "ambiguous":   # `excite --from result.json`
        cand = candidates_from_result(crane, res.to_json())
    else:                                            # `excite --separate …`
        cand = parse_candidates(crane, sep, seed=seed)
    d = design_excitation(crane, cand, duration=args.duration, candidates=args.starts,
                          budget=args.budget, seed=seed)
    need = [u["duration_needed_s"] for u in d.unseparated]
    lengthened = None
    if need and all(need) and max(need) <= args.max_duration and d.source != "random":
        lengthened = max(need)                          # `excite --max-duration`
        d = lengthen(crane, d, lengthened)
    ev = evaluate(crane, d.plan)
    res2 = Discrepancy(crane).fit(record(crane, d.plan, d.ff, (truth,), seed=seed + 1))
    out.update(separate=sep, design_source=d.source, separation=d.separation,
               lengthened_to=lengthened, design_duration=float(d.plan.duration),
               default_separation=d.default_separation, evaluations=d.evaluations,
               design_s=d.runtime_s, design_limits_ok=bool(ev.ok()),
               design_max_violation=float(ev.max_limit_violation),
               unseparated=d.unseparated, designed_verdict=res2.verdict,
               designed_named=res2.effect, designed_joint=res2.joint,
               designed_candidates=[(c["effect"], c["joint"]) for c in res2.candidates],
               designed_right=bool(res2.verdict == "named" and (res2.effect, res2.joint)
                                   == key))
    return out


def report(rows, args, wall):
    amb = [r for r in rows if r["group"] == "ambiguous"]
    wrong = [r for r in rows if r["group"] == "wrong"]

    def n(rs, k):
        return sum(bool(r.get(k)) for r in rs)

    def pct(a, b):
        return f"{a} of {b} ({100.0 * a / b:.0f} %)" if b else "0 of 0"
    L = ["# Discrepancy workflow: designed excitations on confusable pairs", "",
         f"{datetime.datetime.now().isoformat(timespec='seconds')}, {platform.platform()}, "
         f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f} at the end. `python "
         f"benchmarks/bench_discrepancy_excite.py --seeds {args.seeds} --seed-base "
         f"{args.seed_base}{' --pairs ' + args.pairs if args.pairs else ''} --magnitude "
         f"{args.magnitude[0]:g} {args.magnitude[1]:g} --workers {args.workers} "
         f"--default-duration {args.default_duration:g} --speed "
         f"{args.speed[0]:g} {args.speed[1]:g} --duration {args.duration:g} --starts "
         f"{args.starts} --budget {args.budget}{' --fitted' if args.fitted else ''}"
         f"{f' --max-duration {args.max_duration:g}' if args.max_duration else ''}` "
         f"({len(rows)} trials, {wall / 60:.1f} min). "
         f"Default: a {args.default_duration:g} s sequence of small moves (poses in the middle "
         f"30 % of every range, {args.speed[0]:g}–{args.speed[1]:g} of the speed limits), the "
         f"hidden effect at {args.magnitude[0]:g}–{args.magnitude[1]:g} × its trial magnitude "
         "(log-uniform). Designs: "
         f"{args.duration:g} s, {args.starts} random starts + Nelder–Mead for {args.budget} "
         "evaluations; the candidates are the ambiguous verdict's "
         + ("candidates at the values they were fitted to (`excite --from result.json`). "
            if args.fitted else "`--separate` list at trial magnitudes. ") + "Judge: "
         "the fast plant (recordings made with it), seed 001's sensor noise.", "",
         "| measure | result | target |", "| --- | ---: | ---: |",
         f"| default sequence: named right | {pct(n(rows, 'default_right'), len(rows))} | |",
         f"| default sequence: ambiguous | {pct(len(amb), len(rows))} | |",
         f"| default sequence: named wrong | {pct(len(wrong), len(rows))} | |",
         f"| default sequence: other (explained / unexplained) | "
         f"{pct(len(rows) - len(amb) - len(wrong) - n(rows, 'default_right'), len(rows))} | |",
         f"| **designed sequence: named right, of the default-ambiguous** | "
         f"{pct(n(amb, 'designed_right'), len(amb))} | ≥ 90 % |",
         f"| designed sequence: still ambiguous with the truth among the candidates, of "
         f"those | {pct(sum(r.get('designed_verdict') == 'ambiguous' for r in amb), len(amb))}"
         " | |",
         f"| designed sequence: named right, of the default-wrong | "
         f"{pct(n(wrong, 'designed_right'), len(wrong))} | |",
         f"| designs within every limit (evaluate, 1 kHz resampling) | "
         f"{pct(n(amb + wrong, 'design_limits_ok'), len(amb + wrong))} | all |"]
    if amb + wrong:
        ts = sorted(r["design_s"] for r in amb + wrong)
        L.append(f"| design runtime (median, max) | {ts[len(ts) // 2]:.0f} s, {ts[-1]:.0f} s | |")
    L += ["", "| machine | hidden | other | seed | default | designed | separation default → "
          "designed (σ²) | design |", "| --- | --- | --- | ---: | --- | --- | --- | --- |"]
    for r in rows:
        dflt = f"{r['default_verdict']} {r['default_named'] or ''}"
        if r["default_verdict"] == "ambiguous":
            dflt += " (" + ", ".join(c[0] for c in r["default_candidates"]) + ")"
        if "designed_verdict" in r:
            des = f"{r['designed_verdict']} {r['designed_named'] or ''}"
            if r["designed_verdict"] == "ambiguous":
                des += " (" + ", ".join(c[0] for c in r["designed_candidates"]) + ")"
            sepn = f"{r['default_separation']:.0f} → {r['separation']:.0f}"
            dsg = (f"{r['design_source']}, {r['evaluations']} eval., {r['design_s']:.0f} s"
                   + (f", run {r['lengthened_to']:.0f} s" if r.get("lengthened_to") else ""))
        else:
            des, sepn, dsg = "–", "–", "–"
        L.append(f"| {r['machine']} | {r['hidden']}{'@' + r['joint'] if r['truth'].get('joint') else ''}"
                 f" ×{r['factor']:.2f} | {r['other']} | {r['seed']} | {dflt} | {des} | {sepn} | "
                 f"{dsg} |")
    uns = [(r, u) for r in rows for u in r.get("unseparated", [])]
    if uns:
        L += ["", "## Pairs the best design found still does not separate", ""]
        L += [f"- {r['machine']} seed {r['seed']}: {u['why']}" for r, u in uns]
    return "\n".join(L) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--magnitude", type=float, nargs=2, default=(0.2, 1.0),
                    help="hidden effect: × its trial magnitude, drawn in LO HI (0.2 1)")
    ap.add_argument("--default-duration", type=float, default=15.0)
    ap.add_argument("--speed", type=float, nargs=2, default=(0.15, 0.35))
    ap.add_argument("--duration", type=float, default=20.0, help="designed sequence [s]")
    ap.add_argument("--starts", type=int, default=2)
    ap.add_argument("--budget", type=int, default=12)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed-base", type=int, default=600)
    ap.add_argument("--max-duration", type=float, default=0.0,
                    help="lengthen a design whose pairs need it up to this many s (0: never)")
    ap.add_argument("--fitted", action="store_true",
                    help="design for the ambiguous result's candidates at their fitted values "
                         "(excite --from RESULT.json) instead of at trial magnitudes")
    ap.add_argument("--pairs", default=None,
                    help="comma-separated indices into PAIRS (default: all)")
    ap.add_argument("--name", default="discrepancy_excite", help="results file name")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    from planner.io import atomic_write_text
    t0 = time.perf_counter()
    rows = []
    out = Path(args.out)
    with ProcessPoolExecutor(args.workers) as ex:
        pick = [int(x) for x in args.pairs.split(",")] if args.pairs else range(len(PAIRS))
        futs = [ex.submit(trial, *PAIRS[k], args.seed_base + 10 * k + s, args)
                for k in pick for s in range(args.seeds)]
        for i, f in enumerate(as_completed(futs)):
            r = f.result()
            rows.append(r)
            print(f"[{i + 1}/{len(futs)}] {r['machine']} {r['hidden']} (vs {r['other']}) seed "
                  f"{r['seed']}: default {r['default_verdict']} {r['default_named']}"
                  + (f" -> designed {r['designed_verdict']} {r['designed_named']} "
                     f"({r['design_s']:.0f} s)" if 'designed_verdict' in r else ""),
                  file=sys.stderr)
            rows.sort(key=lambda r: (r["machine"], r["hidden"], r["seed"]))
            atomic_write_text(out / f"{args.name}.md",
                              report(rows, args, time.perf_counter() - t0))
            atomic_write_text(out / f"{args.name}.json",
                              json.dumps(rows, indent=1, default=float))
    print((out / f"{args.name}.md").read_text())


if __name__ == "__main__":
    main()
