"""Compare two vehicles' critical scenarios (the paper's A-vs-B view) by cross-evaluation.

Every scenario ranked for either vehicle is evaluated exactly for both (same trajectories,
same environment and sun), each with its own reaction model. A scenario is *critical for X
only* when X's collision probability is at least ``RANK_MIN_P`` (what a ranking keeps) and
exceeds the other vehicle's by at least ``MARGIN_P``, or the other's is below
``RANK_MIN_P`` (``critical_for``); the explanation then names, at X's named step (same
time, so the same target position in the ego frame), the sensors of X that miss the target and why
(``ranking.explain``: glare, weather, range, FOV, partly in view) and the sensors of the
other vehicle that see it (Pd >= 0.5) and may confirm it for braking, with their type, so
every difference is traced back to the two sensor setups.

The two sides are named by their vehicles' names; two vehicles of the same name (two
versions of one vehicle file, two searches of one preset) by the name with the side's tag
and run folder, ``System B (A: run1)`` / ``System B (B: run2)`` (``side_labels``), so no
column, ``critical_for`` value or explanation of one side can be taken for the other's.
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.atomic import atomic_write_bytes, atomic_write_text
from sensorgap.errors import InputError
from sensorgap.filesio import write_json
from sensorgap.markdown import md_cell, md_text
from sensorgap.models import System
from sensorgap.search.problem import Candidate, SearchProblem
from sensorgap.search.ranking import RANK_MIN_P, classify, explain
from sensorgap.search.run import ranking_csv
from sensorgap.search.runfolder import ROW_TEXT, RunFolder, read_json_file, read_run

__all__ = [
    "ROW_TEXT",
    "RunRanking",
    "candidate_of",
    "check_rankings",
    "compare_runs",
    "read_run",
    "side_labels",
    "write_comparison",
]

#: Collision-probability difference that makes a scenario critical for one vehicle only.
MARGIN_P = 0.1
#: Per-sensor Pd from which a sensor counts as seeing the target.
SEES_PD = 0.5


#: A search run folder as compare reads it (``search.runfolder``).
RunRanking = RunFolder
#: Longest run folder name a side's label quotes, characters.
MAX_LABEL_FOLDER_CHARS = 40


def _folder_part(folder: Path) -> str:
    """A run folder's name for a label: its own name (of the resolved path, so ``.`` has
    one), characters outside a vehicle name's set (``config.common.NAME_CHARS``) and ``|``
    (a Markdown cell) replaced by ``_``, at most ``MAX_LABEL_FOLDER_CHARS``."""
    name = Path(folder).resolve().name or "run"
    ok = "".join(
        c if (" " <= c <= "~" or "\u00c0" <= c <= "\u017f") and c != "|" else "_" for c in name
    )
    return ok[:MAX_LABEL_FOLDER_CHARS].strip() or "run"


def side_labels(name_a: str, name_b: str, folder_a: Path, folder_b: Path) -> tuple[str, str]:
    """How the two sides of a comparison are named in its columns, ``critical_for`` and
    text: their vehicles' names, or, when the names are equal (two versions of one vehicle
    file, two searches of one preset) or one is ``both`` or ``neither`` (the other values
    of ``critical_for``), the name with the side's tag and run folder:
    ``System B (A: run1)`` and ``System B (B: run2)``."""
    if name_a != name_b and not {name_a, name_b} & {"both", "neither"}:
        return name_a, name_b
    return (
        f"{name_a} (A: {_folder_part(folder_a)})",
        f"{name_b} (B: {_folder_part(folder_b)})",
    )


def candidate_of(
    row: dict[str, Any], problem: SearchProblem, source: Path | str = "ranking.json"
) -> Candidate:
    """The candidate of a ranking row (preset, world-frame sun, parameters); a missing or
    malformed value -> ``InputError`` naming ``source`` and the field."""
    env = str(row["environment"]).split("@")[0]
    if env not in problem.environments:
        raise InputError(
            source,
            f"ranking[{row.get('scenario_id')}].environment",
            f"unknown environment {env[:64]!r}; the run's environments: "
            f"{', '.join(problem.environments)}",
        )
    field = "sun_azimuth_deg"
    try:
        sun = (
            None
            if row.get("sun_azimuth_deg") is None
            else (float(row["sun_azimuth_deg"]), float(row["sun_elevation_deg"]))
        )
        params: dict[str, Any] = {}
        for p in problem.family.space:
            field = f"p_{p.name}"
            params[p.name] = p.from_json(row[field])
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(
            source,
            f"ranking[{row.get('scenario_id')}].{field}",
            f"missing or malformed value ({exc})",
        ) from None
    return Candidate(problem.family.name, env, sun, params)


def _sensor_type(system: System, sensor_id: str) -> str:
    for s in system.sensors:
        if s.id == sensor_id:
            return type(s.model).__name__.lower()
    return "?"


class _Side:
    """One vehicle (its run's recorded vehicle, reaction model, friction and targets): its
    problems per (run that ranked the scenario, family), exact evaluation."""

    def __init__(self, run: RunFolder) -> None:
        self.run = run
        self.system = run.system()
        self.evaluator = run.evaluator("exact")
        self.problems: dict[tuple[Path, str], SearchProblem] = {}
        #: the side's label in columns and text (``side_labels``; set by ``compare_runs``)
        self.name = self.system.name

    def problem(self, source: RunFolder, family: str) -> SearchProblem:
        """The problem of ``family`` as ``source`` (the run that ranked the scenario)
        recorded it, with its environments, evaluated for this side's vehicle."""
        key = (source.folder, family)
        if key not in self.problems:
            self.problems[key] = SearchProblem(
                source.family(family), searched_environments(source), self.evaluator
            )
        return self.problems[key]


def searched_environments(run: RunFolder) -> dict[str, Any]:
    """The environments a run searched (as it recorded them; all of its file when the
    settings do not list them)."""
    envs = run.environments()
    names = [e for e in run.settings.get("environments", []) if e in envs]
    return {e: envs[e] for e in names} if names else dict(envs)


def _seeing(
    system: System,
    ev: Any,
    env: Any,
    target: Any,
    tr: Any,
    t_s: float,
    speed: Any,
) -> list[str]:
    """A vehicle's sensors with Pd >= ``SEES_PD`` (exact, with the trace's occluders) at the
    step of trace ``tr`` nearest ``t_s`` s: ``id (type, Pd x[, cannot confirm])``; which
    sensors confirm there follows the target's ground speed ``speed`` (m/s per step) as
    ``Evaluator.confirming`` does (a reaction model's moving-only sensors)."""
    k = int(np.argmin(np.abs(tr.t - t_s)))
    confirm = set(ev.confirming(float(speed[k])))
    pd = ev.per_sensor_pd(
        env,
        target,
        tr.heading[k : k + 1],
        tr.x[k : k + 1],
        tr.y[k : k + 1],
        psi=None if tr.psi is None else tr.psi[k : k + 1],
        occluders=None if tr.occluders is None else tr.occluders[k : k + 1],
    )[:, 0]
    return [
        f"{sn.id} ({_sensor_type(system, sn.id)}, Pd {p:.2f}"
        f"{'' if i in confirm else ', cannot confirm'})"
        for i, (sn, p) in enumerate(zip(system.sensors, pd, strict=True))
        if p >= SEES_PD
    ]


def check_rankings(*runs: Path) -> None:
    """Read every ranked row of each run as the comparison will (``candidate_of``), so that
    a malformed ranking is refused before any map is computed or file written."""
    for path in runs:
        run = read_run(path)
        side = _Side(run)
        for row in run.rows:
            candidate_of(row, side.problem(run, str(row["family"])), run.folder / "ranking.json")


def critical_for(p_a: float, p_b: float, name_a: str, name_b: str, margin_p: float) -> str:
    """Who a scenario is critical for from the two collision probabilities: a side counts
    from ``RANK_MIN_P`` (what a ranking keeps; below it a collision is as good as never);
    when both count, one only if its probability is higher by ``margin_p`` or more, else
    ``both``; ``neither`` when none counts."""
    a, b = p_a >= RANK_MIN_P, p_b >= RANK_MIN_P
    if a and b:
        if abs(p_a - p_b) < margin_p:
            return "both"
        return name_a if p_a > p_b else name_b
    return name_a if a else name_b if b else "neither"


def compare_runs(run_a: Path, run_b: Path, margin_p: float = MARGIN_P) -> list[dict[str, Any]]:
    """Cross-evaluate the ranked scenarios of two runs (see the module docstring)."""
    ra, rb = read_run(run_a), read_run(run_b)
    sides = [_Side(ra), _Side(rb)]
    sides[0].name, sides[1].name = side_labels(sides[0].name, sides[1].name, ra.folder, rb.folder)
    seen: dict[str, dict[str, Any]] = {}
    for k, side in enumerate(sides):
        for row in side.run.rows:
            sid = str(row["scenario_id"])
            entry = seen.setdefault(
                sid,
                {
                    "row": row,
                    "ranks": [None, None],
                    "run": side.run,
                    "source": side.run.folder / "ranking.json",
                },
            )
            entry["ranks"][k] = int(row["rank"])
    out = []
    for sid, entry in sorted(
        seen.items(), key=lambda kv: (min(r for r in kv[1]["ranks"] if r is not None), kv[0])
    ):
        row = entry["row"]
        probs, speeds, classes, results = [], [], [], []
        for side in sides:
            prob = side.problem(entry["run"], str(row["family"]))
            cand = candidate_of(row, prob, entry["source"])
            res = prob.evaluate(cand)
            results.append((prob, cand, res))
            probs.append(
                float(res.metrics.get("collision_probability", 0.0)) if res.feasible else 0.0
            )
            speeds.append(float(res.metrics.get("impact_speed_kmh", 0.0)) if res.feasible else 0.0)
            classes.append(classify(res))
        diff = probs[0] - probs[1]
        critical = critical_for(probs[0], probs[1], sides[0].name, sides[1].name, margin_p)
        worse = 0 if diff >= 0 else 1
        better = 1 - worse
        prob_w, cand_w, res_w = results[worse]
        ex = explain(prob_w, cand_w) if res_w.feasible else None
        why = (
            f"{sides[worse].name}: {ex.reason}"
            if ex is not None
            else f"{sides[worse].name}: infeasible ({res_w.note})"
        )
        sees: list[str] = []
        if critical not in ("both", "neither") and ex is not None:
            prob_b, _, _ = results[better]
            ev_b = prob_b.evaluator
            tr = ev_b.trace(
                prob_b.scenario(cand_w), prob_b.environment(cand_w), prob_b.family.duration_s
            )
            env = prob_b.environment(cand_w)
            target = ev_b.target(prob_b.family.target_class)
            speed = prob_b.scenario(cand_w).target.speed  # m/s per step
            sees = _seeing(sides[better].system, ev_b, env, target, tr, ex.step_t_s, speed)
            why += (
                f" | {sides[better].name} at the same moment sees it with "
                + ("; ".join(sees) if sees else "no sensor above Pd 0.5")
                + f" (P(collision) {probs[better]:.2g} vs {probs[worse]:.2g})"
            )
            if not sees:  # it confirms the target at another step: which, and with what
                res_b = results[better][2]
                t_med = float(res_b.metrics.get("t_confirm_median_s", math.nan))
                if math.isfinite(t_med):
                    later = _seeing(sides[better].system, ev_b, env, target, tr, t_med, speed)
                    why += f"; it confirms it at {t_med:.2f} s (median) with " + (
                        "; ".join(later) if later else "no single sensor above Pd 0.5"
                    )
                else:
                    why += "; it does not confirm it with probability 1/2 either"
        out.append(
            {
                "scenario_id": sid,
                "family": row["family"],
                "environment": row["environment"],
                f"rank_{sides[0].name}": entry["ranks"][0],
                f"rank_{sides[1].name}": entry["ranks"][1],
                f"collision_probability_{sides[0].name}": probs[0],
                f"collision_probability_{sides[1].name}": probs[1],
                f"impact_speed_kmh_{sides[0].name}": speeds[0],
                f"impact_speed_kmh_{sides[1].name}": speeds[1],
                f"class_{sides[0].name}": classes[0],
                f"class_{sides[1].name}": classes[1],
                "critical_for": critical,
                "dominant_effect": "" if ex is None else ex.dominant,
                "other_sees": "; ".join(sees),
                "why": why,
            }
        )
    return out


def run_notes(run_a: Path, run_b: Path) -> list[str]:
    """The notes of the two runs' searches (``summary.json`` ``note``: e.g. that no
    candidate was feasible, so nothing could be ranked and nothing is said about the
    sensors), each prefixed with its run folder's name; none when a run has none or no
    readable summary (hostile round fifteen: a comparison of two such runs read as "no
    gap in either")."""
    out = []
    for run in (Path(run_a), Path(run_b)):
        try:
            data = read_json_file(run / "summary.json")
        except (InputError, OSError):
            continue
        note = data.get("note") if isinstance(data, dict) else None
        if isinstance(note, str) and note.strip():
            out.append(f"{run.name}: {' '.join(note.split())}")
    return out


def write_comparison(run_a: Path, run_b: Path, out: Path) -> list[dict[str, Any]]:
    """``comparison.csv``, ``comparison.json`` and ``comparison.md`` into ``out``."""
    rows = compare_runs(run_a, run_b)
    notes = run_notes(run_a, run_b)
    out.mkdir(parents=True, exist_ok=True)
    cols = list(rows[0]) if rows else ["scenario_id"]
    atomic_write_bytes(out / "comparison.csv", ranking_csv(rows, cols))
    write_json(
        out / "comparison.json",
        {
            "columns": cols,
            "rows": rows,
            "margin_collision_probability": MARGIN_P,
            "run_notes": notes,
        },
    )
    counts = Counter((r["critical_for"], r["dominant_effect"]) for r in rows)
    lines = [
        "# Critical scenarios: cross-evaluation of two vehicles",
        "",
        f"Critical for one vehicle only: its collision probability is at least "
        f"{RANK_MIN_P:g} (what a ranking keeps) and higher by >= {MARGIN_P:g}, or the "
        f"other's is below {RANK_MIN_P:g}. Each scenario ranked for either vehicle is "
        "evaluated exactly for both, each vehicle with its own reaction model.",
        "",
        *[md_text(f"Note of run {n}") for n in notes],
        *([""] if notes else []),
        "| critical for | dominant effect | scenarios |",
        "|---|---|---|",
    ]
    lines += [
        f"| {md_cell(str(who))} | {md_cell(str(eff))} | {n} |"
        for (who, eff), n in sorted(counts.items())
    ]
    lines += ["", "| " + " | ".join(md_cell(c) for c in cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        cells = []
        for c in cols:
            v = r[c]
            cells.append(
                "" if v is None else f"{v:.2f}" if isinstance(v, float) else md_cell(str(v))
            )
        lines.append("| " + " | ".join(cells) + " |")
    atomic_write_text(out / "comparison.md", "\n".join(lines) + "\n")
    return rows
