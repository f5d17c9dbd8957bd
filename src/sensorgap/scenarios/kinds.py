"""The built-in family kinds: cut-in, overtake (approach from behind), slower or stopped
vehicle ahead (in a curve), crossing pedestrian/cyclist. Open loop: the ego keeps its speed
and lane (the search asks what the sensors see, not how a planner reacts).

Each kind generates a whole batch at once (``generate_batch``): B parameter vectors ->
(B, T) states, lane centres from the family's ``LaneTable``; one scenario is a batch of one.
"""

from __future__ import annotations

import math
from functools import cache
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from sensorgap.roads import RoadNetwork
from sensorgap.scenarios.batch import (
    ScenarioBatch,
    Tracks,
    blend_batch,
    lane_progress,
    off_road,
    tracks_from_path,
)
from sensorgap.scenarios.family import Columns, Family, FamilyKind, Param, register_kind
from sensorgap.scenarios.trajectory import InfeasibleScenario, time_axis

F64 = NDArray[np.float64]

#: How far beside the outermost lane a crossing pedestrian or cyclist may be (its footway or
#: verge), m (estimate: urban footway width).
FOOTWAY_M = 5.0
#: Where a crossing target waits and where it stops: this far beyond the outermost lane, m
#: (estimate: on the footway, clear of the kerb).
CURB_OFFSET_M = 2.0
#: Acceleration and deceleration of a crossing target, m/s2 (estimates: pedestrians start
#: walking at ~1-1.5 m/s2, cyclists pull away at ~1.5-2.5 m/s2; both within LIMITS).
CROSSING_ACCEL_M_S2 = {"pedestrian": 1.5, "bike": 2.0}

_ROAD_SETTINGS = {"road": None, "road_id": None, "target": None, "duration_s": 10.0}


def travel_direction(net: RoadNetwork, road_id: str, lane: int) -> int:
    """+1 if traffic in ``lane`` moves along +s, -1 against (from the lane graph)."""
    return _travel(id(net), net, road_id, lane)


@cache
def _travel(_key: int, net: RoadNetwork, road_id: str, lane: int) -> int:
    for _node, data in net.lane_graph.nodes(data=True):
        if data.get("road") == road_id and data.get("lane") == lane:
            return int(data["travel"])
    raise InfeasibleScenario(f"lane {lane} does not exist on road {road_id}")


def _col(cols: Columns, name: str) -> F64:
    """A float parameter column as (B, 1) for broadcasting against time."""
    return np.asarray(cols[name], dtype=np.float64)[:, None]


def _is(cols: Columns, name: str, value: str) -> NDArray[np.bool_]:
    return np.asarray(cols[name]).astype(str) == value


class _LaneKind(FamilyKind):
    """Shared machinery: objects moving along lanes at constant speed."""

    def _start(self, family: Family, lane_key: str) -> tuple[str, int, int, F64]:
        st = family.settings
        rid = str(st["road_id"])
        lane = int(st[lane_key])
        return rid, lane, travel_direction(family.network, rid, lane), time_axis(family.duration_s)

    @staticmethod
    def _follow(family: Family, rid: str, lane: int, s: F64, travel: int, t: F64) -> Tracks:
        return family.lane_table(rid, lane).tracks(s, travel, t)

    @staticmethod
    def _blend(
        family: Family, rid: str, lane_from: int, lane_to: int, s: F64, travel: int, w: F64
    ) -> tuple[F64, F64, F64]:
        """Poses (x, y in m, heading in rad: ``lane_from``'s) at road ``s`` (m) of a lane
        change from ``lane_from`` to ``lane_to``, ``w`` (0..1) of the way across."""
        xa, ya, ha = family.lane_table(rid, lane_from).poses(s, travel)
        xb, yb, _ = family.lane_table(rid, lane_to).poses(s, travel)
        return (1.0 - w) * xa + w * xb, (1.0 - w) * ya + w * yb, ha

    @staticmethod
    def _changing(
        family: Family, rid: str, lane_from: int, lane_to: int, s: F64, travel: int, t: F64, w: F64
    ) -> Tracks:
        x, y, h = _LaneKind._blend(family, rid, lane_from, lane_to, s, travel, w)
        return tracks_from_path(t, x, y, h)

    @staticmethod
    def _off_road(
        net: RoadNetwork, rid: str, tracks: dict[str, F64]
    ) -> list[tuple[NDArray[np.bool_], list[str]]]:
        """Per named track (its road s, m), the rows whose s leaves road ``rid``, with the
        reason (``off_road``), in the order given: the ``checks`` of ``_batch``."""
        length = net.road(rid).length
        return [off_road(s, length, rid, who) for who, s in tracks.items()]

    @staticmethod
    def _batch(
        t: F64,
        ego: Tracks,
        target: Tracks,
        family: Family,
        checks: list[tuple[NDArray[np.bool_], list[str]]],
    ) -> ScenarioBatch:
        b = ScenarioBatch(
            t, ego, target, np.ones(len(ego.x), dtype=bool), [""] * len(ego.x), family.target_class
        )
        for bad, notes in checks:
            b.reject(bad, notes, offroad=True)
        return b


