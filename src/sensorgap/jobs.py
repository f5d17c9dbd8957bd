"""The default main job (``make run``): the whole pipeline for one vehicle.

``output/<system>/`` receives the coverage maps per environment preset (car bodies heading
as the ego), the near-field blind spots, the far-field (Table IV-style) profiles per
environment (a car body along the lane), the critical-scenario search (``search.sqlite``,
``ranking.csv/json``), the exported catalog (``scenarios/``, ``roads/``,
``catalog.json``) and the report (``report.html``, ``report.md``), plus ``run.json``
(command, versions, config hashes, settings) and ``manifest.json``. Stage timings, the
total time and the peak memory are printed at the end (targets: 60 s, 1.5 GiB on 2 cores;
machine-dependent, so not written to a file).
"""

from __future__ import annotations

import multiprocessing
import resource
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.analysis.farfield import LEVELS
from sensorgap.analysis.farfield_outputs import write_farfield
from sensorgap.analysis.nearfield import write_nearfield
from sensorgap.analysis.paper import FarFieldSetup, run_farfield
from sensorgap.atomic import removed_on_error
from sensorgap.config import load_environment, load_environments, load_target
from sensorgap.config.common import name_problem
from sensorgap.config.load import require_shipped, short
from sensorgap.config.presets import roads_dir, shipped_road, templates_dir
from sensorgap.coverage import GridSpec, Scene
from sensorgap.coverage.grid import GridCoverage
from sensorgap.coverage.outputs import compute_coverage, write_coverage
from sensorgap.errors import InputError
from sensorgap.export import export_catalog
from sensorgap.filesio import (
    MANIFEST_NAME,
    is_temporary,
    refuse_if_changed,
    write_csv,
    write_manifest,
)
from sensorgap.models import Conditions, System, load_system
from sensorgap.provenance import write_run_info
from sensorgap.report import write_report
from sensorgap.roads import read_opendrive
from sensorgap.runtime import children_spared_stop_signals, start_resource_tracker
from sensorgap.scenarios import family_presets
from sensorgap.search.anchors import (
    NCAP_ENVIRONMENT,
    NCAP_FAMILY,
    evaluate_anchors,
    ncap_obstructed_cases,
    write_anchors,
)
from sensorgap.search.run import exclusive_folder, refuse_search_clash, run_search
from sensorgap.search.runfolder import STORE_FILE
from sensorgap.search.settings import Prepared, SearchSettings, prepare
from sensorgap.stale import export_removing_stale_report, search_removing_stale

DEFAULT_SYSTEM = "system_a"
#: Coverage grid of the default job: x from, x to, y from, y to, cell size (m); target
#: bodies centred at the cells (0.5 m: about 1 s per environment and thread).
DEFAULT_GRID = (-60.0, 260.0, -50.0, 50.0, 0.5)
#: Heading of the coverage maps' target bodies relative to the ego, deg (driving the same
#: way: the common case in traffic).
COVERAGE_HEADING_DEG = 0.0
#: Default search: every family x every environment preset, differential evolution, lookup.
DEFAULT_BUDGET = 100_000
DEFAULT_TOP = 20
DEFAULT_SEED = 1
#: The default search runs as this many independent searches sharing the budget, so the
#: report can say how many of them found each top weakness (``run_search`` ``seeds``).
DEFAULT_SEEDS = 3
#: Targets of the default job on 2 cores.
TARGET_TIME_S = 60.0
TARGET_PEAK_MIB = 1536.0


def peak_rss_mib() -> float:
    """Peak resident set size of this process so far, MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


class _Clock:
    """Named wall-clock timings of the job's stages, s."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()
        self.stages: dict[str, float] = {}

    def stage(self, name: str, fn: Callable[[], Any]) -> Any:
        t = time.perf_counter()
        out = fn()
        self.stages[name] = round(time.perf_counter() - t, 3)
        print(f"  {name}: {self.stages[name]:.1f} s")
        return out

    @property
    def total(self) -> float:
        return time.perf_counter() - self.t0


def _coverage(system_name: str, out: Path, workers: int, environments: list[str]) -> dict[str, Any]:
    """Coverage maps of car bodies heading as the ego (``COVERAGE_HEADING_DEG``), one per
    environment preset, on ``workers`` threads (the body kernels release the GIL)."""
    system = load_system(system_name)
    target = load_target("car")
    xmin, xmax, ymin, ymax, res = DEFAULT_GRID

    grid = GridSpec(xmin, xmax, ymin, ymax, res, target.reference_height_m)
    names = list(environments)
    scenes = {n: Scene(system, target, Conditions.from_config(load_environment(n))) for n in names}

    def one(env_name: str) -> GridCoverage:
        return compute_coverage(scenes[env_name], grid, heading_deg=COVERAGE_HEADING_DEG)

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        covs = list(pool.map(one, names))
    areas = {}
    for name, cov in zip(names, covs, strict=True):  # figures on this thread (pyplot)
        summary = write_coverage(
            scenes[name],
            grid,
            out / "coverage" / f"{target.name}_{name}",
            heading_deg=COVERAGE_HEADING_DEG,
            cov=cov,
        )
        areas[name] = dict(summary["area_m2_by_level"])
    return areas


