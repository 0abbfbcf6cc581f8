"""A task suite of random point-to-point moves for any machine (issue 27: "the same table for
the other three machines"): start and goal tips from joint configurations drawn uniformly
inside ``margin`` of every joint's range (seeded), written as a suite file that ``library
build --tasks FILE`` reads (planner/tasks/suites.py). No headboard: the machines other than
the s100f forwarder have no load space in their specs.

    python benchmarks/random_suite.py CRANE --moves 48 [--seed 0] [--margin 0.1] --out FILE
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from planner.io import atomic_write_text  # noqa: E402
from planner.model import Crane  # noqa: E402


def suite_text(crane_id: str, moves: int, seed: int, margin: float) -> str:
    crane = Crane.from_id(crane_id)
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    span = L["q_max"] - L["q_min"]
    lo, hi = L["q_min"] + margin * span, L["q_max"] - margin * span
    qs = lo + rng.random((2 * moves, crane.n)) * (hi - lo)
    tips = [np.round(crane.tip(q), 3) for q in qs]
    out = ["# Random point-to-point moves (benchmarks/random_suite.py): start and goal tips from",
           f"# joint configurations drawn uniformly inside {margin:g} of each joint's range,",
           f"# seed {seed}. Tip coordinates (r, z, slew [rad]) in the crane's frame 0.", "",
           "[suite]", f'id = "random-{crane_id}-{seed}"', f'crane = "{crane_id}"',
           f'description = "{moves} random moves inside {margin:g} margins (seed {seed})"',
           'source = "assumed: random joint configurations (no seed gives a work cycle for '
           'this machine)"', ""]
    for k in range(moves):
        a, b = tips[k], tips[moves + k]
        out += ["[[moves]]", f'id = "r{k:02d}"',
                f"start = [{a[0]:.3f}, {a[1]:.3f}, {a[2]:.3f}]",
                f"goal = [{b[0]:.3f}, {b[1]:.3f}, {b[2]:.3f}]", ""]
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("crane")
    ap.add_argument("--moves", type=int, default=48)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--margin", type=float, default=0.1)
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    atomic_write_text(Path(a.out), suite_text(a.crane, a.moves, a.seed, a.margin))


if __name__ == "__main__":
    main()
