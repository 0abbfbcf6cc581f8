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
# # Seed 000 revisited: local laws vs the Bellman DP vs the NLP (Cranab 850)
#
# **Question.** Seed 000 drove the tip of a Cranab 850 forwarder crane along three straight
# moves — A–B (reach out), B–C (lower), A–C (diagonal), with A = (1.5, 1.0), B = (5.5, 1.0),
# C = (5.5, −3.0) m as (r, z) at slew 0 — with three *local* redundancy laws (least norm,
# maximum velocity, maximum lifting capacity) and compared them with a *global* Bellman DP
# (Tables 8.1 / 8.2). With the link lengths the seed lost refitted to its DP times:
#
# 1. does our DP reproduce the seed's DP times,
# 2. how much time do the local laws leave on the table,
# 3. how far is the DP (a grid) from the continuous optimum on the same line (an NLP), and what
#    does a real move cost — from rest to rest within acceleration, jerk and pump limits, the
#    tip free to leave the line?
#
# Every trajectory below is judged by the same `evaluate()`; every number is computed here.

# %%
# %matplotlib inline
# Settings. CRANE_NB_SMALL=1 (set by the test suite): small settings that run in seconds;
# otherwise the full study (`make notebooks`). CRANE_NB_OUT: where figure files go.
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Markdown, display
from nbtools import fmt, show, show_file, study, table

SMALL_SETTINGS = dict(dp_step=0.02, dp_tele_step=0.02, dp_window=5, kin_N=40, free_N=20,
                      law_rate=100.0, speeds=(1.0, 2.5))
FULL_SETTINGS = dict(dp_step=0.01, dp_tele_step=0.01, dp_window=5, kin_N=100, free_N=40,
                     law_rate=100.0, speeds=(1.0, 2.5))
SMALL, S, OUT, T_START = study(SMALL_SETTINGS, FULL_SETTINGS)  # reads CRANE_NB_SMALL

# %% [markdown]
# ## The machine and its fitted geometry
#
# Seed 000 gives the joint ranges and speeds of the Cranab 850 but its figure with the link
# lengths is lost. `tools/fit_cranab850.py` fitted the boom-foot height d0, the boom d1 and
# the outer boom d2 so that the seed's DP (Δ = 0.01 m, telescope grid 0.01 m, q = 5, speed
# limits only) reproduces Table 8.1; the spec `planner/problems/cranes/cranab850.toml` carries the
# result, the fit record is `benchmarks/results/cranab850_fit.json`.

# %%
import json

import planner
from planner import Crane
from planner.bounds import lower_bound

crane = Crane.from_id("cranab850")
spec = crane.spec
geom = dict(d0=spec.joints[0].dh.d, d1=spec.joints[1].dh.a, d2=spec.joints[3].dh.d)
fit_file = (Path(planner.__file__).resolve().parents[1] / "benchmarks" / "results"
            / "cranab850_fit.json")
fit = json.loads(fit_file.read_text()) if fit_file.exists() else None
table(["length", "in the spec [m]", "fit record [m]"],
      [[k, f"{v:.3f}", f"{fit[k]:.3f}" if fit else "(record not shipped)"]
       for k, v in geom.items()])
if fit:
    assert all(abs(geom[k] - fit[k]) < 1e-9 for k in geom), "spec and fit record disagree"
    print(f"fit: {fit['method']}\nDP times of the fit {fit['dp_times_s']} s vs Table 8.1 "
          f"{fit['table_8_1_s']} s (RMS relative error {100 * fit['rms_relative_error']:.1f} %)")
L = crane.limit_arrays()
table(["joint", "range", "speed limit"],
      [[j.name, f"{np.degrees(L['q_min'][i]):.0f}° … {np.degrees(L['q_max'][i]):.0f}°"
        if j.revolute else f"{L['q_min'][i]:.2f} … {L['q_max'][i]:.2f} m",
        f"{L['qd_max'][i]:.2f} {'rad/s' if j.revolute else 'm/s'}"]
       for i, j in enumerate(spec.joints)])

# %%
from planner.plots import workspace_extent, workspace_figure

POINTS = dict(A=(1.5, 1.0, 0.0), B=(5.5, 1.0, 0.0), C=(5.5, -3.0, 0.0))
MOVES = ("AB", "BC", "AC")
# seed 000, Tables 8.1 (DP) and 8.2 (laws at a commanded tip speed): the reference values
SEED_DP = dict(AB=1.15, BC=0.89, AC=1.18)
SEED_LAW = {("max_velocity", 1.0): (4.00, 4.00, 5.67), ("max_velocity", 2.5): (1.6, 1.6, 2.28),
            ("max_lift", 1.0): (4.00, 4.05, 5.76), ("max_lift", 2.5): (1.7, 1.89, 2.81)}
