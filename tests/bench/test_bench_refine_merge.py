"""``bench_refine.py --merge``: a run too long for one working session (the 400-entry
library refine) goes in parts whose results are kept, merged into one report."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import bench_refine  # noqa: E402


def _row(i, offset, osc=0.001):
    return dict(id=i, status="ok", objective="time", duration_s=8.0,
                exudyn=dict(offset_m=offset, peak_osc_m=osc, max_track_m=0.01,
                            settle_goal_s=0.1))


def _part(argv, rows, options=None, refined=2, wall=100.0):
    info = dict(status="improved", cpu_s=50.0, lengthened_s=0.5,
                predicted=dict(refined=dict(rest_offset_m=1e-4, residual_oscillation_m=1e-4,
                                            track_m=0.01)))
    return dict(date="2026-11-27 09:00 UTC", platform="x", cpus=2, load=[1.0, 1.0, 1.0],
                argv=argv, crane="s100f", library_entries=400, selected=len(rows), every=4,
                offset=0, order="id", options=options or dict(iterations=150), settle=3.0,
                refine=dict(refined=refined, wall_s=wall, workers=2),
                infos={r["id"]: info for r in rows},
                runs={w: dict(rows=rows, seconds=10.0) for w in ("nominal", "refined")})


def test_parts_merge_into_one_report_a_later_row_replacing_an_earlier_one():
    a = _part("--offset 0", [_row("a", 0.002), _row("b", 0.009)])
    b = _part("--offset 1", [_row("b", 0.001), _row("c", 0.003)], wall=50.0)
    rep = bench_refine.merge([a, b], "--merge a b")
    rows = rep["runs"]["refined"]["rows"]
    assert [r["id"] for r in rows] == ["a", "b", "c"]
    assert rows[1]["exudyn"]["offset_m"] == 0.001          # the later part's
    assert rep["selected"] == 3 and rep["refine"]["wall_s"] == 150.0
    md = bench_refine.markdown(rep)
    assert "| refined | 3 of 3 (100 %)" in md
    assert "`--offset 0`; `--offset 1`" in md


def test_parts_of_different_runs_are_refused_by_objective():
    a = _part("--offset 0", [_row("a", 0.002)])
    b = _part("--offset 1 --iterations 80", [_row("c", 0.003)], options=dict(iterations=80))
    with pytest.raises(ValueError, match="time entries of the run '--offset 1 --iterations 80'"):
        bench_refine.merge([a, b], "--merge a b")


def _energy(row):
    return dict(row, objective="energy")


def test_options_that_only_touch_energy_entries_may_differ_between_time_parts():
    # a part run before an option existed counts it at its default (what its code did)
    old = _part("--offset 1", [_row("a:time", 0.002)], options=dict(iterations=150))
    new = _part("--offset 3", [_row("b:time", 0.001)],
                options=dict(iterations=150, energy_entries="plain", idle_reverse=0.05))
    rep = bench_refine.merge([old, new], "--merge")
    assert rep["options_by_objective"]["time"]["keep_direction"] is False
    # energy entries refined one way and another are not one run
    e1 = _part("--offset 0", [_energy(_row("a:energy", 0.002))],
               options=dict(iterations=150, energy_entries="priced"))
    e2 = _part("--offset 2", [_energy(_row("b:energy", 0.002))],
               options=dict(iterations=150, energy_entries="priced", idle_reverse=0.05))
    with pytest.raises(ValueError, match="energy entries of the run '--offset 2'"):
        bench_refine.merge([old, e1, e2], "--merge")
    rep = bench_refine.merge([old, e1, new], "--merge")
    assert rep["options_by_objective"]["energy"]["keep_direction"] is True
    md = bench_refine.markdown(rep)   # one row per objective beside the whole
    assert "| refined, energy entries | 1 of 1 (100 %)" in md
    assert "| refined, time entries | 2 of 2 (100 %)" in md
    assert ("the time entries differ in {'energy_weight': 0.0, 'keep_direction': False, "
            "'time_entries': 'plain'}") in md
    # a part from before energy entries were priced refined them plain
    e0 = _part("--offset 4", [_energy(_row("c:energy", 0.002))], options=dict(iterations=150))
    with pytest.raises(ValueError, match="energy entries of the run '--offset 4'"):
        bench_refine.merge([e1, e0], "--merge")


def _with_prediction(part, entry, rest):
    part["infos"][entry] = dict(part["infos"][entry], predicted=dict(refined=dict(
        rest_offset_m=rest, residual_oscillation_m=1e-4, track_m=0.01)))
    return part


def test_an_amend_part_must_re_refine_every_entry_its_option_acts_on():
    opts = dict(iterations=150, energy_entries="priced")
    run = _part("--offset 0", [_energy(_row("a:energy", 0.027)), _energy(_row("b:energy", 0.001)),
                               _energy(_row("c:energy", 0.006))], options=opts)
    run = _with_prediction(_with_prediction(run, "a:energy", 0.027), "c:energy", 0.006)
    t = _part("--offset 1", [_row("a:time", 0.001)], options=dict(iterations=150))
    fix_opts = dict(opts, fallback_above=0.004)
    fix = _part("--ids a:energy", [_energy(_row("a:energy", 0.001))], options=fix_opts)
    fix["infos"]["a:energy"] = dict(fix["infos"]["a:energy"], predicted=dict(
        refined=dict(rest_offset_m=1e-3, residual_oscillation_m=1e-4, track_m=0.01),
        fallback=dict(taken=True, first=dict(rest_offset_m=0.027, residual_oscillation_m=1e-4))))
    # c is predicted 6 mm off too and the fix leaves it out
    with pytest.raises(ValueError, match="entry 'c:energy' of '--offset 0' is predicted 6.0 mm"):
        bench_refine.merge([run, t], "--merge", [fix])
    fix["runs"] = {w: dict(rows=[_energy(_row("a:energy", 0.001)),
                                 _energy(_row("c:energy", 0.002))], seconds=1.0)
                   for w in ("nominal", "refined")}
    fix["infos"]["c:energy"] = dict(fix["infos"]["a:energy"], predicted=dict(
        refined=dict(rest_offset_m=0.006, residual_oscillation_m=1e-4, track_m=0.01)))
    rep = bench_refine.merge([run, t], "--merge", [fix])
    rows = {r["id"]: r for r in rep["runs"]["refined"]["rows"]}
    assert rows["a:energy"]["exudyn"]["offset_m"] == 0.001        # the amend's row
    assert rep["options_by_objective"]["energy"]["fallback_above"] == 0.004
    assert "fallback_above" not in rep["options_by_objective"]["time"]
    assert rep["amend"][0]["first_pass_same"] == 2
    assert "2 entries re-refined, 2 of them with the parts' first refinement" in \
        bench_refine.markdown(rep)
    # an amend part may not change anything else
    bad = _part("--ids a:energy --iterations 80", [_energy(_row("a:energy", 0.001))],
                options=dict(fix_opts, iterations=80))
    with pytest.raises(ValueError, match=r"differs from the parts in .*'iterations'"):
        bench_refine.merge([run, t], "--merge", [bad])
