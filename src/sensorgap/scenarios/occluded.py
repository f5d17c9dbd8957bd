"""Family kinds where another road user hides the target (issue #17): a car cutting in
from beyond (or in front of) a truck in the next lane, a pedestrian stepping out between
parked cars, and a lead vehicle cutting out to reveal a stopped car. The occluders are
part of the scene (``ScenarioBatch.occluders``): they hide the target from the sensors
(``coverage.occluders``) but are not collision partners of the ego in this open-loop
search.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sensorgap.config import TargetConfig, load_target
from sensorgap.roads import RoadNetwork
from sensorgap.scenarios.batch import (
    OccluderTracks,
    ScenarioBatch,
    blend_batch,
    lane_progress,
)
from sensorgap.scenarios.family import Columns, Family, Param, register_kind
from sensorgap.scenarios.kinds import (
    _ROAD_SETTINGS,
    Crossing,
    _col,
    _LaneKind,
)

F64 = NDArray[np.float64]

#: Gap between a parked car's side and the kerb (the outer edge of the outermost driving
#: lane), m (estimate: parked at the kerb, wheels ~0.2 m off the lane marking).
PARKED_CLEARANCE_M = 0.2


def kerbs(net: RoadNetwork, rid: str, s: F64) -> tuple[F64, F64]:
    """Road t (m) of the kerbs at road ``s`` (m): the outer border of the outermost lane
    of type ``driving`` on the left and on the right (the road's extent on a side without
    one)."""
    road = net.road(rid)
    left, right = (np.asarray(a, dtype=np.float64).copy() for a in net.road_extents(rid, s))
    secs = road.section_index(s)
    for i in np.unique(secs):
        m = secs == i
        sec = road.sections[int(i)]
        for lanes, out in ((sec.left, left), (sec.right, right)):
            ids = [ln.id for ln in lanes if ln.type == "driving"]
            if ids:
                out[m] = net.lane_edges(rid, max(ids, key=abs), s[m])[1]
    return left, right


def occluder_class(family: Family) -> TargetConfig:
    """The config of ``family``'s occluder class (its length, width, height, m): the one
    of the targets file it was loaded with (``Family.occluder``: a run's recorded copy),
    else the shipped one (hostile round 30: the shipped classes, cached, were used always:
    a run searched with a 12 m car was exported with the shipped 4.5 m one)."""
    if family.occluder is not None:
        return family.occluder
    return load_target(str(family.settings["occluder"]))


def target_class(family: Family) -> TargetConfig:
    """The config of ``family``'s target class, from the same targets file as
    ``occluder_class``."""
    if family.target_config is not None:
        return family.target_config
    return load_target(family.target_class)


def _occluder(family: Family, label: str, x: F64, y: F64, h: F64, t: F64) -> OccluderTracks:
    """An occluder of class ``family.settings['occluder']`` along (B, T) centre states."""
    from sensorgap.scenarios.batch import tracks_from_path

    cfg = occluder_class(family)
    return OccluderTracks(
        label,
        tracks_from_path(t, x, y, h),
        float(cfg.length_m),
        float(cfg.width_m),
        float(cfg.height_m),
    )


@register_kind
class CutInBehindTruck(_LaneKind):
    """The ego overtakes a slower truck (class ``occluder``) driving in ``occluder_lane``,
    the lane next to ``ego_lane``; a car (the target) drives ``target_gap_m`` (its rear to
    the truck's front, along the road) ahead of the truck in ``target_lane``,
    ``speed_delta_m_s`` faster than the truck, and changes into the ego lane (``lc_start_s``,
    ``lc_duration_s`` for the whole lateral move, ``shape``). With ``target_lane`` one lane
    beyond the truck's (a three-lane carriageway) the car is in the truck's shadow from the
    start and crosses the truck's lane in front of it on its way into the ego lane: it
    emerges from the shadow only when its inner side passes the sight line past the
    truck's front corner (about the truck's inner side), by when it is already moving
    towards the ego lane at speed. ``target_lane = occluder_lane`` is the car pulling out
    from just in front of the truck (hidden only while the ego is far behind)."""

    name = "cut_in_behind_occluder"
    description = "car cuts in from in front of / beyond a truck into the ego lane"
    settings = {
        **_ROAD_SETTINGS,
        "ego_lane": None,
        "occluder_lane": None,
        "target_lane": None,
        "occluder": "truck",
    }
    parameters = (
        Param("ego_s0_m", 50.0, 500.0, unit="m"),
        Param("ego_speed_m_s", 22.0, 36.0, unit="m/s"),
        Param("truck_speed_m_s", 15.0, 25.0, unit="m/s"),
        Param("truck_dx_m", 10.0, 60.0, unit="m"),
        Param("target_gap_m", 1.0, 15.0, unit="m"),
        Param("speed_delta_m_s", 0.0, 6.0, unit="m/s"),
        Param("lc_start_s", 0.5, 6.0, unit="s"),
        Param("lc_duration_s", 2.5, 5.0, unit="s"),
        Param("shape", choices=("cosine", "quintic")),
    )

    def generate_batch(self, family: Family, cols: Columns, net: RoadNetwork) -> ScenarioBatch:
        rid, lane, tr, t = self._start(family, "ego_lane")
        side_lane = int(family.settings["target_lane"])
        truck_lane = int(family.settings["occluder_lane"])
        truck = occluder_class(family)
        car = target_class(family)
        s0 = _col(cols, "ego_s0_m")
        s_e = lane_progress(s0, tr, 0.0, _col(cols, "ego_speed_m_s"), t)
        v_truck = _col(cols, "truck_speed_m_s")
        s_k = lane_progress(s0, tr, _col(cols, "truck_dx_m"), v_truck, t)
        ahead = 0.5 * truck.length_m + _col(cols, "target_gap_m") + 0.5 * car.length_m
        s_t = lane_progress(
            s0, tr, _col(cols, "truck_dx_m") + ahead, v_truck + _col(cols, "speed_delta_m_s"), t
        )
        checks = self._off_road(net, rid, {"ego": s_e, "target": s_t, "truck": s_k})
        u = (t - _col(cols, "lc_start_s")) / _col(cols, "lc_duration_s")
        w = blend_batch(np.asarray(cols["shape"]).astype(str), u)
        ego = self._follow(family, rid, lane, s_e, tr, t)
        tgt = self._changing(family, rid, side_lane, lane, s_t, tr, t, w)
        kx, ky, kh = family.lane_table(rid, truck_lane).poses(s_k, tr)
        b = self._batch(t, ego, tgt, family, checks)
        b.occluders = (_occluder(family, str(family.settings["occluder"]), kx, ky, kh, t),)
        return b


@register_kind
class CutOutReveal(_LaneKind):
    """A lead vehicle (class ``occluder``) drives ``lead_gap_m`` (centre to the ego's rear
    axle) ahead in ``lane`` at the ego's speed, hiding a stopped or slow target ahead; at
    ``cut_out_s`` it changes into ``target_lane`` over ``lc_duration_s`` and leaves the lane
    ``reveal_s`` before it would reach the target (the classic late cut-out that reveals a
    stopped car; 0: an evasive swerve at the last moment, a cosine lane change of 2 s peaks
    at about 4.3 m/s2 lateral). The target stands where that timing puts it:
    ``(cut_out_s + lc_duration_s + reveal_s) x closing speed`` plus half the two lengths
    ahead of the lead."""

    name = "cut_out_reveal"
    description = "lead vehicle cuts out and reveals a stopped vehicle ahead"
    settings = {**_ROAD_SETTINGS, "lane": None, "target_lane": None, "occluder": "car"}
    parameters = (
        Param("ego_s0_m", 50.0, 400.0, unit="m"),
        Param("ego_speed_m_s", 15.0, 33.0, unit="m/s"),
        Param("lead_gap_m", 12.0, 50.0, unit="m"),
        Param("target_speed_m_s", 0.0, 8.0, unit="m/s"),
        Param("cut_out_s", 0.2, 4.0, unit="s"),
        Param("lc_duration_s", 2.0, 4.5, unit="s"),
        Param("reveal_s", 0.0, 3.0, unit="s"),
    )

    def generate_batch(self, family: Family, cols: Columns, net: RoadNetwork) -> ScenarioBatch:
        rid, lane, tr, t = self._start(family, "lane")
        other = int(family.settings["target_lane"])
        lead_cfg = occluder_class(family)
        car = target_class(family)
        s0 = _col(cols, "ego_s0_m")
        ve = _col(cols, "ego_speed_m_s")
        vt = _col(cols, "target_speed_m_s")
        t0, md = _col(cols, "cut_out_s"), _col(cols, "lc_duration_s")
        closing = ve - vt  # > 0: the ego is faster than any target of the range
        gap = (t0 + md + _col(cols, "reveal_s")) * closing + 0.5 * (
            lead_cfg.length_m + car.length_m
        )
        s_e = lane_progress(s0, tr, 0.0, ve, t)
        s_l = lane_progress(s0, tr, _col(cols, "lead_gap_m"), ve, t)
        s_t = lane_progress(s0, tr, _col(cols, "lead_gap_m") + gap, vt, t)
        checks = self._off_road(net, rid, {"ego": s_e, "target": s_t, "lead vehicle": s_l})
        w = blend_batch(np.full(len(s0), "cosine"), (t - t0) / md)
        ego = self._follow(family, rid, lane, s_e, tr, t)
        tgt = self._follow(family, rid, lane, s_t, tr, t)
        lx, ly, ha = self._blend(family, rid, lane, other, s_l, tr, w)
        b = self._batch(t, ego, tgt, family, checks)
        b.occluders = (
            _occluder(family, "lead " + str(family.settings["occluder"]), lx, ly, ha, t),
        )
        return b


@register_kind
class CrossingBehindParked(Crossing):
    """``crossing`` from the ego's right, stepping out between two cars (class
    ``occluder``) parked at the kerb beside the outermost lane, ``parked_gap_m`` apart
    (bumper to bumper) around the crossing line: the pedestrian or cyclist is hidden by
    them until it steps into the lane (Euro NCAP's obstructed near-side crossing: public
    anchor for the geometry and speeds, docs/search.md)."""

    name = "crossing_behind_parked"
    description = "pedestrian steps out between parked cars in front of the ego"
    settings = {**Crossing.settings, "duration_s": 5.0, "occluder": "car"}

    def footway_edges(self, net: RoadNetwork, rid: str, s: F64) -> tuple[F64, F64]:
        """The kerbs (``kerbs``): the pedestrian starts ``CURB_OFFSET_M`` (2 m) beyond
        the kerb, level with the outer sides of the cars parked there (0.2 m clearance +
        1.8 m width)."""
        return kerbs(net, rid, s)

    parameters = (
        Param("ego_s0_m", 85.0, 98.0, unit="m"),
        Param("ego_speed_m_s", 2.8, 16.7, unit="m/s"),
        Param("cross_ahead_m", 15.0, 80.0, unit="m"),
        Param("target_speed_m_s", 0.8, 2.5, unit="m/s"),
        Param("conflict_offset_s", -1.5, 1.0, unit="s"),
        Param("parked_gap_m", 0.8, 3.0, unit="m"),
        Param("side", choices=("right",)),
    )

    def generate_batch(self, family: Family, cols: Columns, net: RoadNetwork) -> ScenarioBatch:
        b = super().generate_batch(family, cols, net)
        rid = str(family.settings["road_id"])
        tr = self._start(family, "ego_lane")[2]
        t = b.t
        parked = occluder_class(family)
        s_c = (_col(cols, "ego_s0_m") + tr * _col(cols, "cross_ahead_m"))[:, 0]
        s_c = np.clip(s_c, 0.0, net.road(rid).length)
        t_left, t_right = kerbs(net, rid, s_c)
        # the ego's right in road t is -t when driving along +s: that side's kerb
        kerb = np.where(tr > 0, t_right, t_left)
        out = -1.0 if tr > 0 else 1.0  # direction away from the road on that side
        lat = kerb + out * (PARKED_CLEARANCE_M + 0.5 * parked.width_m)
        half = 0.5 * _col(cols, "parked_gap_m")[:, 0] + 0.5 * parked.length_m
        occs = []
        for k, sign in enumerate((-1.0, 1.0)):
            s_p = np.clip(s_c + sign * half, 0.0, net.road(rid).length)
            xr, yr, hr = net.reference_line(rid, s_p)
            x = xr - lat * np.sin(hr)
            y = yr + lat * np.cos(hr)
            h = hr + (0.0 if tr > 0 else math.pi)
            shape = (len(s_c), len(t))
            occs.append(
                _occluder(
                    family,
                    f"parked {parked.name} {k + 1}",
                    np.broadcast_to(x[:, None], shape),
                    np.broadcast_to(y[:, None], shape),
                    np.broadcast_to(h[:, None], shape),
                    t,
                )
            )
        # the pedestrian waits on the footway (``CURB_OFFSET_M`` beyond the lane) level with
        # the parked cars' outer sides (clearance + width: 2.0 m for a 1.8 m car)
        b.occluders = tuple(occs)
        return b
