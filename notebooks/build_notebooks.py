"""Generate the notebook studies (notebooks/*.ipynb) from the cell sources in this file.

    python notebooks/build_notebooks.py [--out notebooks] [--check]

The .ipynb files are committed WITHOUT outputs and are a pure function of this file (cell ids
are derived from the notebook name and cell index), so a review reads the sources here and a
rebuild reproduces the committed files byte for byte (``--check`` exits 1 when they differ).
Execute them with ``make notebooks`` (full settings, into build/notebooks) or
``python notebooks/run_notebooks.py --small`` (the tests' settings).

Every notebook opens with its question, reads ``CRANE_NB_SMALL`` in its first code cell
(``1``: small settings — coarser grids, fewer intervals, shorter recordings — for the test
suite; otherwise the full study) and ends with a cell that prints the answer in numbers computed
from the results.
"""
from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path

import nbformat

HERE = Path(__file__).resolve().parent


def md(text):
    return ("markdown", textwrap.dedent(text).strip("\n"))


def code(text):
    return ("code", textwrap.dedent(text).strip("\n"))


# ----------------------------------------------------------------------------- shared cells
SETUP = r'''
%matplotlib inline
# Settings. CRANE_NB_SMALL=1 (set by the test suite): small settings that run in seconds;
# otherwise the full study (`make notebooks`). CRANE_NB_OUT: where figure files go.
import io
import os
import tempfile
import time
from pathlib import Path

SMALL = os.environ.get("CRANE_NB_SMALL", "0") == "1"
SMALL_SETTINGS = @SMALL@
FULL_SETTINGS = @FULL@
S = SMALL_SETTINGS if SMALL else FULL_SETTINGS
OUT = Path(os.environ.get("CRANE_NB_OUT") or tempfile.mkdtemp(prefix="crane-nb-"))
OUT.mkdir(parents=True, exist_ok=True)
T_START = time.perf_counter()

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Image, Markdown, display


def show(fig):
    """Show a figure inline as a PNG (independent of the backend: planner.plots uses Agg)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    display(Image(data=buf.getvalue()))


def show_file(path):
    display(Image(filename=str(path)))


def table(header, rows):
    """A markdown table from a header and rows of cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    display(Markdown("\n".join(lines)))


def fmt(x, spec=".3f", none="—"):
    return none if x is None or not np.isfinite(x) else format(x, spec)


def span(vals, scale=1.0, spec=".1f", unit=""):
    """'lo to hi unit' of scaled values (one number when they print alike)."""
    lo, hi = format(scale * min(vals), spec), format(scale * max(vals), spec)
    return f"{lo}{unit}" if lo == hi else f"{lo} to {hi}{unit}"


print(f"settings: {'small' if SMALL else 'full'} {S}")
'''

FOOTER = r'''
print(f"run time {time.perf_counter() - T_START:.1f} s with the {'small' if SMALL else 'full'} "
      "settings")
'''


def final(text):
    """The closing cell: the answer, then the run time."""
    return ("code", textwrap.dedent(text).strip("\n") + "\n" + FOOTER.strip("\n"))


def setup_cell(small: dict, full: dict):
    return code(SETUP.replace("@SMALL@", repr(small)).replace("@FULL@", repr(full)))


