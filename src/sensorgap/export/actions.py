"""Building blocks of the ``maneuver`` export style (``export.maneuver``): the scenario
being assembled (``Build``), lane starts with lane speeds, relative-gap triggers, lane
changes, and the planned triggers ``simulate`` checks."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scenariogeneration import xosc

from sensorgap.config import TargetConfig
from sensorgap.export.params import Expressions, number
from sensorgap.export.spec import ScenarioSpec

EGO = "Ego"
TARGET = "Target"
#: The ego's replaceable controller and its default esmini type (assigned, not active).
SUT_CONTROLLER = "SystemUnderTest"
DEFAULT_EGO_CONTROLLER = "ExternalController"
#: Declared parameters of the ego's controller (string values as written).
EGO_CONTROLLER_PARAMETERS: dict[str, str | float] = {
    "ego_controller": DEFAULT_EGO_CONTROLLER,
    "ego_controller_longitudinal": "false",
    "ego_controller_lateral": "false",
}
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
class Build:
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
        ev = xosc.Event(
            name, xosc.Priority.override if self.minor >= 2 else xosc.Priority.overwrite
        )
        ev.add_action(f"{name}_action", action)
        ev.add_trigger(trigger)
        self.events.setdefault(actor, []).append(ev)
        return ev


def fmt(v: float) -> float:
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


def lane_speed(b: Build, lane: int, speed: str, s0: float, s1: float) -> str | float:
    """The expression of a planned speed ``speed`` (m/s of road s) as lane speed over the
    stretch [s0, s1] (see ``lane_speed_factor``)."""
    f = lane_speed_factor(b.spec, lane, s0, s1)
    if abs(f - 1.0) < 5e-7:
        return speed if speed.startswith("$") and " " not in speed else b.p.expr(speed)
    return b.p.expr(f"({speed}) * {number(f)}")


def lane_start(
    b: Build, name: str, lane: int, tr: int, ahead: str, speed: str, until_s: float | None = None
) -> float:
    """``name`` starts in ``lane`` ``ahead`` (expression) of the ego's start at ``speed``
    (expression, m/s of road s; written as lane speed over the stretch it covers in this
    lane until ``until_s``, default the duration); returns its start s, m."""
    rid = str(b.st["road_id"])
    s_text = f"$ego_s0_m {'+' if tr > 0 else '-'} ({ahead})"
    s0 = b.p.value(s_text)
    until = b.spec.family.duration_s if until_s is None else until_s
    v = lane_speed(b, lane, speed, s0, s0 + tr * b.p.value(speed) * until)
    b.init.append((name, xosc.TeleportAction(xosc.LanePosition(b.p.expr(s_text), 0.0, lane, rid))))
    b.init.append((name, xosc.AbsoluteSpeedAction(v, step_dynamics())))
    return s0


def step_dynamics() -> xosc.TransitionDynamics:
    return xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0.0)


def after_start(name: str) -> xosc.ValueTrigger:
    """Fires at the first step after the initialisation (time > 0): init actions are done,
    so no event overrides a running init action (esmini's "conflicting domain")."""
    return xosc.ValueTrigger(
        name, 0.0, xosc.ConditionEdge.none, xosc.SimulationTimeCondition(0.0, xosc.Rule.greaterThan)
    )


def gap_trigger(
    b: Build, name: str, actor: str, reference: str, gap_expr: str, closing: float
) -> xosc.EntityTrigger:
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
        b.p.expr(text),
        xosc.Rule.greaterThan if grows else xosc.Rule.lessThan,
        xosc.RelativeDistanceType.longitudinal,
        reference,
        alongroute=False,
        freespace=False,
        coordinate_system=xosc.CoordinateSystem.road,
    )
    return xosc.EntityTrigger(name, 0.0, xosc.ConditionEdge.rising, cond, actor)


def lane_change(
    b: Build,
    actor: str,
    name: str,
    lane: int | None,
    shape: str,
    duration: str,
    trigger: xosc.EntityTrigger | xosc.ValueTrigger,
    time_s: float,
    reference: str,
    speed: tuple[str, int, float, float] | None = None,
) -> None:
    """``actor`` changes into ``lane`` (None: the ego's lane) with ``shape`` over
    ``duration`` (expression, s) when ``trigger`` fires (planned at ``time_s``); with
    ``speed`` = (planned speed expression, new lane, stretch from s, to s) its lane speed
    changes with the same shape to the new lane's over the same time."""
    dyn = xosc.TransitionDynamics(shape, xosc.DynamicsDimension.time, duration)
    action = (
        xosc.RelativeLaneChangeAction(0, EGO, dyn)
        if lane is None
        else xosc.AbsoluteLaneChangeAction(lane, dyn)
    )
    ev = b.event(actor, name, action, trigger)
    if speed is not None:
        v = lane_speed(b, speed[1], speed[0], speed[2], speed[3])
        ev.add_action(
            f"{name}_lane_speed",
            xosc.AbsoluteSpeedAction(
                v, xosc.TransitionDynamics(shape, xosc.DynamicsDimension.time, duration)
            ),
        )
    b.triggers.append(PlannedTrigger(name, actor, reference, time_s))


def after_change(
    b: Build, tr: int, s0: float, speed: str, t_start: float, t_end: float
) -> tuple[float, float]:
    """The road-s stretch an entity starting at ``s0`` at ``speed`` covers from the end of
    its lane change (``t_start`` + duration = ``t_end``; the start if it ends after the
    scenario) to the scenario's end."""
    v, t_total = b.p.value(speed), b.spec.family.duration_s
    t_from = t_end if t_end < t_total else t_start
    return s0 + tr * v * t_from, s0 + tr * v * t_total


def declare_shape(b: Build, shape: str | None = None) -> str:
    """The declared OpenSCENARIO shape of a lane-change blend (reference): the family's
    ``shape`` parameter, or ``shape`` for kinds whose blend is fixed (overtake's merge and
    cut-out's lead vehicle: ``cosine``)."""
    if shape is None:
        shape = str(b.spec.params.get("shape", "cosine"))
    b.p.values["lane_change_shape"] = LANE_CHANGE_SHAPE[shape]
    return b.p.ref("lane_change_shape")


def occluder_name(label: str) -> str:
    """Entity name of an occluder: its label in CamelCase (``lead car`` -> ``LeadCar``)."""
    return "".join(w.capitalize() for w in label.split())
