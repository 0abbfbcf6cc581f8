"""The benchmark's outputs: acceptance checks, seed tables side by side, ``bench.md``,
``bench.json`` and the figures (time–energy scatter with the Pareto front, per-move bars,
joint and cylinder-stroke profiles). Energies in the markdown are kJ, flows L/min; the JSON
stays SI.

The seed tables compare with the seeds' published numbers (the suites' task files:
``reference_s`` / ``reference_J``) and with the committed reports of ``benchmarks/`` scripts,
read from the folder ``results`` (default ``benchmarks/results`` relative to the current
directory; a missing file is said so in the report)."""
from __future__ import annotations

import json
import time as _time
from pathlib import Path

import numpy as np

from planner.bench.figures import fig_bars, fig_profiles, fig_time_energy
from planner.bench.methods import LAW_VARIANTS
from planner.bench.rows import by_move as _by_move
from planner.bench.rows import succeeded as _ok
from planner.io import atomic_write_text, dumps
from planner.tasks.cycles import START_TELE

DEFAULT_RESULTS = Path("benchmarks/results")
LAWS = list(LAW_VARIANTS)   # the seeds' laws: the local references of the acceptance checks
GLOBAL_ENERGY = ("dp:energy", "dp:energy-pinned", "nlp:energy-path")  # DP or NLP on the cycles
SAVING_TARGET = 0.15


# ------------------------------------------------------------------------------ acceptance
def global_vs_local(sres) -> dict:
    """Seed-002 cycles: pump energy of the global planners vs the JLA reference and the best
    local law (same tip path, same clock). Pass: every cycle solved, mean saving vs JLA ≥ 15 %,
    and never more energy than the best local law."""
    cycles, meths = [], {}
    for mv, R in _by_move(sres).items():
        ref = R.get("law:jla")
        e_ref = ref["energy_J"] if ref and ref["status"] == "ok" else None
        loc = {m: R[m]["energy_J"] for m in LAWS if _ok(R.get(m))}
        best = min(loc, key=loc.get) if loc else None
        c = dict(move=mv, jla_J=e_ref, jla_success=bool(ref and ref["success"]), best_local=best,
                 best_local_J=loc.get(best), methods={})
        for g in GLOBAL_ENERGY + ("topp:dp",):
            r = R.get(g)
            if r is None or r["status"] == "n/a":
                continue
            e = r["energy_J"] if _ok(r) else None
            c["methods"][g] = dict(
                success=_ok(r), energy_J=e, verdict=r["verdict"],
                saving_vs_jla=None if e is None or not e_ref else 1 - e / e_ref,
                saving_vs_best_local=None if e is None or best is None else 1 - e / loc[best])
        cycles.append(c)
    for g in GLOBAL_ENERGY + ("topp:dp",):
        rs = [c["methods"][g] for c in cycles if g in c["methods"]]
        if not rs:
            continue
        sv = [r["saving_vs_jla"] for r in rs if r["saving_vs_jla"] is not None]
        sb = [r["saving_vs_best_local"] for r in rs if r["saving_vs_best_local"] is not None]
        solved = sum(r["success"] for r in rs)
        mean = float(np.mean(sv)) if sv else None
        fails = [f"{c['move']}: {c['methods'][g]['verdict']}" for c in cycles
                 if g in c["methods"] and not c["methods"][g]["success"]]
        meths[g] = dict(cycles=len(rs), solved=solved, failures=fails, mean_saving_vs_jla=mean,
                        min_saving_vs_jla=min(sv) if sv else None,
                        min_saving_vs_best_local=min(sb) if sb else None,
                        never_above_best_local=bool(sb) and len(sb) == len(rs)
                        and min(sb) >= 0,
                        passed=solved == len(rs) and mean is not None and mean >= SAVING_TARGET
                        and len(sb) == len(rs) and min(sb) >= 0)
    return dict(target_saving=SAVING_TARGET, cycles=cycles, methods=meths,
                passed=any(meths.get(g, {}).get("passed") for g in GLOBAL_ENERGY))


