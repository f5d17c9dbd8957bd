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
import re
from collections import Counter
from dataclasses import dataclass

import numpy as np

from sensorgap.config import EnvironmentConfig
from sensorgap.models.conditions import Conditions
from sensorgap.models.geometry import rotate_offsets, sensor_range
from sensorgap.scenarios.trajectory import DT_S
from sensorgap.search.evaluate import Trace
from sensorgap.search.metrics import critical_index
from sensorgap.search.problem import (
    Candidate,
    Result,
    SearchProblem,
    enough_margin,
)

#: Default near-duplicate distance.
MIN_DISTANCE = 0.15
#: Default cap of ranked scenarios per (family, environment preset), so the top N span the
#: families and conditions instead of N variants of the single worst one.
MAX_PER_GROUP = 3
_EFFECT_ORDER = ("occlusion", "glare", "weather", "partly in view", "range")
_WITHOUT = {
    "occlusion": "without the occluders",
    "glare": "without the sun",
    "weather": "in clear air",
    "partly in view": "in clear air",
    "range": "in clear air",
}


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


def diverse_top(
    results: list[Result],
    problems: dict[str, SearchProblem],
    top: int,
    min_distance: float = MIN_DISTANCE,
    max_per_group: int = MAX_PER_GROUP,
) -> list[Result]:
    """The ``top`` highest-risk feasible results, near-duplicates collapsed and at most
    ``max_per_group`` per (family, environment preset) (ties broken by scenario id, so the
    order is deterministic). When fewer than ``top`` remain, the cap is lifted for the rest
    (the list is never shorter than it could be)."""
    ok = sorted(
        (r for r in results if r.feasible),
        key=lambda r: (-r.score, -r.risk, r.candidate.scenario_id),
    )
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
            if all(
                candidate_distance(prob, r.candidate, c.candidate) >= min_distance for c in chosen
            ):
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
    #: Per glared sensor, the angle (deg) between the sun and its line of sight to the
    #: target's centre at the reference height: the angle the veiling glare falls with.
    sun_deg: dict[str, float] | None = None


def reference_environment() -> EnvironmentConfig:
    """Clear air, no precipitation, no ROC shift, no sun."""
    return EnvironmentConfig(name="reference")


def occluder_phrase(labels: tuple[str, ...] | list[str]) -> str:
    """The occluders of a scene in words: numbered labels of one kind merge into a plural
    (``parked car 1``, ``parked car 2`` -> ``parked cars``), kinds joined by ``and``."""
    kinds: dict[str, int] = {}
    for label in labels:
        base = re.sub(r"\s+\d+$", "", label)
        kinds[base] = kinds.get(base, 0) + 1
    words = [k + ("s" if n > 1 else "") for k, n in kinds.items()]
    return " and ".join(words)


def named_step(tr: Trace) -> int:
    """The step a scenario's reason names: with a collision outcome, the step of weakest
    confirmation (lowest Pd of the confirming sensors, the last of equals) between the threat
    onset and t_safe (the last moment a confirmation still avoids the collision; the end
    when none is defined); otherwise the step that sets the risk."""
    t_threat = tr.extra.get("t_threat_s", math.nan)
    if not math.isfinite(t_threat):
        return critical_index(tr)
    k0 = int(round(t_threat / DT_S))
    t_safe = tr.extra.get("t_safe_s", math.nan)
    k1 = len(tr.t) - 1 if not math.isfinite(t_safe) else int(round(t_safe / DT_S))
    k0, k1 = min(k0, len(tr.t) - 1), min(max(k1, k0), len(tr.t) - 1)
    pd = (tr.pd if tr.pd_confirm is None else tr.pd_confirm)[k0 : k1 + 1]
    return k0 + int(len(pd) - 1 - np.argmin(pd[::-1]))  # the last of equals: nearest


