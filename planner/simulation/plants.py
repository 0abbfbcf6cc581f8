"""One plant interface: every plant is built from a machine and effects, runs valve commands
open loop into the measured-data record, and reports what each effect did.

=========  ===========================================================================  =======
name       plant                                                                         judge?
=========  ===========================================================================  =======
fast       the quasi-static open-loop replay plus effects                               no: the
           (:func:`planner.simulation.plant.respond`; the model that plans and fits)    model's
exudyn     Exudyn multibody + chamber-pressure dynamics with its own circuit code        yes
           (:class:`planner.simulation.dynamic.exudyn_plant.ExudynPlant`)
twin       the model's dynamic twin: RNEA + chamber pressures, valves, pump (CasADi,    no: the
           compiled BDF2; :class:`planner.simulation.twin_plant.TwinPlant`)             model's
=========  ===========================================================================  =======

The contract (:class:`BasePlant`):

* ``Plant(crane, effects=())`` — the spec's own ``[[effects]]`` first, then the given ones.
  Each effect acts through the hooks it shares with the plant (``hooks``,
  :mod:`planner.model.effects.hooks`); an effect that shares none is **refused** at
  construction with :class:`~planner.model.effects.EffectRefused` naming it and the plants that
  apply it. Nothing is dropped silently.
* ``run(t_u, u, q0, t_end=None, rate=None)`` — commands ``u`` (M, n) held from ``t_u``
  (zero-order hold), from rest at ``q0`` -> a :class:`PlantRecord` sampled at ``rate`` [Hz]
  (default: the command grid): what the sensors report and the true states behind them.
* ``report()`` — one row per effect: its name, joint, values and the hooks it acted through.

:func:`plant_class` looks a plant up by name (imports only the one asked for: Exudyn is heavy).
"""
from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from planner.model.effects import as_effects, effect_from_dict, refuse
from planner.model.effects.hooks import DYNAMIC_HOOKS, PENDULUM_HOOKS, QUASI_STATIC_HOOKS

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["PlantRecord", "BasePlant", "FastPlant", "PLANTS", "plant_class", "make_plant",
           "applying", "PlantDiverged", "plant_to_csv", "load_swing"]


class PlantDiverged(RuntimeError):
    """A plant run that stopped early: ``status`` ("diverged" | "timeout"), ``t_fail`` [s]
    and the reason."""

    def __init__(self, status: str, t_fail: float, reason: str, plant: str = "dynamic"):
        super().__init__(f"{plant} plant {status} at t = {t_fail:.4f} s: {reason}")
        self.status, self.t_fail, self.reason, self.plant = status, t_fail, reason, plant


@dataclass
class PlantRecord:
    """A run of a plant sampled at ``t`` (N,) [s]: the commanded ``u`` (N, n) in effect, what
    the sensors report (``q``, ``p_a``, ``p_b``; (N, n), rad | m, Pa) and the true states
    (``q_true``, ``p_a_true``, ``p_b_true``); ``status`` "ok" | "diverged" | "timeout" with
    ``reason`` and ``t_fail`` (a run that stopped early keeps what it recorded)."""
    t: np.ndarray
    u: np.ndarray
    q: np.ndarray
    p_a: np.ndarray
    p_b: np.ndarray
    q_true: np.ndarray
    p_a_true: np.ndarray
    p_b_true: np.ndarray
    plant: str
    status: str = "ok"
    reason: str = ""
    t_fail: float | None = None
    meta: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def recording(self):
        """The measured-data record (:class:`planner.simulation.recording.Recording`)."""
        from planner.simulation.recording import Recording
        return Recording(self.t, self.u, self.q, self.p_a, self.p_b)


