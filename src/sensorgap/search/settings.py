"""What a search is asked (``SearchSettings``, checked before any work) and what that
resolves to (``prepare``: the vehicle, environments, families, evaluator and one search
problem per family, the record a run folder keeps and the digests of every input).

Reading the input files is the only I/O here; the search loop (``search.loop``) and the
writers (``search.run``) take a ``Prepared``.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from sensorgap.config import EnvironmentConfig, load_environments, load_targets
from sensorgap.config.common import as_integer, finite_real, shown
from sensorgap.config.presets import resolve_road, roads_dir
from sensorgap.errors import InputError
from sensorgap.models import System, load_system
from sensorgap.roads import xsd_errors
from sensorgap.scenarios import Family, load_families
from sensorgap.search.evaluate import DetectionRule, Evaluator
from sensorgap.search.executors import ProblemSpec, check_scheduler_address
from sensorgap.search.problem import SearchProblem
from sensorgap.search.ranking import MIN_DISTANCE
from sensorgap.search.runfolder import MAX_RANKED_ROWS
from sensorgap.search.store import configs_digest, file_digest, reaction_digest
from sensorgap.search.strategies import get_strategy, strategy_names

#: Largest budget of one search, candidates.
MAX_BUDGET = 1_000_000
#: Largest seed (numpy's seed sequences take any non-negative integer; this keeps it an
#: int64 in the store).
MAX_SEED = 2**63 - 1
#: ``--detection`` as M/N: ASCII digits only (range checked by ``DetectionRule.parse``).
_DETECTION_TEXT = re.compile(r"[0-9]{1,9}/[0-9]{1,9}")
#: Most independent searches one run's budget may be split into (``seeds``).
MAX_SEEDS = 10
#: Most environments one search covers: each costs its own coverage maps (``--pd
#: lookup``; 2,000 environments of a 5 MB file took 120 s at 1.5 GB under load, and the
#: time grows with their number).
MAX_ENVIRONMENTS = 1000
#: Worker processes of a local Dask cluster (``executor="dask"`` without a scheduler):
#: each holds its own interpreter, numpy and kernels, ~0.2 GiB (hostile round 28: 16
#: workers 3.3 GiB PSS, 5.0 GiB RSS, budget 2,000 in 3 min; 2-core machine, 2026-11-27);
#: 8 stays within the ~2 GiB a command may use beside its own.
MAX_DASK_PROCESSES = 8


@dataclass(frozen=True)
class SearchSettings:
    """One search: the vehicle (preset name or .toml path), family names or files,
    environment preset names (of ``environments_file`` if given), the budget (candidates
    in all), the seed and the number of independent searches sharing the budget
    (``seeds``), how many rows to rank (``top``), the strategy, ``mode`` (Pd by map
    ``lookup`` or ``exact``), whether the sun position is searched, the ranking's
    near-duplicate distance, the detection rule, and where batches are evaluated
    (``workers`` threads, or Dask worker processes with ``executor="dask"``)."""

    vehicle: str | Path
    families: tuple[str, ...]
    environments: tuple[str, ...]
    budget: int
    seed: int
    top: int
    strategy: str = "de"
    mode: str = "lookup"
    sun_search: bool = True
    environments_file: Path | None = None
    min_distance: float = MIN_DISTANCE
    detection: str = "cumulative"
    workers: int = 2
    executor: str = "local"
    scheduler: str | None = None
    seeds: int = 1

    def check(self) -> None:
        """Refuse settings out of their ranges (``InputError`` naming the field)."""
        for name in ("budget", "seed", "top", "workers", "seeds"):
            value = getattr(self, name)
            if as_integer(value) is None:  # '10' or True, given to the library
                raise InputError(name, "", f"must be an integer, got {shown(value)}")
        for name in ("strategy", "mode", "detection", "executor"):
            value = getattr(self, name)
            if not isinstance(value, str):
                raise InputError(name, "", f"must be a str, got {shown(value)}")
        if not isinstance(self.sun_search, bool):  # 'no' would be true
            raise InputError("sun_search", "", f"must be a bool, got {shown(self.sun_search)}")
        distance = finite_real(self.min_distance)
        if distance is None or distance < 0.0:
            raise InputError(
                "min_distance", "", f"must be a finite number >= 0, got {shown(self.min_distance)}"
            )
        for name in ("families", "environments"):
            for value in getattr(self, name):
                if not isinstance(value, str | Path):
                    raise InputError(name, "", f"must be a list of names, got {shown(value)} in it")
        if not 1 <= self.budget <= MAX_BUDGET:
            raise InputError(
                "budget", "", f"must be within 1..{MAX_BUDGET}, got {shown(int(self.budget))}"
            )
        if not 1 <= self.workers <= 64:
            raise InputError("workers", "", f"must be 1..64, got {shown(int(self.workers))}")
        if self.executor == "dask" and not self.scheduler and self.workers > MAX_DASK_PROCESSES:
            raise InputError(
                "workers",
                "",
                f"at most {MAX_DASK_PROCESSES} with the dask executor and no scheduler (each "
                f"is a local worker process of ~0.2 GiB), got {int(self.workers)}; name a "
                "scheduler to use a cluster's workers",
            )
        n_env = len(set(self.environments))
        if n_env > MAX_ENVIRONMENTS:
            raise InputError(
                "environments",
                "",
                f"{n_env} environments; at most {MAX_ENVIRONMENTS} in one search (name fewer)",
            )
        if not 1 <= self.top <= MAX_RANKED_ROWS:
            raise InputError(
                "top", "", f"must be within 1..{MAX_RANKED_ROWS}, got {shown(int(self.top))}"
            )
        if get_strategy(self.strategy) is None:
            raise InputError(
                "strategy",
                "",
                f"unknown strategy {self.strategy!r}; allowed: {', '.join(strategy_names())}",
            )
        if self.mode not in ("lookup", "exact"):
            # the parameter's name (the command line's --pd offers only these two)
            raise InputError("mode", "", f"must be lookup or exact, got {self.mode!r}")
        if isinstance(self.seed, bool) or not 0 <= self.seed <= MAX_SEED:
            raise InputError(
                "seed", "", f"must be an integer within 0..{MAX_SEED}, got {shown(int(self.seed))}"
            )
        if isinstance(self.seeds, bool) or not 1 <= self.seeds <= MAX_SEEDS:
            raise InputError(
                "seeds",
                "",
                f"must be an integer within 1..{MAX_SEEDS}, got {shown(int(self.seeds))}",
            )
        if self.detection != "cumulative" and not _DETECTION_TEXT.fullmatch(self.detection):
            # DetectionRule.parse takes str.isdigit, which also admits other scripts' digits
            # ("３/5"); here, as for every other number, only ASCII digits
            raise InputError(
                "detection",
                "",
                "expected 'cumulative' or M/N in ASCII digits (no spaces) with 1 <= M <= N <= 50 "
                f"(e.g. 3/5), got {self.detection[:80]!r}",
            )
        if self.executor not in ("local", "dask"):
            raise InputError("executor", "", f"must be local or dask, got {self.executor!r}")
        if self.scheduler is not None:
            if self.executor != "dask":  # it would be ignored: the batches run here
                raise InputError(
                    "scheduler", "", "a scheduler address needs the Dask executor (--executor dask)"
                )
            check_scheduler_address(self.scheduler)


@dataclass
class Prepared:
    """The resolved inputs of a search (``prepare``)."""

    settings: SearchSettings
    system: System
    families: list[Family]
    environments: dict[str, EnvironmentConfig]
    rule: DetectionRule
    evaluator: Evaluator
    #: one search problem per family, by family name
    problems: dict[str, SearchProblem]
    #: how a Dask worker rebuilds the problems (``search.executors``)
    spec: ProblemSpec
    #: the settings as the store, ranking.json and summary.json record them
    record: dict[str, Any]
    #: content digests of every input the stored results depend on
    inputs: dict[str, str]

    def shares(self) -> list[int]:
        """Candidates per family: the budget split evenly (the first ones get the rest)."""
        n, b = len(self.families), self.settings.budget
        return [b // n + (1 if i < b % n else 0) for i in range(n)]

    def exact_problems(self) -> dict[str, SearchProblem]:
        """The problems with exact evaluation (the lookup's proposals are re-evaluated with
        them before anything is ranked)."""
        s = self.settings
        if s.mode == "exact":
            return self.problems
        ev = Evaluator(self.system, mode="exact", rule=self.rule)
        return {
            f.name: SearchProblem(f, self.environments, ev, s.sun_search) for f in self.families
        }


def vehicle_ref(vehicle: str | Path) -> str:
    """How the run records its vehicle: a preset name as given, a file as its absolute
    path (so export, compare and report work from any working directory)."""
    text = str(vehicle)
    if text.endswith(".toml") or "/" in text or Path(text).exists():
        return str(Path(text).resolve())
    return text


def input_digests(
    vehicle_file: Path, evaluator: Evaluator, envs: dict[str, EnvironmentConfig], fams: list[Family]
) -> dict[str, str]:
    """Content digests of every input the stored results depend on (``--resume`` refuses
    when one changed): the vehicle file, its reaction model and friction, the
    environments, the target classes and each family's file and road."""
    out = {
        "vehicle": file_digest(vehicle_file),
        "reaction": reaction_digest(evaluator.reaction, evaluator.friction),
        "environments": configs_digest(envs),
        "targets": configs_digest(load_targets()),
    }
    for f in fams:
        out[f"family {f.name}"] = file_digest(Path(f.source))
        out[f"road of {f.name}"] = file_digest(resolve_road(str(f.settings["road"])))
    return out


