"""The loop on the landing gap (issue 28, item 4): Exudyn machines whose dynamic parameters
the planner was never given, each calibrated from one designed excitation log, the library's
feed-forward refined on the calibrated twin and replayed on that machine. Judge: the Exudyn
plant throughout; the twin only fits and refines.

Machines: the drawn machines of ``bench_refine_robust.py`` (same seed and spread: each
machine's bulk modulus, hose volumes, spool and pump time constants, friction within ±30 %,
a leakage and a valve dead band the spec does not have, and a bulk modulus that rises with
pressure), plus a command delay U(0, ``--delay-max``) between the command and the valves (in
the calibrated family since 2026-11-27: ``[dynamics] command_delay``), and one valve (drawn)
whose spool lags U(0, ``--lag-max``) behind the others — the effect the twin lacks: its family
has one spool time constant for every valve. Per machine:

1. the excitation (``trials.excitation``, ``--duration`` s, or ``--excitation FILE.csv``)
   replayed open loop on the machine, logged at 50 Hz with seed 001's sensor noise;
2. ``TwinFit`` on that log (every parameter; ``--anchor``), the calibrated spec written to
   ``WORK/cal-<machine>.toml`` (what ``crane-planner calibrate`` writes);
3. the first ``--entries`` entries of the chain library refined on it (``library refine
   --model``, a copy of the library per machine) and replayed on the machine.

Beside them, on the same machines: the nominal commands and the commands refined once on the
spec's twin (un-calibrated; the refinements ``bench_refine_robust.py`` stored in ``sel.h5``).

    python benchmarks/bench_calibrate_loop.py --work /tmp/robust/work [--machines 6]
        [--entries 8] [--duration 120] [--iterations 12] [--workers 2]

The issue's ≥ 100 entries per machine go in parts: ``--library sel-s100f-400-p0-v5.h5`` (a
``bench_refine.py`` part's library: its entries, each refined on the spec's twin) with
``--calibrations DIR`` (the calibrated twins of a first run: the same fits for every part)
and ``--only m1,m2`` (some of the machines), each part in its own ``--work`` and ``--tag``;
then ``--merge PART.json … --tag T`` (refuses parts on other machines, other calibrations or
a repeated entry) writes one report and its figure (landed share per machine, rest offsets).

Results: benchmarks/results/calibrate_loop.md / .json.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_refine_robust import TOL, _crane, _landed, draw_machines  # noqa: E402
from bench_refine_robust import machine_plant as robust_plant  # noqa: E402
from planner.io import atomic_write_text  # noqa: E402
from planner.library.refine import refine_library  # noqa: E402
from planner.library.refined import entry_commands  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.library.workers import WorkerPool  # noqa: E402
from planner.refine import RefineOptions  # noqa: E402

RESULTS = Path(__file__).parent / "results"


def truth_of(m: dict) -> dict:
    """The drawn machine's values under the calibration's parameter names."""
    out = dict(bulk_modulus=m["bulk_modulus"], spool_time_constant=m["spool_time_constant"],
               pump_time_constant=m["pump_time_constant"], command_delay=m.get("delay", 0.0))
    law = m.get("bulk_law") or {}
    out.update(bulk_low=law.get("lo", 1.0), bulk_high=law.get("hi", 1.0),
               bulk_reference_pressure=law.get("p_ref", 8e6))
    for k, j in m["joints"].items():
        out[f"hose_a.{k}"], out[f"hose_b.{k}"] = j["hose_volume"]
        for q in ("coulomb", "viscous", "leakage"):
            out[f"{q}.{k}"] = j[q]
        out[f"deadband.{k}"] = j["deadband"] if j["deadband"] is not None else 0.0
    return out


def machine_plant(crane, m: dict):
    """The Exudyn plant of drawn machine ``m``: bench_refine_robust's machine (its
    ``[dynamics]`` values, dead bands and pressure law) with its command ``delay`` — a
    transport delay between the command and the valves (bus, controller cycle) — and the
    extra spool lag ``lag`` [s] of its valve ``lag_joint``, which the twin's family (one spool
    time constant for every valve) lacks."""
    from planner.model.effects import make
    extra = [make("time_delay", delay=m["delay"])] if m.get("delay") else []
    if m.get("lag"):
        extra.append(make("valve_lag", joint=m["lag_joint"], tau=m["lag"]))
    return robust_plant(crane, m, extra)


def replay_task(path: str, entry_id: str, which: str, machine: dict, settle: float) -> dict:
    """One entry's ``which`` commands ("nominal" or "refined") on machine ``machine``."""
    from planner.simulation.dynamic.claims import replay_move
    t0 = time.process_time()
    crane = _crane(path)
    with LibraryStore.open(path, "r") as db:
        traj = db.trajectory(entry_id)
        t_u, u, used, _ = entry_commands(db, entry_id, traj, which)
    if used != which:
        return dict(id=entry_id, machine=machine["name"], commands=which, status="missing",
                    reason=f"no {which} commands", duration_s=float(traj.duration))
    m = replay_move(crane, traj, t_u=t_u, u=u, settle=settle, tol=TOL,
                    plant=machine_plant(crane, machine))
    e = m.exudyn
    return dict(id=entry_id, machine=machine["name"], commands=used, status=m.status,
                reason=m.reason, duration_s=float(traj.duration), library=Path(path).name,
                offset_m=e.get("offset_m"), peak_osc_m=e.get("peak_osc_m"),
                max_track_m=e.get("max_track_m"), cpu_s=time.process_time() - t0)