class BasePlant(ABC):
    """A plant (see the module doc). A subclass sets ``name``, ``description``, ``hooks``
    (the effect hooks it calls) and ``physical_first`` (a dynamic plant: an effect's physical
    data replaces its quasi-static stand-ins), calls :meth:`_take_effects` in its constructor
    and implements :meth:`run`."""
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    hooks: ClassVar[tuple[str, ...]] = ()
    physical_first: ClassVar[bool] = False

    def _take_effects(self, crane: Crane, effects) -> tuple:
        """The spec's effects, then ``effects``; each checked against this plant's hooks
        (:class:`EffectRefused` for one it cannot apply). Sets ``self.effects`` and
        ``self.applied`` (effect -> the hooks it acts through here)."""
        given = (tuple(effect_from_dict(d) for d in crane.spec.effects)
                 + as_effects(crane, effects))
        self.applied = {}
        for e in given:
            self.applied[e] = refuse(e, self.name, self.hooks, self.physical_first,
                                     elsewhere=_elsewhere(e, self.name))
        self.effects = given
        return given

    def acting(self, hook: str) -> list:
        """The effects that act through ``hook`` in this plant, in order."""
        return [e for e in self.effects if hook in self.applied[e]]

    @abstractmethod
    def run(self, t_u, u, q0, t_end: float | None = None,
            rate: float | None = None) -> PlantRecord:
        """Commands ``u`` (M, n) held from ``t_u`` (M,), from rest at ``q0`` (n,)."""

    def pump_energy(self, rec: PlantRecord) -> float | None:
        """The pump's energy at the shaft [J] over the run ``rec`` (hydraulic work / η, what
        :func:`planner.trajectory.evaluate` reports as ``energy_J``), where this plant
        accounts for it; None here (a plant without its own pump model)."""
        return None

    def report(self) -> list[dict]:
        """What each effect did here: its catalogue form and the hooks it acted through."""
        return [dict(e.to_dict(), plant=self.name, hooks=list(self.applied[e]))
                for e in self.effects]


def _grid(t_u, t_end, rate):
    """Sample times: the command grid to ``t_end`` (default), or ``rate`` [Hz] from t_u[0]."""
    t_u = np.asarray(t_u, float)
    if rate is None:
        dt = float(np.median(np.diff(t_u))) if t_u.size > 1 else 0.02
    else:
        dt = 1.0 / float(rate)
    return t_u[0] + dt * np.arange(int(np.floor((t_end - t_u[0]) / dt + 1e-9)) + 1)


def _sample(t_src, a, t):
    return np.column_stack([np.interp(t, t_src, a[:, i]) for i in range(a.shape[1])])


class FastPlant(BasePlant):
    """The quasi-static replay with every stage of effects
    (:func:`planner.simulation.plant.respond`): rigid flows from the commands, pressures from
    the model's inverse dynamics, the quasi-static stand-ins of forces and leaks."""
    name = "fast"
    description = "quasi-static open-loop replay plus effects (the model's own family)"
    hooks = QUASI_STATIC_HOOKS

    def __init__(self, crane: Crane, effects=(), plant=None):
        from planner.simulation.replay import Plant
        self.crane = crane
        self._take_effects(crane, effects)
        self._deviations = Plant() if plant is None else plant
        # the robustness study's deviations are effects too (checked like the others)
        for e in as_effects(crane, self._deviations):
            self.applied.setdefault(e, refuse(e, self.name, self.hooks))

    def run(self, t_u, u, q0, t_end=None, rate=None) -> PlantRecord:
        from planner.simulation.plant import respond
        given = self.effects[len(self.crane.spec.effects):]
        r = respond(self.crane, t_u, u, q0, given, plant=self._deviations, t_end=t_end)
        t = r.t if rate is None else _grid(t_u, r.t[-1], rate)
        if rate is None:
            q, pa, pb, qt = r.q, r.p_a, r.p_b, r.state.q
            pat, pbt, uu = r.state.p_a, r.state.p_b, r.u
        else:
            q, pa, pb = (_sample(r.t, a, t) for a in (r.q, r.p_a, r.p_b))
            qt, pat, pbt = (_sample(r.t, a, t) for a in (r.state.q, r.state.p_a, r.state.p_b))
            uu = np.asarray(u, float)[np.clip(np.searchsorted(t_u, t + 1e-9, side="right") - 1,
                                              0, len(t_u) - 1)]
        return PlantRecord(t, uu, q, pa, pb, qt, pat, pbt, plant=self.name,
                           meta=dict(r.meta, response=r))


