"""Compare two vehicles' critical scenarios (the paper's A-vs-B view) by cross-evaluation.

Every scenario ranked for either vehicle is evaluated exactly for both (same trajectories,
same environment and sun), each with its own reaction model. A scenario is *critical for X
only* when X's collision probability exceeds the other vehicle's by at least
``MARGIN_P``; the explanation then names, at X's named step (same time, so the same target
position in the ego frame), the sensors of X that miss the target and why
(``ranking.explain``: glare, weather, range, FOV, partly in view) and the sensors of the
other vehicle that see it (Pd >= 0.5) and may confirm it for braking, with their type, so
every difference is traced back to the two sensor setups.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.atomic import atomic_write_bytes, atomic_write_text
from sensorgap.config import load_environments
from sensorgap.errors import InputError
from sensorgap.filesio import write_json
from sensorgap.models import System, load_system
from sensorgap.scenarios import load_family
from sensorgap.search.evaluate import Evaluator
from sensorgap.search.problem import Candidate, SearchProblem
from sensorgap.search.ranking import classify, explain
from sensorgap.search.run import ranking_csv

#: Collision-probability difference that makes a scenario critical for one vehicle only.
MARGIN_P = 0.1
#: Per-sensor Pd from which a sensor counts as seeing the target.
SEES_PD = 0.5


@dataclass
class RunRanking:
    """A search run folder's ranking and settings."""

    folder: Path
    vehicle: str
    rows: list[dict[str, Any]]
    settings: dict[str, Any]


