"""Compiled (numba) inner loops of the grid evaluator: geometry and ROC + fusion.

The physics of each sensor type stays a pure numpy function (``PreparedSensor.snr_db``) so
that user-registered sensor types work unchanged; what is compiled here is generic: the
field-of-view and range test of every cell of a sub-grid (same definitions as
``sensorgap.models.geometry``) and, for the closed-form ROC kinds, ``log(1 - Pd)`` added into
the fusion accumulator (eq. 11 in the log domain). ``nogil=True`` lets the grid's worker
threads run them in parallel. Results equal the numpy path to ~1 ulp (different libm).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sensorgap.config.vehicle import RocConfig
from sensorgap.jit import njit
from sensorgap.models.geometry import Mount

F64 = NDArray[np.float64]

# FOV modes for the horizontal test (see geometry.fov_mask)
_H_ALL, _H_HALF, _H_NARROW, _H_WIDE = 0, 1, 2, 3


def mount_constants(m: Mount) -> F64:
    """Pack what the geometry kernel needs about a mount into one float64 array."""
    half_h, half_v = 0.5 * m.hfov, 0.5 * m.vfov
    if half_h >= math.pi:
        mode, th = _H_ALL, 0.0
    elif half_h == 0.5 * math.pi:
        mode, th = _H_HALF, 0.0
    elif half_h < 0.5 * math.pi:
        mode, th = _H_NARROW, math.tan(half_h)
    else:
        mode, th = _H_WIDE, math.tan(math.pi - half_h)
    v_all = 1.0 if half_v >= 0.5 * math.pi else 0.0
    tv2 = 0.0 if v_all else math.tan(half_v) ** 2
    return np.array(
        [
            math.cos(m.yaw),
            math.sin(m.yaw),
            math.cos(m.pitch),
            math.sin(m.pitch),
            1.0 if m.pitch != 0.0 else 0.0,
            float(mode),
            th,
            v_all,
            tv2,
            m.min_range,
            m.max_range,
        ]
    )


@njit(nogil=True, fastmath=False, inline="always")
def sensor_frame(
    ddx: float, ddy: float, dz: float, c: F64
) -> tuple[bool, float, float, float, float, float]:  # pragma: no cover - compiled
    """Whether the offset (``ddx``, ``ddy``, ``dz``) from a mount (vehicle-frame axes, m) is
    in view of it (``mount_constants`` ``c``: field of view and range, as
    ``geometry.fov_mask`` and ``in_range``), with its range r (m) and sensor-frame u, v, w
    (m) and u^2 + v^2 (m2)."""
    cy, sy, cp, sp = c[0], c[1], c[2], c[3]
    mode, th, tv2 = int(c[5]), c[6], c[8]
    u = cy * ddx + sy * ddy
    v = -sy * ddx + cy * ddy
    w = dz
    if c[4] != 0.0:
        u, w = cp * u - sp * dz, sp * u + cp * dz
    if mode == 2:
        if not (u > 0.0 and abs(v) <= u * th):
            return False, 0.0, u, v, w, 0.0
    elif mode == 1:
        if not (u >= 0.0):
            return False, 0.0, u, v, w, 0.0
    elif mode == 3 and u < 0.0 and abs(v) < -u * th:
        return False, 0.0, u, v, w, 0.0
    rho2 = u * u + v * v
    if c[7] == 0.0 and not (w * w <= rho2 * tv2):
        return False, 0.0, u, v, w, rho2
    r = math.sqrt(rho2 + w * w)
    return r > 0.0 and r <= c[10] and r >= c[9], r, u, v, w, rho2


@njit(nogil=True, fastmath=False)
def subgrid_geometry(
    dx: F64, dy: F64, dz: float, c: F64, skip: NDArray[np.bool_], want_angles: bool
) -> tuple[NDArray[np.int64], F64, F64, F64]:
    """For the sub-grid of offsets (dy rows x dx columns, m) return the flat indices of the
    cells in view with their range (m), azimuth and elevation (rad; zeros unless
    ``want_angles``). Cells with ``skip`` set (same shape as the sub-grid) are left out."""
    rmax = c[10]
    ny, nx = dy.size, dx.size
    n = ny * nx
    idx = np.empty(n, np.int64)
    rr = np.empty(n, np.float64)
    aa = np.empty(n if want_angles else 0, np.float64)
    ee = np.empty(n if want_angles else 0, np.float64)
    rmax2 = rmax * rmax
    # dx is an evenly spaced ascending grid: each row only scans the columns that can lie
    # within max_range (one extra cell each side absorbs rounding; r2 is checked anyway)
    step = dx[1] - dx[0] if nx > 1 else 1.0
    k = 0
    for j in range(ny):
        ddy = dy[j]
        room = rmax2 - ddy * ddy - dz * dz
        if room < 0.0:
            continue
        half = math.sqrt(room)
        i0 = max(0, int(math.floor((-half - dx[0]) / step)) - 1)
        i1 = min(nx, int(math.ceil((half - dx[0]) / step)) + 2)
        for i in range(i0, i1):
            if skip[j, i]:
                continue
            ddx = dx[i]
            r2 = ddx * ddx + ddy * ddy + dz * dz
            if r2 > rmax2:
                continue
            ok, r, u, v, w, rho2 = sensor_frame(ddx, ddy, dz, c)
            if not ok:
                continue
            idx[k] = j * nx + i
            rr[k] = r
            if want_angles:
                aa[k] = math.atan2(v, u)
                ee[k] = math.atan2(w, math.sqrt(rho2))
            k += 1
    if want_angles:
        return idx[:k], rr[:k], aa[:k], ee[:k]
    return idx[:k], rr[:k], aa, ee


# ROC kinds with a compiled log(1 - Pd)
ROC_PAPER, ROC_SMOOTHSTEP, ROC_SWERLING1 = 0, 1, 2
_COMPILED_ROC = {"paper": ROC_PAPER, "smoothstep": ROC_SMOOTHSTEP, "swerling1": ROC_SWERLING1}


def roc_constants(roc: RocConfig, shift_db: float) -> tuple[int, F64] | None:
    """(kind code, constants) for a compiled ROC, or ``None`` (use the numpy path)."""
    code = _COMPILED_ROC.get(roc.kind)
    if code is None:
        return None
    if code == ROC_PAPER:
        # Pd = exp(a / (1 + SNR)), a = ln 0.5 * (1 + SNR50); 0 below the floor
        a = math.log(0.5) * (1.0 + 10.0 ** (roc.snr50_db / 10.0))
        return code, np.array([a, roc.floor_db, shift_db])
    if code == ROC_SWERLING1:
        return code, np.array([math.log(roc.pfa), -1.0e300, shift_db])
    return code, np.array([roc.snr50_db, roc.half_width_db, shift_db])


@njit(nogil=True, fastmath=False)
def accumulate_log_miss(
    snr_db: F64,
    flat: NDArray[np.int64],
    code: int,
    c: F64,
    log_miss: F64,
    certain: NDArray[np.bool_],
) -> None:
    """Add ``log(1 - Pd)`` of each cell into ``log_miss`` (flat view) and flag Pd = 1 cells
    in ``certain``: the fusion of eq. 11 for one sensor, without forming Pd."""
    shift = c[2]
    for k in range(snr_db.size):
        s = snr_db[k] - shift
        if s < -300.0:
            s = -300.0
        elif s > 300.0:
            s = 300.0
        if code == 2 or code == 0:
            if s < c[1]:
                continue  # Pd = 0 below the floor: log(1 - 0) = 0
            q = c[0] / (1.0 + 10.0 ** (s / 10.0))  # ln Pd (<= 0)
            if q == 0.0:
                certain[flat[k]] = True
            else:
                log_miss[flat[k]] += math.log(-math.expm1(q))
        else:
            t = (s - (c[0] - c[1])) / (2.0 * c[1])
            if t <= 0.0:
                continue
            if t >= 1.0:
                certain[flat[k]] = True
                continue
            p = t * t * (3.0 - 2.0 * t)
            log_miss[flat[k]] += math.log1p(-p)