def refuse_unexportable_roads(fams: list[Family]) -> None:
    """Every road of ``fams`` that is not a shipped one must pass the OpenDRIVE 1.7 schema
    (``roads.xsd_errors``): the search's catalog copies it, and ``export`` refused it
    only after the whole search (hostile round 42, F6: a namespace on the root, a lane's
    ``direction``, a second ``<header>``, all read for the analysis, were an internal
    error of ``export``). ``InputError`` naming the road file. The shipped roads pass
    (tested) and are not checked again (loading the schema takes ~0.5 s)."""
    seen: set[Path] = set()
    for fam in fams:
        road = fam.settings.get("road")
        if road is None:
            continue
        path = resolve_road(str(road))
        if path in seen or _shipped(path):
            continue
        seen.add(path)
        errors = xsd_errors(path, limit=1)
        if errors:
            raise InputError(
                path,
                "",
                f"not valid OpenDRIVE 1.7 ({errors[0]}): a catalog of family "
                f"{fam.name!r} copies this road and must pass the schema; fix the road "
                "(docs/roads.md)",
            )


def _shipped(path: Path) -> bool:
    """Whether ``path`` is one of the shipped roads (no ``SENSORGAP_ROADS`` set)."""
    if os.environ.get("SENSORGAP_ROADS"):
        return False
    try:
        return path.resolve().parent == roads_dir().resolve()
    except OSError:
        return False