def nlp_vs_laws(sres) -> dict:
    """Seed 000: the free-path minimum-time NLP against every local law, on equal limits.

    ``nlp:time-free`` and ``nlp:time-free-kin`` against the fastest successful law as the laws
    run (velocity limits only); ``nlp:time-free-acc`` (and, with its extra jerk limit,
    ``nlp:time-free``) against ``topp:law``: every law's own path made feasible under the spec's
    limits (rest to rest; velocity, acceleration, pump)."""
    out = {}
    pairs = (("nlp:time-free", LAWS), ("nlp:time-free-kin", LAWS),
             ("nlp:time-free-acc", ("topp:law",)), ("nlp:time-free", ("topp:law",)))
    for n, refs in pairs:
        moves = []
        for mv, R in _by_move(sres).items():
            laws = {m: R[m]["duration_s"] for m in refs if _ok(R.get(m))}
            best = min(laws, key=laws.get) if laws else None
            if best == "topp:law":
                best_name = "law:" + R[best]["info"].get("law", "?")
            else:
                best_name = best
            t = R[n]["duration_s"] if _ok(R.get(n)) else None
            moves.append(dict(move=mv, nlp_s=t, best_law=best_name, best_law_s=laws.get(best),
                              margin_pct=None if t is None or best is None
                              else 100 * (1 - t / laws[best])))
        key = n if refs is LAWS else f"{n} vs topp:law"
        out[key] = dict(moves=moves, passed=all(m["margin_pct"] is not None
                                                and m["margin_pct"] > 0 for m in moves))
    return out


# ------------------------------------------------------------------------------ formatting
def _f(x, fmt="{:.3f}", scale=1.0):
    return "—" if x is None else fmt.format(x * scale)


def _short(text, n):
    return text if len(text) <= n else text[:n - 1].rstrip() + "…"


def _gap(x):
    return "—" if x is None else f"{0.0 if abs(x) < 0.05 else x:+.1f} %"


def _pf(ok):
    return "**PASS**" if ok else "**MISS**"


def _results_json(results, name, missing: list):
    """The committed report ``results/name`` (JSON), or None (its path added to ``missing``)
    when absent or unreadable."""
    p = Path(results) / name
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        missing.append(str(p))
        return None


