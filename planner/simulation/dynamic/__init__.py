"""The independent dynamic plant (issue 13): Exudyn multibody + hydraulic pressure dynamics.

``circuit`` (the hydraulic circuit, numpy) -> ``fastpath`` (the same physics for one state in
plain Python, what the integrator evaluates) -> ``exudyn_plant`` (the Exudyn model and its run)
-> ``energy`` (energy balance of a run) -> ``simulate`` (commands / trajectories -> the
measured-data CSV, what ``crane-planner simulate --plant exudyn`` does).
"""
