"""``benchmarks/refine_distribution.py``: the residual distributions drawn from a
``bench_refine.py`` results file."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import refine_distribution  # noqa: E402


def _rows(offsets):
    return [dict(id=f"e{i}", status="ok", exudyn=dict(offset_m=o, peak_osc_m=o / 2,
                                                       max_track_m=10 * o))
            for i, o in enumerate(offsets)] + [dict(id="bad", status="error")]


def test_values_are_sorted_millimetres_and_a_failed_replay_is_counted():
    v, failed = refine_distribution.values(_rows([0.003, 0.001, 0.002]), "offset_m")
    assert np.allclose(v, [1.0, 2.0, 3.0]) and failed == 1


def test_the_figure_is_written_and_a_bad_file_is_one_line_exit_2(tmp_path, capsys):
    rep = dict(crane="s100f", selected=4,
               runs=dict(nominal=dict(rows=_rows([0.1, 0.2, 0.05])),
                         refined=dict(rows=_rows([0.001, 0.0004, 0.002]))))
    f = tmp_path / "r.json"
    f.write_text(json.dumps(rep))
    assert refine_distribution.main([str(f)]) == 0
    png = f.with_suffix(".png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob("*.part*"))
    (tmp_path / "x.json").write_text("{}")
    assert refine_distribution.main([str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a bench_refine.py results file" in err[0]
