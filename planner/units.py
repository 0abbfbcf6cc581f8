"""Units: angle strings and other human-friendly input -> SI.

Everything inside the package is SI (m, rad, s, Pa, m³/s, J). Human input may write angles as
``"30deg"`` / ``"30°"`` / ``"0.5rad"``; a plain number is already SI.
"""
from __future__ import annotations

import math
from typing import Any

__all__ = ["parse_angle", "DEG"]

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
