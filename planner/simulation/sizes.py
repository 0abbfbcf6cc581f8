"""How large a simulated recording may be: ``simulate --rate`` within a logger's rates and a
number of rows that stays within about 1 GB of memory (a rate of 1 MHz used to write a 790 MB
CSV with 6.1 GB of memory), refused before the replay like the control laws' step count."""
from __future__ import annotations

import math

# measured: 0.46 million rows of s100f, 0.8 GB peak, 15 s
MAX_RATE_HZ = 10_000.0
MAX_SAMPLES = 500_000


def check_rate(rate: float, duration: float) -> int:
    """The number of samples of a recording of ``duration`` [s] at ``rate`` [Hz]; ValueError
    naming `rate` when the rate is outside 1 ... :data:`MAX_RATE_HZ` Hz or the recording
    would have more than :data:`MAX_SAMPLES` rows."""
    if not (math.isfinite(rate) and 1.0 <= rate <= MAX_RATE_HZ):
        raise ValueError(f"`rate` = {rate:g}: allowed 1 ... {MAX_RATE_HZ:g} Hz (loggers: "
                         "20-500 Hz)")
    n = int(math.ceil(duration * rate)) + 1
    if n > MAX_SAMPLES:
        raise ValueError(f"`rate` = {rate:g}: {n} samples over {duration:g} s; allowed at most "
                         f"{MAX_SAMPLES} (`rate` <= {MAX_SAMPLES / max(duration, 1e-9):.4g} Hz "
                         "for this trajectory)")
    return n
