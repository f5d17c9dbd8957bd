"""Where the bodies are: each entity's planned bounding box next to the one esmini logs
(issue #15 item 1: "bodies within 0.05 m of plan").

esmini's CSV log has, per entity and step, its origin (``World_Position_X/Y``), heading
and its bounding box as it uses it (``bb_x, bb_y``: the box centre in the entity's frame;
``bb_length, bb_width``), after any adjustment of its own (a vehicle whose rear axle is
not at its origin has its box shifted, the fault issue #15 found). The logged box's
centre and four corners are compared with the planned box's (ego: the vehicle file's body
about the rear axle; target and occluders: their planned centre paths and sizes) at the
logged times within the plan, corner by corner (front left with front left, ...).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgap.export.maneuver import EGO, TARGET, occluder_name
from sensorgap.export.spec import ScenarioSpec
from sensorgap.scenarios.trajectory import Trajectory

F64 = NDArray[np.float64]

#: Largest distance of a logged box's centre or corner from the plan's, m (issue #15).
MAX_BODY_DEV_M = 0.05


@dataclass(frozen=True)
class PlannedBox:
    """A body in the plan: its box centre's path and its length and width, m."""

    centre: Trajectory
    length_m: float
    width_m: float


def planned_boxes(spec: ScenarioSpec) -> dict[str, PlannedBox]:
    """Every body of the plan by entity name: the ego (the vehicle file's body about its
    planned rear axle), the target and the occluders (their planned centre paths)."""
    body = spec.system.config.vehicle
    ahead = 0.5 * (body.x_front_m + body.x_rear_m)  # rear axle -> box centre, m
    ego = spec.scenario.ego
    c, s = np.cos(ego.heading), np.sin(ego.heading)
    out = {
        EGO: PlannedBox(
            Trajectory(ego.t, ego.x + ahead * c, ego.y + ahead * s, ego.heading, ego.speed),
            body.length_m,
            body.width_m,
        ),
        TARGET: PlannedBox(spec.scenario.target, spec.target.length_m, spec.target.width_m),
    }
    for occ in spec.scenario.occluders:
        out[occluder_name(occ.label)] = PlannedBox(occ.path, occ.length_m, occ.width_m)
    return out


def box_points(cx: F64, cy: F64, heading: F64, length: F64 | float, width: F64 | float) -> F64:
    """(n, 5, 2) centre and corners (front left, front right, rear right, rear left) of
    boxes with centres ``cx, cy`` (m), ``heading`` (rad) and ``length``, ``width`` (m)."""
    c, s = np.cos(heading), np.sin(heading)
    hl = 0.5 * np.broadcast_to(np.asarray(length, dtype=np.float64), np.shape(cx))
    hw = 0.5 * np.broadcast_to(np.asarray(width, dtype=np.float64), np.shape(cx))
    pts = [(0.0 * hl, 0.0 * hw), (hl, hw), (hl, -hw), (-hl, -hw), (-hl, hw)]
    return np.stack(
        [np.stack([cx + c * u - s * v, cy + s * u + c * v], axis=-1) for u, v in pts], axis=1
    )


def box_deviation(
    plan: PlannedBox,
    t: F64,
    x: F64,
    y: F64,
    heading: F64,
    bb_x: F64,
    bb_y: F64,
    length: F64,
    width: F64,
) -> float:
    """Largest distance (m) of a logged box's centre or corners from the planned box's at
    the logged times ``t`` (s) within the plan; the logged box from the entity's origin
    ``x, y`` (m), ``heading`` (rad) and esmini's ``bb_x, bb_y`` (box centre in the
    entity's frame, m), ``length``, ``width`` (m). inf: no logged time within the plan."""
    keep = t <= plan.centre.t[-1] + 1e-9
    if not keep.any():
        return float("inf")
    t, x, y, heading = t[keep], x[keep], y[keep], heading[keep]
    c, s = np.cos(heading), np.sin(heading)
    cx = x + c * bb_x[keep] - s * bb_y[keep]
    cy = y + s * bb_x[keep] + c * bb_y[keep]
    logged = box_points(cx, cy, heading, length[keep], width[keep])
    p = plan.centre
    planned = box_points(
        np.interp(t, p.t, p.x),
        np.interp(t, p.t, p.y),
        np.interp(t, p.t, p.heading),
        plan.length_m,
        plan.width_m,
    )
    return float(np.max(np.hypot(*(logged - planned).transpose(2, 0, 1))))
