"""Reading the benchmark's result rows (one dict per suite, move and method; the layout of
``bench.json``, written by :mod:`planner.bench.run`), shared by the report and the figures."""
from __future__ import annotations

__all__ = ["by_move", "succeeded"]


def by_move(sres: dict) -> dict:
    """{move id: {method: row}} of one suite's result, in the rows' order."""
    out = {}
    for r in sres["rows"]:
        out.setdefault(r["move"], {})[r["method"]] = r
    return out


def succeeded(row) -> bool:
    """True when ``row`` exists and counts as a success (status ok, within the limits, clear,
    one motion)."""
    return row is not None and bool(row.get("success"))
