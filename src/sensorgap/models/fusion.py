"""Fusion of overlapping sensors, Ponn et al. 2019 eq. 11 (after Senouci et al. 2012):
``p = 1 - prod_i (1 - p_i)``, assuming independent detections.

Computed in the log domain: ``p = -expm1(sum_i log1p(-p_i))`` keeps full precision for
tiny p_i (where ``1 - (1 - p)`` loses digits) and for products close to 1; a p_i of exactly
1 makes the fused value exactly 1 without evaluating log(0).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


class FusionAccumulator:
    """Streams per-sensor Pd arrays (same shape) into the fused Pd of eq. 11."""

    def __init__(self, shape: tuple[int, ...]) -> None:
        self.log_miss = np.zeros(shape, dtype=np.float64)  # sum of log(1 - p_i)
        self.certain = np.zeros(shape, dtype=bool)  # some p_i == 1

    def add(self, pd: F64, index: NDArray[np.intp] | None = None) -> None:
        """Add one sensor's Pd, for all cells or only at flat, unique ``index``."""
        pd = np.asarray(pd, dtype=np.float64)
        one = pd >= 1.0
        mid = (pd > 0.0) & ~one
        flat_log = self.log_miss.reshape(-1)
        flat_cert = self.certain.reshape(-1)
        if index is None:
            index = np.arange(flat_log.size)
        flat_cert[index[one]] = True
        flat_log[index[mid]] += np.log1p(-pd[mid])

    def result(self) -> F64:
        """The fused detection probability, in [0, 1] (never -0.0)."""
        out = -np.expm1(self.log_miss)
        out[self.certain] = 1.0
        out += 0.0  # turns -0.0 (from expm1(0)) into +0.0
        return out


def fuse(pds: Iterable[F64] | F64) -> F64:
    """Fused Pd (eq. 11) of per-sensor Pd arrays; a 2-D array is (sensors, points).

    An empty set of sensors gives 0 (nothing can detect).
    """
    rows = list(pds)
    if not rows:
        raise ValueError("fuse() needs at least one Pd array (use zeros for no sensors)")
    acc = FusionAccumulator(np.shape(rows[0]))
    for p in rows:
        acc.add(p)
    return acc.result()