# ----------------------------------------------------------------------------- (a) seed 000
A = [
    md(r'''
    # Seed 000 revisited: local laws vs the Bellman DP vs the NLP (Cranab 850)

    **Question.** Seed 000 drove the tip of a Cranab 850 forwarder crane along three straight
    moves — A–B (reach out), B–C (lower), A–C (diagonal), with A = (1.5, 1.0), B = (5.5, 1.0),
    C = (5.5, −3.0) m as (r, z) at slew 0 — with three *local* redundancy laws (least norm,
    maximum velocity, maximum lifting capacity) and compared them with a *global* Bellman DP
    (Tables 8.1 / 8.2). With the link lengths the seed lost refitted to its DP times:

    1. does our DP reproduce the seed's DP times,
    2. how much time do the local laws leave on the table,
    3. how far is the DP (a grid) from the continuous optimum on the same line (an NLP), and what
       does a real move cost — from rest to rest within acceleration, jerk and pump limits, the
       tip free to leave the line?

    Every trajectory below is judged by the same `evaluate()`; every number is computed here.
    '''),
    setup_cell(
        small=dict(dp_step=0.02, dp_tele_step=0.02, dp_window=5, kin_N=40, free_N=20,
                   law_rate=100.0, speeds=(1.0, 2.5)),
        full=dict(dp_step=0.01, dp_tele_step=0.01, dp_window=5, kin_N=100, free_N=40,
                  law_rate=100.0, speeds=(1.0, 2.5))),
    md(r'''
    ## The machine and its fitted geometry

    Seed 000 gives the joint ranges and speeds of the Cranab 850 but its figure with the link
    lengths is lost. `tools/fit_cranab850.py` fitted the boom-foot height d0, the boom d1 and
    the outer boom d2 so that the seed's DP (Δ = 0.01 m, telescope grid 0.01 m, q = 5, speed
    limits only) reproduces Table 8.1; the spec `problems/cranes/cranab850.toml` carries the
    result, the fit record is `benchmarks/results/cranab850_fit.json`.
    '''),
    code(r'''
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
    '''),
    code(r'''
    from planner.plots import workspace_figure

    POINTS = dict(A=(1.5, 1.0, 0.0), B=(5.5, 1.0, 0.0), C=(5.5, -3.0, 0.0))
    MOVES = ("AB", "BC", "AC")
    # seed 000, Tables 8.1 (DP) and 8.2 (laws at a commanded tip speed): the reference values
    SEED_DP = dict(AB=1.15, BC=0.89, AC=1.18)
    SEED_LAW = {("max_velocity", 1.0): (4.00, 4.00, 5.67), ("max_velocity", 2.5): (1.6, 1.6, 2.28),
                ("max_lift", 1.0): (4.00, 4.05, 5.76), ("max_lift", 2.5): (1.7, 1.89, 2.81)}
    ws = workspace_figure(crane, OUT / "workspace_cranab850.png")
    show_file(OUT / "workspace_cranab850.png")
    print(f"max reach {ws['r_max']:.2f} m; tip height {ws['z_min']:.2f} … {ws['z_max']:.2f} m")
    '''),
    md(r'''
    ## The global planners: DP on the line, NLP on the line, NLP free

    * **DP** (`planner/methods/dp.py`): Bellman recursion over stations along the line × a
      telescope grid, the slowest joint (or the pump) deciding each edge's time — the seed's
      kinematic model; it starts and ends at speed.
    * **NLP on the line** (`kinematic_line_nlp`): the same model (velocity limits only, tip on
      the line) but continuous — no grid — warm-started from the DP: the continuous optimum the
      DP approximates.
    * **NLP free** (`MoveNLP`, time objective): what a real move needs — rest to rest, jerk-,
      acceleration- and pump-limited, the tip free to leave the line.

    The lower bound is each joint's distance over its speed limit, minimised over the telescope
    at both ends.
    '''),
    code(r'''
    from planner.methods.dp import dp
    from planner.methods.nlp import MoveNLP, kinematic_line_nlp
    from planner.geometry.paths import Line
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
    '''),
    md(r'''
    ## The local laws

    `planner/methods/laws.py`: at 100 Hz each law turns the commanded tip velocity (the line at
    the commanded tip speed, plus a drift correction) into joint rates; when a joint saturates
    the whole command is scaled down (β < 1) and the tip slows. *Least norm*: the
    pseudo-inverse; *maximum velocity*: the rates that keep β largest; *maximum lift*: the
    telescope as a function of the distance to the lifting-capacity centre (seed 000's d3(ρ)).
    '''),
    code(r'''
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
    '''),
    md(r'''
    ## Who is fastest, move by move

    Bars: the planners' times; open markers: the seed's values. The local laws at 1 m/s are
    bounded by the commanded speed (path length / 1 m/s); at 2.5 m/s a joint saturates on
    every move and the law slows down.
    '''),
    code(r'''
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
    '''),
    md(r'''
    ## How the global planners use the redundancy

    The DP on A–C (joint rates relative to their limits: the planner rides a limit the whole
    way), then the telescope along the path and the path progress over time for the DP, the
    line NLP and the laws: the global methods pick the telescope so that the slowest joint is
    as fast as possible; the laws fix it by a local rule.
    '''),
    code(r'''
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
    '''),
    md(r'''
    ## Leaving the line

    The free NLP is a different problem — rest to rest with the (assumed) acceleration, jerk and
    pump limits of the spec — and needs no straight line: its tip paths (the crane drawn at the
    start of each move) against the seed's lines.
    '''),
    code(r'''
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
    '''),
    md("## Answer"),
    final(r'''
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
        f"**1. DP vs the seed.** Our DP takes " + ", ".join(
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
    '''),
]


# ----------------------------------------------------------------------------- (b) energy
B = [
    md(r'''
    # Energy: local laws vs global planners on the seed-002 cycles (S100F)

    **Question.** Seed 002 proposed local redundancy laws for a forwarder crane that resolve the
    tip command in cylinder space with an energy criterion — JLA (joint-limit avoidance only),
    Q-optimal (least pump flow), P-optimal (least pressure-weighted flow, exponent n) — and
    measured them on three test cycles (horizontal h, vertical v, diagonal d). On our S100F
    model (load-sensing pump, single-acting lift cylinder):

    1. how much pump energy does each local law use per cycle,
    2. how much does a *global* planner save on the same cycles — the Bellman DP along the same
       straight sections at the same tip speed, and the NLP (free path, rest to rest, in the
       same time per section),
    3. where does the energy go: into the cylinders (load pressure × flow), into throttling
       across the valves (pump pressure − load pressure) × flow, or into the pump?
    '''),
    setup_cell(
        small=dict(cycles=("d",), speeds=(1.0,), laws=("jla", "q_optimal", "p1", "p2"),
                   rate=100.0, dp_step=0.05, dp_window=3, nlp_N=20),
        full=dict(cycles=("h", "v", "d"), speeds=(0.5, 1.0),
                  laws=("jla", "q_optimal", "p1", "p1_5", "p2"), rate=100.0, dp_step=0.02,
                  dp_window=3, nlp_N=40)),
    md(r'''
    ## The machine and the cycles

    `planner/cycles.py` encodes seed 002's cycles (5 s rest, two extend/retract sections along
    one line, pauses; per-axis tip speed 0.5 or 1 m/s); the start points and the preliminary
    moves are assumptions (the seed gives neither). The pump is load sensing: its pressure is
    the highest load pressure of the functions that draw flow plus a margin, and every litre it
    delivers costs that pressure — whichever function it goes to.
    '''),
    code(r'''
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
    '''),
    md(r'''
    ## Where the energy goes

    Pump power = p_pump·Q/η. With the per-function flows Q_i and load pressures p_i it splits
    exactly into Σ p_i·Q_i (delivered to the cylinders), Σ (p_pump − p_i)·Q_i (throttled across
    the compensators of every function that needs less than the highest pressure) and
    p_pump·Q·(1/η − 1) (pump losses). `evaluate()` returns all of it on a 1 kHz grid
    (`ev.hyd`: `p_pump`, `q_pump`, `power`, `throttle_loss`, `p_load`, `q_act`).
    '''),
    code(r'''
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
    '''),
    md(r'''
    ## The local laws

    `planner/methods/laws_energy.py` with the gains tuned as the seed did; each law follows the
    time-based cycle command at 100 Hz from the assumed start configuration
    (`follow_command`), the pump flow shared like load-sensing flow-sharing valves.
    '''),
    code(r'''
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
    '''),
    md(r'''
    ## The global planners

    * **DP** (`dp(..., objective="energy", tip_speed=...)`): on every straight section of the
      cycle, the joint path of least pump energy at the section's tip speed (telescope gridded,
      at most `window` grid steps per stage; the grid is chosen so that the window spans the
      telescope's rate limit); the telescope is chained from one section to the next — as
      `benchmarks/seed002_table.py` does. Twice: with the first section's telescope free
      ("DP, free start") and pinned at the laws' start value ("DP, same start"), because the
      start pose alone is worth a good part of the saving.
    * **NLP** (`energy_optimal`): per section, the least pump energy from the section's start
      tip to its end tip within the section's duration, from rest to rest, the tip free to
      leave the line, the redundancy free at both ends (so the sections need not join: a bound
      on what path freedom buys, not a cycle a crane could run as is).
    '''),
    code(r'''
    from planner.methods.dp import dp
    from planner.methods.nlp import MoveNLP, energy_optimal
    from planner.geometry.paths import Line

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
    '''),
    code(r'''
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
    '''),
    md(r'''
    ### The energy split

    Stacked: cylinders / throttling / pump losses per method; the number on top is the
    flow-weighted mean pump pressure.
    '''),
    code(r'''
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
    '''),
    md(r'''
    ### One section up close

    The first working section of the cycle (after the preliminary move) for JLA and the DP:
    the pump pressure follows the highest load pressure — who sets it, and how far the other
    functions sit below it (throttled).
    '''),
    code(r'''
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
    '''),
    md("## Answer"),
    final(r'''
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
    '''),
]


