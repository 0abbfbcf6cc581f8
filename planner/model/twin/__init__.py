"""The dynamic twin: the planner's own dynamic model of a machine, written once in CasADi
(docs/design.md, "Three models and the judge").

Beside the quasi-static model (which plans; no oil, no state) and the Exudyn plant (which
judges; its own circuit code), the twin integrates what a replay of open-loop commands really
does: the rigid bodies of the model's RNEA driven through the stroke map by both chamber
pressures of every actuator, the oil's compressibility in hoses and cylinders, the spool lag
and dead band, the pressure-compensated meter-in edge that starves when the pump lags, the
meter-out (load-holding) edge, anti-cavitation make-up, leakage, Coulomb and viscous friction,
end stops, and the load-sensing pump with its regulator lag and flow limit. Its valve physics
is the model's one definition (:mod:`planner.model.valve_physics`).

* :mod:`~planner.model.twin.params` — the machine's data as the compiled step's inputs;
* :mod:`~planner.model.twin.ode` — the right-hand side (CasADi);
* :mod:`~planner.model.twin.integrator` — BDF2 with Newton on the compiled Jacobian;
* :mod:`~planner.model.twin.twin` — :class:`Twin` (build once, simulate many) and
  :class:`TwinRun`;
* :mod:`~planner.model.twin.coupled` — the payload hanging on the grapple link
  (``Twin(..., grapple=…)``): the model's pendulum as four more states, its pull on the boom;
* :mod:`~planner.model.twin.pendulum` — the swing along a given joint motion (one way), the
  swing amplitude that :func:`planner.refine.refine_commands` puts a cost on.

The plant face (effects, sensors, the measured-data record) is
:class:`planner.simulation.twin_plant.TwinPlant`, registered as the ``twin`` plant.
"""
from planner.model.twin.ode import build_rhs, state_size, unpack
from planner.model.twin.params import TwinParams, twin_params
from planner.model.twin.twin import Twin, TwinRun

__all__ = ["Twin", "TwinRun", "TwinParams", "twin_params", "build_rhs", "state_size", "unpack"]
