"""Coverage at arbitrary points (vehicle frame)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgap.coverage.kernel import evaluate_sensor
from sensorgap.coverage.scene import Scene
from sensorgap.models.fusion import FusionAccumulator
from sensorgap.models.numerics import SNR_NOT_IN_VIEW_DB
from sensorgap.models.system import Sensor

F64 = NDArray[np.float64]


@dataclass
class PointCoverage:
    """Per-sensor and fused detection at N points.

    Attributes:
        points: (N, 3) x, y, z in the vehicle frame, m.
        sensor_ids: row labels of ``snr_db`` and ``pd``.
        snr_db: (S, N) SNR, dB (``SNR_NOT_IN_VIEW_DB`` where a sensor cannot see a point).
        pd: (S, N) per-sensor detection probability.
        fused: (N,) fused detection probability (eq. 11).
        evaluated: ids of the sensors actually evaluated (the rest were culled).
    """

    points: F64
    sensor_ids: list[str]
    snr_db: F64
    pd: F64
    fused: F64
    evaluated: list[str]


def sensor_can_reach_box(sensor: Sensor, lo: F64, hi: F64) -> bool:
    """Whether the sensor's range sphere intersects the axis-aligned box [lo, hi] (m)."""
    m = sensor.mount
    c = np.array([m.x, m.y, m.z])
    nearest = np.clip(c, lo, hi)
    return bool(math.dist(c.tolist(), nearest.tolist()) <= m.max_range)


def as_points(points: NDArray[np.floating] | list[list[float]], height: float = 0.0) -> F64:
    """(N, 2) or (N, 3) -> (N, 3) float64; z defaults to ``height`` (m)."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] not in (2, 3):
        raise ValueError(f"points must have shape (N, 2) or (N, 3), got {p.shape}")
    if p.shape[1] == 2:
        p = np.column_stack([p, np.full(len(p), height)])
    if not np.all(np.isfinite(p)):
        raise ValueError("points must be finite")
    return p


def evaluate_points(
    scene: Scene, points: NDArray[np.floating] | list[list[float]], cull: bool = True
) -> PointCoverage:
    """Per-sensor SNR (dB), Pd and fused Pd at points (vehicle frame, m).

    With ``cull`` (default) a sensor whose range cannot reach the points' bounding box is
    not evaluated at all; its SNR is reported as ``SNR_NOT_IN_VIEW_DB`` and its Pd as 0.
    """
    p = as_points(points)
    n = len(p)
    ids = [s.id for s in scene.sensors]
    snr = np.full((len(ids), n), SNR_NOT_IN_VIEW_DB)
    pd = np.zeros((len(ids), n))
    acc = FusionAccumulator((n,))
    evaluated: list[str] = []
    if n:
        lo, hi = p.min(axis=0), p.max(axis=0)
        x, y, z = p[:, 0].copy(), p[:, 1].copy(), p[:, 2].copy()
        for row, s in enumerate(scene.sensors):
            if cull and not sensor_can_reach_box(s, lo, hi):
                scene.skip(s, "out of range of the queried region")
                continue
            evaluated.append(s.id)
            idx, s_snr, s_pd = evaluate_sensor(scene, s, x, y, z)
            snr[row, idx] = s_snr
            pd[row, idx] = s_pd
            acc.add(s_pd, idx)
    return PointCoverage(
        points=p, sensor_ids=ids, snr_db=snr, pd=pd, fused=acc.result(), evaluated=evaluated
    )
