"""Do designed excitations resolve ambiguous pairs? (issue 14, item 4)

For the pairs the issue found confused (viscous vs Coulomb friction, payload vs actuator mass,
pressure offset vs actuator mass) and the new sensor_gain vs flow_gain: one effect of the pair
is hidden in the plant at a realistic magnitude, a short default test sequence is recorded
and fitted. Where the verdict is ``ambiguous`` (or names the wrong one of the pair), a test
sequence is designed to separate the pair (:func:`planner.calibration.excite.
design_excitation`, the candidates at the values the ambiguous fit found), recorded on the
same plant with fresh noise and fitted again: right name or not.

    python benchmarks/bench_discrepancy_excite.py [--seeds 3] [--duration 20] [--workers 2]
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

PAIRS = (("cat215b", "viscous_friction", "coulomb_friction", "swing"),
         ("cat215b", "coulomb_friction", "viscous_friction", "boom"),
         ("umea-lab", "payload_mass", "actuator_mass", "tele"),
         ("cat215b", "actuator_mass", "pressure_offset", "stick"),
         ("cat215b", "sensor_gain", "flow_gain", "boom"))


def trial(machine, hidden, other, joint, seed, duration, candidates):
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import numpy as np
    from planner import Crane
    from planner.calibration.discrepancy import Discrepancy
    from planner.calibration.excite import design_excitation
    from planner.calibration.trials import hidden_trial, record
    from planner.model.effects import CATALOGUE
    crane = Crane.from_id(machine)
    j = joint if CATALOGUE[hidden].per_joint else None
    rec, _, _, truth = hidden_trial(crane, hidden, seed, duration, joint=j)
    res = Discrepancy(crane).fit(rec)
    right = (res.effect, res.joint) == (truth.name, truth.joint)
    out = dict(machine=machine, hidden=hidden, other=other, joint=joint, seed=seed,
               truth=truth.to_dict(), default_verdict=res.verdict, default_named=res.effect,
               default_right=bool(right and res.verdict == "named"))
    if res.verdict == "named" and right:
        return out
    # the candidates at realistic values: the truth's class and the other one, as fitted
    rng = np.random.default_rng(seed)
    cls_o = CATALOGUE[other]
    cand = (truth, cls_o.trial(crane, rng, joint if cls_o.per_joint else None))
    t0 = time.perf_counter()
    d = design_excitation(crane, cand, duration=duration, candidates=candidates, seed=seed)
    rec2 = record(crane, d.plan, d.ff, (truth,), seed=seed + 1)
    res2 = Discrepancy(crane).fit(rec2)
    out.update(design_seed=d.seed, separation=d.separation,
               default_separation=d.default_separation, design_s=time.perf_counter() - t0,
               designed_verdict=res2.verdict, designed_named=res2.effect,
               designed_right=bool(res2.verdict == "named" and (res2.effect, res2.joint)
                                   == (truth.name, truth.joint)))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--candidates", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    from planner.io import atomic_write_text
    t0 = time.perf_counter()
    rows = []
    with ProcessPoolExecutor(args.workers) as ex:
        futs = [ex.submit(trial, m, h, o, j, 600 + 10 * k + s, args.duration, args.candidates)
                for k, (m, h, o, j) in enumerate(PAIRS) for s in range(args.seeds)]
        for f in as_completed(futs):
            r = f.result()
            rows.append(r)
            print(f"{r['machine']} {r['hidden']}/{r['other']} seed {r['seed']}: default "
                  f"{r['default_verdict']} {r['default_named']}"
                  + (f" -> designed {r['designed_verdict']} {r['designed_named']}"
                     if 'designed_verdict' in r else ""), file=sys.stderr)
    rows.sort(key=lambda r: (r["machine"], r["hidden"], r["seed"]))
    wall = time.perf_counter() - t0
    amb = [r for r in rows if "designed_verdict" in r]
    L = ["# Discrepancy workflow: designed excitations on confusable pairs", "",
         f"{datetime.datetime.now().isoformat(timespec='seconds')}, {platform.platform()}, "
         f"{os.cpu_count()} CPUs. `python benchmarks/bench_discrepancy_excite.py --seeds "
         f"{args.seeds} --duration {args.duration:g} --candidates {args.candidates}` "
         f"({len(rows)} trials, {wall / 60:.1f} min). Recordings of {args.duration:g} s on the "
         "fast plant with seed 001's noise.", "",
         "| measure | result | target |", "| --- | ---: | ---: |",
         f"| default sequence: named right | {sum(r['default_right'] for r in rows)} of "
         f"{len(rows)} | |",
         f"| default sequence: ambiguous or wrong (a design was made) | {len(amb)} of "
         f"{len(rows)} | |",
         f"| designed sequence: named right, of those | "
         f"{sum(r['designed_right'] for r in amb)} of {len(amb)} | ≥ 90 % |", "",
         "| machine | hidden | other | seed | default | designed | separation default → "
         "designed (σ²) |", "| --- | --- | --- | ---: | --- | --- | --- |"]
    for r in rows:
        L.append(f"| {r['machine']} | {r['hidden']} | {r['other']} | {r['seed']} | "
                 f"{r['default_verdict']} {r['default_named'] or ''} | "
                 + (f"{r['designed_verdict']} {r['designed_named'] or ''} | "
                    f"{r['default_separation']:.0f} → {r['separation']:.0f} |"
                    if "designed_verdict" in r else "– | – |"))
    out = Path(args.out)
    atomic_write_text(out / "discrepancy_excite.md", "\n".join(L) + "\n")
    atomic_write_text(out / "discrepancy_excite.json", json.dumps(rows, indent=1, default=float))
    print("\n".join(L))


if __name__ == "__main__":
    main()
