"""The ``maneuver`` export style: a scenario a system under test can drive through.

Instead of replaying timed polylines, each file describes the encounter as OpenSCENARIO
actions (docs/export.md, "maneuver style"):

* ``Ego``: its initial lane position (``LanePosition``, s = ``$ego_s0_m``) and speed
  (``$ego_speed_m_s``), then no motion action: a simulator's default controller keeps lane
  and speed. It carries an ``ObjectController`` ``SystemUnderTest`` (property
  ``esminiController = $ego_controller``) that an event at the first step activates on
  the longitudinal and lateral domains given by ``$ego_controller_longitudinal`` and
  ``$ego_controller_lateral`` (default false: the simulator's default controller keeps
  lane and speed).
* The target (and the occluders of issue #17) start at lane positions relative to the
  ego's start (expressions over the declared parameters) with their planned speeds; their
  behaviour is ``LaneChangeAction`` (the family's blend shape and duration),
  ``SpeedAction`` (rate-limited braking) or a timed ``FollowTrajectoryAction`` (crossing
  pedestrians and cyclists), each started by a condition relative to the ego (longitudinal
  ``RelativeDistanceCondition`` in road coordinates: the planned gap at the planned start)
  so an ego that drives differently still meets the encounter as planned.
* StopTrigger: the ego collides with the target, or the duration has passed.

``maneuver_triggers`` lists the relative triggers with their planned times; ``simulate``
compares the relative geometry at esmini's trigger with the plan's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scenariogeneration import xosc

from sensorgap.config import TargetConfig, load_target
from sensorgap.export.params import Expressions, number
from sensorgap.export.spec import ScenarioSpec
from sensorgap.scenarios.kinds import CROSSING_ACCEL_M_S2, travel_direction
from sensorgap.scenarios.trajectory import Trajectory

EGO = "Ego"
TARGET = "Target"
#: The ego's replaceable controller and its default esmini type (assigned, not active).
SUT_CONTROLLER = "SystemUnderTest"
DEFAULT_EGO_CONTROLLER = "ExternalController"
#: Declared parameters of the ego's controller (string values as written).
EGO_CONTROLLER_PARAMETERS: dict[str, str | float] = {
    "ego_controller": DEFAULT_EGO_CONTROLLER, "ego_controller_longitudinal": "false",
    "ego_controller_lateral": "false"}
#: OpenSCENARIO dynamics shape per lane-change blend. The cosine blend is the sinusoidal
#: shape exactly. The quintic (minimum-jerk) blend has no counterpart; of the standard's
#: shapes sinusoidal is the closest in position (largest difference 4.4 % of the lane
#: offset; cubic 5.4 %, linear 14.7 %) and in peak lateral speed (1.57 x offset /
#: duration; quintic 1.88, cubic 1.5); measured in esmini on 8 quintic cut-ins: 0.17-0.39
#: m from the plan with sinusoidal, 0.21-0.40 m with cubic (docs/export.md).
LANE_CHANGE_SHAPE = {"cosine": "sinusoidal", "quintic": "sinusoidal"}


@dataclass(frozen=True)
class PlannedTrigger:
    """An event started by a condition relative to another entity: ``actor``'s event
    ``event`` starts when it is at the planned relative position to ``reference``, at
    ``time_s`` (s) in the plan."""

    event: str
    actor: str
    reference: str
    time_s: float


@dataclass
class _Build:
    """What one scenario's maneuver file is assembled from."""

    spec: ScenarioSpec
    minor: int
    p: Expressions
    entities: list[tuple[str, Any]] = field(default_factory=list)
    init: list[tuple[str, Any]] = field(default_factory=list)
    events: dict[str, list[xosc.Event]] = field(default_factory=dict)
    triggers: list[PlannedTrigger] = field(default_factory=list)

    @property
    def st(self) -> dict[str, Any]:
        return self.spec.family.settings

    def event(self, actor: str, name: str, action: Any, trigger: Any) -> xosc.Event:
        ev = xosc.Event(name, xosc.Priority.override if self.minor >= 2
                        else xosc.Priority.overwrite)
        ev.add_action(f"{name}_action", action)
        ev.add_trigger(trigger)
        self.events.setdefault(actor, []).append(ev)
        return ev


