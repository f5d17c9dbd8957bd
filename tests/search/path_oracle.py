"""The numpy reference of ``scenarios.fastpath.path_states`` (``batch.tracks_from_path``):
heading and speed of a sampled path by central differences. It was
``Trajectory.from_path`` in the package, used by tests only; kept here as the oracle
(docs/kernels.md, issue #16: one implementation per concept in the package)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sensorgap.scenarios import Trajectory

F64 = NDArray[np.float64]


def trajectory_from_path(t: F64, x: F64, y: F64, fallback_heading: F64) -> Trajectory:
    """Heading (rad) and speed (m/s) from the sampled path (s, m; central differences);
    where the object stands still the heading is ``fallback_heading`` (e.g. the lane's)."""
    vx, vy = np.gradient(x, t), np.gradient(y, t)
    speed = np.hypot(vx, vy)
    moving = speed > 1e-6
    heading = np.where(moving, np.arctan2(vy, vx), fallback_heading)
    # keep the heading continuous and close to the fallback's branch
    heading = fallback_heading + np.angle(np.exp(1j * (heading - fallback_heading)))
    return Trajectory(t=t, x=x, y=y, heading=np.unwrap(heading), speed=speed)
