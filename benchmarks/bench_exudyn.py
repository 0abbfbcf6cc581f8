"""Validation of the Exudyn plant (issue 13, item 2) and its speed (item 5), every machine:

* rest: chamber pressures after 1 s at rest vs the model's load-holding pressures;
* slow move (10 % speed: a Ruckig rest-to-rest move between two random poses, 10× slower):
  strokes vs the fast replay plant (% of each stroke range) and load pressures F/A_a vs the
  model's along the plan (0.5 s moving averages, % of the move's peak, ≥ 1 MPa);
* lowest hydraulic natural frequency: measured (free oscillation after a 0.2 s valve pulse,
  zero crossings of the stroke) beside β·(A_a²/V_a + A_b²/V_b)/m_eff, m_eff = M_ii/(dx/dq)²;
* energy balance residual and pump energy vs evaluate() on the full-speed move;
* speed: a 60 s recording (a slow move padded with rest) of s100f, wall time on one core.

Run: ``python benchmarks/bench_exudyn.py [--quick]`` -> benchmarks/results/exudyn_validation.md
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from planner import Crane, evaluate
from planner.methods.ruckig import rest_to_rest
from planner.simulation.dynamic.energy import energy_balance
from planner.simulation.dynamic.exudyn_plant import ExudynPlant
from planner.simulation.dynamic.simulate import simulate_trajectory, slowed
from planner.simulation.plant import respond
from planner.simulation.replay import stroke_stops

MACHINES = ("s100f", "umea-lab", "cranab850", "cat215b")
OUT = Path(__file__).parent / "results"


def _poses(crane, seed):
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + 0.15 * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - 0.15 * (L["q_max"] - L["q_min"])
    return lo + rng.random((2, crane.n)) * (hi - lo)


def _ma(a, w=25):
    k = np.ones(w) / w
    return np.column_stack([np.convolve(a[:, i], k, mode="valid") for i in range(a.shape[1])])


def rest(crane, q0):
    plant = ExudynPlant(crane)
    run = plant.integrate([0.0, 1.0], np.zeros((2, crane.n)), q0)
    pa0, pb0 = plant.initial_pressures(q0)
    scale = np.maximum(np.maximum(np.abs(pa0), np.abs(pb0)), 1e5)
    err = np.maximum(np.abs(run.p_a[-1] - pa0), np.abs(run.p_b[-1] - pb0)) / scale
    return dict(status=run.status, max_rel=float(err.max()))


def slow_move(crane, traj, factor=10.0):
    tr = slowed(traj, factor)
    plant = ExudynPlant(crane)
    run, t_u, u, _ = simulate_trajectory(crane, tr, 50.0, settle=1.0, plant=plant)
    if not run.ok:
        return dict(status=run.status, t_fail=run.t_fail, reason=run.reason)
    fast = respond(crane, t_u, u, tr.q[0], t_end=run.t[-1], dt=0.02)
    q, pa, pb, _ = run.sample(fast.t)
    lo, hi = stroke_stops(crane)
    xe = np.abs(crane.stroke(q)[0] - crane.stroke(fast.state.q)[0]).max(axis=0) / (hi - lo)
    A = np.array([j.actuator.area_a for j in crane.spec.joints])
    B = np.array([0.0 if j.actuator.acting == "single" else j.actuator.area_b
                  for j in crane.spec.joints])
    hy = crane.hydraulics(*tr.sample(np.clip(fast.t, tr.t[0], tr.t[-1]))[:3])
    Fd, Fm = (pa * A - pb * B) / A, (hy["p_a"] * A - hy["p_b"] * B) / A
    scale = np.maximum(np.abs(Fm).max(axis=0), 1e6)
    pe = np.abs(_ma(Fd) - _ma(Fm)).max(axis=0) / scale
    return dict(status="ok", stroke_err_pct=(100 * xe).tolist(),
                load_pressure_err_pct=(100 * pe).tolist(), wall_s=run.wall_s,
                sim_s=float(run.t[-1] - run.t[0]))


def natural_frequency(crane, q0):
    """Lowest measured free-oscillation frequency over the joints, with the analytic one."""
    plant = ExudynPlant(crane)
    C = plant.circuit
    out = []
    for i in range(crane.n):
        u = np.zeros((3, crane.n))
        u[0, i] = 0.3 * (1 if q0[i] < np.mean(crane.limit_arrays()["q_max"][i]) else -1)
        run = plant.integrate([0.0, 0.2, 3.0], u, q0)
        x = run.x[run.t > 0.45, i]
        x = x - x.mean()
        zc = np.flatnonzero(np.diff(np.sign(x)) != 0)
        f_meas = (len(zc) - 1) / 2 / (run.t[run.t > 0.45][zc[-1]] - run.t[run.t > 0.45][zc[0]]) \
            if len(zc) > 2 else float("nan")
        qe = run.q[-1]
        xq, d = crane.stroke(qe)
        e = np.zeros(crane.n)
        e[i] = 1.0
        Mii = float((crane.inverse_dynamics(qe, 0 * qe, e, plant.payload)
                     - crane.inverse_dynamics(qe, 0 * qe, 0 * qe, plant.payload))[i])
        va, vb = C.volumes(xq)
        k = C.beta * (C.area_a[i] ** 2 / va[i]
                      + (0.0 if C.single[i] else C.area_b[i] ** 2 / vb[i]))
        f_an = np.sqrt(k / (Mii / d[i] ** 2)) / (2 * np.pi)
        out.append(dict(joint=crane.names[i], measured_hz=float(f_meas), analytic_hz=float(f_an)))
    return out


def full_speed(crane, traj):
    plant = ExudynPlant(crane)
    run, *_ = simulate_trajectory(crane, traj, 50.0, settle=1.0, plant=plant)
    if not run.ok:
        return dict(status=run.status, t_fail=run.t_fail)
    eb = energy_balance(plant, run)
    ev = evaluate(crane, traj)
    return dict(status="ok", residual_pct=100 * eb["residual_rel"],
                pump_energy_exudyn_J=eb["pump_shaft_J"], pump_energy_evaluate_J=ev.energy_J)


def speed(crane_id="s100f"):
    crane = Crane.from_id(crane_id)
    q0, q1 = _poses(crane, 1)
    traj = slowed(rest_to_rest(crane, q0, q1, scale=0.5).trajectory, 4.0)
    plant = ExudynPlant(crane)
    run, *_ = simulate_trajectory(crane, traj, 50.0, plant=plant,
                                  settle=max(60.0 - traj.duration, 0.0))
    return dict(crane=crane_id, sim_s=float(run.t[-1] - run.t[0]), wall_s=run.wall_s,
                status=run.status, step_s=plant.step)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="s100f only")
    args = ap.parse_args(argv)
    machines = MACHINES[:1] if args.quick else MACHINES
    res = {}
    for cid in machines:
        crane = Crane.from_id(cid)
        q0, q1 = _poses(crane, 1)
        traj = rest_to_rest(crane, q0, q1, scale=1.0).trajectory
        r = dict(rest=rest(crane, q0), slow=slow_move(crane, traj),
                 frequency=natural_frequency(crane, q0), full=full_speed(crane, traj))
        res[cid] = r
        print(cid, json.dumps(r)[:400], file=sys.stderr)
    res["speed"] = speed()
    OUT.mkdir(exist_ok=True)
    (OUT / "exudyn_validation.json").write_text(json.dumps(res, indent=1))
    lines = ["# Exudyn plant: validation (issue 13, item 2) and speed (item 5)", "",
             "Produced by `python benchmarks/bench_exudyn.py`; judge: the Exudyn plant "
             "(planner/simulation/dynamic), against the model (rest, energy) and the fast replay "
             "plant (slow moves). Moves: Ruckig rest-to-rest between two random poses "
             "(seed 1, 15 % inside the limits).", "",
             "| machine | rest: max pressure error (% of load-holding) | slow move (10 %): max "
             "stroke error (% of range) per joint | slow move: load pressure error (% of peak, "
             "0.5 s mean) per joint | energy balance residual (%) | pump energy Exudyn / "
             "evaluate() (kJ) |", "| --- | --- | --- | --- | --- | --- |"]
    for cid in machines:
        r = res[cid]
        s, f = r["slow"], r["full"]
        lines.append(
            f"| {cid} | {100 * r['rest']['max_rel']:.3f} | "
            + (", ".join(f"{v:.2f}" for v in s["stroke_err_pct"]) if s["status"] == "ok"
               else s["status"]) + " | "
            + (", ".join(f"{v:.1f}" for v in s["load_pressure_err_pct"])
               if s["status"] == "ok" else "–") + " | "
            + (f"{f['residual_pct']:.2f} | {f['pump_energy_exudyn_J'] / 1e3:.1f} / "
               f"{f['pump_energy_evaluate_J'] / 1e3:.1f}" if f["status"] == "ok"
               else f"{f['status']} | –") + " |")
    lines += ["", "## Lowest hydraulic natural frequency", "",
              "| machine | joint | measured (Hz) | β·(A_a²/V_a + A_b²/V_b)/m_eff (Hz) |",
              "| --- | --- | --- | --- |"]
    for cid in machines:
        for fr in res[cid]["frequency"]:
            lines.append(f"| {cid} | {fr['joint']} | {fr['measured_hz']:.2f} | "
                         f"{fr['analytic_hz']:.2f} |")
    sp = res["speed"]
    lines += ["", "## Speed", "",
              f"{sp['crane']}: {sp['sim_s']:.1f} s simulated (step {sp['step_s'] * 1e3:g} ms, "
              f"output at 50 Hz) in {sp['wall_s']:.1f} s wall on one core ({sp['status']}).", ""]
    (OUT / "exudyn_validation.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
