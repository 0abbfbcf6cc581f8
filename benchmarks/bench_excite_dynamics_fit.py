"""The independent check of ``excite --for dynamics`` (issue 28, item 3): hidden parameters of
the twin recovered by the calibration (:class:`planner.calibration.twin_fit.TwinFit`, its own
Jacobian and noise estimate) from a twin log of the designed sequence and from one of the
trials' plain excitation of the same length, seed 001's sensor noise.

Per case (machine, the parameters designed for and fitted, their hidden factors): the design
for exactly those parameters (no random blocks), the plain excitation of seed ``--seed``, each
fitted with 6 iterations; reported: the predicted sd (design, plain), the fitted factor and
its 95 % interval, |ln(fitted/true)|, the misfit at the fit's end and at the truth (pressures,
RMS in noise units: a fit that ends above the truth's misfit stopped in a local minimum).

    python benchmarks/bench_excite_dynamics_fit.py [--seed 2] [--duration 20]
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
from planner import Crane  # noqa: E402
from planner.calibration.excite_dynamics import design_dynamics  # noqa: E402
from planner.calibration.trials import excitation  # noqa: E402
from planner.calibration.twin_fit import TwinFit  # noqa: E402
from planner.calibration.twin_params import machine_of  # noqa: E402
from planner.io import atomic_write_text  # noqa: E402
from planner.model.twin import Twin  # noqa: E402
from planner.simulation.recording import Recording  # noqa: E402

CASES = (("umea-lab", {"bulk_modulus": 0.8}),
         ("umea-lab", {"bulk_modulus": 0.8, "hose_a.boom": 0.7}))


def fit(crane, plan, ff, truth, seed):
    dyn, db = machine_of(crane, truth)
    run = Twin(crane, dynamics=dyn, deadband=db).simulate(ff.t, ff.u, plan.q[0],
                                                          t_end=ff.t[-1])
    q, pa, pb, u = run.sample(ff.t)
    rec = Recording(ff.t, u, q, pa, pb).with_noise(crane, True, seed=seed)
    f = TwinFit(crane, [rec], parameters=list(truth))
    res = f.solve(max_iterations=6)
    f.smooth = 0.0
    at_truth = f.rms(np.array([p.to_z(truth[p.name]) for p in f.params]))
    return res, at_truth


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--noise-seed", type=int, default=1)
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--name", default="excite_dynamics_fit")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args()
    cmd = "python benchmarks/bench_excite_dynamics_fit.py " + " ".join(sys.argv[1:])
    w0 = time.perf_counter()
    rows, lines = [], []
    for cid, factors in CASES:
        crane = Crane.from_id(cid)
        nominal = {p: _nominal(crane, p) for p in factors}
        truth = {p: f * nominal[p] for p, f in factors.items()}
        d = design_dynamics(crane, a.duration, seed=a.seed, candidates=0,
                            parameters=list(truth), compare=True)
        p0, f0 = excitation(crane, a.duration, seed=a.seed)
        for label, plan, ff, sd in (("designed", d.plan, d.ff, d.sd),
                                    ("plain", p0, f0, d.plain["sd_scaled"])):
            res, at_truth = fit(crane, plan, ff, truth, a.noise_seed)
            for k in truth:
                lo, hi = res.interval[k]
                row = dict(machine=cid, hidden=_label(factors), sequence=label,
                           length_s=float(plan.duration), parameter=k, sd_predicted=sd[k],
                           fitted_factor=res.values[k] / nominal[k],
                           interval_factor=(lo / nominal[k], hi / nominal[k]),
                           error=abs(float(np.log(res.values[k] / truth[k]))),
                           truth_inside=bool(lo <= truth[k] <= hi),
                           rms_fit=res.rms_after["pressures"],
                           rms_truth=at_truth["pressures"], runtime_s=res.runtime_s)
                rows.append(row)
                print(row, flush=True)
    wall = time.perf_counter() - w0
    out = Path(a.out)
    atomic_write_text(out / f"{a.name}.json", json.dumps(dict(
        date=datetime.datetime.now().isoformat(timespec="seconds"), command=cmd,
        machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                     load=os.getloadavg()), rows=rows), indent=1, default=float))
    lines = [f"# Excitation for the twin's dynamics: hidden parameters recovered by the "
             "calibration, designed vs plain", "",
             f"{datetime.datetime.now().isoformat(timespec='seconds')}, {platform.platform()}, "
             f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f} at the end. `{cmd}` "
             f"({wall / 60:.1f} min). Twin logs (the twin with the hidden factors, seed 001's "
             f"noise, noise seed {a.noise_seed}) of the design for exactly the fitted "
             f"parameters (no random blocks, pool seed {a.seed}) and of the trials' plain "
             f"excitation (seed {a.seed}), {a.duration:g} s each; `TwinFit(...).solve(6)` as "
             "`calibrate --parameters …` runs it. rms: pressures, noise units, at the fit's "
             "end and at the truth (a fit ending above the truth's misfit stopped in a local "
             "minimum).", "",
             "| hidden | sequence | length [s] | parameter | sd predicted | fitted × spec | "
             "95 % interval × spec | \\|ln error\\| | truth inside | rms fit / truth |",
             "| --- | --- | ---: | --- | ---: | ---: | --- | ---: | --- | --- |"]
    for r in rows:
        lo, hi = r["interval_factor"]
        lines.append(f"| {r['hidden']} | {r['sequence']} | {r['length_s']:.1f} | "
                     f"{r['parameter']} | {r['sd_predicted']:.2g} | {r['fitted_factor']:.4f} "
                     f"| {lo:.4f} … {hi:.4f} | {r['error']:.2g} | "
                     f"{'yes' if r['truth_inside'] else 'no'} | {r['rms_fit']:.4f} / "
                     f"{r['rms_truth']:.4f} |")
    atomic_write_text(out / f"{a.name}.md", "\n".join(lines) + "\n")
    print("\n".join(lines))


def _nominal(crane, name):
    from planner.calibration.twin_params import twin_parameters
    return next(p.nominal for p in twin_parameters(crane) if p.name == name)


def _label(factors):
    return ", ".join(f"{k} ×{v:g}" for k, v in factors.items())


if __name__ == "__main__":
    main()
