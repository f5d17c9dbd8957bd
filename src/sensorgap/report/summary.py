"""The report's first page: what was tested, the top weaknesses as sentences, what to test
first, and how far to trust it.

Every number comes from the run folder as the search wrote it: the ranking rows of
``ranking.json`` (exact evaluation: collision probability, impact speed, t_safe,
confirmation time, the reason with per-sensor Pd at the named step), its
``lookup_vs_exact`` block and ``summary.json`` (candidates per family, sensor-critical
counts). Only unit conversions are done here (m/s -> km/h; a world-frame sun azimuth ->
the direction from the vehicle at the named step, with the ego heading of the report's
exact trace of the same scenario).

Weaknesses: the highest-ranked scenario of each (family, dominant effect), in rank order,
at most ``MAX_WEAKNESSES``: different failure mechanisms rather than variants of the worst.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.config import EnvironmentConfig
from sensorgap.coverage.outputs import read_coverage_npz
from sensorgap.errors import InputError
from sensorgap.export.spec import ScenarioSpec
from sensorgap.filesio import loads_json
from sensorgap.models import System
from sensorgap.report.document import Block, Bullets, Link, Para, Section, Table
from sensorgap.search.evaluate import Evaluator, Trace
from sensorgap.search.possible import no_feasible_note
from sensorgap.search.problem import Candidate, SearchProblem
from sensorgap.search.ranking import (
    RANK_MIN_P,
    Explanation,
    explain,
    named_step,
    occluder_phrase,
)
from sensorgap.search.robustness import RowRobustness

#: Weaknesses (and "test these first" rows) on the summary page.
MAX_WEAKNESSES = 3
#: km/h per m/s.
KMH = 3.6
#: Visibility below which the air counts as fog (WMO No. 8: fog below 1 km), m.
FOG_VISIBILITY_M = 1000.0

_PLURAL = {"ultrasonic": "ultrasonic sensors", "lidar": "lidars"}


@dataclass
class RankedScenario:
    """One row of the ranking with what the report rebuilt for it."""

    row: dict[str, Any]
    spec: ScenarioSpec
    #: the scenario evaluated exactly (the report's figure)
    trace: Trace
    #: per sensor, why it misses the target at the named step (``search.ranking.explain``,
    #: exact evaluation; its text is the row's reason)
    explanation: Explanation
    #: the sensors that may confirm a target for braking (the vehicle's reaction model)
    confirming: tuple[str, ...]
    #: exported files relative to the run folder ({"file": .xosc, "road": .xodr}) or None
    files: dict[str, str] | None

    @property
    def step(self) -> int:
        """Index of the named step in the trace (``search.ranking.named_step``)."""
        return named_step(self.trace)


def explain_spec(spec: ScenarioSpec, evaluator: Evaluator) -> Explanation:
    """Per-sensor causes at the named step of a ranked scenario, recomputed exactly as the
    search did (``search.ranking.explain`` with an exact ``evaluator``; its text equals the
    ranking row's reason for the same vehicle, reaction model and detection rule)."""
    problem = SearchProblem(
        spec.family, {spec.environment_name: spec.environment}, evaluator, sun_search=False
    )
    return explain(
        problem, Candidate(spec.family.name, spec.environment_name, None, dict(spec.params))
    )


# --- the numbers of the ranking's reason (``search.ranking.explain``) ---------------------

# A sensor id (at most 64 characters, config.vehicle.MountConfig) starts where no id
# character precedes it: unanchored, ``[\w.-]+`` was tried from every position of a long
# word run and rescanned it each time (quadratic: 5 rows with 200,000-character reasons
# without spaces took minutes); now each run is tried once, at most 64 characters deep.
_MISSING = re.compile(
    r"(?<![\w.-])(?P<sid>[\w.-]{1,64}) \((?P<eff>occlusion|glare|weather|partly in view|"
    r"range): Pd (?P<p>[\d.]+), (?P<b>[\d.]+) (?:without the occluders|"
    r"without the sun|in clear air)(?:, sun [\d.]+ deg from its line of sight)?\)"
)


def pd_without(reason: str) -> dict[str, float]:
    """Per sensor itemised in a ranking row's reason (the first four confirming sensors in
    view with Pd < 0.5), its Pd without the cause: without the occluders, without the sun,
    or in clear air (as the search printed it, two decimals)."""
    return {m["sid"]: float(m["b"]) for m in _MISSING.finditer(reason)}


# --- words -------------------------------------------------------------------------------


def _num(v: Any) -> float | None:
    """A finite float of a JSON value, else None."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        return None
    return float(v) if math.isfinite(v) else None


def fmt_p(p: float) -> str:
    """A probability as text: two decimals, or two significant digits below 0.01."""
    return f"{p:.2f}" if p >= 0.01 or p == 0.0 else f"{p:.1e}"


def weather_words(env: EnvironmentConfig) -> str:
    """The weather of an environment in words (snow, rain, fog with visibility)."""
    parts = []
    if env.snow_mm_h > 0:
        parts.append(f"snowfall {env.snow_mm_h:g} mm/h")
    if env.rain_mm_h > 0:
        parts.append(f"rain {env.rain_mm_h:g} mm/h")
    if env.visibility_m < FOG_VISIBILITY_M:
        parts.append(f"fog with {env.visibility_m:g} m visibility")
    return ", ".join(parts) or "clear air"


def _weather_noun(env: EnvironmentConfig) -> str:
    if env.visibility_m < FOG_VISIBILITY_M:
        return "fog"
    return "snow" if env.snow_mm_h > 0 else "rain" if env.rain_mm_h > 0 else "weather"


def direction_words(azimuth_deg: float) -> str:
    """A vehicle-frame azimuth (deg, counter-clockwise from straight ahead) in words."""
    a = (azimuth_deg + 180.0) % 360.0 - 180.0
    side = "left" if a > 0 else "right"
    m = abs(a)
    if m <= 5.0:
        return "straight ahead"
    if m < 85.0:
        return f"{m:.0f}° to the {side} of straight ahead"
    if m <= 95.0:
        return f"to the {side}"
    if m < 175.0:
        return f"{180.0 - m:.0f}° to the {side} of straight behind"
    return "straight behind"


def sun_azimuth_deg(env: EnvironmentConfig, ego_heading_rad: float | None) -> float | None:
    """The visible sun's azimuth seen from the vehicle (deg, counter-clockwise from straight
    ahead, as ``Conditions.sun_directions``): a vehicle-frame sun as given, a world-frame
    (compass) azimuth turned by the ego heading (rad, world frame). None without a visible
    sun above the horizon or, for a world-frame sun, without a heading."""
    sun = env.sun
    if sun is None or not sun.visible or sun.elevation_deg <= 0.0:
        return None
    if sun.frame == "vehicle":
        return sun.azimuth_deg
    if ego_heading_rad is None:
        return None
    return 90.0 - sun.azimuth_deg - math.degrees(ego_heading_rad)


def sun_words(env: EnvironmentConfig, ego_heading_rad: float | None) -> str:
    """Where the sun is seen from the vehicle ("" when there is no visible sun)."""
    sun = env.sun
    if sun is None or not sun.visible or sun.elevation_deg <= 0.0:
        return ""
    az = sun_azimuth_deg(env, ego_heading_rad)
    where = "" if az is None else f", {direction_words(az)}"
    return f"sun {sun.elevation_deg:.0f}° above the horizon{where}"


def condition_words(env: EnvironmentConfig, ego_heading_rad: float | None) -> str:
    """Weather and sun of an environment in words."""
    sun = sun_words(env, ego_heading_rad)
    return weather_words(env) + (f", {sun}" if sun else "")


def where_words(x_m: float, y_m: float) -> str:
    """A position in the ego vehicle frame (x forward, y left, m) in words."""
    parts = []
    if abs(x_m) >= 0.5:
        parts.append(f"{abs(x_m):.0f} m {'ahead' if x_m > 0 else 'behind'}")
    if abs(y_m) >= 1.0:
        parts.append(f"{abs(y_m):.0f} m to the {'left' if y_m > 0 else 'right'}")
    return " and ".join(parts) or "beside the vehicle"


def _and(words: list[str]) -> str:
    """Words joined as "a", "a and b", "a, b and c"."""
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def _sensor_names(ids: list[str], types: dict[str, str]) -> str:
    kinds = {types.get(i, "sensor") for i in ids}
    names = _and(ids)
    if len(kinds) == 1:
        kind = kinds.pop()
        return f"the {kind if len(ids) == 1 else _PLURAL.get(kind, kind + 's')} {names}"
    named = [f"{i} ({types.get(i, 'sensor')})" for i in ids]
    return _and(named)


#: Effects of a confirming sensor in view with Pd < 0.5 (``search.ranking``).
LOW_EFFECTS = ("occlusion", "glare", "weather", "partly in view", "range")


def _low_words(
    effect: str,
    ids: list[str],
    pd: float,
    without: list[float | None],
    occluder: str,
    env: EnvironmentConfig,
    types: dict[str, str],
    sun_deg: dict[str, float] | None = None,
) -> str:
    who, one = _sensor_names(ids, types), len(ids) == 1
    known = [w for w in without if w is not None]
    cause = {
        "occlusion": "without it",
        "glare": "without the sun",
        "weather": "in clear air",
        "partly in view": "in clear air",
        "range": "even in clear air",
    }[effect]
    nums = f"Pd {pd:.2f}"
    if known and len(known) == len(without) and len(set(known)) == 1:
        nums += f"; {known[0]:.2f} {cause}"
    elif len(known) == len(without):
        said = [f"{w:.2f}" for w in known]
        nums += f"; {cause} " + _and(said)
    elif known:  # the search itemised some of them only
        nums += f"; {cause}: " + ", ".join(
            f"{i} {w:.2f}" for i, w in zip(ids, without, strict=True) if w is not None
        )
    if effect == "occlusion":
        verb = f"{'is' if one else 'are'} blocked by the {occluder}"
    elif effect == "glare":
        verb = f"{'is' if one else 'are'} blinded by the sun"
        # the sun's angle (deg) from each line of sight to the target: the angle the
        # veiling glare falls with (models/camera.py)
        angles = [a for i in ids if (a := (sun_deg or {}).get(i)) is not None]
        if angles and len(angles) == len(ids):
            said = [f"{a:.0f}°" for a in angles]
            degs = said[0] if len(set(said)) == 1 else _and(said)
            verb += f" {degs} from {'its line' if one else 'their lines'} of sight"
    elif effect == "weather":
        verb = f"{'loses' if one else 'lose'} it in the {_weather_noun(env)}"
    elif effect == "partly in view":
        verb = f"{'sees' if one else 'see'} too little of it"
    else:
        verb = f"{'is' if one else 'are'} too far from it"
    return f"{who} {verb} ({nums})"


def sensors_words(r: RankedScenario, types: dict[str, str]) -> str:
    """Which sensors miss the target at the named step and why, as one clause: every
    confirming sensor in view with Pd < 0.5 by name, with its effect and Pd (and its Pd
    without the cause where the search's reason gives it), then how many confirming
    sensors do not have it in view, and the sensors that see it but cannot confirm it."""
    ex, env = r.explanation, r.spec.environment
    pd = ex.pd or {}
    without = pd_without(str(r.row.get("reason", "")))
    occluder = occluder_phrase(r.trace.occluder_labels) or "another road user"
    groups: dict[tuple[str, float], list[str]] = {}
    n_fov = n_far = 0
    seeing, support = [], []
    for sid, effect in ex.sensors.items():
        if effect == "sees (cannot confirm)":
            support.append(sid)
        if sid not in r.confirming:
            continue
        if effect == "sees":
            seeing.append(sid)
        elif effect == "FOV":
            n_fov += 1
        elif effect == "range" and sid not in without:
            n_far += 1  # out of its range, or in view but too weak even in clear air
        elif effect in LOW_EFFECTS:
            groups.setdefault((effect, round(pd.get(sid, 0.0), 2)), []).append(sid)
    parts = [
        _low_words(e, ids, p, [without.get(i) for i in ids], occluder, env, types, ex.sun_deg)
        for (e, p), ids in groups.items()
    ]
    if seeing:
        parts.append(
            f"only {_sensor_names(seeing, types)} {'detects' if len(seeing) == 1 else 'detect'} it"
        )
    cover = []
    if n_far:
        cover.append(f"{n_far} {'is' if n_far == 1 else 'are'} out of range")
    if n_fov:
        cover.append(f"{n_fov} {'looks' if n_fov == 1 else 'look'} elsewhere")
    if cover and (parts or seeing):
        parts.append(f"of the other confirming sensors {' and '.join(cover)}")
    elif cover:
        parts.append("no confirming sensor has it in view (" + ", ".join(cover) + ")")
    if support:
        parts.append(
            f"{_sensor_names(support, types)} {'sees' if len(support) == 1 else 'see'}"
            " it but cannot confirm it for braking"
        )
    return "; ".join(parts)


def _heading(r: RankedScenario) -> float | None:
    h = r.trace.heading
    return float(h[min(r.step, len(h) - 1)]) if len(h) else None


def weakness_sentence(r: RankedScenario, types: dict[str, str]) -> str:
    """One ranked scenario in plain words (``weakness_parts`` as one text)."""
    return " ".join(weakness_parts(r, types))


def weakness_parts(r: RankedScenario, types: dict[str, str]) -> tuple[str, str]:
    """One ranked scenario in plain words: (what: road user and manoeuvre, condition,
    speeds; then where the target is at the named step, which sensors miss it and why, when
    it is confirmed and the outcome: collision probability and impact speed of the
    ranking)."""
    row, spec, tr = r.row, r.spec, r.trace
    target = spec.target.name
    desc = spec.family.description or spec.family.name
    first = f"{desc.rstrip('.')}, in {condition_words(spec.environment, _heading(r))}"
    v_ego, v_tgt = _num(row.get("p_ego_speed_m_s")), _num(row.get("p_target_speed_m_s"))
    if v_ego is not None:
        speeds = f"ego at {v_ego * KMH:.0f} km/h"
        if v_tgt is not None:
            speeds += f", {target} at {v_tgt * KMH:.0f} km/h"
        first += f" ({speeds})"
    out = [first + "."]
    k = r.step
    t_k, t_safe = float(tr.t[k]), _num(row.get("t_safe_s"))
    when = f"At {t_k:.2f} s"
    if t_safe is not None and abs(t_safe - t_k) < 1e-6:
        when += ", the last moment to confirm it in time,"
    elif t_safe is not None:
        when += f" (it must be confirmed by {t_safe:.2f} s)"
    pdc = float((tr.pd if tr.pd_confirm is None else tr.pd_confirm)[k])
    seen = (
        "no confirming sensor detects it"
        if pdc < 0.005
        else f"the confirming sensors detect it with Pd {pdc:.2f} per cycle"
    )
    clause = sensors_words(r, types)
    out.append(
        f"{when} the {target} is {where_words(float(tr.x[k]), float(tr.y[k]))} and "
        f"{seen}" + (f": {clause}." if clause else ".")
    )
    t_conf, margin = _num(row.get("t_confirm_median_s")), _num(row.get("detection_margin_s"))
    p_never = _num(row.get("p_never_confirmed"))
    if t_conf is not None:
        late = f", {-margin:.2f} s too late" if margin is not None and margin < 0 else ""
        end = f"The vehicle confirms it at {t_conf:.2f} s (median){late}:"
    elif p_never is not None:
        end = f"The vehicle never confirms it with probability {fmt_p(p_never)}:"
    else:
        end = "Outcome:"
    p = _num(row.get("collision_probability"))
    v_imp = _num(row.get("impact_speed_kmh"))
    end += (
        f" P(collision) {fmt_p(p if p is not None else 0.0)}"
        + (f", impact at {v_imp:.0f} km/h" if v_imp is not None else "")
        + f" (rank {row.get('rank')})."
    )
    out.append(end)
    others = [e.strip() for e in str(row.get("environments") or "").split(",")][1:]
    if others:
        n = Counter(e.split("@")[0] for e in others if e)
        names = [k if c == 1 else f"{k} with {c} sun positions" for k, c in n.items()]
        out.append(
            f"The same trajectory is critical for the same reason in {len(others)} "
            f"more condition{'s' if len(others) > 1 else ''} ({', '.join(names)})."
        )
    return out[0], " ".join(out[1:])


def condition_label(r: RankedScenario) -> str:
    """The scenario's condition, short (weather; the sun where it was searched)."""
    text = weather_words(r.spec.environment)
    if r.spec.sun_deg is not None:
        text += ", " + sun_words(r.spec.environment, _heading(r))
    return f"{text} ({r.spec.environment_name})"


def pick_weaknesses(ranked: list[RankedScenario], n: int = MAX_WEAKNESSES) -> list[RankedScenario]:
    """The highest-ranked scenario of each (family, dominant effect), in rank order."""
    seen: set[tuple[str, str]] = set()
    out = []
    for r in ranked:
        key = (str(r.row.get("family")), str(r.row.get("dominant_effect")))
        if key not in seen:
            seen.add(key)
            out.append(r)
        if len(out) == n:
            break
    return out


# --- coverage: where the vehicle is blind ------------------------------------------------

#: Radius of the far-field blind-area count about the centre of the body (m): the largest
#: circle inside the default coverage map (y from -50 to 50 m); smaller maps use their own.
BLIND_RADIUS_M = 50.0
#: Directions from the centre of the body, 45 deg each, counter-clockwise from straight
#: ahead (a spot beside the doors is "left", not "ahead-left" as seen from the rear axle).
SECTORS = (
    "ahead",
    "ahead-left",
    "left",
    "behind-left",
    "behind",
    "behind-right",
    "right",
    "ahead-right",
)


def blind_extents(
    path: Path, system: System, radius_m: float = BLIND_RADIUS_M
) -> tuple[float, dict[str, tuple[float, float, float]]]:
    """Per direction (``SECTORS``): (area m2, nearest and farthest distance from the body
    in m) of the cells where a coverage map (``coverage.npz``: exact fused Pd at cell
    centres) has Pd < 0.5 within ``radius_m`` of the centre of the body, outside the body;
    the radius is reduced to the largest circle inside the map. Distances are those of the
    cell centres from the body's footprint rectangle (0, 0 for a direction without such
    cells). Returns (radius, extents)."""
    pd, x, y, res = read_coverage_npz(path)
    body = system.config.vehicle
    cx = 0.5 * (body.x_rear_m + body.x_front_m)
    r = min(
        radius_m,
        cx - (float(x.min()) - res / 2),
        float(x.max()) + res / 2 - cx,
        -(float(y.min()) - res / 2),
        float(y.max()) + res / 2,
    )
    xx, yy = np.meshgrid(x, y)
    hw = 0.5 * body.width_m
    inside = (xx >= body.x_rear_m) & (xx <= body.x_front_m) & (np.abs(yy) <= hw)
    blind = (np.hypot(xx - cx, yy) <= r) & (pd < 0.5) & ~inside
    k = (np.floor((np.degrees(np.arctan2(yy, xx - cx)) + 22.5) / 45.0).astype(int)) % 8
    dx = np.maximum(np.maximum(body.x_rear_m - xx, xx - body.x_front_m), 0.0)
    dist = np.hypot(dx, np.maximum(np.abs(yy) - hw, 0.0))
    out = {}
    for i, name in enumerate(SECTORS):
        sel = blind & (k == i)
        n = int(np.count_nonzero(sel))
        out[name] = (
            (float(n) * res * res, float(dist[sel].min()), float(dist[sel].max()))
            if n
            else (0.0, 0.0, 0.0)
        )
    return r, out


def blind_areas(
    path: Path, system: System, radius_m: float = BLIND_RADIUS_M
) -> tuple[float, dict[str, float]]:
    """Area (m2) per direction (``SECTORS``) where a coverage map (``coverage.npz``: exact
    fused Pd at cell centres) has Pd < 0.5 within ``radius_m`` of the centre of the body,
    outside the body; the radius is reduced to the largest circle inside the map. Returns
    (radius, areas)."""
    r, ext = blind_extents(path, system, radius_m)
    return r, {name: e[0] for name, e in ext.items()}


#: Near-field blind spots smaller than this (m2) are counted, not described one by one.
MIN_SPOT_WORDS_M2 = 0.01


def _sector(x: float, y: float, cx: float) -> str:
    """The direction (``SECTORS``) of a point (m) seen from the body's centre at x = cx."""
    return SECTORS[int(math.floor((math.degrees(math.atan2(y, x - cx)) + 22.5) / 45.0)) % 8]


def _m(v: float) -> str:
    """A distance (m) as text: one decimal from 1 m, two below."""
    return f"{v:.1f}" if abs(v) >= 1.0 else f"{v:.2f}"


def spot_words(bounds: list[float], centroid: list[float], system: System) -> str:
    """Where a near-field blind spot lies, from its exact bounding box (xmin, ymin, xmax,
    ymax, m, vehicle frame) and centroid: its direction from the body's centre, along the
    body from the nearer bumper, across from the body's side ("behind-left: from 0.2 m
    behind to 1.0 m ahead of the rear bumper, up to 0.5 m left of the body")."""
    body = system.config.vehicle
    x0, y0, x1, y1 = (float(v) for v in bounds)
    cx = 0.5 * (body.x_rear_m + body.x_front_m)
    where = _sector(float(centroid[0]), float(centroid[1]), cx)
    if float(centroid[0]) < cx:
        ref, name, out_dir, in_dir = body.x_rear_m, "the rear bumper", "behind", "ahead of"
        far, near = ref - x0, ref - x1  # distance outwards (behind) of each end
    else:
        ref, name, out_dir, in_dir = body.x_front_m, "the front bumper", "ahead of", "behind"
        far, near = x1 - ref, x0 - ref
    if near >= 0.0:
        along = f"{_m(near)} to {_m(far)} m {out_dir} {name}"
    elif far <= 0.0:
        along = f"{_m(-far)} to {_m(-near)} m {in_dir} {name}"
    else:
        along = f"from {_m(far)} m {out_dir} to {_m(-near)} m {in_dir} {name}"
    hw = 0.5 * body.width_m
    side = "left" if float(centroid[1]) > 0.0 else "right"
    lo, hi = (y0, y1) if side == "left" else (-y1, -y0)  # distances outwards of y = 0
    if lo >= hw:
        across = f"{_m(lo - hw)} to {_m(hi - hw)} m {side} of the body"
    elif hi > hw:
        across = f"up to {_m(hi - hw)} m {side} of the body"
    else:
        across = f"within the body's width ({side} half)"
    return f"{where}: {along}, {across}"


def _swap_sides(text: str) -> str:
    """``text`` with left and right exchanged."""
    return re.sub(r"left|right", lambda m: "right" if m.group(0) == "left" else "left", text)


def mirrored_pairs(items: list[tuple[str, str]]) -> list[tuple[str, str]]:
    """(amount, "<direction>: <where>") items with mirror images merged: two items of the
    same amount whose texts differ only by left and right become one, "<amount> each",
    "<direction> and <its mirror>: <where, 'to the side of'>" (symmetric vehicles list
    every side blind spot twice)."""
    out: list[tuple[str, str]] = []
    used: set[int] = set()
    for i, (amount, words) in enumerate(items):
        if i in used:
            continue
        j = next(
            (
                k
                for k in range(i + 1, len(items))
                if k not in used
                and items[k][0] == amount
                and items[k][1] == _swap_sides(words)
                and items[k][1] != words
            ),
            None,
        )
        if j is None:
            out.append((amount, words))
            continue
        used.add(j)
        head, _, rest = words.partition(": ")
        rest = re.sub(r" (left|right) of the body", " to the side of the body", rest)
        rest = re.sub(r"\((left|right) half\)", "(each half)", rest)
        first, second = sorted((head, _swap_sides(head)), key=lambda t: "right" in t)
        out.append((f"{amount} each", f"{first} and {second}" + (f": {rest}" if rest else "")))
    return out


def _nearfield_words(nf: Path, system: System) -> str:
    """The near-field blind spots of ``nearfield.json`` in words, by direction."""
    try:
        d = loads_json(nf.read_text(encoding="utf-8"))
        exact = float(d["blind_spot_m2"]["exact"])
        radius = float(d.get("window", {}).get("radius_m", 5.0))
        holes = [
            (float(h["area_m2"]), list(h["bounds_m"]), list(h["centroid_m"]))
            for h in d["blind_spot_m2"].get("holes", [])
        ]
        for a, b, c in holes:
            # finite numbers (m, m²), not text or lists: they are placed and named by
            # direction below (hostile round 24: an internal error, outside this check)
            if len(b) != 4 or len(c) != 2:
                raise ValueError("bounds_m: 4 numbers, centroid_m: 2 numbers expected")
            if not all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in (a, *b, *c)
            ):
                raise ValueError("a hole's area_m2, bounds_m and centroid_m are finite numbers")
        unseen = d.get("unseen_any_height_m2")
        total = None if unseen is None else float(unseen["exact"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise InputError(nf, "blind_spot_m2", f"unreadable: {exc}") from None
    if total is not None and total - exact >= 0.005:
        # the paper's measure counts enclosed regions only: say what lies open to the outside
        text = (
            f"near field: {total:.2f} m² within {radius:g} m of the body seen by no sensor "
            f"at any height, {total - exact:.2f} m² of it open to the outside (no sensor "
            f"looks there) and {exact:.2f} m² enclosed blind spots"
        )
    else:
        text = (
            f"near field: {exact:.2f} m² within {radius:g} m of the body seen by no sensor "
            "at any height" + ("" if total is not None else " (enclosed blind spots)")
        )
    big = [(f"{a:.2f} m²", spot_words(b, c, system)) for a, b, c in holes if a >= MIN_SPOT_WORDS_M2]
    small = [h for h in holes if h[0] < MIN_SPOT_WORDS_M2]
    if big:
        text += " (" + "; ".join(f"{a} {w}" for a, w in mirrored_pairs(big))
        if small:
            text += (
                f"; {_count(len(small), 'sliver')} below {MIN_SPOT_WORDS_M2:g} m² "
                f"at the body's edge"
            )
        text += ")"
    return text


def _coverage_para(folder: Path, system: System) -> Para | None:
    cov = folder / "coverage"
    maps = sorted(p.parent for p in cov.glob("*/coverage.npz")) if cov.is_dir() else []
    if not maps and not (folder / "nearfield" / "nearfield.json").is_file():
        return None
    parts = []
    if maps:
        clear = [m for m in maps if m.name.endswith("_clear") or m.name == "clear"]
        m = (clear or maps)[0]
        r, ext = blind_extents(m / "coverage.npz", system)
        areas = {n: e[0] for n, e in ext.items()}
        env = m.name
        if (m / "summary.json").is_file():
            try:
                env = str(
                    loads_json((m / "summary.json").read_text(encoding="utf-8")).get(
                        "environment", env
                    )
                )
            except (OSError, ValueError, AttributeError, RecursionError):
                raise InputError(m / "summary.json", "", "unreadable JSON") from None
        where = sorted(
            ((round(e[0]), n, e[1], e[2]) for n, e in ext.items() if round(e[0]) >= 1),
            key=lambda t: -t[0],
        )
        text = (
            f"within {r:g} m of the vehicle a car (heading the same way; {env}, "
            f"coverage/{m.name}) is detected with Pd < 0.5 over "
            f"{sum(areas.values()):,.0f} m² outside the body"
        )
        if where:
            pairs = mirrored_pairs(
                [
                    (f"{a:,} m²", f"{n}: {_m(d0)} to {_m(d1)} m from the body")
                    for a, n, d0, d1 in where
                ]
            )
            text += ": " + ", ".join(
                f"{a} {w.partition(': ')[0]} ({w.partition(': ')[2]})" for a, w in pairs
            )
        elif sum(areas.values()) >= 0.5:
            text += " (less than 1 m² in each direction)"
        parts.append(text)
    nf = folder / "nearfield" / "nearfield.json"
    if nf.is_file():
        parts.append(_nearfield_words(nf, system))
    return Para("Blind spots: " + "; ".join(parts) + ".")


# --- the section ---------------------------------------------------------------------------


def _count(n: int, word: str, plural: str | None = None) -> str:
    return f"{n:,} {word if n == 1 else plural or word + 's'}"


def _vehicle_para(system: System, settings: dict[str, Any]) -> Para:
    kinds = Counter(s.type_name for s in system.sensors)
    sensors = ", ".join(_count(n, k, _PLURAL.get(k)) for k, n in kinds.items())
    body = system.config.vehicle
    text = (
        f"Vehicle: {system.name} ({system.source.name}), {len(system.sensors)} sensors "
        f"({sensors}); body {body.length_m:g} m x {body.width_m:g} m."
    )
    if settings.get("reaction"):
        text += f" Braking: {settings['reaction']}."
    return Para(text)


def _searched_para(
    settings: dict[str, Any], search: dict[str, Any] | None, n_ranked: int, n_unavoidable: int
) -> Para:
    fams = [str(f) for f in settings.get("families", [])]
    envs = [str(e) for e in settings.get("environments", [])]
    budget = (search or {}).get("settings", {}).get("budget", settings.get("budget"))
    cand = (search or {}).get("candidates")
    parts = [
        f"Searched: {_count(len(fams), 'scenario family', 'scenario families')} "
        f"({', '.join(fams)}) in {_count(len(envs), 'environment')} "
        f"({', '.join(envs)})"
    ]
    if settings.get("sun_search"):
        parts.append("with the sun searched where it is visible (2-30° high, any direction)")
    run = []
    if budget is not None:
        run.append(f"budget {int(budget):,} candidates")
    if cand is not None and cand != budget:
        run.append(f"{int(cand):,} evaluated")
    if settings.get("strategy"):
        run.append(f"strategy {settings['strategy']}")
    if settings.get("seed") is not None:
        run.append(f"seed {settings['seed']}")
    text = " ".join(parts) + ("; " + ", ".join(run) if run else "") + ". "
    if (search or {}).get("feasible") == 0 and cand:  # an empty ranking is not "safe"
        reasons = (search or {}).get("infeasible_reasons") or {}
        note = no_feasible_note(int(cand), {str(k): int(v) for k, v in reasons.items()})
        return Para(text + f"Found: {note[0].upper()}{note[1:]}.")
    text += (
        f"Found: {_count(n_ranked, 'sensor-critical scenario')} ranked (the vehicle "
        "collides where one with perfect perception and the same braking does not)"
    )
    if n_unavoidable:
        text += (
            f"; {n_unavoidable} more collide even with perfect perception or are "
            "marginal, avoidable only by it (listed "
            "apart, unavoidable.csv)"
        )
    return Para(text + ".")


def _test_first(picked: list[RankedScenario], seeds: int = 1) -> Table:
    rows: list[list[str | Link]] = []
    for r in picked:
        p = _num(r.row.get("collision_probability"))
        v = _num(r.row.get("impact_speed_kmh"))
        files: list[str | Link] = (
            [
                Link(Path(r.files["file"]).name, r.files["file"]),
                Link(Path(r.files["road"]).name, r.files["road"]),
            ]
            if r.files
            else ["not exported", ""]
        )
        rows.append(
            [
                str(r.row.get("rank")),
                str(r.row.get("scenario_id")),
                r.spec.family.name,
                r.spec.environment_name,
                "" if p is None else fmt_p(p),
                "" if v is None else f"{v:.0f}",
                *files,
            ]
        )
        if seeds > 1:
            f = r.row.get("found_by_seeds")
            rows[-1].insert(6, "" if f is None else f"{int(f)} of {seeds}")
    head = [
        "rank",
        "scenario",
        "family",
        "environment",
        "P(collision)",
        "impact [km/h]",
        "OpenSCENARIO",
        "OpenDRIVE",
    ]
    if seeds > 1:
        head.insert(6, "found by searches")
    return Table(head, rows)


def _confidence(
    settings: dict[str, Any],
    search: dict[str, Any] | None,
    lve: dict[str, Any] | None,
    ranked: list[RankedScenario],
    robust: list[RowRobustness] | None = None,
) -> list[str]:
    items = []
    per = (search or {}).get("per_family", {})
    if per:
        never = [f for f, d in per.items() if not d.get("sensor_critical_by_lookup")]
        if never:
            cands = sorted({int(per[f].get("budget", 0)) for f in never})
            threats = sorted(int(per[f].get("threats", 0)) for f in never)
            spread = (
                f"{threats[0]:,}"
                if threats[0] == threats[-1]
                else f"{threats[0]:,}-{threats[-1]:,}"
            )
            items.append(
                f"No sensor-critical scenario at all in {', '.join(never)} ("
                + (f"{cands[0]:,}" if len(cands) == 1 else f"{cands[0]:,}-{cands[-1]:,}")
                + f" candidates{' each' if len(never) > 1 else ''}, {spread} of them "
                "threats): the search found no case where the sensors fail there, which "
                "does not prove that there is none."
            )
        else:
            items.append("Every searched family produced sensor-critical scenarios.")
        fams = Counter(str(r.row.get("family")) for r in ranked)
        lower = [f for f, d in per.items() if d.get("sensor_critical_by_lookup") and f not in fams]
        if fams:
            text = "The ranked scenarios come from " + ", ".join(
                f"{f} ({n})" for f, n in fams.most_common()
            )
            if lower:
                text += (
                    f"; {_count(len(lower), 'other family', 'other families')} had "
                    "sensor-critical scenarios less likely to collide (see the "
                    "per-family table)"
                )
            items.append(text + ".")
    else:
        items.append("Per-family counts: not available (summary.json of the search is missing).")
    if lve and lve.get("reevaluated"):
        key = next((k for k in lve if k.startswith("top") and k.endswith("_overlap")), None)
        text = (
            f"Lookup vs exact: the search proposes with fast lookup maps; of "
            f"{lve['reevaluated']:,} proposals re-evaluated exactly, "
            f"{lve.get('sensor_critical_lookup', 0)} are sensor-critical by lookup, "
            f"{lve.get('sensor_critical_exact', 0)} exactly, "
            f"{lve.get('sensor_critical_both', 0)} by both; P(collision) differs by at "
            f"most {fmt_p(float(lve.get('max_abs_diff_collision_probability', 0.0)))} "
            f"(mean {fmt_p(float(lve.get('mean_abs_diff_collision_probability', 0.0)))})"
        )
        if key:
            k = key[3:-8]
            text += f"; top-{k} overlap {lve[key]} of {k}"
        items.append(
            text + ". The search seeks out what the lookup overrates, so the proposals it "
            "re-evaluates show the lookup's largest errors; every number in this report is "
            "the exact evaluation's."
        )
    else:
        items.append("Lookup vs exact evaluation: not measured in this run.")
    items.append(_stability(settings, (search or {}).get("stability")))
    if robust:
        items.append(_robustness_line(robust))
    return items


def _variant_text(v: Any) -> str:
    """'camera exposure 0.01 s' of a ``search.robustness.Variant``."""
    unit = f" {v.unit}" if v.unit else ""
    return f"{v.parameter} {v.value:g}{unit}"


def _robustness_line(robust: list[RowRobustness]) -> str:
    """The confidence line on the model's uncertain values (``search.robustness``): short,
    so that the summary prints on one page; the rows are in ``robustness_section``."""
    counts = sorted({len(r.variants) for r in robust})
    if not counts or counts[-1] == 0:
        return "Uncertain model values: none applies to this vehicle's sensors."
    spread = f"{counts[0]}" if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
    ok = sum(r.survives for r in robust)
    return (
        f"Uncertain model values ({spread} variants, each value at either end of its "
        f"range): {ok} of the top {len(robust)} stay sensor-critical under every one "
        "(section 'Robustness of the top findings')."
    )


def robustness_section(robust: list[RowRobustness] | None) -> Section:
    """The top findings under the model's uncertain values, one row each."""
    if not robust:
        return Section(
            "robustness",
            "Robustness of the top findings",
            [Para("Not part of this run (no ranked scenario).")],
        )
    return Section(
        "robustness",
        "Robustness of the top findings",
        [
            Para(
                "Each finding re-evaluated exactly with one uncertain value at a time at "
                "either end of its plausible range, the rest as the run recorded it: the "
                "presets' calibrated values (docs/models.md, 'Calibrated values') and the "
                "camera's veiling-glare estimates (docs/models.md, 'Direct sun'). It "
                "survives when it stays sensor-critical at P(collision) "
                f"{fmt_p(RANK_MIN_P)} or more under every one."
            ),
            _robustness_table(robust),
        ],
    )


def _robustness_table(robust: list[RowRobustness]) -> Table:
    """Per checked row: its P(collision), the lowest under the variants and with which."""
    rows = []
    for r in robust:
        lo = r.lowest
        rows.append(
            [
                str(r.rank),
                r.family,
                r.environment,
                fmt_p(r.collision_probability),
                "-" if lo is None else fmt_p(lo.collision_probability),
                "-" if lo is None else _variant_text(lo),
                "yes" if r.survives else f"no ({len(r.broken_by)} of {len(r.variants)})",
            ]
        )
    return Table(
        [
            "rank",
            "family",
            "environment",
            "P(collision)",
            "lowest over the ranges",
            "with",
            "survives every variant",
        ],
        rows,
        "The top findings under the model's uncertain values (search/robustness.py)",
    )


def _stability(settings: dict[str, Any], stab: dict[str, Any] | None) -> str:
    """The confidence line on seeds: measured when the budget ran as several independent
    searches (``run_search`` ``seeds``), else how to measure it."""
    seed = settings.get("seed")
    if not stab or int(stab.get("seeds", 1)) < 2 or not stab.get("found_by"):
        return (
            "Stability over seeds: not measured in this run (one search"
            + (f", seed {seed}" if seed is not None else "")
            + "); the ranking can "
            "change with the budget and the seed: rerun with --seeds 3 (the budget as "
            "three independent searches) to see how many of them find each weakness."
        )
    k = int(stab["seeds"])
    found = [int(f) for f in stab["found_by"]]
    per = [int(b) for b in stab.get("budget_per_seed", [])]
    each = (
        f" of {per[0]:,}"
        if per and min(per) == max(per)
        else f" of {min(per):,}-{max(per):,}"
        if per
        else ""
    )
    text = (
        f"Stability over seeds: the budget ran as {k} independent searches"
        f"{each} candidates each. How many of them found each of the top {len(found)} "
        "weaknesses on their own, as the same kind of weakness (the same family, cause "
        "and environment preset, at any sun position, in that search's own ranking): "
        + _found_counts(found, k)
    )
    near = [int(f) for f in stab.get("found_near_by", [])]
    if len(near) == len(found):
        text += (
            f"; at nearly the same parameters and sun (within the ranking's "
            f"near-duplicate distance {float(stab.get('near_distance', 0.15)):g}): "
            + _found_counts(near, k)
        )
    if 1 in found:
        text += "; a weakness found by one search only may be missed by a rerun with another seed"
    return text + "."


def _found_counts(found: list[int], k: int) -> str:
    """'7 by all 3, 2 by 2, 1 by one only' of per-row search counts."""
    counts = Counter(found)
    parts = [
        f"{counts[j]} by {'all ' + str(k) if j == k else j if j > 1 else 'one only'}"
        for j in range(k, 0, -1)
        if counts[j]
    ]
    if counts[0]:
        parts.append(f"{counts[0]} by none alone (only their union ranked it)")
    return ", ".join(parts)


def summary_section(
    folder: Path,
    system: System,
    settings: dict[str, Any],
    ranked: list[RankedScenario] | None,
    search: dict[str, Any] | None,
    lookup_vs_exact: dict[str, Any] | None,
    n_unavoidable: int,
    robust: list[RowRobustness] | None = None,
) -> Section:
    """The summary page (``ranked`` None: no search in this run; ``robust``: the top rows
    under the model's uncertain values, ``search.robustness``)."""
    blocks: list[Block] = [_vehicle_para(system, settings)]
    cover = _coverage_para(folder, system)
    if cover is not None:
        blocks.append(cover)
    if ranked is None:
        blocks.append(
            Para(
                "No search in this run: no weaknesses ranked (run `sensorgap run` "
                f"or `sensorgap search --out {folder.name}`)."
            )
        )
        return Section("summary", "Summary", blocks)
    blocks.append(_searched_para(settings, search, len(ranked), n_unavoidable))
    types = {s.id: s.type_name for s in system.sensors}
    picked = pick_weaknesses(ranked)
    subs = [
        Section(
            "weaknesses",
            "Top weaknesses",
            [Bullets([weakness_parts(r, types) for r in picked], ordered=True)]
            if picked
            else [Para("None found: no scenario in which the sensors make the difference.")],
        ),
    ]
    if picked:
        seeds = int(((search or {}).get("stability") or {}).get("seeds", 1))
        subs.append(Section("test-first", "Test these first", [_test_first(picked, seeds)]))
    subs.append(
        Section(
            "confidence",
            "Confidence",
            [Bullets(_confidence(settings, search, lookup_vs_exact, ranked, robust))],
        )
    )
    return Section("summary", "Summary", blocks, subs)
