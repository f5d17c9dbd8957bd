"""Compiled (numba) kinematics of a batch: target in the ego frame, TTC and headway in one
pass over (B, T) states (same definitions as ``evaluate.kinematics_arrays``)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sensorgap.jit import njit

F64 = NDArray[np.float64]


@njit(nogil=True)
def cos_sin_near(
    h: float, h0: float, c0: float, s0: float
) -> tuple[float, float]:  # pragma: no cover - compiled
    """cos/sin of angle h, rad, from those of a nearby angle h0 (angle addition with a
    Taylor series of the small difference: error < 1e-18 for |h - h0| < 0.02 rad; sin/cos
    otherwise). Headings change little from one 50 ms step to the next, so this replaces
    most trigonometric calls."""
    d = h - h0
    if abs(d) < 0.02:
        d2 = d * d
        sd = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0)))
        cd = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0))
        return c0 * cd - s0 * sd, s0 * cd + c0 * sd
    return math.cos(h), math.sin(h)


@njit(nogil=True)
def kinematics_kernel(
    ex: F64,
    ey: F64,
    eh: F64,
    ev: F64,
    tx: F64,
    ty: F64,
    th: F64,
    length: float,
    width: float,
    body_half_width: float,
    x_front: float,
    x_rear: float,
    margin: float,
    xr: F64,
    yr: F64,
    headway: F64,
    dist: F64,
    psi: F64,
) -> None:  # pragma: no cover - compiled
    """(B, T) arrays of ego (rear axle) and target (centre) states -> ego-frame target
    position (m), time headway (s, inf unless in path ahead and not overlapping), distance
    (m) and relative heading ``th - eh`` (rad). (The time to collision is the encounter
    geometry's path TTC, ``search.outcome``.)"""
    mid = 0.5 * (x_front + x_rear)
    b, t = ex.shape
    for r in range(b):
        lh = np.nan
        c = 1.0
        s = 0.0
        lt = np.nan
        ct = 1.0
        st = 0.0
        for k in range(t):
            if eh[r, k] != lh:
                c, s = cos_sin_near(eh[r, k], lh, c, s)
                lh = eh[r, k]
            if th[r, k] != lt:
                ct, st = cos_sin_near(th[r, k], lt, ct, st)
                lt = th[r, k]
            dx = tx[r, k] - ex[r, k]
            dy = ty[r, k] - ey[r, k]
            x = c * dx + s * dy
            y = -s * dx + c * dy
            ac = abs(ct * c + st * s)  # |cos(th - eh)|
            as_ = abs(st * c - ct * s)  # |sin(th - eh)|
            half_long = 0.5 * (ac * length + as_ * width)
            half_lat = 0.5 * (as_ * length + ac * width)
            in_path = abs(y) <= body_half_width + half_lat + margin
            front = x >= mid
            gap = x - half_long - x_front
            if in_path and front and gap > 0.0 and ev[r, k] > 0.1:
                headway[r, k] = gap / ev[r, k]
            else:
                headway[r, k] = np.inf
            xr[r, k] = x
            yr[r, k] = y
            dist[r, k] = math.sqrt(x * x + y * y)
            psi[r, k] = th[r, k] - eh[r, k]
