"""Does a finding survive the model's uncertain values? (issue #16)

Each top ranked row is re-evaluated exactly with one uncertain value at a time at either
end of its plausible range, everything else as the run recorded it: the calibrated values
of the presets (``analysis.sensitivity.KNOBS``, changed only where a device's source note
says ``calibrated``) and the camera's veiling-glare estimates
(``analysis.sensitivity.GLARE_ESTIMATES``, every camera). A finding *survives* when it
stays sensor-critical with P(collision) >= ``RANK_MIN_P`` (what a ranking keeps) under
every one of them. The report's confidence section prints the result.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from sensorgap.analysis.sensitivity import GLARE_ESTIMATES, KNOBS, Knob, varied_system
from sensorgap.models import System
from sensorgap.search.compare import candidate_of, searched_environments
from sensorgap.search.problem import SearchProblem
from sensorgap.search.ranking import RANK_MIN_P, classify
from sensorgap.search.runfolder import RunFolder

#: The uncertain values a finding is checked against, each at both ends of its range.
ROBUSTNESS_KNOBS: tuple[Knob, ...] = KNOBS + GLARE_ESTIMATES
#: How many of the top ranked rows are checked (the report's top weaknesses come first).
ROBUSTNESS_TOP = 10


@dataclass(frozen=True)
class Variant:
    """One uncertain value at one end of its range and what the finding became.

    Attributes:
        parameter: the knob's label. value: the value set, in ``unit``.
        collision_probability: P(collision) with it (exact). cls: ``classify``'s class.
    """

    parameter: str
    value: float
    unit: str
    collision_probability: float
    cls: str

    @property
    def holds(self) -> bool:
        """Still sensor-critical at P(collision) >= ``RANK_MIN_P``."""
        return self.cls == "sensor-critical" and self.collision_probability >= RANK_MIN_P


@dataclass(frozen=True)
class RowRobustness:
    """A ranked row under every variant (``variants``: only the knobs its vehicle uses)."""

    rank: int
    scenario_id: str
    family: str
    environment: str
    collision_probability: float
    variants: tuple[Variant, ...]

    @property
    def survives(self) -> bool:
        """Sensor-critical at P(collision) >= ``RANK_MIN_P`` under every variant."""
        return all(v.holds for v in self.variants)

    @property
    def lowest(self) -> Variant | None:
        """The variant with the lowest P(collision) (None: no variant applies)."""
        return min(self.variants, key=lambda v: v.collision_probability, default=None)

    @property
    def broken_by(self) -> list[Variant]:
        """The variants under which it is no longer a finding."""
        return [v for v in self.variants if not v.holds]


def finding_robustness(
    run: RunFolder,
    system: System,
    rows: Sequence[dict[str, Any]],
    knobs: Sequence[Knob] = ROBUSTNESS_KNOBS,
) -> list[RowRobustness]:
    """Each of ``rows`` (ranking rows of ``run``, whose vehicle is ``system``) evaluated
    exactly under each knob of ``knobs`` at its low and high end (P(collision) 0..1 and the
    class), with the run's recorded environments, reaction model, friction and targets."""
    envs = searched_environments(run)
    variants: dict[str, list[Variant]] = {str(r["scenario_id"]): [] for r in rows}
    for knob in knobs:
        for value in (knob.low, knob.high):
            varied = varied_system(system, knob, value)
            if varied is None:
                continue
            ev = run.evaluator("exact", system=varied)
            by_family: dict[str, list[dict[str, Any]]] = {}
            for row in rows:
                by_family.setdefault(str(row["family"]), []).append(row)
            for fam, fam_rows in by_family.items():  # one batch per family (as evaluate)
                prob = SearchProblem(run.family(fam), envs, ev)
                cands = [candidate_of(r, prob, run.folder / "ranking.json") for r in fam_rows]
                for row, res in zip(fam_rows, prob.evaluate_many(cands, threads=1), strict=True):
                    p = (
                        float(res.metrics.get("collision_probability", 0.0))
                        if res.feasible
                        else 0.0
                    )
                    variants[str(row["scenario_id"])].append(
                        Variant(knob.label, float(value), knob.unit, p, classify(res))
                    )
    return [
        RowRobustness(
            int(r["rank"]),
            str(r["scenario_id"]),
            str(r["family"]),
            str(r["environment"]),
            float(r["collision_probability"]),
            tuple(variants[str(r["scenario_id"])]),
        )
        for r in rows
    ]
