# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Energy: local laws vs global planners on the seed-002 cycles (S100F)
#
# **Question.** Seed 002 proposed local redundancy laws for a forwarder crane that resolve the
# tip command in cylinder space with an energy criterion — JLA (joint-limit avoidance only),
# Q-optimal (least pump flow), P-optimal (least pressure-weighted flow, exponent n) — and
# measured them on three test cycles (horizontal h, vertical v, diagonal d). On our S100F
# model (load-sensing pump, single-acting lift cylinder):
#
# 1. how much pump energy does each local law use per cycle,
# 2. how much does a *global* planner save on the same cycles — the Bellman DP along the same
#    straight sections at the same tip speed, and the NLP (free path, rest to rest, in the
#    same time per section),
# 3. where does the energy go: into the cylinders (load pressure × flow), into throttling
#    across the valves (pump pressure − load pressure) × flow, or into the pump?

# %%
# %matplotlib inline
# Settings. CRANE_NB_SMALL=1 (set by the test suite): small settings that run in seconds;
# otherwise the full study (`make notebooks`). CRANE_NB_OUT: where figure files go.
import time

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Markdown, display
from nbtools import show, span, study, table

SMALL_SETTINGS = dict(cycles=("d",), speeds=(1.0,), laws=("jla", "q_optimal", "p1", "p2"),
                      rate=100.0, dp_step=0.05, dp_window=3, nlp_N=20)
FULL_SETTINGS = dict(cycles=("h", "v", "d"), speeds=(0.5, 1.0),
                     laws=("jla", "q_optimal", "p1", "p1_5", "p2"), rate=100.0, dp_step=0.02,
                     dp_window=3, nlp_N=40)
SMALL, S, OUT, T_START = study(SMALL_SETTINGS, FULL_SETTINGS)  # reads CRANE_NB_SMALL

# %% [markdown]
# ## The machine and the cycles
#
# `planner/tasks/cycles.py` encodes seed 002's cycles (5 s rest, two extend/retract sections along
# one line, pauses; per-axis tip speed 0.5 or 1 m/s); the start points and the preliminary
# moves are assumptions (the seed gives neither). The pump is load sensing: its pressure is
# the highest load pressure of the functions that draw flow plus a margin, and every litre it
# delivers costs that pressure — whichever function it goes to.

# %%
from planner import Crane
from planner.tasks.cycles import START, START_TELE, cycle, labels

crane = Crane.from_id("s100f")
pump = crane.spec.pump
print(f"{crane.spec.name}: joints {crane.names}; pump {pump.kind}, "
      f"{pump.max_flow * 6e4:.0f} L/min, margin {pump.margin / 1e5:.0f} bar, "
      f"standby {pump.standby / 1e5:.0f} bar, efficiency {pump.efficiency:.2f}")
table(["joint", "actuator", "acting", "piston area [cm²]", "annulus area [cm²]"],
      [[j.name, j.actuator.kind, j.actuator.acting, f"{1e4 * j.actuator.area_a:.1f}",
        f"{1e4 * j.actuator.area_b:.1f}" if j.actuator.area_b else "—"]
       for j in crane.spec.joints])
rows = []
fig, axs = plt.subplots(1, len(S["cycles"]), figsize=(4.2 * len(S["cycles"]), 4),
                        squeeze=False)
for ax, name in zip(axs[0], S["cycles"]):
    _, dur, secs = cycle(name, S["speeds"][-1])
    for lab, sec in zip(labels(name), secs):
        rows.append([name, lab, f"({sec.start[0]:g}, {sec.start[1]:g}) → "
                     f"({sec.end[0]:g}, {sec.end[1]:g})",
                     f"{sec.t0:g}–{sec.t1:g}", f"{sec.path_speed:.2f}"])
        ax.annotate("", sec.end[:2], sec.start[:2],
                    arrowprops=dict(arrowstyle="->", color="C0" if lab != "preliminary"
                                    else "C1"))
    o = crane.frame_origins(crane.ik(START[name], tele=START_TELE[name]))
    ax.plot(np.hypot(o[:, 0], o[:, 1]), o[:, 2], "o-", color="0.5", lw=3, alpha=0.6)
    ax.set_aspect("equal")
    ax.set_xlim(-0.5, 10.5)
    ax.set_ylim(-3, 6)
    ax.grid(alpha=0.3)
    ax.set_title(f"cycle {name} ({dur:g} s at {S['speeds'][-1]:g} m/s)")
    ax.set_xlabel("r [m]")
