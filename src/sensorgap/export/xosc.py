"""One ranked scenario as an OpenSCENARIO file (scenariogeneration objects, 1.0 to 1.3):
the ``replay`` style, and the parts both styles share (entities, environment, parameter
declarations, FileHeader); the ``maneuver`` style is ``export.maneuver``.

Replay mapping (docs/export.md):

* Entities: ``Ego`` (the vehicle's body from its vehicle file; reference point = rear-axle
  centre on the ground, the sensorgap vehicle frame) and ``Target`` (car/truck: Vehicle,
  bike: Vehicle of category bicycle, pedestrian: Pedestrian), bounding boxes from the
  vehicle and target files; the target's origin is its rear axle (pedestrians: centre).
* Init: TeleportAction to the first state (WorldPosition x, y, heading); the ego's initial
  speed (AbsoluteTargetSpeed, step), the target's FollowTrajectoryAction.
* Manoeuvres: FollowTrajectoryAction with the evaluated 20 Hz states as a timed Polyline
  (absolute timing, following mode ``position``; vertices that esmini's vertex filter
  would merge are left out, ``filtered_vertices``), so a player reproduces the evaluated
  paths. The target's starts in the init (else esmini's default controller moves it along
  the road in the first step: a crossing cyclist 0.05 m off); the ego's in an act that
  starts at time > 0, after its init speed action (an earlier start overrides it: esmini's
  "conflicting domain" warnings).
* Environment: the evaluated conditions: Sun (world azimuth clockwise from north,
  elevation; intensity = direct irradiance x 105 lm/W, an estimate of the luminous
  efficacy of direct sunlight), Fog visualRange = visibility, Precipitation (rain or snow,
  mm/h from 1.1 on; 1.0: intensity 0..1 = mm/h / 50, estimate), TimeOfDay (a fixed date;
  the sun is given explicitly), RoadCondition friction 1.0 (dry) or 0.7 (wet; estimate).
* ParameterDeclarations: every searched parameter with its value (re-sweep with
  ``sensorgap.CriticalScenarios``), plus the environment and the sun.
* StopTrigger: SimulationTime > duration. FileHeader: description with the metrics, a
  fixed creation date (deterministic files), author ``sensorgap``.
"""

from __future__ import annotations

import datetime as dt
import math
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from scenariogeneration import xosc
from scenariogeneration.xosc.enumerations import VersionBase

from sensorgap.config import TargetConfig
from sensorgap.export.brake import BrakeStep, brake_events
from sensorgap.export.spec import ScenarioSpec
from sensorgap.scenarios.trajectory import Trajectory

#: OpenSCENARIO versions written (minor of 1.x) and the default.
VERSIONS = {"1.0": 0, "1.1": 1, "1.2": 2, "1.3": 3}
DEFAULT_VERSION = "1.2"
#: Luminous efficacy of direct sunlight, lm/W (estimate; ~93-105 lm/W, Darula & Kittler).
SUN_LUMEN_PER_WATT = 105.0
#: FileHeader creation date of every exported file (fixed: same inputs, same bytes).
CREATION_DATE = dt.datetime(2026, 1, 1, 0, 0, 0)
#: Ego body height when the vehicle file has none, m (estimate: passenger car).
RAIN_FULL_SCALE_MM_H = 50.0
WET_FRICTION = 0.7
EGO = "Ego"
TARGET = "Target"


#: Where a vehicle target's rear axle sits behind its box centre, as a fraction of its
#: length (estimate: overhangs of about 20 % of the length at each end, the axles at 0.2 L
#: and 0.8 L from the rear). OpenSCENARIO puts a vehicle's origin at its rear axle, so the
#: exported paths are of that point and the bounding box centre lies this far ahead of it.
REAR_AXLE_BEHIND_CENTRE = 0.3


def target_origin_offset(target: TargetConfig) -> float:
    """Distance (m) from a target's exported origin (its rear axle; pedestrians: the box
    centre, the standard's reference point for them) forward to its box centre."""
    return 0.0 if target.name == "pedestrian" else REAR_AXLE_BEHIND_CENTRE * target.length_m