# ----------------------------------------------------------------------------- (c) open loop
C = [
    md(r'''
    # Open loop: seed 003's circle and parabola on the Umeå lab crane

    **Question.** Seed 003 plans the tip of a small lab crane along a circle and a parabola in
    the phase plane (θ, θ̇) of the path parameter — with the telescope as a designed function
    φ4(θ) — rides 90 % of the velocity envelope, redesigns the start (and end) so that the
    motion starts from rest (Ruckig), and replays the result *open loop* as valve commands.

    1. How fast can each path be driven, and what does the optimised telescope buy over a
       constant one?
    2. What does starting (and stopping) at rest cost, and how does the seed's design compare
       with TOPP-RA on the same joint path once acceleration and the pump are respected?
    3. Open loop, how far does the tip drift from the plan when the commands are replayed on a
       plant that is not quite the model (start pose off by 1° / 2 cm, valve gains ±2 %, pump
       −10 %) — and how much of that drift is the plan's own fault?
    '''),
    setup_cell(
        small=dict(opt=dict(n_theta=121, maxfev=800, restarts=0, n_fine=801), profile_n=801,
                   topp_grid=200, topp_samples=301, rate=50.0),
        full=dict(opt=dict(), profile_n=2001, topp_grid=400, topp_samples=501, rate=50.0)),
    md(r'''
    ## The crane and the paths

    `umea-lab`: exact DH table and velocity limits from seed 003; accelerations, masses,
    cylinders and pump are assumed. The circle (R = 0.7 m about (x, z) = (3.0, 2.5) m in the
    x–z plane, θ ∈ [−π, π]) and the parabola (θ = x ∈ [1.6, 3.07] m at azimuth α) are
    `planner/methods/phase.py`'s `seed_setup`. The seed's α = −π/3 is not reachable on this
    crane (checked below), so the parabola runs at α = −π/4.
    '''),
    code(r'''
    import math

    from planner import Crane
    from planner.methods import phase as ph

    crane = Crane.from_id("umea-lab")
    L = crane.limit_arrays()
    table(["joint", "range", "velocity limits (−/+)", "acceleration (assumed)"],
          [[j.name, f"{L['q_min'][i]:.2f} … {L['q_max'][i]:.2f}",
            f"{L['qd_min'][i]:.2f} / {L['qd_max'][i]:.2f}", f"{L['qdd_max'][i]:.2f}"]
           for i, j in enumerate(crane.spec.joints)])
    ALPHA = -math.pi / 4
    p_seed = ph.parabola_path(alpha=-math.pi / 3)
    th = p_seed.grid(101)
    band = ph.feasible_band(crane, p_seed, th, np.linspace(*crane.tele_range, 60))
    print(f"parabola at the seed's α = −60°: reachable with some telescope value at "
          f"{100 * band.any(axis=1).mean():.0f} % of its points -> using α = "
          f"{math.degrees(ALPHA):.0f}°")
    PATHS = {"circle": ph.seed_setup("circle"), "parabola": ph.seed_setup("parabola", alpha=ALPHA)}
    fig = plt.figure(figsize=(6.5, 5))
    ax = fig.add_subplot(projection="3d")
    for i, (name, (path, _)) in enumerate(PATHS.items()):
        xyz = path.xyz(path.grid(200))
        ax.plot(xyz[:, 0], xyz[:, 1], xyz[:, 2], color=f"C{i}", lw=2, label=name)
    o = crane.frame_origins(0.5 * (L["q_min"] + L["q_max"]))
    ax.plot(o[:, 0], o[:, 1], o[:, 2], "o-", color="0.4", lw=3, label="crane at mid-range")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.legend(fontsize=8)
    ax.set_title("seed 003 test paths (frame 0)")
    show(fig)
    '''),
    md(r'''
    ## Phase-plane design, from rest, and TOPP-RA

    Per path: the telescope coefficients that maximise the area under the envelope (the lowest
    of the joints' velocity bounds on θ̇), the seed's profile θ̇ = 0.9·envelope, the from-rest
    redesign (Ruckig on θ, joining the nominal profile at 5 % of the path — the circle keeps
    cycling, the parabola also stops from 95 %), and TOPP-RA on the *same* joint path Φ(θ),
    rest to rest, with the velocity and (assumed) acceleration limits, with and without the
    pump's flow limit.
    '''),
    code(r'''
    from planner.methods.topp import retime
    from planner.trajectory import evaluate

    D = {}
    for name, (path, tele) in PATHS.items():
        t0 = time.perf_counter()
        opt = ph.optimise_telescope(crane, path, tele, **S["opt"])
        assert opt.ok, f"{name}: the optimised telescope is infeasible"
        prof = ph.time_efficient_profile(crane, path, tele, opt.coef, 0.9, n=S["profile_n"])
        fr = ph.from_rest(crane, prof, space="theta")
        idx = np.unique(np.linspace(0, opt.env.theta.size - 1, S["topp_samples"]).round()
                        .astype(int))
        topp = {}
        for key, lim in (("v+a", ("velocity", "acceleration")),
                         ("v+a+pump", ("velocity", "acceleration", "pump_flow"))):
            r = retime(crane, opt.env.q[idx], ss=opt.env.theta[idx], limits=lim,
                       gridpoints=S["topp_grid"])
            assert r.ok, f"{name} TOPP-RA {key}: {r.reason}"
            topp[key] = r
        D[name] = dict(path=path, tele=tele, opt=opt, prof=prof, fr=fr, topp=topp,
                       designs={"seed 90 % profile (moving ends)": prof.trajectory(crane),
                                "seed from rest (Ruckig)": fr.trajectory,
                                "TOPP-RA v+a": topp["v+a"].trajectory,
                                "TOPP-RA v+a+pump": topp["v+a+pump"].trajectory},
                       seconds=time.perf_counter() - t0)
        D[name]["ev"] = {k: evaluate(crane, tr, kinds=("position", "velocity", "acceleration",
                                                       "pump_flow"))
                         for k, tr in D[name]["designs"].items()}

    rows = []
    for name, d in D.items():
        o = d["opt"]
        rows.append([name, f"{o.area:.3f}", fmt(o.const_area) if o.const_best is not None
                     else "no constant reaches the path", f"{o.env.time_at_envelope:.3f}"])
    table(["path", "envelope area, optimised φ4", "… best constant telescope",
           "time riding the envelope [s]"], rows)
    rows = []
    for name, d in D.items():
        for k, ev in d["ev"].items():
            rows.append([name, k, f"{ev.duration:.3f}", f"{100 * ev.violations['velocity']:.2f} %",
                         f"{100 * ev.violations['acceleration']:.1f} %",
                         f"{100 * ev.violations['pump_flow']:.1f} %"])
    table(["path", "design", "duration [s]", "velocity excess", "acceleration excess (assumed limits)",
           "pump-flow excess"], rows)
    print("design time per path [s]: " + ", ".join(f"{k} {d['seconds']:.1f}" for k, d in D.items()))
    '''),
    md(r'''
    ### The phase plane

    Each joint's velocity bound on θ̇ (the envelope is the lowest), the seed's 90 % profile, the
    from-rest redesign and the TOPP-RA timings mapped back to θ (from the tip position); below,
    the optimised telescope inside the band of reachable telescope values.
    '''),
    code(r'''
    def theta_dot_of(d, traj, n=1500):
        """θ(t) of the tip's position and θ̇ by differences on a uniform time grid."""
        t = np.linspace(traj.t[0], traj.t[-1], n)
        th = d["path"].theta_of(crane.fk(traj.sample(t)[0]))
        if d["path"].periodic:
            th = np.unwrap(th)
        return th, np.gradient(th, t)


    for name, d in D.items():
        opt, prof, env = d["opt"], d["prof"], d["opt"].env
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(9, 8), height_ratios=[3, 2], sharex=True)
        top = 2.5 * float(np.max(env.envelope))
        for i in range(crane.n):
            b = env.bounds[:, i]
            if np.any(np.isfinite(b)):
                ax.plot(env.theta, np.where(np.isfinite(b), b, np.nan), lw=0.9, alpha=0.8,
                        label=f"{crane.names[i]} bound")
        ax.fill_between(env.theta, env.envelope, top, color="0.88", zorder=0)
        ax.plot(env.theta, env.envelope, "r", lw=2, label="envelope")
        ax.plot(prof.theta, prof.f, "k", lw=1.5, label="90 % profile")
        t_fr, th_fr, thd_fr = d["fr"].phase
        ax.plot(th_fr, thd_fr, "--", color="tab:purple", lw=1.5, label="from rest (Ruckig)")
        for key, style in (("v+a", ":"), ("v+a+pump", "-.")):
            th, thd = theta_dot_of(d, d["topp"][key].trajectory)
            ax.plot(th, thd, style, color="tab:cyan", lw=1.5, label=f"TOPP-RA {key}")
        ax.set_ylim(0, top)
        ax.set_ylabel("θ̇ [rad/s]" if name == "circle" else "θ̇ = ẋ [m/s]")
        ax.legend(fontsize=7.5, ncol=3, loc="upper right")
        ax.grid(alpha=0.3)
        ax.set_title(f"{name}: envelope area {opt.area:.3f}"
                     + (f" (best constant telescope {opt.const_area:.3f})"
                        if opt.const_best is not None else " (no constant telescope reaches it)"))
        lo = np.array([opt.band_tele[m].min() if m.any() else np.nan for m in opt.band])
        hi = np.array([opt.band_tele[m].max() if m.any() else np.nan for m in opt.band])
        ax2.fill_between(opt.band_theta, lo, hi, color="tab:green", alpha=0.15,
                         label="reachable telescope values")
        ax2.plot(env.theta, env.tele, "k", lw=1.8, label="optimised φ4(θ)")
        if opt.const_best is not None:
            ax2.axhline(opt.const_best, color="r", ls="--", lw=1,
                        label=f"best constant {opt.const_best:.2f} m")
        ax2.set_ylabel("telescope [m]")
        ax2.set_xlabel("θ [rad]" if name == "circle" else "θ = x [m]")
        ax2.legend(fontsize=7.5)
        ax2.grid(alpha=0.3)
        show(fig)
    '''),
    md(r'''
    ## Replay robustness

    `planner/simulate.py`'s `robustness`: the design's valve feed-forward (50 Hz) is replayed
    open loop on the nominal plant and on perturbed plants — every joint's start off by ±1°
    (±2 cm for the telescope), every valve gain ±2 %, the pump −10 %, and each start error
    combined with each gain error — and the tip's distance from the plan is recorded. The
    nominal replay shows the plan's own error (a plan that asks more flow than the pump gives
    is slowed by flow sharing); the score is the worst maximum over the perturbations.
    '''),
    code(r'''
    from planner.simulation.replay import robustness

    ROB = {}
    for name, d in D.items():
        for key in ("seed from rest (Ruckig)", "TOPP-RA v+a", "TOPP-RA v+a+pump"):
            ROB[name, key] = robustness(crane, d["designs"][key], rate=S["rate"], series=True)
    table(["path", "design", "duration [s]", "nominal replay: max tip error [mm]",
           "score: worst max tip error [mm]", "worst perturbation", "worst final error [mm]"],
          [[name, key, f"{r['duration_s']:.2f}", f"{1e3 * r['nominal']['max_tip_error_m']:.1f}",
            f"{1e3 * r['score_m']:.1f}", r["worst"], f"{1e3 * r['worst_final_m']:.1f}"]
           for (name, key), r in ROB.items()])
    print("perturbations per design:", len(next(iter(ROB.values()))["perturbations"]))
    '''),
    code(r'''
    fig, axs = plt.subplots(1, len(D), figsize=(6 * len(D), 4), squeeze=False)
    for ax, name in zip(axs[0], D):
        for i, key in enumerate(("seed from rest (Ruckig)", "TOPP-RA v+a+pump")):
            r = ROB[name, key]
            t = np.array(r["t"])
            ax.fill_between(t, 0, 1e3 * np.array(r["envelope_m"]), color=f"C{i}", alpha=0.2)
            ax.plot(t, 1e3 * np.array(r["envelope_m"]), color=f"C{i}", lw=1,
                    label=f"{key}: worst over perturbations")
            ax.plot(t, 1e3 * np.array(r["tip_error_m"]["nominal"]), color=f"C{i}", lw=2, ls="--",
                    label=f"{key}: nominal plant")
        ax.set_title(f"{name}: open-loop tip error of the replay")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("tip error [mm]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    show(fig)

    # the circle's tip path on the worst plant vs the plan (x–z plane)
    from planner.feedforward import commands
    from planner.simulation.replay import default_perturbations, replay

    d = D["circle"]
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    for i, key in enumerate(("seed from rest (Ruckig)", "TOPP-RA v+a+pump")):
        traj = d["designs"][key]
        ff = commands(crane, traj, S["rate"])
        plant = default_perturbations(crane)[ROB["circle", key]["worst"]]
        sim = replay(crane, ff.t, ff.u, traj.q[0], plant)
        xyz = crane.fk(sim.q)
        ax.plot(xyz[:, 0], xyz[:, 2], color=f"C{i}", lw=1.5,
                label=f"{key}, replay on '{ROB['circle', key]['worst']}'")
    plan = crane.fk(d["designs"]["TOPP-RA v+a+pump"].q)
    ax.plot(plan[:, 0], plan[:, 2], "k--", lw=1, label="plan (the circle)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower center")
    ax.set_title("circle: planned vs replayed tip path, worst plant")
    show(fig)
    '''),
    md("## Answer"),
    final(r'''
    lines = []
    for name, d in D.items():
        o, ev = d["opt"], d["ev"]
        nom = ev["seed 90 % profile (moving ends)"].duration
        frd = ev["seed from rest (Ruckig)"].duration
        tva, tvp = ev["TOPP-RA v+a"].duration, ev["TOPP-RA v+a+pump"].duration
        rs, rt = ROB[name, "seed from rest (Ruckig)"], ROB[name, "TOPP-RA v+a+pump"]
        gain = (f"{o.area / o.const_area:.2f}× the envelope area of the best constant telescope"
                if o.const_best is not None else "a path no constant telescope can follow")
        lines.append(
            f"- **{name}**: the optimised telescope gives {gain}; the seed's 90 % profile takes "
            f"{nom:.2f} s (moving ends), from rest {frd:.2f} s ({frd - nom:+.2f} s), but it "
            f"exceeds the assumed acceleration limits by "
            f"{100 * ev['seed from rest (Ruckig)'].violations['acceleration']:.0f} % and the pump "
            f"by {100 * ev['seed from rest (Ruckig)'].violations['pump_flow']:.0f} %. TOPP-RA on "
            f"the same joint path, rest to rest: {tva:.2f} s within velocity and acceleration, "
            f"{tvp:.2f} s within the pump too. Open loop the seed's design drifts "
            f"{1e3 * rs['nominal']['max_tip_error_m']:.0f} mm on the nominal plant and up to "
            f"{1e3 * rs['score_m']:.0f} mm on the "
            f"perturbed plants ({rs['worst']}); the pump-feasible TOPP-RA design "
            f"{1e3 * rt['nominal']['max_tip_error_m']:.1f} mm and {1e3 * rt['score_m']:.0f} mm "
            f"({rt['worst']}).")
    own = [ROB[n, "seed from rest (Ruckig)"]["nominal"]["max_tip_error_m"] for n in D]
    own_t = [ROB[n, "TOPP-RA v+a+pump"]["nominal"]["max_tip_error_m"] for n in D]
    left = [ROB[n, "TOPP-RA v+a+pump"]["score_m"] for n in D]
    worst = sorted({ROB[n, "TOPP-RA v+a+pump"]["worst"] for n in D})
    lines += ["", f"**In short:** the seed's velocity-only design is not replayable open loop as "
              f"planned — {span(own, 1e3, '.0f', ' mm')} of drift on the *nominal* plant is its "
              f"own (it asks more flow than the pump gives); planned within the pump, the nominal "
              f"replay stays within {span(own_t, 1e3, '.1f', ' mm')} and what is left is the "
              f"plant's doing: {span(left, 1e3, '.0f', ' mm')} in the worst case "
              f"({', '.join(worst)}) — a case for feedback on top of the feed-forward."]
    display(Markdown("\n".join(lines)))
    '''),
]