axs[0, 0].set_ylabel("z [m]")
show(fig)
table(["cycle", "section", "tip (r, z) [m]", f"t [s] at {S['speeds'][-1]:g} m/s",
       "path speed [m/s]"], rows)

# %% [markdown]
# ## Where the energy goes
#
# Pump power = p_pump·Q/η. With the per-function flows Q_i and load pressures p_i it splits
# exactly into Σ p_i·Q_i (delivered to the cylinders), Σ (p_pump − p_i)·Q_i (throttled across
# the compensators of every function that needs less than the highest pressure) and
# p_pump·Q·(1/η − 1) (pump losses). `evaluate()` returns all of it on a 1 kHz grid
# (`ev.hyd`: `p_pump`, `q_pump`, `power`, `throttle_loss`, `p_load`, `q_act`).

# %%
from planner.trajectory import evaluate

PARTS = ("cylinders", "throttling", "pump losses")


def integral(P, t):
    return float(np.sum(0.5 * (P[1:] + P[:-1]) * np.diff(t)))


def breakdown(ev):
    h = ev.hyd
    parts = dict(cylinders=np.sum(h["p_load"] * h["q_act"], axis=1),
                 throttling=h["throttle_loss"],
                 **{"pump losses": h["power"] - h["p_pump"] * h["q_pump"]})
    out = {k: integral(v, ev.t) for k, v in parts.items()}
    pumping = h["q_pump"] > 1e-4 * pump.max_flow
    setter = np.argmax(h["p_load"], axis=1)
    out.update(total=ev.energy_J,
               volume=integral(h["q_pump"], ev.t),
               mean_p_pump=(integral(h["p_pump"] * h["q_pump"], ev.t)
                            / max(integral(h["q_pump"], ev.t), 1e-12)),
               setter_share={n: float(np.mean(setter[pumping] == i)) if pumping.any() else 0.0
                             for i, n in enumerate(crane.names)})
    assert abs(sum(out[k] for k in PARTS) - ev.energy_J) <= 1e-6 * max(ev.energy_J, 1.0)
    return out


def add(parts):
    tot = {k: sum(p[k] for p in parts) for k in PARTS + ("total", "volume")}
    tot["mean_p_pump"] = (sum(p["mean_p_pump"] * p["volume"] for p in parts)
                          / max(tot["volume"], 1e-12))
    return tot


# %% [markdown]
# ## The local laws
#
# `planner/methods/laws_energy.py` with the gains tuned as the seed did; each law follows the
# time-based cycle command at 100 Hz from the assumed start configuration
# (`follow_command`), the pump flow shared like load-sensing flow-sharing valves.

# %%
from planner.methods import laws_energy as le
from planner.methods.laws import follow_command

LAW_TITLES = dict(jla="JLA", q_optimal="Q-optimal", p1="P-optimal n=1",
                  p1_5="P-optimal n=1.5", p2="P-optimal n=2")


def make_law(key):
    if key == "jla":
        return le.JLA()
    if key == "q_optimal":
        return le.QOptimal()
    return le.POptimal({"p1": 1.0, "p1_5": 1.5, "p2": 2.0}[key])


CASES = [(name, v) for name in S["cycles"] for v in S["speeds"]]
LAWRUN = {}
for name, v in CASES:
    cmd, dur, secs = cycle(name, v)
    q0 = crane.ik(START[name], tele=START_TELE[name])
    for key in S["laws"]:
        res = follow_command(crane, make_law(key), cmd, dur, q0=q0, rate=S["rate"])
        ev = evaluate(crane, res.trajectory)
        LAWRUN[name, v, key] = dict(ev=ev, E=breakdown(ev), err=res.max_path_error_m,
                                    violation=ev.max_limit_violation,
                                    solve_s=res.solve_time_s)
table(["cycle", "speed [m/s]"] + [LAW_TITLES[k] + " [kJ]" for k in S["laws"]]
      + ["largest tracking error [mm]", "largest limit violation"],
      [[name, f"{v:g}"] + [f"{LAWRUN[name, v, k]['E']['total'] / 1e3:.1f}" for k in S["laws"]]
       + [f"{1e3 * max(LAWRUN[name, v, k]['err'] for k in S['laws']):.2f}",
          f"{max(LAWRUN[name, v, k]['violation'] for k in S['laws']):.1e}"]
       for name, v in CASES])

