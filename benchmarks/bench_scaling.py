"""Scaling study (issue 7): how the planners' cost grows with the problem size on this machine.

1. DP (:func:`planner.methods.dp.dp`, minimum time): wall time [s], grid nodes and edges vs
   (a) grid resolution — path step Δ = telescope step, window fixed (so the telescope's largest
   change per metre of path stays the same); (b) path length at a fixed grid; (c) the telescope
   window w. The minimum time of each grid shows the accuracy the resolution buys.
2. NLP (:class:`planner.methods.nlp.MoveNLP`, minimum time, free path): build time (once) and
   solve time (median of repeats) vs the horizon N on every machine (3 or 4 joints), with IPOPT
   iterations, problem size and the duration found; and the same moves on the s100f with its
   telescope frozen (a 3-DOF variant of the 4-DOF crane).
3. Library build (:func:`planner.library.build.build`, local processes) vs workers; the Dask numbers
   are cited from benchmarks/results/library_build.json, not re-run.

Outputs (atomic writes): scaling.md, scaling.json, scaling_dp.png, scaling_nlp.png,
scaling_library.png in ``--out``.

    python benchmarks/bench_scaling.py [--quick] [--out benchmarks/results]

``--quick`` (~1 min) runs smaller sweeps and writes to a temporary folder unless --out is given.
"""
from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
import tracemalloc
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from planner import Crane
from planner.bench.run import machine_info
from planner.io import atomic_write_text, dumps
from planner.methods.dp import dp
from planner.methods.nlp import MoveNLP
from planner.geometry.paths import Line, tip_to_xyz, xyz_to_tip

RESULTS = Path(__file__).parent / "results"
DASK_JSON = RESULTS / "library_build.json"
SEED000 = dict(A=(1.5, 1.0, 0.0), B=(5.5, 1.0, 0.0), C=(5.5, -3.0, 0.0))  # tips (r, z, slew)
# DP resolution moves: seed 000's A–C, and the s100f line of bench_dp_laws.py's TOPP case
DP_MOVES = {"cranab850 A–C": ("cranab850", SEED000["A"], SEED000["C"]),
            "s100f line": ("s100f", (7.0, -1.0, 0.0), (3.0, 2.0, 0.5))}
# DP length sweep: sub-segments from one end of the 8.47 m chord r = 7.5 m, slew −0.6 → 0.6 rad
CHORD = ((7.5, 0.0, -0.6), (7.5, 0.0, 0.6))
NLP_MACHINES = ("cat215b", "cranab850", "s100f", "umea-lab")
FROZEN_MACHINE = "s100f"


@dataclass(frozen=True)
class Config:
    """Sweep sizes. Steps/lengths in m, repeats = timed runs per case (median reported)."""
    dp_steps: tuple = (0.08, 0.04, 0.02, 0.01, 0.005)
    dp_window: int = 5
    dp_window_step: float = 0.01
    dp_windows: tuple = (1, 2, 3, 5, 8, 12)
    dp_lengths: tuple = (0.5, 1.0, 2.0, 4.0, 8.0)
    dp_length_step: float = 0.01
    dp_repeats: int = 3
    nlp_N: tuple = (10, 20, 40, 80, 160)
    nlp_moves: int = 3
    nlp_repeats: int = 3
    lib_moves: int = 24
    lib_workers: tuple = (1, 2, 3, 4)
    lib_rounds: int = 2
    lib_robustness: bool = True


FULL = Config()
QUICK = Config(dp_steps=(0.08, 0.04, 0.02), dp_window_step=0.02, dp_windows=(1, 3, 5),
               dp_lengths=(1.0, 2.0, 4.0), dp_length_step=0.02, nlp_N=(10, 20, 40),
               nlp_moves=1, nlp_repeats=1, lib_moves=6, lib_workers=(1, 2), lib_rounds=1)


# ------------------------------------------------------------------------------ helpers
def timed(f, repeats: int):
    """(median wall time [s], all times [s], last result) of ``repeats`` calls of f()."""
    ts, out = [], None
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        out = f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), ts, out


def slope(x, y) -> float:
    """Log-log slope (numpy.polyfit, degree 1) of y against x; nan with < 2 usable points."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def machine() -> dict:
    """The planner's machine record plus the load and the CPU model."""
    info = dict(machine_info(), load_1_5_15=os.getloadavg())
    try:
        cpu = [ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
               if ln.startswith("model name")]
        info["cpu_model"] = cpu[0] if cpu else None
    except OSError:
        info["cpu_model"] = None
    return info


# ------------------------------------------------------------------------------ 1. DP
def dp_edges(stages: int, tele_nodes: int, window: int) -> int:
    """Number of in-grid edges: per stage, every node m links to the m + j (|j| ≤ w) that
    exist on the telescope grid."""
    m = np.arange(tele_nodes)
    per_stage = np.minimum(m, window) + np.minimum(tele_nodes - 1 - m, window) + 1
    return int(stages * per_stage.sum())


FAST_S = 0.3        # [s] DP grids faster than this (warm-up call) get FAST_REPEATS timed runs
FAST_REPEATS = 7


def dp_case(crane, path, step: float, tele_step: float, window: int, repeats: int) -> dict:
    """One DP grid: median wall time [s] over ``repeats`` (FAST_REPEATS when the untimed
    warm-up call took < FAST_S), grid size, peak traced memory [MB] (one extra call under
    tracemalloc) and the minimum time [s]."""
    def run():
        return dp(crane, path, "time", step=step, tele_step=tele_step, window=window)
    t0 = time.perf_counter()
    run()  # warm-up (first-touch allocations)
    if time.perf_counter() - t0 < FAST_S:
        repeats = max(repeats, FAST_REPEATS)
    med, ts, r = timed(run, repeats)
    tracemalloc.start()
    run()
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    g = r.grid
    w = g["window"]
    return dict(step_m=step, tele_step_m=tele_step, window=w, length_m=path.length,
                status=r.status, stages=g["stages"], tele_nodes=g["tele_nodes"],
                nodes=(g["stages"] + 1) * g["tele_nodes"],
                edges=dp_edges(g["stages"], g["tele_nodes"], w),
                time_s=med, times_s=ts, peak_mb=peak, duration_s=r.duration_s)


