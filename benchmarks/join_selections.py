"""One selection library from the parts of a refinement run (issue 28's 100-entry loop).

``bench_refine.py --work DIR`` keeps each part's selection (``DIR/sel-TAG.h5``: the chosen
entries, their nominal commands and their refinement on the spec's twin). The loop of
``bench_calibrate_loop.py --library`` takes one such library; this joins several parts into
one, entries in id order (so that a move's energy and time entries sit side by side and the
first N of the joined library mix both objectives), each entry's refinement copied unchanged.
The parts must come from libraries of the same spec. ``--library LIB --every K --offsets
O,O`` names the entries to take — those ``bench_refine.py --order id --every K --offset O``
selects in LIB, for each O — and each is taken from the first part that holds it (an entry
no part holds is an error); without it, every entry of every part.

    python benchmarks/join_selections.py --out SEL.h5 PART.h5 [PART.h5 …]
                                         [--library LIB --every K --offsets O,O]
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_refine import _spec, copy_entry  # noqa: E402

from planner.library.refined import GROUP, read_refined  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402


def wanted(library: Path, every: int, offsets: list[int]) -> list[str]:
    """The ids bench_refine's ``--order id --every K --offset O`` selects, over ``offsets``."""
    with LibraryStore.open(library) as db:
        ok = sorted(r["id"] for r in db.index_rows() if r["status"] == "ok")
    return sorted({i for o in offsets for i in ok[o::every]})


def join(parts: list[Path], out: Path, only: list[str] | None = None) -> list[str]:
    """Write ``out`` holding the entries ``only`` (default: every entry) of ``parts``, ids
    sorted; returns the ids."""
    where, spec_toml = {}, None
    for p in parts:
        with LibraryStore.open(p) as db:
            if spec_toml is None:
                spec_toml = db.spec_toml
            elif db.spec_toml != spec_toml:
                sys.exit(f"{p}: another spec than {parts[0]}'s; allowed: parts of one library")
            for r in db.index_rows():
                if r["id"] in where or (only is not None and r["id"] not in only):
                    continue
                if r["status"] != "ok" or read_refined(db, r["id"]) is None:
                    sys.exit(f"{p}: entry {r['id']!r} has no refinement; refine the part first")
                where[r["id"]] = p
    ids = sorted(where)
    lost = sorted(set(only or ()) - set(where))
    if lost:
        sys.exit(f"entry {lost[0]!r} (and {len(lost) - 1} more) is in none of the parts")
    part = out.with_name(out.name + ".part")
    with LibraryStore.open(parts[0]) as first:
        spec = _spec(first)
    with LibraryStore.create(part, spec, overwrite=True) as dst:
        for i in ids:
            with LibraryStore.open(where[i]) as src:
                copy_entry(src, dst, i)
                g = dst.group(i)
                g.copy(src.group(i)[GROUP], g, name=GROUP)
                dst.commit()
    os.replace(part, out)
    return ids


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("parts", nargs="+", type=Path, help="bench_refine selections (sel-*.h5)")
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--library", type=Path, help="the library the parts were selected from")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--offsets", default="0", help="comma-separated offsets (0)")
    a = ap.parse_args()
    only = wanted(a.library, a.every, [int(o) for o in a.offsets.split(",")]) \
        if a.library else None
    ids = join(a.parts, a.out, only)
    print(f"{a.out}: {len(ids)} entries from {len(a.parts)} parts")


if __name__ == "__main__":
    main()