def explain(problem: SearchProblem, cand: Candidate) -> Explanation:
    """Per-sensor reason at the named step (``named_step``), exact evaluation of the
    target's body; a sensor that sees the target (Pd >= 0.5) but cannot confirm it for
    braking (the reaction model's ``confirm_with``) is listed as such."""
    ev = problem.evaluator
    sc = problem.scenario(cand)
    env = problem.environment(cand)
    tr = ev.trace(sc, env, problem.family.duration_s)
    k = named_step(tr)
    target = ev.target(sc.target_class)
    h, x, y = tr.heading[k : k + 1], tr.x[k : k + 1], tr.y[k : k + 1]
    psi = None if tr.psi is None else tr.psi[k : k + 1]
    occ = None if tr.occluders is None else tr.occluders[k : k + 1]
    pd_act = ev.per_sensor_pd(env, target, h, x, y, psi=psi, occluders=occ)[:, 0]
    pd_open = pd_act if occ is None else ev.per_sensor_pd(env, target, h, x, y, psi=psi)[:, 0]
    pd_nosun = ev.per_sensor_pd(env.model_copy(update={"sun": None}), target, h, x, y, psi=psi)[
        :, 0
    ]
    pd_ref = ev.per_sensor_pd(reference_environment(), target, h, x, y, psi=psi)[:, 0]
    frac = ev.visible_fraction(env, target, x, y, psi)[:, 0]
    confirm = set(ev.confirming(float(sc.target.speed[k])))
    effects: dict[str, str] = {}
    low: list[tuple[str, str, float, float]] = []
    sun_deg: dict[str, float] = {}
    sun = Conditions.sun_directions(env, h)
    for i, s in enumerate(ev.system.sensors):
        m = s.mount
        if frac[i] <= 0.0 and pd_ref[i] <= 0.0:
            xs, ys, zs = rotate_offsets(
                m, x - m.x, y - m.y, np.array([target.reference_height_m - m.z])
            )
            r = float(sensor_range(xs, ys, zs)[0])
            reach = 0.5 * math.hypot(target.length_m, target.width_m)
            effects[s.id] = "range" if r - reach > m.max_range else "FOV"
            continue
        if pd_act[i] >= 0.5:
            effects[s.id] = "sees" if i in confirm else "sees (cannot confirm)"
            continue
        if pd_open[i] - pd_act[i] >= 0.2:
            eff, better = "occlusion", pd_open[i]
        elif pd_nosun[i] - pd_open[i] >= 0.2:
            eff, better = "glare", pd_nosun[i]
        elif pd_ref[i] - pd_nosun[i] >= 0.2:
            eff, better = "weather", pd_ref[i]
        elif 0.0 < frac[i] < 1.0 and pd_ref[i] < 0.5:
            eff, better = "partly in view", pd_ref[i]
        else:
            eff, better = "range", pd_ref[i]
        effects[s.id] = eff
        if eff == "glare" and sun is not None:
            sun_deg[s.id] = sight_angle_deg(
                sun[0], float(x[0]) - m.x, float(y[0]) - m.y, target.reference_height_m - m.z
            )
        if i in confirm:
            low.append((s.id, eff, float(pd_act[i]), float(better)))
    counts = Counter(e for _, e, _, _ in low)
    if counts:
        dominant = max(_EFFECT_ORDER, key=lambda e: (counts[e], -_EFFECT_ORDER.index(e)))
    elif any(e == "sees" for e in effects.values()):
        dominant = "none"
    else:
        dominant = (
            "FOV"
            if any(e == "FOV" for i, (sid, e) in enumerate(effects.items()) if i in confirm)
            else "range"
        )
    n_fov = sum(1 for i, e in enumerate(effects.values()) if e == "FOV" and i in confirm)
    n_rng = sum(1 for i, e in enumerate(effects.values()) if e == "range" and i in confirm)
    seen = [sid for sid, e in effects.items() if e == "sees"]
    support = [sid for sid, e in effects.items() if e == "sees (cannot confirm)"]
    pc = tr.extra.get("collision_probability")
    pdc = tr.pd if tr.pd_confirm is None else tr.pd_confirm
    head = (
        f"{dominant}: at t={tr.t[k]:.2f} s the target is at x={x[0]:.1f} y={y[0]:.1f} m "
        f"(ego frame), Pd of the confirming sensors {pdc[k]:.2f}"
    )
    parts = [head]
    if pc is not None:
        parts.append(f"P(collision) {pc:.2g}")
    if low:
        parts.append(
            "missing: "
            + ", ".join(
                f"{sid} ({e}: Pd {p:.2f}, {b:.2f} {_WITHOUT[e]}{_sun_words(sun_deg, sid)})"
                for sid, e, p, b in low[:4]
            )
        )
    if counts.get("occlusion") and tr.occluder_labels:
        parts.append(
            f"hidden behind the {occluder_phrase(tr.occluder_labels)} "
            "for " + ", ".join(sid for sid, e, _, _ in low if e == "occlusion")
        )
    if seen:
        parts.append("confirming: " + ", ".join(seen[:3]))
    if support:
        parts.append("seen but cannot confirm: " + ", ".join(support[:3]))
    if n_fov or n_rng:
        parts.append(
            f"confirming sensors not covering the target: {n_fov} by field of view, "
            f"{n_rng} by range"
        )
    pds = {s.id: float(pd_act[i]) for i, s in enumerate(ev.system.sensors)}
    return Explanation("; ".join(parts), dominant, float(tr.t[k]), effects, pds, sun_deg or None)