def sub_line(length: float) -> Line:
    """The first ``length`` metres of the chord CHORD (a straight tip line)."""
    a, b = tip_to_xyz(CHORD[0]), tip_to_xyz(CHORD[1])
    u = length / float(np.linalg.norm(b - a))
    if not 0 < u <= 1:
        raise ValueError(f"length must be in (0, {np.linalg.norm(b - a):.2f}] m")
    return Line(xyz_to_tip(a), xyz_to_tip(a + u * (b - a)))


def dp_resolution(cfg: Config, bar=None) -> dict:
    """Per DP_MOVES move: rows for Δ in cfg.dp_steps (tele step = Δ, window fixed), with the
    relative gap [-] of each minimum time to the finest grid's."""
    out = {}
    for name, (cid, a, b) in DP_MOVES.items():
        crane, path = Crane.from_id(cid), Line(a, b)
        rows = []
        for d in sorted(cfg.dp_steps, reverse=True):
            rows.append(dp_case(crane, path, d, d, cfg.dp_window, cfg.dp_repeats))
            _tick(bar, f"DP {name} Δ={d}")
        best = rows[-1]["duration_s"]
        for r in rows:
            r["gap_to_finest"] = r["duration_s"] / best - 1.0
        out[name] = rows
    return out


def dp_window(cfg: Config, bar=None) -> list:
    """Seed 000's A–C on the cranab850 at Δ = cfg.dp_window_step for every window w."""
    crane, path = Crane.from_id("cranab850"), Line(SEED000["A"], SEED000["C"])
    rows = []
    for w in cfg.dp_windows:
        rows.append(dp_case(crane, path, cfg.dp_window_step, cfg.dp_window_step, w,
                            cfg.dp_repeats))
        _tick(bar, f"DP window {w}")
    return rows


def dp_length(cfg: Config, bar=None) -> list:
    """Sub-segments of CHORD on the cranab850 at a fixed grid (Δ = cfg.dp_length_step)."""
    crane = Crane.from_id("cranab850")
    rows = []
    for L in cfg.dp_lengths:
        rows.append(dp_case(crane, sub_line(L), cfg.dp_length_step, cfg.dp_length_step,
                            cfg.dp_window, cfg.dp_repeats))
        _tick(bar, f"DP length {L}")
    return rows


def dp_study(cfg: Config) -> dict:
    """All DP sweeps and their fitted log-log exponents."""
    n = len(DP_MOVES) * len(cfg.dp_steps) + len(cfg.dp_windows) + len(cfg.dp_lengths)
    with tqdm(total=n, desc="DP", unit="grid") as bar:
        res = dict(resolution=dp_resolution(cfg, bar), window=dp_window(cfg, bar),
                   length=dp_length(cfg, bar))
    fits = {}
    for name, rows in res["resolution"].items():
        e = [r["edges"] for r in rows]
        t = [r["time_s"] for r in rows]
        fits[name] = dict(time_vs_edges=slope(e, t),
                          time_vs_edges_finest_pair=slope(e[-2:], t[-2:]),
                          edges_vs_step=slope([r["step_m"] for r in rows], e),
                          memory_vs_edges=slope(e, [r["peak_mb"] for r in rows]))
    fits["window"] = dict(time_vs_edges=slope([r["edges"] for r in res["window"]],
                                              [r["time_s"] for r in res["window"]]))
    fits["length"] = dict(time_vs_stages=slope([r["stages"] for r in res["length"]],
                                               [r["time_s"] for r in res["length"]]))
    res["fits"] = fits
    return res


# ------------------------------------------------------------------------------ 2. NLP
def nlp_moves(crane, k: int, seed: int, frozen: tuple | None = None, min_dist: float = 1.0):
    """k (start, goal) tips of random configurations 10 % inside the joint ranges, ≥ min_dist
    [m] apart in (r, z); ``frozen`` = (joint, value) holds that joint at value in both."""
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + 0.1 * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - 0.1 * (L["q_max"] - L["q_min"])
    out = []
    while len(out) < k:
        qa, qb = (lo + rng.random(crane.n) * (hi - lo) for _ in range(2))
        if frozen is not None:
            qa[frozen[0]] = qb[frozen[0]] = frozen[1]
        a, b = crane.tip(qa), crane.tip(qb)
        if np.hypot(a[0] - b[0], a[1] - b[1]) >= min_dist:
            out.append((a, b))
    return out


def freeze_joint(nlp: MoveNLP, joint: int, value: float) -> None:
    """Hold ``joint`` at ``value`` (rest: q̇ = q̈ = jerk = 0) at every node through the solver's
    variable bounds. Variables start with X = [q; q̇; q̈] per node (column-major), then the jerks
    U (n per interval); IPOPT removes fixed variables (fixed_variable_treatment make_parameter),
    so the problem it solves has one joint fewer."""
    n, N = nlp.crane.n, nlp.N
    for k in range(N + 1):
        base = 3 * n * k
        for i, v in ((base + joint, value), (base + n + joint, 0.0), (base + 2 * n + joint, 0.0)):
            nlp.lbw[i] = nlp.ubw[i] = v
    for k in range(N):
        i = nlp._nx + n * k + joint
        nlp.lbw[i] = nlp.ubw[i] = 0.0


def nlp_case(crane, N: int, moves, repeats: int, frozen: tuple | None = None) -> dict:
    """Build the minimum-time free-path NLP once (build time [s]), then time every move
    (:func:`solve_timing`). Size = CasADi variables, constraints, free variables (not fixed by
    equal bounds), non-zeros of the constraint Jacobian and of the Lagrangian's Hessian."""
    t0 = time.perf_counter()
    nlp = MoveNLP(crane, "time", "free", N=N)
    build = time.perf_counter() - t0
    if frozen is not None:
        freeze_joint(nlp, *frozen)
    rows = [solve_timing(nlp, a, b, repeats) for a, b in moves]
    ok = [r for r in rows if r["status"] == "ok"]
    out = dict(N=N, build_s=build, variables=int(nlp.nw), constraints=int(len(nlp.lbg)),
               free_variables=int(np.sum(nlp.lbw < nlp.ubw)), **_nnz(nlp), moves=rows,
               ok=len(ok))
    for k in ("solve_s", "first_solve_s", "guess_s", "iterations", "s_per_iteration",
              "eval_s_per_iteration", "ipopt_s_per_iteration"):
        out[f"median_{k}"] = _med([r[k] for r in ok])
    return out


