"""Feed-forward refined on the dynamic twin, judged on the independent Exudyn plant (issue 27).

A copy of the library is refined (``library refine``: the twin of the library's own spec),
then each selected entry is replayed open loop on Exudyn twice — its nominal commands and its
refined ones — with the valves closed ``settle`` s after the last command. Judge: the Exudyn
plant (its own circuit code; it never imports the twin's). Per entry: the tip error during
the move, the rest offset from the goal, the residual oscillation (the largest distance from
the rest point after the plan's end) and the lengthening; the refine cost per entry.

    python benchmarks/bench_refine.py --library LIB.h5 [--every K] [--workers N]
                                      [--iterations I] [--tag NAME] [--work DIR]

``--work DIR`` keeps the selection library and its refined commands there: ``library refine``
resumes, so a run that was stopped refines only what is missing when started again with the
same arguments. A run longer than a working session (the 400-entry library is about six CPU
hours) goes in parts whose results are kept: ``--order id --every 4 --offset 0 --tag
s100f-400-p0``, … ``--offset 3 … -p3`` (in the entries' id order, not the file's, which
follows the build's workers: each part then holds the same entries whichever build of the
library it runs on — the build is deterministic), then

    python benchmarks/bench_refine.py --merge refine_s100f-400-p0.json … --tag s100f-400

writes one report over the parts' entries (rows of a later part replace an earlier one's for
the same entry; every part must have refined each objective's entries with the same options —
those :func:`planner.refine.for_objective` gives it, an option a part's code lacked counting
at its default — and the same settle time). ``--amend FIX.json …`` adds parts that re-refine
the entries a new option acts on (``fallback_above``: a second, plain refinement where the
first is predicted off on the twin); the merge checks they cover every entry of the parts
above its threshold, their rows replace those, and the report counts how many first
refinements they reproduced.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from planner.io import atomic_write_text  # noqa: E402
from planner.library.dynamic import replay_library  # noqa: E402
from planner.library.refine import refine_library  # noqa: E402
from planner.library.refined import read_refined  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.refine import RefineOptions  # noqa: E402

TOL = 0.005   # [m] the landing tolerance: at rest within 5 mm, ringing under 5 mm


def _q(a, p):
    a = np.asarray([x for x in a if x is not None and np.isfinite(x)], float)
    return float(np.percentile(a, p)) if a.size else float("nan")


def _stats(rows, key):
    v = [r["exudyn"].get(key) for r in rows if r.get("status") == "ok"]
    return dict(median=_q(v, 50), p90=_q(v, 90), max=_q(v, 100))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--library")
    ap.add_argument("--merge", nargs="+", metavar="JSON",
                    help="merge these results files (parts of one run) into --tag")
    ap.add_argument("--amend", nargs="+", metavar="JSON",
                    help="with --merge: parts that re-refine the run's entries its twin "
                    "predicted off with an added fallback_above (their rows replace)")
    ap.add_argument("--every", type=int, default=1, help="every K-th ok entry (1: all)")
    ap.add_argument("--offset", type=int, default=0, help="starting at this ok entry (0)")
    ap.add_argument("--order", choices=("file", "id"), default="file",
                    help="the order --every and --offset count in: the file's (default) or "
                    "the entries' ids (parts of one run across library builds)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--iterations", type=int, default=RefineOptions().iterations)
    ap.add_argument("--settle", type=float, default=3.0)
    ap.add_argument("--tag", default="s100f")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    ap.add_argument("--work", help="keep the selection and its refinements here (resumable)")
    ap.add_argument("--energy-weight", type=float, default=0.0)
    ap.add_argument("--ids", help="these entries (ID,ID,…) instead of --every/--offset")
    ap.add_argument("--options", default="{}", metavar="JSON",
                    help="more refine options, e.g. '{\"keep_direction\": true}'")
    a = ap.parse_args()
    if a.merge:
        rep = merge([json.loads(Path(f).read_text()) for f in a.merge],
                    " ".join(sys.argv[1:]),
                    [json.loads(Path(f).read_text()) for f in (a.amend or ())])
        out = Path(a.out)
        atomic_write_text(out / f"refine_{a.tag}.json", json.dumps(rep, indent=1, default=str))
        atomic_write_text(out / f"refine_{a.tag}.md", markdown(rep))
        return
    if not a.library:
        ap.error("--library is required (unless --merge)")
    tmp = tempfile.TemporaryDirectory()
    with LibraryStore.open(a.library) as db:
        ok = [r["id"] for r in db.index_rows() if r["status"] == "ok"]
        crane_id = db.crane_id
    ids = (sorted(ok) if a.order == "id" else ok)[a.offset::a.every]
    if a.ids:
        ids = a.ids.split(",")
        missing = [i for i in ids if i not in ok]
        if missing:
            sys.exit(f"--ids: {missing[0]!r} is not an ok entry of {a.library}")
    # refine only the selected entries: a library holding just them
    work = Path(a.work) if a.work else Path(tmp.name)
    work.mkdir(parents=True, exist_ok=True)
    sel = work / f"sel-{a.tag}.h5"
    if sel.exists():
        with LibraryStore.open(sel) as db:
            have = [r["id"] for r in db.index_rows()]
        if have != ids:
            sys.exit(f"--work {work}: {sel.name} holds other entries than this selection; "
                     "use another --work or --tag")
    else:
        _select(Path(a.library), ids, sel)
    _refine_and_replay(a, ids, sel, crane_id, ok)
    tmp.cleanup()


def effective_options(options: dict, objective) -> dict:
    """The refine options an entry of ``objective`` gets from a part run with ``options``
    (:func:`planner.refine.for_objective`; an option the part's code did not have yet takes
    the value that means what that code did: its default, but ``energy_entries`` and
    ``time_entries`` "plain" and ``idle_reverse``, ``fallback_above`` and ``tube_weight`` 0)."""
    from dataclasses import asdict
    from planner.refine import for_objective
    known = dict(energy_entries="plain", time_entries="plain", idle_reverse=0.0,
                 fallback_above=0.0, tube_weight=0.0)
    known.update({k: v for k, v in options.items() if k in RefineOptions.__dataclass_fields__})
    o = asdict(for_objective(RefineOptions(**known), objective))
    if objective != "energy":   # how energy moves are refined does not touch the others
        o.pop("energy_entries")
    if objective != "time":     # nor how time moves are
        o.pop("time_entries")
    if not o["keep_direction"]:
        o.pop("idle_reverse")
    if not (o["keep_direction"] or o["keep_closed"] or o["energy_weight"] > 0):
        o.pop("fallback_above")   # acts only on a refinement that keeps or prices
    o.pop("restart_iterations")   # acts only on a given start, which these parts never take
    return o


#: options an ``--amend`` part may add to a run's: each acts only on an entry whose first
#: refinement the twin predicts above a threshold, so the amend part re-refines exactly those
AMEND_FIELDS = ("fallback_above",)


def _score(info) -> float:
    """How far an entry's refinement is predicted from landed (inf: no prediction)."""
    from planner.refine.measures import score
    p = ((info or {}).get("predicted") or {}).get("refined")
    return score(p) if p else np.inf