# %% [markdown]
# ## The global planners
#
# * **DP** (`dp(..., objective="energy", tip_speed=...)`): on every straight section of the
#   cycle, the joint path of least pump energy at the section's tip speed (telescope gridded,
#   at most `window` grid steps per stage; the grid is chosen so that the window spans the
#   telescope's rate limit); the telescope is chained from one section to the next — as
#   `benchmarks/seed002_table.py` does. Twice: with the first section's telescope free
#   ("DP, free start") and pinned at the laws' start value ("DP, same start"), because the
#   start pose alone is worth a good part of the saving.
# * **NLP** (`energy_optimal`): per section, the least pump energy from the section's start
#   tip to its end tip within the section's duration, from rest to rest, the tip free to
#   leave the line, the redundancy free at both ends (so the sections need not join: a bound
#   on what path freedom buys, not a cycle a crane could run as is).

# %%
from planner.geometry.paths import Line
from planner.methods.dp import dp
from planner.methods.nlp import MoveNLP, energy_optimal

vmax_tele = float(crane.limit_arrays()["qd_max"][crane.chain.tele])


def dp_cycle(name, v, tele_start=None):
    _, _, secs = cycle(name, v)
    tele, parts, evs, relaxed = tele_start, [], [], 0
    for sec in secs:
        ts = min(0.02, vmax_tele * (S["dp_step"] / sec.path_speed) / S["dp_window"])
        kw = dict(objective="energy", tip_speed=sec.path_speed, step=S["dp_step"],
                  tele_step=ts, window=S["dp_window"], tele_start=tele)
        r = dp(crane, Line(sec.start, sec.end), **kw)
        if not r.ok:  # greedy chaining can dead-end on the pump limit (as the benchmark)
            r = dp(crane, Line(sec.start, sec.end), pump=False, **kw)
            relaxed += 1
        assert r.ok, r.reason
        ev = evaluate(crane, r.trajectory)
        tele = float(r.path_q[-1, crane.chain.tele])
        parts.append(breakdown(ev))
        evs.append((sec, ev))
    return dict(E=add(parts), evs=evs, relaxed=relaxed,
                violation=max(e.max_limit_violation for _, e in evs))


time_nlp = MoveNLP(crane, "time", "free", N=S["nlp_N"])
energy_nlp = MoveNLP(crane, "energy", "free", N=S["nlp_N"])
NLP_CACHE = {}


def nlp_cycle(name, v):
    _, _, secs = cycle(name, v)
    parts, evs, winners = [], [], []
    for sec in secs:
        key = (tuple(np.round(sec.start, 9)), tuple(np.round(sec.end, 9)), sec.t1 - sec.t0)
        if key not in NLP_CACHE:   # the cycles repeat their sections
            res, info = energy_optimal(crane, sec.start, sec.end, sec.t1 - sec.t0,
                                       time_nlp=time_nlp, energy_nlp=energy_nlp)
            assert res.ok, res.reason
            NLP_CACHE[key] = (evaluate(crane, res.trajectory), info["winner"])
        ev, win = NLP_CACHE[key]
        parts.append(breakdown(ev))
        evs.append((sec, ev))
        winners.append(win)
    return dict(E=add(parts), evs=evs, winners=winners,
                violation=max(e.max_limit_violation for _, e in evs))


GLOBAL = {}
for name, v in CASES:
    t0 = time.perf_counter()
    GLOBAL[name, v, "dp"] = dp_cycle(name, v)
    GLOBAL[name, v, "dp_pinned"] = dp_cycle(name, v, tele_start=START_TELE[name])
    t1 = time.perf_counter()
    GLOBAL[name, v, "nlp"] = nlp_cycle(name, v)
    print(f"{name} {v:g} m/s: DP {t1 - t0:.1f} s, NLP {time.perf_counter() - t1:.1f} s "
          f"(NLP sections won by: {', '.join(GLOBAL[name, v, 'nlp']['winners'])}; "
          f"DP sections re-solved without the pump limit: {GLOBAL[name, v, 'dp']['relaxed']})")


# %%
def energy(name, v, m):
    return (LAWRUN[name, v, m] if m in S["laws"] else GLOBAL[name, v, m])["E"]


METHODS = list(S["laws"]) + ["dp_pinned", "dp", "nlp"]
TITLES = dict(LAW_TITLES, dp_pinned="DP, same start (line, same speed)",
              dp="DP, free start (line, same speed)", nlp="NLP (free path, same time)")
rows = []
for name, v in CASES:
    jla = energy(name, v, "jla")["total"]
    rows.append([name, f"{v:g}"] + [
        f"{energy(name, v, m)['total'] / 1e3:.1f}"
        + ("" if m == "jla" else f" ({100 * (1 - energy(name, v, m)['total'] / jla):+.1f} %)")
        for m in METHODS])
table(["cycle", "speed [m/s]"] + [TITLES[m] + " [kJ]" for m in METHODS], rows)
print("in brackets: saving vs JLA (positive = less energy)")