def solve_timing(nlp: MoveNLP, a, b, repeats: int) -> dict:
    """One move on a built NLP: the first solve [s] (one-off costs after a build, timed on its
    own), the median of ``repeats`` solves [s], the default guess alone [s] (the Python side of
    solve()), and per IPOPT iteration [s]: all of (solve − guess), the CasADi function
    evaluations (the solver's t_wall_nlp_* of the last solve) and the rest = IPOPT itself
    (mostly the sparse KKT factorisation)."""
    # the NLP itself: the default guess passed explicitly, so that solve() does not swap in
    # the exact Ruckig move when it is faster (that would hide the grid's convergence in N,
    # and it does not know about a joint frozen through the variable bounds)
    def own():
        return nlp.solve(a, b, w0=nlp.default_guess(a, b)[0])
    t0 = time.perf_counter()
    own()
    first = time.perf_counter() - t0
    med, ts, r = timed(own, repeats)
    st = nlp.solver.stats()  # the last solve's (a time-optimal solve is one solver call)
    ev = sum(v for k, v in st.items() if k.startswith("t_wall_nlp"))
    guess = timed(lambda: nlp.default_guess(a, b), repeats)[0]
    it = r.iterations or float("nan")
    return dict(status=r.status, duration_s=r.duration_s, iterations=r.iterations,
                first_solve_s=first, solve_s=med, solve_times_s=ts, guess_s=guess, eval_s=ev,
                s_per_iteration=(med - guess) / it, eval_s_per_iteration=ev / it,
                ipopt_s_per_iteration=(med - guess - ev) / it)


def _nnz(nlp: MoveNLP) -> dict:
    """Non-zeros of the constraint Jacobian and the Lagrangian's Hessian (None if the CasADi
    build does not expose them)."""
    out = {}
    for key, name in (("jac_nnz", "nlp_jac_g"), ("hess_nnz", "nlp_hess_l")):
        try:
            f = nlp.solver.get_function(name)
            out[key] = int(f.sparsity_out(f.n_out() - 1).nnz())
        except Exception:  # an optional diagnostic: absent in some CasADi versions
            out[key] = None
    return out


def _med(v):
    return float(statistics.median(v)) if v else float("nan")


def nlp_cases(cfg: Config) -> dict:
    """{label: (crane, moves, frozen)}: every machine on its own moves, and the s100f on moves
    with the telescope at mid-range, free (4 DOF) and frozen there (3 DOF)."""
    cases = {}
    for k, cid in enumerate(NLP_MACHINES):
        c = Crane.from_id(cid)
        cases[f"{cid} ({c.n} DOF)"] = (c, nlp_moves(c, cfg.nlp_moves, seed=700 + k), None)
    c = Crane.from_id(FROZEN_MACHINE)
    j = c.chain.tele
    mid = 0.5 * sum(c.tele_range)
    mv = nlp_moves(c, cfg.nlp_moves, seed=799, frozen=(j, mid))
    cases[f"{FROZEN_MACHINE} tele-mid moves (4 DOF)"] = (c, mv, None)
    cases[f"{FROZEN_MACHINE} tele frozen at {mid:.2f} m (3 DOF)"] = (c, mv, (j, mid))
    return cases


def nlp_study(cfg: Config) -> dict:
    """Every case at every N, the per-move duration gap to the largest N, and the exponents."""
    cases = nlp_cases(cfg)
    res = {}
    with tqdm(total=len(cases) * len(cfg.nlp_N), desc="NLP", unit="N") as bar:
        for label, (crane, moves, frozen) in cases.items():
            rows = []
            for N in cfg.nlp_N:
                rows.append(nlp_case(crane, N, moves, cfg.nlp_repeats, frozen))
                _tick(bar, f"{label} N={N}")
            res[label] = dict(machine=crane.spec.id, joints=crane.n - (frozen is not None),
                              frozen=None if frozen is None else dict(joint=crane.names[frozen[0]],
                                                                      value=frozen[1]),
                              moves=[dict(start=a, goal=b) for a, b in moves], by_N=rows,
                              fits=_nlp_fits(rows))
            _duration_gaps(rows)
    return res


def _duration_gaps(rows) -> None:
    """Per N: median over moves of duration / duration at the largest N − 1 [-]."""
    ref = [m["duration_s"] for m in rows[-1]["moves"]]
    for r in rows:
        g = [m["duration_s"] / d - 1 for m, d in zip(r["moves"], ref)
             if m["status"] == "ok" and np.isfinite(d)]
        r["median_gap_to_largest_N"] = _med(g)
        r["max_gap_to_largest_N"] = max(g) if g else float("nan")


def _nlp_fits(rows) -> dict:
    """Log-log exponents in N over all N (and solve time between the two largest N)."""
    N = [r["N"] for r in rows]

    def col(k):
        return [r[k] if r[k] is not None else float("nan") for r in rows]
    return dict(solve_vs_N=slope(N, col("median_solve_s")),
                solve_vs_N_largest_pair=slope(N[-2:], col("median_solve_s")[-2:]),
                build_vs_N=slope(N, col("build_s")),
                per_iteration_vs_N=slope(N, col("median_s_per_iteration")),
                eval_per_iteration_vs_N=slope(N, col("median_eval_s_per_iteration")),
                ipopt_per_iteration_vs_N=slope(N, col("median_ipopt_s_per_iteration")),
                ipopt_per_iteration_largest_pair=slope(
                    N[-2:], col("median_ipopt_s_per_iteration")[-2:]),
                eval_per_iteration_largest_pair=slope(
                    N[-2:], col("median_eval_s_per_iteration")[-2:]),
                iterations_vs_N=slope(N, col("median_iterations")),
                variables_vs_N=slope(N, col("variables")),
                jac_nnz_vs_N=slope(N, col("jac_nnz")))