def _fmt(v: float) -> float:
    return float(round(v, 6))


def origin_offset(cfg: TargetConfig) -> float:
    """Distance (m) from an entity's exported origin (vehicles: rear axle; pedestrians:
    box centre) forward to its box centre (see ``xosc.target_origin_offset``)."""
    from sensorgap.export.xosc import target_origin_offset

    return target_origin_offset(cfg)


def lane_speed_factor(spec: ScenarioSpec, lane: int, s0: float, s1: float) -> float:
    """Length of ``lane``'s centre line per metre of road s between road s ``s0`` and
    ``s1`` (m). The plan moves entities along the road's reference line s; OpenSCENARIO
    speeds are along the lane, which in a curve is longer (outer side) or shorter: the
    exported speed is the planned one times this factor, so the entity covers the planned
    s over that stretch (to the extent the curvature is uniform along it)."""
    rid = str(spec.family.settings["road_id"])
    length = float(spec.family.network.road(rid).length)
    s0, s1 = (min(max(v, 0.0), length) for v in (s0, s1))
    if abs(s1 - s0) < 1e-6:
        return 1.0
    n = max(2, math.ceil(abs(s1 - s0) / 0.5) + 1)
    x, y, _, _ = spec.family.network.lane_center(rid, lane, np.linspace(s0, s1, n))
    return float(np.sum(np.hypot(np.diff(x), np.diff(y)))) / abs(s1 - s0)


def _lane_speed(b: _Build, lane: int, speed: str, s0: float, s1: float) -> str | float:
    """The expression of a planned speed ``speed`` (m/s of road s) as lane speed over the
    stretch [s0, s1] (see ``lane_speed_factor``)."""
    f = lane_speed_factor(b.spec, lane, s0, s1)
    if abs(f - 1.0) < 5e-7:
        return speed if speed.startswith("$") and " " not in speed else b.p.expr(speed)
    return b.p.expr(f"({speed}) * {number(f)}")


def _lane_start(b: _Build, name: str, lane: int, tr: int, ahead: str, speed: str,
                until_s: float | None = None) -> float:
    """``name`` starts in ``lane`` ``ahead`` (expression) of the ego's start at ``speed``
    (expression, m/s of road s; written as lane speed over the stretch it covers in this
    lane until ``until_s``, default the duration); returns its start s, m."""
    rid = str(b.st["road_id"])
    s_text = f"$ego_s0_m {'+' if tr > 0 else '-'} ({ahead})"
    s0 = b.p.value(s_text)
    until = b.spec.family.duration_s if until_s is None else until_s
    v = _lane_speed(b, lane, speed, s0, s0 + tr * b.p.value(speed) * until)
    b.init.append((name, xosc.TeleportAction(xosc.LanePosition(b.p.expr(s_text), 0.0, lane,
                                                               rid))))
    b.init.append((name, xosc.AbsoluteSpeedAction(v, _step())))
    return s0


def _step() -> xosc.TransitionDynamics:
    return xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0.0)


def _after_start(name: str) -> xosc.ValueTrigger:
    """Fires at the first step after the initialisation (time > 0): init actions are done,
    so no event overrides a running init action (esmini's "conflicting domain")."""
    return xosc.ValueTrigger(name, 0.0, xosc.ConditionEdge.none,
                             xosc.SimulationTimeCondition(0.0, xosc.Rule.greaterThan))


