"""URDF round trip (issue 16, item 17): forward kinematics of the generated URDF, parsed by
yourdfpy, against the model's FK on random configurations of every machine. Writes
benchmarks/results/urdf_round_trip.md."""
import sys
import tempfile
from pathlib import Path

import numpy as np
import yourdfpy

from planner import Crane
from planner.model.urdf import urdf_xml

N = 1000


def main(out=Path(__file__).parent / "results" / "urdf_round_trip.md"):
    rows = []
    for cid in ("cranab850", "umea-lab", "s100f", "cat215b"):
        crane = Crane.from_id(cid)
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / "c.urdf"
            p.write_text(urdf_xml(crane))
            robot = yourdfpy.URDF.load(str(p), load_meshes=False,
                                       build_collision_scene_graph=False)
        L = crane.limit_arrays()
        Q = L["q_min"] + np.random.default_rng(0).random((N, crane.n)) * (L["q_max"] - L["q_min"])
        err = 0.0
        for q in Q:
            robot.update_cfg(dict(zip(crane.names, map(float, q))))
            err = max(err, float(np.max(np.abs(robot.get_transform("tip", "base_link")[:3, 3]
                                               - crane.fk(q)))))
        rows.append(f"| {cid} | {crane.n} | {N} | {err:.2e} |")
    text = "\n".join(["# URDF round trip: FK from the URDF (yourdfpy) vs the model", "",
                      "Random configurations over the full joint ranges (seed 0), "
                      "`python benchmarks/urdf_round_trip.py`.", "",
                      "| machine | joints | configurations | max tip error [m] |",
                      "| --- | ---: | ---: | ---: |", *rows, ""])
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
