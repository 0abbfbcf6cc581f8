"""Simulation: the "true" plant = the nominal model plus effects.

Layers (each imports only the ones above it): ``effects`` (the catalogue: one class per effect,
its registry) -> ``replay`` (the fast quasi-static open-loop replay: commands, start and valves
stages; :class:`~planner.simulation.replay.Plant`, the robustness study's constructor of an
effect set; the robustness score) -> ``recording`` (the measured-data CSV contract: read,
write, sensor noise) -> ``plant`` (the plant's response with every stage: forces, leakage,
sensors; what ``crane-planner simulate`` does). Nothing here imports :mod:`planner.calibration`.
"""