# ----------------------------------------------------------------------------- (d) calibration
D = [
    md(r'''
    # Calibration: a hidden effect found, named and fixed (CAT 215B)

    **Question.** A recording of a log loader — valve commands, joint positions, chamber
    pressures, with sensor noise — disagrees with the nominal model. Something physical is
    missing. From the recording alone:

    1. where does the model disagree, and by how much above the noise,
    2. which effect of the catalogue explains it, with which parameter and uncertainty,
    3. how much of the gap closes once the effect is added, and
    4. does the feed-forward re-planned on the calibrated model track better on the real
       (hidden) plant?

    Two recordings are made by `planner/trials.py`, each with one effect drawn at a realistic
    magnitude and hidden in the plant; the workflow (`planner/discrepancy.py`) sees only the
    recording. The truth is revealed at the end and compared.
    '''),
    setup_cell(
        small=dict(duration=20.0, recordings=(("A", "flow_gain", 3), ("B", "coulomb_friction", 4)),
                   threshold=30.0),
        full=dict(duration=60.0, recordings=(("A", "flow_gain", 3), ("B", "coulomb_friction", 4)),
                  threshold=30.0)),
    md(r'''
    ## The catalogue

    `planner/effects.py`: every effect is a small augmentation of the nominal model — the same
    object is injected into the simulated "true" plant and fitted by the workflow.
    '''),
    code(r'''
    from planner import Crane
    from planner.simulation.effects import catalogue

    crane = Crane.from_id("cat215b")
    print(f"{crane.spec.name}: joints {crane.names}")
    table(["effect", "acts on", "parameters (plausible range)", "description"],
          [[e["name"], e["acts_on"],
            ", ".join(k if isinstance(v, str) else f"{k} [{v[0]:.3g}, {v[1]:.3g}]"
                      for k, v in e["parameters"].items()), e["description"]]
           for e in catalogue()])
    '''),
    md(r'''
    ## The recordings

    `hidden_trial`: an excitation sequence (rest-to-rest moves of every joint between random
    poses, the first at full speed, holds in between), its 50 Hz valve feed-forward, replayed on
    the plant with the hidden effect, sensor noise at seed 001's levels (0.1°, 2 mm, 0.17 MPa).
    '''),
    code(r'''
    from planner.calibration.trials import hidden_trial

    REC, _HIDDEN = {}, {}
    for label, effect, seed in S["recordings"]:
        rec, plan, ff, truth = hidden_trial(crane, effect, seed, S["duration"])
        REC[label] = dict(rec=rec, plan=plan, ff=ff)
        _HIDDEN[label] = truth          # not shown to the workflow (nor printed until the end)
    rec = REC["A"]["rec"]
    print(f"recording A: {len(rec.t)} samples over {rec.t[-1] - rec.t[0]:.1f} s; channels: "
          f"q ×{rec.q.shape[1]}, p_a ×{rec.p_a.shape[1]}, p_b ×{rec.p_b.shape[1]}")
    fig, axs = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for i, j in enumerate(crane.names):
        axs[0].plot(rec.t, rec.u[:, i], lw=0.8, label=j)
        axs[1].plot(rec.t, rec.q[:, i], lw=0.8, label=j)
        axs[2].plot(rec.t, rec.p_a[:, i] / 1e6, lw=0.6, label=f"{j} a")
    axs[0].set_ylabel("valve command")
    axs[1].set_ylabel("q [rad]")
    axs[2].set_ylabel("p_a [MPa]")
    axs[2].set_xlabel("t [s]")
    for ax in axs:
        ax.legend(fontsize=7, ncol=3, loc="upper right")
        ax.grid(alpha=0.3)
    axs[0].set_title("recording A as the workflow sees it")
    show(fig)
    '''),
    md(r'''
    ## Find and name

    `Discrepancy(crane).fit(rec)`: replay the measured commands on the nominal model, estimate
    the noise floor from the data, locate the disagreement, fit every catalogue effect on every
    joint on alternate 1 s training blocks, rank them on the held-out blocks (score = ΔJ −
    k·ln n) and name the best if its score passes the threshold; else "none".
    '''),
    code(r'''
    from planner.calibration.discrepancy import Discrepancy

    RES = {}
    for label in REC:
        t0 = time.perf_counter()
        RES[label] = Discrepancy(crane, threshold=S["threshold"]).fit(REC[label]["rec"])
        print(f"recording {label}: {RES[label].message} "
              f"[{time.perf_counter() - t0:.1f} s, {len(RES[label].ranking)} candidates]")
    res = RES["A"]
    table(["channel", "nominal residual RMS / noise"],
          [[c["channel"], f"{c['rms_over_noise']:.1f}"] for c in res.where["channels"][:6]])
    w = res.where
    worst = w["channels"][0]["channel"].split("_")[1]
    print(f"{w['n_windows']} windows of 2 s stand out; joint {worst}'s residual by condition "
          "(mean square / noise²): " + ", ".join(f"{k} {v:.1f}" for k, v in
                                                 w["conditions"][worst].items() if v is not None))
    '''),
    code(r'''
    from planner.plots import (discrepancy_overlay_figure, discrepancy_ranking_figure,
                               discrepancy_residual_figure)

    discrepancy_ranking_figure(res, OUT / "ranking_A.png")
    show_file(OUT / "ranking_A.png")
    table(["rank", "model", "fitted parameters", "held-out score", "condition number"],
          [[r["rank"], r["model"],
            "; ".join(", ".join(f"{k} = {v:.4g}" for k, v in e.items() if k not in ("name", "joint"))
                      for e in r["effects"]), f"{r['score']:.1f}", f"{r['cond']:.3g}"]
           for r in res.ranking[:5]])
    table(["named effect", "joint", "parameter", "estimate", "standard error", "95 % interval"],
          [[res.effect, res.joint or "—", k, f"{v:.5g}", f"{res.uncertainty[k]:.2g}",
            f"{v - 1.96 * res.uncertainty[k]:.5g} … {v + 1.96 * res.uncertainty[k]:.5g}"]
           for k, v in res.parameters.items() if k != "joint"])
    print("identifiable:", res.identifiable, "| second effect:", res.second)
    '''),
    md(r'''
    ## The gap, before and after

    Held-out blocks only. "Above-noise removed" is the share of the residual that stands above
    the noise floor (smoothed over 0.5 s) which the calibrated model explains.
    '''),
    code(r'''
    chans = [c["channel"] for c in res.where["channels"][:6]]
    table(["channel", "noise σ", "RMS before", "RMS after", "VAF before", "VAF after",
           "above-noise removed"],
          [[c, f"{res.noise[c]:.3g}", f"{res.rms_before[c]:.3g}", f"{res.rms_after[c]:.3g}",
            f"{res.vaf_before[c]:.1f} %", f"{res.vaf_after[c]:.1f} %",
            "—" if res.gap_reduction_channels[c] is None
            else f"{100 * res.gap_reduction_channels[c]:.0f} %"] for c in chans])
    print(f"overall: {100 * res.gap_reduction:.1f} % of the above-noise held-out residual removed")
    discrepancy_residual_figure(res, OUT / "residuals_A.png")
    show_file(OUT / "residuals_A.png")
    discrepancy_overlay_figure(res, OUT / "overlay_A.png")
    show_file(OUT / "overlay_A.png")
    '''),
    md(r'''
    ## Fix: the calibrated model and the re-planned feed-forward

    The calibrated spec is the machine's TOML plus an `[[effects]]` table. `compensate`
    re-plans the feed-forward of a trajectory on it (iterative learning on the calibrated model
    for valve effects); `closed_loop` replays the nominal and the re-planned commands on the
    true — hidden — plant and measures the tip's distance from the plan. The trajectory is the
    recording's own, slowed where needed so that the nominal plant could follow it
    (`trackable`). `write_report` writes the whole story (markdown, JSON, figures).
    '''),
    code(r'''
    from planner.calibration.compensate import closed_loop, compensate
    from planner.calibration.discrepancy import calibrated_spec_text
    from planner.calibration.report import write_report
    from planner.feedforward import commands
    from planner.simulation.plant import respond
    from planner.calibration.trials import trackable

    print("\n".join(calibrated_spec_text(crane, res.effects, "(recording A)").splitlines()[-6:]))
    CL = {}
    for label in REC:
        truth = (_HIDDEN[label],)
        CL[label] = closed_loop(crane, trackable(crane, REC[label]["plan"]), RES[label].effects,
                                plant_effects=truth)
        files = write_report(RES[label], OUT / f"report_{label}", crane=crane,
                             measured=f"hidden trial {label}", closed=CL[label])
        print(f"recording {label}: report -> {', '.join(f.name for f in files)} in "
              f"{OUT / f'report_{label}'}")
    table(["recording", "tip error, nominal feed-forward: RMS / max [mm]",
           "re-planned on the calibrated model: RMS / max [mm]"],
          [[k, f"{1e3 * c['before']['rms_m']:.2f} / {1e3 * c['before']['max_m']:.2f}",
            f"{1e3 * c['after']['rms_m']:.2f} / {1e3 * c['after']['max_m']:.2f}"]
           for k, c in CL.items()])

    # the tracking error over time for recording A (the same runs closed_loop makes)
    truth = (_HIDDEN["A"],)
    plan = trackable(crane, REC["A"]["plan"])
    bias = np.zeros((1, crane.n))
    for e in truth:
        bias = e.sense_q(crane, bias)
    ff = commands(crane, plan, 50.0)
    p2, t2, u2, q_read = compensate(crane, plan, res.effects, 50.0)
    fig, axs = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for label, (pl, t, u, q0) in (("nominal feed-forward", (plan, ff.t, ff.u, plan.q[0])),
                                  ("re-planned on the calibrated model", (p2, t2, u2, q_read))):
        r = respond(crane, t, u, q0 - bias[0], truth, t_end=t[-1])
        err = np.linalg.norm(crane.fk(r.state.q) - crane.fk(pl.sample(r.t)[0]), axis=1)
        axs[0].semilogy(r.t, np.maximum(1e3 * err, 1e-4), lw=1, label=label)
    j = crane.names.index(res.joint) if res.joint else 0
    axs[1].plot(ff.t, ff.u[:, j], lw=0.8, label="nominal")
    axs[1].plot(t2, u2[:, j], lw=0.8, ls="--", label="re-planned")
    axs[0].set_ylabel("tip error [mm]")
    axs[0].legend(fontsize=8)
    axs[0].grid(alpha=0.3, which="both")
    axs[0].set_title("recording A's trajectory replayed open loop on the true plant")
    axs[1].set_ylabel(f"valve command {crane.names[j]}")
    axs[1].set_xlabel("t [s]")
    axs[1].legend(fontsize=8)
    axs[1].grid(alpha=0.3)
    show(fig)
    '''),
    md(r'''
    ## Recording B

    The same workflow on the second recording: its residuals before and after.
    '''),
    code(r'''
    rb = RES["B"]
    discrepancy_residual_figure(rb, OUT / "residuals_B.png")
    show_file(OUT / "residuals_B.png")
    chans = [c["channel"] for c in rb.where["channels"][:4]]
    table(["channel", "noise σ", "RMS before", "RMS after", "above-noise removed"],
          [[c, f"{rb.noise[c]:.3g}", f"{rb.rms_before[c]:.3g}", f"{rb.rms_after[c]:.3g}",
            "—" if rb.gap_reduction_channels[c] is None
            else f"{100 * rb.gap_reduction_channels[c]:.0f} %"] for c in chans])
    '''),
    md(r'''
    ## The truth revealed
    '''),
    code(r'''
    rows = []
    for label in REC:
        t, r = _HIDDEN[label], RES[label]
        for k, v in t.values.items():
            est, sd = r.parameters.get(k, float("nan")), r.uncertainty.get(k, float("nan"))
            rows.append([label, f"{t.name} on {t.joint}", f"{r.effect} on {r.joint}", k,
                         f"{v:.5g}", f"{est:.5g} ± {sd:.2g}",
                         f"{abs(est - v) / sd:.1f}" if sd else "—"])
    table(["recording", "hidden", "named", "parameter", "true value", "estimate ± σ",
           "|error| / σ"], rows)
    '''),
    md("## Answer"),
    final(r'''
    lines = []
    for label in REC:
        t, r, c = _HIDDEN[label], RES[label], CL[label]
        k = next(iter(t.values))
        est, sd = r.parameters.get(k, float("nan")), r.uncertainty.get(k, float("nan"))
        top = r.where["channels"][0]
        runner = r.ranking[1]
        moved = c["before"]["rms_m"] > 1e-6
        rec = REC[label]["rec"]
        lines.append(
            f"- **Recording {label}** ({rec.t[-1] - rec.t[0]:.1f} s): the nominal model is off most in "
            f"{top['channel']} ({top['rms_over_noise']:.1f}× the noise). Named: **{r.effect}** on "
            f"{r.joint}, {k} = {est:.4g} ± {sd:.2g} (held-out score "
            f"{r.ranking[0]['score']:.0f}; runner-up {runner['model']} {runner['score']:.0f}; "
            f"threshold {S['threshold']:g}). Hidden: {t.name} on {t.joint}, {k} = "
            f"{t.values[k]:.4g} — {'right' if (r.effect, r.joint) == (t.name, t.joint) else 'WRONG'}"
            f", {abs(est - t.values[k]) / sd:.1f} σ off. Calibrated, the model removes "
            f"{100 * r.gap_reduction:.0f} % of the above-noise held-out residual. "
            + (f"Open-loop tracking of the recording's trajectory on the true plant: "
               f"{1e3 * c['before']['rms_m']:.1f} mm RMS with the nominal feed-forward → "
               f"{1e3 * c['after']['rms_m']:.2f} mm re-planned on the calibrated model "
               f"({100 * c['reduction']:.1f} % less)."
               if moved else
               f"The effect does not move the crane (pressure-compensated valves: the tip "
               f"error of the nominal feed-forward is {1e3 * c['before']['rms_m']:.1g} mm), so "
               f"the fix is in the predicted pressures, not in the commands."))
    display(Markdown("\n".join(lines)))
    '''),
]