def calibrate_task(lib: str, work: str, m: dict, duration: float, iterations: int,
                   seed: int, excitation_csv: str | None, anchor: str = "twin") -> dict:
    """Log the excitation on machine ``m`` and calibrate the twin on it (runs in a worker)."""
    from planner.calibration.trials import excitation
    from planner.calibration.twin_fit import TwinFit
    from planner.calibration.twin_spec import calibrated_twin_text
    from planner.simulation.recording import Recording
    c0 = time.process_time()
    crane = _crane(lib)
    if excitation_csv:
        from planner.cli.common import read_trajectory
        from planner.feedforward import commands
        plan = read_trajectory(crane, excitation_csv)
        ff = commands(crane, plan, 50.0)
    else:
        plan, ff = excitation(crane, duration=duration, seed=seed)
    plant = machine_plant(crane, m)
    rec = plant.run(ff.t, ff.u, plan.q[0], t_end=float(ff.t[-1]), rate=50.0)
    if not rec.ok:
        return dict(machine=m["name"], status="log failed", reason=rec.reason)
    log = Recording(rec.t, rec.u, rec.q_true, rec.p_a_true, rec.p_b_true).with_noise(
        crane, True, seed=seed + 1)
    log_cpu = time.process_time() - c0
    fit = TwinFit(crane, [log], anchor=anchor)
    res = fit.solve(max_iterations=iterations)
    import pickle
    (Path(work) / f"cal-{m['name']}.pkl").write_bytes(pickle.dumps(res))   # kept first
    path = Path(work) / f"cal-{m['name']}.toml"
    atomic_write_text(path, calibrated_twin_text(crane, res, f"on the {m['name']} log"))
    return dict(machine=m["name"], status="ok", log_s=float(log.t[-1] - log.t[0]),
                log_cpu_s=log_cpu, fit=res.to_dict(), spec=str(path),
                cpu_s=time.process_time() - c0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--work", help="bench_refine_robust's work folder (required unless --merge "
                    "or --markdown) "
                    "(sel.h5, chain.json)")
    ap.add_argument("--robust", default=str(RESULTS / "refine_robust.json"))
    ap.add_argument("--machines", type=int, default=6)
    ap.add_argument("--entries", type=int, default=8)
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--excitation", metavar="CSV", help="a designed excitation instead")
    ap.add_argument("--iterations", type=int, default=12)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--delay-max", type=float, default=0.03,
                    help="each machine's command delay drawn from U(0, this) [s]")
    ap.add_argument("--lag-max", type=float, default=0.02,
                    help="one drawn valve's extra spool lag U(0, this) [s] (the effect the "
                    "twin lacks; 0: none)")
    ap.add_argument("--anchor", choices=("twin", "log"), default="twin",
                    help="TwinFit's segment anchors")
    ap.add_argument("--library", metavar="LIB.h5",
                    help="the entries (every ok one, refined on the spec's twin: e.g. a "
                    "bench_refine part's sel-*.h5) instead of WORK/sel.h5 and its chain")
    ap.add_argument("--calibrations", metavar="DIR",
                    help="the calibrated twins of an earlier run (DIR/cal-<machine>.json): "
                    "no new logs or fits")
    ap.add_argument("--only", metavar="M,M", help="these machines of the drawn ones")
    ap.add_argument("--merge", nargs="+", metavar="JSON",
                    help="one report from parts run on the same machines and calibrations")
    ap.add_argument("--markdown", metavar="JSON")
    ap.add_argument("--tag", default="calibrate_loop", help="result file name stem")
    ap.add_argument("--start", choices=("nominal", "refined"), default="nominal",
                    help="the calibrated twin's refinement starts from the nominal commands "
                         "or from the spec's twin's refinement (library refine --start)")
    ap.add_argument("--refine-iterations", type=int, default=150,
                    help="L-BFGS-B iterations of the calibrated twin's refinement (150)")
    a = ap.parse_args()
    if a.markdown:
        rep = json.loads(Path(a.markdown).read_text())
        atomic_write_text(RESULTS / f"{a.tag}.md", markdown(rep))
        return
    if a.merge:
        rep = merge([json.loads(Path(p).read_text()) for p in a.merge], a.merge)
        rep["figure"] = figure(rep, RESULTS / f"{a.tag}.png")
        atomic_write_text(RESULTS / f"{a.tag}.json", json.dumps(rep, indent=1, default=float))
        atomic_write_text(RESULTS / f"{a.tag}.md", markdown(rep))
        return
    if not a.work:
        ap.error("--work is required (unless --merge or --markdown)")
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    if a.library:
        sel = Path(a.library)
        with LibraryStore.open(sel, "r") as db:
            chain = [r["id"] for r in db.index_rows() if r["status"] == "ok"][:a.entries]
    else:
        sel = work / "sel.h5"
        chain = json.loads((work / "chain.json").read_text())[:a.entries]
    robust = json.loads(Path(a.robust).read_text())
    machines = [m for m in robust["machines"] if m["name"].startswith("m")][:a.machines]
    check = draw_machines(_crane(str(sel)).spec.dynamics, len(machines), robust["seed"],
                          robust["spread"])[2:]
    assert json.loads(json.dumps(check, default=float)) == machines, "machines differ"
    rng = np.random.default_rng(a.seed + 1000)
    names = _crane(str(sel)).names
    for m in machines:     # a command delay per machine (the same draws as before)
        m["delay"] = float(rng.uniform(0.0, a.delay_max))
    lag_rng = np.random.default_rng(a.seed + 2000)
    for m in machines:     # the effect the twin lacks: one valve slower than the others
        if a.lag_max > 0:
            m["lag_joint"] = str(names[int(lag_rng.integers(len(names)))])
            m["lag"] = float(lag_rng.uniform(0.0, a.lag_max))
    if a.only:
        keep = a.only.split(",")
        bad = sorted(set(keep) - {m["name"] for m in machines})
        if bad:
            sys.exit(f"--only: {bad[0]!r} is not one of the drawn machines")
        machines = [m for m in machines if m["name"] in keep]
    t0 = time.perf_counter()
    fits = {}
    done = {}
    cal_dir = Path(a.calibrations) if a.calibrations else work
    for m in machines:
        p = cal_dir / f"cal-{m['name']}.json"
        if p.exists():
            done[m["name"]] = json.loads(p.read_text())
            spec = cal_dir / f"cal-{m['name']}.toml"
            if done[m["name"]].get("spec") and not Path(done[m["name"]]["spec"]).exists() \
                    and spec.exists():       # calibrations kept elsewhere (a results folder)
                done[m["name"]]["spec"] = str(spec)
        elif a.calibrations:
            sys.exit(f"--calibrations {cal_dir}: no cal-{m['name']}.json")
    todo = [m for m in machines if m["name"] not in done]
    with WorkerPool(a.workers) as pool:
        for r in pool.imap_unordered(calibrate_task, [
                (str(sel), str(work), m, a.duration, a.iterations, a.seed, a.excitation,
                 a.anchor)
                for m in todo]):
            atomic_write_text(work / f"cal-{r['machine']}.json", json.dumps(r, default=float))
            done[r["machine"]] = r
            print(f"{r['machine']}: {r['status']} {r.get('cpu_s', 0):.0f} s", flush=True)
    fits = done
    cal_wall = time.perf_counter() - t0
    opts = RefineOptions(iterations=a.refine_iterations)
    refine = {}
    t1 = time.perf_counter()
    for m in machines:
        f = fits[m["name"]]
        if f["status"] != "ok":
            continue
        lib = work / f"cal-{m['name']}.h5"
        if not lib.exists():
            shutil.copyfile(sel, lib)
        refine[m["name"]] = refine_library(lib, model=f["spec"], workers=a.workers,
                                           limit=len(chain), options=opts,
                                           show_progress=False, start=a.start)
        refine[m["name"]]["cpu_s"] = _entry_cpu(lib, chain)
        print(f"refined on cal-{m['name']}: {refine[m['name']].get('refined')}", flush=True)
    refine_wall = time.perf_counter() - t1
    # every command kind on every machine: nominal and refined on the spec's twin (sel.h5),
    # refined on the calibrated twin (the machine's own copy)
    tasks = [(str(sel), i, w, m, robust["settle"]) for m in machines for i in chain
             for w in ("nominal", "refined")]
    tasks += [(str(work / f"cal-{m['name']}.h5"), i, "refined", m, robust["settle"])
              for m in machines if fits[m["name"]]["status"] == "ok" for i in chain]
    t2 = time.perf_counter()
    with WorkerPool(a.workers) as pool:
        rows = list(pool.imap_unordered(replay_task, tasks))
    for r in rows:
        if r["commands"] == "refined" and r.get("library", "").startswith("cal-"):
            r["commands"] = "calibrated"
    replay_wall = time.perf_counter() - t2
    old = []
    rep = dict(date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
               platform=platform.platform(), cpus=os.cpu_count(), load=os.getloadavg(),
               argv=" ".join(sys.argv[1:]), chain=chain, machines=machines,
               truth={m["name"]: truth_of(m) for m in machines}, fits=fits,
               refine=refine, rows=rows + old, settle=robust["settle"], tol=TOL,
               calibrate_wall_s=cal_wall, refine_wall_s=refine_wall, replay_wall_s=replay_wall,
               options=opts.__dict__, delay_max=a.delay_max, lag_max=a.lag_max,
               anchor=a.anchor, library=str(sel), calibrations=str(cal_dir),
               duration=a.duration, iterations=a.iterations, excitation=a.excitation,
               start=a.start)
    atomic_write_text(RESULTS / f"{a.tag}.json", json.dumps(rep, indent=1, default=float))
    atomic_write_text(RESULTS / f"{a.tag}.md", markdown(rep))