def _amend(rep_used: dict, parts: list, amend: list) -> dict:
    """Check the ``amend`` parts against the run's ``parts`` (module doc): the options differ
    only in :data:`AMEND_FIELDS`, and every entry of the parts whose twin prediction lies
    above the amend's ``fallback_above`` is re-refined in it. Returns {objective: options}."""
    out, ids = {}, {r["id"] for a in amend for r in a["runs"]["nominal"]["rows"]}
    for a in amend:
        for r in a["runs"]["nominal"]["rows"]:
            ob = r.get("objective")
            o = effective_options(a["options"], ob)
            if ob not in rep_used:
                raise ValueError(f"--amend: entry '{r['id']}' is a {ob} entry; the run has none")
            diff = {k for k in set(o) | set(rep_used[ob][0])
                    if o.get(k) != rep_used[ob][0].get(k)}
            if not diff <= set(AMEND_FIELDS) or out.setdefault(ob, o) != o:
                raise ValueError(f"--amend: the run '{a['argv']}' differs from the parts in "
                                 f"{sorted(diff)}; allowed: only {', '.join(AMEND_FIELDS)}")
    for ob, o in out.items():
        thr = o.get("fallback_above", 0.0)
        for p in parts:
            for r in p["runs"]["nominal"]["rows"]:
                if r.get("objective") == ob and r["id"] not in ids and \
                        _score(p["infos"].get(r["id"])) > thr:
                    raise ValueError(f"--amend: entry '{r['id']}' of '{p['argv']}' is predicted "
                                     f"{1e3 * _score(p['infos'].get(r['id'])):.1f} mm from "
                                     f"landed, above fallback_above = {1e3 * thr:g} mm, and "
                                     "not re-refined in the amend parts; allowed: amend parts "
                                     "that cover every such entry")
    return out