def sight_angle_deg(sun: np.ndarray, dx_m: float, dy_m: float, dz_m: float) -> float:
    """Angle (deg, 0..180) between a vehicle-frame unit vector to the sun and the line of
    sight from a sensor to a point offset by (dx, dy, dz) m from it (vehicle-frame axes);
    the ``theta`` of the camera's veiling glare (models/camera.py), 0 for a zero offset."""
    r = math.sqrt(dx_m * dx_m + dy_m * dy_m + dz_m * dz_m)
    if r == 0.0:
        return 0.0
    c = (float(sun[0]) * dx_m + float(sun[1]) * dy_m + float(sun[2]) * dz_m) / r
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def _sun_words(sun_deg: dict[str, float], sid: str) -> str:
    a = sun_deg.get(sid)
    return "" if a is None else f", sun {a:.1f} deg from its line of sight"


#: Candidates re-evaluated exactly before ranking: the best by the search objective in
#: every (family, environment preset) group, about this many in all (and at least
#: ``POOL_PER_RANK`` per ranked row), at least ``POOL_GROUP_MIN`` per group, plus the
#: ``UNAVOIDABLE_PER_GROUP`` highest-impact unavoidable ones per group.
POOL_MIN = 400
POOL_PER_RANK = 25
POOL_GROUP_MIN = 5
UNAVOIDABLE_PER_GROUP = 2
#: Sensor-critical scenarios less likely than this to end in a collision are not ranked
#: (counted in summary.json): a list of one-in-10^30 collisions helps no test engineer.
RANK_MIN_P = 1e-6
#: Outcome tolerances within which two rows of a family and dominant effect are one
#: encounter placed elsewhere on the road (``rank_exact``): P(collision), km/h, s.
SAME_OUTCOME = {"collision_probability": 1e-5, "impact_speed_kmh": 0.01, "t_safe_s": 1e-6}


def classify(r: Result) -> str:
    """``sensor-critical`` (a perfect-perception vehicle avoids the collision with at least
    ``MIN_PERFECT_MARGIN_S`` to spare, this one may not), ``marginal`` (perfect perception
    avoids it by less), ``unavoidable`` (collides even with perfect perception), ``not
    critical`` or ``infeasible``."""
    if not r.feasible:
        return "infeasible"
    if r.metrics.get("collision_perfect", 0.0) > 0.5:
        return "unavoidable"
    if r.metrics.get("collision_probability", 0.0) > 0.0:
        if not enough_margin(r.metrics.get("perfect_margin_s", math.inf)):
            return "marginal"
        return "sensor-critical"
    return "not critical"


