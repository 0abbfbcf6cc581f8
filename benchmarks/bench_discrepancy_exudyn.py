"""The discrepancy trial benchmark with the Exudyn plant as the truth (issues 13 and 14).

The recordings come from the independent dynamic plant (:mod:`planner.simulation.dynamic`:
oil compliance, spool dynamics, orifice flow, a load-sensing pump with its own dynamics, the
``[dynamics]`` friction of each machine) replaying the trials' test sequences open loop; the
fast quasi-static model still diagnoses (:class:`planner.calibration.discrepancy.Discrepancy`).
Two groups on each machine and seed:

* **clean**: nothing injected. The fast model lacks the plant's dynamics, so "explained" is not
  the expected answer: the honest ones are ``unexplained`` with a signature (e.g. periodic at
  the hydraulic natural frequency) or a catalogue name that describes a real difference of the
  two models (e.g. friction, which the fast model does not have). Reported as found.
* **hidden**: one effect that has a physical counterpart in the engine (flow gain, Coulomb
  friction, payload, leakage, valve dead band), injected into the Exudyn plant at the trial
  magnitude; success = ``named`` with the right effect (and joint), or ``ambiguous`` with it
  among the candidates. Beside it, the same effect on the fast plant (the trial benchmark's
  own judge) for the same machine and seed.

* **dynamic** (``--dynamic``, its own results file ``discrepancy_exudyn_dynamic.md``): the
  effects only the dynamic plant has (``bulk_modulus`` × 0.3–0.6 for the machine,
  ``hose_volume`` × 2–4 on one actuator) hidden in the Exudyn truth, beside a clean Exudyn
  recording of the same sequence. The fast model cannot show them (no compressible oil), so
  no catalogue name is right: the honest verdict is ``unexplained``; a named or ambiguous
  catalogue effect counts as a wrong name. The residual's periodic signature is reported, clean
  against hidden (a softer oil should ring lower, ∝ sqrt(β)).

    python benchmarks/bench_discrepancy_exudyn.py [--seeds 2] [--duration 30] [--workers 2]
    python benchmarks/bench_discrepancy_exudyn.py --dynamic [--seeds 2]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

MACHINES = ("cat215b", "s100f", "umea-lab", "cranab850")
HIDDEN = ("flow_gain", "coulomb_friction", "payload_mass", "leakage", "valve_deadband")
DYNAMIC = ("bulk_modulus", "hose_volume", "grapple_swing")   # --dynamic: Exudyn plant only


def dynamic_effect(crane, name, rng):
    """A hidden dynamics-stage effect at a magnitude that matters: the whole machine's oil
    stiffness × 0.3–0.6, one random actuator's hose volume × 2–4, or the grapple hanging on
    a link of 10–18 % of the tip's reach at mid-range (1–1.8 m on a 10 m crane) with a pin
    damping of 2–10 % of critical."""
    from planner.model.effects import make
    if name == "bulk_modulus":
        return make(name, scale=float(rng.uniform(0.3, 0.6)))
    if name == "grapple_swing":
        from planner.model.dynamics_spec import GYRATION
        L = crane.limit_arrays()
        tip = np.asarray(crane.tip(0.5 * (L["q_min"] + L["q_max"])), float).ravel()
        length = float(rng.uniform(0.10, 0.18) * np.hypot(tip[0], tip[1]))
        inertia = crane.spec.payload.total * (length ** 2 + GYRATION ** 2)
        omega = np.sqrt(crane.spec.gravity * length / (length ** 2 + GYRATION ** 2))
        zeta = float(rng.uniform(0.02, 0.10))
        return make(name, length=round(length, 3),
                    damping=round(min(2 * zeta * inertia * omega, 5e4), 1))
    return make(name, str(rng.choice(crane.names)), scale=float(rng.uniform(2.0, 4.0)))


def exudyn_record(crane, plan, ff, effects, seed):
    """The trials' ``record`` on the Exudyn plant: ``ff`` replayed open loop from the plan's
    start, sampled on the command grid, sensed, seed 001's noise."""
    from planner.simulation.dynamic.exudyn_plant import ExudynPlant
    from planner.simulation.recording import Recording
    plant = ExudynPlant(crane, effects)
    run = plant.integrate(np.asarray(ff.t, float), np.asarray(ff.u, float), plan.q[0],
                          t_end=float(ff.t[-1]), max_wall_s=900.0)
    if not run.ok:
        return None, f"{run.status} at t = {run.t_fail:.2f} s: {run.reason}"
    t = np.asarray(ff.t, float)
    t = t[t <= run.t[-1] + 1e-12]
    q, p_a, p_b, u = run.sample(t)
    q_s, pa_s, pb_s = plant.sense(q, p_a, p_b, t)
    return Recording(t, u, q_s, pa_s, pb_s).with_noise(crane, True, seed), ""


