"""A twin calibration's result (:class:`TwinFitResult`) and its parameters' 95 % intervals
from the Gauss–Newton standard deviations (:func:`intervals`; the covariance itself is
:class:`planner.calibration.twin_fit.TwinFit`'s, its module doc says how it is scaled)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["TwinFitResult", "intervals", "UNIDENTIFIED"]

UNIDENTIFIED = 1.0      # scaled standard deviation above which a parameter is not identified
_Z95 = 1.959964


def intervals(params, z, sd):
    """(values, nominal, interval, identified, sd_scaled, units), each name -> value, of the
    fitted scaled parameters ``z`` with scaled standard deviations ``sd``: a log-scaled
    parameter's interval is a factor, a linear one ± its typical size."""
    values, nominal, interval, ident, sds, units = {}, {}, {}, {}, {}, {}
    for p, zi, si in zip(params, z, sd):
        v = p.to_value(zi)
        values[p.name], nominal[p.name], units[p.name] = v, p.nominal, p.unit
        if p.log:
            lo, hi = v * math.exp(-_Z95 * si), v * math.exp(_Z95 * si)
        else:
            lo, hi = max(v - _Z95 * si * p.scale, 0.0), v + _Z95 * si * p.scale
        interval[p.name] = (float(lo), float(hi))
        ident[p.name] = bool(si <= UNIDENTIFIED)
        sds[p.name] = float(si)
    return values, nominal, interval, ident, sds, units


@dataclass
class TwinFitResult:
    """A calibration: ``values`` (name -> fitted value), ``nominal`` (the spec's),
    ``interval`` (name -> 95 % (lo, hi)), ``identified`` (name -> bool), ``sd_scaled``,
    the misfit before and after (RMS in noise units, positions and pressures apart),
    ``runs`` (twin runs), ``runtime_s``, ``status`` of the optimiser, the ``dynamics`` and
    ``deadband`` of the calibrated machine, ``segments`` and ``samples`` used."""
    values: dict
    nominal: dict
    interval: dict
    identified: dict
    sd_scaled: dict
    rms_before: dict
    rms_after: dict
    runs: int
    runtime_s: float
    status: str
    message: str
    dynamics: object = None
    deadband: np.ndarray | None = None
    segments: int = 0
    samples: int = 0
    units: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return dict(status=self.status, message=self.message, runtime_s=self.runtime_s,
                    twin_runs=self.runs, segments=self.segments, samples=self.samples,
                    rms_before=self.rms_before, rms_after=self.rms_after,
                    parameters={k: dict(value=self.values[k], nominal=self.nominal[k],
                                        unit=self.units.get(k, ""),
                                        interval95=list(self.interval[k]),
                                        identified=self.identified[k],
                                        sd_scaled=self.sd_scaled[k]) for k in self.values})