def read_run(folder: Path) -> RunRanking:
    """``ranking.json`` of a search run folder; ``InputError`` naming the file if absent
    or malformed."""
    path = Path(folder) / "ranking.json"
    if not path.is_file():
        raise InputError(path, "", "not a search run folder (ranking.json is missing)")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, RecursionError) as exc:
        raise InputError(path, "", f"malformed ranking file: not JSON ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(path, "", "malformed ranking file: expected a JSON object")
    rows, settings = data.get("ranking"), data.get("settings")
    if not isinstance(rows, list):
        raise InputError(path, "ranking", "malformed ranking file: expected a list of rows")
    if not isinstance(settings, dict):
        raise InputError(path, "settings", "malformed ranking file: expected an object")
    vehicle = settings.get("vehicle_ref") or settings.get("vehicle_file")
    if not isinstance(vehicle, str) or not vehicle:
        raise InputError(path, "settings.vehicle_ref", "malformed ranking file: expected "
                         "the vehicle (a preset name or a path)")
    if not settings.get("vehicle_ref"):
        vehicle = Path(vehicle).stem
    envs = settings.get("environments", [])
    if not (isinstance(envs, list) and all(isinstance(e, str) for e in envs)):
        raise InputError(path, "settings.environments", "malformed ranking file: expected "
                         "a list of environment names")
    for i, row in enumerate(rows):
        if not isinstance(row, dict):
            raise InputError(path, f"ranking[{i}]", "malformed ranking file: expected an "
                             "object")
        for key in ROW_TEXT:
            if not isinstance(row.get(key), str) or not row[key]:
                raise InputError(path, f"ranking[{i}].{key}", "malformed ranking file: "
                                 "missing or not a string")
        rank = row.get("rank")
        if not isinstance(rank, int) or isinstance(rank, bool) or rank < 1:
            raise InputError(path, f"ranking[{i}].rank", "malformed ranking file: expected "
                             f"a positive integer, got {rank!r}")
    return RunRanking(Path(folder), vehicle, rows, settings)


#: Text fields every ranking row must carry.
ROW_TEXT = ("scenario_id", "family", "environment")


def candidate_of(row: dict[str, Any], problem: SearchProblem,
                 source: Path | str = "ranking.json") -> Candidate:
    """The candidate of a ranking row (preset, world-frame sun, parameters); a missing or
    malformed value -> ``InputError`` naming ``source`` and the field."""
    env = str(row["environment"]).split("@")[0]
    field = "sun_azimuth_deg"
    try:
        sun = (None if row.get("sun_azimuth_deg") is None
               else (float(row["sun_azimuth_deg"]), float(row["sun_elevation_deg"])))
        params: dict[str, Any] = {}
        for p in problem.family.space:
            field = f"p_{p.name}"
            value = row[field]
            if p.categorical:
                if value not in p.choices:
                    raise ValueError(f"not one of {', '.join(p.choices)}")
                params[p.name] = str(value)
            else:
                if isinstance(value, bool) or not isinstance(value, int | float) \
                        or not math.isfinite(value):
                    raise ValueError("not a finite number")
                params[p.name] = float(value)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(source, f"ranking[{row.get('scenario_id')}].{field}",
                         f"missing or malformed value ({exc})") from None
    return Candidate(problem.family.name, env, sun, params)


def _sensor_type(system: System, sensor_id: str) -> str:
    for s in system.sensors:
        if s.id == sensor_id:
            return type(s.model).__name__.lower()
    return "?"


class _Side:
    """One vehicle: its problems per family (exact evaluation)."""

    def __init__(self, run: RunRanking, environments: dict[str, Any]) -> None:
        self.run = run
        self.system = load_system(run.vehicle)
        self.evaluator = Evaluator(self.system, mode="exact")
        self.environments = environments
        self.problems: dict[str, SearchProblem] = {}

    @property
    def name(self) -> str:
        return self.system.name

    def problem(self, family: str) -> SearchProblem:
        if family not in self.problems:
            self.problems[family] = SearchProblem(load_family(family), self.environments,
                                                  self.evaluator)
        return self.problems[family]


def compare_runs(run_a: Path, run_b: Path,
                 margin_p: float = MARGIN_P) -> list[dict[str, Any]]:
    """Cross-evaluate the ranked scenarios of two runs (see the module docstring)."""
    ra, rb = read_run(run_a), read_run(run_b)
    presets = load_environments()
    envs = {e: presets[e] for e in dict.fromkeys(
        [*ra.settings.get("environments", []), *rb.settings.get("environments", [])])
        if e in presets}
    sides = [_Side(ra, envs), _Side(rb, envs)]
    seen: dict[str, dict[str, Any]] = {}
    for k, side in enumerate(sides):
        for row in side.run.rows:
            sid = str(row["scenario_id"])
            entry = seen.setdefault(sid, {"row": row, "ranks": [None, None],
                                          "source": side.run.folder / "ranking.json"})
            entry["ranks"][k] = int(row["rank"])
    out = []
    for sid, entry in sorted(seen.items(), key=lambda kv: (
            min(r for r in kv[1]["ranks"] if r is not None), kv[0])):
        row = entry["row"]
        probs, speeds, classes, results = [], [], [], []
        for side in sides:
            prob = side.problem(str(row["family"]))
            cand = candidate_of(row, prob, entry["source"])
            res = prob.evaluate(cand)
            results.append((prob, cand, res))
            probs.append(float(res.metrics.get("collision_probability", 0.0))
                         if res.feasible else 0.0)
            speeds.append(float(res.metrics.get("impact_speed_kmh", 0.0))
                          if res.feasible else 0.0)
            classes.append(classify(res))
        diff = probs[0] - probs[1]
        critical = ("both" if abs(diff) < margin_p and min(probs) > 0.0
                    else "neither" if abs(diff) < margin_p
                    else sides[0].name if diff > 0 else sides[1].name)
        worse = 0 if diff >= 0 else 1
        better = 1 - worse
        prob_w, cand_w, res_w = results[worse]
        ex = explain(prob_w, cand_w) if res_w.feasible else None
        why = (f"{sides[worse].name}: {ex.reason}" if ex is not None
               else f"{sides[worse].name}: infeasible ({res_w.note})")
        sees: list[str] = []
        if critical not in ("both", "neither") and ex is not None:
            prob_b, _, _ = results[better]
            ev_b = prob_b.evaluator
            tr = ev_b.trace(prob_b.scenario(cand_w), prob_b.environment(cand_w),
                            prob_b.family.duration_s)
            k = int(np.argmin(np.abs(tr.t - ex.step_t_s)))
            env = prob_b.environment(cand_w)
            target = ev_b.target(prob_b.family.target_class)
            pd = ev_b.per_sensor_pd(env, target, tr.heading[k:k + 1], tr.x[k:k + 1],
                                    tr.y[k:k + 1],
                                    psi=None if tr.psi is None else tr.psi[k:k + 1],
                                    occluders=None if tr.occluders is None
                                    else tr.occluders[k:k + 1])[:, 0]
            confirm = set(ev_b.confirm_rows)
            sees = [f"{sn.id} ({_sensor_type(sides[better].system, sn.id)}, Pd {p:.2f}"
                    f"{'' if i in confirm else ', cannot confirm'})"
                    for i, (sn, p) in enumerate(zip(sides[better].system.sensors, pd,
                                                    strict=True)) if p >= SEES_PD]
            why += (f" | {sides[better].name} at the same moment sees it with "
                    + ("; ".join(sees) if sees else "no sensor above Pd 0.5")
                    + f" (P(collision) {probs[better]:.2g} vs {probs[worse]:.2g})")
        out.append({
            "scenario_id": sid, "family": row["family"], "environment": row["environment"],
            f"rank_{sides[0].name}": entry["ranks"][0], f"rank_{sides[1].name}": entry["ranks"][1],
            f"collision_probability_{sides[0].name}": probs[0],
            f"collision_probability_{sides[1].name}": probs[1],
            f"impact_speed_kmh_{sides[0].name}": speeds[0],
            f"impact_speed_kmh_{sides[1].name}": speeds[1],
            f"class_{sides[0].name}": classes[0], f"class_{sides[1].name}": classes[1],
            "critical_for": critical, "dominant_effect": "" if ex is None else ex.dominant,
            "other_sees": "; ".join(sees), "why": why,
        })
    return out


def write_comparison(run_a: Path, run_b: Path, out: Path) -> list[dict[str, Any]]:
    """``comparison.csv``, ``comparison.json`` and ``comparison.md`` into ``out``."""
    rows = compare_runs(run_a, run_b)
    out.mkdir(parents=True, exist_ok=True)
    cols = list(rows[0]) if rows else ["scenario_id"]
    atomic_write_bytes(out / "comparison.csv", ranking_csv(rows, cols))
    write_json(out / "comparison.json", {"columns": cols, "rows": rows,
                                         "margin_collision_probability": MARGIN_P})
    counts = Counter((r["critical_for"], r["dominant_effect"]) for r in rows)
    lines = ["# Critical scenarios: cross-evaluation of two vehicles", "",
             f"Critical for one vehicle only: collision probability higher by >= "
             f"{MARGIN_P:g}. Each scenario ranked for either vehicle is evaluated exactly "
             "for both, each vehicle with its own reaction model.", "",
             "| critical for | dominant effect | scenarios |", "|---|---|---|"]
    lines += [f"| {who} | {eff} | {n} |" for (who, eff), n in sorted(counts.items())]
    lines += ["", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        cells = []
        for c in cols:
            v = r[c]
            cells.append("" if v is None else f"{v:.2f}" if isinstance(v, float)
                         else str(v).replace("|", "/"))
        lines.append("| " + " | ".join(cells) + " |")
    atomic_write_text(out / "comparison.md", "\n".join(lines) + "\n")
    return rows
