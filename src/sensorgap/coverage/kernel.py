"""The per-sensor evaluation kernel shared by point and grid coverage."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sensorgap.coverage.scene import Scene
from sensorgap.models.geometry import fov_mask, in_range, rotate_offsets, sensor_range, spherical
from sensorgap.models.numerics import clip_snr_db
from sensorgap.models.roc import detection_probability
from sensorgap.models.system import Sensor

F64 = NDArray[np.float64]
IntArr = NDArray[np.intp]


def evaluate_offsets(
    scene: Scene, sensor: Sensor, dx: F64, dy: F64, dz: F64 | float
) -> tuple[NDArray[np.bool_], F64, F64]:
    """SNR (dB) and Pd of ``sensor`` at points given as offsets from its mount (m).

    Returns ``(in_view_mask, snr_db, pd)`` where ``snr_db`` and ``pd`` hold the in-view
    points only; every other point has Pd = 0 by definition (outside FOV or range).
    """
    m = sensor.mount
    xs, ys, zs = rotate_offsets(m, dx, dy, dz)
    ok = fov_mask(m, xs, ys, zs)
    if not ok.all():
        xs, ys, zs = xs[ok], ys[ok], zs[ok]
    prepared = scene.prepared(sensor)
    r = sensor_range(xs, ys, zs)
    inr = in_range(m, r)
    if not inr.all():
        ok[ok] = inr
        xs, ys, zs, r = xs[inr], ys[inr], zs[inr], r[inr]
    if r.size == 0:
        return ok, np.empty(0), np.empty(0)
    if prepared.uses_angles:
        _, az, el = spherical(xs, ys, zs)
    else:
        az = el = np.zeros_like(r)
    snr = clip_snr_db(prepared.snr_db(r, az, el))
    pd = detection_probability(snr, sensor.roc, scene.roc_shift_db)
    return ok, snr, pd


def candidates(sensor: Sensor, r2: F64) -> IntArr:
    """Flat indices of squared ranges (m2) inside [min_range, max_range]."""
    m = sensor.mount
    near = r2 <= m.max_range * m.max_range
    if m.min_range > 0.0:
        near &= r2 >= m.min_range * m.min_range
    return np.flatnonzero(near)


def evaluate_sensor(
    scene: Scene, sensor: Sensor, x: F64, y: F64, z: F64
) -> tuple[IntArr, F64, F64]:
    """SNR (dB) and Pd of ``sensor`` at flat points (vehicle frame, m).

    Returns ``(index, snr_db, pd)`` for the points in view (indices into the inputs).
    """
    m = sensor.mount
    dx, dy, dz = x - m.x, y - m.y, z - m.z
    idx = candidates(sensor, dx * dx + dy * dy + dz * dz)
    if idx.size == 0:
        return idx, np.empty(0), np.empty(0)
    ok, snr, pd = evaluate_offsets(scene, sensor, dx[idx], dy[idx], dz[idx])
    return idx[ok], snr, pd
