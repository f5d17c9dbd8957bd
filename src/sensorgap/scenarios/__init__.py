"""Scenario families: parameterised ego/target trajectories on real roads.

Importing this package registers the built-in kinds (``cut_in``, ``overtake``,
``slow_ahead``, ``crossing``, and with an occluder ``cut_in_behind_occluder``,
``cut_out_reveal``, ``crossing_behind_parked``); families are the TOML files in
``templates/scenarios``.
"""

from sensorgap.scenarios import kinds, occluded  # noqa: F401  (registration)
from sensorgap.scenarios.family import (
    Family,
    FamilyKind,
    Param,
    Scenario,
    get_kind,
    kind_names,
    register_kind,
)
from sensorgap.scenarios.loader import family_presets, load_families, load_family
from sensorgap.scenarios.trajectory import InfeasibleScenario, Trajectory

__all__ = [
    "Family",
    "FamilyKind",
    "InfeasibleScenario",
    "Param",
    "Scenario",
    "Trajectory",
    "family_presets",
    "get_kind",
    "kind_names",
    "load_families",
    "load_family",
    "register_kind",
]
