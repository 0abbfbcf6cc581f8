#!/usr/bin/env python3
"""Seed 002's Table 5.1 on the s100f model: cycle energies of the local cylinder-space laws, plus
a global DP along the same straight sections.

    python benchmarks/seed002_table.py [--out benchmarks/results] [--no-gain-check]

For the cycles h, v, d (planner.tasks.cycles) × per-axis tip speed 0.5 and 1 m/s × {conventional,
hydraulic transformer (HT)}:

a) the local laws JLA, Q-optimal, P-optimal n = 1, 1.5, 2 (planner.methods.laws_energy, their
   tuned default gains) run with ``follow_command`` at 100 Hz from the assumed start
   configuration; every trajectory is judged by ``evaluate`` (energy_J = pump energy; the
   largest violation of the checked limits — position and velocity — and, for information, the
   pump-flow limit, enforced for the laws by flow sharing) and by the law's largest tracking error;
b) the global DP (planner.methods.dp, objective "energy") on every straight section of the cycle
   (the preliminary move included) at the cycle's tip speed (√2 × the per-axis speed on the
   diagonal), the telescope chained between consecutive sections (the first section free); the
   section trajectories' evaluate() energies are summed. The telescope grid is chosen so that
   the window of 3 grid steps per stage spans the telescope's rate limit (see DP_TELE_STEP);
c) (unless --no-gain-check) the gain check of the tuning rule: every criterion law at its tuned
   gain and at the next rung of the ladder on all 12 runs — admissible when the largest tracking
   error is ≤ 5 mm and the total variation of the joint rates is ≤ 2× the JLA run's.

Writes <out>/seed002_table.json and <out>/seed002_table.md atomically and prints the tables.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import tomllib
from datetime import datetime, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if str(ROOT) not in sys.path:  # run from a checkout without installing
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from planner.tasks.cycles import CYCLES, SPEEDS, START, START_REASON, START_TELE, cycle  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.methods import laws_energy as le  # noqa: E402
from planner.methods.dp import dp  # noqa: E402
from planner.methods.laws import follow_command  # noqa: E402
from planner.model import Crane  # noqa: E402
from planner.geometry.paths import Line  # noqa: E402
from planner.model.spec import parse_spec  # noqa: E402
from planner.trajectory import evaluate  # noqa: E402
from planner.problems import crane_path  # noqa: E402

RATE_HZ = 100.0
DP_STEP = 0.02          # [m] path spacing of the DP stages
DP_WINDOW = 3           # telescope grid steps per stage
DP_TELE_STEP_MAX = 0.02  # [m] the brief's telescope grid (used when it is fine enough)
LADDER = (-0.25, -0.5, -1.0, -2.0, -5.0, -10.0, -20.0)
ERR_MAX_M = 5e-3        # tuning rule: the tip must follow the path within 5 mm ...
TV_RATIO_MAX = 2.0      # ... without oscillating (joint-rate total variation ≤ 2× JLA's)
SEED_ROW = dict(cycle="v", speed=1.0, system="conventional",
                kJ=dict(jla=454, q_optimal=442, p1=351, p1_5=341, p2=332))
LAW_KEYS = ("jla", "q_optimal", "p1", "p1_5", "p2")
LAW_TITLES = {"jla": "JLA", "q_optimal": "Q-opt", "p1": "P¹", "p1_5": "P^1.5", "p2": "P²"}


def make_law(key, **gain):
    if key == "jla":
        return le.JLA(**gain)
    if key == "q_optimal":
        return le.QOptimal(**gain)
    n = {"p1": 1.0, "p1_5": 1.5, "p2": 2.0}[key]
    return le.POptimal(n, **gain)


def cranes():
    conv = Crane.from_id("s100f")
    data = tomllib.loads(Path(crane_path("s100f")).read_text(encoding="utf-8"))
    data["transformer"]["enabled"] = True
    return {"conventional": conv, "HT": Crane(parse_spec(data, "s100f-ht"))}


def rate_variation(traj):
    qd = np.diff(traj.q, axis=0) / np.diff(traj.t)[:, None]
    return float(np.abs(np.diff(qd, axis=0)).sum())


def run_law(crane, law, name, speed):
    cmd, duration, _ = cycle(name, speed)
    q0 = crane.ik(START[name], tele=START_TELE[name])
    res = follow_command(crane, law, cmd, duration, q0=q0, rate=RATE_HZ)
    ev = evaluate(crane, res.trajectory)
    x, _ = crane.stroke(res.trajectory.q)
    c = le.cylinder_setup(crane, law.ht)
    s = (x[:, c["P"]] - c["x_lo"]) / (c["x_hi"] - c["x_lo"])
    return dict(energy_J=ev.energy_J, max_limit_violation=ev.max_limit_violation, ok=ev.ok(),
                violations={k: float(v) for k, v in ev.violations.items()},
                max_tracking_error_m=res.max_path_error_m, min_beta=res.min_beta,
                rate_variation=rate_variation(res.trajectory),
                min_stroke_margin=float(np.min(np.minimum(s, 1 - s))),
                tele_range_m=[float(res.trajectory.q[:, crane.chain.tele].min()),
                              float(res.trajectory.q[:, crane.chain.tele].max())],
                duration_s=res.duration_s, solve_time_s=res.solve_time_s)


def dp_tele_step(crane, path_speed):
    """Telescope grid so that DP_WINDOW steps per stage reach the telescope's rate limit
    (capped at DP_TELE_STEP_MAX); with 0.02 m at 1 m/s one step per stage would already need
    1 m/s > 0.6 m/s and the DP could not move the telescope at all."""
    vmax = float(crane.limit_arrays()["qd_max"][crane.chain.tele])
    h = vmax * (DP_STEP / path_speed) / DP_WINDOW
    return min(DP_TELE_STEP_MAX, h)


def run_dp(crane, name, speed, tele_start=None):
    """DP on every section, telescope chained; ``tele_start`` pins the first section's start
    (None: free)."""
    _, _, sections = cycle(name, speed)
    tele = tele_start
    total, t0 = 0.0, time.perf_counter()
    rows, worst, status = [], 0.0, "ok"
    for sec in sections:
        ts = dp_tele_step(crane, sec.path_speed)
        kw = dict(objective="energy", tip_speed=sec.path_speed, step=DP_STEP, tele_step=ts,
                  window=DP_WINDOW, tele_start=tele)
        r = dp(crane, Line(sec.start, sec.end), **kw)
        relaxed = False
        if not r.ok:  # greedy chaining can dead-end on the pump-flow limit: retry without it
            r2 = dp(crane, Line(sec.start, sec.end), pump=False, **kw)
            if r2.ok:
                relaxed, first_reason, r = True, r.reason, r2
        if not r.ok:
            status = f"{r.status}: {r.reason}"
            rows.append(dict(start=sec.start[:2], end=sec.end[:2], status=r.status,
                             reason=r.reason))
            break
        ev = evaluate(crane, r.trajectory)
        tele_in = float(r.path_q[0][crane.chain.tele])
        tele = float(r.path_q[-1][crane.chain.tele])
        total += ev.energy_J
        worst = max(worst, ev.max_limit_violation)
        rows.append(dict(start=sec.start[:2], end=sec.end[:2], path_speed=sec.path_speed,
                         pump_flow_relaxed=relaxed,
                         reason_with_pump_limit=first_reason if relaxed else "",
                         tele_step_m=ts, stages=r.grid["stages"],
                         tele_nodes=r.grid["tele_nodes"], energy_J=ev.energy_J,
                         dp_energy_J=r.energy_J, tele_in_m=tele_in, tele_out_m=tele,
                         max_limit_violation=ev.max_limit_violation,
                         violations={k: float(v) for k, v in ev.violations.items()},
                         solve_time_s=r.solve_time_s))
    return dict(status=status, energy_J=total if status == "ok" else None,
                max_limit_violation=worst, sections=rows,
                pump_flow_relaxed=sum(bool(x.get("pump_flow_relaxed")) for x in rows),
                solve_time_s=time.perf_counter() - t0)


def next_rung(g):
    lower = [x for x in LADDER if x < g - 1e-12]
    return max(lower) if lower else 2 * g


def gain_check(cr, law_rows):
    out = {}
    for key in LAW_KEYS[1:]:
        law = make_law(key)
        gname = "k_q" if key == "q_optimal" else "k_p"
        g = getattr(law, gname)
        up = next_rung(g)
        rec = dict(gain_name=gname, chosen=g, next_rung=up, chosen_fail=[], next_fail=[],
                   chosen_worst_err_m=0.0, next_worst_err_m=0.0,
                   chosen_worst_tv_ratio=0.0, next_worst_tv_ratio=0.0)
        for (name, speed, sysname), laws in law_rows.items():
            ref = laws["jla"]
            for which, r in (("chosen", laws[key]),
                             ("next", run_law(cr[sysname], make_law(key, **{gname: up}),
                                              name, speed))):
                tvr = r["rate_variation"] / ref["rate_variation"]
                rec[f"{which}_worst_err_m"] = max(rec[f"{which}_worst_err_m"],
                                                  r["max_tracking_error_m"])
                rec[f"{which}_worst_tv_ratio"] = max(rec[f"{which}_worst_tv_ratio"], tvr)
                if r["max_tracking_error_m"] > ERR_MAX_M or tvr > TV_RATIO_MAX or not r["ok"]:
                    rec[f"{which}_fail"].append(f"{name} {speed:g} {sysname}")
        out[key] = rec
    return out


def saving(ref, e):
    return None if (ref is None or e is None) else (ref - e) / ref


def fmt_pct(x):
    return "—" if x is None else f"{100 * x:+.1f} %"


def markdown(res):
    L = []
    A = L.append
    A("# Seed 002 Table 5.1 on s100f: local cylinder-space laws vs JLA, and a global DP\n")
    A(f"Generated by `benchmarks/seed002_table.py` on {res['machine']['date_utc']} "
      f"({res['machine']['platform']}, {res['machine']['cpu_count']} CPUs, Python "
      f"{res['machine']['python']}); run time {res['runtime_s']:.0f} s.\n")
    A("Machine: s100f (all dimensions assumed, see planner/problems/cranes/s100f.toml); HT = the "
      "same spec with `[transformer] enabled = true`. Cycles: planner/cycles.py (seed timing; "
      "preliminary moves and start positions ASSUMED: "
      + ", ".join(f"{k}: tip ({START[k][0]:g}, {START[k][1]:g}) m, telescope {START_TELE[k]:g} m"
                  for k in CYCLES) + f" — {START_REASON}). Laws at {RATE_HZ:g} Hz with "
      "`follow_command`; energy = pump energy from `evaluate()` (quasi-static load-sensing "
      "model; the law trajectories are piecewise linear, so no inertial forces enter).\n")
    A("## Energy per cycle [kJ] and saving vs JLA (same system and cycle)\n")
    A("| cycle | speed [m/s] | system | " + " | ".join(LAW_TITLES[k] for k in LAW_KEYS) + " |")
    A("| --- | --- | --- | " + " | ".join("---" for _ in LAW_KEYS) + " |")
    for row in res["table"]:
        cells = []
        for k in LAW_KEYS:
            r = row["laws"][k]
            e = r["energy_J"] / 1e3
            cells.append(f"{e:.1f}" if k == "jla" else f"{e:.1f} ({fmt_pct(r['saving_vs_jla'])})")
        A(f"| {row['cycle']} | {row['speed']:g} | {row['system']} | " + " | ".join(cells) + " |")
    s = res["seed_row"]
    A(f"| seed: v | 1 | conventional | {s['kJ']['jla']} | {s['kJ']['q_optimal']} (+2.6 %) | "
      f"{s['kJ']['p1']} (+22.7 %) | {s['kJ']['p1_5']} (+24.9 %) | {s['kJ']['p2']} (+26.9 %) |\n")
    A("Positive saving = less energy than JLA. Every law run passed `evaluate()` for position "
      f"and velocity: {res['all_laws_ok']} (largest violation "
      f"{res['worst_law_violation']:.2e}); largest tracking error "
      f"{1e3 * res['worst_tracking_error_m']:.2f} mm; largest pump-flow excess (not enforced "
      f"by the laws) {100 * res['worst_pump_flow_excess']:.1f} %"
      + (" (" + "; ".join(res["pump_flow_excess_runs"]) + ")"
         if res["pump_flow_excess_runs"] else "")
      + f"; smallest stroke margin {100 * res['min_stroke_margin']:.1f} % of a stroke.\n")
    A("## Global DP along the same sections\n")
    ts = [sec["tele_step_m"] for row in res["table"] for sec in row["dp"]["sections"]
          if "tele_step_m" in sec]
    A(f"DP: objective \"energy\", step {DP_STEP} m, window {DP_WINDOW}, telescope grid = "
      f"rate limit × stage time / window ({max(ts):.4f}–{min(ts):.4f} m; the brief's "
      f"{DP_TELE_STEP_MAX} m would freeze the telescope at 1 m/s: one grid step per 0.02 s stage "
      "is 1 m/s > its 0.6 m/s limit), telescope chained between sections (first section free), "
      "energies from `evaluate()` of each section trajectory, summed.\n")
    A("| cycle | speed [m/s] | system | JLA [kJ] | best local [kJ] | DP [kJ] | DP vs JLA | "
      "DP vs best local | DP max violation | DP time [s] | DP, start pinned [kJ] | "
      "pinned vs JLA | pinned vs best local |")
    A("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in res["table"]:
        d, dp_ = row["dp"], row["dp_pinned_start"]
        e = "—" if d["energy_J"] is None else f"{d['energy_J'] / 1e3:.1f}" + \
            ("*" if d["pump_flow_relaxed"] else "")
        ep = "—" if dp_["energy_J"] is None else f"{dp_['energy_J'] / 1e3:.1f}" + \
            ("*" if dp_["pump_flow_relaxed"] else "")
        A(f"| {row['cycle']} | {row['speed']:g} | {row['system']} | "
          f"{row['laws']['jla']['energy_J'] / 1e3:.1f} | "
          f"{row['best_local_energy_J'] / 1e3:.1f} ({LAW_TITLES[row['best_local']]}) | {e} | "
          f"{fmt_pct(d['saving_vs_jla'])} | {fmt_pct(d['saving_vs_best_local'])} | "
          f"{d['max_limit_violation']:.1e} | {d['solve_time_s']:.1f} | {ep} | "
          f"{fmt_pct(dp_['saving_vs_jla'])} | {fmt_pct(dp_['saving_vs_best_local'])} |")
    A("")
    A("'DP, start pinned': the first section starts at the laws' start telescope value "
      "(START_TELE) instead of a free one, so the DP and the laws start from the same "
      "configuration (the free DP always chose the fully extended telescope, 2.3 m). "
      "'*': greedy chaining left a section with no transition that respects the pump-flow "
      "limit; that section was re-solved without it (pump=False; the laws do not respect it "
      "either) and its pump-flow excess is in the JSON.\n")
    A("## Gains (tuned as the seed did) and the gain check\n")
    g = res["gains"]
    A(f"JLA: k_JLA = {g['jla']['k_jla']:g} m²/s (Chan–Dubey on the strokes, 15 % zone, "
      f"continuous at the zone edge); Q-opt: k_Q = {g['q_optimal']['k_q']:g}; P-opt: k_P = "
      f"{g['p1']['k_p']:g} (n = 1), {g['p1_5']['k_p']:g} (n = 1.5), {g['p2']['k_p']:g} (n = 2), "
      f"p_ref = 10 MPa; low-pass τ = {g['jla']['tau_s']:g} s. Ladder {list(LADDER)}; a gain "
      f"is admissible when on all 12 runs the tracking error stays ≤ {1e3 * ERR_MAX_M:g} mm and "
      f"the joint-rate total variation ≤ {TV_RATIO_MAX:g}× the JLA run's.\n")
    if res.get("gain_check"):
        A("| law | gain | chosen | worst err [mm] / TV ratio | fails | next rung | "
          "worst err [mm] / TV ratio | fails |")
        A("| --- | --- | --- | --- | --- | --- | --- | --- |")
        for k, r in res["gain_check"].items():
            A(f"| {LAW_TITLES[k]} | {r['gain_name']} | {r['chosen']:g} | "
              f"{1e3 * r['chosen_worst_err_m']:.2f} / {r['chosen_worst_tv_ratio']:.2f} | "
              f"{', '.join(r['chosen_fail']) or 'none'} | {r['next_rung']:g} | "
              f"{1e3 * r['next_worst_err_m']:.2f} / {r['next_worst_tv_ratio']:.2f} | "
              f"{', '.join(r['next_fail']) or 'none'} |")
        A("")
    A("## Does the model reproduce the seed?\n")
    A(res["discussion"])
    A("")
    return "\n".join(L)


def discussion(res):
    t = res["table"]

    def sav(k):
        return np.array([r["laws"][k]["saving_vs_jla"] for r in t])
    lines = []
    p = {k: sav(k) for k in LAW_KEYS[1:]}
    vfc = next(r for r in t if r["cycle"] == "v" and r["speed"] == 1.0
               and r["system"] == "conventional")
    lines.append(
        "**Seed pattern**: P-optimal saves energy in nearly every case, more with higher n and "
        "at higher speed (best 26.9 %, vertical fast conventional n = 2); Q-optimal is mostly "
        "worse than JLA. **This model**: P-optimal saves in "
        + ", ".join(f"{LAW_TITLES[k]} {int(np.sum(p[k] > 0))}/12" for k in ("p1", "p1_5", "p2"))
        + " runs (mean saving " + ", ".join(f"{LAW_TITLES[k]} {100 * p[k].mean():+.1f} %"
                                            for k in ("p1", "p1_5", "p2"))
        + ("; increasing with n" if p["p1"].mean() < p["p1_5"].mean() < p["p2"].mean()
           else "; not increasing with n")
        + "; individual runs {:+.1f} % to {:+.1f} %, overall mean {:+.1f} %); Q-optimal in {}/12 "
        "(mean {:+.1f} %).".format(100 * min(v.min() for k, v in p.items() if k != "q_optimal"),
                                   100 * max(v.max() for k, v in p.items() if k != "q_optimal"),
                                   100 * np.mean([p[k] for k in ("p1", "p1_5", "p2")]),
                                   int(np.sum(p["q_optimal"] > 0)),
                                   100 * np.mean(p["q_optimal"])))
    lines.append(
        f"On the seed's headline row (v, 1 m/s, conventional) the model gives JLA "
        f"{vfc['laws']['jla']['energy_J'] / 1e3:.0f} kJ (seed 454 kJ — the same order, by "
        f"choice of the assumed machine, not a validation) but P² "
        f"{fmt_pct(vfc['laws']['p2']['saving_vs_jla'])} instead of +26.9 %: the pattern is NOT reproduced there. Q-optimal being no better "
        f"than JLA is reproduced.")
    hi = np.array([r["speed"] == 1.0 for r in t])
    lines.append(
        "Speed: the mean P-optimal saving is {:+.1f} % at 1 m/s vs {:+.1f} % at 0.5 m/s; the "
        "model's energies are nearly speed-independent (quasi-static pressures, law trajectories "
        "without inertia), so the seed's 'more at higher speed' has no mechanism here except "
        "rate saturation.".format(
            100 * np.mean([p[k][hi] for k in ("p1", "p1_5", "p2")]),
            100 * np.mean([p[k][~hi] for k in ("p1", "p1_5", "p2")])))
    lines.append(
        "Why: in this load-sensing model the pump pressure is the highest active load pressure "
        "(almost always the single-acting lift cylinder, 11–15 MPa) and every litre the pump "
        "delivers costs that pressure. ∇H_P weights the lift by p^n and the telescope extension "
        "/ jib retraction (meter-in chamber at tank pressure) by ≈ 0, so P-optimal shifts motion "
        "from the lift to the jib and telescope; that lowers Σ p_i·Q_i but not p_pump·ΣQ unless "
        "the lift stops completely (the max() switches to a lower pressure) — a quadratic "
        "null-space penalty never stops it. The configuration dependence of the pressures "
        "(moment arms), which is what a global method exploits, is invisible to these local "
        "rate criteria.")
    conv = {(r["cycle"], r["speed"]): r for r in t if r["system"] == "conventional"}
    htr = {(r["cycle"], r["speed"]): r for r in t if r["system"] == "HT"}
    ht_vs = []
    for key, r in htr.items():
        ref = conv[key]["laws"]["jla"]["energy_J"]
        ht_vs.append((key, saving(ref, r["laws"]["jla"]["energy_J"]),
                      saving(ref, r["best_local_energy_J"])))
    lines.append(
        "**Transformer**: HT + JLA vs conventional JLA: " + ", ".join(
            f"{c} {sp:g} m/s {fmt_pct(a)}" for (c, sp), a, _ in ht_vs)
        + "; the best HT law vs conventional JLA: " + ", ".join(
            f"{c} {sp:g} {fmt_pct(b)}" for (c, sp), _, b in ht_vs)
        + " (seed: up to +31.8 % on the horizontal cycle). In the model the transformer pairs "
        "jib extension with lift extension (ẋ_lift = u* + k·ẋ_jib, k = 0.47): that helps when "
        "both rise (d 'out'), but on the horizontal reach-out the lift lowers while the jib "
        "extends, so the jib pumps against the lift's piston pressure on its rod side and "
        "that oil is throttled to tank — the HT costs energy there.")
    for label, key in (("free", "dp"), ("pinned", "dp_pinned_start")):
        d = [r for r in t if r[key]["energy_J"] is not None]
        if not d:
            continue
        sj = np.array([r[key]["saving_vs_jla"] for r in d])
        sb = np.array([r[key]["saving_vs_best_local"] for r in d])
        # Nurmi & Mattila: local methods use 15–30 % MORE energy than the DP: (E_loc − E_dp)/E_dp
        more = np.array([(r["laws"]["jla"]["energy_J"] - r[key]["energy_J"]) /
                         r[key]["energy_J"] for r in d])
        moreb = np.array([(r["best_local_energy_J"] - r[key]["energy_J"]) /
                          r[key]["energy_J"] for r in d])
        inband = int(np.sum((more >= 0.15) & (more <= 0.30)))
        above = [f"{r['cycle']} {r['speed']:g} {r['system']}" for r, m in zip(d, more)
                 if m > 0.30]
        res[f"nurmi_mattila_{label}"] = dict(jla_more_than_dp=more.tolist(),
                                             best_local_more_than_dp=moreb.tolist(),
                                             rows_in_band=inband, rows=len(d))
        lines.append(
            f"**Global vs local (DP, first telescope {label})**: the DP saves "
            f"{100 * sj.min():.1f} – {100 * sj.max():.1f} % vs JLA (mean {100 * sj.mean():.1f} %) "
            f"and {100 * sb.min():.1f} – {100 * sb.max():.1f} % vs the best local law (mean "
            f"{100 * sb.mean():.1f} %) on {len(d)}/12 rows; put the other way round, JLA uses "
            f"{100 * more.min():.0f} – {100 * more.max():.0f} % (mean {100 * more.mean():.0f} %) "
            f"and the best local law {100 * moreb.min():.0f} – {100 * moreb.max():.0f} % (mean "
            f"{100 * moreb.mean():.0f} %) more energy than the DP. Nurmi & Mattila's 15–30 % "
            f"(measured, 4-DOF forestry crane): {inband}/{len(d)} rows inside the band"
            + (f", above it: {', '.join(above)}" if above else "") + ".")
    nf, npn = res.get("nurmi_mattila_free"), res.get("nurmi_mattila_pinned")
    if nf and npn:
        mf, mp = np.mean(nf["jla_more_than_dp"]), np.mean(npn["jla_more_than_dp"])
        lines.append(
            f"**Verdict on Nurmi & Mattila**: JLA uses on average {100 * mf:.0f} % more energy "
            f"than the DP when the DP may choose its start telescope ({nf['rows_in_band']}/"
            f"{nf['rows']} rows in the 15–30 % band), but only {100 * mp:.0f} % more from the "
            f"laws' own start configuration ({npn['rows_in_band']}/{npn['rows']} rows in the "
            "band) — much of the 'global' advantage here is the choice of the start "
            "configuration. The model thus shows a global-vs-local gap of that order only with "
            "a free start, and the local P-optimal law does not close it (the seed's hope). "
            "Caveats: the DP is optimal per section only (greedy chaining of the telescope), it "
            "respects the pump-flow limit (the laws do not: see above), both are judged "
            "quasi-statically on piecewise-linear trajectories (velocity steps at the section "
            "ends), and every number rests on the assumed s100f data.")
    return "\n\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(HERE / "results"))
    ap.add_argument("--no-gain-check", action="store_true")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    cr = cranes()
    law_rows, table = {}, []
    for name in CYCLES:
        for speed in SPEEDS:
            for sysname, crane in cr.items():
                laws = {k: run_law(crane, make_law(k), name, speed) for k in LAW_KEYS}
                law_rows[(name, speed, sysname)] = laws
                ref = laws["jla"]["energy_J"]
                for r in laws.values():
                    r["saving_vs_jla"] = saving(ref, r["energy_J"])
                best = min(LAW_KEYS, key=lambda k: laws[k]["energy_J"])
                d = run_dp(crane, name, speed)
                d["saving_vs_jla"] = saving(ref, d["energy_J"])
                d["saving_vs_best_local"] = saving(laws[best]["energy_J"], d["energy_J"])
                dpin = run_dp(crane, name, speed, tele_start=START_TELE[name])
                dpin["saving_vs_jla"] = saving(ref, dpin["energy_J"])
                dpin["saving_vs_best_local"] = saving(laws[best]["energy_J"], dpin["energy_J"])
                row = dict(cycle=name, speed=speed, system=sysname, laws=laws, best_local=best,
                           best_local_energy_J=laws[best]["energy_J"], dp=d,
                           dp_pinned_start=dpin)
                table.append(row)
                e_dp = "—" if d["energy_J"] is None else f"{d['energy_J'] / 1e3:6.1f}"
                print(f"{name} {speed:g} {sysname:12s} " + "  ".join(
                    f"{LAW_TITLES[k]} {laws[k]['energy_J'] / 1e3:6.1f}"
                    + ("" if k == "jla" else f" ({fmt_pct(laws[k]['saving_vs_jla'])})")
                    for k in LAW_KEYS)
                    + f"  DP {e_dp} ({fmt_pct(d['saving_vs_jla'])} vs JLA)", flush=True)
    allr = [r for row in table for r in row["laws"].values()]
    res = dict(
        benchmark="seed002_table", crane="s100f",
        machine=dict(platform=platform.platform(), cpu_count=os.cpu_count(),
                     python=platform.python_version(),
                     date_utc=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")),
        settings=dict(rate_hz=RATE_HZ, dp_step_m=DP_STEP, dp_window=DP_WINDOW,
                      dp_tele_step_max_m=DP_TELE_STEP_MAX, ladder=list(LADDER),
                      err_max_m=ERR_MAX_M, tv_ratio_max=TV_RATIO_MAX),
        start=dict(tips={k: list(v) for k, v in START.items()}, tele_m=dict(START_TELE),
                   reason=START_REASON),
        gains={k: make_law(k).gains() for k in LAW_KEYS},
        table=table, seed_row=SEED_ROW,
        all_laws_ok=bool(all(r["ok"] for r in allr)),
        worst_law_violation=max(r["max_limit_violation"] for r in allr),
        worst_tracking_error_m=max(r["max_tracking_error_m"] for r in allr),
        worst_pump_flow_excess=max(r["violations"]["pump_flow"] for r in allr),
        min_stroke_margin=min(r["min_stroke_margin"] for r in allr),
        pump_flow_excess_runs=[
            f"{row['cycle']} {row['speed']:g} {row['system']} {LAW_TITLES[k]} "
            f"{100 * r['violations']['pump_flow']:.1f} %"
            for row in table for k, r in row["laws"].items() if r["violations"]["pump_flow"] > 0])
    if not args.no_gain_check:
        res["gain_check"] = gain_check(cr, law_rows)
        for k, r in res["gain_check"].items():
            print(f"gain check {LAW_TITLES[k]}: {r['gain_name']} = {r['chosen']:g} fails "
                  f"{r['chosen_fail'] or 'none'}; next rung {r['next_rung']:g} fails "
                  f"{r['next_fail'] or 'none'}", flush=True)
    res["discussion"] = discussion(res)
    res["runtime_s"] = time.perf_counter() - t_start
    out = Path(args.out)
    atomic_write_text(out / "seed002_table.json", dumps(res) + "\n")
    md = markdown(res)
    atomic_write_text(out / "seed002_table.md", md if md.endswith("\n") else md + "\n")
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
