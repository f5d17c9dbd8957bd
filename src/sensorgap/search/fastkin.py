"""Compiled (numba) kinematics of a batch: target in the ego frame, TTC and headway in one
pass over (B, T) states (same definitions as ``evaluate.kinematics_arrays``)."""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


@numba.njit(cache=True, nogil=True)
def kinematics_kernel(ex: F64, ey: F64, eh: F64, ev: F64, tx: F64, ty: F64, th: F64,
                      tv: F64, length: float, width: float, body_half_width: float,
                      x_front: float, x_rear: float, margin: float,
                      xr: F64, yr: F64, ttc: F64, headway: F64,
                      dist: F64) -> None:  # pragma: no cover - compiled
    """Flat arrays of ego (rear axle) and target (centre) states -> ego-frame target
    position (m), TTC (s, inf: not in path or not closing, 0: overlapping), time headway
    (s, inf unless in path ahead) and distance (m)."""
    mid = 0.5 * (x_front + x_rear)
    for k in range(ex.size):
        c = math.cos(eh[k])
        s = math.sin(eh[k])
        ct = math.cos(th[k])
        st = math.sin(th[k])
        dx = tx[k] - ex[k]
        dy = ty[k] - ey[k]
        x = c * dx + s * dy
        y = -s * dx + c * dy
        dvx = tv[k] * ct - ev[k] * c
        dvy = tv[k] * st - ev[k] * s
        vxr = c * dvx + s * dvy
        ac = abs(ct * c + st * s)  # |cos(th - eh)|
        as_ = abs(st * c - ct * s)  # |sin(th - eh)|
        half_long = 0.5 * (ac * length + as_ * width)
        half_lat = 0.5 * (as_ * length + ac * width)
        in_path = abs(y) <= body_half_width + half_lat + margin
        front = x >= mid
        if front:
            gap = x - half_long - x_front
            closing = -vxr
        else:
            gap = x_rear - x - half_long
            closing = vxr
        hit = in_path and gap <= 0.0
        if hit:
            ttc[k] = 0.0
        elif in_path and closing > 1e-9:
            ttc[k] = gap / closing
        else:
            ttc[k] = np.inf
        if in_path and front and not hit and ev[k] > 0.1:
            headway[k] = gap / ev[k]
        else:
            headway[k] = np.inf
        xr[k] = x
        yr[k] = y
        dist[k] = math.sqrt(x * x + y * y)