# ------------------------------------------------------------------------------ 3. library
def library_run(workers: int, moves: int, folder, robustness: bool = True) -> dict:
    """Wall time [s] of one fresh build of the first ``moves`` forwarder-cycle moves on the
    s100f, objective time, with ``workers`` local processes (build()'s own clock: pool start,
    every worker building its NLP, planning, writing)."""
    import planner.library.build as library
    library.clear_planner_caches()  # forked workers would inherit the parent's built NLPs
    out = Path(folder) / f"w{workers}_{time.monotonic_ns()}.h5"
    s = library.build("s100f", "forwarder-cycle", out, objectives=("time",), workers=workers,
                      limit=moves, robustness=robustness, progress=False)
    out.unlink(missing_ok=True)
    return dict(workers=workers, seconds=s["seconds"], entries=s["planned"],
                statuses=s["statuses"])


def library_study(cfg: Config) -> dict:
    """Interleaved rounds over cfg.lib_workers (after a 1-move warm-up that loads every module),
    median time per worker count, speed-up and efficiency vs 1 worker."""
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        library_run(1, 1, tmp, cfg.lib_robustness)
        with tqdm(total=cfg.lib_rounds * len(cfg.lib_workers), desc="library",
                  unit="build") as bar:
            for rnd in range(cfg.lib_rounds):
                for w in cfg.lib_workers:
                    runs.append(dict(library_run(w, cfg.lib_moves, tmp, cfg.lib_robustness),
                                     round=rnd))
                    _tick(bar, f"workers={w}")
    rows = []
    for w in cfg.lib_workers:
        ts = [r["seconds"] for r in runs if r["workers"] == w]
        rows.append(dict(workers=w, median_s=_med(ts), times_s=ts))
    t1 = next(r["median_s"] for r in rows if r["workers"] == 1)
    for r in rows:
        r["speedup"] = t1 / r["median_s"]
        r["efficiency"] = r["speedup"] / r["workers"]
    two = next((r for r in rows if r["workers"] == 2), None)
    serial = 2.0 / two["speedup"] - 1.0 if two else float("nan")  # Amdahl from S(2)
    return dict(moves=cfg.lib_moves, objective="time", robustness=cfg.lib_robustness,
                entries=runs[0]["entries"], runs=runs, by_workers=rows,
                amdahl_serial_fraction=serial, dask=dask_reference())


def dask_reference(path=DASK_JSON) -> dict | None:
    """The Dask LocalCluster numbers of bench_library.py (not re-run here)."""
    import json
    try:
        d = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    k = d.get("dask", {})
    if "1" not in k or "2" not in k:
        return None
    return dict(source=str(path), date=k.get("date"),  # None: the rows carry no date
                entries=k["1"]["entries"], seconds_1=k["1"]["seconds"],
                seconds_2=k["2"]["seconds"], speedup=k.get("speedup"))


# ------------------------------------------------------------------------------ report
def _tick(bar, text):
    if bar is not None:
        bar.set_postfix_str(text)
        bar.update(1)


def _pct(x):
    """Relative value [-] as a percentage with 3 significant digits (|x| < 1e-12: rounding)."""
    if x is None or not np.isfinite(x):
        return "n/a"
    return "0 %" if abs(x) < 1e-12 else f"{100 * x:+.3g} %"


def md_dp(d: dict) -> list:
    L = ["## 1. Dynamic programming (minimum time)", "",
         f"Wall time = median of the timed runs after one warm-up ({FAST_REPEATS} runs when "
         f"the warm-up took < {FAST_S} s); nodes = (stages + 1) × "
         "telescope nodes; edges = the in-grid transitions (≤ 2w + 1 per node); memory = peak "
         "traced by tracemalloc in one run; gap = minimum time / the finest grid's − 1.", ""]
    for name, rows in d["resolution"].items():
        L += [f"### (a) Resolution: {name} (path step Δ = telescope step, window "
              f"{rows[0]['window']})", "",
              "| Δ [m] | stages | tele nodes | nodes | edges | time [s] | peak mem [MB] | "
              "min. time [s] | gap to finest |",
              "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        L += [f"| {r['step_m']:g} | {r['stages']} | {r['tele_nodes']} | {r['nodes']:,} | "
              f"{r['edges']:,} | {r['time_s']:.4f} | {r['peak_mb']:.0f} | "
              f"{r['duration_s']:.5f} | {_pct(r['gap_to_finest'])} |" for r in rows]
        L.append("")
    w = d["window"]
    L += [f"### (b) Telescope window: cranab850 A–C, Δ = {w[0]['step_m']:g} m", "",
          "| window w | edges | time [s] | min. time [s] |", "| ---: | ---: | ---: | ---: |"]
    L += [f"| {r['window']} | {r['edges']:,} | {r['time_s']:.4f} | {r['duration_s']:.5f} |"
          for r in w]
    g = d["length"]
    L += ["", f"### (c) Path length: cranab850, sub-segments of the chord r = 7.5 m, slew −0.6 → "
          f"0.6 rad; Δ = {g[0]['step_m']:g} m, window {g[0]['window']}", "",
          "| length [m] | stages | nodes | time [s] | min. time [s] |",
          "| ---: | ---: | ---: | ---: | ---: |"]
    L += [f"| {r['length_m']:.2f} | {r['stages']} | {r['nodes']:,} | {r['time_s']:.4f} | "
          f"{r['duration_s']:.4f} |" for r in g]
    fi = d["fits"]
    L += ["", "### Fitted log-log exponents (numpy.polyfit; expected from the code in brackets)",
          "", "| sweep | time vs edges [1] | same, two finest grids [1] | edges vs Δ [−2] | "
          "peak memory vs edges [1] |", "| --- | ---: | ---: | ---: | ---: |"]
    L += [f"| resolution, {k} | {fi[k]['time_vs_edges']:.2f} | "
          f"{fi[k]['time_vs_edges_finest_pair']:.2f} | {fi[k]['edges_vs_step']:.2f} | "
          f"{fi[k]['memory_vs_edges']:.2f} |" for k in d["resolution"]]
    L += [f"| window | {fi['window']['time_vs_edges']:.2f} (≤ 1) | | | |",
          f"| path length (time vs stages) | {fi['length']['time_vs_stages']:.2f} | | | |"]
    return L + [""]