# %% [markdown]
# ### The energy split
#
# Stacked: cylinders / throttling / pump losses per method; the number on top is the
# flow-weighted mean pump pressure.

# %%
shown = [c for c in CASES if c[1] == S["speeds"][-1]]
fig, axs = plt.subplots(1, len(shown), figsize=(5.2 * len(shown), 4.4), squeeze=False,
                        sharey=True)
colors = dict(cylinders="tab:green", throttling="tab:red", **{"pump losses": "0.6"})
for ax, (name, v) in zip(axs[0], shown):
    bottom = np.zeros(len(METHODS))
    for part in PARTS:
        vals = np.array([energy(name, v, m)[part] / 1e3 for m in METHODS])
        ax.bar(range(len(METHODS)), vals, bottom=bottom, color=colors[part], label=part)
        bottom += vals
    for i, m in enumerate(METHODS):
        ax.text(i, bottom[i] + 3, f"{energy(name, v, m)['mean_p_pump'] / 1e6:.1f} MPa",
                ha="center", fontsize=7)
    ax.set_xticks(range(len(METHODS)), [TITLES[m].split(" (")[0] for m in METHODS],
                  rotation=35, ha="right", fontsize=8)
    ax.set_title(f"cycle {name}, {v:g} m/s")
    ax.grid(axis="y", alpha=0.3)
axs[0, 0].set_ylabel("pump energy per cycle [kJ]")
axs[0, 0].legend(fontsize=8, loc="lower left")
show(fig)
rows = []
for name, v in CASES:
    for m in METHODS:
        e = energy(name, v, m)
        rows.append([f"{name} {v:g}", TITLES[m], f"{e['total'] / 1e3:.1f}",
                     f"{100 * e['cylinders'] / e['total']:.0f} %",
                     f"{100 * e['throttling'] / e['total']:.0f} %",
                     f"{100 * e['pump losses'] / e['total']:.0f} %",
                     f"{1e3 * e['volume']:.0f}", f"{e['mean_p_pump'] / 1e6:.1f}"])
table(["case", "method", "energy [kJ]", "cylinders", "throttling", "pump losses",
       "oil pumped [L]", "mean pump pressure [MPa]"], rows)

# %% [markdown]
# ### One section up close
#
# The first working section of the cycle (after the preliminary move) for JLA and the DP:
# the pump pressure follows the highest load pressure — who sets it, and how far the other
# functions sit below it (throttled).

# %%
name, v = shown[0]
_, _, secs = cycle(name, v)
k = 1 if len(secs) > 4 else 0
sec = secs[k]
ev_law = LAWRUN[name, v, "jla"]["ev"]
ev_dp = GLOBAL[name, v, "dp"]["evs"][k][1]
win = (ev_law.t >= sec.t0) & (ev_law.t <= sec.t1)
fig, axs = plt.subplots(2, 2, figsize=(11, 6.5), sharex="col")
for col, (label, t, h, q) in enumerate([
        ("JLA", ev_law.t[win] - sec.t0, {kk: vv[win] for kk, vv in ev_law.hyd.items()},
         ev_law.q[win]),
        ("DP", ev_dp.t, ev_dp.hyd, ev_dp.q)]):
    ax = axs[0, col]
    ax.plot(t, h["p_pump"] / 1e6, "k", lw=2, label="pump")
    for i, n in enumerate(crane.names):
        pl = np.where(h["q_act"][:, i] > 1e-4 * pump.max_flow, h["p_load"][:, i], np.nan)
        ax.plot(t, pl / 1e6, label=f"{n} (load)")
    ax.set_title(f"{label}: section '{labels(name)[k]}' of cycle {name} at {v:g} m/s")
    ax.set_ylabel("pressure [MPa]")
    ax.legend(fontsize=7, ncol=2, loc="best")
    ax.grid(alpha=0.3)
    ax = axs[1, col]
    ax.stackplot(t, np.sum(h["p_load"] * h["q_act"], axis=1) / 1e3, h["throttle_loss"] / 1e3,
                 (h["power"] - h["p_pump"] * h["q_pump"]) / 1e3,
                 colors=[colors[p] for p in PARTS], labels=PARTS)
    ax.set_ylabel("power [kW]")
    ax.set_xlabel("t in the section [s]")
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(alpha=0.3)
show(fig)

fig, ax = plt.subplots(figsize=(10, 3.2))
tele = crane.chain.tele
for m in ("jla", S["laws"][-1]):
    e = LAWRUN[name, v, m]["ev"]
    ax.plot(e.t, e.q[:, tele], label=TITLES[m])
