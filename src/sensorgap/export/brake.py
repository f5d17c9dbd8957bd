"""The reaction model's braking as OpenSCENARIO actions on the ego (``simulate
--ego-reaction``, issue #15 item 3).

The reaction model (``search.outcome``) brakes from the planned speed ``v0`` with a
deceleration that ramps up at the jerk J to ``A = min(decel_max, mu g)`` and holds until
standstill. OpenSCENARIO has no jerk-limited dynamics shape, so the ramp is a sequence of
``SpeedAction``s with linear shape and a constant rate, one per simulation step: step i
(from onset + i dt) goes to the model's speed at onset + (i + 1) dt at the rate that gets
there in dt (the ramp's mean deceleration over the step: the speeds at the step ends are
the model's exactly), then one action at the rate A to standstill. Each starts on
``SimulationTime`` (half a step before its time: a condition holds at the first step at or
after it); each overrides the one before. Speeds and rates are multiplied by the ego's
lane-speed factor (the exported ego speed per planned speed), so the ego's progress along
its lane stays the plan's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scenariogeneration import xosc

from sensorgap.search.outcome import braked_speed


@dataclass(frozen=True)
class BrakeStep:
    """One speed action of the braking: from ``start_s`` (simulation time, s) to
    ``speed_m_s`` (m/s) at ``rate_m_s2`` (m/s2)."""

    start_s: float
    speed_m_s: float
    rate_m_s2: float


def brake_steps(
    t_brake_s: float,
    v0_m_s: float,
    jerk_m_s3: float,
    decel_m_s2: float,
    step_s: float,
    factor: float = 1.0,
) -> list[BrakeStep]:
    """The speed actions of a jerk-limited braking from ``v0_m_s`` (m/s) starting at
    ``t_brake_s`` (s): the ramp (``jerk_m_s3``, m/s3, up to ``decel_m_s2``, m/s2) one
    ``step_s`` (s) at a time, then constant deceleration to 0; speeds and rates times
    ``factor`` (the ego's lane speed per planned speed)."""
    if not (v0_m_s > 0.0 and jerk_m_s3 > 0.0 and decel_m_s2 > 0.0 and step_s > 0.0):
        raise ValueError("need v0, jerk, decel and step > 0")
    t_ramp = decel_m_s2 / jerk_m_s3
    out: list[BrakeStep] = []
    tau = 0.0
    while tau < t_ramp - 1e-12:
        tau1 = min(tau + step_s, t_ramp)
        v_a = float(braked_speed(tau, v0_m_s, jerk_m_s3, decel_m_s2))
        v_b = float(braked_speed(tau1, v0_m_s, jerk_m_s3, decel_m_s2))
        if v_a <= 0.0:
            return out
        if v_b <= 0.0:  # stops during the ramp: the time to standstill within this step
            t_stop = math.sqrt(2.0 * v0_m_s / jerk_m_s3)
            tau1 = max(t_stop, tau + 1e-9)
        out.append(
            BrakeStep(
                t_brake_s + tau,
                factor * max(v_b, 0.0),
                factor * (v_a - max(v_b, 0.0)) / (tau1 - tau),
            )
        )
        if v_b <= 0.0:
            return out
        tau = tau1
    out.append(BrakeStep(t_brake_s + tau, 0.0, factor * decel_m_s2))
    return out


def brake_events(steps: list[BrakeStep], minor: int, step_s: float) -> list[xosc.Event]:
    """One event per brake step: an ``AbsoluteSpeedAction`` (linear shape, rate) started
    by ``SimulationTime > start - step / 2``."""
    events = []
    for i, st in enumerate(steps):
        ev = xosc.Event(
            f"ego_brake_{i}", xosc.Priority.override if minor >= 2 else xosc.Priority.overwrite
        )
        ev.add_action(
            f"ego_brake_{i}_action",
            xosc.AbsoluteSpeedAction(
                float(round(st.speed_m_s, 6)),
                xosc.TransitionDynamics(
                    xosc.DynamicsShapes.linear,
                    xosc.DynamicsDimension.rate,
                    float(round(st.rate_m_s2, 6)),
                ),
            ),
        )
        ev.add_trigger(
            xosc.ValueTrigger(
                f"ego_brake_{i}_time",
                0.0,
                xosc.ConditionEdge.none,
                xosc.SimulationTimeCondition(
                    float(round(st.start_s - 0.5 * step_s, 6)), xosc.Rule.greaterThan
                ),
            )
        )
        events.append(ev)
    return events