#: name -> "module:Class" (imported on first use)
PLANTS = {"fast": "planner.simulation.plants:FastPlant",
          "exudyn": "planner.simulation.dynamic.exudyn_plant:ExudynPlant",
          "twin": "planner.simulation.twin_plant:TwinPlant"}
#: the hooks each plant calls, known without importing it (for messages and listings)
PLANT_HOOKS = {"fast": (QUASI_STATIC_HOOKS, False), "exudyn": (PENDULUM_HOOKS, True),
               "twin": (DYNAMIC_HOOKS, True)}


def plant_class(name: str) -> type:
    """The plant class registered as ``name`` (ValueError naming the known ones)."""
    if name not in PLANTS:
        raise ValueError(f"plant = {name!r}; allowed: {', '.join(PLANTS)}")
    mod, _, cls = PLANTS[name].partition(":")
    return getattr(importlib.import_module(mod), cls)


def make_plant(name: str, crane: Crane, effects=()) -> BasePlant:
    """The plant ``name`` of ``crane`` with ``effects``."""
    return plant_class(name)(crane, effects)


def applying(effect) -> list[str]:
    """The registered plants that apply ``effect`` (an instance or class)."""
    cls = effect if isinstance(effect, type) else type(effect)
    return [p for p, (hooks, phys) in PLANT_HOOKS.items() if cls.hooks_in(hooks, phys)]


def _elsewhere(effect, here: str) -> str:
    others = [p for p in applying(effect) if p != here]
    return (f"plants that apply it: {', '.join(others)}" if others
            else "no registered plant applies it")


def load_swing(plant: BasePlant, rec: PlantRecord):
    """(t (K,) [s], (K, 2) [m]): the horizontal offset (x, y) in frame 0 of the load's centre
    of mass from under the boom tip, on the plant's own integration grid, for a plant whose
    grapple hangs on its link (the Exudyn plant with ``[dynamics.grapple]`` or the
    ``grapple_swing`` effect); None for any other."""
    run = rec.meta.get("run")
    if getattr(run, "grapple_q", None) is None or not hasattr(plant, "tree"):
        return None
    from planner.simulation.dynamic.grapple import link_frames
    tree = plant.tree
    n = tree["crane_links"]
    _, links = link_frames(tree, np.hstack([run.q, run.grapple_q]))
    com = (links[-1] @ np.array([tree["grapple"].length, 0.0, 0.0, 1.0]))[:, :2]
    return np.asarray(run.t, float), com - links[n][:, :2, 3]