def _gap_trigger(b: _Build, name: str, actor: str, reference: str, gap_expr: str,
                 closing: float) -> xosc.EntityTrigger:
    """Fires when ``actor``'s longitudinal distance (origin to origin, road s) to
    ``reference`` reaches the planned signed gap ``gap_expr`` (m, + = actor ahead) that
    changes at ``closing`` (m/s, d gap / dt). OpenSCENARIO conditions compare the absolute
    distance, so the rule is ``greaterThan`` while the distance grows and ``lessThan``
    while it shrinks; the rising edge ignores a condition already true at the start (a
    gap that passes through zero first)."""
    gap = b.p.value(gap_expr)
    grows = gap * closing > 0.0
    text = gap_expr if gap >= 0.0 else f"-({gap_expr})"
    cond = xosc.RelativeDistanceCondition(
        b.p.expr(text), xosc.Rule.greaterThan if grows else xosc.Rule.lessThan,
        xosc.RelativeDistanceType.longitudinal, reference, alongroute=False, freespace=False,
        coordinate_system=xosc.CoordinateSystem.road)
    return xosc.EntityTrigger(name, 0.0, xosc.ConditionEdge.rising, cond, actor)


def _lane_change(b: _Build, actor: str, name: str, lane: int | None, shape: str,
                 duration: str, trigger: xosc.EntityTrigger | xosc.ValueTrigger,
                 time_s: float, reference: str,
                 speed: tuple[str, int, float, float] | None = None) -> None:
    """``actor`` changes into ``lane`` (None: the ego's lane) with ``shape`` over
    ``duration`` (expression, s) when ``trigger`` fires (planned at ``time_s``); with
    ``speed`` = (planned speed expression, new lane, stretch from s, to s) its lane speed
    changes with the same shape to the new lane's over the same time."""
    dyn = xosc.TransitionDynamics(shape, xosc.DynamicsDimension.time, duration)
    action = (xosc.RelativeLaneChangeAction(0, EGO, dyn) if lane is None
              else xosc.AbsoluteLaneChangeAction(lane, dyn))
    ev = b.event(actor, name, action, trigger)
    if speed is not None:
        v = _lane_speed(b, speed[1], speed[0], speed[2], speed[3])
        ev.add_action(f"{name}_lane_speed", xosc.AbsoluteSpeedAction(
            v, xosc.TransitionDynamics(shape, xosc.DynamicsDimension.time, duration)))
    b.triggers.append(PlannedTrigger(name, actor, reference, time_s))


def _after_change(b: _Build, tr: int, s0: float, speed: str, t_start: float,
                  t_end: float) -> tuple[float, float]:
    """The road-s stretch an entity starting at ``s0`` at ``speed`` covers from the end of
    its lane change (``t_start`` + duration = ``t_end``; the start if it ends after the
    scenario) to the scenario's end."""
    v, t_total = b.p.value(speed), b.spec.family.duration_s
    t_from = t_end if t_end < t_total else t_start
    return s0 + tr * v * t_from, s0 + tr * v * t_total


def _declare_shape(b: _Build) -> str:
    """The declared OpenSCENARIO shape of the family's lane-change blend (reference)."""
    shape = str(b.spec.params.get("shape", "cosine"))
    b.p.values["lane_change_shape"] = LANE_CHANGE_SHAPE[shape]
    return b.p.ref("lane_change_shape")


def occluder_name(label: str) -> str:
    """Entity name of an occluder: its label in CamelCase (``lead car`` -> ``LeadCar``)."""
    return "".join(w.capitalize() for w in label.split())


# --- the family kinds ------------------------------------------------------------------

def _cut_in(b: _Build) -> None:
    sp, p = b.spec, b.spec.params
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), int(b.st["ego_lane"]))
    off = number(origin_offset(sp.target))
    t_s, t_e = float(p["lc_start_s"]), float(p["lc_start_s"]) + float(p["lc_duration_s"])
    s0 = _lane_start(b, TARGET, int(b.st["target_lane"]), tr, f"$dx0_m - {off}",
                     "$target_speed_m_s", t_s)
    gap = f"$dx0_m - {off} + ($target_speed_m_s - $ego_speed_m_s) * $lc_start_s"
    dv = float(p["target_speed_m_s"]) - float(p["ego_speed_m_s"])
    trig = _gap_trigger(b, "cut_in_gap", TARGET, EGO, gap, dv)
    _lane_change(b, TARGET, "cut_in", None, _declare_shape(b), b.p.ref("lc_duration_s"),
                 trig, t_s, EGO, ("$target_speed_m_s", int(b.st["ego_lane"]),
                                  *_after_change(b, tr, s0, "$target_speed_m_s", t_s, t_e)))