workspace_figure(crane, OUT / "workspace_cranab850.png")
ws = workspace_extent(crane)
show_file(OUT / "workspace_cranab850.png")
print(f"max reach {ws['r_max']:.2f} m; tip height {ws['z_min']:.2f} … {ws['z_max']:.2f} m")

# %% [markdown]
# ## The global planners: DP on the line, NLP on the line, NLP free
#
# * **DP** (`planner/methods/dp.py`): Bellman recursion over stations along the line × a
#   telescope grid, the slowest joint (or the pump) deciding each edge's time — the seed's
#   kinematic model; it starts and ends at speed.
# * **NLP on the line** (`kinematic_line_nlp`): the same model (velocity limits only, tip on
#   the line) but continuous — no grid — warm-started from the DP: the continuous optimum the
#   DP approximates.
# * **NLP free** (`MoveNLP`, time objective): what a real move needs — rest to rest, jerk-,
#   acceleration- and pump-limited, the tip free to leave the line.
#
# The lower bound is each joint's distance over its speed limit, minimised over the telescope
# at both ends.

# %%
from planner.geometry.paths import Line
from planner.methods.dp import dp
from planner.methods.nlp import MoveNLP, kinematic_line_nlp
from planner.trajectory import evaluate


def stations(a, b, step):
    return max(2, int(round(max(abs(b[0] - a[0]), abs(b[1] - a[1])) / step)))


def entry(status, time_s, traj=None, solve_s=float("nan"), **kw):
    ev = evaluate(crane, traj) if traj is not None else None
    return dict(status=status, time=time_s if status == "ok" else float("nan"), traj=traj,
                ev=ev, solve_s=solve_s,
                violation=ev.max_limit_violation if ev is not None else float("nan"), **kw)


R = {}
free_nlp = MoveNLP(crane, "time", "free", N=S["free_N"])
for mv in MOVES:
    a, b = POINTS[mv[0]], POINTS[mv[1]]
    lb = lower_bound(crane, a, b)
    R[mv, "bound"] = dict(time=lb.velocity_s, rest=lb.rest_to_rest_s)
    r = dp(crane, Line(a, b), stages=stations(a, b, S["dp_step"]),
           tele_step=S["dp_tele_step"], window=S["dp_window"])
    R[mv, "dp"] = entry(r.status, r.duration_s, r.trajectory, r.solve_time_s)
    k = kinematic_line_nlp(crane, a, b, N=S["kin_N"], w0_traj=r.trajectory)
    R[mv, "nlp_line"] = entry(k.status, k.duration_s, k.trajectory, k.solve_time_s)
    f = free_nlp.solve(a, b)
    R[mv, "nlp_free"] = entry(f.status, f.duration_s, f.trajectory, f.solve_time_s)

table(["move", "velocity bound [s]", "DP [s]", "seed DP [s]", "NLP on the line [s]",
       "NLP free, rest to rest [s]", "rest-to-rest bound [s]", "largest limit violation"],
      [[f"{mv[0]}–{mv[1]}", fmt(R[mv, "bound"]["time"]), fmt(R[mv, "dp"]["time"]),
        f"{SEED_DP[mv]:.2f}", fmt(R[mv, "nlp_line"]["time"]), fmt(R[mv, "nlp_free"]["time"]),
        fmt(R[mv, "bound"]["rest"]),
        f"{max(R[mv, m]['violation'] for m in ('dp', 'nlp_line', 'nlp_free')):.1e}"]
       for mv in MOVES])
print("solve times [s]: " + ", ".join(
    f"{mv} DP {R[mv, 'dp']['solve_s']:.2f} / line NLP {R[mv, 'nlp_line']['solve_s']:.2f} / "
    f"free NLP {R[mv, 'nlp_free']['solve_s']:.2f}" for mv in MOVES))

# %% [markdown]
# ## The local laws
#
# `planner/methods/laws.py`: at 100 Hz each law turns the commanded tip velocity (the line at
# the commanded tip speed, plus a drift correction) into joint rates; when a joint saturates
# the whole command is scaled down (β < 1) and the tip slows. *Least norm*: the
# pseudo-inverse; *maximum velocity*: the rates that keep β largest; *maximum lift*: the
# telescope as a function of the distance to the lifting-capacity centre (seed 000's d3(ρ)).

# %%
from planner.methods.laws import LAWS, follow

LAW_NAMES = ("least_norm", "max_velocity", "max_lift")
for mv in MOVES:
    a, b = POINTS[mv[0]], POINTS[mv[1]]
    for law in LAW_NAMES:
        for v in S["speeds"]:
            res = follow(crane, Line(a, b), LAWS[law](), v, rate=S["law_rate"])
            R[mv, law, v] = entry(res.status, res.duration_s, res.trajectory,
                                  res.solve_time_s, reason=res.reason, min_beta=res.min_beta)

