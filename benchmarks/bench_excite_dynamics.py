"""Excitation for the twin's dynamics (issue 28, item 3): the designed sequence
(``excite MACHINE --for dynamics``) against the trials' plain excitation of the same length.

Per machine: the design (:func:`planner.calibration.excite_dynamics.design_dynamics`, the
default pool and parameters) with ``compare``: the D-criterion ln det(JᵀJ) of each (also per
recording of exactly ``--duration`` s: p·ln(T/T_actual) added, p parameters), each parameter's
predicted scaled standard deviation (Cramér–Rao, seed 001's sensor noise), the needed
duration (every sd ≤ UNIDENTIFIED), the parameters each leaves unidentified, both sequences
judged by ``evaluate`` (1 kHz, every limit kind), the design's runtime (the plain
excitation's scoring apart) and twin runs.

    python benchmarks/bench_excite_dynamics.py [--crane s100f] [--duration 120] [--seed 0]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from planner import Crane, evaluate  # noqa: E402
from planner.calibration.excite_dynamics import design_dynamics  # noqa: E402
from planner.calibration.trials import excitation  # noqa: E402
from planner.calibration.twin_fit import UNIDENTIFIED  # noqa: E402
from planner.io import atomic_write_text  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--crane", default="s100f")
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--candidates", type=int, default=2)
    ap.add_argument("--name", default="excite_dynamics")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args()
    cmd = "python benchmarks/bench_excite_dynamics.py " + " ".join(sys.argv[1:])
    crane = Crane.from_id(a.crane)
    w0 = time.perf_counter()
    d = design_dynamics(crane, a.duration, seed=a.seed, candidates=a.candidates,
                        compare=True, progress=lambda s: print(s, flush=True))
    wall = time.perf_counter() - w0
    plan0, _ = excitation(crane, a.duration, seed=a.seed)
    ev_d, ev_p = evaluate(crane, d.plan), evaluate(crane, plan0)
    p = len(d.sd)
    T, T0 = float(d.plan.duration), d.plain["duration_s"]
    norm = dict(design=d.logdet + p * np.log(a.duration / T),
                plain=d.plain["logdet"] + p * np.log(a.duration / T0))
    design_s = d.runtime_s - d.plain["runtime_s"]
    rep = dict(date=datetime.datetime.now().isoformat(timespec="seconds"), command=cmd,
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=os.getloadavg()),
               crane=a.crane, duration=a.duration, design=d.to_dict(),
               logdet_per_duration=norm, design_runtime_s=design_s, wall_s=wall,
               violations=dict(design=ev_d.violations, plain=ev_p.violations))
    out = Path(a.out)
    atomic_write_text(out / f"{a.name}.json", json.dumps(rep, indent=1, default=float))
    lines = [f"# Excitation for the twin's dynamics: designed vs plain ({a.crane}, "
             f"{a.duration:g} s)", "",
             f"{rep['date']}, {platform.platform()}, {os.cpu_count()} CPUs, load "
             f"{os.getloadavg()[0]:.1f} at the end (the machine shared with other sessions). "
             f"`{cmd}` ({wall / 60:.1f} min in all). The design: `crane-planner excite "
             f"{a.crane} --for dynamics --duration {a.duration:g} --seed {a.seed} --compare "
             f"--out exc.csv`. Criterion: the twin's Fisher information at the spec's values, "
             f"JᵀJ of the calibration's own noise-scaled residuals (segments at holds; seed "
             f"001's sensor noise), J by central differences (step 0.01 in the scaled "
             f"parameters); sd = sqrt(diag((JᵀJ)⁻¹)) in twin_params' scaled units "
             f"(a log-scaled parameter: sd 0.1 ≈ ±10 %); identified: sd ≤ {UNIDENTIFIED:g}.",
             "",
             "| measure | designed | plain excitation (trials, seed "
             f"{a.seed}) |", "| --- | ---: | ---: |",
             f"| length [s] | {T:.1f} | {T0:.1f} |",
             f"| ln det(JᵀJ), {p} parameters | {d.logdet:.1f} | {d.plain['logdet']:.1f} |",
             f"| ln det per recording of {a.duration:g} s | **{norm['design']:.1f}** | "
             f"{norm['plain']:.1f} |",
             f"| ln det predicted from the blocks alone | {d.predicted_logdet:.1f} | – |",
             f"| needed duration (every sd ≤ {UNIDENTIFIED:g}) | "
             f"{_s(d.needed_s)} | {_s(d.plain['needed_duration_s'])} |",
             f"| parameters unidentified at its length | {len(d.unidentified)} | "
             f"{len(d.plain['unidentified'])} |",
             f"| largest relative limit excess (evaluate, 1 kHz) | "
             f"{max(ev_d.violations.values()):.2g} | {max(ev_p.violations.values()):.2g} "
             f"({max(ev_p.violations, key=ev_p.violations.get)}) |",
             f"| runtime [s] | {design_s:.0f} (pool {len(d.pool)} blocks + the sequence) | "
             f"{d.plain['runtime_s']:.0f} (scoring) |", "",
             f"Blocks chosen, in order: {', '.join(d.order)}.", "",
             "| parameter | sd designed | sd plain | ratio |", "| --- | ---: | ---: | ---: |"]
    for k, v in d.sd.items():
        v0 = d.plain["sd_scaled"][k]
        lines.append(f"| {k} | {v:.3g} | {v0:.3g} | {v / v0:.2f} |")
    if d.unidentified or d.plain["unidentified"]:
        lines += ["", "Unidentified at the sequence's length:"]
        for who, u in (("designed", d.unidentified), ("plain", d.plain["unidentified"])):
            for k, why in u.items():
                lines.append(f"- {who}: {k}: {why}")
    lines += ["", "| block | length [s] | ln det alone | chosen |", "| --- | ---: | ---: | ---: |"]
    for k, b in d.pool.items():
        lines.append(f"| {k} | {b['duration_s']:.1f} | {b['logdet_alone']:.1f} | "
                     f"{b['chosen']} |")
    atomic_write_text(out / f"{a.name}.md", "\n".join(lines) + "\n")
    print("\n".join(lines))


def _s(x):
    return "beyond 600 s" if x is None else f"{x:.0f} s"


if __name__ == "__main__":
    main()
