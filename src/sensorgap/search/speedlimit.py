"""The highest ego speed a family may use in an environment: driving within sight.

A critical scenario must be an encounter a lawful vehicle could be in. German road traffic
law, StVO section 3(1) (which an automated driving function must obey, StVG section 1e),
bounds the speed by the visibility:

* sentence 4 (driving within sight): "Es darf nur so schnell gefahren werden, dass
  innerhalb der uebersehbaren Strecke gehalten werden kann" — the vehicle must be able to
  stop within the distance it can see. Applied with the vehicle's own reaction model
  (latency, jerk-limited brake ramp, deceleration ``min(decel_max, mu g)`` on the road
  surface the weather implies), the same stopping model as the collision outcome
  (``search.outcome.stopping_distance``), over the meteorological visibility of the
  weather (``Conditions.meteorological_visibility_m``: fog, rain and snow);
* sentence 3: below 50 m visibility through fog, snowfall or rain, at most 50 km/h.

Without this bound the search ranks a vehicle driving 120 km/h in 50 m fog as a sensor
weakness: an encounter no lawful driver is in (docs/search.md, "Speed within sight").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sensorgap.config import EnvironmentConfig
from sensorgap.config.reaction import ReactionConfig, road_condition
from sensorgap.models.conditions import Conditions
from sensorgap.search.outcome import G_M_S2, stopping_distance

#: StVO section 3(1) sentence 3: below this visibility, m ...
FOG_RULE_VISIBILITY_M = 50.0
#: ... at most this speed, m/s (50 km/h).
FOG_RULE_SPEED_M_S = 50.0 / 3.6
#: Upper end of the bisection, m/s (360 km/h: above every family's range).
_V_HIGH_M_S = 100.0


@dataclass(frozen=True)
class SpeedLimit:
    """The speed bound of one environment for one vehicle.

    Attributes:
        speed_m_s: the highest lawful ego speed, m/s (``inf`` when nothing bounds it
            below 360 km/h).
        visibility_m: the meteorological visibility it was derived from, m.
        rule: which rule binds, in words (for the report and infeasibility notes).
    """

    speed_m_s: float
    visibility_m: float
    rule: str


def sight_speed_m_s(
    visibility_m: float, latency_s: float, jerk_m_s3: float, decel_m_s2: float
) -> float:
    """The highest speed, m/s, from which a vehicle stops within ``visibility_m`` m: latency
    ``latency_s`` s, brake ramp ``jerk_m_s3`` m/s3 up to ``decel_m_s2`` m/s2 (bisection to
    1e-6 m/s on the monotone stopping distance; ``inf`` above 360 km/h)."""
    if not visibility_m > 0.0:
        return 0.0
    if stopping_distance(_V_HIGH_M_S, latency_s, jerk_m_s3, decel_m_s2) <= visibility_m:
        return math.inf
    lo, hi = 0.0, _V_HIGH_M_S
    while hi - lo > 1e-6:
        mid = 0.5 * (lo + hi)
        if stopping_distance(mid, latency_s, jerk_m_s3, decel_m_s2) <= visibility_m:
            lo = mid
        else:
            hi = mid
    return lo


def speed_limit(
    env: EnvironmentConfig, reaction: ReactionConfig, friction: dict[str, float]
) -> SpeedLimit:
    """The lawful ego speed bound of ``env`` for a vehicle with ``reaction`` on roads of
    peak ``friction`` per condition (module docstring)."""
    vis = Conditions.from_config(env).meteorological_visibility_m()
    cond = road_condition(env)
    decel = min(reaction.decel_max_m_s2, friction[cond] * G_M_S2)
    sight = sight_speed_m_s(vis, reaction.latency_s, reaction.jerk_m_s3, decel)
    if vis < FOG_RULE_VISIBILITY_M and sight > FOG_RULE_SPEED_M_S:
        return SpeedLimit(
            FOG_RULE_SPEED_M_S, vis, f"StVO 3(1): visibility {vis:g} m, below 50 m at most 50 km/h"
        )
    if math.isinf(sight):
        return SpeedLimit(math.inf, vis, "no bound below 360 km/h")
    return SpeedLimit(
        sight,
        vis,
        f"StVO 3(1) driving within sight: stop within the visibility "
        f"{vis:g} m ({cond} road, {decel:.1f} m/s2, latency "
        f"{reaction.latency_s:g} s) at most {sight * 3.6:.0f} km/h",
    )
