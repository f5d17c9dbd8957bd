"""Anchor cases: public test points of a family, evaluated exactly for one vehicle (issue
#17). They are not searched: they place the vehicle on a scale an assessor knows.

Euro NCAP's obstructed near-side pedestrian crossing (AEB VRU test protocol; the child
variant "CPNCO"): the vehicle under test drives straight at 10, 20, ..., 60 km/h; a
pedestrian walks out at 5 km/h from behind vehicles parked at the kerb on the right and
would be hit at the middle of the front bumper (the "50 %" impact point) without braking.
In ``pedestrian_behind_parked_cars`` (an adult, 1.8 m; the family has no child body):

* ``ego_speed_m_s`` = the test speed / 3.6;
* ``target_speed_m_s`` = 5 / 3.6 m/s;
* ``conflict_offset_s`` = -x_front / v: the pedestrian reaches the lane centre when the
  ego's front bumper reaches the crossing line (the family times the rear axle);
* ``cross_ahead_m`` = x_front + v * 4.5 s, at least the family's 15 m: the impact would
  come 4.5 s after the start (estimate: beyond the search's 4 s minimum start TTC and
  long enough for a whole stop from 60 km/h, so the start is not the deciding moment);
* ``parked_gap_m`` = 1.0 m (estimate: a gap a pedestrian squeezes through), ``ego_s0_m`` =
  90 m (the family's road), ``side`` = right; the ``clear`` preset (its sun high behind
  the vehicle: no glare).

Each row is an exact evaluation (``SearchProblem.evaluate``, the vehicle's reaction model)
and carries the ``sensorgap evaluate`` command that reproduces it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sensorgap.atomic import atomic_write_bytes, utf8
from sensorgap.config import EnvironmentConfig, load_environments
from sensorgap.errors import shell_quote
from sensorgap.filesio import format_float, write_json
from sensorgap.models import System
from sensorgap.scenarios import load_families
from sensorgap.scenarios.family import ParamValue
from sensorgap.search.evaluate import Evaluator
from sensorgap.search.problem import Candidate, SearchProblem
from sensorgap.search.ranking import classify, explain

#: The family the Euro NCAP anchors belong to.
NCAP_FAMILY = "pedestrian_behind_parked_cars"
#: The environment preset the anchor cases are evaluated in (Euro NCAP tests in daylight).
NCAP_ENVIRONMENT = "clear"
#: Vehicle-under-test speeds of the obstructed near-side crossing, km/h (Euro NCAP AEB VRU
#: test protocol: 10-60 km/h in 10 km/h steps).
NCAP_SPEEDS_KMH = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)
#: Pedestrian speed of that test, km/h (Euro NCAP AEB VRU test protocol: 5 km/h).
NCAP_PEDESTRIAN_KMH = 5.0
#: Time from the start to the impact at the lane centre, s (estimate, module docstring).
LEAD_S = 4.5
#: Gap between the two parked cars, m (estimate, module docstring).
PARKED_GAP_M = 1.0
#: The metrics of each anchor (columns of anchors.csv; None where infeasible).
METRIC_COLUMNS = (
    "collision_probability",
    "impact_speed_kmh",
    "collision_perfect",
    "t_safe_s",
    "t_confirm_median_s",
    "detection_margin_s",
)
#: Columns of anchors.csv.
COLUMNS = ("case", "vut_kmh", "pedestrian_kmh", "class", *METRIC_COLUMNS, "dominant_effect")


@dataclass(frozen=True)
class AnchorCase:
    """One anchor: a family, an environment preset and every parameter."""

    label: str
    family: str
    environment: str
    params: dict[str, ParamValue]


def ncap_obstructed_cases(x_front_m: float) -> list[AnchorCase]:
    """The Euro NCAP obstructed near-side crossing at each test speed for a vehicle whose
    front bumper is ``x_front_m`` (m) ahead of its rear axle (module docstring)."""
    out = []
    for kmh in NCAP_SPEEDS_KMH:
        v = kmh / 3.6
        ahead = max(x_front_m + v * LEAD_S, 15.0)
        out.append(
            AnchorCase(
                f"Euro NCAP obstructed crossing {kmh:g} km/h",
                NCAP_FAMILY,
                NCAP_ENVIRONMENT,
                {
                    "ego_s0_m": 90.0,
                    "ego_speed_m_s": v,
                    "cross_ahead_m": ahead,
                    "target_speed_m_s": NCAP_PEDESTRIAN_KMH / 3.6,
                    "conflict_offset_s": -x_front_m / v,
                    "parked_gap_m": PARKED_GAP_M,
                    "side": "right",
                },
            )
        )
    return out


def _finite(v: float) -> float | None:
    return v if math.isfinite(v) else None


def evaluate_anchors(
    system: System,
    cases: list[AnchorCase],
    environments: dict[str, EnvironmentConfig] | None = None,
    vehicle_ref: str | None = None,
) -> list[dict[str, Any]]:
    """Evaluate every case exactly for ``system`` (its reaction model) in its environment
    preset (``environments``: the shipped ones by default); one row per case with the
    ranking's outcome metrics (m, s, km/h), the class, the dominant effect and the
    ``sensorgap evaluate`` command (``vehicle_ref``: how the command names the vehicle,
    default its name)."""
    envs = environments or load_environments()
    ev = Evaluator(system, mode="exact")
    rows: list[dict[str, Any]] = []
    problems: dict[tuple[str, str], SearchProblem] = {}
    for case in cases:
        key = (case.family, case.environment)
        if key not in problems:
            problems[key] = SearchProblem(
                load_families([case.family])[0], {case.environment: envs[case.environment]}, ev
            )
        prob = problems[key]
        cand = Candidate(case.family, case.environment, None, dict(case.params))
        res = prob.evaluate(cand)
        m = res.metrics
        row: dict[str, Any] = {
            "case": case.label,
            "vut_kmh": 3.6 * float(case.params["ego_speed_m_s"]),
            "pedestrian_kmh": 3.6 * float(case.params["target_speed_m_s"]),
            "class": classify(res),
            "feasible": res.feasible,
            "note": res.note,
            "family": case.family,
            "environment": case.environment,
            "params": dict(case.params),
        }
        for name in METRIC_COLUMNS:
            row[name] = _finite(float(m.get(name, math.nan))) if res.feasible else None
        row["dominant_effect"] = explain(prob, cand).dominant if res.feasible else ""
        params = " ".join(
            f"--param {k}={v!r}" if isinstance(v, float) else f"--param {k}={v}"
            for k, v in case.params.items()
        )
        row["command"] = (
            f"sensorgap evaluate --vehicle {shell_quote(vehicle_ref or system.name)} "
            f"--family {case.family} --environment {case.environment} "
            f"{params} --out OUT"
        )
        rows.append(row)
    return rows


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return format_float(v)
    return str(v)


def write_anchors(rows: list[dict[str, Any]], out: Path) -> None:
    """``anchors.csv`` (``COLUMNS``; empty cells for undefined values) and ``anchors.json``
    (every field, with the reproducing command) into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    lines = [",".join(COLUMNS)]
    lines += [",".join(_cell(r[c]) for c in COLUMNS) for r in rows]
    atomic_write_bytes(out / "anchors.csv", utf8("\n".join(lines) + "\n"))
    write_json(out / "anchors.json", {"anchors": rows})
