"""Time-sampled trajectories (world frame) and their feasibility checks."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

#: Sampling rate of every generated trajectory, Hz.
RATE_HZ = 20.0
DT_S = 1.0 / RATE_HZ


class InfeasibleScenario(Exception):
    """A parameter vector whose trajectories are not physically feasible or leave the road."""


class OffRoad(InfeasibleScenario):
    """A trajectory that leaves the road (its s runs outside the road)."""


def time_axis(duration_s: float) -> F64:
    """Sample times 0, 0.05, ..., duration (s) at ``RATE_HZ``."""
    n = round(duration_s * RATE_HZ) + 1
    return np.arange(n, dtype=np.float64) / RATE_HZ  # k / 20 is the nearest double to k dt


@dataclass(frozen=True)
class Limits:
    """Bounds on longitudinal and lateral acceleration (m/s2) and speed (m/s)."""

    max_long_accel: float
    max_lat_accel: float
    max_speed: float


#: Default limits by target class (vehicles: friction-limited ~0.8 g; people: walking).
LIMITS: dict[str, Limits] = {
    "car": Limits(8.0, 8.0, 70.0),
    "truck": Limits(6.0, 5.0, 25.0),
    "bike": Limits(4.0, 4.0, 12.0),
    "pedestrian": Limits(3.0, 3.0, 3.0),
}


@dataclass(frozen=True)
class Trajectory:
    """States at times ``t`` (s): position x, y (m, world), heading (rad, CCW from east,
    unwrapped) and speed (m/s, >= 0). Ego trajectories give the rear-axle centre (the
    vehicle-frame origin), target trajectories the target's centre."""

    t: F64
    x: F64
    y: F64
    heading: F64
    speed: F64

    def __post_init__(self) -> None:
        n = len(self.t)
        for name in ("x", "y", "heading", "speed"):
            arr = getattr(self, name)
            if arr.shape != (n,):
                raise ValueError(f"trajectory {name} has shape {arr.shape}, expected ({n},)")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"trajectory {name} is not finite")
        if n < 2:
            raise ValueError("a trajectory needs at least two samples")

    def long_accel(self) -> F64:
        """Longitudinal acceleration, m/s2."""
        return np.gradient(self.speed, self.t)

    def lat_accel(self) -> F64:
        """Lateral (centripetal) acceleration speed * yaw rate, m/s2."""
        return self.speed * np.gradient(self.heading, self.t)

    def velocity(self) -> tuple[F64, F64]:
        """World velocity components, m/s."""
        return self.speed * np.cos(self.heading), self.speed * np.sin(self.heading)

    def check(self, limits: Limits, who: str) -> None:
        """Raise ``InfeasibleScenario`` when a bound is exceeded (1 % slack)."""
        checks = (
            ("speed", float(np.max(self.speed)), limits.max_speed, "m/s"),
            (
                "longitudinal acceleration",
                float(np.max(np.abs(self.long_accel()))),
                limits.max_long_accel,
                "m/s2",
            ),
            (
                "lateral acceleration",
                float(np.max(np.abs(self.lat_accel()))),
                limits.max_lat_accel,
                "m/s2",
            ),
        )
        for what, value, bound, unit in checks:
            if value > bound * 1.01 + 1e-9:
                raise InfeasibleScenario(f"{who}: {what} {value:.2f} {unit} exceeds {bound:g}")


def blend(shape: str, u: F64) -> F64:
    """Lane-change blend w(u) for u in [0, 1] (clipped): ``cosine`` (half-cosine) or
    ``quintic`` (minimum-jerk 10u^3 - 15u^4 + 6u^5); w(0) = 0, w(1) = 1, zero slope at both."""
    u = np.clip(u, 0.0, 1.0)
    if shape == "cosine":
        return np.asarray(0.5 - 0.5 * np.cos(math.pi * u), dtype=np.float64)
    if shape == "quintic":
        return np.asarray(u**3 * (10.0 - 15.0 * u + 6.0 * u * u), dtype=np.float64)
    raise ValueError(f"unknown lane-change shape {shape!r}; allowed: cosine, quintic")
