"""``bench_calibrate_loop.py --merge``: the loop on ≥ 100 entries per drawn machine goes in
parts (each a bench_refine part's library, the calibrated twins of one run), merged into one
report; parts that disagree on the machines or their calibration, or repeat an entry, are
refused."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import bench_calibrate_loop as loop  # noqa: E402


def _machine(name, delay=0.01):
    return dict(name=name, delay=delay, bulk_law=dict(lo=0.6, p_ref=8e6, hi=1.25))


def _row(i, machine, commands, offset, osc=0.001):
    return dict(id=i, machine=machine, commands=commands, status="ok", offset_m=offset,
                peak_osc_m=osc)


def _part(argv, ids, offsets, spec="/w/cal-m1.toml", delay=0.01, lib="sel-p0.h5",
          params=None, machine="m1"):
    rows = [_row(i, machine, c, o) for i, o in zip(ids, offsets)
            for c in ("nominal", "refined", "calibrated")]
    fit = dict(status="ok", spec=spec, log_s=120.0, fit=dict(
        runtime_s=10.0, twin_runs=5, status="done", parameters=params or {},
        rms_before=dict(positions=9.0, pressures=9.0),
        rms_after=dict(positions=1.0, pressures=1.0)))
    return dict(date="2026-11-27 21:00 UTC", platform="x", cpus=2, load=[1.0, 1.0, 1.0],
                argv=argv, chain=list(ids), machines=[_machine(machine, delay)],
                truth={machine: {}}, fits={machine: fit},
                refine={machine: dict(cpu_s=[30.0 + 10 * k for k in range(len(ids))])},
                rows=rows, settle=3.0, lag_max=0.02, anchor="twin", duration=120.0,
                iterations=12, excitation=None, library=lib)


def test_parts_merge_into_one_report_with_a_row_per_objective():
    a = _part("--library p0", ["a:time", "b:energy"], [0.002, 0.009])
    b = _part("--library p4", ["c:time"], [0.001], lib="sel-p4.h5")
    rep = loop.merge([a, b], ["a.json", "b.json"])
    cal = [r for r in rep["rows"] if r["commands"] == "calibrated"]
    assert sorted(r["id"] for r in cal) == ["a:time", "b:energy", "c:time"]
    md = loop.markdown(rep)
    assert "| m1 | refined on the calibrated twin | 2 of 3 (67 %)" in md
    assert "| time | 2 of 2 (100 %)" in md and "| energy | 0 of 1 (0 %)" in md
    assert "3 entries, started from the nominal commands; CPU per entry median 30 s" in md


def test_parts_with_another_calibration_or_a_repeated_entry_are_refused():
    a = _part("--library p0", ["a:time"], [0.002])
    with pytest.raises(SystemExit, match="calibrated differently"):
        loop.merge([a, _part("x", ["c:time"], [0.001], params=dict(bulk_modulus=1.2e9))],
                   ["a", "b"])
    # the same fit, its spec kept elsewhere (a results folder, another session): one machine
    rep = loop.merge([a, _part("x", ["c:time"], [0.001], spec="/v/cal-m1.toml")], ["a", "b"])
    assert sorted(rep["chain"]) == ["a:time", "c:time"]
    with pytest.raises(SystemExit, match="machine m1 drawn otherwise"):
        loop.merge([a, _part("x", ["c:time"], [0.001], delay=0.02)], ["a", "b"])
    with pytest.raises(SystemExit, match="entry a:time on m1 twice"):
        loop.merge([a, _part("x", ["a:time"], [0.001])], ["a", "b"])


def test_parts_on_other_machines_merge_and_a_machine_drawn_twice_otherwise_is_refused():
    """The 100-entry loop runs one machine per part (``--only mN``): each part's machine list
    holds only its own machine, and the merged report holds all of them."""
    a = _part("--only m1", ["a:time"], [0.002])
    b = _part("--only m2", ["a:time"], [0.001], spec="/w/cal-m2.toml", delay=0.02,
              machine="m2")
    rep = loop.merge([a, b], ["a", "b"])
    assert [m["name"] for m in rep["machines"]] == ["m1", "m2"]
    assert sorted(rep["fits"]) == ["m1", "m2"]
    assert len([r for r in rep["rows"] if r["commands"] == "calibrated"]) == 2
    c = _part("--only m2", ["b:time"], [0.001], spec="/w/cal-m2.toml", delay=0.03,
              machine="m2")
    with pytest.raises(SystemExit, match="machine m2 drawn otherwise"):
        loop.merge([a, b, c], ["a", "b", "c"])