def run_case(case):
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from planner import Crane
    from planner.calibration.discrepancy import Discrepancy
    from planner.calibration.trials import TrialSequence, draw, excitation, record
    crane = Crane.from_id(case["machine"])
    seed = case["seed"]
    plan, ff = excitation(crane, case["duration"], seed=seed)
    truth = None
    if case["effect"] in DYNAMIC:
        truth = dynamic_effect(crane, case["effect"], np.random.default_rng(seed + 7919))
    elif case["effect"]:
        rng = np.random.default_rng(seed + 7919)
        truth = draw(crane, case["effect"], rng, None, TrialSequence(crane, plan, ff))
    effects = (truth,) if truth else ()
    out = dict(case, truth=None if truth is None else dict(effect=truth.name, joint=truth.joint,
                                                           values=truth.values))
    t0 = time.perf_counter()
    rec, why = exudyn_record(crane, plan, ff, effects, seed)
    out["sim_s"] = time.perf_counter() - t0
    if rec is None:
        return dict(out, verdict="plant-failed", reason=why)
    results = {}
    judges = [("exudyn", rec)]
    if not case.get("dynamic"):   # the fast plant cannot record a dynamics-stage effect
        judges.append(("fast", record(crane, plan, ff, effects, noise=True, seed=seed)))
    for judge_name, r in judges:
        t1 = time.perf_counter()
        res = Discrepancy(crane).fit(r)
        results[judge_name] = dict(
            verdict=res.verdict, effect=res.effect, joint=res.joint,
            candidates=[(c["effect"], c["joint"]) for c in res.candidates],
            signature=[dict(kind=s.get("kind"), channel=s.get("channel"),
                            frequency_hz=s.get("frequency_hz")) for s in res.signature[:2]],
            message=res.message[:240], fit_s=time.perf_counter() - t1)
        results[judge_name]["ok"] = success(results[judge_name], out["truth"])
    return dict(out, **{f"{k}_{x}": v for k, d in results.items() for x, v in d.items()})


def success(r, truth):
    """Hidden effect: named right (effect and joint) or ambiguous with it among the candidates.
    Clean: None (no right answer is defined; reported as found)."""
    if truth is None:
        return None
    if r["verdict"] == "named":
        return r["effect"] == truth["effect"] and (truth["joint"] is None
                                                  or r["joint"] == truth["joint"])
    if r["verdict"] == "ambiguous":
        return (truth["effect"], truth["joint"]) in [tuple(c) for c in r["candidates"]]
    return False


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--machines", default=",".join(MACHINES))
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    ap.add_argument("--from-json", action="store_true",
                    help="rewrite the markdown from the results JSON (no runs)")
    ap.add_argument("--dynamic", action="store_true",
                    help="hide the dynamics-stage effects (bulk_modulus, hose_volume) instead")
    args = ap.parse_args()
    name = "discrepancy_exudyn_dynamic" if args.dynamic else "discrepancy_exudyn"
    render = markdown_dynamic if args.dynamic else markdown
    if args.from_json:
        from planner.io import atomic_write_text
        rep = json.loads((Path(args.out) / f"{name}.json").read_text())
        atomic_write_text(Path(args.out) / f"{name}.md", "\n".join(render(rep)))
        return
    cases = [dict(machine=m, seed=900 + s, effect=e, duration=args.duration,
                  dynamic=args.dynamic)
             for m in args.machines.split(",") for s in range(args.seeds)
             for e in (None,) + (DYNAMIC if args.dynamic else HIDDEN)]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as ex:
        rows = []
        for r in ex.map(run_case, cases):
            rows.append(r)
            print(r["machine"], r["seed"], r["effect"], r.get("exudyn_verdict", r.get("verdict")),
                  r.get("exudyn_effect"), "| fast:", r.get("fast_verdict"), r.get("fast_effect"),
                  f"{r['sim_s']:.1f} s", flush=True)
    wall = time.perf_counter() - t0
    out = Path(args.out)
    from planner.io import atomic_write_text
    rep = dict(date=datetime.datetime.now().isoformat(timespec="seconds"),
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=os.getloadavg()),
               args=vars(args), wall_s=wall, rows=rows)
    atomic_write_text(out / f"{name}.json", json.dumps(rep, indent=1, default=str))
    atomic_write_text(out / f"{name}.md", "\n".join(render(rep)))
    print("\n".join(render(rep)))


