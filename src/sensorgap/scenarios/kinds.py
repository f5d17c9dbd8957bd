"""The built-in family kinds: cut-in, overtake (approach from behind), slower or stopped
vehicle ahead (in a curve), crossing pedestrian/cyclist. Open loop: the ego keeps its speed
and lane (the search asks what the sensors see, not how a planner reacts)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from sensorgap.roads import RoadNetwork
from sensorgap.scenarios.family import (
    Family,
    FamilyKind,
    Param,
    ParamValue,
    Scenario,
    register_kind,
)
from sensorgap.scenarios.trajectory import (
    InfeasibleScenario,
    OffRoad,
    Trajectory,
    blend,
    time_axis,
)

F64 = NDArray[np.float64]

_ROAD_SETTINGS = {"road": None, "road_id": None, "target": None, "duration_s": 10.0}


def travel_direction(net: RoadNetwork, road_id: str, lane: int) -> int:
    """+1 if traffic in ``lane`` moves along +s, -1 against (from the lane graph)."""
    for _node, data in net.lane_graph.nodes(data=True):
        if data.get("road") == road_id and data.get("lane") == lane:
            return int(data["travel"])
    raise InfeasibleScenario(f"lane {lane} does not exist on road {road_id}")


def _on_road(net: RoadNetwork, road_id: str, s: F64, who: str) -> None:
    length = net.road(road_id).length
    lo, hi = float(np.min(s)), float(np.max(s))
    if lo < 0.0 or hi > length:
        raise OffRoad(f"{who} leaves road {road_id} (s from {lo:.1f} to {hi:.1f} m, "
                                 f"road is 0..{length:g} m)")


def lane_poses(net: RoadNetwork, road_id: str, lane: int, s: F64,
               travel: int) -> tuple[F64, F64, F64]:
    """Lane-centre x, y (m) and heading in the travel direction (rad) at road ``s``."""
    x, y, h, _ = net.lane_center(road_id, lane, s)
    return x, y, h + (math.pi if travel < 0 else 0.0)


def _follow(net: RoadNetwork, road_id: str, lane: int, s: F64, travel: int,
            t: F64) -> Trajectory:
    x, y, h = lane_poses(net, road_id, lane, s, travel)
    return Trajectory.from_path(t, x, y, h)


def _changing(net: RoadNetwork, road_id: str, lane_from: int, lane_to: int, s: F64,
              travel: int, t: F64, w: F64) -> Trajectory:
    xa, ya, ha = lane_poses(net, road_id, lane_from, s, travel)
    if np.any(w > 0.0):
        xb, yb, _ = lane_poses(net, road_id, lane_to, s, travel)
        xa, ya = (1.0 - w) * xa + w * xb, (1.0 - w) * ya + w * yb
    return Trajectory.from_path(t, xa, ya, ha)


def _f(p: Mapping[str, ParamValue], name: str) -> float:
    return float(p[name])


@register_kind
class CutIn(FamilyKind):
    """Target starts in ``target_lane`` ``dx0_m`` ahead of the ego's rear axle (negative:
    behind) and changes into ``ego_lane``; both at constant speed."""

    name = "cut_in"
    description = "cut-in from an adjacent lane into the ego lane"
    settings = {**_ROAD_SETTINGS, "ego_lane": None, "target_lane": None}
    parameters = (
        Param("ego_s0_m", 50.0, 700.0, unit="m"),
        Param("ego_speed_m_s", 15.0, 36.0, unit="m/s"),
        Param("target_speed_m_s", 10.0, 36.0, unit="m/s"),
        Param("dx0_m", -15.0, 60.0, unit="m"),
        Param("lc_start_s", 0.5, 6.0, unit="s"),
        Param("lc_duration_s", 2.5, 6.0, unit="s"),
        Param("shape", choices=("cosine", "quintic")),
    )

    def generate(self, family: Family, p: Mapping[str, ParamValue],
                 net: RoadNetwork) -> Scenario:
        st = family.settings
        rid = str(st["road_id"])
        t = time_axis(family.duration_s)
        tr = travel_direction(net, rid, int(st["ego_lane"]))
        s_e = _f(p, "ego_s0_m") + tr * _f(p, "ego_speed_m_s") * t
        s_t = _f(p, "ego_s0_m") + tr * (_f(p, "dx0_m") + _f(p, "target_speed_m_s") * t)
        _on_road(net, rid, s_e, "ego")
        _on_road(net, rid, s_t, "target")
        w = blend(str(p["shape"]), (t - _f(p, "lc_start_s")) / _f(p, "lc_duration_s"))
        ego = _follow(net, rid, int(st["ego_lane"]), s_e, tr, t)
        tgt = _changing(net, rid, int(st["target_lane"]), int(st["ego_lane"]), s_t, tr, t, w)
        return Scenario(ego, tgt, family.target_class)


@register_kind
class Overtake(FamilyKind):
    """Target approaches from behind in ``target_lane`` (rear and side field), passes the
    ego and, with ``merge = "yes"``, merges into the ego lane once its centre is
    ``merge_gap_m`` ahead of the ego's rear axle."""

    name = "overtake"
    description = "approach from behind and overtake, optionally merging in front"
    settings = {**_ROAD_SETTINGS, "ego_lane": None, "target_lane": None}
    parameters = (
        Param("ego_s0_m", 150.0, 700.0, unit="m"),
        Param("ego_speed_m_s", 15.0, 33.0, unit="m/s"),
        Param("speed_delta_m_s", 2.0, 15.0, unit="m/s"),
        Param("dx0_m", -80.0, -8.0, unit="m"),
        Param("merge", choices=("no", "yes")),
        Param("merge_gap_m", 6.0, 40.0, unit="m"),
        Param("merge_duration_s", 2.5, 5.0, unit="s"),
    )

    def generate(self, family: Family, p: Mapping[str, ParamValue],
                 net: RoadNetwork) -> Scenario:
        st = family.settings
        rid = str(st["road_id"])
        t = time_axis(family.duration_s)
        tr = travel_direction(net, rid, int(st["ego_lane"]))
        ve, dv, dx0 = _f(p, "ego_speed_m_s"), _f(p, "speed_delta_m_s"), _f(p, "dx0_m")
        s_e = _f(p, "ego_s0_m") + tr * ve * t
        s_t = _f(p, "ego_s0_m") + tr * (dx0 + (ve + dv) * t)
        _on_road(net, rid, s_e, "ego")
        _on_road(net, rid, s_t, "target")
        if p["merge"] == "yes":
            t_m = (_f(p, "merge_gap_m") - dx0) / dv
            w = blend("cosine", (t - t_m) / _f(p, "merge_duration_s"))
        else:
            w = np.zeros_like(t)
        ego = _follow(net, rid, int(st["ego_lane"]), s_e, tr, t)
        tgt = _changing(net, rid, int(st["target_lane"]), int(st["ego_lane"]), s_t, tr, t, w)
        return Scenario(ego, tgt, family.target_class)


