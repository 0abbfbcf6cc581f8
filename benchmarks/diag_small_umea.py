"""Issue 28's two small umea-lab cases diagnosed by the twin: a 6 kg payload change and 400 N
of Coulomb friction on the boom, recorded by the Exudyn plant (the trials' 30 s test sequence,
seed 001's noise).  python benchmarks/diag_small_umea.py [SEED]"""
import json
import sys
import time

import numpy as np

sys.path.insert(0, "benchmarks")
from bench_discrepancy_exudyn import exudyn_record  # noqa: E402
from planner import Crane  # noqa: E402
from planner.calibration.trials import excitation  # noqa: E402
from planner.calibration.twin_diagnosis import TwinDiagnosis  # noqa: E402
from planner.model.effects.base import make  # noqa: E402

seed = int(sys.argv[1]) if len(sys.argv) > 1 else 1000
crane = Crane.from_id("umea-lab")
plan, ff = excitation(crane, 30.0, seed=seed)
for eff in (make("payload_mass", mass=6.0), make("coulomb_friction", "boom", force=400.0)):
    rec, why = exudyn_record(crane, plan, ff, (eff,), seed)
    c0 = time.process_time()
    res = TwinDiagnosis(crane).fit(rec)
    print(json.dumps(dict(truth=[eff.name, eff.joint, eff.values], verdict=res.verdict,
                          effect=res.effect, joint=res.joint, parameters=res.parameters,
                          candidates=[(c["effect"], c["joint"]) for c in res.candidates],
                          message=res.message[:300], cpu_s=time.process_time() - c0),
                     default=str), flush=True)