def _entry_cpu(lib, ids) -> list:
    """The refinement's CPU seconds of each of ``ids`` in library ``lib``."""
    from planner.library.refined import refined_info
    with LibraryStore.open(lib, "r") as db:
        return [float((refined_info(db, i) or {}).get("cpu_s", float("nan"))) for i in ids]


def merge(parts: list, names: list) -> dict:
    """One report from parts (each a run's JSON) on the same drawn machines and calibrated
    twins, with distinct entries per machine; refuses parts that differ."""
    first = parts[0]
    rep = dict(first, argv=" + ".join(p["argv"] for p in parts), parts=list(map(str, names)),
               rows=[], chain=[], refine={})
    fits, drawn = {}, {}
    for p, nm in zip(parts, names):
        for m, f in p["fits"].items():
            same = (json.dumps(f.get("fit"), sort_keys=True, default=float)
                    == json.dumps(fits.get(m, {}).get("fit"), sort_keys=True, default=float))
            if m in fits and not same:     # the fitted values, wherever the spec was kept
                sys.exit(f"--merge {nm}: machine {m} calibrated differently ({f.get('spec')})")
            fits.setdefault(m, f)
        for m in p["machines"]:     # parts may hold other machines (--only); one draw a name
            k = drawn.setdefault(m["name"], m)
            if json.dumps(k, sort_keys=True, default=float) != \
                    json.dumps(m, sort_keys=True, default=float):
                sys.exit(f"--merge {nm}: machine {m['name']} drawn otherwise than in an "
                         "earlier part")
        if p.get("lag_max") != first.get("lag_max") or \
                p.get("delay_max") != first.get("delay_max"):
            sys.exit(f"--merge {nm}: other drawn machines than {names[0]}")
        seen = {(r["machine"], r["id"], r["commands"]) for r in rep["rows"]}
        dup = [r for r in p["rows"] if (r["machine"], r["id"], r["commands"]) in seen]
        if dup:
            sys.exit(f"--merge {nm}: entry {dup[0]['id']} on {dup[0]['machine']} twice")
        rep["rows"] += p["rows"]
        rep["chain"] += [i for i in p["chain"] if i not in rep["chain"]]
        for m, r in p.get("refine", {}).items():
            rep["refine"].setdefault(m, []).append(r)
    rep["machines"] = [drawn[k] for k in sorted(drawn)]
    rep["truth"] = {k: v for p in parts for k, v in p["truth"].items()}
    rep["fits"] = fits
    rep["parts_libraries"] = [p.get("library", "") for p in parts]
    return rep