def _farfield(system_name: str, out: Path, environments: list[str]) -> None:
    setup = FarFieldSetup()
    net = read_opendrive(shipped_road(setup.road))
    system = load_system(system_name)
    envs, levels, metres = [], [], []
    for env_name in environments:
        scene, ff = run_farfield(system, env_name, setup, net, bodies=True)
        write_farfield(
            scene,
            ff,
            out / "farfield" / env_name,
            f"{system.name}, {env_name}: car body along the right lane",
            extra={
                "setup": setup.__dict__,
                "target_model": "body (coverage.body), heading along the lane",
            },
            bodies=True,
        )
        for level, _ in LEVELS:
            envs.append(env_name)
            levels.append(level)
            metres.append(round(ff.levels_m[level], 1))
    write_csv(
        out / "farfield" / "table_iv.csv",
        ["environment", "level", "metres"],
        [np.array(envs), np.array(levels), np.array(metres, dtype=np.float64)],
    )


def _analysis(
    ref: str, folder: Path, workers: int, environments: list[str]
) -> tuple[dict[str, float], float]:
    """The stages the search does not need: coverage maps, near field, far field (each
    deterministic, each writing its own folder). Returns (wall-clock s per stage, this
    process's peak memory, MiB); run in a process of its own beside the search."""
    times: dict[str, float] = {}
    stages: list[tuple[str, Callable[[], Any]]] = [
        ("coverage maps", lambda: _coverage(ref, folder, workers, environments)),
        ("near field", lambda: write_nearfield(load_system(ref), folder / "nearfield")),
        ("far field", lambda: _farfield(ref, folder, environments)),
    ]
    for name, fn in stages:
        t = time.perf_counter()
        fn()
        times[name] = round(time.perf_counter() - t, 3)
    return times, peak_rss_mib()


#: Why a vehicle's stem or preset name cannot name the run's folder (``vehicle_ref``).
_TEMPORARY_FOLDER = (
    "a folder named like a temporary or journal file (*.tmp, *-journal, *-wal, *-shm) is "
    "never part of a finished run folder"
)


def vehicle_ref(vehicle: str) -> tuple[str, str]:
    """(folder name, reference to record) of a ``--vehicle``: a preset name as it is, a
    .toml path by its stem and its absolute path (the run works from any folder). A stem
    that cannot name a folder inside ``--out`` (``.``, ``..``, a leading dot, characters
    outside ``config.common.NAME_CHARS``, a name like a temporary or journal file) is
    refused: ``..toml`` would put the whole job into ``--out`` itself, ``...toml`` into
    its parent, ``a-wal.toml`` into a folder ``verify`` takes for a left-over (hostile
    round 35: refused only after the whole job, naming one of its files)."""
    if vehicle.endswith(".toml") or "/" in vehicle:
        p = Path(vehicle).resolve()
        why = name_problem(p.stem) or (
            "a name that starts with a dot would not make a folder of its own"
            if p.stem.startswith(".")
            else _TEMPORARY_FOLDER
            if is_temporary(p.stem)
            else None
        )
        if why:
            raise InputError(
                p, "", f"vehicle file name (stem) {short(p.stem)} names the run's folder: {why}"
            )
        return p.stem, str(p)
    if is_temporary(vehicle):  # a preset of SENSORGAP_TEMPLATES (hostile round 36)
        raise InputError(
            "--vehicle",
            "",
            f"preset {short(vehicle)} names the run's folder: {_TEMPORARY_FOLDER}",
        )
    return vehicle, vehicle


