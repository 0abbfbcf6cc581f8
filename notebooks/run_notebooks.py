"""Execute the notebook studies with nbclient into an output folder (never in place).

    python notebooks/run_notebooks.py [--out build/notebooks] [--small] [NAME.ipynb ...]

Each notebook is copied to ``--out`` and executed there with the ``python3`` kernel (the
interpreter running this script, see :func:`kernel_name`); its figures go to
``<out>/<notebook>_files/``. ``--small`` sets ``CRANE_NB_SMALL=1`` (the test suite's coarse
settings); without it the notebooks run their full settings (``make notebooks``). Prints the
run time of every notebook; exits non-zero when one fails.
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


def notebooks() -> list[Path]:
    """The studies, in order (a_…, b_…, …)."""
    return sorted(HERE.glob("[a-z]_*.ipynb"))


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
    env = dict(os.environ, CRANE_NB_SMALL="1" if small else "0",
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
    ap.add_argument("names", nargs="*", help="notebooks to run (default: all)")
    args = ap.parse_args(argv)
    todo = [HERE / n for n in args.names] if args.names else notebooks()
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