def figure(rep, path: Path) -> str:
    """Each machine's landed share and the rest offsets' distribution, by commands (a PNG
    at ``path``; its name for the markdown)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = [m["name"] for m in rep["machines"]]
    kinds = [("nominal", "nominal (quasi-static)", "0.6"), ("refined", "refined, spec's twin",
             "tab:orange"), ("calibrated", "refined, calibrated twin", "tab:blue")]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
    w = 0.27
    for k, (c, label, col) in enumerate(kinds):
        share = []
        for nm in names:
            rows = [r for r in rep["rows"] if r["commands"] == c and r["machine"] == nm]
            share.append(100 * sum(_landed(r) for r in rows) / max(len(rows), 1))
        ax.bar(np.arange(len(names)) + (k - 1) * w, share, w, label=label, color=col)
        v = np.sort([1e3 * r["offset_m"] for r in rep["rows"] if r["commands"] == c
                     and r.get("offset_m") is not None])
        if v.size:
            bx.step(v, np.arange(1, v.size + 1) / v.size, where="post", label=label, color=col)
    ax.axhline(90, color="k", lw=0.8, ls="--")
    ax.set_xticks(np.arange(len(names)), names)
    ax.set_ylabel("entries landed [%]")
    ax.set_title("Landed (rest ≤ 5 mm, ringing < 5 mm), judge: Exudyn")
    ax.legend(fontsize=8)
    bx.set_xscale("log")
    bx.axvline(5, color="k", lw=0.8, ls="--")
    bx.set_xlabel("rest offset on the drawn machine [mm]")
    bx.set_ylabel("share of entries")
    bx.set_title("Rest offset, every machine")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def _share(rows):
    ok = [r for r in rows if r.get("status") == "ok" or r.get("offset_m") is not None]
    n = sum(_landed(r) for r in ok)
    return f"{n} of {len(rows)} ({100 * n / max(len(rows), 1):.0f} %)"


def _med(rows, key):
    v = np.array([r[key] for r in rows if r.get(key) is not None], float) * 1e3
    return (f"{np.median(v):.1f} / {np.percentile(v, 90):.1f} / {v.max():.1f}" if v.size
            else "–")


def markdown(rep) -> str:
    names = [m["name"] for m in rep["machines"]]
    L = ["# The loop: twin calibrated from a log, feed-forward refined on it, landing on "
         "the machine (issue 28)", "",
         f"{rep['date']}, {rep['platform']}, {rep['cpus']} CPUs, load "
         f"{' '.join(f'{x:.1f}' for x in rep['load'])}. `python "
         f"benchmarks/bench_calibrate_loop.py {rep['argv']}`.", "",
         "Judge: **the Exudyn plant** (each drawn machine: its own circuit code, a bulk "
         "modulus that rises with pressure and a command delay — both in the calibrated "
         "family — and "
         + ("one valve whose spool lags behind the others, which the twin's family (one spool "
            "time constant) lacks" if rep.get("lag_max") else "nothing the family lacks")
         + "). The twin only fits the log and refines"
         + (f" (segments anchored on the {rep['anchor']})" if rep.get("anchor") else "")
         + ". Landing: "
         "rest offset ≤ 5 mm and ringing < 5 mm, valves closed "
         f"{rep['settle']:g} s after the last command. Entries: "
         + (', '.join(rep['chain']) if len(rep['chain']) <= 24 else
            f"{len(rep['chain'])} of {', '.join(sorted({Path(x).name for x in rep.get('parts_libraries', [rep.get('library', '')])}))} "
            "(ids in the JSON)") + ".",
         "", "Machines (drawn; the planner never saw them): "
         + "; ".join(f"{m['name']}: command delay {1e3 * m.get('delay', 0):.0f} ms, β(p) "
                     f"low {m['bulk_law']['lo']:.2f} at p_ref "
                     f"{m['bulk_law']['p_ref'] / 1e6:.1f} MPa"
                     + (f", the {m['lag_joint']} valve {1e3 * m['lag']:.0f} ms slower"
                        if m.get("lag") else "") for m in rep["machines"]) + ".",
         "", f"Calibration: one {rep['duration']:g} s excitation log per machine "
         f"({'`' + rep['excitation'] + '`' if rep.get('excitation') else 'trials.excitation'}"
         f", 50 Hz, seed 001's noise), every parameter, {rep['iterations']} least-squares "
         "iterations.", "",
         "## Landing on each machine", "",
         "| machine | commands | landed | rest offset median / p90 / max [mm] | ringing "
         "median / p90 / max [mm] |", "| --- | --- | ---: | --- | --- |"]
    label = dict(nominal="nominal (quasi-static)", refined="refined on the spec's twin",
                 calibrated="refined on the calibrated twin")
    for name in names + ["all"]:
        for c in ("nominal", "refined", "calibrated"):
            rows = [r for r in rep["rows"] if r["commands"] == c
                    and (name == "all" or r["machine"] == name)]
            if not rows:
                continue
            nm = "**all**" if name == "all" else name
            L.append(f"| {nm} | {label[c]} | {_share(rows)} | {_med(rows, 'offset_m')} | "
                     f"{_med(rows, 'peak_osc_m')} |")
    cal = [r for r in rep["rows"] if r["commands"] == "calibrated"]
    objectives = sorted({r["id"].rsplit(":", 1)[-1] for r in cal if ":" in r["id"]})
    if len(objectives) > 1:
        L += ["", "Refined on the calibrated twin, by the entries' objective (all machines):", "",
              "| objective | landed | rest offset median / p90 / max [mm] | ringing median / "
              "p90 / max [mm] |", "| --- | ---: | --- | --- |"]
        for o in objectives:
            rows = [r for r in cal if r["id"].endswith(":" + o)]
            L.append(f"| {o} | {_share(rows)} | {_med(rows, 'offset_m')} | "
                     f"{_med(rows, 'peak_osc_m')} |")
    cpu = [c for r in rep.get("refine", {}).values()
           for part in (r if isinstance(r, list) else [r]) for c in part.get("cpu_s", [])
           if c == c]
    if cpu:
        how = ("from the spec's twin's refinement (`library refine --start refined`)"
               if rep.get("start") == "refined" else "from the nominal commands")
        its = (rep.get("options") or {}).get("iterations")
        parts = [p for r in rep.get("refine", {}).values()
                 for p in (r if isinstance(r, list) else [r])]
        again = sum(p.get("restarted", 0) for p in parts)
        kept = sum(p.get("restart_taken", 0) for p in parts)
        restart = (f" {again} entries the calibrated twin predicted off (above "
                   f"{1e3 * rep['options'].get('fallback_above', 0):g} mm) were refined again "
                   f"from the nominal commands ({rep['options'].get('restart_iterations')} "
                   f"iterations), the better kept: {kept} times the restart." if again else "")
        L += ["", f"Refinement on the calibrated twins: {len(cpu)} entries, "
              + (f"{its} L-BFGS-B iterations at most, " if its else "") + f"started {how}; "
              f"CPU per entry median {np.median(cpu):.0f} s, p90 {np.percentile(cpu, 90):.0f} s."
              + restart]
    if rep.get("figure"):
        L += ["", f"![landing before and after calibration]({rep['figure']})"]
    L += ["", "## Calibrated parameters beside the truth", "",
          "Fitted value, its 95 % interval, and the drawn truth (× the spec's value where "
          "the spec has one). `n.i.`: not identified by the log.", ""]
    for name in names:
        f = rep["fits"][name]
        if f["status"] != "ok":
            L.append(f"- {name}: {f['status']} ({f.get('reason', '')})")
            continue
        fit = f["fit"]
        L += [f"### {name}", "",
              f"Log {f['log_s']:.0f} s; fit {fit['runtime_s']:.0f} s wall, {fit['twin_runs']} "
              f"twin runs, {fit['status']}; misfit (RMS, noise units) positions "
              f"{fit['rms_before']['positions']:.2f} → {fit['rms_after']['positions']:.2f}, "
              f"pressures {fit['rms_before']['pressures']:.2f} → "
              f"{fit['rms_after']['pressures']:.2f}.", "",
              "| parameter | spec | truth | fitted | 95 % interval | truth inside |",
              "| --- | ---: | ---: | ---: | --- | :---: |"]
        for k, p in fit["parameters"].items():
            t = rep["truth"][name][k]
            lo, hi = p["interval95"]
            L.append(f"| {k} | {p['nominal']:.4g} | {t:.4g} | {p['value']:.4g} | "
                     f"{lo:.4g} … {hi:.4g}{'' if p['identified'] else ' n.i.'} | "
                     f"{'yes' if lo <= t <= hi else 'no'} |")
        L.append("")
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    main()
