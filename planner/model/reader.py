"""Reading validated values out of TOML tables, with errors that say where and what.

:class:`SpecError` carries the file, the field (dotted path, e.g. ``joint[2].limits.qd``), the
value found and what was expected; :class:`TableReader` is the typed reader the machine specs
(:mod:`planner.model.spec`) and other TOML inputs use.
"""
from __future__ import annotations

import math
from typing import Any

from planner.units import parse_angle

__all__ = ["SpecError", "TableReader", "as_float", "read_toml_text"]


class SpecError(ValueError):
    """A malformed or inconsistent machine specification."""

    def __init__(self, file: str, field: str, value: Any, expected: str):
        self.file, self.field, self.value, self.expected = file, field, value, expected
        super().__init__(f"{file}: field '{field}' = {value!r}: {expected}")


def read_toml_text(path) -> str:
    """The text of a TOML input file: UTF-8, a leading byte-order mark dropped (editors on
    Windows write one; TOML itself does not allow it). A file that cannot be read or is not
    UTF-8 raises :class:`SpecError` naming the file, the line and column and the byte."""
    try:
        raw = open(path, "rb").read()
    except OSError as e:
        raise SpecError(str(path), "<file>", None, f"cannot read file: {e.strerror}") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        col = e.start - (raw.rfind(b"\n", 0, e.start) + 1) + 1
        raise SpecError(str(path), "<encoding>", raw[e.start:e.start + 1],
                        f"line {line}, column {col}: not UTF-8 text (Latin-1 or a Windows "
                        "code page?); allowed: a UTF-8 (or ASCII) TOML file") from None


class TableReader:
    """Reads typed fields out of a TOML table (numbers, angles, vectors, strings, sub-tables,
    allowed keys) and raises :class:`SpecError` naming the file, the field, the value and what
    was expected."""

    def __init__(self, file: str):
        self.file = file

    def fail(self, fld: str, value: Any, expected: str):
        raise SpecError(self.file, fld, value, expected)

    def table(self, parent: dict, key: str, where: str, required=True) -> dict | None:
        if key not in parent:
            if required:
                self.fail(f"{where}{key}", None, "missing table")
            return None
        v = parent[key]
        if not isinstance(v, dict):
            self.fail(f"{where}{key}", v, "expected a table")
        return v

    def keys(self, tbl: dict, allowed: set[str], where: str):
        for k in tbl:
            if k not in allowed:
                self.fail(f"{where}{k}", tbl[k], f"unknown key; allowed: {', '.join(sorted(allowed))}")

    def num(self, tbl: dict, key: str, where: str, default=None, lo=None, hi=None,
            lo_open=False, angle=False) -> float:
        fld = f"{where}{key}"
        if key not in tbl:
            if default is None:
                self.fail(fld, None, "missing (required number)")
            return default
        raw = tbl[key]
        try:
            v = parse_angle(raw) if angle else as_float(raw)
        except ValueError:
            self.fail(fld, raw, "expected a number" + (" or an angle like '30deg'" if angle else ""))
        if not math.isfinite(v):
            self.fail(fld, raw, "expected a finite number")
        if lo is not None and (v <= lo if lo_open else v < lo):
            self.fail(fld, raw, f"must be {'>' if lo_open else '>='} {lo}")
        if hi is not None and v > hi:
            self.fail(fld, raw, f"must be <= {hi}")
        return v

    def vec(self, tbl: dict, key: str, where: str, n: int, default=None, angle=False):
        fld = f"{where}{key}"
        if key not in tbl:
            if default is None:
                self.fail(fld, None, f"missing (required list of {n} numbers)")
            return default
        raw = tbl[key]
        if not isinstance(raw, list) or len(raw) != n:
            self.fail(fld, raw, f"expected a list of {n} numbers")
        out = []
        for x in raw:
            try:
                v = parse_angle(x) if angle else as_float(x)
            except ValueError:
                self.fail(fld, raw, f"expected a list of {n} numbers")
            if not math.isfinite(v):
                self.fail(fld, raw, "expected finite numbers")
            out.append(v)
        return tuple(out)

    def text(self, tbl: dict, key: str, where: str, default=None, choices=None) -> str:
        fld = f"{where}{key}"
        if key not in tbl:
            if default is None:
                self.fail(fld, None, "missing (required string)")
            return default
        v = tbl[key]
        if not isinstance(v, str):
            self.fail(fld, v, "expected a string")
        if choices is not None and v not in choices:
            self.fail(fld, v, f"allowed: {', '.join(choices)}")
        return v


def as_float(x: Any) -> float:
    """A TOML number as float (booleans are not numbers); ValueError otherwise."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ValueError
    return float(x)
