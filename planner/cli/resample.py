"""``resample MEASURED.csv --rate HZ --out FILE``: a logger's recording (any strictly
increasing time, jitter or a different rate) onto the fixed sample rate the discrepancy
workflow reads (commands held, readings interpolated linearly).

Interpolated readings mix neighbouring measurements, so their own noise looks smaller than the
sensor's (about 8 % for ±10 % jitter, more for a change of rate). For a diagnosis, give
``discrepancy`` the logged file itself when only jitter is the problem: it resamples on
reading and estimates the noise on the samples as logged."""
from __future__ import annotations

import math

from planner.cli.common import add_json_arg, emit


def cmd_resample(args):
    """Read every column the contract knows (joint names from the header), resample, write."""
    import numpy as np

    from planner.io import atomic_write_text
    from planner.simulation.recording import read_measured_csv, resample_arrays
    if not (math.isfinite(args.rate) and 1.0 <= args.rate <= 10000.0):
        raise ValueError(f"--rate {args.rate:g}: allowed 1 ... 10000 Hz (loggers: 20-500 Hz)")
    with open(args.measured, encoding="utf-8-sig") as fh:
        header = [c.strip() for c in fh.readline().split(",")]
    joints = [c[2:] for c in header if c.startswith("q_")]
    if not joints:
        raise ValueError(f"{args.measured}: line 1: no q_<joint> columns; expected the "
                         "measured-data CSV (t, u_<joint>, q_<joint>, p_<joint>_a/b)")
    d = read_measured_csv(args.measured, joints, uniform=False)
    t, (u, q, pa, pb) = resample_arrays(d["t"], (d["u"], d["q"], d["p_a"], d["p_b"]),
                                        args.rate)
    cols, blocks = ["t"], [t[:, None]]
    if u is not None:
        cols += [f"u_{j}" for j in joints]
        blocks.append(u)
    cols += [f"q_{j}" for j in joints]
    blocks.append(q)
    if pa is not None:
        P = np.empty((len(t), 2 * len(joints)))
        P[:, 0::2], P[:, 1::2] = pa, pb
        cols += [f"p_{j}_{s}" for j in joints for s in ("a", "b")]
        blocks.append(P)
    M = np.hstack(blocks)
    dt = np.diff(d["t"])
    atomic_write_text(args.out, "\n".join([",".join(cols)] + [",".join(f"{v:.10g}" for v in r)
                                                             for r in M]) + "\n")
    info = dict(status="ok", out=args.out, rate_hz=float(args.rate), samples_in=len(d["t"]),
                samples_out=len(t), rate_in_hz=float(1.0 / np.mean(dt)),
                step_in_min_s=float(dt.min()), step_in_max_s=float(dt.max()),
                note="readings interpolated: their noise looks smaller than the sensor's; "
                     "for a diagnosis of a jittered log, give discrepancy the logged file")
    emit(args, info)
    if not args.json:
        print(f"{args.measured}: {info['samples_in']} samples at {info['rate_in_hz']:.4g} Hz "
              f"mean (steps {info['step_in_min_s']:.4g}...{info['step_in_max_s']:.4g} s) -> "
              f"{args.out}: {len(t)} samples at {args.rate:g} Hz\n{info['note']}")
    return 0


def add_parsers(sub) -> None:
    """``resample``."""
    p = sub.add_parser("resample", help="a logger's recording onto a fixed sample rate")
    p.add_argument("measured", metavar="MEASURED.csv")
    p.add_argument("--rate", type=float, required=True, metavar="HZ")
    p.add_argument("--out", required=True, metavar="FILE.csv")
    add_json_arg(p)
    p.set_defaults(func=cmd_resample)