def plant_to_csv(crane: Crane, traj, out, plant: str = "exudyn", rate: float = 50.0, noise=None,
                 seed: int = 0, effects=(), plan=None, **run_kw) -> dict:
    """What ``crane-planner simulate --plant NAME`` does for a registered plant: replay
    ``traj``'s commands (its own ``u`` on a uniform grid, else the machine's feed-forward at
    ``rate``: the oil springs filled where the crane has ``[dynamics]``) on the plant with the
    hidden ``effects``, and write the measured-data CSV at ``rate``.
    Nothing is written when the run stops early: :class:`PlantDiverged` is raised. Returns a
    JSON-ready summary (``effects``: what each effect did, with its hooks; where the plant
    accounts for its pump, ``pump_energy_J`` beside ``evaluate_energy_J``, the quasi-static
    model's figure for the plan under the crane's ``pricing``, and ``twin_energy_J``, the
    dynamic twin's on the same commands — None where the crane has no twin or the plant
    carries hidden effects the twin was not told of). With ``plan`` (the planned
    trajectory whose end is the arrival; ``traj`` then carries the commands, e.g.
    :func:`planner.feedforward.with_settle`) the summary adds how the run lands
    (:func:`planner.refine.landing_measures`: ``rest_offset_m``, ``residual_oscillation_m``,
    ``track_m``). A plant whose grapple swings on its link (:func:`load_swing`) adds the
    CSV columns ``swing_x``, ``swing_y`` [m] and ``residual_swing_m`` (the largest offset
    after the plan's end: over its tail when the commands run on, else at the record's
    last sample) and ``swing_peak_m`` (during the move)."""
    from planner.feedforward import commands, fills_oil
    from planner.simulation.recording import noise_levels
    p = make_plant(plant, crane, effects)
    if traj.u is not None and len(traj.t) > 2 and np.ptp(np.diff(traj.t)) < 1e-9:
        t_u, u, src = np.asarray(traj.t, float), np.asarray(traj.u, float), "trajectory"
    else:
        ff = commands(crane, traj, rate, oil=fills_oil(crane))     # the machine's: oil filled
        t_u, u, src = (np.asarray(ff.t, float), np.asarray(ff.u, float),
                       f"feedforward@{rate:g}Hz" + ("+oil" if ff.meta["oil"] else ""))
    rec = p.run(t_u, u, traj.q[0], t_end=float(max(traj.t[-1], t_u[-1])), rate=rate, **run_kw)
    if not rec.ok:
        raise PlantDiverged(rec.status, rec.t_fail, rec.reason, plant)
    swing = load_swing(p, rec)
    if swing is None:
        cols = rec.recording().with_noise(crane, noise, seed).to_csv(out, crane)
    else:   # the load's horizontal offset from under the tip, beside the sensors' columns
        from planner.io import atomic_write_text
        cols, M = rec.recording().with_noise(crane, noise, seed).table(crane)
        cols = cols + ["swing_x", "swing_y"]
        M = np.hstack([M, np.column_stack([np.interp(rec.t, swing[0], swing[1][:, i])
                                           for i in (0, 1)])])
        atomic_write_text(out, "\n".join([",".join(cols)] + [",".join(f"{v:.10g}" for v in row)
                                                             for row in M]) + "\n")
    q_plan = traj.sample(np.clip(rec.t, traj.t[0], traj.t[-1]))[0]
    tip_err = np.linalg.norm(crane.fk(rec.q_true) - crane.fk(q_plan), axis=1)
    extra = {k: rec.meta[k] for k in ("steps", "wall_s") if k in rec.meta}
    if "step" in rec.meta:
        extra["step_s"] = rec.meta["step"]
    if plan is not None:
        from planner.refine import landing_measures
        extra.update(landing_measures(crane, rec.t, rec.q_true, plan))
    if swing is not None:   # after the plan's end: its tail (a settle) or the last sample
        t_arrive = float((traj if plan is None else plan).t[-1])
        r = np.linalg.norm(swing[1], axis=1)
        after = swing[0] >= min(t_arrive, swing[0][-1]) - 1e-9
        extra.update(residual_swing_m=float(r[after].max()),
                     swing_peak_m=float(r[swing[0] <= t_arrive].max(initial=0.0)))
    pump_J = p.pump_energy(rec)
    if pump_J is not None:   # the plant's own pump work beside the quasi-static model's
        from planner.trajectory import evaluate
        from planner.methods.nlp.twin_judge import commands_pump_energy
        twin_J = commands_pump_energy(crane, t_u, u, traj.q[0],
                                      float(max(traj.t[-1], t_u[-1]))) if not effects else None
        extra.update(pump_energy_J=float(pump_J),
                     evaluate_energy_J=float(evaluate(crane, traj if plan is None else plan)
                                             .energy_J),
                     twin_energy_J=twin_J, pricing=crane.pricing)
    return dict(status="ok", plant=plant, out=str(out), samples=len(rec.t), columns=cols,
                commands=src, effects=p.report(), noise=noise_levels(noise), seed=seed,
                max_tip_error_m=float(tip_err.max()), final_tip_error_m=float(tip_err[-1]),
                **extra)