def origin_path(tr: Trajectory, ahead_m: float) -> Trajectory:
    """The path of a point ``ahead_m`` (m) behind a trajectory's reference point along its
    heading: box centres -> rear axles (negative: the other way)."""
    if ahead_m == 0.0:
        return tr
    c, s = np.cos(tr.heading), np.sin(tr.heading)
    return Trajectory(
        t=tr.t, x=tr.x - ahead_m * c, y=tr.y - ahead_m * s, heading=tr.heading, speed=tr.speed
    )


#: esmini merges consecutive trajectory vertices closer than this (its ``--traj_filter``
#: default, m; playerbase.cpp) and turns a slow motion (< 0.1 m in more than 1 s) into a
#: stand-still followed by a jump: a target creeping at 0.04 m/s stood still for 2.9 s and
#: then jumped 0.1 m. ``filtered_vertices`` keeps only vertices it leaves alone.
ESMINI_TRAJ_FILTER_M = 0.1
#: Spacing kept between vertices above that radius (rounding of the XML, 1e-6 m), m.
_FILTER_MARGIN_M = 1e-3


def filtered_vertices(x: np.ndarray, y: np.ndarray, idx: list[int] | None = None) -> list[int]:
    """The samples (of ``idx``, default all) to write as trajectory vertices so that
    esmini's default vertex filter keeps every one: the first and last samples, the first
    and last sample of every stand-still (samples at the same position: esmini keeps such
    a pair when the stand-still lasts 1 s or more; one at the start is only its last
    sample: the body is placed at the first sample and waits for the first vertex's
    time) and, between those, samples at least
    ``ESMINI_TRAJ_FILTER_M`` (+1 mm) from the previous vertex and from the next
    stand-still or end. A player interpolates the samples left out linearly in time: off
    by at most a quarter of the spacing (0.025-0.035 m at 20 Hz) for a start from or a
    stop to rest at constant acceleration, by 0 at constant speed."""
    idx = list(range(len(x))) if idx is None else list(idx)
    if len(idx) <= 2:
        return idx
    gap = ESMINI_TRAJ_FILTER_M + _FILTER_MARGIN_M

    def dist(i: int, j: int) -> float:
        return float(np.hypot(x[i] - x[j], y[i] - y[j]))

    anchors = [idx[0]]
    for prev, k, nxt in zip(idx, idx[1:], idx[2:], strict=False):
        still_before = dist(prev, k) <= 1e-9
        still_after = dist(k, nxt) <= 1e-9
        if still_before != still_after:  # a stand-still starts or ends here
            anchors.append(k)
    anchors.append(idx[-1])
    if len(anchors) > 2 and dist(anchors[0], anchors[1]) <= 1e-9:
        # a stand-still at the start: the body is placed there (init) and waits until
        # the first vertex, its end (esmini drops a stand-still shorter than 1 s)
        anchors = anchors[1:]
    pos = {k: i for i, k in enumerate(idx)}
    keep = [anchors[0]]
    for u, v in zip(anchors, anchors[1:], strict=False):
        between = [k for k in idx[pos[u] + 1 : pos[v]] if dist(k, keep[-1]) >= gap]
        picked: list[int] = []
        for k in between:
            if dist(k, picked[-1] if picked else keep[-1]) >= gap:
                picked.append(k)
        # towards a stand-still or the end: the sample nearest to it at the spacing
        last = next((k for k in reversed(between) if dist(k, v) >= gap), None)
        while picked and (
            last is None or dist(picked[-1], last) < gap or pos[picked[-1]] >= pos[last]
        ):
            picked.pop()
        keep += [*picked, *([] if last is None else [last]), v]
    return keep


def _fmt(v: float) -> float:
    """Round to 1 mm / 1e-6 rad: short, stable numbers in the XML."""
    return float(round(v, 6))