@register_kind
class CutIn(_LaneKind):
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

    def generate_batch(self, family: Family, cols: Columns, net: RoadNetwork) -> ScenarioBatch:
        rid, lane, tr, t = self._start(family, "ego_lane")
        s0 = _col(cols, "ego_s0_m")
        s_e = lane_progress(s0, tr, 0.0, _col(cols, "ego_speed_m_s"), t)
        s_t = lane_progress(s0, tr, _col(cols, "dx0_m"), _col(cols, "target_speed_m_s"), t)
        checks = self._off_road(net, rid, {"ego": s_e, "target": s_t})
        u = (t - _col(cols, "lc_start_s")) / _col(cols, "lc_duration_s")
        w = blend_batch(np.asarray(cols["shape"]).astype(str), u)
        ego = self._follow(family, rid, lane, s_e, tr, t)
        tgt = self._changing(family, rid, int(family.settings["target_lane"]), lane, s_t, tr, t, w)
        return self._batch(t, ego, tgt, family, checks)


@register_kind
class Overtake(_LaneKind):
    """Target approaches from behind in ``target_lane`` (rear and side field) at
    ``speed_delta_m_s`` faster than the ego, passes, merges into the ego lane once its
    centre is ``merge_gap_m`` ahead of the ego's rear axle (a cosine lane change of
    ``merge_duration_s``) and, ``brake_delay_s`` after the merge, brakes at ``decel_m_s2``
    to ``final_delta_m_s`` below the ego's speed (0 at most): the classic overtake-and-cut-
    in-then-brake, so the ego closes in on a target that came out of its blind side."""

    name = "overtake"
    description = "approach from behind, overtake, cut in ahead and brake"
    settings = {**_ROAD_SETTINGS, "ego_lane": None, "target_lane": None}
    parameters = (
        Param("ego_s0_m", 150.0, 700.0, unit="m"),
        Param("ego_speed_m_s", 15.0, 33.0, unit="m/s"),
        Param("speed_delta_m_s", 4.0, 15.0, unit="m/s"),
        Param("dx0_m", -40.0, -8.0, unit="m"),
        Param("merge_gap_m", 8.0, 30.0, unit="m"),
        Param("merge_duration_s", 2.5, 5.0, unit="s"),
        Param("brake_delay_s", 0.0, 1.5, unit="s"),
        Param("decel_m_s2", 3.0, 7.0, unit="m/s2"),
        Param("final_delta_m_s", 5.0, 25.0, unit="m/s"),
    )

    def generate_batch(self, family: Family, cols: Columns, net: RoadNetwork) -> ScenarioBatch:
        rid, lane, tr, t = self._start(family, "ego_lane")
        ve, dv, dx0 = (
            _col(cols, "ego_speed_m_s"),
            _col(cols, "speed_delta_m_s"),
            _col(cols, "dx0_m"),
        )
        s0 = _col(cols, "ego_s0_m")
        s_e = lane_progress(s0, tr, 0.0, ve, t)
        # an overtake needs a faster target and a braking one: rows without are computed
        # with stand-ins and rejected (hostile check: a division by zero, exit 1)
        a_in = _col(cols, "decel_m_s2")
        slow, no_brake = dv[:, 0] <= 0.0, a_in[:, 0] <= 0.0
        dv = np.where(dv > 0.0, dv, 1.0)
        md = _col(cols, "merge_duration_s")
        v0 = ve + dv
        vf = np.maximum(ve - _col(cols, "final_delta_m_s"), 0.0)
        a = np.where(a_in > 0.0, a_in, 1.0)
        # a speed difference or deceleration of a few 1e-300 (5e-324 is a valid float)
        # makes the merge time or the braking time +inf: the merge, or the braking's end,
        # never comes, which the formulas below then compute (np.minimum, np.clip, the
        # blend's clip; no inf or NaN reaches a position). Hostile round 22: numpy's
        # overflow warning was printed.
        with np.errstate(over="ignore"):
            t_m = (_col(cols, "merge_gap_m") - dx0) / dv
            td = (v0 - vf) / a
        t_b = t_m + md + _col(cols, "brake_delay_s")
        u = np.clip(t - t_b, 0.0, td)
        travelled = (
            v0 * np.minimum(t, t_b) + v0 * u - 0.5 * a * u * u + vf * np.maximum(t - t_b - td, 0.0)
        )
        s_t = s0 + tr * (dx0 + travelled)
        checks = self._off_road(net, rid, {"ego": s_e, "target": s_t})
        w = blend_batch(np.full(len(s0), "cosine"), (t - t_m) / md)
        ego = self._follow(family, rid, lane, s_e, tr, t)
        tgt = self._changing(family, rid, int(family.settings["target_lane"]), lane, s_t, tr, t, w)
        batch = self._batch(t, ego, tgt, family, checks)
        batch.reject(slow, "an overtake needs the target faster than the ego (speed_delta_m_s > 0)")
        batch.reject(no_brake, "the target's braking needs decel_m_s2 > 0")
        return batch