def _acceptance_md(res):
    A = res["acceptance"]
    L = ["## Acceptance (measured in this run)", ""]
    g = A.get("seed002_global_energy")
    if g:
        L += [f"**1. Seed-002 cycles, global planners on the same tip path and clock vs the JLA "
              f"reference** (target: ≥ {100 * g['target_saving']:.0f} % less pump energy on "
              "average, never more than the best local law):", "",
              "| cycle | JLA [kJ] | best local [kJ] | " + " | ".join(
                  f"{m} [kJ] (vs JLA, vs best local)" for m in g["methods"]) + " |",
              "| --- | ---: | ---: | " + " | ".join("---:" for _ in g["methods"]) + " |"]
        for c in g["cycles"]:
            cells = []
            for m in g["methods"]:
                r = c["methods"].get(m)
                if not r or r["energy_J"] is None:
                    cells.append("fail" if r else "—")
                    continue
                cells.append(f"{r['energy_J'] / 1e3:.1f} "
                             f"({_f(r['saving_vs_jla'], '{:+.1f} %', 100)}, "
                             f"{_f(r['saving_vs_best_local'], '{:+.1f} %', 100)})")
            L.append(f"| {c['move']} | {_f(c['jla_J'], '{:.1f}', 1e-3)} | "
                     f"{_f(c['best_local_J'], '{:.1f}', 1e-3)} ({c['best_local']}) | "
                     + " | ".join(cells) + " |")
        L.append("")
        for m, s in g["methods"].items():
            miss = []
            if s["solved"] < s["cycles"]:
                miss.append(f"{s['cycles'] - s['solved']} of {s['cycles']} cycles not solved "
                            "successfully (" + "; ".join(_short(f, 75) for f in s["failures"]) + ")")
            if s["mean_saving_vs_jla"] is not None and s["mean_saving_vs_jla"] < g["target_saving"]:
                miss.append(f"mean saving {100 * s['mean_saving_vs_jla']:.1f} % is "
                            f"{100 * (g['target_saving'] - s['mean_saving_vs_jla']):.1f} points "
                            "short")
            if s["min_saving_vs_best_local"] is not None and s["min_saving_vs_best_local"] < 0:
                miss.append(f"up to {-100 * s['min_saving_vs_best_local']:.1f} % more than the "
                            "best local law on a cycle")
            info = (" (informative: the DP's path retimed rest to rest per section; the DP and "
                    "the laws run every section at constant speed from a velocity step, so a "
                    "rest-to-rest timing of the same path in the same time is mostly "
                    "infeasible)") if m == "topp:dp" else ""
            L.append(f"- `{m}`{info}: mean saving vs JLA "
                     f"{_f(s['mean_saving_vs_jla'], '{:.1f} %', 100)} (least "
                     f"{_f(s['min_saving_vs_jla'], '{:.1f} %', 100)}), vs the best local law at "
                     f"least {_f(s['min_saving_vs_best_local'], '{:+.1f} %', 100)}: "
                     f"{_pf(s['passed'])}" + (f" — {'; '.join(miss)}" if miss else ""))
        L += ["", f"Item 1: {_pf(g['passed'])} (passed when a DP or NLP planner meets it).", ""]
        st = [r["info"].get("start_tele_m") for r in res["suites"]["seed002-hvd"]["rows"]
              if r["method"] == "dp:energy" and r["success"]]
        pin = g["methods"].get("dp:energy-pinned", {}).get("mean_saving_vs_jla")
        if st and pin is not None:
            L += [f"Where the saving comes from: `dp:energy` chooses its first telescope value "
                  f"freely ({min(st):.2f} m" + (f"–{max(st):.2f} m" if max(st) > min(st) else "")
                  + " here) while the laws start at the "
                  f"assumed {', '.join(f'{k}: {v:g} m' for k, v in START_TELE.items())}; from "
                  f"the laws' own start (`dp:energy-pinned`) the DP saves {100 * pin:.1f} % on "
                  "average — much of the global advantage is the start configuration, as "
                  "benchmarks/results/seed002_table.md found.", ""]
    n = A.get("seed000_nlp_vs_laws")
    if n:
        none = dict(moves=[{}] * len(n["nlp:time-free"]["moves"]), passed=False)
        ra = n.get("nlp:time-free-acc vs topp:law", none)
        rj = n.get("nlp:time-free vs topp:law", none)
        L += ["**2. Seed 000: the free-path minimum-time NLP vs every local law, on equal "
              "limits** (times in s; margin = how much faster the NLP is):", "",
              "| move | fastest law as run (velocity limits) | nlp:time-free-kin | margin | "
              "fastest law path retimed (velocity, acceleration, pump) | nlp:time-free-acc | "
              "margin | nlp:time-free (+ jerk) | margin |",
              "| --- | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: |"]
        for b, c, d in zip(n["nlp:time-free-kin"]["moves"], ra["moves"], rj["moves"]):
            L.append(f"| {b['move']} | {_f(b['best_law_s'])} ({b['best_law']}) | "
                     f"{_f(b['nlp_s'])} | {_f(b['margin_pct'], '{:+.1f} %')} | "
                     f"{_f(c.get('best_law_s'))} ({c.get('best_law')}) | {_f(c.get('nlp_s'))} | "
                     f"{_f(c.get('margin_pct'), '{:+.1f} %')} | {_f(d.get('nlp_s'))} | "
                     f"{_f(d.get('margin_pct'), '{:+.1f} %')} |")
        L += ["", "Seed 000's laws respect velocity limits only: their piecewise-linear "
              "trajectories step from rest to full speed within one 10 ms control step "
              "(`implied_accel_over_limit` in bench.json: the acceleration such a step needs, "
              "over the spec's assumed limit). The criterion is therefore judged on equal "
              "limits, both ways:", "",
              f"- the laws' limit set: `nlp:time-free-kin` (acceleration and jerk limits raised "
              f"×{res['settings']['kin_factor']:g}, still stricter than the laws; judged on "
              f"position, velocity and pump flow like the laws) vs every law as run: "
              f"{_pf(n['nlp:time-free-kin']['passed'])}",
              f"- the spec's limits: `nlp:time-free-acc` (velocity, acceleration, pump; rest to "
              f"rest) vs every law's own path retimed rest to rest by TOPP-RA under the same "
              f"limits (`topp:law`): {_pf(ra['passed'])}", "",
              f"Informative: `nlp:time-free` also keeps the jerk limits, which TOPP-RA cannot; "
              f"against `topp:law` it {'still wins' if rj['passed'] else 'does not win'} on "
              f"every move. Against the laws as run it is "
              + ", ".join(f"{_f(m['margin_pct'], '{:+.1f} %')} ({m['move']})"
                          for m in n["nlp:time-free"]["moves"])
              + ": with the spec's assumed acceleration and jerk limits the analytic "
              "rest-to-rest bound alone (`lower_bound_s` of the NLP rows) is above the laws' "
              "times, so no feasible rest-to-rest move can match a law that ignores them.", ""]
    w = A["wall_time"]
    L.append("**3. Wall time**: " + (
        f"seed000-abc {w['seed000_s']:.1f} s (limit {w['seed000_limit_s']:.0f} s): "
        f"{_pf(w['seed000_pass'])}; " if "seed000_s" in w else "")
        + (f"all four suites {w['total_s']:.1f} s (limit {w['total_limit_s']:.0f} s): "
           f"{_pf(w['total_pass'])}." if w["all_suites"] else
           f"this run {w['total_s']:.1f} s (not all suites: the full-run limit is not judged)."))
    L += ["Measured from the first suite to the last result (figures and reports add "
          f"{res.get('output_time_s', 0):.1f} s; interpreter start-up ≈ 2 s is outside).", ""]
    return L