rows = []
for law in LAW_NAMES:
    for v in S["speeds"]:
        seed = SEED_LAW.get((law, v))
        cells = []
        for i, mv in enumerate(MOVES):
            e = R[mv, law, v]
            t = fmt(e["time"]) if e["status"] == "ok" else e["status"]
            cells.append(t + (f" ({seed[i]:.2f})" if seed else ""))
        rows.append([law, f"{v:g} m/s"] + cells)
table(["law", "tip speed", "A–B [s] (seed)", "B–C [s] (seed)", "A–C [s] (seed)"], rows)
for key, e in R.items():
    if len(key) == 3 and e["status"] != "ok":
        print(f"{key[1]} at {key[2]:g} m/s on {key[0]}: {e['status']} — {e['reason']}")

# %% [markdown]
# ## Who is fastest, move by move
#
# Bars: the planners' times; open markers: the seed's values. The local laws at 1 m/s are
# bounded by the commanded speed (path length / 1 m/s); at 2.5 m/s a joint saturates on
# every move and the law slows down.

# %%
methods = [("dp", "DP"), ("nlp_line", "NLP on the line"), ("nlp_free", "NLP free, rest to rest")]
methods += [((law, 2.5), f"{law} 2.5 m/s") for law in LAW_NAMES if 2.5 in S["speeds"]]
fig, ax = plt.subplots(figsize=(10, 4.2))
w = 0.8 / len(methods)
x = np.arange(len(MOVES))
keys = [k for k, _ in methods]


def pos(j):
    return x + (j - (len(methods) - 1) / 2) * w


for j, (key, label) in enumerate(methods):
    vals = [R[(mv,) + (key if isinstance(key, tuple) else (key,))]["time"] for mv in MOVES]
    ax.bar(pos(j), np.nan_to_num(vals), w, label=label)
    for xi, v in zip(pos(j), vals):
        if not np.isfinite(v):
            ax.text(xi, 0.05, "stalled", rotation=90, ha="center", va="bottom", fontsize=7)
ax.plot(pos(0), [SEED_DP[mv] for mv in MOVES], "k^", mfc="none", label="seed DP (Table 8.1)")
if ("max_velocity", 2.5) in keys:
    ax.plot(pos(keys.index(("max_velocity", 2.5))), SEED_LAW["max_velocity", 2.5], "ks",
            mfc="none", label="seed max-velocity 2.5 m/s (Table 8.2)")
ax.hlines([R[mv, "bound"]["time"] for mv in MOVES], x - 0.42, x + 0.42, colors="r", lw=1.5,
          label="velocity lower bound")
ax.set_xticks(x, [f"{m[0]}–{m[1]}" for m in MOVES])
ax.set_ylabel("move time [s]")
ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
ax.grid(axis="y", alpha=0.3)
ax.set_title("cranab850: time of the seed-000 moves by method")
show(fig)

# %% [markdown]
# ## How the global planners use the redundancy
#
# The DP on A–C (joint rates relative to their limits: the planner rides a limit the whole
# way), then the telescope along the path and the path progress over time for the DP, the
# line NLP and the laws: the global methods pick the telescope so that the slowest joint is
# as fast as possible; the laws fix it by a local rule.

# %%
from planner.plots import trajectory_figure

mv = "AC"
trajectory_figure(crane, R[mv, "dp"]["ev"], OUT / "dp_AC.png",
                  f"cranab850 A–C, minimum-time DP: {R[mv, 'dp']['time']:.3f} s "
                  f"(seed {SEED_DP[mv]:.2f} s)")
show_file(OUT / "dp_AC.png")


def progress(ev, a, b):
    """Share of the line covered (projection of the tip onto A→B in the r–z plane)."""
    d = np.subtract(b[:2], a[:2])
    return (ev.tip[:, :2] - np.asarray(a[:2])) @ d / (d @ d)


a, b = POINTS[mv[0]], POINTS[mv[1]]
tele = crane.chain.tele
curves = [("dp", "DP"), ("nlp_line", "NLP on the line")]
curves += [((law, v), f"{law} {v:g} m/s") for law in LAW_NAMES for v in S["speeds"][-1:]]
fig, axs = plt.subplots(1, 2, figsize=(11, 4))
for key, label in curves:
    e = R[(mv,) + (key if isinstance(key, tuple) else (key,))]
    if e["status"] != "ok":
        continue
    s = progress(e["ev"], a, b)
    axs[0].plot(e["ev"].t, s, label=f"{label} ({e['time']:.2f} s)")
    axs[1].plot(s, e["ev"].q[:, tele], label=label)
axs[0].set_xlabel("t [s]")
axs[0].set_ylabel("progress along A–C")
axs[1].set_xlabel("progress along A–C")
axs[1].set_ylabel("telescope [m]")
for ax in axs:
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
fig.suptitle("A–C: progress over time, and the telescope along the path")
show(fig)

