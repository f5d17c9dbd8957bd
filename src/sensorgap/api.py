"""The scriptable facade (``import sensorgap``): a handful of functions over the pipeline
(named apart from the subpackages ``search``, ``export``, ``report`` they call),
in the spirit of pymoo's ``minimize`` and scenariogeneration's flat namespaces. Each call
takes names or paths as the command line does and returns the library's typed results;
docs/api.md shows them in use (its examples run as tests).

Units: metres, seconds, degrees for angles given by the user (radians inside the models).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from sensorgap.apinames import API_NAMES
from sensorgap.config import load_environment, load_environments, load_target
from sensorgap.coverage import GridSpec, Scene
from sensorgap.coverage.grid import GridCoverage
from sensorgap.coverage.occluders import Occluder
from sensorgap.coverage.outputs import compute_coverage
from sensorgap.coverage.points import PointCoverage
from sensorgap.coverage.points import evaluate_points as _evaluate_points
from sensorgap.models import Conditions, System, load_system
from sensorgap.scenarios import family_presets
from sensorgap.search.run import SearchOutcome, run_search


def load_vehicle(vehicle: str | Path) -> System:
    """A vehicle preset (``system_a``, ``system_b``) or vehicle ``.toml`` file as its
    sensor system (every sensor model built, parameters with units and sources)."""
    return load_system(vehicle)


def scene(
    vehicle: str | Path | System,
    environment: str = "clear",
    target: str = "car",
    environments_file: str | Path | None = None,
    ego_heading_deg: float = 0.0,
) -> Scene:
    """The scene of a vehicle in an environment preset with a target class (sun directions
    resolved for an ego heading, deg, counter-clockwise from east)."""
    system = vehicle if isinstance(vehicle, System) else load_system(vehicle)
    env = load_environment(
        environment, None if environments_file is None else Path(environments_file)
    )
    return Scene(
        system, load_target(target), Conditions.from_config(env, math.radians(ego_heading_deg))
    )


def evaluate_points(
    vehicle: str | Path | System, points: ArrayLike, environment: str = "clear", target: str = "car"
) -> PointCoverage:
    """Per-sensor SNR (dB) and Pd and the fused Pd at (N, 3) vehicle-frame points (m):
    point targets, the paper's setting."""
    return _evaluate_points(
        scene(vehicle, environment, target), np.asarray(points, dtype=np.float64)
    )


def coverage_grid(
    vehicle: str | Path | System,
    environment: str = "clear",
    target: str = "car",
    extent: Sequence[float] = (-60.0, 160.0, -40.0, 40.0),
    resolution: float = 0.5,
    heading_deg: float | None = 0.0,
    occluders: Sequence[Occluder] = (),
    workers: int = 2,
) -> GridCoverage:
    """Fused (and per-sensor) Pd on a grid: ``extent`` = (xmin, xmax, ymin, ymax), m, in
    the vehicle frame, cells of ``resolution`` m; target bodies centred at the cells at
    ``heading_deg`` relative to the ego (``None``: points at the target's reference
    height), hidden by ``occluders`` (bodies only)."""
    sc = scene(vehicle, environment, target)
    xmin, xmax, ymin, ymax = (float(v) for v in extent)
    grid = GridSpec(xmin, xmax, ymin, ymax, float(resolution), sc.target.reference_height_m)
    return compute_coverage(
        sc, grid, per_sensor=True, workers=workers, heading_deg=heading_deg, occluders=occluders
    )


def find_scenarios(
    vehicle: str | Path,
    out: str | Path,
    families: str | Sequence[str] = "all",
    environments: str | Sequence[str] = "all",
    budget: int = 2000,
    seed: int = 1,
    top: int = 10,
    **options: Any,
) -> SearchOutcome:
    """Search for sensor-critical scenarios into the run folder ``out`` (SQLite store,
    ranking.csv/json, summary.json): ``families`` and ``environments`` are ``"all"`` or
    lists of names (families may be .toml paths); ``options`` as ``run_search`` (strategy,
    mode, workers, resume, ...). Every reported number is an exact evaluation."""
    fams = family_presets() if families == "all" else list(families)
    envs = list(load_environments()) if environments == "all" else list(environments)
    return run_search(vehicle, fams, envs, budget, seed, top, Path(out), **options)


def export_catalog(
    run: str | Path,
    out: str | Path | None = None,
    osc_version: str = "1.2",
    top: int | None = None,
    style: str = "maneuver",
) -> dict[str, Any]:
    """The OpenSCENARIO + OpenDRIVE catalog of a search run (XSD-validated) in ``style``
    (``maneuver``: actions on triggers relative to the ego, a replaceable ego controller;
    ``replay``: timed trajectories; docs/export.md); returns the catalog index
    (``catalog.json``)."""
    from sensorgap.export import export_catalog as _export

    return _export(Path(run), None if out is None else Path(out), osc_version, top, style=style)


def write_report(run: str | Path) -> tuple[Path, Path]:
    """``report.html`` and ``report.md`` of a run folder; returns their paths."""
    from sensorgap.report import write_report as _write

    return _write(Path(run))


# the names live in ``sensorgap.apinames`` (the root package offers them lazily from there)
__all__ = list(API_NAMES)
