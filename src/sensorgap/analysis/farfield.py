"""Far-field analysis (Ponn 2019 Sec. IV-B, Figs. 6-7, Table IV): Pd along a target path.

The ego stands on a lane of a real OpenDRIVE road; the target path is the centre line of
another lane ahead of it. Each path sample is transformed into the ego's vehicle frame and
evaluated at the target's reference height; only samples in front of the ego's front bumper
count, over a fixed path length (the paper: 303 m). The result is Pd along the path and the
cumulated path length per detection level (Table IV).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgap.coverage.points import evaluate_points
from sensorgap.coverage.scene import Scene
from sensorgap.errors import InputError

F64 = NDArray[np.float64]

#: The Table IV levels, in the paper's order, with their predicates on Pd.
LEVELS: tuple[tuple[str, str], ...] = (
    ("pd=1.0", "Pd = 1.0"),
    ("pd>=0.8", "Pd >= 0.8"),
    ("pd>=0.5", "Pd >= 0.5"),
    ("pd>0", "Pd > 0"),
    ("pd=0", "Pd = 0"),
)


@dataclass(frozen=True)
class EgoPose:
    """Ego rear-axle centre in world coordinates (m) and heading (rad, CCW from east)."""

    x: float
    y: float
    heading: float


@dataclass
class FarField:
    """Pd along a target path.

    Attributes:
        s: path length from the first sample in front of the ego, m (sample centres).
        ds: path length each sample stands for, m.
        world: (N, 2) world x, y, m.  vehicle: (N, 2) ego vehicle-frame x, y, m.
        pd: (N,) fused detection probability. per_sensor: sensor id -> (N,) Pd.
        levels_m: cumulated path length per Table IV level, m.
    """

    s: F64
    ds: F64
    world: F64
    vehicle: F64
    pd: F64
    per_sensor: dict[str, F64]
    levels_m: dict[str, float]


def world_to_vehicle(pose: EgoPose, x: F64, y: F64) -> tuple[F64, F64]:
    """World (m) -> ego vehicle frame (m)."""
    c, s = math.cos(pose.heading), math.sin(pose.heading)
    dx, dy = x - pose.x, y - pose.y
    return c * dx + s * dy, -s * dx + c * dy


def level_lengths(pd: F64, ds: F64) -> dict[str, float]:
    """Cumulated length (m) of samples per Table IV level (each sample counts ``ds``)."""
    masks = {
        "pd=1.0": pd >= 1.0,
        "pd>=0.8": pd >= 0.8,
        "pd>=0.5": pd >= 0.5,
        "pd>0": pd > 0.0,
        "pd=0": pd <= 0.0,
    }
    return {k: float(np.sum(ds[m])) for k, m in masks.items()}


def path_ahead(
    path_xy: F64, pose: EgoPose, x_front: float, length_m: float, step_m: float
) -> tuple[F64, F64, F64]:
    """Resample a polyline (world, m) at ``step_m`` from its first point in front of the ego's
    front bumper (vehicle x >= ``x_front``) for ``length_m``.

    Returns sample centres (world, (N, 2)), their path length ``s`` (m) and ``ds`` (m).
    Raises ``InputError`` when the path is shorter than requested.
    """
    seg = np.diff(path_xy, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    xv, _ = world_to_vehicle(pose, path_xy[:, 0], path_xy[:, 1])
    ahead = np.flatnonzero(xv >= x_front)
    if ahead.size == 0:
        raise InputError("target_lane", "", "no part of the target lane lies ahead of the ego")
    i0 = int(ahead[0])
    s0 = cum[i0]
    if i0 > 0:  # interpolate the exact crossing of the front-bumper line
        a, b = xv[i0 - 1], xv[i0]
        f = (x_front - a) / (b - a) if b != a else 0.0
        s0 = cum[i0 - 1] + f * seg_len[i0 - 1]
    if cum[-1] - s0 < length_m - 1e-6:
        raise InputError(
            "target_lane",
            "",
            f"only {cum[-1] - s0:.1f} m of the target lane lie "
            f"ahead of the ego; {length_m:g} m needed (choose an ego s farther from the "
            "road's end in its lane's direction of travel, or a shorter length)",
        )
    n = max(1, round(length_m / step_m))
    ds = np.full(n, length_m / n, dtype=np.float64)
    s = np.asarray((np.arange(n) + 0.5) * (length_m / n), dtype=np.float64)
    x = np.interp(s0 + s, cum, path_xy[:, 0])
    y = np.interp(s0 + s, cum, path_xy[:, 1])
    return np.asarray(np.column_stack([x, y]), dtype=np.float64), s, ds


def farfield(
    scene: Scene,
    path_xy: F64,
    pose: EgoPose,
    length_m: float = 303.0,
    step_m: float = 0.1,
    height_m: float | None = None,
    bodies: bool = False,
) -> FarField:
    """Pd along ``path_xy`` (world polyline, m) seen from ``pose`` (Table IV, Figs. 6-7).

    ``bodies`` False (the paper's setting): the target is a point at ``height_m`` (default:
    its reference height). True: the target is its body (``coverage.body``) centred on the
    path, heading along it (the path's tangent)."""
    x_front = scene.system.config.vehicle.x_front_m
    world, s, ds = path_ahead(path_xy, pose, x_front, length_m, step_m)
    xv, yv = world_to_vehicle(pose, world[:, 0], world[:, 1])
    if bodies:
        from sensorgap.coverage.body import body_per_sensor_pd
        from sensorgap.coverage.logmiss import log_miss_of

        if len(world) > 1:
            tangent = np.arctan2(np.gradient(world[:, 1]), np.gradient(world[:, 0]))
        else:
            tangent = np.full(len(world), pose.heading)
        pd, _ = body_per_sensor_pd(scene, xv, yv, tangent - pose.heading)
        fused = np.asarray(-np.expm1(log_miss_of(pd).sum(axis=0)) + 0.0, dtype=np.float64)
        per = {sensor.id: pd[i] for i, sensor in enumerate(scene.sensors)}
        return FarField(
            s=s,
            ds=ds,
            world=world,
            vehicle=np.column_stack([xv, yv]),
            pd=fused,
            per_sensor=per,
            levels_m=level_lengths(fused, ds),
        )
    h = scene.target.reference_height_m if height_m is None else height_m
    cov = evaluate_points(scene, np.column_stack([xv, yv, np.full_like(xv, h)]))
    per = {sid: cov.pd[i] for i, sid in enumerate(cov.sensor_ids) if sid in cov.evaluated}
    return FarField(
        s=s,
        ds=ds,
        world=world,
        vehicle=np.column_stack([xv, yv]),
        pd=cov.fused,
        per_sensor=per,
        levels_m=level_lengths(cov.fused, ds),
    )
