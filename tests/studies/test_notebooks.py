"""The notebook studies: jupytext sources (notebooks/*.py) paired with committed .ipynb files
that run end to end with the small settings.

The committed notebooks must carry no outputs and hold exactly the cells jupytext reads from
their percent-format sources (read here with jupytext and nbformat directly, independent of the
runner's own check, which is tested separately on a copy). Each notebook is executed with
nbclient and the ``python3`` kernel of this interpreter (notebooks/run_notebooks.py) in a
temporary copy — outputs never touch the repository — with CRANE_NB_SMALL=1; a failing cell
fails the test, and the closing cell must print the answer.
"""
import importlib.util
import shutil
from pathlib import Path

import jupytext  # the dev extra installs jupytext, nbformat, nbclient and ipykernel
import nbformat
import pytest

NB_DIR = Path(__file__).resolve().parents[2] / "notebooks"
NAMES = ("a_seed000_revisited", "b_energy", "c_open_loop", "d_calibration")


def _runner():
    spec = importlib.util.spec_from_file_location("run_notebooks", NB_DIR / "run_notebooks.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _cells(nb):
    return [(c.cell_type, c.source) for c in nb.cells]


def test_the_studies_are_all_there_and_committed_without_outputs():
    assert sorted(p.stem for p in NB_DIR.glob("[a-z]_*.ipynb")) == sorted(NAMES)
    assert sorted(p.stem for p in NB_DIR.glob("[a-z]_*.py")) == sorted(NAMES)
    for name in NAMES:
        nb = nbformat.read(NB_DIR / f"{name}.ipynb", as_version=4)
        nbformat.validate(nb)
        assert nb.cells[0].cell_type == "markdown" and "**Question.**" in nb.cells[0].source
        assert "CRANE_NB_SMALL" in next(c for c in nb.cells if c.cell_type == "code").source
        for c in nb.cells:
            if c.cell_type == "code":
                assert c.outputs == [] and c.execution_count is None, (name, c.id)


@pytest.mark.parametrize("name", NAMES)
def test_the_committed_notebook_is_what_jupytext_makes_of_its_source(name):
    src = jupytext.read(NB_DIR / f"{name}.py")
    assert src.metadata["jupytext"]["formats"] == "ipynb,py:percent"   # `jupytext --sync` pairs
    committed = nbformat.read(NB_DIR / f"{name}.ipynb", as_version=4)
    assert _cells(committed) == _cells(src), \
        f"{name}.ipynb is stale: run python notebooks/run_notebooks.py --sync"
    assert len(src.cells) > 5 and src.cells[-1].cell_type == "code"


def test_the_runner_finds_the_committed_notebooks_in_step():
    assert _runner().stale() == []


def test_check_flags_a_stale_notebook_and_sync_rewrites_it(tmp_path):
    run = _runner()
    for name in NAMES:
        for ext in (".py", ".ipynb"):
            shutil.copyfile(NB_DIR / f"{name}{ext}", tmp_path / f"{name}{ext}")
    assert run.stale(tmp_path) == [] and run.sync(tmp_path) == []   # the committed files are
    for name in NAMES:                                              # what --sync writes
        assert (tmp_path / f"{name}.ipynb").read_bytes() == \
            (NB_DIR / f"{name}.ipynb").read_bytes()

    # an edited source: one line changed in the closing cell, one code cell added
    src = tmp_path / "b_energy.py"
    text = src.read_text(encoding="utf-8")
    assert text.count('"settings")') == 1
    src.write_text(text.replace('"settings")', '"settings (edited)")')
                   + "\n# %%\nprint('one more cell')\n", encoding="utf-8")
    # an .ipynb that carries outputs, and a source without its notebook
    nb = nbformat.read(tmp_path / "c_open_loop.ipynb", as_version=4)
    nb.cells[1].execution_count = 1
    nb.cells[1].outputs = [nbformat.v4.new_output("stream", name="stdout", text="x\n")]
    nbformat.write(nb, tmp_path / "c_open_loop.ipynb")
    (tmp_path / "d_calibration.ipynb").unlink()

    problems = run.stale(tmp_path)
    assert len(problems) == 3, problems
    assert problems[0].startswith("b_energy.ipynb: differs") and "cell 16" in problems[0]
    assert problems[1].startswith("c_open_loop.ipynb: cells [1] carry outputs")
    assert problems[2].startswith("d_calibration.ipynb: missing")

    written = run.sync(tmp_path)
    assert sorted(p.name for p in written) == ["b_energy.ipynb", "c_open_loop.ipynb",
                                               "d_calibration.ipynb"]
    assert run.stale(tmp_path) == []
    b = nbformat.read(tmp_path / "b_energy.ipynb", as_version=4)
    assert b.cells[-1].source == "print('one more cell')"
    assert '"settings (edited)")' in b.cells[-2].source
    assert _cells(b) == _cells(jupytext.read(src))
    c = nbformat.read(tmp_path / "c_open_loop.ipynb", as_version=4)
    assert c.cells[1].outputs == [] and c.cells[1].execution_count is None
    assert (tmp_path / "d_calibration.ipynb").read_bytes() == \
        (NB_DIR / "d_calibration.ipynb").read_bytes()
    assert run.main(["--check"]) == 0                        # the repository's own pairs


# the notebooks run with the slow studies: the calibration one (16 s), the energy one (9 s),
# seed 000's (6 s), the open-loop one (12 s: TOPP-RA, a twin refine, two Exudyn replays); their
# workflows are what tests/calibration, tests/methods, tests/refine, tests/simulation and
# tests/bench (the seed000-abc suite) cover in the default run
RUN = [pytest.param(n, marks=pytest.mark.slow) for n in NAMES]


@pytest.mark.parametrize("name", RUN)
def test_notebook_runs_with_the_small_settings(name, tmp_path):
    run = _runner()
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
