"""The target's and occluders' behaviour per family kind in the ``maneuver`` export style
(docs/export.md, table "family kind -> actions -> started by"): lane starts relative to the
ego's start, ``LaneChangeAction`` / ``SpeedAction`` / timed ``FollowTrajectoryAction``,
each started by a condition relative to the ego."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scenariogeneration import xosc

from sensorgap.export.actions import (
    EGO,
    TARGET,
    Build,
    PlannedTrigger,
    after_change,
    after_start,
    declare_shape,
    fmt,
    gap_trigger,
    lane_change,
    lane_speed,
    lane_start,
    occluder_name,
    origin_offset,
    step_dynamics,
)
from sensorgap.export.params import number
from sensorgap.export.spec import ScenarioSpec
from sensorgap.scenarios.kinds import CROSSING_ACCEL_M_S2, travel_direction
from sensorgap.scenarios.occluded import occluder_class
from sensorgap.scenarios.trajectory import Trajectory


def _cut_in_from(b: Build, lane: int, tr: int, ahead: str, speed: str, closing: float) -> None:
    """The target starts in ``lane`` ``ahead`` (expression, m) of the ego's start at
    ``speed`` (expression, m/s) and cuts into the ego's lane when the planned gap at
    ``lc_start_s`` is reached (the gap changes at ``closing``, m/s), over
    ``lc_duration_s``, keeping ``speed`` in the ego's lane after."""
    p = b.spec.params
    t_s, t_e = float(p["lc_start_s"]), float(p["lc_start_s"]) + float(p["lc_duration_s"])
    s0 = lane_start(b, TARGET, lane, tr, ahead, speed, t_s)
    gap = f"{ahead} + ({speed} - $ego_speed_m_s) * $lc_start_s"
    trig = gap_trigger(b, "cut_in_gap", TARGET, EGO, gap, closing)
    lane_change(
        b,
        TARGET,
        "cut_in",
        None,
        declare_shape(b),
        b.p.ref("lc_duration_s"),
        trig,
        t_s,
        EGO,
        (speed, int(b.st["ego_lane"]), *after_change(b, tr, s0, speed, t_s, t_e)),
    )


def _cut_in(b: Build) -> None:
    sp, p = b.spec, b.spec.params
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), int(b.st["ego_lane"]))
    off = number(origin_offset(sp.target))
    dv = float(p["target_speed_m_s"]) - float(p["ego_speed_m_s"])
    _cut_in_from(b, int(b.st["target_lane"]), tr, f"$dx0_m - {off}", "$target_speed_m_s", dv)


def _cut_in_behind_truck(b: Build) -> None:
    sp, p = b.spec, b.spec.params
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), int(b.st["ego_lane"]))
    truck = occluder_class(b.spec.family)
    side = int(b.st["target_lane"])
    name = occluder_name(sp.scenario.occluders[0].label)
    b.entities.append((name, truck))
    lane_start(
        b,
        name,
        int(b.st["occluder_lane"]),
        tr,
        f"$truck_dx_m - {number(origin_offset(truck))}",
        "$truck_speed_m_s",
    )
    half = number(0.5 * truck.length_m + 0.5 * sp.target.length_m - origin_offset(sp.target))
    ahead = f"$truck_dx_m + $target_gap_m + {half}"
    speed = "$truck_speed_m_s + $speed_delta_m_s"
    dv = float(p["truck_speed_m_s"]) + float(p["speed_delta_m_s"]) - float(p["ego_speed_m_s"])
    _cut_in_from(b, side, tr, ahead, speed, dv)


def _overtake(b: Build) -> None:
    sp, p = b.spec, b.spec.params
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), int(b.st["ego_lane"]))
    off = number(origin_offset(sp.target))
    v0, lane = "$ego_speed_m_s + $speed_delta_m_s", int(b.st["ego_lane"])
    t_m = (float(p["merge_gap_m"]) - float(p["dx0_m"])) / float(p["speed_delta_m_s"])
    t_e = t_m + float(p["merge_duration_s"])
    s0 = lane_start(b, TARGET, int(b.st["target_lane"]), tr, f"$dx0_m - {off}", v0, t_m)
    trig = gap_trigger(
        b, "merge_gap", TARGET, EGO, f"$merge_gap_m - {off}", float(p["speed_delta_m_s"])
    )
    stretch = after_change(b, tr, s0, v0, t_m, t_e)
    lane_change(
        b,
        TARGET,
        "merge",
        None,
        declare_shape(b, "cosine"),
        b.p.ref("merge_duration_s"),
        trig,
        t_m,
        EGO,
        (v0, lane, *stretch),
    )
    vf = b.p.value("$ego_speed_m_s - $final_delta_m_s")
    speed = lane_speed(b, lane, "$ego_speed_m_s - $final_delta_m_s", *stretch) if vf > 0.0 else 0.0
    brake = xosc.AbsoluteSpeedAction(
        speed,
        xosc.TransitionDynamics(
            xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, b.p.ref("decel_m_s2")
        ),
    )
    # it brakes brake_delay_s after the merge, still at the overtaking speed: at the gap
    # the merge's gap grows to in (merge_duration_s + brake_delay_s)
    gap = f"$merge_gap_m - {off} + $speed_delta_m_s * ($merge_duration_s + $brake_delay_s)"
    trig_b = gap_trigger(b, "brake_gap", TARGET, EGO, gap, float(p["speed_delta_m_s"]))
    b.event(TARGET, "brake", brake, trig_b)
    b.triggers.append(PlannedTrigger("brake", TARGET, EGO, t_e + float(p["brake_delay_s"])))


