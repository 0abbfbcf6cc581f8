"""One case of bench_discrepancy_twin (Exudyn records, the twin diagnoses), printed as JSON:

    python benchmarks/diag_one.py MACHINE SEED [EFFECT|-] [TWIN_STEP]
"""
import json
import sys

sys.path.insert(0, "benchmarks")
from bench_discrepancy_twin import run_case  # noqa: E402

case = dict(machine=sys.argv[1], seed=int(sys.argv[2]), duration=30.0,
            effect=(sys.argv[3] if len(sys.argv) > 3 and sys.argv[3] != "-" else None),
            twin_step=float(sys.argv[4]) if len(sys.argv) > 4 else None)
r = run_case(case)
print(json.dumps({k: r.get(k) for k in ("verdict", "effect", "joint", "message", "not_credible",
                                        "signature", "ok", "cpu_s")}, default=str, indent=1))
print({k: round(v, 2) for k, v in r["rms_over_noise"].items()} if r.get("rms_over_noise") else "")