def _cut_in_behind_truck(b: _Build) -> None:
    sp, p = b.spec, b.spec.params
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), int(b.st["ego_lane"]))
    truck = load_target(str(b.st["occluder"]))
    side = int(b.st["target_lane"])
    name = occluder_name(sp.scenario.occluders[0].label)
    b.entities.append((name, truck))
    _lane_start(b, name, side, tr, f"$truck_dx_m - {number(origin_offset(truck))}",
                "$truck_speed_m_s")
    half = number(0.5 * truck.length_m + 0.5 * sp.target.length_m - origin_offset(sp.target))
    ahead = f"$truck_dx_m + $target_gap_m + {half}"
    speed = "$truck_speed_m_s + $speed_delta_m_s"
    t_s, t_e = float(p["lc_start_s"]), float(p["lc_start_s"]) + float(p["lc_duration_s"])
    s0 = _lane_start(b, TARGET, side, tr, ahead, speed, t_s)
    gap = f"{ahead} + ($truck_speed_m_s + $speed_delta_m_s - $ego_speed_m_s) * $lc_start_s"
    dv = (float(p["truck_speed_m_s"]) + float(p["speed_delta_m_s"])
          - float(p["ego_speed_m_s"]))
    trig = _gap_trigger(b, "cut_in_gap", TARGET, EGO, gap, dv)
    _lane_change(b, TARGET, "cut_in", None, _declare_shape(b), b.p.ref("lc_duration_s"),
                 trig, t_s, EGO, (speed, int(b.st["ego_lane"]),
                                  *_after_change(b, tr, s0, speed, t_s, t_e)))


def _overtake(b: _Build) -> None:
    sp, p = b.spec, b.spec.params
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), int(b.st["ego_lane"]))
    off = number(origin_offset(sp.target))
    v0, lane = "$ego_speed_m_s + $speed_delta_m_s", int(b.st["ego_lane"])
    t_m = (float(p["merge_gap_m"]) - float(p["dx0_m"])) / float(p["speed_delta_m_s"])
    t_e = t_m + float(p["merge_duration_s"])
    s0 = _lane_start(b, TARGET, int(b.st["target_lane"]), tr, f"$dx0_m - {off}", v0, t_m)
    trig = _gap_trigger(b, "merge_gap", TARGET, EGO, f"$merge_gap_m - {off}",
                        float(p["speed_delta_m_s"]))
    b.p.values["lane_change_shape"] = "sinusoidal"
    stretch = _after_change(b, tr, s0, v0, t_m, t_e)
    _lane_change(b, TARGET, "merge", None, b.p.ref("lane_change_shape"),
                 b.p.ref("merge_duration_s"), trig, t_m, EGO, (v0, lane, *stretch))
    vf = b.p.value("$ego_speed_m_s - $final_delta_m_s")
    speed = (_lane_speed(b, lane, "$ego_speed_m_s - $final_delta_m_s", *stretch)
             if vf > 0.0 else 0.0)
    brake = xosc.AbsoluteSpeedAction(speed, xosc.TransitionDynamics(
        xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, b.p.ref("decel_m_s2")))
    # it brakes brake_delay_s after the merge, still at the overtaking speed: at the gap
    # the merge's gap grows to in (merge_duration_s + brake_delay_s)
    gap = f"$merge_gap_m - {off} + $speed_delta_m_s * ($merge_duration_s + $brake_delay_s)"
    trig_b = _gap_trigger(b, "brake_gap", TARGET, EGO, gap, float(p["speed_delta_m_s"]))
    b.event(TARGET, "brake", brake, trig_b)
    b.triggers.append(PlannedTrigger("brake", TARGET, EGO, t_e + float(p["brake_delay_s"])))


def _slow_ahead(b: _Build) -> None:
    sp = b.spec
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), int(b.st["lane"]))
    _lane_start(b, TARGET, int(b.st["lane"]), tr,
                f"$gap0_m - {number(origin_offset(sp.target))}", "$target_speed_m_s")