for m, style in (("dp", "k-"), ("dp_pinned", "k--")):
    for i, (sc, e) in enumerate(GLOBAL[name, v, m]["evs"]):
        ax.plot(sc.t0 + e.t, e.q[:, tele], style, lw=2,
                label=TITLES[m].split(" (")[0] if i == 0 else None)
ax.set_xlabel("t [s]")
ax.set_ylabel("telescope [m]")
ax.set_title(f"cycle {name} at {v:g} m/s: the telescope (the redundancy) over the cycle")
ax.legend(fontsize=8)
ax.grid(alpha=0.3)
show(fig)


# %% [markdown]
# ## Answer

# %%
def pct(vals, spec="+.1f"):
    return span(vals, 100.0, spec, " %")


def saving(n, v, m, ref="jla"):
    return 1 - energy(n, v, m)["total"] / energy(n, v, ref)["total"]


lines = []
for name, v in CASES:
    jla = energy(name, v, "jla")["total"]
    best = min(S["laws"], key=lambda m: energy(name, v, m)["total"])
    eb = energy(name, v, best)["total"]
    lines.append(
        f"- cycle **{name}** at {v:g} m/s: JLA {jla / 1e3:.1f} kJ; best local law "
        f"{TITLES[best]} {eb / 1e3:.1f} kJ; DP on the same lines from the same start "
        f"{energy(name, v, 'dp_pinned')['total'] / 1e3:.1f} kJ "
        f"({100 * saving(name, v, 'dp_pinned'):+.1f} % vs JLA), free start "
        f"{energy(name, v, 'dp')['total'] / 1e3:.1f} kJ ({100 * saving(name, v, 'dp'):+.1f} %); "
        f"NLP free path {energy(name, v, 'nlp')['total'] / 1e3:.1f} kJ "
        f"({100 * saving(name, v, 'nlp'):+.1f} %).")
crit = [m for m in S["laws"] if m != "jla"]
sav_local = [max(saving(n, v, m) for m in crit) for n, v in CASES]
share = lambda part, ms: [energy(n, v, m)[part] / energy(n, v, m)["total"]
                          for n, v in CASES for m in ms]
p_of = lambda ms: [energy(n, v, m)["mean_p_pump"] for n, v in CASES for m in ms]
vol_of = lambda ms: [energy(n, v, m)["volume"] for n, v in CASES for m in ms]
setter = {j: np.mean([LAWRUN[n, v, "jla"]["E"]["setter_share"][j] for n, v in CASES])
          for j in crane.names}
top = max(setter, key=setter.get)
lines += [
    "",
    f"**1. Local laws.** The best energy criterion (Q- or P-optimal) changes the energy by "
    f"{pct(sav_local)} against JLA (positive: a saving; seed 002 reported up to +26.9 % for "
    "P-optimal n = 2 on cycle v at 1 m/s).",
    f"**2. Global.** The DP along the same lines at the same speed saves "
    f"{pct([saving(n, v, 'dp_pinned') for n, v in CASES])} against JLA from the laws' "
    f"start pose and {pct([saving(n, v, 'dp') for n, v in CASES])} when it may choose "
    f"the start telescope; leaving the line (NLP, rest to rest in the same time) "
    f"{pct([saving(n, v, 'nlp') for n, v in CASES])}.",
    f"**3. Where it goes.** Throttling takes {pct(share('throttling', S['laws']), '.0f')} "
    f"of the pump energy with the local laws and "
    f"{pct(share('throttling', ['dp_pinned', 'dp']), '.0f')} with the DP; the "
    f"cylinders get {pct(share('cylinders', S['laws']), '.0f')} and "
    f"{pct(share('cylinders', ['dp_pinned', 'dp']), '.0f')}; the pump losses are the "
    f"fixed share 1 − η = {100 * (1 - pump.efficiency):.0f} %. With JLA the {top} cylinder "
    f"sets the pump pressure {100 * setter[top]:.0f} % of the pumping time. Mean pump "
    f"pressure {span(p_of(S['laws']), 1e-6, unit=' MPa')} with the laws vs "
    f"{span(p_of(['dp_pinned', 'dp']), 1e-6, unit=' MPa')} with the DP; oil pumped "
    f"{span(vol_of(S['laws']), 1e3, '.0f', ' L')} vs "
    f"{span(vol_of(['dp_pinned', 'dp']), 1e3, '.0f', ' L')} per cycle.",
]
display(Markdown("\n\n".join(lines)))
print(f"run time {time.perf_counter() - T_START:.1f} s with the {'small' if SMALL else 'full'} "
      "settings")