def _follow(name: str, tr: Trajectory) -> xosc.FollowTrajectoryAction:
    keep = filtered_vertices(tr.x, tr.y)
    traj = xosc.Trajectory(f"{name}_path", False)
    traj.add_shape(
        xosc.Polyline(
            [_fmt(float(tr.t[k])) for k in keep],
            [
                xosc.WorldPosition(
                    _fmt(float(tr.x[k])), _fmt(float(tr.y[k])), 0.0, _fmt(float(tr.heading[k]))
                )
                for k in keep
            ],
        )
    )
    return xosc.FollowTrajectoryAction(
        traj, xosc.FollowingMode.position, xosc.ReferenceContext.absolute, 1.0, 0.0
    )


def ego_entity(spec: ScenarioSpec) -> xosc.Vehicle:
    body = spec.system.config.vehicle
    bb = xosc.BoundingBox(
        body.width_m,
        body.length_m,
        body.height_m,
        _fmt(0.5 * (body.x_front_m + body.x_rear_m)),
        0.0,
        0.5 * body.height_m,
    )
    front = xosc.Axle(0.5, 0.65, _fmt(0.85 * body.width_m), _fmt(body.wheelbase_m), 0.33)
    rear = xosc.Axle(0.0, 0.65, _fmt(0.85 * body.width_m), 0.0, 0.33)
    return xosc.Vehicle(
        EGO, xosc.VehicleCategory.car, bb, front, rear, _fmt(body.max_speed_m_s), 10.0, 10.0
    )


def actor_entity(name: str, t: TargetConfig) -> xosc.Vehicle | xosc.Pedestrian:
    """A target or occluder of class ``t`` as entity ``name``: its origin at the rear axle
    (pedestrians: the box centre), the bounding box centre ``target_origin_offset`` ahead."""
    d = target_origin_offset(t)  # origin at the rear axle: the box centre is d ahead
    bb = xosc.BoundingBox(t.width_m, t.length_m, t.height_m, _fmt(d), 0.0, 0.5 * t.height_m)
    if t.name == "pedestrian":
        return xosc.Pedestrian(
            name, 80.0, xosc.PedestrianCategory.pedestrian, bb, model="pedestrian"
        )
    category = {"bike": xosc.VehicleCategory.bicycle, "truck": xosc.VehicleCategory.truck}.get(
        t.name, xosc.VehicleCategory.car
    )
    wheel = 0.6 if t.name == "bike" else 0.8
    front = xosc.Axle(0.5, wheel, _fmt(0.85 * t.width_m), _fmt(2.0 * d), wheel / 2)
    rear = xosc.Axle(0.0, wheel, _fmt(0.85 * t.width_m), 0.0, wheel / 2)
    return xosc.Vehicle(name, category, bb, front, rear, _fmt(t.max_speed_m_s), 10.0, 10.0)


def environment(spec: ScenarioSpec, minor: int) -> xosc.Environment:
    env = spec.environment
    sun = env.sun
    intensity = 0.0
    az = el = 0.0
    if sun is not None:
        az = math.radians(sun.azimuth_deg % 360.0)
        el = math.radians(max(sun.elevation_deg, 0.0))
        if sun.visible and sun.elevation_deg > 0.0:
            intensity = sun.direct_irradiance_w_m2 * SUN_LUMEN_PER_WATT
    precip_type, mm_h = xosc.PrecipitationType.dry, 0.0
    if env.snow_mm_h > 0.0:
        precip_type, mm_h = xosc.PrecipitationType.snow, env.snow_mm_h
    elif env.rain_mm_h > 0.0:
        precip_type, mm_h = xosc.PrecipitationType.rain, env.rain_mm_h
    intensity_p = min(mm_h / RAIN_FULL_SCALE_MM_H, 1.0) if minor == 0 else mm_h
    cloud = xosc.CloudState.free if minor < 2 else xosc.FractionalCloudCover.zeroOktas
    if sun is None or not sun.visible:
        cloud = xosc.CloudState.overcast if minor < 2 else xosc.FractionalCloudCover.eightOktas
    weather = xosc.Weather(
        cloudstate=cloud,
        atmosphericPressure=None if minor == 0 else _fmt(env.pressure_hpa * 100.0),
        temperature=None if minor == 0 else _fmt(env.temperature_c + 273.15),
        sun=xosc.Sun(_fmt(intensity), _fmt(az), _fmt(el)),
        fog=xosc.Fog(int(round(min(env.visibility_m, 1.0e6)))),
        precipitation=xosc.Precipitation(precip_type, _fmt(intensity_p)),
    )
    wet = mm_h > 0.0
    return xosc.Environment(
        f"{spec.environment_name}",
        xosc.TimeOfDay(False, 2026, 6, 21, 12, 0, 0),
        weather,
        xosc.RoadCondition(WET_FRICTION if wet else 1.0),
    )


