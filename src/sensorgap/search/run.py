"""``run_search``: the search over families x environments, written to a run folder.

Run folder: ``search.sqlite`` (every evaluated candidate; resume), ``ranking.csv`` and
``ranking.json`` (the diverse top K with metrics, parameters and reasons) and
``summary.json`` (settings and counts). Deterministic: the same settings and seed give
byte-identical ranking files.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from sensorgap.atomic import atomic_write_bytes
from sensorgap.config import load_environments, load_targets
from sensorgap.config.presets import resolve_road
from sensorgap.errors import InputError
from sensorgap.filesio import format_float, write_json
from sensorgap.models import load_system
from sensorgap.scenarios import load_families
from sensorgap.search.evaluate import DetectionRule, Evaluator
from sensorgap.search.executors import ProblemSpec, check_scheduler_address, make_executor
from sensorgap.search.metrics import metric_names
from sensorgap.search.problem import Result, SearchProblem
from sensorgap.search.ranking import (
    MIN_DISTANCE,
    POOL_MIN,
    POOL_PER_RANK,
    STABILITY_TOP,
    Explanation,
    classify,
    disagreement,
    found_by,
    found_near,
    merge_pairs,
    rank_exact,
    reevaluate,
)
from sensorgap.search.runfolder import record_inputs, write_search_record
from sensorgap.search.store import Store, digest, file_digest
from sensorgap.search.strategies import get_strategy, strategy_names

MAX_BUDGET = 1_000_000
MAX_SEED = 2**63 - 1
#: Most independent searches one run's budget may be split into (``seeds``).
MAX_SEEDS = 10
#: The ranking's leading metric columns (collision terms), in this order.
HEAD_METRICS = ("collision_probability", "impact_speed_kmh", "collision_perfect", "t_safe_s",
                "detection_margin_s", "t_confirm_median_s", "t_threat_s",
                "p_never_confirmed")


def _finite_or_none(v: float) -> float | None:
    """A metric value for the output files: None (an empty cell) where it is undefined."""
    return None if not math.isfinite(v) else v


@dataclass
class SearchOutcome:
    """What a search produced."""

    ranking: list[dict[str, Any]]
    results: list[Result]
    evaluated: int
    reused: int
    summary: dict[str, Any] = field(default_factory=dict)


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return format_float(v)
    return str(v)


def ranking_csv(rows: list[dict[str, Any]], columns: list[str]) -> bytes:
    """CSV of the ranking (quoted where needed, ``\\n`` line ends, round-trip floats)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow(["" if r.get(c) is None else _fmt(r[c]) for c in columns])
    return buf.getvalue().encode("utf-8")


def _vehicle_ref(vehicle: str | Path) -> str:
    """How the run records its vehicle: a preset name as given, a file as its absolute
    path (so export, compare and report work from any working directory)."""
    text = str(vehicle)
    if text.endswith(".toml") or "/" in text or Path(text).exists():
        return str(Path(text).resolve())
    return text


def _input_digests(vehicle_file: Path, evaluator: Evaluator, envs: dict[str, Any],
                   fams: list[Any]) -> dict[str, str]:
    """Content digests of every input the stored results depend on (``--resume`` refuses
    when one changed): the vehicle file, its reaction model and friction, the
    environments, the target classes and each family's file and road."""
    out = {"vehicle": file_digest(vehicle_file),
           "reaction": digest(json.dumps([evaluator.reaction.model_dump(mode="json"),
                                          evaluator.friction], sort_keys=True)),
           "environments": digest(json.dumps({k: v.model_dump(mode="json")
                                              for k, v in envs.items()}, sort_keys=True)),
           "targets": digest(json.dumps({k: v.model_dump(mode="json")
                                         for k, v in load_targets().items()},
                                        sort_keys=True))}
    for f in fams:
        out[f"family {f.name}"] = file_digest(Path(f.source))
        out[f"road of {f.name}"] = file_digest(resolve_road(str(f.settings["road"])))
    return out