def _cut_out_reveal(b: _Build) -> None:
    sp, p = b.spec, b.spec.params
    lane, other = int(b.st["lane"]), int(b.st["target_lane"])
    tr = travel_direction(sp.family.network, str(b.st["road_id"]), lane)
    lead = load_target(str(b.st["occluder"]))
    name = occluder_name(sp.scenario.occluders[0].label)
    b.entities.append((name, lead))
    t_s, t_e = float(p["cut_out_s"]), float(p["cut_out_s"]) + float(p["lc_duration_s"])
    s_lead = _lane_start(b, name, lane, tr, f"$lead_gap_m - {number(origin_offset(lead))}",
                         "$ego_speed_m_s", t_s)
    half = number(0.5 * (lead.length_m + sp.target.length_m) - origin_offset(sp.target))
    reveal = (f"($cut_out_s + $lc_duration_s + $reveal_s) * ($ego_speed_m_s - "
              f"$target_speed_m_s) + {half}")
    _lane_start(b, TARGET, lane, tr, f"$lead_gap_m + {reveal}", "$target_speed_m_s")
    # the lead pulls out when the ego is at the planned distance to the hidden target
    gap = (f"$lead_gap_m + ($lc_duration_s + $reveal_s) * ($ego_speed_m_s - "
           f"$target_speed_m_s) + {half}")
    closing = float(p["target_speed_m_s"]) - float(p["ego_speed_m_s"])
    trig = _gap_trigger(b, "reveal_gap", TARGET, EGO, gap, closing)
    b.p.values["lane_change_shape"] = "sinusoidal"
    _lane_change(b, name, "cut_out", other, b.p.ref("lane_change_shape"),
                 b.p.ref("lc_duration_s"), trig, t_s, EGO, (
                     "$ego_speed_m_s", other,
                     *_after_change(b, tr, s_lead, "$ego_speed_m_s", t_s, t_e)))
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


def _crossing(b: _Build) -> None:
    """The target waits on the footway and follows its planned crossing (timed polyline of
    the 20 Hz plan, relative timing) once the ego is the planned distance away; a target
    under way at the start follows it from the start (absolute timing)."""
    sp, p = b.spec, b.spec.params
    rid = str(b.st["road_id"])
    tr = travel_direction(sp.family.network, rid, int(b.st["ego_lane"]))
    from sensorgap.export.xosc import origin_path

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
        return xosc.RoadPosition(s_c, _fmt(lat), rid, xosc.Orientation(
            h=_fmt(rel), reference=xosc.ReferenceContext.relative))

    moving = np.flatnonzero(path.speed > 1e-9)
    last = int(moving[-1]) + 1 if len(moving) else 0
    last = min(last, len(path.t) - 1)
    b.init.append((TARGET, xosc.TeleportAction(road_pos(0))))
    b.init.append((TARGET, xosc.AbsoluteSpeedAction(_fmt(float(path.speed[0])), _step())))
    if math.isinf(t_dep) and t_dep > 0.0:
        return  # it would leave the footway after the scenario's end: it waits there
    if t_dep > 0.0:
        first = int(np.searchsorted(path.t, t_dep, side="right"))
        idx = list(range(first, last + 1))
        times = [0.0] + [_fmt(float(path.t[k]) - t_dep) for k in idx]
        idx = [0, *idx]
        # the ego's rear axle is cross_ahead - ego_speed * t_dep = ego_speed * (tau_c -
        # conflict_offset) before the crossing line, tau_c = time from departure to the
        # ego lane's centre
        tau_c = float(p["cross_ahead_m"]) / float(p["ego_speed_m_s"]) + float(
            p["conflict_offset_s"]) - t_dep
        gap = f"$ego_speed_m_s * ({number(tau_c)} - $conflict_offset_s)"
        cond = xosc.RelativeDistanceCondition(
            b.p.expr(gap), xosc.Rule.lessThan, xosc.RelativeDistanceType.longitudinal,
            TARGET, alongroute=False, freespace=False,
            coordinate_system=xosc.CoordinateSystem.entity)
        trig: Any = xosc.EntityTrigger("crossing_gap", 0.0, xosc.ConditionEdge.rising, cond,
                                       EGO)
        timing = xosc.ReferenceContext.relative
        b.triggers.append(PlannedTrigger("cross", EGO, TARGET, t_dep))
    else:
        idx = list(range(0, last + 1))
        times = [_fmt(float(path.t[k])) for k in idx]
        trig = _after_start("crossing_under_way")
        timing = xosc.ReferenceContext.absolute
    traj = xosc.Trajectory("Target_crossing", False)
    traj.add_shape(xosc.Polyline(times, [road_pos(k) for k in idx]))
    follow = xosc.FollowTrajectoryAction(traj, xosc.FollowingMode.position, timing, 1.0, 0.0)
    b.event(TARGET, "cross", follow, trig)
    if last < len(path.t) - 1:  # it stops on the far footway: hold it there
        stop = xosc.AbsoluteSpeedAction(0.0, _step())
        done = xosc.ValueTrigger("crossed", 0.0, xosc.ConditionEdge.none,
                                 xosc.StoryboardElementStateCondition(
                                     xosc.StoryboardElementType.action, "cross_action",
                                     xosc.StoryboardElementState.endTransition))
        b.event(TARGET, "stand", stop, done)


