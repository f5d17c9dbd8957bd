"""``sensorgap.CriticalScenarios``: the ranked scenarios inside scenariogeneration workflows.

A ``scenariogeneration.ScenarioGenerator`` whose parameter is the rank in a search run:
``CriticalScenarios(run_dir).generate(folder)`` writes the same files as ``sensorgap
export``, byte for byte: ``folder/scenarios/<scenario_id>.xosc`` referencing
``../roads/<road>.xodr``, the roads copied beside them (relative paths: the folder can be
moved). Any searched parameter can be overridden for a re-sweep, e.g.
``gen = CriticalScenarios(run); gen.parameters = {"rank": [1], "ego_speed_m_s": [20, 25]}``;
the trajectories are then regenerated with the family's generator and the files named
``<scenario_id>_<k>.xosc``. ``scenario(**params)`` returns the OpenSCENARIO object as
any ScenarioGenerator does. ``style`` is the export style (``maneuver``, the default, or
``replay``), as ``sensorgap export --style``.
"""

from __future__ import annotations

import itertools
import shutil
from pathlib import Path
from typing import Any

from scenariogeneration import ScenarioGenerator, xosc

from sensorgap.atomic import atomic_path
from sensorgap.export.catalog import DEFAULT_STYLE, STYLES, write_xosc
from sensorgap.export.maneuver import build_maneuver_scenario
from sensorgap.export.spec import ScenarioSpec, read_run
from sensorgap.export.xosc import DEFAULT_VERSION, build_scenario


class CriticalScenarios(ScenarioGenerator):
    """The critical scenarios of a search run as a scenariogeneration generator."""

    def __init__(
        self,
        run_dir: str | Path,
        osc_version: str = DEFAULT_VERSION,
        top: int | None = None,
        style: str = DEFAULT_STYLE,
    ) -> None:
        super().__init__()
        if style not in STYLES:
            raise ValueError(f"style must be one of {', '.join(STYLES)}, got {style!r}")
        self.style = style
        self.run = read_run(Path(run_dir))
        self.system = self.run.system()
        rows = self.run.rows if top is None else self.run.rows[:top]
        self._rows = {int(r["rank"]): r for r in rows}
        self.osc_version = osc_version
        self.parameters: dict[str, list[Any]] = {"rank": sorted(self._rows)}
        self.naming = "numerical"

    def spec(self, rank: int, **overrides: Any) -> ScenarioSpec:
        """The scenario of ``rank``, with searched parameters overridden."""
        row = dict(self._rows[int(rank)])
        for k, v in overrides.items():
            row[f"p_{k}"] = v
        # a sweep's row carries other parameters under the ranked row's id (its files'
        # name); the ranked row itself is checked against its id
        return ScenarioSpec.from_row(
            row, self.system, self.run.folder / "ranking.json", self.run, check_id=not overrides
        )

    def scenario(self, **kwargs: Any) -> xosc.Scenario:
        """The OpenSCENARIO object for one permutation (``rank`` plus overrides)."""
        rank = kwargs.pop("rank")
        sp = self.spec(rank, **kwargs)
        self.road_file = str(sp.road_path)
        if self.style == "replay":
            return build_scenario(sp, str(sp.road_path), self.osc_version)
        return build_maneuver_scenario(sp, str(sp.road_path), self.osc_version)[0]

    def generate(
        self,
        generation_folder: str,
        override_parameters: Any = None,
        write_relative_road_path: bool = True,
    ) -> tuple[list[str], list[str]]:
        """Write the scenarios (and their roads) into ``generation_folder`` in the CLI's
        layout (``scenarios/``, ``roads/``, relative road paths; see the module docstring);
        returns (scenario files, road files) as ScenarioGenerator does."""
        params = self.parameters if override_parameters is None else override_parameters
        if isinstance(params, dict):
            keys = list(params)
            combos = [
                dict(zip(keys, values, strict=True))
                for values in itertools.product(*(params[k] for k in keys))
            ]
        else:
            combos = [dict(c) for c in params]
        sweep = any(len(c) > 1 for c in combos)
        out = Path(generation_folder)
        (out / "scenarios").mkdir(parents=True, exist_ok=True)
        (out / "roads").mkdir(parents=True, exist_ok=True)
        scenario_files: list[str] = []
        road_files: list[str] = []
        for k, combo in enumerate(combos):
            rank = combo.pop("rank")
            sp = self.spec(rank, **combo)
            road = out / "roads" / sp.road_path.name
            if str(road) not in road_files:
                with atomic_path(road) as tmp:
                    shutil.copyfile(sp.road_path, tmp)
                road_files.append(str(road))
            name = f"{sp.scenario_id}_{k}" if sweep else sp.scenario_id
            path = out / "scenarios" / f"{name}.xosc"
            write_xosc(sp, path, f"../roads/{sp.road_path.name}", self.osc_version, self.style)
            scenario_files.append(str(path))
        return scenario_files, road_files
