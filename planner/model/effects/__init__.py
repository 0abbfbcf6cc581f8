"""The catalogue of effects a nominal crane model can miss (docs/design.md, "Core ideas" 3).

Each effect is one class (:class:`Effect`, see :mod:`planner.model.effects.base`): its
parameters (unit, plausible range, neutral value), its injection into the "true" plant, its
trial magnitude, its command delay and its observability rule. The same object is injected into
the plant (:func:`planner.simulation.plant.respond`, :func:`planner.simulation.replay.replay`),
drawn by the hidden-effect trials (:mod:`planner.calibration.trials`) and fitted to data by
:mod:`planner.calibration.discrepancy` — one definition serves injection and identification.
Effects are model augmentations, so they live in the model layer: a calibrated machine spec
carries its ``[[effects]]`` and :func:`planner.model.spec.load_spec` validates them at load.

An effect acts at one stage of the plant (the hooks; the default hooks do nothing):

===========  ==================================================================================
commands     what the valves see of the command signal (time_delay, valve_lag)
start        where the crane really starts (start_offset; not in the catalogue)
valves       valve and pump data of the replay (flow_gain, valve_deadband, pump_flow_limit)
forces       extra actuator force or load (coulomb_friction, viscous_friction, payload_mass,
             actuator_mass; grapple_load, not in the catalogue)
strokes      extra stroke motion driven by pressure (leakage)
sensors      what the transducers report (joint_offset, pressure_offset, sensor_gain,
             sensor_drift, pressure_drift)
dynamics     the oil's physical data, in the dynamic (Exudyn) plant only (bulk_modulus,
             hose_volume; never drawn by trials nor fitted: the quasi-static model has no oil)
===========  ==================================================================================

Which plant applies an effect is decided by its **hooks**, not its stage or its name: every
plant lists the hooks it calls, an effect acts through the ones it overrides, and a plant that
shares none with it refuses it by name (:mod:`planner.model.effects.hooks`; e.g. friction acts
through ``force`` in the quasi-static plant and through ``dynamics`` — the actuator's own
friction — in the dynamic ones).

Adding an effect is one class: subclass :class:`Effect`, set its attributes, override its
stage's hook (and ``trial_values`` when trials should draw it), and :func:`register` it —
a built-in one in the tuple below (its place there is its place in the catalogue). Parse the
CLI form with :func:`parse_effect` (``"flow_gain:joint=boom,scale=1.05"``) and list the
catalogue with :func:`catalogue`.
"""
from planner.model.effects.base import (CATALOGUE, STAGES, Effect, Parameter, ValveSet,
                                             as_effects, catalogue, effect_from_dict, make,
                                             fittable, parse_effect, quasi_static, refuse,
                                             register, unregister)
from planner.model.effects.hooks import EffectRefused
from planner.model.effects.dynamics import BulkModulus, GrappleSwing, HoseVolume
from planner.model.effects.loads import (ActuatorMass, CoulombFriction, GrappleLoad,
                                              JointOffset, PayloadMass, PressureOffset,
                                              ViscousFriction)
from planner.model.effects.motion import (FlowGain, Leakage, PumpFlowLimit, StartOffset,
                                               TimeDelay, ValveDeadband, ValveLag,
                                               valve_commands)
from planner.model.effects.sensors import PressureDrift, SensorDrift, SensorGain

__all__ = ["Parameter", "ValveSet", "Effect", "STAGES", "CATALOGUE", "register", "unregister",
           "catalogue", "make", "parse_effect", "effect_from_dict", "as_effects",
           "JointOffset", "FlowGain", "ValveDeadband", "ValveLag", "TimeDelay", "PumpFlowLimit",
           "Leakage", "CoulombFriction", "ViscousFriction", "PayloadMass", "ActuatorMass",
           "PressureOffset", "StartOffset", "GrappleLoad", "SensorGain", "SensorDrift",
           "PressureDrift", "BulkModulus", "HoseVolume", "GrappleSwing", "quasi_static", "fittable",
           "refuse", "EffectRefused", "valve_commands"]

for _cls in (JointOffset, FlowGain, ValveDeadband, ValveLag, TimeDelay, PumpFlowLimit, Leakage,
             CoulombFriction, ViscousFriction, PayloadMass, ActuatorMass, PressureOffset,
             SensorGain, SensorDrift, PressureDrift, BulkModulus, HoseVolume,
             GrappleSwing):
    register(_cls)
del _cls