def _crossing_behind_parked(b: _Build) -> None:
    _crossing(b)
    for occ in b.spec.scenario.occluders:
        name = occluder_name(occ.label)
        cfg = load_target(str(b.st["occluder"]))
        b.entities.append((name, cfg))
        d = origin_offset(cfg)
        h = float(occ.path.heading[0])
        x = float(occ.path.x[0]) - d * math.cos(h)
        y = float(occ.path.y[0]) - d * math.sin(h)
        b.init.append((name, xosc.TeleportAction(xosc.WorldPosition(_fmt(x), _fmt(y), 0.0,
                                                                    _fmt(h)))))


KINDS = {"cut_in": _cut_in, "overtake": _overtake, "slow_ahead": _slow_ahead,
         "crossing": _crossing, "cut_in_behind_occluder": _cut_in_behind_truck,
         "cut_out_reveal": _cut_out_reveal, "crossing_behind_parked": _crossing_behind_parked}


def supported(spec: ScenarioSpec) -> bool:
    """Whether the maneuver style knows the family's kind."""
    return spec.family.kind.name in KINDS


def _ego(b: _Build) -> None:
    """The ego: lane position from the declared parameters; its controller is activated
    (or left inactive: keep lane and speed) at the first step."""
    lane = int(b.st.get("ego_lane", b.st.get("lane", 0)))
    b.init.append((EGO, xosc.TeleportAction(xosc.LanePosition(
        b.p.ref("ego_s0_m"), 0.0, lane, str(b.st["road_id"])))))
    b.event(EGO, "ego_controller", xosc.ActivateControllerAction(
        b.p.ref("ego_controller_lateral"), b.p.ref("ego_controller_longitudinal")),
            _after_start("ego_controller_start"))


def _ego_speed(b: _Build) -> None:
    """The ego's speed (after the kind's events are known): ``$ego_speed_m_s`` as lane
    speed over the stretch up to the first relative trigger (the scenario's end if there
    is none), so the ego is where the plan has it when the encounter starts."""
    lane = int(b.st.get("ego_lane", b.st.get("lane", 0)))
    tr = travel_direction(b.spec.family.network, str(b.st["road_id"]), lane)
    s0, v = b.p.value("$ego_s0_m"), b.p.value("$ego_speed_m_s")
    until = min([t.time_s for t in b.triggers if t.time_s > 0.0],
                default=b.spec.family.duration_s)
    speed = _lane_speed(b, lane, "$ego_speed_m_s", s0, s0 + tr * v * until)
    b.init.insert(1, (EGO, xosc.AbsoluteSpeedAction(speed, _step())))