def md_nlp(n: dict) -> list:
    L = ["## 2. NLP (minimum time, free path, pump limit)", "",
         "Built once per N (build [s]); each move solved once (first solve: one-off costs "
         "after a build), then repeatedly from the default guess (solve = median; medians over "
         "the moves in the table). vars / cons = CasADi decision variables / constraints (free: "
         "not fixed by equal bounds); nnz J / H = non-zeros of the constraint Jacobian / the "
         "Lagrangian's Hessian; iters = IPOPT iterations; ms / iter = (solve − default guess) "
         "/ iters, split into CasADi evaluations (eval) and IPOPT itself (the rest: mostly the "
         "sparse KKT factorisation); gap = median over moves of duration / duration at the "
         "largest N − 1.", ""]
    for label, c in n.items():
        L += [f"### {label}", "",
              "| N | vars (free) | cons | nnz J / H | build [s] | first solve [s] | solve [s] | "
              "guess [s] | iters | ms / iter (eval + IPOPT) | ok | gap to largest N |",
              "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
              "---: |"]
        for r in c["by_N"]:
            L.append(f"| {r['N']} | {r['variables']} ({r['free_variables']}) | "
                     f"{r['constraints']} | {r['jac_nnz']} / {r['hess_nnz']} | "
                     f"{r['build_s']:.3f} | "
                     f"{r['median_first_solve_s']:.3f} | {r['median_solve_s']:.3f} | "
                     f"{r['median_guess_s']:.3f} | "
                     f"{r['median_iterations']:.0f} | {1e3 * r['median_s_per_iteration']:.2f} "
                     f"({1e3 * r['median_eval_s_per_iteration']:.2f} + "
                     f"{1e3 * r['median_ipopt_s_per_iteration']:.2f}) | "
                     f"{r['ok']}/{len(r['moves'])} | {_pct(r['median_gap_to_largest_N'])} |")
        L.append("")
    L += ["Fitted log-log exponents in N (over all N; solve also between the two largest N):",
          "", "| case | solve | solve, largest pair | per iter | eval / iter | IPOPT / iter | "
          "IPOPT / iter, largest pair | iterations | build | Jacobian nnz |",
          "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for label, c in n.items():
        f = c["fits"]
        L.append(f"| {label} | " + " | ".join(f"{f[k]:.2f}" for k in (
            "solve_vs_N", "solve_vs_N_largest_pair", "per_iteration_vs_N",
            "eval_per_iteration_vs_N", "ipopt_per_iteration_vs_N",
            "ipopt_per_iteration_largest_pair", "iterations_vs_N",
            "build_vs_N", "jac_nnz_vs_N")) + " |")
    L += ["", "Durations [s] per move at each N:", "", "| case | N | " +
          " | ".join(f"move {i + 1}" for i in range(_max_moves(n))) + " |",
          "| --- | ---: |" + " ---: |" * _max_moves(n)]
    for label, c in n.items():
        for r in c["by_N"]:
            cells = [f"{m['duration_s']:.4f}" if m["status"] == "ok" else m["status"]
                     for m in r["moves"]]
            L.append(f"| {label} | {r['N']} | " + " | ".join(cells) + " |")
    return L + [""]


def _max_moves(n):
    return max(len(c["by_N"][0]["moves"]) for c in n.values())


def md_library(lib: dict, cpus) -> list:
    L = ["## 3. Library build vs workers (local processes)", "",
         f"`build('s100f', 'forwarder-cycle', objectives=('time',), limit={lib['moves']}, "
         f"workers=w)` into a fresh file ({lib['entries']} entries; robustness scoring "
         f"{'on' if lib['robustness'] else 'off'}); build()'s own wall time, {len(lib['runs'])} "
         "builds in interleaved rounds, median per w. Every worker builds its NLP once.", "",
         "| workers | median [s] | runs [s] | speed-up | efficiency |",
         "| ---: | ---: | --- | ---: | ---: |"]
    L += [f"| {r['workers']} | {r['median_s']:.2f} | "
          f"{', '.join(f'{t:.2f}' for t in r['times_s'])} | {r['speedup']:.2f} | "
          f"{100 * r['efficiency']:.0f} % |" for r in lib["by_workers"]]
    dk = lib.get("dask")
    if dk:
        when = f"run {dk['date']}" if dk["date"] else "rows undated in the file"
        L += ["", f"Dask LocalCluster (cited from `{Path(dk['source']).name}`, {when}; "
              f"{dk['entries']} entries, objectives time + energy, robustness on): 1 worker "
              f"{dk['seconds_1']:.1f} s, 2 workers {dk['seconds_2']:.1f} s, speed-up "
              f"{dk['speedup']:.2f}."]
    L.append(f"\nThe machine has {cpus} CPUs: more workers than that cannot add throughput.")
    return L + [""]


def findings(rep: dict) -> list:
    """Short findings in numbers, computed from the measurements."""
    out = []
    if rep.get("dp"):
        out += _dp_findings(rep["dp"])
    if rep.get("nlp"):
        out += _nlp_findings(rep["nlp"]) + _frozen_finding(rep["nlp"])
    if rep.get("library"):
        out += _library_findings(rep["library"], rep["machine"]["cpu_count"])
    return out


def _span(v, fmt="{:.2f}", sep="–"):
    """'min–max' of the finite values (equal when formatted: one value)."""
    v = [x for x in v if x is not None and np.isfinite(x)]
    if not v:
        return "n/a"
    lo, hi = fmt.format(min(v)), fmt.format(max(v))
    return lo if lo == hi else f"{lo}{sep}{hi}"


def _dp_findings(d: dict) -> list:
    out = []
    for name, rows in d["resolution"].items():
        f = d["fits"][name]
        out.append(f"DP {name}: halving Δ (and the telescope step) multiplies the edges by "
                   f"~4 (edges ∝ Δ^{f['edges_vs_step']:.2f}); time ∝ edges^"
                   f"{f['time_vs_edges']:.2f} over Δ = {rows[0]['step_m']:g} → "
                   f"{rows[-1]['step_m']:g} m, {f['time_vs_edges_finest_pair']:.2f} between the "
                   f"two finest grids (expected 1){_coarse_note(f)}; finest grid "
                   f"{rows[-1]['time_s']:.2f} s and "
                   f"{rows[-1]['peak_mb']:.0f} MB peak (memory ∝ edges^"
                   f"{f['memory_vs_edges']:.2f}). Minimum time vs the finest grid: "
                   + ", ".join(f"{_pct(r['gap_to_finest'])} at {r['step_m']:g} m"
                               for r in rows[:-1]) + ".")
    fl, fw = d["fits"]["length"], d["fits"]["window"]
    out.append(f"DP path length {d['length'][0]['length_m']:g} → {d['length'][-1]['length_m']:g}"
               f" m at a fixed grid: time ∝ stages^{fl['time_vs_stages']:.2f} (expected 1). "
               f"Window w = {d['window'][0]['window']} → {d['window'][-1]['window']}: time ∝ "
               f"edges^{fw['time_vs_edges']:.2f} (the IK of the nodes does not grow with w); "
               f"minimum time {_span([r['duration_s'] for r in d['window']], '{:.5f}')} s "
               "over the windows.")
    return out


def _coarse_note(f) -> str:
    if f["time_vs_edges"] < f["time_vs_edges_finest_pair"] - 0.05:
        return "; the fixed per-stage Python cost of the Bellman loop flattens the coarse end"
    return ""


def _nlp_findings(n: dict) -> list:
    fits = [c["fits"] for c in n.values()]
    first = [c["by_N"][0] for c in n.values()]
    last = [c["by_N"][-1] for c in n.values()]
    N0, N1 = first[0]["N"], last[0]["N"]
    mid = [next((r for r in c["by_N"] if r["N"] == 40), None) for c in n.values()]
    out = [f"NLP solve time ∝ N^{_span([f['solve_vs_N'] for f in fits])} over N = {N0} → {N1} "
           f"(all cases), but N^{_span([f['solve_vs_N_largest_pair'] for f in fits])} between "
           f"the two largest N: {_span([r['median_solve_s'] for r in first], '{:.3f}')} s at "
           f"N = {N0}, {_span([r['median_solve_s'] for r in last], '{:.2f}')} s at N = {N1}.",
           f"Per IPOPT iteration over all N: CasADi evaluations ∝ "
           f"N^{_span([f['eval_per_iteration_vs_N'] for f in fits])}, IPOPT itself ∝ "
           f"N^{_span([f['ipopt_per_iteration_vs_N'] for f in fits])}; between the two largest "
           f"N: evaluations N^{_span([f['eval_per_iteration_largest_pair'] for f in fits])}, "
           f"IPOPT itself N^{_span([f['ipopt_per_iteration_largest_pair'] for f in fits])}. "
           f"Jacobian non-zeros ∝ N^{_span([f['jac_nnz_vs_N'] for f in fits])}, iterations ∝ "
           f"N^{_span([f['iterations_vs_N'] for f in fits])}"
           + (": IPOPT's own work (mostly the sparse KKT solve), not the problem size or the "
              "iteration count, turns superlinear at the largest N."
              if min(f["ipopt_per_iteration_largest_pair"] for f in fits) > 1.3 else "."),
           f"Build ∝ N^{_span([f['build_vs_N'] for f in fits])} "
           f"({_span([r['build_s'] for r in last])} s at N = {N1}). The default guess costs "
           f"{_span([r['median_guess_s'] for r in first], '{:.3f}')} s per solve whatever N "
           f"(up to {100 * max(r['median_guess_s'] / r['median_solve_s'] for r in first):.0f} %"
           f" of the solve at N = {N0}).",
           f"Minimum time vs N = {N1} (median over moves): "
           f"{_span([100 * r['median_gap_to_largest_N'] for r in first], '{:+.1f}', ' to ')} %"
           f" at N = {N0}"
           + (f", {_span([100 * r['median_gap_to_largest_N'] for r in mid], '{:+.2f}', ' to ')}"
              " % at N = 40 (the library's N)" if all(mid) and N1 != 40 else "") + "."]
    return out


def _frozen_finding(n: dict) -> list:
    free = next((c for k, c in n.items() if "tele-mid" in k), None)
    frz = next((c for c in n.values() if c["frozen"]), None)
    if not (free and frz):
        return []
    r = [b["median_solve_s"] / a["median_solve_s"] for a, b in zip(free["by_N"], frz["by_N"])]
    dur = [m2["duration_s"] / m1["duration_s"] for a, b in zip(free["by_N"], frz["by_N"])
           for m1, m2 in zip(a["moves"], b["moves"]) if m1["status"] == m2["status"] == "ok"]
    return [f"DOF: freezing the {frz['machine']} telescope (3 of 4 joints free, same moves) "
            f"scales the solve time by {_span(r)} over N and the move durations by "
            f"{_span(dur, '{:.3f}')} (the redundancy can only help). Across machines, the "
            f"3-joint cat215b solves in {_span(_solve_ratio(n), '{:.2f}')} × the time of the "
            "4-joint machines at equal N (different limits and moves, so not only the DOF)."]


def _solve_ratio(n: dict) -> list:
    """cat215b median solve / each 4-joint machine's, per N."""
    three = next((c for c in n.values() if c["machine"] == "cat215b" and not c["frozen"]), None)
    if three is None:
        return []
    return [a["median_solve_s"] / b["median_solve_s"] for c in n.values()
            if c["joints"] == 4 for a, b in zip(three["by_N"], c["by_N"])]


def _library_findings(lib: dict, cpus) -> list:
    rows = lib["by_workers"]
    txt = ", ".join(f"{r['speedup']:.2f}× at {r['workers']} ({100 * r['efficiency']:.0f} %)"
                    for r in rows[1:])
    out = [f"Library build ({lib['entries']} entries): speed-up {txt}; Amdahl serial fraction "
           f"from the 2-worker speed-up {lib['amdahl_serial_fraction']:.2f}."]
    over = [r for r in rows if cpus and r["workers"] > cpus]
    at = next((r for r in rows if r["workers"] == cpus), None)
    if over and at:
        out.append(f"More workers than the {cpus} CPUs: "
                   + ", ".join(f"{r['workers']} workers take {r['median_s'] / at['median_s']:.2f}"
                               f" × the {cpus}-worker time" for r in over)
                   + " (each extra process builds its own NLP and competes for the cores).")
    dk = lib.get("dask")
    if dk:
        out.append(f"Dask LocalCluster (cited): {dk['speedup']:.2f}× with 2 workers on "
                   f"{dk['entries']} time + energy entries.")
    return out


EXPECTED = [
    "Expected from the code: the DP computes the IK of every node, O(stages × tele nodes), "
    "then every edge cost as (stages, tele nodes, 2w + 1, joints) arrays, and a Bellman loop "
    "over the stages, each step vectorised over nodes × window: time and memory "
    "O(stages × tele nodes × (2w + 1) × joints), i.e. exponent 1 in the edges, Δ^-2 when Δ and "
    "the telescope step shrink together, 1 in the path length, ≤ 1 in (2w + 1).",
    "The NLP has (4 × joints) × N + O(1) variables (q, q̇, q̈ per node, jerk per interval, T) "
    "and O(joints × N) constraints; its KKT matrix is banded in time, so a sparse "
    "factorisation costs O(N) per IPOPT iteration: solve time ∝ N × iterations.",
]


def markdown(rep: dict) -> str:
    m = rep["machine"]
    L = ["# Scaling study (issue 7)" + (" — quick run" if rep["quick"] else ""), "",
         f"Machine: {m['platform']}, {m['cpu_count']} CPUs ({m.get('cpu_model') or 'unknown'}), "
         f"Python {m['python']}, {m['date_utc']}; 1-min load {m['load_1_5_15'][0]:.2f} at the "
         f"start, {m.get('load_1_5_15_end', [float('nan')])[0]:.2f} at the end. "
         f"`python benchmarks/bench_scaling.py{' --quick' if rep['quick'] else ''}`, "
         f"{rep['wall_s']:.0f} s.", "", "## Findings", ""]
    L += [f"- {f}" for f in findings(rep)]
    L += ["", *[f"- {e}" for e in EXPECTED], ""]
    if rep.get("dp"):
        L += md_dp(rep["dp"])
    if rep.get("nlp"):
        L += md_nlp(rep["nlp"])
    if rep.get("library"):
        L += md_library(rep["library"], m["cpu_count"])
    L += ["Figures: `scaling_dp.png`, `scaling_nlp.png`, `scaling_library.png`; raw numbers: "
          "`scaling.json`.", ""]
    return "\n".join(L)


# ------------------------------------------------------------------------------ figures
def _ref_line(ax, x, y0, p, label):
    """Dashed y ∝ x^p through (x[0], y0)."""
    x = np.asarray(x, float)
    ax.plot(x, y0 * (x / x[0]) ** p, "k--", lw=0.8, alpha=0.6, label=label)


def _tidy(ax, xticks=None):
    """Grid, no minor tick labels on log axes, plain labels at ``xticks``."""
    from matplotlib.ticker import NullFormatter, ScalarFormatter
    ax.grid(alpha=0.3, which="both")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_minor_formatter(NullFormatter())
    if xticks is not None:
        ax.set_xticks(list(xticks))
        ax.xaxis.set_major_formatter(ScalarFormatter())


def fig_dp(d: dict, path) -> None:
    """2 × 2: time vs edges (resolution), accuracy vs Δ, time vs 2w + 1, time vs stages."""
    from planner.plots import plt, save
    fig, ax = plt.subplots(2, 2, figsize=(10, 8))
    a, acc, win, ln = ax.flat
    for name, rows in d["resolution"].items():
        e = [r["edges"] for r in rows]
        a.loglog(e, [r["time_s"] for r in rows], "o-", label=name)
        acc.loglog([r["step_m"] for r in rows[:-1]],
                   [max(abs(r["gap_to_finest"]), 1e-12) for r in rows[:-1]], "o-", label=name)
    first = min((r[0] for r in d["resolution"].values()), key=lambda r: r["edges"])
    _ref_line(a, [first["edges"], max(r[-1]["edges"] for r in d["resolution"].values())],
              first["time_s"], 1.0, "∝ edges¹")
    a.set(xlabel="graph edges [-]", ylabel="DP wall time [s]",
          title="(a) resolution: Δ = telescope step, w fixed")
    steps = [r["step_m"] for r in next(iter(d["resolution"].values()))[:-1]]
    acc.set(xlabel="path step Δ = telescope step [m]",
            ylabel="|min. time / finest grid's − 1| [-] (0 drawn at 1e-12)",
            title="(a) accuracy vs the finest grid")
    w = d["window"]
    x = [2 * r["window"] + 1 for r in w]
    win.loglog(x, [r["time_s"] for r in w], "o-", label="cranab850 A–C")
    _ref_line(win, x, w[0]["time_s"], 1.0, "∝ (2w + 1)¹")
    win.set(xlabel="transitions per node 2w + 1 [-]", ylabel="DP wall time [s]",
            title=f"(b) telescope window, Δ = {w[0]['step_m']:g} m")
    g = d["length"]
    st = [r["stages"] for r in g]
    ln.loglog(st, [r["time_s"] for r in g], "o-", label="cranab850 chord")
    _ref_line(ln, st, g[0]["time_s"], 1.0, "∝ stages¹")
    ln.set(xlabel=f"stages (path length / {g[0]['step_m']:g} m) [-]", ylabel="DP wall time [s]",
           title="(c) path length, fixed grid")
    for axis, ticks in ((a, None), (acc, steps), (win, x), (ln, st)):
        _tidy(axis, ticks)
        axis.legend(fontsize=8)
    fig.suptitle("DP (minimum time) cost scaling")
    fig.tight_layout()
    save(fig, path)


def fig_nlp(n: dict, path) -> None:
    """2 × 2 vs N: solve time, build time, time per IPOPT iteration, duration gap."""
    from planner.plots import plt, save
    fig, ax = plt.subplots(2, 2, figsize=(11, 8.5))
    for label, c in n.items():
        rows = c["by_N"]
        N = [r["N"] for r in rows]
        ls = "s--" if c["frozen"] else "o-"
        ax[0, 0].loglog(N, [r["median_solve_s"] for r in rows], ls, label=label)
        ax[0, 1].loglog(N, [r["build_s"] for r in rows], ls, label=label)
        ax[1, 0].loglog(N, [1e3 * r["median_s_per_iteration"] for r in rows], ls, label=label)
        ax[1, 1].loglog(N[:-1], [max(abs(r["median_gap_to_largest_N"]), 1e-6)
                                 for r in rows[:-1]], ls, label=label)
    rows = next(iter(n.values()))["by_N"]
    N = [r["N"] for r in rows]
    _ref_line(ax[0, 0], N, rows[0]["median_solve_s"], 1.0, "∝ N¹")
    _ref_line(ax[0, 1], N, rows[0]["build_s"], 1.0, "∝ N¹")
    _ref_line(ax[1, 0], N, 1e3 * rows[0]["median_s_per_iteration"], 1.0, "∝ N¹")
    ax[0, 0].set(ylabel="solve time (median) [s]", title="solve (built once, solved repeatedly)")
    ax[0, 1].set(ylabel="build time [s]", title="build (once per N)")
    ax[1, 0].set(ylabel="(solve − default guess) / iterations [ms]",
                 title="time per IPOPT iteration")
    ax[1, 1].set(ylabel="|duration / duration at largest N − 1| [-]",
                 title="convergence of the minimum time (median over moves)")
    for a in ax.flat:
        a.set_xlabel("horizon N [intervals]")
        _tidy(a, N if a is not ax[1, 1] else N[:-1])
    ax[0, 0].legend(fontsize=7)
    ax[0, 1].legend(fontsize=7, handles=ax[0, 1].get_lines()[-1:])
    fig.suptitle("Minimum-time NLP (free path) vs the horizon N; dashed squares: s100f with "
                 "the telescope frozen")
    fig.tight_layout()
    save(fig, path)


def fig_library(lib: dict, cpus, path) -> None:
    """Wall time and speed-up vs workers (local processes), Dask cited."""
    from planner.plots import plt, save
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    rows = lib["by_workers"]
    w = [r["workers"] for r in rows]
    for r in rows:
        ax[0].plot([r["workers"]] * len(r["times_s"]), r["times_s"], "k.", alpha=0.5)
    ax[0].plot(w, [r["median_s"] for r in rows], "o-", label="local processes (median; dots: runs)")
    ax[0].set(xlabel="workers [-]", ylabel="build wall time [s]",
              title=f"s100f forwarder-cycle, {lib['entries']} time-optimal entries")
    ax[0].set_ylim(bottom=0)
    ax[1].plot(w, [r["speedup"] for r in rows], "o-", label="local processes")
    ax[1].plot(w, [min(x, cpus or x) for x in w], "k--", lw=0.8, label=f"ideal on {cpus} CPUs")
    dk = lib.get("dask")
    if dk:
        ax[1].plot([1, 2], [1.0, dk["speedup"]], "s:", label=f"Dask LocalCluster, "
                   f"{dk['entries']} entries (cited)")
    ax[1].set(xlabel="workers [-]", ylabel="speed-up vs 1 worker [-]", title="speed-up")
    ax[1].set_ylim(bottom=0)
    for a in ax:
        a.set_xticks(w)
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.tight_layout()
    save(fig, path)


def write_outputs(rep: dict, out) -> list:
    """scaling.json, scaling.md and the figures of the parts present, atomically; the paths."""
    out = Path(out)
    paths = []
    cpus = rep["machine"]["cpu_count"]
    for key, fn, name in (("dp", fig_dp, "scaling_dp.png"), ("nlp", fig_nlp, "scaling_nlp.png"),
                          ("library", lambda x, p: fig_library(x, cpus, p),
                           "scaling_library.png")):
        if rep.get(key):
            fn(rep[key], out / name)
            paths.append(out / name)
    atomic_write_text(out / "scaling.json", dumps(rep) + "\n")
    atomic_write_text(out / "scaling.md", markdown(rep))
    return [out / "scaling.json", out / "scaling.md", *paths]


def run(cfg: Config, quick: bool = False, parts=("dp", "nlp", "library")) -> dict:
    """Measure the requested parts; the report dict (raw numbers, machine, config)."""
    t0 = time.perf_counter()
    rep = dict(machine=machine(), quick=quick, config=asdict(cfg))
    if "dp" in parts:
        rep["dp"] = dp_study(cfg)
    if "nlp" in parts:
        rep["nlp"] = nlp_study(cfg)
    if "library" in parts:
        rep["library"] = library_study(cfg)
    rep["wall_s"] = time.perf_counter() - t0
    rep["machine"]["load_1_5_15_end"] = os.getloadavg()
    return rep


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sweeps (~1 min)")
    ap.add_argument("--out", default=None,
                    help="output folder (default benchmarks/results; --quick: a temp folder)")
    args = ap.parse_args(argv)
    out = Path(args.out) if args.out else (
        Path(tempfile.gettempdir()) / "bench_scaling_quick" if args.quick else RESULTS)
    rep = run(QUICK if args.quick else FULL, quick=args.quick)
    for p in write_outputs(rep, out):
        print(p)
    print("\n".join(f"- {f}" for f in findings(rep)))


if __name__ == "__main__":
    main()