def description(spec: ScenarioSpec) -> str:
    """FileHeader description: what, where, how critical (one line)."""
    m = spec.metrics
    keys = (
        "risk",
        "log10_risk",
        "t_detect_s",
        "ttc_at_detect_s",
        "min_ttc_s",
        "mean_pd",
        "corridor_s",
    )
    vals = ", ".join(f"{k}={m[k]:.6g}" for k in keys if k in m)
    sun = "" if spec.sun_deg is None else f", sun {spec.sun_deg[0]:g}/{spec.sun_deg[1]:g} deg"
    return (
        f"sensorgap critical scenario {spec.scenario_id} (rank {spec.rank}) for "
        f"{spec.system.name}: family {spec.family.name}, environment "
        f"{spec.environment_name}{sun}, target {spec.target.name}; {vals}"
    )


def declarations(
    spec: ScenarioSpec, extra: dict[str, str | float] | None = None
) -> xosc.ParameterDeclarations:
    """Every searched parameter with its value, the environment and the sun, then
    ``extra`` (parameters of the maneuver style) in their order."""
    params = xosc.ParameterDeclarations()
    for name, value in spec.params.items():
        if isinstance(value, str):
            params.add_parameter(xosc.Parameter(name, xosc.ParameterType.string, value))
        else:
            params.add_parameter(
                xosc.Parameter(name, xosc.ParameterType.double, repr(float(value)))
            )
    params.add_parameter(
        xosc.Parameter("environment", xosc.ParameterType.string, spec.environment_name)
    )
    if spec.sun_deg is not None:
        params.add_parameter(
            xosc.Parameter("sun_azimuth_deg", xosc.ParameterType.double, repr(spec.sun_deg[0]))
        )
        params.add_parameter(
            xosc.Parameter("sun_elevation_deg", xosc.ParameterType.double, repr(spec.sun_deg[1]))
        )
    for name, value in (extra or {}).items():
        if isinstance(value, bool):
            params.add_parameter(
                xosc.Parameter(name, xosc.ParameterType.boolean, str(value).lower())
            )
        elif isinstance(value, str):
            params.add_parameter(xosc.Parameter(name, xosc.ParameterType.string, value))
        else:
            params.add_parameter(
                xosc.Parameter(name, xosc.ParameterType.double, repr(float(value)))
            )
    return params


def set_version(version: str) -> int:
    """Set scenariogeneration's target version (a class attribute its objects consult
    when built: enumerations of newer versions raise) and return the minor."""
    minor = VERSIONS[version]
    VersionBase().setVersion(1, minor)
    return minor


def assemble(
    spec: ScenarioSpec,
    params: xosc.ParameterDeclarations,
    entities: xosc.Entities,
    storyboard: xosc.StoryBoard,
    road_relpath: str,
    minor: int,
) -> xosc.Scenario:
    """The Scenario object with our FileHeader (description, author, fixed date)."""
    return xosc.Scenario(
        description(spec),
        "sensorgap",
        params,
        entities,
        storyboard,
        xosc.RoadNetwork(roadfile=road_relpath),
        xosc.Catalog(),
        osc_minor_version=minor,
        creation_date=CREATION_DATE,
    )


