"""Ranking: sort by risk, collapse near-duplicates, explain each ranked scenario.

Near-duplicates: two candidates of the same family and environment preset whose distance
is below ``min_distance`` (default 0.15). The distance is the RMS over dimensions of the
range-normalised parameter differences (choices: 0 if equal, 1 if not; sun azimuth: the
circular difference / 180 deg; sun elevation: difference / 28 deg), so 0 = identical and
1 = opposite corners of the box. The lower-risk one of a pair is dropped; candidates of
different families or environment presets are never duplicates. At most ``MAX_PER_GROUP``
(3) scenarios per (family, environment preset) enter the list while others remain.

Reason: at the critical step (the one that sets the risk) each sensor is evaluated exactly
in the scenario's environment, in the same environment without sun, and in a reference
clear atmosphere (23 km, no precipitation, no ROC shift, no sun). A sensor is ``out of
view`` (``FOV`` or ``range`` from its mount geometry) or in view with Pd < 0.5 because of
``glare`` (Pd without sun higher by >= 0.2), ``weather`` (reference higher by >= 0.2 than
without sun) or ``range`` (weak even in clear air). The dominant effect is the most frequent
among in-view low-Pd sensors (ties: glare, weather, range), or, when no sensor has the
target in view, ``FOV`` if some sensor has it within range, else ``range``.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from sensorgap.config import EnvironmentConfig
from sensorgap.models.geometry import fov_mask, rotate_offsets, sensor_range
from sensorgap.search.metrics import critical_index
from sensorgap.search.problem import Candidate, Result, SearchProblem

#: Default near-duplicate distance.
MIN_DISTANCE = 0.15
#: Default cap of ranked scenarios per (family, environment preset), so the top N span the
#: families and conditions instead of N variants of the single worst one.
MAX_PER_GROUP = 3
_EFFECT_ORDER = ("glare", "weather", "range")


def candidate_distance(problem: SearchProblem, a: Candidate, b: Candidate) -> float:
    """Normalised distance (see module docstring); inf across families/environments."""
    if a.family != b.family or a.environment != b.environment:
        return math.inf
    n = len(problem.family.space)
    acc = problem.family.distance(a.params, b.params) ** 2 * n
    if a.sun is not None and b.sun is not None:
        daz = abs(a.sun[0] - b.sun[0]) % 360.0
        acc += (min(daz, 360.0 - daz) / 180.0) ** 2 + ((a.sun[1] - b.sun[1]) / 28.0) ** 2
        n += 2
    return math.sqrt(acc / max(n, 1))


def diverse_top(results: list[Result], problems: dict[str, SearchProblem], top: int,
                min_distance: float = MIN_DISTANCE,
                max_per_group: int = MAX_PER_GROUP) -> list[Result]:
    """The ``top`` highest-risk feasible results, near-duplicates collapsed and at most
    ``max_per_group`` per (family, environment preset) (ties broken by scenario id, so the
    order is deterministic). When fewer than ``top`` remain, the cap is lifted for the rest
    (the list is never shorter than it could be)."""
    ok = sorted((r for r in results if r.feasible),
                key=lambda r: (-r.score, -r.risk, r.candidate.scenario_id))
    chosen: list[Result] = []
    for cap in (max_per_group, None):
        groups = Counter((c.candidate.family, c.candidate.environment) for c in chosen)
        for r in ok:
            if len(chosen) == top:
                return chosen
            key = (r.candidate.family, r.candidate.environment)
            if r in chosen or (cap is not None and groups[key] >= cap):
                continue
            prob = problems[r.candidate.family]
            if all(candidate_distance(prob, r.candidate, c.candidate) >= min_distance
                   for c in chosen):
                chosen.append(r)
                groups[key] += 1
    return chosen


@dataclass(frozen=True)
class Explanation:
    """Why a scenario is critical (see module docstring)."""

    reason: str
    dominant: str
    step_t_s: float
    sensors: dict[str, str]
    pd: dict[str, float] | None = None


def reference_environment() -> EnvironmentConfig:
    """Clear air, no precipitation, no ROC shift, no sun."""
    return EnvironmentConfig(name="reference")


def explain(problem: SearchProblem, cand: Candidate) -> Explanation:
    """Per-sensor reason at the critical step (exact evaluation)."""
    ev = problem.evaluator
    sc = problem.scenario(cand)
    env = problem.environment(cand)
    tr = ev.trace(sc, env, problem.family.duration_s)
    k = critical_index(tr)
    target = ev.target(sc.target_class)
    h, x, y = tr.heading[k:k + 1], tr.x[k:k + 1], tr.y[k:k + 1]
    pd_act = ev.per_sensor_pd(env, target, h, x, y, exact=True)[:, 0]
    pd_nosun = ev.per_sensor_pd(env.model_copy(update={"sun": None}), target, h, x, y,
                                exact=True)[:, 0]
    pd_ref = ev.per_sensor_pd(reference_environment(), target, h, x, y, exact=True)[:, 0]
    z = target.reference_height_m
    effects: dict[str, str] = {}
    low: list[tuple[str, str, float, float]] = []
    for i, s in enumerate(problem.evaluator.system.sensors):
        m = s.mount
        xs, ys, zs = rotate_offsets(m, x - m.x, y - m.y, np.array([z - m.z]))
        r = float(sensor_range(xs, ys, zs)[0])
        in_range = m.min_range <= r <= m.max_range
        if not (in_range and bool(fov_mask(m, xs, ys, zs)[0])):
            effects[s.id] = "range" if not in_range else "FOV"
            continue
        if pd_act[i] >= 0.5:
            effects[s.id] = "sees"
            continue
        if pd_nosun[i] - pd_act[i] >= 0.2:
            eff, better = "glare", pd_nosun[i]
        elif pd_ref[i] - pd_nosun[i] >= 0.2:
            eff, better = "weather", pd_ref[i]
        else:
            eff, better = "range", pd_ref[i]
        effects[s.id] = eff
        low.append((s.id, eff, float(pd_act[i]), float(better)))
    counts = Counter(e for _, e, _, _ in low)
    if counts:
        dominant = max(_EFFECT_ORDER, key=lambda e: (counts[e], -_EFFECT_ORDER.index(e)))
    elif any(e == "sees" for e in effects.values()):
        dominant = "none"
    else:
        dominant = "FOV" if any(e == "FOV" for e in effects.values()) else "range"
    out_fov = sum(1 for e in effects.values() if e == "FOV")
    out_rng = sum(1 for sid, e in effects.items() if e == "range"
                  and sid not in {s for s, _, _, _ in low})
    seen = [sid for sid, e in effects.items() if e == "sees"]
    parts = [f"{dominant}: at t={tr.t[k]:.2f} s target at x={x[0]:.1f} y={y[0]:.1f} m, "
             f"Pd={tr.pd[k]:.2f}, P_undet={tr.p_undetected[k]:.2g}"]
    if low:
        parts.append("low Pd: " + ", ".join(f"{sid} {e} {p:.2f} (else {b:.2f})"
                                            for sid, e, p, b in low[:4]))
    if seen:
        parts.append("sees: " + ", ".join(seen[:3]))
    parts.append(f"out of view: {out_fov} FOV, {out_rng} range")
    pds = {s.id: float(pd_act[i]) for i, s in enumerate(problem.evaluator.system.sensors)}
    return Explanation("; ".join(parts), dominant, float(tr.t[k]), effects, pds)
