"""dB-domain helpers and the numeric limits every output respects.

Values in the sensor equations span > 35 orders of magnitude (kT ~ 4e-21 J, the direct sun
on a camera ~ 1e13 electrons), so terms are added in dB in float64 and never exponentiated
while large.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

#: Reported SNRs are clipped to this range, dB. Below -300 dB or above +300 dB every ROC
#: is saturated (Pd = its floor or exactly 1), so the clip changes no probability.
SNR_FLOOR_DB = -300.0
SNR_CEIL_DB = 300.0
#: SNR reported for a point outside a sensor's field of view or range, dB.
SNR_NOT_IN_VIEW_DB = SNR_FLOOR_DB

LN10_OVER_10 = math.log(10.0) / 10.0  #: converts dB to nepers-of-power: ln(x) = dB * this


def db(x: float) -> float:
    """10 log10(x) for a positive finite scalar; raises ``ValueError`` otherwise."""
    if not (x > 0.0 and math.isfinite(x)):
        raise ValueError(f"dB of a non-positive or non-finite value: {x!r}")
    return 10.0 * math.log10(x)


def clip_snr_db(snr_db: NDArray[np.float64]) -> NDArray[np.float64]:
    """Clip SNR (dB) to [SNR_FLOOR_DB, SNR_CEIL_DB] in place and return it."""
    return np.clip(snr_db, SNR_FLOOR_DB, SNR_CEIL_DB, out=snr_db)