NOTEBOOKS = {
    "a_seed000_revisited": A,
    "b_energy": B,
    "c_open_loop": C,
    "d_calibration": D,
}


# ----------------------------------------------------------------------------- build
def build(name: str, cells) -> str:
    nb = nbformat.v4.new_notebook()
    nb.nbformat, nb.nbformat_minor = 4, 5   # fixed, so the files do not follow nbformat's default
    nb.metadata = {
        "kernelspec": {"name": "python3", "display_name": "Python 3 (ipykernel)",
                       "language": "python"},
        "language_info": {"name": "python"},
    }
    for i, (kind, src) in enumerate(cells):
        c = (nbformat.v4.new_markdown_cell(src) if kind == "markdown"
             else nbformat.v4.new_code_cell(src))
        c.id = f"{name[:40]}-{i:02d}"
        nb.cells.append(c)
    nbformat.validate(nb)
    return nbformat.writes(nb) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(HERE), help="output folder (this folder)")
    ap.add_argument("--check", action="store_true",
                    help="only compare with the files in --out; exit 1 if any differs")
    args = ap.parse_args(argv)
    out = Path(args.out)
    stale = []
    for name, cells in NOTEBOOKS.items():
        text = build(name, cells)
        path = out / f"{name}.ipynb"
        if args.check:
            if not path.exists() or path.read_text(encoding="utf-8") != text:
                stale.append(path.name)
            continue
        out.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        print(f"wrote {path}")
    if stale:
        print("out of date (run python notebooks/build_notebooks.py): " + ", ".join(stale))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