@register_kind
class SlowAhead(FamilyKind):
    """A slower or stopped target ``gap0_m`` ahead in the ego lane (place it in a curve
    with ``ego_s0_m``); both at constant speed, so a gap that closes ends in a collision."""

    name = "slow_ahead"
    description = "slower or stopped vehicle ahead in the ego lane"
    settings = {**_ROAD_SETTINGS, "lane": None}
    parameters = (
        Param("ego_s0_m", 450.0, 900.0, unit="m"),
        Param("ego_speed_m_s", 15.0, 36.0, unit="m/s"),
        Param("target_speed_m_s", 0.0, 15.0, unit="m/s"),
        Param("gap0_m", 40.0, 220.0, unit="m"),
    )

    def generate(self, family: Family, p: Mapping[str, ParamValue],
                 net: RoadNetwork) -> Scenario:
        st = family.settings
        rid, lane = str(st["road_id"]), int(st["lane"])
        t = time_axis(family.duration_s)
        tr = travel_direction(net, rid, lane)
        s_e = _f(p, "ego_s0_m") + tr * _f(p, "ego_speed_m_s") * t
        s_t = _f(p, "ego_s0_m") + tr * (_f(p, "gap0_m") + _f(p, "target_speed_m_s") * t)
        _on_road(net, rid, s_e, "ego")
        _on_road(net, rid, s_t, "target")
        return Scenario(_follow(net, rid, lane, s_e, tr, t), _follow(net, rid, lane, s_t, tr, t),
                        family.target_class)


@register_kind
class Crossing(FamilyKind):
    """A pedestrian or cyclist crosses the road ``cross_ahead_m`` ahead of the ego's start,
    at constant speed, from the ego's ``side``; timed so that it reaches the ego lane's
    centre ``conflict_offset_s`` after the ego's rear axle reaches the crossing line
    (negative: before)."""

    name = "crossing"
    description = "pedestrian or cyclist crossing in front of the ego"
    settings = {**_ROAD_SETTINGS, "ego_lane": None, "duration_s": 6.0}
    parameters = (
        Param("ego_s0_m", 85.0, 98.0, unit="m"),
        Param("ego_speed_m_s", 4.0, 13.0, unit="m/s"),
        Param("cross_ahead_m", 15.0, 60.0, unit="m"),
        Param("target_speed_m_s", 0.8, 2.5, unit="m/s"),
        Param("conflict_offset_s", -1.5, 1.5, unit="s"),
        Param("side", choices=("right", "left")),
    )

    def generate(self, family: Family, p: Mapping[str, ParamValue],
                 net: RoadNetwork) -> Scenario:
        st = family.settings
        rid, lane = str(st["road_id"]), int(st["ego_lane"])
        t = time_axis(family.duration_s)
        tr = travel_direction(net, rid, lane)
        ve = _f(p, "ego_speed_m_s")
        s_e = _f(p, "ego_s0_m") + tr * ve * t
        s_c = _f(p, "ego_s0_m") + tr * _f(p, "cross_ahead_m")
        _on_road(net, rid, s_e, "ego")
        _on_road(net, rid, np.array([s_c]), "crossing line")
        inner, outer = net.lane_edges(rid, lane, np.array([s_c]))
        t_c = 0.5 * float(inner[0] + outer[0])
        right = -tr  # the ego's right in road t: -t when driving along +s
        side = right if p["side"] == "right" else -right
        t_p = _f(p, "cross_ahead_m") / ve + _f(p, "conflict_offset_s")
        lat = t_c + side * _f(p, "target_speed_m_s") * (t_p - t)
        x, y = net.road_to_world(rid, np.full_like(t, s_c), lat)
        _, _, h = net.reference_line(rid, np.array([s_c]))
        tgt = Trajectory.from_path(t, x, y, np.full_like(t, float(h[0]) - side * 0.5 * math.pi))
        return Scenario(_follow(net, rid, lane, s_e, tr, t), tgt, family.target_class)