def run_default(
    out: Path,
    workers: int = 2,
    system_name: str = DEFAULT_SYSTEM,
    budget: int = DEFAULT_BUDGET,
    top: int = DEFAULT_TOP,
    seed: int = DEFAULT_SEED,
    families: list[str] | None = None,
    environments: list[str] | None = None,
    seeds: int = DEFAULT_SEEDS,
    certify_out: bool = False,
) -> dict[str, Any]:
    """The whole pipeline for a vehicle (preset name or .toml path) into
    ``out/<vehicle>/``: coverage maps, near field, far field, search over ``families``
    and ``environments`` (default: all), the Euro NCAP anchor cases when their family is
    searched (``search.anchors``: ``anchors/anchors.csv``), export and report; returns run
    info. ``seeds``: independent searches sharing the budget (``run_search``).
    ``certify_out``: also write ``out/manifest.json`` (``sensorgap run``). Every refusal
    comes before any stage writes (``refuse_job_clash``); a job that fails or is stopped
    later leaves ``out`` as it was (``atomic.removed_on_error``)."""
    name, ref = vehicle_ref(system_name)
    system = load_system(ref)  # bad input is refused before anything is written
    fams = family_presets() if families is None else list(families)
    envs = list(load_environments()) if environments is None else list(environments)
    all_envs = load_environments()
    unknown = [e for e in envs if e not in all_envs]
    if unknown:
        raise InputError(
            "environments",
            "",
            f"unknown environment preset(s) {', '.join(unknown)}; presets: {', '.join(all_envs)}",
        )
    # every search setting (budget, seeds, families) checked before anything is written:
    # the coverage, near and far field run beside the search and would write first
    prepared = prepare(
        SearchSettings(
            ref, tuple(fams), tuple(envs), budget, seed, top, "de", workers=workers, seeds=seeds
        )
    )
    # the shipped target and road its coverage maps and far field use by name (hostile
    # round 29: a SENSORGAP_ROADS or SENSORGAP_TEMPLATES lacking them failed after the
    # search had run, as "target: unknown target 'car'")
    require_shipped(
        targets=("car", FarFieldSetup().target),
        # the anchor cases' environment (hostile round 30: a KeyError after all the work)
        environments=(NCAP_ENVIRONMENT,) if NCAP_FAMILY in fams else (),
    )
    shipped_road(FarFieldSetup().road)
    folder = out / name
    refuse_job_clash(prepared, folder)
    # a failed or stopped job leaves OUT as it was: a folder it made removed, an earlier
    # run restored (its search store, changed in place, kept as a copy)
    with removed_on_error(out, copies=(f"{name}/{STORE_FILE}",)):
        folder.mkdir(parents=True, exist_ok=True)
        # no search into the folder while the job writes it (its own search included:
        # it takes no lock of its own), nor a second job
        with exclusive_folder(folder):
            info = _run_job(out, folder, ref, system, fams, envs, budget, top, seed, seeds, workers)
        if certify_out:
            write_manifest(out)
    return info


def refuse_job_clash(prepared: Prepared, folder: Path) -> None:
    """Before any stage of the job writes into ``folder`` (an earlier run of the same
    vehicle, or a new folder): everything a later stage would refuse, so a refused job
    has written nothing. The folder's certified files must be unchanged or lost
    (``filesio.refuse_if_changed``: the job certifies the folder again, so a file edited
    by hand would be certified; a lost one it writes again), and the search must accept the folder
    (``search.run.refuse_search_clash``, the check ``run_search`` itself makes: a store
    of a search with other settings, such as other environments or another vehicle file
    of the same name, or of other input file contents, a damaged store, a symbolic
    link), and no search may be writing it now (``search.run.exclusive_folder``).
    ``InputError`` naming the file or ``--out``."""
    if not folder.is_dir():
        return  # a new folder: nothing to clash with
    with exclusive_folder(folder):  # no search writing it now
        refuse_if_changed(folder, (), lost_ok=True)
        refuse_search_clash(prepared, folder, resume=True)