@register_kind
class SlowAhead(_LaneKind):
    """A slower or stopped target ``gap0_m`` ahead in the ego lane (place it in a curve
    with ``ego_s0_m``); both at constant speed, so a gap that closes ends in a collision."""

    name = "slow_ahead"
    description = "slower or stopped vehicle ahead in the ego lane"
    #: before t = 0 both kept their speeds, the target farther ahead: one within reach at
    #: t = 0 had earlier chances to be detected that the encounter would leave out
    start_out_of_reach = True
    settings = {**_ROAD_SETTINGS, "lane": None, "duration_s": 18.0}
    parameters = (
        Param("ego_s0_m", 100.0, 600.0, unit="m"),
        Param("ego_speed_m_s", 15.0, 36.0, unit="m/s"),
        Param("target_speed_m_s", 0.0, 15.0, unit="m/s"),
        Param("gap0_m", 250.0, 420.0, unit="m"),
    )

    def generate_batch(self, family: Family, cols: Columns, net: RoadNetwork) -> ScenarioBatch:
        rid, lane, tr, t = self._start(family, "lane")
        s0 = _col(cols, "ego_s0_m")
        s_e = lane_progress(s0, tr, 0.0, _col(cols, "ego_speed_m_s"), t)
        s_t = lane_progress(s0, tr, _col(cols, "gap0_m"), _col(cols, "target_speed_m_s"), t)
        checks = self._off_road(net, rid, {"ego": s_e, "target": s_t})
        ego = self._follow(family, rid, lane, s_e, tr, t)
        tgt = self._follow(family, rid, lane, s_t, tr, t)
        return self._batch(t, ego, tgt, family, checks)


#: Slowest target or ego speed of a crossing, m/s (an estimate: below 1 cm/s a party
#: stands; the crossing's timing divides by both speeds).
MIN_CROSSING_SPEED_M_S = 0.01


