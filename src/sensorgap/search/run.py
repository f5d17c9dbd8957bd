"""``run_search``: the search over families x environments, written to a run folder, in
three parts: the settings and their resolved inputs (``search.settings``), the search loop
without I/O (``search.loop``), and here the ranking of its results (``rank_results``,
``search_summary``) and the writers (``write_ranking``; the SQLite store).

Run folder: ``search.sqlite`` (every evaluated candidate; resume), ``ranking.csv`` and
``ranking.json`` (the diverse top K with metrics, parameters and reasons) and
``summary.json`` (settings and counts). Deterministic: the same settings and seed give
byte-identical ranking files.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import math
import shutil
import sqlite3
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from sensorgap.atomic import (
    atomic_write_bytes,
    created_folders,
    remove_created_folders,
    utf8,
)
from sensorgap.errors import InputError
from sensorgap.filesio import (
    format_float,
    json_bytes,
    refuse_certified_by_other,
    refuse_links,
)
from sensorgap.locks import folder_lock, writing
from sensorgap.runtime import DeferredStop
from sensorgap.search.executors import make_executor
from sensorgap.search.loop import LoopResult, search_loop
from sensorgap.search.metrics import metric_names, output_value
from sensorgap.search.possible import infeasible_reasons, no_feasible_note
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
from sensorgap.search.runfolder import INPUTS_DIR, RUN_JSON, record_inputs, write_search_record
from sensorgap.search.settings import (
    Prepared,
    SearchSettings,
    prepare,
    vehicle_ref,
)
from sensorgap.search.store import Store, check_store, record_ranked, refuse_wal

# no monitor thread (it only tunes the refresh of a slow bar): one more thread to start,
# and under a process limit (ulimit -u) tqdm warned in three lines on stderr
tqdm.monitor_interval = 0

#: The ranking's leading metric columns (collision terms), in this order.
HEAD_METRICS = (
    "collision_probability",
    "impact_speed_kmh",
    "collision_perfect",
    "t_safe_s",
    "detection_margin_s",
    "t_confirm_median_s",
    "t_threat_s",
    "p_never_confirmed",
)


#: What a search writes into its run folder (relative POSIX paths; ``inputs/``: the
#: folder): a resumed search into a folder with a manifest checks every other listed file
#: first (``filesio.refuse_if_changed``), so a file edited by hand is never certified.
SEARCH_WRITES = (
    "ranking.json",
    "ranking.csv",
    "summary.json",
    "unavoidable.csv",
    "run.json",
    "search.sqlite",
    "inputs/",
)


#: Files of a finished run or catalog: a new search (no --resume) into a folder holding
#: one but no stored candidates is refused (its export and report would stay, stale).
EARLIER_RUN_FILES = ("ranking.json", "run.json", "catalog.json")


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
    return utf8(buf.getvalue())


def _speed_limits(prob: SearchProblem) -> dict[str, dict[str, Any]]:
    """Per environment: the lawful ego speed bound the search used (``search.speedlimit``),
    km/h (None: not bounded), the visibility it came from, m, and the rule in words."""
    return {
        n: {
            "speed_kmh": (None if math.isinf(lim.speed_m_s) else round(lim.speed_m_s * 3.6, 1)),
            "visibility_m": (None if math.isinf(lim.visibility_m) else lim.visibility_m),
            "rule": lim.rule,
        }
        for n, lim in prob.speed_limits.items()
    }


@dataclass
class Ranked:
    """The ranking of a search: rows (dicts of the ranking's ``columns``), the
    unavoidable rows listed apart, the lookup-vs-exact disagreement over what was
    re-evaluated, the stability over seeds and the (lookup, exact) pairs."""

    columns: list[str]
    rows: list[dict[str, Any]]
    unavoidable: list[dict[str, Any]]
    lookup_vs_exact: dict[str, float]
    stability: dict[str, Any]
    pairs: list[tuple[Result, Result]]


def rank_results(p: Prepared, loop: LoopResult) -> Ranked:
    """Re-evaluate the best proposals exactly (each independent search's own best when
    there are several) and rank them (``ranking.rank_exact``); with several searches, say
    per row how many found it on their own (``ranking.found_by``, ``found_near``)."""
    s = p.settings
    exact_problems = p.exact_problems()
    pool = max(POOL_MIN, POOL_PER_RANK * s.top)
    cache: dict[str, Result] = {}
    explained: dict[str, Explanation] = {}
    per_seed: list[list[tuple[Result, Result]]] = []
    if s.seeds == 1:
        pairs, lve = reevaluate(loop.results, exact_problems, pool, cache)
    else:  # each search's own best re-evaluated; the ranking over their union
        per_seed = [
            reevaluate(
                [r for r, s_i in zip(loop.results, loop.stream, strict=True) if s_i == k],
                exact_problems,
                pool,
                cache,
            )[0]
            for k in range(s.seeds)
        ]
        pairs = merge_pairs(*per_seed)
        lve = disagreement(pairs)
    lookup_of = {lk.candidate.scenario_id: lk for lk, _ in pairs}
    chosen, unavoidable = rank_exact(
        pairs, exact_problems, s.top, s.min_distance, explained=explained
    )
    stability: dict[str, Any] = {"seeds": s.seeds}
    found: list[int | None] = [None] * len(chosen)
    if s.seeds > 1:
        tops = [
            rank_exact(ps, exact_problems, s.top, s.min_distance, explained=explained)[0]
            for ps in per_seed
        ]
        found = list(found_by(chosen, tops))
        near = found_near(chosen, tops, exact_problems, s.min_distance)
        stability.update(
            {
                "budget_per_seed": [
                    sum(1 for s_i in loop.stream if s_i == k) for k in range(s.seeds)
                ],
                "top": STABILITY_TOP,
                "found_by": found[:STABILITY_TOP],
                "found_near_by": near[:STABILITY_TOP],
                "near_distance": s.min_distance,
                "rule": "a ranked row counts as found by a search when that search's own "
                f"ranking (top {s.top}) holds a row of the same family and dominant "
                "effect with an environment preset in common (any sun position)",
            }
        )
    params = sorted({q.name for f in p.families for q in f.space})
    metrics = metric_names()
    head = [m for m in HEAD_METRICS if m in metrics]
    columns = [
        "rank",
        "scenario_id",
        "class",
        "found_by_seeds",
        "family",
        "environment",
        "environments",
        "target",
        "sun_azimuth_deg",
        "sun_elevation_deg",
        *head,
        "dominant_effect",
        "named_step_t_s",
        "lookup_collision_probability",
        "risk",
        *[m for m in metrics if m not in head and m != "risk"],
        *[f"p_{q}" for q in params],
        "reason",
    ]

    def row_of(
        rank: int, r: Result, env_labels: list[str], ex: Explanation, seeds_found: int | None = None
    ) -> dict[str, Any]:
        c = r.candidate
        lk = lookup_of.get(c.scenario_id)
        row: dict[str, Any] = {
            "rank": rank,
            "scenario_id": c.scenario_id,
            "class": classify(r),
            "found_by_seeds": seeds_found,
            "family": c.family,
            "environment": c.environment_label,
            "environments": ", ".join(env_labels),
            "target": exact_problems[c.family].family.target_class,
            "sun_azimuth_deg": None if c.sun is None else c.sun[0],
            "sun_elevation_deg": None if c.sun is None else c.sun[1],
            "risk": r.risk,
            "dominant_effect": ex.dominant,
            "reason": ex.reason,
            "named_step_t_s": output_value("named_step_t_s", ex.step_t_s),
            "lookup_collision_probability": (
                None if lk is None or s.mode == "exact" else lk.metrics.get("collision_probability")
            ),
        }
        row.update({m: output_value(m, r.metrics[m]) for m in metrics})
        row.update({f"p_{k}": v for k, v in c.params.items()})
        return row

    rows = [
        row_of(i, r, envs_, ex, f)
        for i, ((r, envs_, ex), f) in enumerate(zip(chosen, found, strict=True), start=1)
    ]
    unav_rows = [row_of(i, r, envs_, ex) for i, (r, envs_, ex) in enumerate(unavoidable, start=1)]
    return Ranked(columns, rows, unav_rows, lve, stability, pairs)


def search_summary(p: Prepared, loop: LoopResult, ranked: Ranked) -> dict[str, Any]:
    """``summary.json``: settings, counts per family, the best collision probability, the
    lookup-vs-exact disagreement, the stability over seeds, the lawful speed bounds, how
    many candidates were infeasible for which reason (``infeasible_reasons``) and, when
    none was feasible, a ``note`` saying so (an empty ranking of a search without one
    possible encounter read as "safe")."""
    s = p.settings
    results = loop.results
    n_ok = sum(r.feasible for r in results)
    per_family = {}
    for f, share in zip(p.families, p.shares(), strict=True):
        rs = [r for r in results if r.candidate.family == f.name]
        per_family[f.name] = {
            "budget": share,
            "feasible": sum(r.feasible for r in rs),
            "threats": sum(
                1 for r in rs if r.feasible and math.isfinite(r.metrics.get("t_threat_s", math.nan))
            ),
            "sensor_critical_by_lookup": sum(1 for r in rs if classify(r) == "sensor-critical"),
            "unavoidable_by_lookup": sum(1 for r in rs if classify(r) == "unavoidable"),
        }
    reasons = infeasible_reasons(r.note for r in results if not r.feasible)
    note = {"note": no_feasible_note(len(results), reasons)} if results and not n_ok else {}
    return {
        "settings": {**p.record, "budget": s.budget, "top": s.top, "min_distance": s.min_distance},
        "candidates": len(results),
        "feasible": n_ok,
        "infeasible": len(results) - n_ok,
        "infeasible_reasons": reasons,
        **note,
        "best_collision_probability": max(
            (
                float(r.metrics.get("collision_probability", 0.0))
                for _, r in ranked.pairs
                if classify(r) == "sensor-critical"
            ),
            default=0.0,
        ),
        "best_log10_risk": max((r.score for r in results), default=-300.0),
        "lookup_vs_exact": ranked.lookup_vs_exact,
        "stability": ranked.stability,
        "per_family": per_family,
        "speed_limits": _speed_limits(next(iter(p.problems.values()))),
    }


def ranking_files(p: Prepared, ranked: Ranked, summary: dict[str, Any]) -> dict[str, bytes]:
    """The bytes of ``ranking.csv``, ``unavoidable.csv``, ``ranking.json`` and
    ``summary.json``, by file name (``RANKING_FILES``)."""
    return {
        "ranking.csv": ranking_csv(ranked.rows, ranked.columns),
        "unavoidable.csv": ranking_csv(ranked.unavoidable, ranked.columns),
        "ranking.json": json_bytes(
            {
                "columns": ranked.columns,
                "ranking": ranked.rows,
                "unavoidable": ranked.unavoidable,
                "settings": p.record,
                "lookup_vs_exact": ranked.lookup_vs_exact,
                "stability": ranked.stability,
            }
        ),
        "summary.json": json_bytes(summary),
    }


def write_ranking(out: Path, files: dict[str, bytes]) -> None:
    """``ranking_files`` into ``out`` (each written to a temporary file and renamed)."""
    for name, data in files.items():
        atomic_write_bytes(out / name, data)


def exclusive_folder(out: Path) -> contextlib.AbstractContextManager[None]:
    """Hold the lock of the folder ``out`` (``locks.folder_lock``, the one every
    command writing a run folder takes) while a search writes it; a second command into
    the same folder at the same time -> ``InputError`` (two searches storing into one
    database and writing one ranking left a folder whose manifest did not match it)."""
    return folder_lock(out)


def _stored_count(db: Path) -> int:
    """Candidates stored in ``db``, read without writing (0 when there is no readable
    store; a damaged one is reported when it is opened)."""
    if not db.is_file() or db.stat().st_size == 0:
        return 0
    refuse_wal(db)  # opening a WAL database, even read-only, creates -wal and -shm
    try:
        con = sqlite3.connect(f"{db.resolve().as_uri()}?mode=ro", uri=True)
        try:
            row = con.execute("SELECT COUNT(*) FROM candidates").fetchone()
        finally:
            con.close()
    except sqlite3.Error:
        return 0
    return int(row[0]) if row else 0


def refuse_search_clash(p: Prepared, out: Path, resume: bool) -> None:
    """Everything a search with the resolved settings ``p`` refuses about its folder
    ``out`` before it stores anything, checked without writing: a file it writes (or its
    journal, ``inputs/`` and its sub-folders) that is a symbolic link; without ``resume``
    a folder that already holds stored candidates, or a finished run or catalog
    (``EARLIER_RUN_FILES``); a ``search.sqlite`` that is damaged, holds a search with
    other settings, or results for other input files (``store.check_store``: the checks
    ``Store`` makes when it opens); a symbolic link anywhere else in ``out``
    (``filesio.refuse_links``). ``InputError`` naming ``out`` or the file. Used by
    ``run_search`` and, before any of its stages writes, by the main job
    (``jobs.run_default``), so a job refused at its search has written nothing."""
    db = out / "search.sqlite"
    # what it writes, followed through a link, would land outside --out (SQLite opens
    # the store and its journal through one; the inputs are copied into inputs/*/)
    inputs = out / INPUTS_DIR
    written = [out / w.rstrip("/") for w in SEARCH_WRITES] + [out / f"{db.name}-journal"]
    if inputs.is_dir() and not inputs.is_symlink():
        written += sorted(inputs.iterdir())
    for path in written:
        if path.is_symlink():
            raise InputError(
                "out",
                "",
                f"{path} is a symbolic link; a search writes only inside --out (remove the "
                "link, or use another --out)",
            )
    if not out.is_dir():
        return
    n_stored = 0 if resume else _stored_count(db)
    if n_stored:  # refused before the store is opened for writing (it would change)
        raise InputError(
            "out",
            "",
            f"{out} already holds a search ({n_stored} candidates "
            "stored); add --resume to continue it, or use another --out",
        )
    earlier = next((n for n in EARLIER_RUN_FILES if (out / n).exists()), None)
    if not resume and earlier is not None:  # its export and report would stay, stale
        raise InputError(
            "out",
            "",
            f"{out} holds an earlier run or catalog ({earlier}) without a stored "
            "search; a new search would leave its scenarios and report beside the new "
            "ranking: use another --out",
        )
    # another command's certified output (a coverage folder, a catalog exported
    # elsewhere: its manifest lists no search.sqlite) is not a search's to add to
    refuse_certified_by_other(out, "search", lambda rel: rel == db.name, db.name)
    check_store(db, p.record, p.inputs)
    refuse_links(out, "out", "search")  # a link elsewhere in --out: verify rejects it


def _count_or_none(store: Store) -> int | None:
    """How many results ``store`` holds, None when that cannot be read (kept, then)."""
    try:
        return store.count()
    except Exception:  # noqa: BLE001 - a failing store: its folder is kept as it is
        return None


def _remove_fresh_search(db: Path | None, fresh: list[Path], created: list[Path]) -> None:
    """Remove what a new search that stored nothing wrote: its database (and journal;
    None: the database was there before), ``fresh`` (``run.json`` and ``inputs/`` where
    they did not exist before) and the folders it created (``created``, when empty
    then)."""
    if db is not None:
        for leftover in (db, db.with_name(db.name + "-journal")):
            leftover.unlink(missing_ok=True)
    for path in fresh:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
    remove_created_folders(created)


def run_search(
    vehicle: str | Path,
    families: list[str],
    environments: list[str],
    budget: int,
    seed: int,
    top: int,
    out: Path,
    strategy: str = "de",
    mode: str = "lookup",
    sun_search: bool = True,
    environments_file: Path | None = None,
    progress: bool | None = None,
    min_distance: float = MIN_DISTANCE,
    detection: str = "cumulative",
    workers: int = 2,
    resume: bool = False,
    executor: str = "local",
    scheduler: str | None = None,
    seeds: int = 1,
    lock: bool = True,
    stop: DeferredStop | None = None,
) -> SearchOutcome:
    """Search, store every candidate, write the ranking; see the module docstring and
    ``SearchSettings`` for the arguments. ``workers``: threads per batch
    (``executor="local"``) or Dask worker processes of a local cluster (``"dask"`` without
    ``scheduler``); the result does not depend on either. ``seeds``: the budget runs as
    that many independent searches, each with its share; the ranking is over all of them,
    and each ranked row says how many of the searches found it on their own
    (``found_by_seeds``; ``summary.json`` ``stability``): the confidence a rerun with
    another seed would find it too, at no extra cost. ``lock=False``: the caller holds
    ``exclusive_folder(out)`` already (the main job, for all its stages). ``stop``: stop
    signals are held from the recording of the ranked results on, until the caller's
    block ends (``runtime.DeferredStop``: the CLI writes the manifest in it).
    """
    p = prepare(
        SearchSettings(
            vehicle,
            tuple(families),
            tuple(environments),
            budget,
            seed,
            top,
            strategy,
            mode,
            sun_search,
            environments_file,
            min_distance,
            detection,
            workers,
            executor,
            scheduler,
            seeds,
        )
    )
    db = out / "search.sqlite"
    new_db = not db.exists()
    created = created_folders(out)  # removed again if nothing can be stored
    out.mkdir(parents=True, exist_ok=True)
    locked = exclusive_folder(out) if lock else contextlib.nullcontext()
    with locked, contextlib.ExitStack() as marks:
        refuse_search_clash(p, out, resume)
        try:  # refused when a command is writing a folder above or below (locks.writing)
            marks.enter_context(writing(out, certifies=True))
        except InputError:
            _remove_fresh_search(None, [], created)
            raise
        try:
            store = Store(db, p.record, p.inputs)
        except InputError:
            # not opened (a full disk: "disk I/O error"): nothing was stored, so leave no
            # database and no folder this search created
            _remove_fresh_search(db if new_db else None, [], created)
            raise
        try:  # a damaged store fails here too: closed then (no connection left open)
            n = store.count()
        except BaseException:
            store.close()
            raise
        if n and not resume:
            store.close()
            raise InputError(
                "out",
                "",
                f"{out} already holds a search ({n} candidates "
                "stored); add --resume to continue it, or use another --out",
            )
        resuming = n > 0
        # what this search adds before it stores anything (removed again if it fails then)
        fresh = [out / n for n in (RUN_JSON, INPUTS_DIR) if not (out / n).exists()]
        try:
            runner = make_executor(executor, scheduler, workers)
        except BaseException:  # any failure (a stop signal, memory) before anything stored
            store.close()
            # nothing was stored: no empty database behind, nor a folder this search created
            _remove_fresh_search(db if new_db else None, [], created)
            raise
        stored: int | None = None
        closed = False
        try:
            # the run folder keeps its inputs: copies under inputs/, paths and SHA-256 in
            # run.json
            write_search_record(
                out,
                vehicle_ref(vehicle),
                p.record,
                record_inputs(
                    out, p.system.source, environments_file, p.system.config.reaction, p.families
                ),
            )
            disable = (not sys.stderr.isatty()) if progress is None else not progress
            try:
                with tqdm(total=budget, disable=disable, desc="search", unit="cand") as bar:
                    loop = search_loop(
                        p, runner, store.get if resuming else None, store.put_async, bar.update
                    )
            finally:
                stored = _count_or_none(store)
                closed = True
                store.close()
                runner.close()
        except BaseException:
            # a new search that failed before storing anything (a full disk at run.json,
            # out of memory, a thread limit, Ctrl-C): no folder, store or inputs of it stay
            # (hostile round fourteen: inputs/, run.json and an empty store stayed, and the
            # next search there was told to --resume); with results stored the folder stays,
            # for --resume
            if not closed:
                stored = _count_or_none(store)
                with contextlib.suppress(Exception):
                    store.close()
                with contextlib.suppress(Exception):
                    runner.close()
            if new_db and stored == 0:
                _remove_fresh_search(db, fresh, created)
            raise
        ranked = rank_results(p, loop)
        if stop is not None:  # from here the ranking files, their record and the
            stop.begin()  # caller's manifest are written together
        # the exact results of the ranked rows, so every reader can check ranking.json's
        # numbers against the store, and the SHA-256 of the ranking files, so none can be
        # edited (rows removed or re-ranked: hostile round eighteen, F5) without the
        # store saying so (runfolder.RunFolder.check_store)
        summary = search_summary(p, loop, ranked)
        files = ranking_files(p, ranked, summary)
        shown = {row["scenario_id"] for row in (*ranked.rows, *ranked.unavoidable)}
        record_ranked(
            db,
            {
                e.candidate.scenario_id: e.metrics
                for _, e in ranked.pairs
                if e.candidate.scenario_id in shown
            },
            {name: hashlib.sha256(data).hexdigest() for name, data in files.items()},
        )
        write_ranking(out, files)
        return SearchOutcome(ranked.rows, loop.results, loop.evaluated, loop.reused, summary)
