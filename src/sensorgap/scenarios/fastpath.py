"""Compiled (numba) loops of batch trajectory generation: uniform-table interpolation,
states from sampled paths and the feasibility extremes, one pass over (B, T) each.

Definitions (uniform time step ``dt``): velocity by central differences inside,
one-sided differences at both ends (as ``numpy.gradient`` with ``edge_order=1``);
speed ``|v|``; heading ``atan2(vy, vx)`` where the object moves (speed > 1e-6 m/s), else the
fallback heading, taken on the fallback's branch (within pi of it) and unwrapped along time.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sensorgap.jit import njit

F64 = NDArray[np.float64]

#: Speed below which an object counts as standing still (heading from the fallback), m/s.
STILL_M_S = 1e-6


@njit(nogil=True, inline="always")
def _table_pose(
    s: float, step: float, last: int, tx: F64, ty: F64, th: F64
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """Linear interpolation of a table sampled every ``step`` from 0 (samples 0..``last``)
    at ``s`` (clipped to the table)."""
    f = s / step
    if not f > 0.0:
        f = 0.0
    if f >= last:
        f = float(last)
    i = min(int(f), last - 1)
    a = f - i
    return (
        tx[i] + a * (tx[i + 1] - tx[i]),
        ty[i] + a * (ty[i + 1] - ty[i]),
        th[i] + a * (th[i + 1] - th[i]),
    )


@njit(nogil=True)
def table_poses(
    s: F64, step: float, n: int, tx: F64, ty: F64, th: F64, ox: F64, oy: F64, oh: F64
) -> None:  # pragma: no cover - compiled
    """Linear interpolation of a table sampled every ``step`` from 0 (``n`` samples) at
    flat ``s`` (clipped to the table)."""
    for k in range(s.size):
        ox[k], oy[k], oh[k] = _table_pose(s[k], step, n - 1, tx, ty, th)


@njit(nogil=True, inline="always")
def _velocity(
    x: F64, y: F64, i: int, k: int, inv_dt: float, inv_2dt: float
) -> tuple[float, float]:  # pragma: no cover
    """Velocity (m/s) of row ``i`` at step ``k``: central differences inside, one-sided at
    both ends (``inv_dt``, ``inv_2dt``: 1 / dt and 1 / (2 dt), 1/s; multiplying by them
    instead of dividing by dt differs in the last bit and takes a third less time)."""
    t = x.shape[1]
    if k == 0:
        return (x[i, 1] - x[i, 0]) * inv_dt, (y[i, 1] - y[i, 0]) * inv_dt
    if k == t - 1:
        return (x[i, k] - x[i, k - 1]) * inv_dt, (y[i, k] - y[i, k - 1]) * inv_dt
    return (x[i, k + 1] - x[i, k - 1]) * inv_2dt, (y[i, k + 1] - y[i, k - 1]) * inv_2dt


@njit(nogil=True)
def path_states(
    x: F64, y: F64, fb: F64, dt: float, heading: F64, speed: F64
) -> None:  # pragma: no cover - compiled
    """(B, T) positions (m) and fallback headings (rad) -> heading and speed."""
    b, t = x.shape
    two_pi = 2.0 * math.pi
    inv_dt, inv_2dt = 1.0 / dt, 1.0 / (2.0 * dt)
    for i in range(b):
        prev = 0.0
        for k in range(t):
            vx, vy = _velocity(x, y, i, k, inv_dt, inv_2dt)
            v = math.sqrt(vx * vx + vy * vy)
            speed[i, k] = v
            f = fb[i, k]
            h = math.atan2(vy, vx) if v > STILL_M_S else f
            d = h - f  # onto the fallback's branch: (-pi, pi] around f
            if d > math.pi or d <= -math.pi:
                d = d - two_pi * math.floor((d + math.pi) / two_pi)
            h = f + d
            if k > 0:  # unwrap along time
                j = h - prev
                if j > math.pi or j < -math.pi:
                    h = h - two_pi * math.floor((j + math.pi) / two_pi)
            heading[i, k] = h
            prev = h


@njit(nogil=True, inline="always")
def _row_extremes(
    heading: F64, speed: F64, i: int, inv_dt: float, inv_2dt: float
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """Row ``i``'s max speed (m/s), max |longitudinal acceleration| and max |lateral
    acceleration| (speed x yaw rate), m/s2; differences as in ``path_states``."""
    t = speed.shape[1]
    vmax = 0.0
    amax = 0.0
    lmax = 0.0
    for k in range(t):
        if k == 0:
            j0, j1, f = 0, 1, inv_dt
        elif k == t - 1:
            j0, j1, f = k - 1, k, inv_dt
        else:
            j0, j1, f = k - 1, k + 1, inv_2dt
        a = abs((speed[i, j1] - speed[i, j0]) * f)
        yr = (heading[i, j1] - heading[i, j0]) * f
        lat = abs(speed[i, k] * yr)
        vmax = max(vmax, speed[i, k])
        amax = max(amax, a)
        lmax = max(lmax, lat)
    return vmax, amax, lmax


@njit(nogil=True)
def track_extremes(
    heading: F64, speed: F64, dt: float, out: F64
) -> None:  # pragma: no cover - compiled
    """Per row: max speed (m/s), max |longitudinal acceleration| and max |lateral
    acceleration| (speed x yaw rate), m/s2; differences as in ``path_states``."""
    inv_dt, inv_2dt = 1.0 / dt, 1.0 / (2.0 * dt)
    for i in range(speed.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = _row_extremes(heading, speed, i, inv_dt, inv_2dt)


@njit(nogil=True)
def lane_tracks(
    s: F64,
    step: float,
    n: int,
    tx: F64,
    ty: F64,
    th: F64,
    turn: float,
    dt: float,
    x: F64,
    y: F64,
    heading: F64,
    speed: F64,
    ext: F64,
) -> None:  # pragma: no cover - compiled
    """Objects following a lane, row by row in one pass (the row stays in the cache):
    positions and the lane heading plus ``turn`` (rad: pi against the lane's direction)
    from the lane table at (B, T) road ``s`` (as ``table_poses``), speeds (as
    ``path_states``) and the feasibility extremes (as ``track_extremes``)."""
    b, t = s.shape
    inv_dt, inv_2dt = 1.0 / dt, 1.0 / (2.0 * dt)
    for i in range(b):
        for k in range(t):
            x[i, k], y[i, k], hk = _table_pose(s[i, k], step, n - 1, tx, ty, th)
            heading[i, k] = hk + turn if turn != 0.0 else hk
        for k in range(t):
            vx, vy = _velocity(x, y, i, k, inv_dt, inv_2dt)
            speed[i, k] = math.sqrt(vx * vx + vy * vy)
        ext[i, 0], ext[i, 1], ext[i, 2] = _row_extremes(heading, speed, i, inv_dt, inv_2dt)


@njit(nogil=True)
def affine_progress(
    s0: F64, sign: float, offset: F64, speed: F64, t: F64, out: F64
) -> None:  # pragma: no cover - compiled
    """``out[i, k] = s0[i] + sign * (offset[i] + speed[i] * t[k])``: road s (m) of objects
    moving at constant speed (m/s) along a lane in direction ``sign`` (+1 / -1), in one
    pass (the numpy expression made three (B, T) temporaries)."""
    for i in range(out.shape[0]):
        for k in range(out.shape[1]):
            out[i, k] = s0[i] + sign * (offset[i] + speed[i] * t[k])


@njit(nogil=True)
def row_bounds(s: F64, lo: F64, hi: F64) -> None:  # pragma: no cover - compiled
    """Each row's smallest and largest value, in one pass (as ``numpy.min`` and
    ``numpy.max`` along the last axis; a row with a NaN gets NaN for both, as there)."""
    for i in range(s.shape[0]):
        a = s[i, 0]
        z = s[i, 0]
        nan = a != a
        for k in range(1, s.shape[1]):
            v = s[i, k]
            a = min(a, v)
            z = max(z, v)
            nan |= v != v
        lo[i] = np.nan if nan else a
        hi[i] = np.nan if nan else z