def _cell(r, judge):
    v = r.get(f"{judge}_verdict", r.get("verdict"))
    if v in ("named",):
        return f"named {r[f'{judge}_effect']}" + (f"@{r[f'{judge}_joint']}"
                                                  if r.get(f"{judge}_joint") else "")
    if v == "ambiguous":
        return "ambiguous: " + ", ".join(f"{e}" + (f"@{j}" if j else "")
                                         for e, j in r[f"{judge}_candidates"])
    if v == "unexplained":
        sig = r[f"{judge}_signature"]
        s = sig[0] if sig else {}
        f = f" {s['frequency_hz']:.2f} Hz" if s.get("frequency_hz") else ""
        return f"unexplained: {s.get('kind')}{f} on {s.get('channel')}"
    return str(v)


def markdown(rep) -> list:
    rows = rep["rows"]
    hid = [r for r in rows if r["effect"]]
    cln = [r for r in rows if not r["effect"]]
    n_ok_e = sum(bool(r.get("exudyn_ok")) for r in hid)
    n_ok_f = sum(bool(r.get("fast_ok")) for r in hid)
    wrong_e = sum(r.get("exudyn_verdict") == "named" and not r.get("exudyn_ok") for r in hid)
    wrong_f = sum(r.get("fast_verdict") == "named" and not r.get("fast_ok") for r in hid)
    a = rep["args"]
    L = ["# Discrepancy workflow with the Exudyn plant as the truth", "",
         f"{rep['date']}, {rep['machine']['platform']}, {rep['machine']['cpus']} CPUs, load "
         f"{rep['machine']['load'][0]:.1f} (other work on the machine). "
         f"`python benchmarks/bench_discrepancy_exudyn.py --seeds {a['seeds']} --duration "
         f"{a['duration']:g}` ({len(rows)} cases, {rep['wall_s'] / 60:.1f} min). "
         "The truth: the Exudyn plant replaying the trials' test sequence open loop (seed 001's "
         "sensor noise); the diagnosis: the fast quasi-static model, as on real data. Beside "
         "each, the same case recorded on the fast plant (the trial benchmark's judge).", "",
         "| measure | truth = Exudyn | truth = fast plant |", "| --- | ---: | ---: |",
         f"| hidden effect: right name or a tie with it | {n_ok_e} of {len(hid)} | "
         f"{n_ok_f} of {len(hid)} |",
         f"| hidden effect: confidently wrong (named another) | {wrong_e} of {len(hid)} | "
         f"{wrong_f} of {len(hid)} |"]
    for v in ("explained", "named", "ambiguous", "unexplained", "plant-failed"):
        ne = sum(r.get("exudyn_verdict", r.get("verdict")) == v for r in cln)
        nf = sum(r.get("fast_verdict") == v for r in cln)
        L.append(f"| clean recording: {v} | {ne} of {len(cln)} | {nf} of {len(cln)} |")
    n_unexp = sum(r.get("exudyn_verdict") == "unexplained" for r in rows)
    per = sorted({round(r["exudyn_signature"][0]["frequency_hz"], 2) for r in rows
                  if r.get("exudyn_signature") and r["exudyn_signature"][0].get("frequency_hz")})
    L += ["", "## Reading", "",
          f"With the dynamic plant as the truth the fast model leaves a residual above noise on "
          f"every recording: {n_unexp} of {len(rows)} verdicts are `unexplained`, none names a "
          f"catalogue effect that is not there and none says `explained`. The signatures are "
          f"the plant's own dynamics, which no catalogue effect of the quasi-static model "
          f"represents: a periodic residual on the slew pressures at "
          f"{', '.join(f'{f:g}' for f in per) or '–'} Hz on s100f and cranab850 (their slews' "
          f"lowest hydraulic modes, 0.71 and 0.75 Hz in `exudyn_validation.md`: oil "
          f"compliance against the slewing inertia), steps and drifts on joints where the "
          f"open-loop replay settles elsewhere. The price is that a hidden catalogue effect on "
          f"top of that gap is not named either ({n_ok_e} of {len(hid)}, against {n_ok_f} of "
          f"{len(hid)} when the fast plant is the truth): the workflow, as issue 14 asks, says "
          f"what it cannot explain rather than naming something else, and the gap it reports "
          f"is the one to close first (a dynamic diagnosing model, or oil compliance in the "
          f"catalogue).", ""]
    L += ["", "## Cases", "", "| machine | seed | hidden | truth = Exudyn | truth = fast plant "
          "| Exudyn s |", "| --- | ---: | --- | --- | --- | ---: |"]
    for r in rows:
        tr = r.get("truth")
        h = "–" if not tr else tr["effect"] + (f"@{tr['joint']}" if tr["joint"] else "")
        L.append(f"| {r['machine']} | {r['seed']} | {h} | {_cell(r, 'exudyn')} | "
                 f"{_cell(r, 'fast') if 'fast_verdict' in r else '–'} | {r['sim_s']:.1f} |")
    return L + [""]


