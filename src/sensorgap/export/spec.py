"""A ranked scenario rebuilt from a search run: everything an exporter needs.

``ScenarioSpec.from_row`` takes a row of ``ranking.json`` and regenerates the evaluated
trajectories with the family's generator (a batch of one, identical to the search), the
environment (preset + world-frame sun) and the metrics, so every exported file traces back
to one searched candidate.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sensorgap.config import EnvironmentConfig, TargetConfig, load_environments, load_target
from sensorgap.config.presets import resolve_road
from sensorgap.errors import InputError
from sensorgap.models import System
from sensorgap.scenarios import InfeasibleScenario, Scenario, load_family
from sensorgap.scenarios.family import Family, Param, ParamValue
from sensorgap.search.metrics import check_metric_value, metric_names
from sensorgap.search.problem import Candidate
from sensorgap.search.runfolder import STORE_FILE, RunFolder, read_run

__all__ = ["RunInfo", "ScenarioSpec", "read_run", "specs_of_run"]


#: A run folder as export reads it (``search.runfolder``: the one reader of run folders).
RunInfo = RunFolder


@dataclass
class ScenarioSpec:
    """One ranked scenario, regenerated."""

    scenario_id: str
    rank: int
    family: Family
    params: dict[str, ParamValue]
    environment_name: str
    environment: EnvironmentConfig
    sun_deg: tuple[float, float] | None
    scenario: Scenario
    target: TargetConfig
    system: System
    metrics: dict[str, float]
    reason: str

    @property
    def road_path(self) -> Path:
        """The OpenDRIVE file of the family's road."""
        return resolve_road(str(self.family.settings["road"]))

    @classmethod
    def from_row(
        cls,
        row: dict[str, Any],
        system: System,
        source: Path | str = "ranking.json",
        run: RunFolder | None = None,
        check_id: bool = True,
    ) -> ScenarioSpec:
        """Rebuild a ranking row (``InputError`` naming ``source`` if it is inconsistent)
        from the inputs ``run`` recorded (family, its road, environments, targets); without
        ``run``, from the shipped presets. In a run the search wrote (``run.searched``:
        it holds search.sqlite) the row's ``scenario_id`` must be the store's id of its
        family, environment, sun and parameters (``check_id``; off for a generator's
        parameter sweep, whose rows keep the ranked row's id to name their files); a run
        folder written by another tool may name its rows freely (``SCENARIO_ID``)."""
        at = _row_label(row, run)
        field = "family"
        try:
            try:
                family = (
                    run.family(str(row["family"]))
                    if run is not None
                    else load_family(str(row["family"]))
                )
            except InputError as exc:  # named by the row that asked for it
                if exc.field == "targets":  # but the run's recorded targets file by itself
                    raise
                raise ValueError(exc.message) from None
            params: dict[str, ParamValue] = {}
            for p in family.space:
                field = f"p_{p.name}"
                params[p.name] = p.from_json(row[field])
            metric_cols = set(metric_names())  # p_never_confirmed, ... are metrics
            extra = sorted(
                k
                for k in row
                if k.startswith("p_") and k[2:] not in params and k not in metric_cols
            )
            if extra:
                field = extra[0][:64]
                raise ValueError(
                    f"not a parameter of family {family.name!r} "
                    f"({', '.join(p.name for p in family.space)})"
                )
            field = "target"
            if "target" in row and row["target"] != family.settings.get("target"):
                raise ValueError(
                    f"{str(row['target'])[:40]!r} is not the family's target "
                    f"{family.settings.get('target')!r}"
                )
            field = "environment"
            env_name = str(row["environment"]).split("@")[0]
            presets = run.environments() if run is not None else load_environments()
            if env_name not in presets:
                raise ValueError(f"unknown environment {env_name[:64]!r}")
            env = presets[env_name]
            sun = None
            if env.sun is None:  # searched without a sun: the row's sun columns are empty
                for field in ("sun_azimuth_deg", "sun_elevation_deg"):
                    if row.get(field) is not None:
                        raise ValueError(
                            f"must be null: environment {env_name[:64]!r} has no sun "
                            f"(got {str(row.get(field))[:40]!r})"
                        )
            if row.get("sun_azimuth_deg") is not None and env.sun is not None:
                field = "sun_azimuth_deg"
                az = _finite(row["sun_azimuth_deg"])
                field = "sun_elevation_deg"
                sun = (az, _finite(row["sun_elevation_deg"]))
                env = env.model_copy(
                    update={
                        "sun": env.sun.model_copy(
                            update={
                                "azimuth_deg": sun[0],
                                "elevation_deg": sun[1],
                                "frame": "world",
                            }
                        )
                    }
                )
            field = "environment"
            label = (
                env_name
                if sun is None
                else Candidate(str(row["family"]), env_name, sun, {}).environment_label
            )
            if str(row["environment"]) != label:
                raise ValueError(
                    f"{str(row['environment'])[:64]!r} does not match the row's "
                    f"environment and sun columns (expected {label!r})"
                )
            for k in metric_names():  # printed by the report as they stand
                field = k
                check_metric_value(k, row.get(k))
        except KeyError:
            raise InputError(source, f"{at}.{field}", "missing") from None
        except (TypeError, ValueError) as exc:
            raise InputError(source, f"{at}.{field}", str(exc)) from None
        try:
            scenario = family.generate(params)
        except (KeyError, TypeError, ValueError, InfeasibleScenario) as exc:
            raise InputError(source, at, f"cannot rebuild the scenario: {exc}") from None
        if check_id and run is not None and run.searched:
            # the id names the row's files and report entries: an id edited by hand would
            # export and report this scenario under another scenario's name
            cid = Candidate(family.name, env_name, sun, params).scenario_id
            if str(row["scenario_id"]) != cid:
                raise InputError(
                    source,
                    f"{at}.scenario_id",
                    f"{str(row['scenario_id'])[:64]!r} is not the id the run's "
                    f"{STORE_FILE} gives the row's family, environment, sun and parameters "
                    f"({cid!r}); restore the row or search again",
                )
            stored = run.stored_ids()
            if stored is not None and cid not in stored:
                # a row made up by hand (parameters and id edited together)
                raise InputError(
                    source,
                    f"{at}.scenario_id",
                    f"{cid!r} is not a candidate of the run's {STORE_FILE} (every ranked "
                    "row is one); restore the row or search again",
                )
        metrics = {k: float(row[k]) for k in metric_names() if isinstance(row.get(k), int | float)}
        targets = run.targets() if run is not None else None
        if run is not None and targets is not None and scenario.target_class not in targets:
            # never the shipped preset of that name instead of the run's own targets
            raise InputError(
                run.input_path("targets") or "targets",
                "targets",
                f"no target class {scenario.target_class!r} (the target of family "
                f"{family.name!r}); it defines {', '.join(targets) or 'none'}",
            )
        target = (
            targets[scenario.target_class]
            if targets is not None and scenario.target_class in targets
            else load_target(scenario.target_class)
        )
        return cls(
            str(row["scenario_id"]),
            int(row["rank"]),
            family,
            params,
            env_name,
            env,
            sun,
            scenario,
            target,
            system,
            metrics,
            str(row.get("reason", "")),
        )


def _row_label(row: dict[str, Any], run: RunFolder | None) -> str:
    """``ranking[i]``: the row's 0-based position in ``ranking.json`` (as the checks on
    reading it name rows), or its scenario id when it is not one of the run's rows."""
    if run is not None:
        for i, r in enumerate(run.rows):
            if r is row or r == row:
                return f"ranking[{i}]"
    return f"ranking[id={str(row.get('scenario_id', '?'))[:64]}]"


def _finite(v: Any) -> float:
    """A finite JSON number of a ranking row (a sun angle), else ``ValueError``."""
    return float(Param("angle").from_json(v))


def specs_of_run(run: RunFolder, top: int | None = None) -> list[ScenarioSpec]:
    """Every (or the first ``top``) ranked scenario of a run, regenerated from the inputs
    the run recorded."""
    system = run.system()
    rows = run.rows if top is None else run.rows[:top]
    return [ScenarioSpec.from_row(r, system, run.folder / "ranking.json", run) for r in rows]