def _slow_ahead(b: Build) -> None:
    sp = b.spec
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), int(b.st["lane"]))
    lane_start(
        b,
        TARGET,
        int(b.st["lane"]),
        tr,
        f"$gap0_m - {number(origin_offset(sp.target))}",
        "$target_speed_m_s",
    )


def _cut_out_reveal(b: Build) -> None:
    sp, p = b.spec, b.spec.params
    lane, other = int(b.st["lane"]), int(b.st["target_lane"])
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), lane)
    lead = occluder_class(b.spec.family)
    name = occluder_name(sp.scenario.occluders[0].label)
    b.entities.append((name, lead))
    t_s, t_e = float(p["cut_out_s"]), float(p["cut_out_s"]) + float(p["lc_duration_s"])
    s_lead = lane_start(
        b, name, lane, tr, f"$lead_gap_m - {number(origin_offset(lead))}", "$ego_speed_m_s", t_s
    )
    half = number(0.5 * (lead.length_m + sp.target.length_m) - origin_offset(sp.target))
    reveal = (
        f"($cut_out_s + $lc_duration_s + $reveal_s) * ($ego_speed_m_s - $target_speed_m_s) + {half}"
    )
    lane_start(b, TARGET, lane, tr, f"$lead_gap_m + {reveal}", "$target_speed_m_s")
    # the lead pulls out when the ego is at the planned distance to the hidden target
    gap = (
        f"$lead_gap_m + ($lc_duration_s + $reveal_s) * ($ego_speed_m_s - "
        f"$target_speed_m_s) + {half}"
    )
    closing = float(p["target_speed_m_s"]) - float(p["ego_speed_m_s"])
    trig = gap_trigger(b, "reveal_gap", TARGET, EGO, gap, closing)
    lane_change(
        b,
        name,
        "cut_out",
        other,
        declare_shape(b, "cosine"),
        b.p.ref("lc_duration_s"),
        trig,
        t_s,
        EGO,
        ("$ego_speed_m_s", other, *after_change(b, tr, s_lead, "$ego_speed_m_s", t_s, t_e)),
    )
    # the triggering entity is the target (its distance to the ego); the action the lead's
    b.triggers[-1] = PlannedTrigger("cut_out", TARGET, EGO, float(p["cut_out_s"]))


def _departure(tr: Trajectory, accel: float) -> float:
    """When a crossing target leaves its waiting point (s; <= 0: under way at the start):
    the first sample that moved, back along the constant-acceleration start."""
    moved = np.hypot(tr.x - tr.x[0], tr.y - tr.y[0]) > 1e-9
    if not moved.any():
        return math.inf
    k = int(np.argmax(moved))
    if k == 0 or tr.speed[0] > 1e-6:
        return -math.inf
    d = float(np.hypot(tr.x[k] - tr.x[0], tr.y[k] - tr.y[0]))
    return float(tr.t[k]) - math.sqrt(2.0 * d / accel)


