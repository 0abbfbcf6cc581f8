"""Helpers the notebook studies share: settings, output folder, inline figures, tables.

The studies import this module by name: Jupyter started in ``notebooks/`` finds it in the
working directory, and ``run_notebooks.py`` puts this folder on the kernel's ``PYTHONPATH``.
"""
from __future__ import annotations

import io
import os
import tempfile
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Image, Markdown, display

__all__ = ["study", "show", "show_file", "table", "fmt", "span"]


def study(small_settings: dict, full_settings: dict):
    """(small, settings, output folder, start time) of a study. ``CRANE_NB_SMALL=1`` (the test
    suite) picks the small settings that run in seconds, otherwise the full study (``make
    notebooks``); ``CRANE_NB_OUT`` names the folder figure files go to (default: a new
    temporary folder). Prints the settings in use."""
    small = os.environ.get("CRANE_NB_SMALL", "0") == "1"
    settings = small_settings if small else full_settings
    out = Path(os.environ.get("CRANE_NB_OUT") or tempfile.mkdtemp(prefix="crane-nb-"))
    out.mkdir(parents=True, exist_ok=True)
    print(f"settings: {'small' if small else 'full'} {settings}")
    return small, settings, out, time.perf_counter()


def show(fig):
    """Show a figure inline as a PNG (independent of the matplotlib backend)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    display(Image(data=buf.getvalue()))


def show_file(path):
    """Show a PNG file inline."""
    display(Image(filename=str(path)))


def table(header, rows):
    """A markdown table from a header and rows of cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    display(Markdown("\n".join(lines)))


def fmt(x, spec=".3f", none="—"):
    """A number formatted with ``spec``; ``none`` for None or non-finite values."""
    return none if x is None or not np.isfinite(x) else format(x, spec)


def span(vals, scale=1.0, spec=".1f", unit=""):
    """'lo to hi unit' of scaled values (one number when they print alike)."""
    lo, hi = format(scale * min(vals), spec), format(scale * max(vals), spec)
    return f"{lo}{unit}" if lo == hi else f"{lo} to {hi}{unit}"