def _quiet_on_ctrl_c() -> None:
    """Initializer of the job's second process: Ctrl-C ends it as SIGTERM does, without a
    KeyboardInterrupt traceback ("Process SpawnProcess-1:" and 30-70 lines on standard
    error: a terminal sends Ctrl-C to the whole process group; hostile round twenty, F4).
    The process starts with the stop signals blocked (``_spawn_blocking_ctrl_c``): one
    sent during its start-up is pending until here, then ends it."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    if hasattr(signal, "pthread_sigmask"):
        stops = [getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n)]
        signal.pthread_sigmask(signal.SIG_UNBLOCK, stops)


def _spawn_blocking_ctrl_c(pool: ProcessPoolExecutor, fn: Callable[..., Any], *args: Any) -> Any:
    """``pool.submit(fn, *args)`` with the stop signals blocked in this thread while the
    pool starts its process, which inherits them blocked (``_quiet_on_ctrl_c`` unblocks
    them; ``runtime.children_spared_stop_signals``); one sent to this process meanwhile
    is delivered after."""
    with children_spared_stop_signals():
        return pool.submit(fn, *args)


def _run_job(
    out: Path,
    folder: Path,
    ref: str,
    system: System,
    fams: list[str],
    envs: list[str],
    budget: int,
    top: int,
    seed: int,
    seeds: int,
    workers: int,
) -> dict[str, Any]:
    """The job's stages into ``folder`` (checked by ``run_default``, locked by it);
    returns run info."""
    # the job rewrites the whole folder and certifies it at the end: its earlier
    # manifest would make the export refuse the job's own new search files as "changed
    # by hand" (refuse_job_clash checked them before any stage wrote)
    (folder / MANIFEST_NAME).unlink(missing_ok=True)
    clock = _Clock()
    print(f"{folder}: main job for {system.name} ({ref})")

    def search() -> Any:
        # a ranking changed from the earlier run's makes its export and report stale:
        # removed as `sensorgap search --resume` does (stale.search_removing_stale)
        return search_removing_stale(folder, lambda: _search())[0]

    def _search() -> Any:
        return run_search(
            ref,
            fams,
            envs,
            budget,
            seed,
            top,
            folder,
            strategy="de",
            progress=False,
            workers=workers,
            resume=True,
            seeds=seeds,
            lock=False,  # the job holds the folder's lock
        )

    side_peak = 0.0
    if workers >= 2:
        # coverage, near and far field in a second process beside the search: the search
        # leaves a core idle between its batches (ask/tell, decoding, the store), and
        # neither needs the other's files. 'spawn': no fork of a threaded process.
        ctx = multiprocessing.get_context("spawn")
        start_resource_tracker()
        with ProcessPoolExecutor(1, mp_context=ctx, initializer=_quiet_on_ctrl_c) as pool:
            side = _spawn_blocking_ctrl_c(pool, _analysis, ref, folder, 1, envs)
            outcome = clock.stage("search", search)
            times, side_peak = clock.stage(
                "coverage, near and far field (beside the search, waiting for them)", side.result
            )
        for name, secs in times.items():
            print(f"    {name}: {secs:.1f} s (in the second process)")
    else:
        times, _ = clock.stage(
            "coverage, near and far field", lambda: _analysis(ref, folder, workers, envs)
        )
        outcome = clock.stage("search", search)
    if NCAP_FAMILY in fams:
        clock.stage(
            "anchors",
            lambda: write_anchors(
                evaluate_anchors(
                    system, ncap_obstructed_cases(system.config.vehicle.x_front_m), vehicle_ref=ref
                ),
                folder / "anchors",
            ),
        )
    # the export's new scenario files make the earlier report stale: its figures of
    # scenarios no longer exported removed (as `sensorgap export` does)
    clock.stage(
        "export", lambda: export_removing_stale_report(folder, lambda: export_catalog(folder))
    )
    settings = {
        "budget": budget,
        "top": top,
        "seed": seed,
        "seeds": seeds,
        "strategy": "de",
        "pd": "lookup",
        "families": fams,
        "environments": envs,
        "coverage_grid_m": list(DEFAULT_GRID),
        "coverage_target": f"car bodies at heading {COVERAGE_HEADING_DEG:g} deg",
        "farfield_target": "car body along the lane",
        "workers": workers,
    }
    command = [
        "sensorgap",
        "run",
        "--vehicle",
        ref,
        "--out",
        str(out),
        "--budget",
        str(budget),
        "--seed",
        str(seed),
        "--seeds",
        str(seeds),
        "--families",
        ",".join(fams),
        "--environments",
        ",".join(envs),
        "--workers",
        str(workers),
    ]
    tdir = templates_dir()
    files = [
        system.source,
        tdir / "environments.toml",
        tdir / "targets.toml",
        tdir / "reactions.toml",
        *sorted((tdir / "scenarios").glob("*.toml")),
        *sorted(roads_dir().glob("*.xodr")),
    ]
    write_run_info(
        folder, command, ref, files, settings, {"candidates": outcome.summary["candidates"]}
    )
    clock.stage("report", lambda: write_report(folder))
    # peak memory of the job: this process's peak plus the second process's (an upper
    # bound: the two peaks need not coincide)
    total, peak = clock.total, peak_rss_mib() + side_peak
    write_manifest(folder)  # timings are printed, not written: files stay byte-identical
    info = {
        "settings": settings,
        "timings_s": {**clock.stages, **times},
        "total_s": total,
        "peak_rss_mib": peak,
    }
    both = " (both processes' peaks added)" if side_peak else ""
    print(
        f"{folder}: {outcome.summary['candidates']:,} candidates, "
        f"{len(outcome.ranking)} ranked; total {total:.1f} s (target {TARGET_TIME_S:.0f} s), "
        f"peak memory {peak:.0f} MiB{both} (target {TARGET_PEAK_MIB:.0f} MiB)"
        + (f"; {outcome.summary['note']}" if "note" in outcome.summary else "")
    )
    return info
