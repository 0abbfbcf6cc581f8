"""Seed 003's paths with the path-constrained NLP (umea-lab): the tip on the circle / the
parabola, the telescope free, rest to rest, every limit (velocity, acceleration, jerk, pump).
Compare with benchmarks/results/seed003_paths.md (phase-plane profile, TOPP-RA on the
optimised-telescope path).

    python benchmarks/seed003_nlp.py [--out benchmarks/results]
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import platform
from pathlib import Path

from planner import Crane
from planner.io import atomic_write_text
from planner.methods.nlp import MoveNLP
from planner.geometry.paths import circle, parabola
from planner.trajectory import evaluate


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    crane = Crane.from_id("umea-lab")
    cases = {
        "circle (full, θ ∈ [−π, π])": circle((3.0, 0.0, 2.5), 0.7, -math.pi, math.pi),
        "half circle (θ ∈ [−π/2, π/2])": circle((3.0, 0.0, 2.5), 0.7, -math.pi / 2, math.pi / 2),
        "parabola (α = −45°, see seed003_paths.md)": parabola(1.6, 3.07, 1.5, 3.0, -math.pi / 4),
    }
    rows = []
    for name, cv in cases.items():
        for N in (60,):
            r = MoveNLP(crane, "time", cv, N=N).solve()
            row = dict(path=name, N=N, status=r.status, reason=r.reason,
                       solve_s=r.solve_time_s, iterations=r.iterations)
            if r.ok:
                ev = evaluate(crane, r.trajectory)
                row.update(duration_s=r.duration_s, max_limit_violation=ev.max_limit_violation,
                           checked=list(ev.checked), energy_J=ev.energy_J)
            rows.append(row)
            print(row)
    md = ["# Seed 003 paths with the path-constrained NLP (umea-lab)", "",
          f"{datetime.datetime.now().isoformat(timespec='seconds')}, {platform.platform()}. "
          "Tip on the path at every node (path parameter per node, monotone), telescope free, "
          "rest to rest, limits: position, velocity, acceleration, jerk, pump flow.", "",
          "| path | N | status | duration [s] | max limit violation | solve [s] |",
          "| --- | ---: | --- | ---: | ---: | ---: |"]
    for r in rows:
        md.append(f"| {r['path']} | {r['N']} | {r['status']} | "
                  f"{r.get('duration_s', float('nan')):.3f} | "
                  f"{100 * r.get('max_limit_violation', float('nan')):.4f} % | {r['solve_s']:.2f} |")
    md += ["", "For comparison (seed003_paths.md, same machine): TOPP-RA rest to rest on the "
           "phase-plane-optimised telescope path takes 4.176 s with velocity limits only and "
           "5.444 s with velocity + acceleration on the full circle; on the parabola 4.611 s and "
           "5.048 s. The NLP also honours jerk and the pump and chooses the telescope itself. "
           "The parabola's goal is reachable only with the telescope at its 1.55 m limit "
           "(workspace edge); at N = 40 IPOPT did not converge there (max_iter), at N = 60 it "
           "did."]
    out = Path(args.out)
    atomic_write_text(out / "seed003_nlp.json", json.dumps(rows, indent=2) + "\n")
    atomic_write_text(out / "seed003_nlp.md", "\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