def _same_first(part: dict, firsts: dict) -> int:
    """How many of an amend part's entries predicted their first (kept, priced) refinement
    as the run's parts did (the refinement is deterministic: all of them)."""
    same = 0
    for k, v in part["infos"].items():
        fb = (v.get("predicted") or {}).get("fallback") or {}
        first = _score(dict(predicted=dict(refined=fb.get("first")))) if fb else _score(v)
        same += abs(first - firsts.get(k, np.nan)) < 1e-9
    return same


def merge(parts: list, argv: str, amend: list = ()) -> dict:
    """One report over ``parts`` (results of this bench on one library, same options and
    settle time): their entries' rows and refinements, a later part's replacing an earlier
    one's; the refine summary summed (wall time: the parts' sum). ``amend``: parts whose
    options add one of :data:`AMEND_FIELDS` (a second refinement where the first is predicted
    not to land) and that re-refine every entry it acts on (:func:`_amend` checks); their
    rows replace the parts'."""
    if not parts:
        raise ValueError("--merge: no results file given")
    base = parts[0]
    used = {}
    for p in parts:   # the options each objective's entries were refined with
        for r in p["runs"]["nominal"]["rows"]:
            o = effective_options(p["options"], r.get("objective"))
            if used.setdefault(r.get("objective"), (o, p["argv"]))[0] != o:
                raise ValueError(f"--merge: the {r.get('objective')} entries of the run "
                                 f"'{p['argv']}' were refined with other options than those of "
                                 f"'{used[r.get('objective')][1]}'; allowed: parts of one run")
    for k in ("crane", "settle", "library_entries"):
        bad = [p.get("argv") for p in parts if p.get(k) != base.get(k)]
        if bad:
            raise ValueError(f"--merge: field '{k}' differs between the parts (e.g. the run "
                             f"'{bad[0]}'); allowed: parts of one run")
    amended = _amend(used, parts, list(amend)) if amend else {}
    firsts = {}
    for p in parts:
        firsts.update({k: _score(v) for k, v in p["infos"].items()})
    runs = {w: {} for w in ("nominal", "refined")}
    infos, refine = {}, dict(refined=0, wall_s=0.0, workers=base["refine"].get("workers"))
    for p in list(parts) + list(amend):
        for w in runs:
            runs[w].update({r["id"]: r for r in p["runs"][w]["rows"]})
        infos.update(p["infos"])
        refine["refined"] += int(p["refine"].get("refined", 0))
        refine["wall_s"] += float(p["refine"].get("wall_s", 0.0))
    rep = dict(base, argv=argv, selected=len(runs["nominal"]), every=1, offset=0, infos=infos,
               options_by_objective=dict({k: v[0] for k, v in used.items()}, **amended),
               refine=refine, parts=[dict(argv=p["argv"], date=p["date"],
                                          selected=p["selected"]) for p in parts],
               amend=[dict(argv=p["argv"], date=p["date"], selected=p["selected"],
                           ids=sorted(p["infos"]), first_pass_same=_same_first(p, firsts))
                      for p in amend],
               runs={w: dict(rows=sorted(v.values(), key=lambda r: r["id"]),
                             seconds=sum(p["runs"][w].get("seconds", 0.0) for p in parts))
                     for w, v in runs.items()})
    return rep