def markdown_dynamic(rep) -> list:
    """``--dynamic``: verdict counts of the hidden dynamics-stage effects and the clean
    recordings, and the periodic signature of each case beside its clean twin."""
    rows = rep["rows"]
    a = rep["args"]
    clean = {(r["machine"], r["seed"]): r for r in rows if not r["effect"]}
    L = ["# Discrepancy workflow: effects only the dynamic plant has, hidden in the Exudyn truth",
         "", f"{rep['date']}, {rep['machine']['platform']}, {rep['machine']['cpus']} CPUs, load "
         f"{rep['machine']['load'][0]:.1f}. `python benchmarks/bench_discrepancy_exudyn.py "
         f"--dynamic --seeds {a['seeds']} --duration {a['duration']:g}` ({len(rows)} cases, "
         f"{rep['wall_s'] / 60:.1f} min). The truth: the Exudyn plant with the oil's bulk "
         "modulus × 0.3–0.6 (whole machine), one actuator's hose volume × 2–4, or the grapple "
         "swinging on a passive two-axis link (10–18 % of the reach, 2–10 % of critical "
         "damping), replaying the "
         "trials' test sequence open loop, seed 001's sensor noise; the diagnosis: the fast "
         "quasi-static model, which has no compressible oil and no swinging load, so no "
         "catalogue name is right and "
         "the honest verdict is `unexplained`.", "",
         "| hidden | cases | unexplained (honest) | named a catalogue effect (wrong) | "
         "ambiguous (wrong) | explained (blind) | plant failed |",
         "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for eff in (None,) + DYNAMIC:
        rs = [r for r in rows if r["effect"] == eff]
        if not rs:
            continue
        n = {v: sum(r.get("exudyn_verdict", r.get("verdict")) == v for r in rs)
             for v in ("unexplained", "named", "ambiguous", "explained", "plant-failed")}
        L.append(f"| {eff or 'nothing (clean)'} | {len(rs)} | {n['unexplained']} | "
                 f"{n['named']} | {n['ambiguous']} | {n['explained']} | {n['plant-failed']} |")
    L += ["", "## Cases", "", "| machine | seed | hidden | verdict | same sequence, clean "
          "| Exudyn s |", "| --- | ---: | --- | --- | --- | ---: |"]
    for r in rows:
        if not r["effect"]:
            continue
        tr = r["truth"]
        v = tr["values"]
        h = f"{tr['effect']}" + (f"@{tr['joint']}" if tr["joint"] else "") + (
            f" ×{v['scale']:.2f}" if "scale" in v else
            f" {v['length']:.2f} m, {v['damping']:.0f} N·m·s/rad (pendulum "
            f"{np.sqrt(9.81 * v['length'] / (v['length'] ** 2 + 0.09)) / (2 * np.pi):.2f} Hz)")
        c = clean.get((r["machine"], r["seed"]))
        L.append(f"| {r['machine']} | {r['seed']} | {h} | {_cell(r, 'exudyn')} | "
                 f"{_cell(c, 'exudyn') if c else '–'} | {r['sim_s']:.1f} |")
    return L + [""]


if __name__ == "__main__":
    main()