def _speed_limits(prob: SearchProblem) -> dict[str, dict[str, Any]]:
    """Per environment: the lawful ego speed bound the search used (``search.speedlimit``),
    km/h (None: not bounded), the visibility it came from, m, and the rule in words."""
    return {n: {"speed_kmh": (None if math.isinf(lim.speed_m_s)
                              else round(lim.speed_m_s * 3.6, 1)),
                "visibility_m": (None if math.isinf(lim.visibility_m) else lim.visibility_m),
                "rule": lim.rule}
            for n, lim in prob.speed_limits.items()}


def run_search(vehicle: str | Path, families: list[str], environments: list[str],
               budget: int, seed: int, top: int, out: Path, strategy: str = "de",
               mode: str = "lookup", sun_search: bool = True,
               environments_file: Path | None = None, progress: bool | None = None,
               min_distance: float = MIN_DISTANCE,
               detection: str = "cumulative", workers: int = 2,
               resume: bool = False, executor: str = "local",
               scheduler: str | None = None, seeds: int = 1) -> SearchOutcome:
    """Search, store every candidate, write the ranking; see the module docstring.
    ``workers``: threads per batch (``executor="local"``) or Dask worker processes of a
    local cluster (``"dask"`` without ``scheduler``); the result does not depend on either.
    ``seeds``: the budget runs as that many independent searches (random streams ``[seed,
    family]`` and ``[seed, family, s]`` for s = 1..), each with its share; the ranking is
    over all of them, and each ranked row says how many of the searches found it on their
    own (``found_by_seeds``; ``summary.json`` ``stability``): the confidence a rerun with
    another seed would find it too, at no extra cost.
    """
    if not 1 <= budget <= MAX_BUDGET:
        raise InputError("budget", "", f"must be within 1..{MAX_BUDGET}, got {budget}")
    if not 1 <= workers <= 64:
        raise InputError("workers", "", f"must be 1..64, got {workers}")
    if top < 1:
        raise InputError("top", "", f"must be >= 1, got {top}")
    if get_strategy(strategy) is None:
        raise InputError("strategy", "", f"unknown strategy {strategy!r}; allowed: "
                         f"{', '.join(strategy_names())}")
    if mode not in ("lookup", "exact"):
        raise InputError("pd", "", f"must be lookup or exact, got {mode!r}")
    if isinstance(seed, bool) or not 0 <= seed <= MAX_SEED:
        raise InputError("seed", "", f"must be an integer within 0..{MAX_SEED}, got {seed}")
    if isinstance(seeds, bool) or not 1 <= seeds <= MAX_SEEDS:
        raise InputError("seeds", "", f"must be an integer within 1..{MAX_SEEDS}, got {seeds}")
    if scheduler is not None:
        check_scheduler_address(scheduler)
    all_envs = load_environments(environments_file)
    if not environments:
        raise InputError("environments", "", "give at least one environment; presets: "
                         f"{', '.join(all_envs)}")
    for e in environments:
        if e not in all_envs:
            raise InputError("environments", "", f"unknown environment {e!r}; presets: "
                             f"{', '.join(all_envs)}")
    fams = load_families(families)
    if budget < len(fams) * seeds:
        raise InputError("budget", "", f"budget {budget} is smaller than the number of "
                         f"families ({len(fams)}) times seeds ({seeds}); give at least one "
                         "evaluation per family and seed")
    system = load_system(vehicle)
    envs = {e: all_envs[e] for e in dict.fromkeys(environments)}
    rule = DetectionRule.parse(detection)
    evaluator = Evaluator(system, mode=mode, rule=rule)
    problems = {f.name: SearchProblem(f, envs, evaluator, sun_search) for f in fams}
    spec = ProblemSpec(str(vehicle), tuple(families), tuple(envs),
                       None if environments_file is None else str(environments_file), mode,
                       rule.label(), sun_search)
    settings = {"vehicle": system.name, "vehicle_file": system.source.name,
                "vehicle_ref": _vehicle_ref(vehicle),
                "families": [f.name for f in fams], "environments": list(envs),
                "seed": seed, "seeds": seeds, "strategy": strategy, "pd": mode,
                "sun_search": sun_search,
                "detection": rule.label(), "reaction": evaluator.reaction.label(),
                "target_model": "bodies"}
    inputs = _input_digests(system.source, evaluator, envs, fams)
    db = out / "search.sqlite"
    new_db = not db.exists()
    new_out = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    store = Store(db, settings, inputs)
    if store.count() and not resume:
        n = store.count()
        store.close()
        raise InputError("out", "", f"{out} already holds a search ({n} candidates "
                         "stored); add --resume to continue it, or use another --out")
    shares = [budget // len(fams) + (1 if i < budget % len(fams) else 0)
              for i in range(len(fams))]
    results: list[Result] = []
    stream: list[int] = []  # which of the independent searches each result belongs to
    evaluated = reused = 0
    disable = (not sys.stderr.isatty()) if progress is None else not progress
    resuming = store.count() > 0
    try:
        runner = make_executor(executor, scheduler, workers)
    except InputError:
        store.close()
        if new_db:  # nothing was stored: leave no empty database behind
            db.unlink(missing_ok=True)
        if new_out:  # nor an empty folder this search created
            with contextlib.suppress(OSError):
                out.rmdir()
        raise
    # the run folder keeps its inputs: copies under inputs/, paths and SHA-256 in run.json
    write_search_record(out, _vehicle_ref(vehicle), settings, record_inputs(
        out, system.source, environments_file, system.config.reaction, fams))
    try:
        with tqdm(total=budget, disable=disable, desc="search", unit="cand") as bar:
            for i, (fam, share) in enumerate(zip(fams, shares, strict=True)):
                prob = problems[fam.name]
                strat_cls = get_strategy(strategy)
                assert strat_cls is not None
                idx = 0
                for s_i in range(seeds):
                    part = share // seeds + (1 if s_i < share % seeds else 0)
                    strat = strat_cls(prob.dim, prob.levels, part,
                                      np.random.default_rng([seed, i] if s_i == 0
                                                            else [seed, i, s_i]),
                                      batch=strat_cls.batch_for(part))
                    while True:
                        X = strat.ask()
                        if len(X) == 0:
                            break
                        decoded = prob.decode_batch(X)
                        cands = prob.candidates(decoded)
                        batch: list[Result | None] = [
                            store.get(fam.name, idx + j, c.scenario_id) if resuming else None
                            for j, c in enumerate(cands)]
                        todo = np.array([j for j, r in enumerate(batch) if r is None],
                                        dtype=int)
                        reused += len(batch) - todo.size
                        if todo.size:
                            sub = decoded.take(todo)
                            fresh = prob.results([cands[j] for j in todo],
                                                 runner.evaluate(spec, prob, sub))
                            for j, r in zip(todo.tolist(), fresh, strict=True):
                                batch[j] = r
                            store.put_async([(idx + j, batch[j]) for j in todo.tolist()])
                            evaluated += todo.size
                        done = [r for r in batch if r is not None]
                        strat.tell(X, np.array([r.objective for r in done]))
                        results.extend(done)
                        stream.extend([s_i] * len(done))
                        idx += len(done)
                        bar.update(len(done))
    finally:
        store.close()
        runner.close()
    exact_problems = problems if mode == "exact" else {
        f.name: SearchProblem(f, envs, Evaluator(system, mode="exact", rule=rule), sun_search)
        for f in fams}
    pool = max(POOL_MIN, POOL_PER_RANK * top)
    cache: dict[str, Result] = {}
    explained: dict[str, Explanation] = {}
    if seeds == 1:
        pairs, lve = reevaluate(results, exact_problems, pool, cache)
    else:  # each search's own best re-evaluated; the ranking over their union
        per_seed = [reevaluate([r for r, s_i in zip(results, stream, strict=True)
                                if s_i == k], exact_problems, pool, cache)[0]
                    for k in range(seeds)]
        pairs = merge_pairs(*per_seed)
        lve = disagreement(pairs)
    lookup_of = {lk.candidate.scenario_id: lk for lk, _ in pairs}
    chosen, unavoidable = rank_exact(pairs, exact_problems, top, min_distance,
                                     explained=explained)
    stability: dict[str, Any] = {"seeds": seeds}
    found: list[int | None] = [None] * len(chosen)
    if seeds > 1:
        tops = [rank_exact(ps, exact_problems, top, min_distance, explained=explained)[0]
                for ps in per_seed]
        found = list(found_by(chosen, tops))
        near = found_near(chosen, tops, exact_problems, min_distance)
        stability.update({
            "budget_per_seed": [sum(1 for s_i in stream if s_i == k) for k in range(seeds)],
            "top": STABILITY_TOP,
            "found_by": found[:STABILITY_TOP],
            "found_near_by": near[:STABILITY_TOP],
            "near_distance": min_distance,
            "rule": "a ranked row counts as found by a search when that search's own "
                    f"ranking (top {top}) holds a row of the same family and dominant "
                    "effect with an environment preset in common (any sun position)"})
    params = sorted({p.name for f in fams for p in f.space})
    metrics = metric_names()
    head = [m for m in HEAD_METRICS if m in metrics]
    columns = ["rank", "scenario_id", "class", "found_by_seeds", "family", "environment",
               "environments",
               "target", "sun_azimuth_deg", "sun_elevation_deg", *head, "dominant_effect",
               "named_step_t_s", "lookup_collision_probability", "risk",
               *[m for m in metrics if m not in head and m != "risk"],
               *[f"p_{p}" for p in params], "reason"]

    def row_of(rank: int, r: Result, env_labels: list[str], ex: Explanation,
               seeds_found: int | None = None) -> dict[str, Any]:
        c = r.candidate
        lk = lookup_of.get(c.scenario_id)
        row: dict[str, Any] = {
            "rank": rank, "scenario_id": c.scenario_id, "class": classify(r),
            "found_by_seeds": seeds_found,
            "family": c.family, "environment": c.environment_label,
            "environments": ", ".join(env_labels),
            "target": exact_problems[c.family].family.target_class,
            "sun_azimuth_deg": None if c.sun is None else c.sun[0],
            "sun_elevation_deg": None if c.sun is None else c.sun[1],
            "risk": r.risk, "dominant_effect": ex.dominant, "reason": ex.reason,
            "named_step_t_s": ex.step_t_s,
            "lookup_collision_probability": (None if lk is None or mode == "exact" else
                                             lk.metrics.get("collision_probability")),
        }
        row.update({m: _finite_or_none(r.metrics[m]) for m in metrics})
        row.update({f"p_{k}": v for k, v in c.params.items()})
        return row

    rows = [row_of(i, r, envs_, ex, f)
            for i, ((r, envs_, ex), f) in enumerate(zip(chosen, found, strict=True), start=1)]
    unav_rows = [row_of(i, r, envs_, ex)
                 for i, (r, envs_, ex) in enumerate(unavoidable, start=1)]
    atomic_write_bytes(out / "ranking.csv", ranking_csv(rows, columns))
    atomic_write_bytes(out / "unavoidable.csv", ranking_csv(unav_rows, columns))
    write_json(out / "ranking.json", {"columns": columns, "ranking": rows,
                                      "unavoidable": unav_rows, "settings": settings,
                                      "lookup_vs_exact": lve, "stability": stability})
    n_ok = sum(r.feasible for r in results)
    per_family = {}
    for f, share in zip(fams, shares, strict=True):
        rs = [r for r in results if r.candidate.family == f.name]
        per_family[f.name] = {
            "budget": share, "feasible": sum(r.feasible for r in rs),
            "threats": sum(1 for r in rs if r.feasible and math.isfinite(
                r.metrics.get("t_threat_s", math.nan))),
            "sensor_critical_by_lookup": sum(1 for r in rs if classify(r) == "sensor-critical"),
            "unavoidable_by_lookup": sum(1 for r in rs if classify(r) == "unavoidable"),
        }
    summary = {"settings": {**settings, "budget": budget, "top": top,
                            "min_distance": min_distance},
               "candidates": len(results), "feasible": n_ok, "infeasible": len(results) - n_ok,
               "best_collision_probability": max(
                   (float(r.metrics.get("collision_probability", 0.0)) for _, r in pairs
                    if classify(r) == "sensor-critical"), default=0.0),
               "best_log10_risk": max((r.score for r in results), default=-300.0),
               "lookup_vs_exact": lve,
               "stability": stability,
               "per_family": per_family,
               "speed_limits": _speed_limits(next(iter(problems.values())))}
    write_json(out / "summary.json", summary)
    return SearchOutcome(rows, results, evaluated, reused, summary)