def prepare(s: SearchSettings) -> Prepared:
    """Check the settings and resolve them: every input read and checked before any
    candidate is evaluated or any file written."""
    s.check()
    # plain ints and floats from here on (a numpy integer reached the store's JSON)
    s = replace(
        s,
        budget=int(s.budget),
        seed=int(s.seed),
        top=int(s.top),
        workers=int(s.workers),
        seeds=int(s.seeds),
        min_distance=float(s.min_distance),
    )
    all_envs = load_environments(s.environments_file)
    if not s.environments:
        raise InputError(
            "environments", "", f"give at least one environment; presets: {', '.join(all_envs)}"
        )
    for e in s.environments:
        if e not in all_envs:
            raise InputError(
                "environments", "", f"unknown environment {e!r}; presets: {', '.join(all_envs)}"
            )
    fams = load_families(list(s.families))
    refuse_unexportable_roads(fams)
    if s.budget < len(fams) * s.seeds:
        raise InputError(
            "budget",
            "",
            f"budget {s.budget} is smaller than the number of "
            f"families ({len(fams)}) times seeds ({s.seeds}); give at least one "
            "evaluation per family and seed",
        )
    system = load_system(s.vehicle)
    envs = {e: all_envs[e] for e in dict.fromkeys(s.environments)}
    rule = DetectionRule.parse(s.detection)
    evaluator = Evaluator(system, mode=s.mode, rule=rule)
    problems = {f.name: SearchProblem(f, envs, evaluator, s.sun_search) for f in fams}
    spec = ProblemSpec(
        str(s.vehicle),
        tuple(s.families),
        tuple(envs),
        None if s.environments_file is None else str(s.environments_file),
        s.mode,
        rule.label(),
        s.sun_search,
    )
    record = {
        "vehicle": system.name,
        "vehicle_file": system.source.name,
        "vehicle_ref": vehicle_ref(s.vehicle),
        "families": [f.name for f in fams],
        "environments": list(envs),
        "seed": s.seed,
        "seeds": s.seeds,
        "strategy": s.strategy,
        "pd": s.mode,
        "sun_search": s.sun_search,
        "detection": rule.label(),
        "reaction": evaluator.reaction.label(),
        "target_model": "bodies",
    }
    return Prepared(
        s,
        system,
        fams,
        envs,
        rule,
        evaluator,
        problems,
        spec,
        record,
        input_digests(system.source, evaluator, envs, fams),
    )
