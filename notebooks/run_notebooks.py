"""Keep the notebook studies in step with their sources, and execute them.

    python notebooks/run_notebooks.py [--out build/notebooks] [--small] [NAME ...]
    python notebooks/run_notebooks.py --sync     # rewrite every .ipynb from its .py
    python notebooks/run_notebooks.py --check    # exit 1 when an .ipynb is stale

Each study is a jupytext percent-format source ``notebooks/<name>.py`` (the file a reviewer
reads and edits) paired with ``notebooks/<name>.ipynb``, committed without outputs.
``--sync`` regenerates the .ipynb from the .py with jupytext (no outputs, cell ids
``<name>-NN``, so the file is a pure function of the source); ``jupytext --sync
notebooks/*.py`` does the same for existing cells. ``--check`` compares without writing: the
.ipynb must hold the .py's cells (type and source) and no outputs.

Running: each notebook is copied to ``--out`` and executed there with nbclient and the
``python3`` kernel (the interpreter running this script, see :func:`kernel_name`); its figures
go to ``<out>/<notebook>_files/``. ``--small`` sets ``CRANE_NB_SMALL=1`` (the test suite's
coarse settings); without it the notebooks run their full settings (``make notebooks``). Prints
the run time of every notebook; exits non-zero when one fails.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
KERNEL = "python3"


def notebooks(folder: Path = HERE) -> list[Path]:
    """The studies' notebooks in ``folder``, in order (a_…, b_…, …)."""
    return sorted(Path(folder).glob("[a-z]_*.ipynb"))


def sources(folder: Path = HERE) -> list[Path]:
    """The studies' jupytext sources in ``folder``, in order (a_….py, b_….py, …)."""
    return sorted(Path(folder).glob("[a-z]_*.py"))


def notebook_text(src: Path) -> str:
    """The .ipynb text jupytext makes of the percent-format source ``src``: the same cells,
    no outputs, no execution counts, cell ids ``<name>-NN`` (name cut to 40 characters, NN the
    cell index), metadata from the source's header."""
    import jupytext
    import nbformat
    src = Path(src)
    nb = jupytext.read(src)
    for i, cell in enumerate(nb.cells):
        cell.id = f"{src.stem[:40]}-{i:02d}"
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    nbformat.validate(nb)
    text = jupytext.writes(nb, fmt="ipynb")
    return text if text.endswith("\n") else text + "\n"


def stale(folder: Path = HERE) -> list[str]:
    """What is out of step in ``folder``: one line per notebook whose .ipynb is missing, lacks
    its .py, differs from its .py in a cell's type or source, or carries outputs. Empty when
    every pair is in step. Cell ids and metadata are not compared."""
    import jupytext
    import nbformat
    folder = Path(folder)
    problems = []
    for nb_path in notebooks(folder):
        if not nb_path.with_suffix(".py").exists():
            problems.append(f"{nb_path.name}: no source {nb_path.stem}.py")
    for src in sources(folder):
        dst = src.with_suffix(".ipynb")
        if not dst.exists():
            problems.append(f"{dst.name}: missing (run --sync)")
            continue
        want = [(c.cell_type, c.source) for c in jupytext.read(src).cells]
        nb = nbformat.read(dst, as_version=4)
        have = [(c.cell_type, c.source) for c in nb.cells]
        if have != want:
            first = next((i for i, (h, w) in enumerate(zip(have, want)) if h != w),
                         min(len(have), len(want)))
            problems.append(f"{dst.name}: differs from {src.name} from cell {first} on "
                            f"({len(have)} cells, the source has {len(want)}; run --sync)")
        run = [i for i, c in enumerate(nb.cells) if c.cell_type == "code"
               and (c.get("outputs") or c.get("execution_count") is not None)]
        if run:
            problems.append(f"{dst.name}: cells {run} carry outputs or execution counts "
                            "(commit it without outputs: run --sync)")
    return problems


def sync(folder: Path = HERE) -> list[Path]:
    """Rewrite every .ipynb in ``folder`` from its .py (:func:`notebook_text`); returns the
    files that changed."""
    written = []
    for src in sources(folder):
        dst = src.with_suffix(".ipynb")
        text = notebook_text(src)
        if not dst.exists() or dst.read_text(encoding="utf-8") != text:
            dst.write_text(text, encoding="utf-8")
            written.append(dst)
    return written


