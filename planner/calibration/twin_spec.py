"""The calibrated twin as a file: the crane spec's own TOML with its ``[dynamics]`` section
rewritten to the fitted values and each valve's ``deadband`` set to its fitted value (what
``crane-planner calibrate --out`` writes). Every line that changed says so in a comment: the
fitted value's 95 % interval, or "spec's value, not fitted". The rest of the file (bodies,
limits, pump, comments) is the spec's text unchanged, so ``library refine --model FILE`` and
every other command read it as the same machine with the calibrated oil, hoses, valves,
friction and leakage.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import json
import re

if TYPE_CHECKING:
    from planner.calibration.twin_fit import TwinFitResult
    from planner.model import Crane

__all__ = ["calibrated_twin_text"]

_HEADER = re.compile(r"^\s*\[\[?\s*([A-Za-z0-9_.\"-]+)\s*\]\]?")


def _comment(res: TwinFitResult, name: str, unit: str) -> str:
    if name not in res.values:
        return "# spec's value, not fitted"
    lo, hi = res.interval[name]
    flag = "" if res.identified[name] else "; not identified by the logs"
    return (f"# calibrated (spec's {res.nominal[name]:.4g}); 95 % interval "
            f"{lo:.4g} … {hi:.4g} {_unit(res.units.get(name, unit))}{flag}".rstrip())


def _unit(u: str) -> str:
    return "" if u == "1" else u      # a share: no unit written


def calibrated_twin_text(crane: Crane, res: TwinFitResult, source: str = "") -> str:
    """The spec's TOML with the calibrated ``[dynamics]`` and dead bands (module doc)."""
    spec = crane.spec
    if not spec.text:
        raise ValueError(f"crane '{spec.id}': the spec's TOML text is not available")
    dyn, db = res.dynamics, res.deadband
    out, skip, joint_k, in_actuator, set_db = [], False, -1, False, False

    def close_actuator():
        # a [joint.actuator] table that had no deadband line gets one at its end
        if in_actuator and not set_db:
            j = spec.joints[joint_k]
            while out and not out[-1].strip():
                out.pop()
            out.append(f"deadband = {float(db[joint_k])!r}  "
                       + _comment(res, f"deadband.{j.name}", ""))
            out.append("")
    for line in spec.text.splitlines():
        m = _HEADER.match(line)
        if m:
            close_actuator()
            in_actuator, set_db = False, False
            name = m.group(1)
            skip = name == "dynamics" or name.startswith("dynamics.joint")
            if line.lstrip().startswith("[[") and name == "joint":
                joint_k += 1
            if name == "joint.actuator":
                in_actuator = True
        if skip:
            continue
        if in_actuator and re.match(r"^\s*deadband\s*=", line):
            j = spec.joints[joint_k]
            out.append(f"deadband = {float(db[joint_k])!r}  "
                       + _comment(res, f"deadband.{j.name}", ""))
            set_db = True
            continue
        out.append(line)
    close_actuator()
    while out and not out[-1].strip():
        out.pop()
    src = f"calibrated by crane-planner calibrate {source}".strip()
    lines = ["", f"# [dynamics] {src}: fitted values with their 95 % intervals; the others are "
                 "the spec's",
             "[dynamics]",
             f"bulk_modulus = {dyn.bulk_modulus!r}  " + _comment(res, "bulk_modulus", "Pa"),
             f"spool_time_constant = {dyn.spool_time_constant!r}  "
             + _comment(res, "spool_time_constant", "s"),
             f"pump_time_constant = {dyn.pump_time_constant!r}  "
             + _comment(res, "pump_time_constant", "s"),
             f"bulk_low = {dyn.bulk_low!r}  " + _comment(res, "bulk_low", ""),
             f"bulk_high = {dyn.bulk_high!r}  " + _comment(res, "bulk_high", ""),
             f"bulk_reference_pressure = {dyn.bulk_reference_pressure!r}  "
             + _comment(res, "bulk_reference_pressure", "Pa"),
             f"command_delay = {dyn.command_delay!r}  " + _comment(res, "command_delay", "s"),
             f"pump_line_volume = {dyn.pump_line_volume!r}  # spec's value, not fitted",
             f"compensator_dp = {dyn.compensator_dp!r}  # spec's value, not fitted",
             f"meter_out_dp = {dyn.meter_out_dp!r}  # spec's value, not fitted",
             f"meter_out_margin = {dyn.meter_out_margin!r}  # spec's value, not fitted",
             f"source = {json.dumps(src, ensure_ascii=False)}"]
    for j in spec.joints:
        jd = dyn.joints[j.name]
        n = j.name
        lines += ["", f"[dynamics.joint.{n}]",
                  f"hose_volume = [{jd.hose_volume[0]!r}, {jd.hose_volume[1]!r}]  "
                  f"# a: {_comment(res, f'hose_a.{n}', 'm³')[2:]}; "
                  f"b: {_comment(res, f'hose_b.{n}', 'm³')[2:]}",
                  f"coulomb = {jd.coulomb!r}  " + _comment(res, f"coulomb.{n}", ""),
                  f"viscous = {jd.viscous!r}  " + _comment(res, f"viscous.{n}", ""),
                  f"leakage = {jd.leakage!r}  " + _comment(res, f"leakage.{n}", "m³/(s·Pa)")]
        if jd.source:
            lines.append(f"source = {json.dumps(jd.source, ensure_ascii=False)}")
    if dyn.grapple is not None and not any(
            _HEADER.match(x) and _HEADER.match(x).group(1) == "dynamics.grapple" for x in out):
        g = dyn.grapple
        lines += ["", "[dynamics.grapple]", f"link_length = {g.length!r}",
                  f"damping = {g.damping!r}", f"gyration = {g.gyration!r}"]
    return "\n".join(out + lines) + "\n"
