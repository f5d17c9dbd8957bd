"""Physical bounds of scenario-family parameters, by name.

A family file's ``[parameters]`` range and ``sensorgap evaluate --param`` are checked
against these bounds (a value outside is not a manoeuvre a road user makes; a tiny or
negative lane-change duration would also divide by ~0 in the trajectory). Each bound has
a unit and a source (docs/limits.md).
"""

from __future__ import annotations

import math
from typing import NamedTuple


class Bound(NamedTuple):
    """Closed range ``[low, high]`` of a parameter in ``unit``, with its ``source``."""

    low: float
    high: float
    unit: str
    source: str


#: Parameter name -> its physical bound.
PARAMETER_BOUNDS: dict[str, Bound] = {
    # Lane-change duration (start to end of the lateral move), s. Naturalistic single lane
    # changes take 6.28 s on average, SD 2.0 s (7,192 lane changes of 16 commuters;
    # Olsen, Lee & Wierwille 2002, "Analysis of distribution, frequency, and duration of
    # naturalistic lane changes", Proc. HFES 46th Annual Meeting): 10 s is about the mean
    # + 2 SD. The shortest means reported are 1.25 s and 1.95 s (an early study reviewed by
    # Toledo & Zohar 2007, "Modeling duration of lane changes", TRR 1999), and about 1.5 s
    # to execute the change (Finnegan & Green 1990, UMTRI-90-34): 1 s is below any of them.
    "lc_duration_s": Bound(
        1.0,
        10.0,
        "s",
        "lane changes take 1-10 s: Olsen et al. 2002, 6.28 +- 2.0 s; Toledo & Zohar 2007",
    ),
    # The overtaking car's merge into the ego lane is a lane change: the same bound (a
    # zero merge duration would also divide by zero in the trajectory).
    "merge_duration_s": Bound(
        1.0,
        10.0,
        "s",
        "a merge is a lane change, 1-10 s: Olsen et al. 2002, 6.28 +- 2.0 s; Toledo & Zohar 2007",
    ),
    # Braking of a road user: at most the peak tyre-road friction, mu <= 0.9 on dry asphalt
    # (Wong, Theory of Ground Vehicles; templates/reactions.toml [friction]), 0.9 g = 8.8
    # m/s2; 10 m/s2 leaves room for sports tyres.
    "decel_m_s2": Bound(
        0.0,
        10.0,
        "m/s2",
        "braking at up to about 1 g: peak tyre-road friction mu <= 0.9 on dry asphalt (Wong)",
    ),
    # Gap between the two parked cars the pedestrian steps out between (bumper to bumper):
    # wide enough for a walker (0.5 m, targets.toml), and short of a gap that no longer
    # hides anyone (estimate: 10 m, two car lengths).
    "parked_gap_m": Bound(
        0.5,
        10.0,
        "m",
        "estimate: a walker (0.5 m) passes; beyond two car lengths the cars hide no one",
    ),
}


#: Bounds by unit suffix, for parameters without their own entry (any family's, plugins'
#: included): a speed of a road user, m/s, a distance or position along the road, m, an
#: acceleration, m/s2, a speed difference, m/s, and a time, s (the first suffix that
#: matches wins).
SUFFIX_BOUNDS: dict[str, Bound] = {
    "_speed_m_s": Bound(
        0.0,
        100.0,
        "m/s",
        "road users move forwards at up to 360 km/h; estimate: above any road vehicle's top speed",
    ),
    "_m": Bound(
        -10_000.0,
        10_000.0,
        "m",
        "a scene within 10 km of the ego: the largest sensor range, docs/limits.md",
    ),
    "_m_s2": Bound(
        -10.0,
        10.0,
        "m/s2",
        "road users accelerate and brake at up to about 1 g: mu <= 0.9 on dry asphalt (Wong)",
    ),
    # after "_speed_m_s": a speed difference between two road users (speed_delta_m_s)
    "_m_s": Bound(
        -100.0,
        100.0,
        "m/s",
        "a speed difference of two road users, each at most 100 m/s",
    ),
    "_s": Bound(
        -60.0,
        60.0,
        "s",
        "a moment or span within the longest scenario (family duration_s <= 60 s)",
    ),
}


def bound_of(name: str) -> Bound | None:
    """The physical bound of parameter ``name``: its own, else by unit suffix, else None."""
    b = PARAMETER_BOUNDS.get(name)
    if b is not None:
        return b
    return next((sb for suffix, sb in SUFFIX_BOUNDS.items() if name.endswith(suffix)), None)


def bound_error(name: str, value: float) -> str | None:
    """Why ``value`` of parameter ``name`` is refused (outside its physical bound, or not
    finite), or None when it is accepted (also for a parameter without a bound)."""
    b = bound_of(name)
    if b is None:
        return None
    if not (math.isfinite(value) and b.low <= value <= b.high):
        return f"must be within {b.low:g}..{b.high:g} {b.unit} ({b.source}), got {float(value)!r}"
    return None