# %% [markdown]
# ## Leaving the line
#
# The free NLP is a different problem — rest to rest with the (assumed) acceleration, jerk and
# pump limits of the spec — and needs no straight line: its tip paths (the crane drawn at the
# start of each move) against the seed's lines.

# %%
fig, ax = plt.subplots(figsize=(7, 5.5))
for i, mv in enumerate(MOVES):
    a, b = POINTS[mv[0]], POINTS[mv[1]]
    ax.plot([a[0], b[0]], [a[1], b[1]], "--", color=f"C{i}", lw=1)
    e = R[mv, "nlp_free"]
    if e["status"] == "ok":
        ax.plot(e["ev"].tip[:, 0], e["ev"].tip[:, 1], color=f"C{i}", lw=2,
                label=f"{mv[0]}–{mv[1]} free NLP {e['time']:.2f} s "
                      f"(DP on the line {R[mv, 'dp']['time']:.2f} s)")
        o = crane.frame_origins(e["traj"].q[0])
        ax.plot(np.hypot(o[:, 0], o[:, 1]), o[:, 2], "o-", color=f"C{i}", alpha=0.35, lw=3)
for name, p in POINTS.items():
    ax.annotate(name, p[:2], xytext=(5, 5), textcoords="offset points", fontsize=12)
ax.set_aspect("equal")
ax.set_xlabel("r [m]")
ax.set_ylabel("z [m]")
ax.grid(alpha=0.3)
ax.legend(fontsize=8, loc="lower left")
ax.set_title("tip paths: free rest-to-rest NLP (solid) vs the straight lines (dashed)")
show(fig)

# %% [markdown]
# ## Answer

# %%
dp_t = np.array([R[mv, "dp"]["time"] for mv in MOVES])
seed_dp = np.array([SEED_DP[mv] for mv in MOVES])
line_t = np.array([R[mv, "nlp_line"]["time"] for mv in MOVES])
free_t = np.array([R[mv, "nlp_free"]["time"] for mv in MOVES])
bound_t = np.array([R[mv, "bound"]["time"] for mv in MOVES])
vfast = max(S["speeds"])
best_law = []
for mv in MOVES:
    ok = [(R[mv, law, vfast]["time"], law) for law in LAW_NAMES
          if R[mv, law, vfast]["status"] == "ok"]
    best_law.append(min(ok) if ok else (float("nan"), "none"))
ratio = np.array([t for t, _ in best_law]) / dp_t
stalled = [f"{law} on {mv[0]}–{mv[1]}" for mv in MOVES for law in LAW_NAMES
           if R[mv, law, vfast]["status"] != "ok"]
dev = (dp_t - seed_dp) / seed_dp
gap = (dp_t - line_t) / line_t
worst_v = max(R[k]["violation"] for k in R if "violation" in R[k] and R[k]["status"] == "ok")
lines = [
    "**1. DP vs the seed.** Our DP takes " + ", ".join(
        f"{mv[0]}–{mv[1]} {t:.3f} s (seed {s:.2f} s)" for mv, t, s in zip(MOVES, dp_t, seed_dp))
    + f": within {100 * np.max(np.abs(dev)):.1f} % of Table 8.1"
    + (" (small grid)" if SMALL else "") + ".",
    f"**2. Local laws.** At {vfast:g} m/s the best local law needs "
    + ", ".join(f"{t:.3f} s ({law}) on {mv[0]}–{mv[1]}"
                for mv, (t, law) in zip(MOVES, best_law))
    + f" — {np.nanmin(ratio):.2f}× to {np.nanmax(ratio):.2f}× the DP's time"
    + (f"; stalled: {', '.join(stalled)}" if stalled else "") + ".",
    f"**3. Grid vs continuum.** The NLP on the same line is "
    f"{100 * np.min(gap):.1f}–{100 * np.max(gap):.1f} % faster than the DP "
    f"({', '.join(f'{t:.3f} s' for t in line_t)}); the velocity bound is "
    f"{', '.join(f'{t:.3f} s' for t in bound_t)}.",
    f"**Real moves.** From rest to rest within acceleration, jerk and pump limits and free to "
    f"leave the line the NLP needs {', '.join(f'{t:.3f} s' for t in free_t)} — "
    f"{np.min(free_t / dp_t):.2f}× to {np.max(free_t / dp_t):.2f}× the seed-model DP time: "
    "the seed's kinematic comparison leaves out most of what a real move costs.",
    f"Every trajectory was judged by `evaluate()`; the largest violation of a limit a "
    f"method claims is {worst_v:.1e} (relative).",
]
display(Markdown("\n\n".join(lines)))
print(f"run time {time.perf_counter() - T_START:.1f} s with the {'small' if SMALL else 'full'} "
      "settings")