@register_kind
class Crossing(_LaneKind):
    """A pedestrian or cyclist crosses the road ``cross_ahead_m`` ahead of the ego's start
    from the ego's ``side``: it waits on the footway ``CURB_OFFSET_M`` beyond the outermost
    lane, accelerates at ``CROSSING_ACCEL_M_S2`` to ``target_speed_m_s``, crosses, and stops
    the same distance beyond the far side; timed so that it reaches the ego lane's centre
    ``conflict_offset_s`` after the ego's rear axle reaches the crossing line (negative:
    before). Targets that are already under way at t = 0 start on their path."""

    name = "crossing"
    description = "pedestrian or cyclist crossing in front of the ego"
    settings = {**_ROAD_SETTINGS, "ego_lane": None, "duration_s": 6.0}
    parameters: ClassVar[tuple[Param, ...]] = (
        Param("ego_s0_m", 85.0, 98.0, unit="m"),
        Param("ego_speed_m_s", 4.0, 13.0, unit="m/s"),
        Param("cross_ahead_m", 15.0, 60.0, unit="m"),
        Param("target_speed_m_s", 0.8, 2.5, unit="m/s"),
        Param("conflict_offset_s", -1.5, 1.5, unit="s"),
        Param("side", choices=("right", "left")),
    )

    def footway_edges(self, net: RoadNetwork, rid: str, s: F64) -> tuple[F64, F64]:
        """Road t (m) of the left and right edges the crossing starts and ends
        ``CURB_OFFSET_M`` beyond, at road ``s`` (m): the outer borders of the road's
        outermost lanes (footways included)."""
        return net.road_extents(rid, s)

    def generate_batch(self, family: Family, cols: Columns, net: RoadNetwork) -> ScenarioBatch:
        rid, lane, tr, t = self._start(family, "ego_lane")
        ve = _col(cols, "ego_speed_m_s")
        s0 = _col(cols, "ego_s0_m")
        s_e = lane_progress(s0, tr, 0.0, ve, t)
        s_c = s0 + tr * _col(cols, "cross_ahead_m")  # (B, 1)
        checks = self._off_road(net, rid, {"ego": s_e, "crossing line": s_c})
        s_cc = np.clip(s_c[:, 0], 0.0, net.road(rid).length)
        inner, outer = net.lane_edges(rid, lane, s_cc)
        t_c = (0.5 * (inner + outer))[:, None]
        right = -tr  # the ego's right in road t: -t when driving along +s
        side = np.where(_is(cols, "side", "right"), right, -right).astype(np.float64)[:, None]
        t_left, t_right = self.footway_edges(net, rid, s_cc)
        t_left, t_right = t_left[:, None], t_right[:, None]
        # from the footway on `side` (road t on that side) to the one opposite
        start = np.where(side > 0, t_left + CURB_OFFSET_M, t_right - CURB_OFFSET_M)
        end = np.where(side > 0, t_right - CURB_OFFSET_M, t_left + CURB_OFFSET_M)
        d_near, d_total = np.abs(start - t_c), np.abs(start - end)
        a = CROSSING_ACCEL_M_S2.get(family.target_class, 1.5)
        # a crossing needs both to move: the timing divides by both speeds (a standing
        # target never crosses, a standing ego never reaches the crossing line); such rows
        # are computed with a stand-in speed and rejected (hostile round nine: exit 1)
        v_in, ve_in = _col(cols, "target_speed_m_s"), ve
        still = (v_in[:, 0] < MIN_CROSSING_SPEED_M_S) | (ve_in[:, 0] < MIN_CROSSING_SPEED_M_S)
        ve = np.where(ve_in >= MIN_CROSSING_SPEED_M_S, ve_in, 1.0)
        v = np.where(v_in >= MIN_CROSSING_SPEED_M_S, v_in, 1.0)
        v = np.minimum(v, np.sqrt(a * d_total))  # triangular
        ta, da = v / a, v * v / (2.0 * a)
        t_cruise = (d_total - 2.0 * da) / v
        t_end = 2.0 * ta + t_cruise
        # time after departure at which the lane centre is reached
        tau_c = np.where(
            d_near <= da,
            np.sqrt(2.0 * d_near / a),
            np.where(
                d_near <= d_total - da,
                ta + (d_near - da) / v,
                t_end - np.sqrt(np.maximum(2.0 * (d_total - d_near) / a, 0.0)),
            ),
        )
        t_p = _col(cols, "cross_ahead_m") / ve + _col(cols, "conflict_offset_s")
        tau = np.clip(t - (t_p - tau_c), 0.0, t_end)
        dist = np.where(
            tau <= ta,
            0.5 * a * tau * tau,
            np.where(
                tau <= ta + t_cruise, da + v * (tau - ta), d_total - 0.5 * a * (t_end - tau) ** 2
            ),
        )
        lat = start - side * dist
        xr, yr, hr = net.reference_line(rid, s_cc)
        xr, yr, hr = xr[:, None], yr[:, None], hr[:, None]
        x, y = xr - lat * np.sin(hr), yr + lat * np.cos(hr)
        tgt = tracks_from_path(t, x, y, np.broadcast_to(hr - side * 0.5 * math.pi, x.shape))
        ego = self._follow(family, rid, lane, s_e, tr, t)
        batch = self._batch(t, ego, tgt, family, checks)
        batch.reject(
            still,
            "a crossing needs the target and the ego to move (target_speed_m_s and "
            f"ego_speed_m_s at least {MIN_CROSSING_SPEED_M_S:g} m/s)",
        )
        return batch