def _crossing(b: Build) -> None:
    """The target waits on the footway and follows its planned crossing (timed polyline of
    the 20 Hz plan, relative timing) once the ego is the planned distance away; a target
    under way at the start follows it from the start (absolute timing)."""
    sp, p = b.spec, b.spec.params
    rid = str(b.st["road_id"])
    tr = travel_direction(sp.family.network, rid, int(b.st["ego_lane"]))
    from sensorgap.export.xosc import filtered_vertices, origin_path

    path = origin_path(sp.scenario.target, origin_offset(sp.target))
    accel = CROSSING_ACCEL_M_S2.get(sp.target.name, 1.5)
    t_dep = _departure(sp.scenario.target, accel)
    s_c = b.p.expr(f"$ego_s0_m {'+' if tr > 0 else '-'} $cross_ahead_m")
    net = sp.family.network
    s_val = b.p.value(f"$ego_s0_m {'+' if tr > 0 else '-'} $cross_ahead_m")
    xr, yr, hr = net.reference_line(rid, s_val)

    def road_pos(k: int) -> xosc.RoadPosition:
        lat = (path.x[k] - xr) * -math.sin(hr) + (path.y[k] - yr) * math.cos(hr)
        rel = float(path.heading[k]) - hr
        rel = math.atan2(math.sin(rel), math.cos(rel))
        return xosc.RoadPosition(
            s_c,
            fmt(lat),
            rid,
            xosc.Orientation(h=fmt(rel), reference=xosc.ReferenceContext.relative),
        )

    moving = np.flatnonzero(path.speed > 1e-9)
    last = int(moving[-1]) + 1 if len(moving) else 0
    last = min(last, len(path.t) - 1)
    b.init.append((TARGET, xosc.TeleportAction(road_pos(0))))
    b.init.append((TARGET, xosc.AbsoluteSpeedAction(fmt(float(path.speed[0])), step_dynamics())))
    if math.isinf(t_dep) and t_dep > 0.0:
        return  # it would leave the footway after the scenario's end: it waits there
    if t_dep > 0.0:
        first = int(np.searchsorted(path.t, t_dep, side="right"))
        idx = filtered_vertices(path.x, path.y, [0, *range(first, last + 1)])
        times = [0.0] + [fmt(float(path.t[k]) - t_dep) for k in idx[1:]]
        # the ego's rear axle is cross_ahead - ego_speed * t_dep = ego_speed * (tau_c -
        # conflict_offset) before the crossing line, tau_c = time from departure to the
        # ego lane's centre
        tau_c = (
            float(p["cross_ahead_m"]) / float(p["ego_speed_m_s"])
            + float(p["conflict_offset_s"])
            - t_dep
        )
        gap = f"$ego_speed_m_s * ({number(tau_c)} - $conflict_offset_s)"
        cond = xosc.RelativeDistanceCondition(
            b.p.expr(gap),
            xosc.Rule.lessThan,
            xosc.RelativeDistanceType.longitudinal,
            TARGET,
            alongroute=False,
            freespace=False,
            coordinate_system=xosc.CoordinateSystem.entity,
        )
        trig: Any = xosc.EntityTrigger("crossing_gap", 0.0, xosc.ConditionEdge.rising, cond, EGO)
        timing = xosc.ReferenceContext.relative
        b.triggers.append(PlannedTrigger("cross", EGO, TARGET, t_dep))
    else:
        idx = filtered_vertices(path.x, path.y, list(range(0, last + 1)))
        times = [fmt(float(path.t[k])) for k in idx]
        trig = after_start("crossing_under_way")
        timing = xosc.ReferenceContext.absolute
    traj = xosc.Trajectory("Target_crossing", False)
    traj.add_shape(xosc.Polyline(times, [road_pos(k) for k in idx]))
    follow = xosc.FollowTrajectoryAction(traj, xosc.FollowingMode.position, timing, 1.0, 0.0)
    b.event(TARGET, "cross", follow, trig)
    if last < len(path.t) - 1:  # it stops on the far footway: hold it there
        stop = xosc.AbsoluteSpeedAction(0.0, step_dynamics())
        done = xosc.ValueTrigger(
            "crossed",
            0.0,
            xosc.ConditionEdge.none,
            xosc.StoryboardElementStateCondition(
                xosc.StoryboardElementType.action,
                "cross_action",
                xosc.StoryboardElementState.endTransition,
            ),
        )
        b.event(TARGET, "stand", stop, done)


def _crossing_behind_parked(b: Build) -> None:
    _crossing(b)
    for occ in b.spec.scenario.occluders:
        name = occluder_name(occ.label)
        cfg = occluder_class(b.spec.family)
        b.entities.append((name, cfg))
        d = origin_offset(cfg)
        h = float(occ.path.heading[0])
        x = float(occ.path.x[0]) - d * math.cos(h)
        y = float(occ.path.y[0]) - d * math.sin(h)
        b.init.append((name, xosc.TeleportAction(xosc.WorldPosition(fmt(x), fmt(y), 0.0, fmt(h)))))


KINDS = {
    "cut_in": _cut_in,
    "overtake": _overtake,
    "slow_ahead": _slow_ahead,
    "crossing": _crossing,
    "cut_in_behind_occluder": _cut_in_behind_truck,
    "cut_out_reveal": _cut_out_reveal,
    "crossing_behind_parked": _crossing_behind_parked,
}


def supported(spec: ScenarioSpec) -> bool:
    """Whether the maneuver style knows the family's kind."""
    return spec.family.kind.name in KINDS
