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

from scenariogeneration import xosc

from sensorgap.export.actions import (
    DEFAULT_EGO_CONTROLLER,
    EGO,
    EGO_CONTROLLER_PARAMETERS,
    LANE_CHANGE_SHAPE,
    SUT_CONTROLLER,
    TARGET,
    Build,
    PlannedTrigger,
    after_start,
    fmt,
    lane_speed,
    occluder_name,
    origin_offset,
    step_dynamics,
)
from sensorgap.export.brake import BrakeStep, brake_events
from sensorgap.export.encounters import KINDS, supported
from sensorgap.export.params import Expressions
from sensorgap.export.spec import ScenarioSpec
from sensorgap.scenarios.kinds import travel_direction
from sensorgap.scenarios.occluded import occluder_class
from sensorgap.scenarios.trajectory import Trajectory

__all__ = [
    "DEFAULT_EGO_CONTROLLER",
    "EGO",
    "LANE_CHANGE_SHAPE",
    "SUT_CONTROLLER",
    "TARGET",
    "PlannedTrigger",
    "build_maneuver_scenario",
    "maneuver_triggers",
    "occluder_name",
    "planned_origins",
    "supported",
]


def _ego(b: Build) -> None:
    """The ego: lane position from the declared parameters; its controller is activated
    (or left inactive: keep lane and speed) at the first step."""
    lane = int(b.st.get("ego_lane", b.st.get("lane", 0)))
    b.init.append(
        (
            EGO,
            xosc.TeleportAction(
                xosc.LanePosition(b.p.ref("ego_s0_m"), 0.0, lane, str(b.st["road_id"]))
            ),
        )
    )
    b.event(
        EGO,
        "ego_controller",
        xosc.ActivateControllerAction(
            b.p.ref("ego_controller_lateral"), b.p.ref("ego_controller_longitudinal")
        ),
        after_start("ego_controller_start"),
    )


def _ego_speed(b: Build) -> None:
    """The ego's speed (after the kind's events are known): ``$ego_speed_m_s`` as lane
    speed over the stretch up to the first relative trigger (the scenario's end if there
    is none), so the ego is where the plan has it when the encounter starts."""
    lane = int(b.st.get("ego_lane", b.st.get("lane", 0)))
    tr = travel_direction(b.spec.family.network, str(b.st["road_id"]), lane)
    s0, v = b.p.value("$ego_s0_m"), b.p.value("$ego_speed_m_s")
    until = min([t.time_s for t in b.triggers if t.time_s > 0.0], default=b.spec.family.duration_s)
    speed = lane_speed(b, lane, "$ego_speed_m_s", s0, s0 + tr * v * until)
    b.init.insert(1, (EGO, xosc.AbsoluteSpeedAction(speed, step_dynamics())))


def build_maneuver_scenario(
    spec: ScenarioSpec,
    road_relpath: str,
    version: str,
    ego_brake: list[BrakeStep] | None = None,
    step_s: float = 0.05,
) -> tuple[xosc.Scenario, list[PlannedTrigger]]:
    """The OpenSCENARIO object of one ranked scenario in the ``maneuver`` style and its
    relative triggers (see the module docstring); with ``ego_brake`` the ego brakes so
    (``simulate --ego-reaction``; ``step_s``: the simulation step, s)."""
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
        raise ValueError(
            f"family kind {kind!r} has no maneuver form; allowed: "
            f"{', '.join(sorted(KINDS))} (export it with --style replay)"
        )
    minor = set_version(version)
    values: dict[str, str | float] = dict(spec.params)
    values.update(EGO_CONTROLLER_PARAMETERS)
    b = Build(spec, minor, Expressions(values, minor))
    b.entities.append((TARGET, spec.target))
    _ego(b)
    KINDS[kind](b)
    _ego_speed(b)
    for ev in brake_events(ego_brake or [], minor, step_s):
        b.events.setdefault(EGO, []).append(ev)
    extra = {k: v for k, v in b.p.values.items() if k not in spec.params}
    extra.update({"ego_controller_longitudinal": False, "ego_controller_lateral": False})

    entities = xosc.Entities()
    props = xosc.Properties()
    props.add_property("esminiController", b.p.ref("ego_controller"))
    entities.add_scenario_object(EGO, ego_entity(spec), xosc.Controller(SUT_CONTROLLER, props))
    for name, cfg in b.entities:
        entities.add_scenario_object(name, actor_entity(name, cfg))
    init = xosc.Init()
    init.add_global_action(xosc.EnvironmentAction(environment(spec, minor)))
    for name, action in b.init:
        init.add_init_action(name, action)
    act = xosc.Act("encounter", after_start("encounter_start"))
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
    hit.add_condition(
        xosc.EntityTrigger(
            "ego_hits_target",
            0.0,
            xosc.ConditionEdge.none,
            xosc.CollisionCondition(TARGET),
            EGO,
            triggeringpoint="stop",
        )
    )
    end = xosc.ConditionGroup("stop")
    end.add_condition(
        xosc.ValueTrigger(
            "end",
            0.0,
            xosc.ConditionEdge.rising,
            xosc.SimulationTimeCondition(fmt(spec.family.duration_s), xosc.Rule.greaterThan),
            "stop",
        )
    )
    stop.add_conditiongroup(hit)
    stop.add_conditiongroup(end)
    sb = xosc.StoryBoard(init, stop)
    sb.add_story(story)
    sc = assemble(spec, declarations(spec, extra), entities, sb, road_relpath, minor)
    return sc, b.triggers


def ego_speed_factor(spec: ScenarioSpec) -> float:
    """The ego's exported lane speed per planned speed (``_ego_speed``'s factor)."""
    from sensorgap.export.actions import lane_speed_factor

    lane = int(spec.family.settings.get("ego_lane", spec.family.settings.get("lane", 0)))
    tr = travel_direction(spec.family.network, str(spec.family.settings["road_id"]), lane)
    s0, v = float(spec.params["ego_s0_m"]), float(spec.params["ego_speed_m_s"])
    until = min(
        [t.time_s for t in maneuver_triggers(spec) if t.time_s > 0.0],
        default=spec.family.duration_s,
    )
    return lane_speed_factor(spec, lane, s0, s0 + tr * v * until)


def maneuver_triggers(spec: ScenarioSpec) -> list[PlannedTrigger]:
    """The relative triggers of a scenario's maneuver-style file (no file written)."""
    from sensorgap.export.xosc import set_version

    minor = set_version("1.2")
    values: dict[str, str | float] = dict(spec.params)
    values.update(EGO_CONTROLLER_PARAMETERS)
    b = Build(spec, minor, Expressions(values, minor))
    KINDS[spec.family.kind.name](b)
    return b.triggers


def planned_origins(spec: ScenarioSpec) -> dict[str, Trajectory]:
    """The planned path of every entity's exported origin (ego: rear axle; vehicles: rear
    axle; pedestrians: centre), by entity name."""
    from sensorgap.export.xosc import origin_path

    out = {
        EGO: spec.scenario.ego,
        TARGET: origin_path(spec.scenario.target, origin_offset(spec.target)),
    }
    for occ in spec.scenario.occluders:
        cfg = occluder_class(spec.family)
        out[occluder_name(occ.label)] = origin_path(occ.path, origin_offset(cfg))
    return out