def reevaluate(
    results: list[Result],
    exact: dict[str, SearchProblem],
    pool: int,
    cache: dict[str, Result] | None = None,
) -> tuple[list[tuple[Result, Result]], dict[str, float]]:
    """Re-evaluate about ``pool`` of the best feasible results (search objective, spread
    over the (family, environment) groups; see ``POOL_MIN``) exactly with the ``exact``
    problems; returns (lookup result, exact result) pairs and the disagreement of the two
    over them (what the lookup proposed vs what exact evaluation decides). ``cache``:
    exact results by scenario id, reused and filled (several searches of one run share
    their re-evaluations)."""
    groups: dict[tuple[str, str], list[Result]] = {}
    for r in results:
        if r.feasible:
            groups.setdefault((r.candidate.family, r.candidate.environment), []).append(r)
    per_group = max(POOL_GROUP_MIN, -(-pool // max(len(groups), 1)))
    seen: set[str] = set()
    chosen = []

    def take(rs: list[Result], n: int) -> None:
        k = 0
        for r in rs:
            if k == n:
                return
            if r.candidate.scenario_id not in seen:
                seen.add(r.candidate.scenario_id)
                chosen.append(r)
                k += 1

    for key in sorted(groups):
        rs = groups[key]
        take(sorted(rs, key=lambda r: (-r.objective, r.candidate.scenario_id)), per_group)
        # the most violent encounters that collide even with perfect perception (listed
        # apart, never ranked)
        take(
            sorted(
                (r for r in rs if classify(r) == "unavoidable"),
                key=lambda r: (-r.metrics.get("impact_speed_kmh", 0.0), r.candidate.scenario_id),
            ),
            UNAVOIDABLE_PER_GROUP,
        )
    cache = {} if cache is None else cache
    by_family: dict[str, list[Result]] = {}
    for r in chosen:
        if r.candidate.scenario_id not in cache:
            by_family.setdefault(r.candidate.family, []).append(r)
    for fam, rs in by_family.items():
        for r, e in zip(rs, exact[fam].evaluate_many([r.candidate for r in rs]), strict=True):
            cache[r.candidate.scenario_id] = e
    pairs = sorted(
        ((r, cache[r.candidate.scenario_id]) for r in chosen),
        key=lambda p: (-p[0].objective, p[0].candidate.scenario_id),
    )
    return pairs, disagreement(pairs)


def disagreement(pairs: list[tuple[Result, Result]]) -> dict[str, float]:
    """Lookup vs exact over (lookup result, exact result) pairs: P(collision) differences,
    sensor-critical counts by each and both, the overlap of the top 10 by P(collision)."""
    if not pairs:
        return {"reevaluated": 0}
    pl = np.array([p[0].metrics.get("collision_probability", 0.0) for p in pairs])
    pe = np.array([p[1].metrics.get("collision_probability", 0.0) for p in pairs])
    cl = {p[0].candidate.scenario_id for p in pairs if classify(p[0]) == "sensor-critical"}
    ce = {p[1].candidate.scenario_id for p in pairs if classify(p[1]) == "sensor-critical"}
    k = min(10, len(pairs))
    top_l = {
        p[0].candidate.scenario_id
        for p in sorted(pairs, key=lambda p: -p[0].metrics.get("collision_probability", 0.0))[:k]
    }
    top_e = {
        p[1].candidate.scenario_id
        for p in sorted(pairs, key=lambda p: -p[1].metrics.get("collision_probability", 0.0))[:k]
    }
    return {
        "reevaluated": len(pairs),
        "mean_abs_diff_collision_probability": float(np.mean(np.abs(pl - pe))),
        "max_abs_diff_collision_probability": float(np.max(np.abs(pl - pe))),
        "sensor_critical_lookup": len(cl),
        "sensor_critical_exact": len(ce),
        "sensor_critical_both": len(cl & ce),
        f"top{k}_overlap": len(top_l & top_e),
    }


def merge_pairs(*pair_lists: list[tuple[Result, Result]]) -> list[tuple[Result, Result]]:
    """The union of several searches' re-evaluated pairs (one per scenario id), in the
    order ``reevaluate`` gives (search objective, then scenario id)."""
    seen: dict[str, tuple[Result, Result]] = {}
    for pairs in pair_lists:
        for p in pairs:
            seen.setdefault(p[0].candidate.scenario_id, p)
    return sorted(seen.values(), key=lambda p: (-p[0].objective, p[0].candidate.scenario_id))


def rank_exact(
    pairs: list[tuple[Result, Result]],
    problems: dict[str, SearchProblem],
    top: int,
    min_distance: float = MIN_DISTANCE,
    max_per_group: int = MAX_PER_GROUP,
    explained: dict[str, Explanation] | None = None,
) -> tuple[
    list[tuple[Result, list[str], Explanation]], list[tuple[Result, list[str], Explanation]]
]:
    """The ranking from exact results: sensor-critical scenarios (collision probability
    at least ``RANK_MIN_P``) by collision probability, then impact speed; near-duplicates of
    a family and environment collapsed, at most ``max_per_group`` per (family,
    environment); the same trajectory critical for the same reason (dominant effect) in
    several environments is one row listing them. Returns (ranking, unavoidable), each row
    (exact result, environment labels, explanation). ``explained``: explanations by
    scenario id, reused and filled (rankings of one run's searches share them)."""
    explained = {} if explained is None else explained

    def key(r: Result) -> tuple[int, float, float, float, str]:
        crit = classify(r) == "sensor-critical"
        return (
            0 if crit else 1,
            -r.metrics.get("collision_probability", 0.0),
            -r.metrics.get("impact_speed_kmh", 0.0),
            -r.score,
            r.candidate.scenario_id,
        )

    exact = [e for _, e in pairs if e.feasible]
    # listed apart, never ranked: unavoidable, and marginal (avoidable only by perfect
    # perception, by less than MIN_PERFECT_MARGIN_S)
    unavoidable = sorted((e for e in exact if classify(e) in ("unavoidable", "marginal")), key=key)
    rest = sorted(
        (
            e
            for e in exact
            if classify(e) == "sensor-critical"
            and e.metrics.get("collision_probability", 0.0) >= RANK_MIN_P
        ),
        key=key,
    )
    rows: list[tuple[Result, list[str], Explanation]] = []
    groups: Counter[tuple[str, str]] = Counter()

    def merged(
        r: Result, ex: Explanation, out: list[tuple[Result, list[str], Explanation]]
    ) -> bool:
        for row in out:
            c, prob = row[0].candidate, problems[r.candidate.family]
            if (
                c.family == r.candidate.family
                and row[2].dominant == ex.dominant
                and prob.family.distance(c.params, r.candidate.params) < min_distance
            ):
                if r.candidate.environment_label not in row[1]:
                    row[1].append(r.candidate.environment_label)
                return True
        return False

    def same_outcome(
        r: Result, ex: Explanation, out: list[tuple[Result, list[str], Explanation]]
    ) -> bool:
        """The same encounter placed elsewhere on the road: same family, effect and
        outcome (``SAME_OUTCOME``: P(collision), impact speed and t_safe within their
        tolerances): joins the first row. Two places on a constant-radius curve give the
        same encounter up to rounding (measured: P 1e-7, impact 1e-5 km/h apart)."""

        def same(a: Result, b: Result) -> bool:
            return all(
                abs(float(a.metrics.get(m, 0.0)) - float(b.metrics.get(m, 0.0))) <= tol
                for m, tol in SAME_OUTCOME.items()
            )

        for row in out:
            if (
                row[0].candidate.family == r.candidate.family
                and row[2].dominant == ex.dominant
                and same(row[0], r)
            ):
                if r.candidate.environment_label not in row[1]:
                    row[1].append(r.candidate.environment_label)
                return True
        return False

    def fill(
        src: list[Result],
        out: list[tuple[Result, list[str], Explanation]],
        limit: int,
        cap: int | None,
    ) -> None:
        for r in src:
            if len(out) >= limit:
                return
            gk = (r.candidate.family, r.candidate.environment)
            if any(row[0] is r for row in out) or (cap is not None and groups[gk] >= cap):
                continue
            prob = problems[r.candidate.family]
            if any(
                candidate_distance(prob, r.candidate, row[0].candidate) < min_distance
                for row in out
            ):
                continue
            ex = explained.get(r.candidate.scenario_id)
            if ex is None:
                ex = explained[r.candidate.scenario_id] = explain(prob, r.candidate)
            if merged(r, ex, out) or same_outcome(r, ex, out):
                continue
            out.append((r, [r.candidate.environment_label], ex))
            groups[gk] += 1

    for cap in (max_per_group, None):
        fill(rest, rows, top, cap)
    rows.sort(key=lambda row: key(row[0]))  # the cap chose them; the list is by outcome
    groups.clear()
    unav: list[tuple[Result, list[str], Explanation]] = []
    fill(unavoidable, unav, min(top, 10), None)
    return rows, unav


#: The summary states the stability of this many leading rows.
STABILITY_TOP = 10


def found_by(
    rows: list[tuple[Result, list[str], Explanation]],
    tops: list[list[tuple[Result, list[str], Explanation]]],
) -> list[int]:
    """Per ranked row: in how many of ``tops`` (each independent search's own ranking) the
    same finding is ranked: a row of the same family and dominant effect with an
    environment preset in common (the same kind of weakness, not the same parameter values
    or sun position: independent searches land at different points of one critical
    region)."""

    def presets(labels: list[str]) -> set[str]:
        return {lab.split("@")[0] for lab in labels}  # 'clear@sun62/5': the preset clear

    def same(
        a: tuple[Result, list[str], Explanation], b: tuple[Result, list[str], Explanation]
    ) -> bool:
        return (
            a[0].candidate.family == b[0].candidate.family
            and a[2].dominant == b[2].dominant
            and bool(presets(a[1]) & presets(b[1]))
        )

    return [sum(1 for t in tops if any(same(row, o) for o in t)) for row in rows]


def found_near(
    rows: list[tuple[Result, list[str], Explanation]],
    tops: list[list[tuple[Result, list[str], Explanation]]],
    problems: dict[str, SearchProblem],
    distance: float,
) -> list[int]:
    """Per ranked row: in how many of ``tops`` a row of the same family and environment
    preset lies within ``distance`` of it (``candidate_distance``: parameters and sun;
    the ranking's near-duplicate test), the stricter sense of found again."""
    return [
        sum(
            1
            for t in tops
            if any(
                candidate_distance(
                    problems[row[0].candidate.family], row[0].candidate, o[0].candidate
                )
                < distance
                for o in t
            )
        )
        for row in rows
    ]