def copy_entry(src, dst, entry_id: str):
    """Add the ok entry ``entry_id`` of the open library ``src`` to the writable ``dst``
    (its plan, start, goal, objective, method and build attributes; not its refinement)."""
    r = next(x for x in src.index_rows() if x["id"] == entry_id)
    at = src.entry_attrs(entry_id)
    dst.add(entry_id, src.trajectory(entry_id), start=r["start"], goal=r["goal"],
            objective=r["objective"], method=r["method"], status="ok",
            attrs={k: v for k, v in at.items() if k in ("suite", "solve_s", "clearance_m")})


def _select(library: Path, ids, sel: Path):
    part = sel.with_name(sel.name + ".part")
    with LibraryStore.open(library) as src, LibraryStore.create(part, _spec(src)) as dst:
        for i in ids:
            copy_entry(src, dst, i)
    os.replace(part, sel)


def _refine_and_replay(a, ids, sel, crane_id, ok):
    opts = RefineOptions(**dict(dict(iterations=a.iterations, energy_weight=a.energy_weight),
                                **json.loads(a.options)))
    t0 = time.perf_counter()
    summary = refine_library(sel, workers=a.workers, options=opts, show_progress=False)
    refine_wall = time.perf_counter() - t0
    print(f"refined {summary['refined']} in {refine_wall:.0f} s", flush=True)
    infos = {}
    with LibraryStore.open(sel) as db:
        for i in ids:
            r = read_refined(db, i)
            infos[i] = r[2] if r else None
    runs = {}
    for which in ("nominal", "refined"):
        t1 = time.perf_counter()
        res = replay_library(sel, workers=a.workers, settle=a.settle, tol=TOL, commands=which,
                             ids=ids)
        runs[which] = dict(rows=sorted(res["rows"], key=lambda r: r["id"]),
                           seconds=time.perf_counter() - t1)
        print(which, f"{runs[which]['seconds']:.0f} s", flush=True)
    rep = dict(date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
               platform=platform.platform(), cpus=os.cpu_count(), load=os.getloadavg(),
               argv=" ".join(sys.argv[1:]), crane=crane_id, library_entries=len(ok),
               selected=len(ids), every=a.every, offset=a.offset, order=a.order,
               options=opts.__dict__, settle=a.settle,
               refine=dict(summary, wall_s=refine_wall, workers=a.workers), infos=infos, runs=runs)
    out = Path(a.out)
    atomic_write_text(out / f"refine_{a.tag}.json", json.dumps(rep, indent=1, default=str))
    atomic_write_text(out / f"refine_{a.tag}.md", markdown(rep))


def _spec(store):
    import tomllib

    from planner.model.spec import parse_spec
    return parse_spec(tomllib.loads(store.spec_toml), "<library spec>", store.spec_toml)


def _objectives(rep) -> str:
    c = {}
    for r in rep["runs"]["nominal"]["rows"]:
        c[r.get("objective")] = c.get(r.get("objective"), 0) + 1
    return ", ".join(f"{k} {v}" for k, v in sorted(c.items(), key=str))


def landed(r) -> bool:
    e = r.get("exudyn") or {}
    return (r.get("status") == "ok" and e.get("offset_m", 1) <= TOL
            and e.get("peak_osc_m", 1) < TOL)


def land_time_ratios(rows) -> list:
    """Per replayed entry: (planned duration + the time after it until the tip stays within
    5 mm of the goal) / planned duration — the move's duration as the crane lands it on
    Exudyn (inf: it never does within the recording)."""
    out = []
    for r in rows:
        e = r.get("exudyn") or {}
        if r.get("status") == "ok" and r.get("duration_s") and "settle_goal_s" in e:
            out.append((r["duration_s"] + e["settle_goal_s"]) / r["duration_s"])
    return out


