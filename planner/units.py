"""Units: angle strings and other human-friendly input -> SI.

Everything inside the package is SI (m, rad, s, Pa, m³/s, J). Human input may write angles as
``"30deg"`` / ``"30°"`` / ``"0.5rad"``; a plain number is already SI.
"""
from __future__ import annotations

import math
from typing import Any

__all__ = ["parse_angle", "parse_point", "DEG"]

DEG = math.pi / 180.0


def parse_angle(value: Any) -> float:
    """A number (SI: rad) or a string like ``"30deg"`` / ``"0.5rad"`` -> radians."""
    if isinstance(value, bool):
        raise ValueError("expected a number or an angle string like '30deg'")
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str):
        s = value.strip().lower()
        for suffix, scale in (("deg", DEG), ("°", DEG), ("rad", 1.0)):
            if s.endswith(suffix):
                return float(s[: -len(suffix)].strip()) * scale
        return float(s)
    raise ValueError("expected a number or an angle string like '30deg'")


def parse_point(text: str) -> tuple[float, float, float]:
    """A tip point ``"r,z[,slew]"`` -> (r [m], z [m], slew [rad]); slew may be written ``30deg``
    and defaults to 0. ValueError (quoting ``text``) for anything but 2 or 3 finite numbers."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) not in (2, 3):
        raise ValueError(f"expected r,z[,slew], got {text!r}")
    try:
        r, z = float(parts[0]), float(parts[1])
        s = parse_angle(parts[2]) if len(parts) == 3 else 0.0
    except ValueError:
        raise ValueError(f"expected numbers in r,z[,slew], got {text!r}") from None
    if not all(math.isfinite(v) for v in (r, z, s)):
        raise ValueError(f"non-finite value in {text!r}")
    return r, z, s