def build_scenario(
    spec: ScenarioSpec,
    road_relpath: str,
    version: str = DEFAULT_VERSION,
    ego_brake: list[BrakeStep] | None = None,
    step_s: float = 0.05,
) -> xosc.Scenario:
    """The OpenSCENARIO object of one ranked scenario in the ``replay`` style. With
    ``ego_brake`` (``simulate --ego-reaction``) the ego's path ends one ``step_s`` (s)
    before the first brake step (the default controller keeps its lane and speed for that
    step: no running action conflicts with the braking) and the brake steps follow."""
    minor = set_version(version)
    params = declarations(spec)
    entities = xosc.Entities()
    entities.add_scenario_object(EGO, ego_entity(spec))
    entities.add_scenario_object(TARGET, actor_entity(TARGET, spec.target))

    init = xosc.Init()
    init.add_global_action(xosc.EnvironmentAction(environment(spec, minor)))
    step = xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0.0)
    # the ego's states are of its rear axle already; the target's of its box centre
    ego = spec.scenario.ego
    if ego_brake:
        n = int(np.searchsorted(ego.t, ego_brake[0].start_s - step_s + 1e-9, side="right"))
        n = max(n, 2)
        ego = Trajectory(ego.t[:n], ego.x[:n], ego.y[:n], ego.heading[:n], ego.speed[:n])
    paths = (
        (EGO, ego),
        (TARGET, origin_path(spec.scenario.target, target_origin_offset(spec.target))),
    )
    for name, tr in paths:
        init.add_init_action(
            name,
            xosc.TeleportAction(
                xosc.WorldPosition(
                    _fmt(float(tr.x[0])), _fmt(float(tr.y[0])), 0.0, _fmt(float(tr.heading[0]))
                )
            ),
        )
        if name == EGO:
            init.add_init_action(name, xosc.AbsoluteSpeedAction(_fmt(float(tr.speed[0])), step))
        else:  # from the first step on: not moved along the road by a default controller
            init.add_init_action(name, _follow(name, tr))

    start = xosc.ValueTrigger(
        "start",
        0.0,
        xosc.ConditionEdge.none,
        xosc.SimulationTimeCondition(0.0, xosc.Rule.greaterThan),
    )
    story = xosc.Story("critical_scenario")
    act = xosc.Act("follow_evaluated_paths", start)
    for name, tr in paths[:1]:
        event = xosc.Event(
            f"{name}_follow", xosc.Priority.override if minor >= 2 else xosc.Priority.overwrite
        )
        event.add_action(f"{name}_trajectory", _follow(name, tr))
        event.add_trigger(start)
        man = xosc.Maneuver(f"{name}_maneuver")
        man.add_event(event)
        for ev in brake_events(ego_brake or [], minor, step_s):
            man.add_event(ev)
        group = xosc.ManeuverGroup(f"{name}_group")
        group.add_actor(name)
        group.add_maneuver(man)
        act.add_maneuver_group(group)
    story.add_act(act)
    stop = xosc.ValueTrigger(
        "end",
        0.0,
        xosc.ConditionEdge.rising,
        xosc.SimulationTimeCondition(_fmt(spec.family.duration_s), xosc.Rule.greaterThan),
        "stop",
    )
    sb = xosc.StoryBoard(init, stop)
    sb.add_story(story)
    return assemble(spec, params, entities, sb, road_relpath, minor)


@contextmanager
def _element_truth_quiet() -> Iterator[None]:
    """scenariogeneration 0.16 tests an XML element's truth value when it writes a
    scenario (``xosc/scenario.py``), which Python 3.12+ warns about: a user's
    ``PYTHONWARNINGS=default`` printed the warning, ``=error`` made every export an
    internal error (hostile round 32). That one warning is ignored while it writes."""
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", message="Testing an element's truth value", category=DeprecationWarning
        )
        yield


def write_scenario_xml(scenario: xosc.Scenario, path: str | Path) -> None:
    """Write ``scenario`` (scenariogeneration's) to ``path``, pretty-printed, without the
    library's element-truth warning (``_element_truth_quiet``)."""
    with _element_truth_quiet():
        scenario.write_xml(str(path), prettyprint=True)