def _clearance_line(rep) -> str:
    """The tip's least distance to the suite's obstacles (the headboard) on Exudyn, nominal
    and refined, beside the plans' (rows without obstacles: nothing to say)."""
    got = {w: [(r.get("exudyn") or {}).get("clearance_m") for r in rep["runs"][w]["rows"]]
           for w in ("nominal", "refined")}
    got = {w: [v for v in vs if v is not None] for w, vs in got.items()}
    plan = [r.get("plan_clearance_m") for r in rep["runs"]["refined"]["rows"]
            if r.get("plan_clearance_m") is not None]
    if not got["refined"]:
        return "Headboard clearance: not measured (no obstacles in these entries' suites)."
    return ("Headboard clearance, the tip's least distance over the replay (Exudyn): refined "
            f"min {_q(got['refined'], 0):.3f} m, median {_q(got['refined'], 50):.3f} m; "
            f"nominal min {_q(got['nominal'], 0):.3f} m"
            + (f"; the plans min {min(plan):.3f} m." if plan else "."))


def _land_line(rep) -> str:
    parts = []
    for which in ("nominal", "refined"):
        x = np.asarray(land_time_ratios(rep["runs"][which]["rows"]), float)
        if not x.size:
            continue
        def pc(p):   # a quantile that stays on a sample (inf: not landed)
            v = float(np.percentile(x, p, method="higher"))
            return f"{100 * (v - 1):+.1f} %" if np.isfinite(v) else "not landed"
        parts.append(f"{which}: median {pc(50)}, p90 {pc(90)}, within +5 % "
                     f"{int((x <= 1.05).sum())} of {x.size}")
    return ("Time to land (Exudyn: the plan's duration plus the time after it until the tip "
            "stays within 5 mm of the goal), against the planned duration — "
            + ("; ".join(parts) if parts else "–") + ".")


def _options_text(rep) -> str:
    by = rep.get("options_by_objective")
    if not by:
        return f"options {rep['options']}"
    first, *rest = sorted(by)
    out = f"options of the {first} entries {by[first]}"
    for o in rest:
        diff = {k: v for k, v in by[o].items() if by[first].get(k) != v}
        out += f"; the {o} entries differ in {diff}"
    return out


