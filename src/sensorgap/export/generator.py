"""``sensorgap.CriticalScenarios``: the ranked scenarios inside scenariogeneration workflows.

A ``scenariogeneration.ScenarioGenerator`` whose parameter is the rank in a search run:
``CriticalScenarios(run_dir).generate(folder)`` writes the same OpenSCENARIO files as
``sensorgap export`` (the road is the family's OpenDRIVE file, referenced by scenariogeneration
as a road file). Any searched parameter can be overridden for a re-sweep, e.g.
``gen = CriticalScenarios(run); gen.parameters = {"rank": [1], "ego_speed_m_s": [20, 25]}``;
the trajectories are then regenerated with the family's generator.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from scenariogeneration import ScenarioGenerator, xosc

from sensorgap.export.spec import ScenarioSpec, read_run
from sensorgap.export.xosc import DEFAULT_VERSION, build_scenario
from sensorgap.models import load_system


class CriticalScenarios(ScenarioGenerator):
    """The critical scenarios of a search run as a scenariogeneration generator."""

    def __init__(self, run_dir: str | Path, osc_version: str = DEFAULT_VERSION,
                 top: int | None = None) -> None:
        super().__init__()
        self.run = read_run(Path(run_dir))
        self.system = load_system(self.run.vehicle_ref)
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
        return ScenarioSpec.from_row(row, self.system, self.run.folder / "ranking.json")

    def scenario(self, **kwargs: Any) -> xosc.Scenario:
        """The OpenSCENARIO object for one permutation (``rank`` plus overrides)."""
        rank = kwargs.pop("rank")
        sp = self.spec(rank, **kwargs)
        self.road_file = str(sp.road_path)
        return build_scenario(sp, str(sp.road_path), self.osc_version)