def kernel_name() -> str:
    """``python3`` — the kernelspec ipykernel installs into the environment
    (<prefix>/share/jupyter/kernels/python3), or, when none is installed, ipykernel's built-in
    one. Its command ``python -m ipykernel_launcher`` is started with ``sys.executable`` by
    jupyter_client, i.e. this venv's interpreter. If some other ``python3`` kernelspec would
    win (e.g. a user-level one pointing at another interpreter), a private kernelspec for this
    interpreter is written to a temporary JUPYTER_PATH entry first."""
    from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel
    try:
        spec = KernelSpecManager().get_kernel_spec(KERNEL)
        exe = spec.argv[0] if spec.argv else ""
    except NoSuchKernel:
        exe = ""
    own = {"python", "python3", f"python{sys.version_info[0]}.{sys.version_info[1]}",
           sys.executable}
    if exe in own or (exe and Path(exe).resolve() == Path(sys.executable).resolve()):
        return KERNEL
    import tempfile

    from ipykernel.kernelspec import install
    prefix = Path(tempfile.mkdtemp(prefix="crane-nb-kernel-"))
    install(kernel_name=KERNEL, prefix=str(prefix))
    os.environ["JUPYTER_PATH"] = os.pathsep.join(
        [str(prefix / "share" / "jupyter")] + [p for p in
                                                os.environ.get("JUPYTER_PATH", "").split(
                                                    os.pathsep) if p])
    return KERNEL


def execute(src: Path, out_dir: Path, *, small: bool, timeout: int = 1800):
    """Copy ``src`` into ``out_dir``, execute the copy there (cwd = ``out_dir``) and save it
    with its outputs. Returns (executed notebook, seconds). Raises nbclient's
    CellExecutionError when a cell fails (the partly executed copy is still saved)."""
    import nbformat
    from nbclient import NotebookClient
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    dst = out_dir / src.name
    if dst.resolve() != Path(src).resolve():
        shutil.copyfile(src, dst)
    nb = nbformat.read(dst, as_version=4)
    # the kernel runs in out_dir: put this folder on its path for the shared nbtools module
    path = os.pathsep.join(p for p in (str(HERE), os.environ.get("PYTHONPATH", "")) if p)
    env = dict(os.environ, CRANE_NB_SMALL="1" if small else "0", PYTHONPATH=path,
               CRANE_NB_OUT=str(out_dir / f"{dst.stem}_files"))
    client = NotebookClient(nb, timeout=timeout, kernel_name=kernel_name(),
                            resources={"metadata": {"path": str(out_dir)}})
    t0 = time.perf_counter()
    try:
        client.execute(env=env)
    finally:
        nbformat.write(nb, dst)
    return nb, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="build/notebooks", help="output folder (build/notebooks)")
    ap.add_argument("--small", action="store_true", help="the tests' small settings")
    ap.add_argument("--timeout", type=int, default=1800, help="per-cell timeout [s] (1800)")
    ap.add_argument("--sync", action="store_true",
                    help="rewrite every .ipynb from its jupytext .py source, run nothing")
    ap.add_argument("--check", action="store_true",
                    help="exit 1 when an .ipynb is out of step with its .py, run nothing")
    ap.add_argument("names", nargs="*",
                    help="notebooks to run, as NAME, NAME.ipynb or NAME.py (default: all)")
    args = ap.parse_args(argv)
    if args.sync:
        for path in sync():
            print(f"wrote {path}")
        return 0
    problems = stale()
    if args.check:
        print("\n".join(problems) if problems else "notebooks in step with their sources")
        return 1 if problems else 0
    for p in problems:
        print(f"warning: {p}", flush=True)
    todo = ([HERE / f"{Path(n).stem}.ipynb" for n in args.names] if args.names
            else notebooks())
    unknown = [p.stem for p in todo if not p.exists()]
    if unknown:
        ap.error(f"names: no notebook {', '.join(unknown)} in {HERE}; "
                 f"allowed: {', '.join(p.stem for p in notebooks())}")
    failed = []
    total = 0.0
    for nb_path in todo:
        print(f"{nb_path.name}: running ({'small' if args.small else 'full'} settings) ...",
              flush=True)
        try:
            _, dt = execute(nb_path, Path(args.out), small=args.small, timeout=args.timeout)
        except Exception as e:  # report and go on with the others
            failed.append(nb_path.name)
            print(f"{nb_path.name}: FAILED: {str(e)[-2000:]}", flush=True)
            continue
        total += dt
        print(f"{nb_path.name}: {dt:.1f} s -> {Path(args.out) / nb_path.name}", flush=True)
    print(f"{len(todo) - len(failed)} of {len(todo)} notebooks executed in {total:.1f} s"
          + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