def markdown(rep) -> str:
    L = [f"# Feed-forward refined on the twin, judged on Exudyn: {rep['crane']} (issue 27)", "",
         f"{rep['date']}, {rep['platform']}, {rep['cpus']} CPUs, load "
         f"{rep['load'][0]:.1f} {rep['load'][1]:.1f} {rep['load'][2]:.1f}. "
         f"`python benchmarks/bench_refine.py {rep['argv']}`.", "",
         f"Entries: {rep['selected']} of the library's {rep['library_entries']} ok entries "
         + (f"(the parts {'; '.join('`' + p['argv'] + '`' for p in rep['parts'])}; "
            if rep.get("parts") else
            f"(every {rep['every']}-th from entry {rep.get('offset', 0)}, in the "
            + ("entries' ids" if rep.get("order") == "id" else "file's") + " order; ")
         + f"objectives {_objectives(rep)}"
         + "".join(f"; amended by `{a['argv']}`: {len(a['ids'])} entries re-refined, "
                   f"{a['first_pass_same']} of them with the parts' first refinement "
                   "reproduced" for a in rep.get("amend") or ())
         + "). Refined by `library refine` on the "
         f"twin of the library's own spec ({_options_text(rep)}); each entry replayed "
         f"open loop on the **Exudyn plant** (the judge; same spec parameters) with its "
         f"nominal and its refined commands, valves closed {rep['settle']:g} s after the last "
         "command.", "",
         "| commands | landed (rest ≤ 5 mm and ringing < 5 mm) | rest offset median / p90 / max "
         "[mm] | ringing median / p90 / max [mm] | tip error during the move median / p90 / "
         "max [mm] |", "| --- | ---: | --- | --- | --- |"]
    objectives = sorted({str(r.get("objective")) for r in rep["runs"]["nominal"]["rows"]})
    groups = [(w, w, None) for w in ("nominal", "refined")]
    if len(objectives) > 1:
        groups += [(w, f"{w}, {o} entries", o) for w in ("nominal", "refined")
                   for o in objectives]
    for which, label, objective in groups:
        rows = [r for r in rep["runs"][which]["rows"]
                if objective is None or str(r.get("objective")) == objective]
        n_ok = sum(landed(r) for r in rows)
        cells = []
        for k in ("offset_m", "peak_osc_m", "max_track_m"):
            s = _stats(rows, k)
            cells.append(f"{1e3 * s['median']:.1f} / {1e3 * s['p90']:.1f} / "
                         f"{1e3 * s['max']:.1f}")
        L.append(f"| {label} | {n_ok} of {len(rows)} ({100 * n_ok / max(len(rows), 1):.0f} %) "
                 f"| {' | '.join(cells)} |")
    infos = [i for i in rep["infos"].values() if i]
    cpu = [i.get("cpu_s") for i in infos]
    ln = [i.get("lengthened_s") for i in infos]
    dur = {r["id"]: r.get("duration_s") for r in rep["runs"]["nominal"]["rows"]}
    rel = [i_["lengthened_s"] / dur[k] for k, i_ in rep["infos"].items()
           if i_ and dur.get(k)]
    pred = [i["predicted"]["refined"] for i in infos]
    st = {}
    for i in infos:
        st[i["status"]] = st.get(i["status"], 0) + 1
    L += ["", f"Refine: {rep['refine']['refined']} entries in {rep['refine']['wall_s']:.0f} s "
          f"wall on {rep['refine'].get('workers')} worker processes; CPU per entry median "
          f"{_q(cpu, 50):.1f} s, p90 {_q(cpu, 90):.1f} s; statuses {st}.",
          f"Lengthening past the plan's end (the commands act up to the tail): median "
          f"{_q(ln, 50):.2f} s, p90 {_q(ln, 90):.2f} s, max {_q(ln, 100):.2f} s; as a share of "
          f"the move: median {100 * _q(rel, 50):.1f} %, p90 {100 * _q(rel, 90):.1f} %.",
          _land_line(rep),
          f"The twin's own prediction for the refined commands: rest offset median "
          f"{1e3 * _q([p['rest_offset_m'] for p in pred], 50):.1f} mm, ringing median "
          f"{1e3 * _q([p['residual_oscillation_m'] for p in pred], 50):.1f} mm, tip error "
          f"during the move median {1e3 * _q([p['track_m'] for p in pred], 50):.1f} mm.",
          _clearance_line(rep), "",
          "Per entry (Exudyn; nominal → refined) [mm]:", "",
          "| entry | s | rest | ringing | during the move | lengthened s |",
          "| --- | ---: | --- | --- | --- | ---: |"]
    nom = {r["id"]: r for r in rep["runs"]["nominal"]["rows"]}
    for r in rep["runs"]["refined"]["rows"]:
        n = nom.get(r["id"], {})
        e, en = r.get("exudyn") or {}, n.get("exudyn") or {}

        def mm(d, k):
            v = d.get(k)
            return "–" if v is None else f"{1e3 * v:.1f}"
        info = rep["infos"].get(r["id"]) or {}
        L.append(f"| {r['id']} | {r.get('duration_s', float('nan')):.1f} | {mm(en, 'offset_m')} → "
                 f"{mm(e, 'offset_m')} | {mm(en, 'peak_osc_m')} → {mm(e, 'peak_osc_m')} | "
                 f"{mm(en, 'max_track_m')} → {mm(e, 'max_track_m')} | "
                 f"{info.get('lengthened_s', float('nan')):.2f} |")
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    main()
