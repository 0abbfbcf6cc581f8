"""The notebook studies (notebooks/*.ipynb) run end to end with the small settings.

Each notebook is executed with nbclient and the ``python3`` kernel of this interpreter
(notebooks/run_notebooks.py) in a temporary copy — outputs never touch the repository — with
CRANE_NB_SMALL=1; a failing cell fails the test, and the closing cell must print the answer. The
committed notebooks must carry no outputs and equal what notebooks/build_notebooks.py generates.
"""
import importlib.util
from pathlib import Path

import nbformat  # the dev extra installs nbformat, nbclient and ipykernel
import pytest

NB_DIR = Path(__file__).resolve().parents[1] / "notebooks"
NAMES = ("a_seed000_revisited", "b_energy", "c_open_loop", "d_calibration")


def _module(name):
    spec = importlib.util.spec_from_file_location(name, NB_DIR / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_studies_are_all_there_and_committed_without_outputs():
    assert sorted(p.stem for p in NB_DIR.glob("[a-z]_*.ipynb")) == sorted(NAMES)
    for name in NAMES:
        nb = nbformat.read(NB_DIR / f"{name}.ipynb", as_version=4)
        nbformat.validate(nb)
        assert nb.cells[0].cell_type == "markdown" and "**Question.**" in nb.cells[0].source
        assert "CRANE_NB_SMALL" in next(c for c in nb.cells if c.cell_type == "code").source
        for c in nb.cells:
            if c.cell_type == "code":
                assert c.outputs == [] and c.execution_count is None, (name, c.id)


def test_the_committed_notebooks_are_what_the_generator_writes(tmp_path):
    build = _module("build_notebooks")
    assert build.main(["--out", str(tmp_path)]) == 0
    for name in NAMES:
        assert (tmp_path / f"{name}.ipynb").read_text(encoding="utf-8") == \
            (NB_DIR / f"{name}.ipynb").read_text(encoding="utf-8"), \
            f"{name}.ipynb is stale: run python notebooks/build_notebooks.py"


@pytest.mark.parametrize("name", NAMES)
def test_notebook_runs_with_the_small_settings(name, tmp_path):
    run = _module("run_notebooks")
    before = (NB_DIR / f"{name}.ipynb").read_bytes()
    nb, seconds = run.execute(NB_DIR / f"{name}.ipynb", tmp_path, small=True, timeout=600)
    assert (NB_DIR / f"{name}.ipynb").read_bytes() == before   # the repo copy is untouched
    cells = [c for c in nb.cells if c.cell_type == "code"]
    assert all(c.execution_count is not None for c in cells)
    assert not [o for c in cells for o in c.outputs if o.output_type == "error"]
    first = "".join(o.get("text", "") for o in cells[0].outputs if o.output_type == "stream")
    assert "settings: small" in first
    last = nb.cells[-1]
    assert last.cell_type == "code" and last.outputs, "the closing cell printed nothing"
    text = " ".join(o.get("text", "") if o.output_type == "stream"
                    else o.get("data", {}).get("text/markdown", "") for o in last.outputs)
    assert any(ch.isdigit() for ch in text), text
    print(f"{name}: {seconds:.1f} s")