def _seed_md(name, sres, suite, results):
    R = _by_move(sres)
    refs = {m.id: m for m in suite.moves} if suite is not None else {}
    L, missing = [], []

    def ref(mv, kind, method, fmt="{:.2f}", scale=1.0):
        m = refs.get(mv)
        return _f(getattr(m, kind).get(method) if m is not None else None, fmt, scale)
    if name == "seed000-abc":
        L += ["Seed 000 side by side (times [s]; seed: Table 8.1 DP, Table 8.2 laws at 2.5 m/s):",
              "", "| move | dp:time | seed DP | law:max_velocity | seed | law:max_lift | seed | "
              "nlp:kin-line | nlp:time-free-kin | nlp:time-free |",
              "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for mv in (x for x in refs if x in R):

            def t(m):
                r = R[mv].get(m)
                return _f(r["duration_s"]) if _ok(r) else "fail"
            L.append(f"| {mv} | {t('dp:time')} | {ref(mv, 'reference_s', 'dp:time')} | "
                     f"{t('law:max_velocity')} | {ref(mv, 'reference_s', 'law:max_velocity')} | "
                     f"{t('law:max_lift')} | {ref(mv, 'reference_s', 'law:max_lift')} | "
                     f"{t('nlp:kin-line')} | {t('nlp:time-free-kin')} | {t('nlp:time-free')} |")
    elif name == "seed002-hvd":
        table = _results_json(results, "seed002_table.json", missing)
        old = {}
        for row in (table or {}).get("table", []):
            if row["system"] == "conventional":
                old[f"{row['cycle']}@{row['speed']:g}"] = row
        L += ["Seed 002 side by side (pump energy [kJ]; 'table' = "
              f"{Path(results) / 'seed002_table.md'}, same model and code path; 'paper' = "
              "seed 002 Table 5.1, known only for v at 1 m/s):", "",
              "| cycle | law:jla | table | paper | law:p_optimal | table P¹ | paper P¹ | "
              "dp:energy | table DP | dp:energy-pinned | table DP pinned |",
              "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for mv, rr in R.items():
            o = old.get(mv)

            def e(m):
                r = rr.get(m)
                return _f(r["energy_J"], "{:.1f}", 1e-3) if r and r["energy_J"] is not None \
                    else "fail"

            def oe(*keys):
                x = o
                for k in keys:
                    x = (x or {}).get(k)
                return _f(x, "{:.1f}", 1e-3)
            L.append(f"| {mv} | {e('law:jla')} | {oe('laws', 'jla', 'energy_J')} | "
                     f"{ref(mv, 'reference_J', 'law:jla', '{:.0f}', 1e-3)} | "
                     f"{e('law:p_optimal')} | "
                     f"{oe('laws', 'p1', 'energy_J')} | "
                     f"{ref(mv, 'reference_J', 'law:p_optimal', '{:.0f}', 1e-3)}"
                     f" | {e('dp:energy')} | {oe('dp', 'energy_J')} | {e('dp:energy-pinned')} | "
                     f"{oe('dp_pinned_start', 'energy_J')} |")
    elif name == "seed003-paths":
        nl = _results_json(results, "seed003_nlp.json", missing) or []
        ph = _results_json(results, "seed003_paths.json", missing) or {}
        L += [f"Seed 003 side by side (times [s]; 'repo' = {Path(results) / 'seed003_nlp.md'} "
              "(N = 60) and seed003_paths.md (TOPP-RA, velocity + acceleration, on the "
              "phase-plane-optimised telescope path)):", "",
              "| path | nlp:time-path | repo NLP | topp:dp | repo TOPP-RA (phase-plane path) | "
              "dp:time (velocity only) | law:max_velocity |",
              "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for mv, rr in R.items():
            rn = next((x.get("duration_s") for x in nl
                       if x.get("path", "").startswith("circle (full" if mv == "circle"
                                                       else "parabola")), None)
            rt = ph.get("paths", {}).get(mv, {}).get("topp", {}).get(
                "velocity_acceleration", {}).get("duration_s")

            def t(m):
                r = rr.get(m)
                return _f(r["duration_s"]) if _ok(r) else "fail"
            L.append(f"| {mv} | {t('nlp:time-path')} | {_f(rn)} | {t('topp:dp')} | {_f(rt)} | "
                     f"{t('dp:time')} | {t('law:max_velocity')} |")
    if missing:
        L += ["", "Not found: " + ", ".join(missing) + " (its columns show —; `results` "
              "names the folder of the committed reports)."]
    return L + ([""] if L else [])


def _suite_md(name, sres, figs, suite=None, results=DEFAULT_RESULTS):
    L = [f"## Suite `{name}` ({sres['crane']})", "", sres["description"] + ".",
         f"Wall time {sres['wall_time_s']:.1f} s; NLP construction (excluded from solve times): "
         + (", ".join(f"{k} {v:.2f} s" for k, v in sres["build_s"].items()) or "none") + "."]
    L += [f"{n}" for n in sres.get("notes", [])]
    L += ["", "| method | runs | success | median duration [s] | median energy [kJ] | "
          "median gap to bound | median solve [s] |", "| --- | ---: | ---: | ---: | ---: | ---: | "
          "---: |"]
    na = []
    for m, s in sres["summary"].items():
        if not s["applicable"]:
            na.append(f"- `{m}`: n/a — {s['reason']}")
            continue
        L.append(f"| {m} | {s['runs']} | {s['successes']}/{s['runs']} "
                 f"({100 * s['success_rate']:.0f} %) | {_f(s['median_duration_s'])} | "
                 f"{_f(s['median_energy_J'], '{:.2f}', 1e-3)} | "
                 f"{_gap(s['median_gap_pct'])} | {_f(s['median_solve_s'])} |")
    L += ["", "| move | method | verdict | duration [s] | energy [kJ] | peak pump [L/min] | "
          "max violation | bound [s] | gap | solve [s] median (min–max, runs) |",
          "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in sres["rows"]:
        if r["status"] == "n/a":
            continue
        st = r.get("solve_time_s") or {}
        verdict = r["verdict"].replace("|", "/")
        if len(verdict) > 140:
            verdict = verdict[:137] + "…"
        L.append(f"| {r['move']} | {r['method']} | {verdict} | {_f(r['duration_s'])} | "
                 f"{_f(r['energy_J'], '{:.2f}', 1e-3)} | "
                 f"{_f(r['peak_pump_flow_m3s'], '{:.1f}', 6e4)} | "
                 f"{_f(r['max_limit_violation'], '{:.3f} %', 100)} | {_f(r['lower_bound_s'])} | "
                 f"{_gap(r['gap_pct'])} | {_f(st.get('median'))} "
                 f"({_f(st.get('min'))}–{_f(st.get('max'))}, {st.get('runs', 0)}) |")
    L += [""] + (["Not applicable here:"] + na + [""] if na else [])
    L += _seed_md(name, sres, suite, results)
    L += [f"![{k}]({v})" for k, v in figs.items()] + [""]
    return L


def markdown(res, figs, suites=None, results=DEFAULT_RESULTS) -> str:
    """bench.md of the result ``res``: ``figs`` {suite: {title: file}}, ``suites`` {name:
    Suite} (for the seeds' published numbers), ``results`` the committed reports' folder."""
    m, s = res["machine"], res["settings"]
    L = ["# crane-planner bench: global planners vs local laws", "",
         f"Generated by `crane-planner bench` on {m['date_utc']} ({m['platform']}, "
         f"{m['cpu_count']} CPUs, Python {m['python']}); wall time {res['wall_time_s']:.1f} s "
         f"for {', '.join(s['suites'])}; repeats {s['repeats']} (solves under "
         f"{s['repeat_below_s']:g} s; slower ones once){'; quick' if s['quick'] else ''}.", "",
         "Every trajectory is judged only by `planner.trajectory.evaluate()` (1 kHz), on the "
         "limit kinds its method claims plus position, velocity and pump flow. success = status "
         f"ok, largest violation ≤ {100 * s['ok_tolerance']:.1f} %, clear of obstacles, and a "
         "cycle's sections joining without a jump. gap = duration over the analytic lower bound "
         "(rest-to-rest + pump for methods with acceleration limits, velocity + pump for the "
         "others), minus 1. Energies are pump energies (quasi-static load-sensing model; "
         "piecewise-linear trajectories — laws, DP — carry no inertial forces). Laws: "
         f"{s['law_speed']:g} m/s commanded tip speed at {s['law_rate']:g} Hz (cycles: the "
         "cycle's clock). Methods: see planner/bench/methods.py.", ""]
    L += _acceptance_md(res)
    for name, sres in res["suites"].items():
        L += _suite_md(name, sres, figs.get(name, {}), (suites or {}).get(name), results)
    return "\n".join(L) + "\n"


def write_outputs(res, keep, out: Path, t0: float, results=DEFAULT_RESULTS):
    """Figures, then bench.md and bench.json (atomically) into ``out``; ``keep``: {suite:
    (profile outcomes, Suite, Crane)}; ``results``: the committed reports' folder."""
    out.mkdir(parents=True, exist_ok=True)
    figs = {}
    for name, (kp, suite, crane) in keep.items():
        sres = res["suites"][name]
        f = {"time–energy": f"{name}_time_energy.png", "per-move bars": f"{name}_bars.png",
             "profiles": f"{name}_profiles.png"}
        fig_time_energy(name, sres, out / f["time–energy"])
        fig_bars(name, sres, out / f["per-move bars"])
        if kp:
            fig_profiles(name, kp, crane, suite.profile_move, out / f["profiles"])
        else:
            f.pop("profiles")
        figs[name] = f
        sres["figures"] = f
    res["output_time_s"] = _time.perf_counter() - t0 - res["wall_time_s"]
    atomic_write_text(out / "bench.md", markdown(res, figs, {n: k[1] for n, k in keep.items()},
                                                 results))
    atomic_write_text(out / "bench.json", dumps(res) + "\n")


__all__ = ["write_outputs", "global_vs_local", "nlp_vs_laws", "markdown"]