def build_maneuver_scenario(spec: ScenarioSpec, road_relpath: str,
                            version: str) -> tuple[xosc.Scenario, list[PlannedTrigger]]:
    """The OpenSCENARIO object of one ranked scenario in the ``maneuver`` style and its
    relative triggers (see the module docstring)."""
    from sensorgap.export.xosc import (
        actor_entity,
        assemble,
        declarations,
        ego_entity,
        environment,
        set_version,
    )

    kind = spec.family.kind.name
    if kind not in KINDS:
        raise ValueError(f"family kind {kind!r} has no maneuver form; allowed: "
                         f"{', '.join(sorted(KINDS))} (export it with --style replay)")
    minor = set_version(version)
    values: dict[str, str | float] = dict(spec.params)
    values.update(EGO_CONTROLLER_PARAMETERS)
    b = _Build(spec, minor, Expressions(values, minor))
    b.entities.append((TARGET, spec.target))
    _ego(b)
    KINDS[kind](b)
    _ego_speed(b)
    extra = {k: v for k, v in b.p.values.items() if k not in spec.params}
    extra.update({"ego_controller_longitudinal": False, "ego_controller_lateral": False})

    entities = xosc.Entities()
    props = xosc.Properties()
    props.add_property("esminiController", b.p.ref("ego_controller"))
    entities.add_scenario_object(EGO, ego_entity(spec),
                                 xosc.Controller(SUT_CONTROLLER, props))
    for name, cfg in b.entities:
        entities.add_scenario_object(name, actor_entity(name, cfg))
    init = xosc.Init()
    init.add_global_action(xosc.EnvironmentAction(environment(spec, minor)))
    for name, action in b.init:
        init.add_init_action(name, action)
    act = xosc.Act("encounter", _after_start("encounter_start"))
    for actor, events in b.events.items():
        man = xosc.Maneuver(f"{actor}_maneuver")
        for ev in events:
            man.add_event(ev)
        group = xosc.ManeuverGroup(f"{actor}_group")
        group.add_actor(actor)
        group.add_maneuver(man)
        act.add_maneuver_group(group)
    story = xosc.Story("critical_scenario")
    story.add_act(act)
    stop = xosc.Trigger("stop")
    hit = xosc.ConditionGroup("stop")
    hit.add_condition(xosc.EntityTrigger("ego_hits_target", 0.0, xosc.ConditionEdge.none,
                                         xosc.CollisionCondition(TARGET), EGO,
                                         triggeringpoint="stop"))
    end = xosc.ConditionGroup("stop")
    end.add_condition(xosc.ValueTrigger(
        "end", 0.0, xosc.ConditionEdge.rising,
        xosc.SimulationTimeCondition(_fmt(spec.family.duration_s), xosc.Rule.greaterThan),
        "stop"))
    stop.add_conditiongroup(hit)
    stop.add_conditiongroup(end)
    sb = xosc.StoryBoard(init, stop)
    sb.add_story(story)
    sc = assemble(spec, declarations(spec, extra), entities, sb, road_relpath, minor)
    return sc, b.triggers


def maneuver_triggers(spec: ScenarioSpec) -> list[PlannedTrigger]:
    """The relative triggers of a scenario's maneuver-style file (no file written)."""
    from sensorgap.export.xosc import set_version

    minor = set_version("1.2")
    values: dict[str, str | float] = dict(spec.params)
    values.update(EGO_CONTROLLER_PARAMETERS)
    b = _Build(spec, minor, Expressions(values, minor))
    KINDS[spec.family.kind.name](b)
    return b.triggers


def planned_origins(spec: ScenarioSpec) -> dict[str, Trajectory]:
    """The planned path of every entity's exported origin (ego: rear axle; vehicles: rear
    axle; pedestrians: centre), by entity name."""
    from sensorgap.export.xosc import origin_path

    out = {EGO: spec.scenario.ego,
           TARGET: origin_path(spec.scenario.target, origin_offset(spec.target))}
    occ_class = spec.family.settings.get("occluder")
    for occ in spec.scenario.occluders:
        cfg = load_target(str(occ_class))
        out[occluder_name(occ.label)] = origin_path(occ.path, origin_offset(cfg))
    return out
