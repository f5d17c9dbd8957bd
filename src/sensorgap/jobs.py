"""The default main job (``make run``): grows with the pipeline."""

from __future__ import annotations

import time
from pathlib import Path

from sensorgap.config import load_environment, load_target
from sensorgap.coverage import GridSpec, Scene
from sensorgap.coverage.outputs import write_coverage
from sensorgap.models import Conditions, load_system

DEFAULT_SYSTEMS = ("system_a", "system_b")
DEFAULT_ENVIRONMENTS = ("clear", "glare_front_right")
DEFAULT_GRID = (-60.0, 260.0, -50.0, 50.0, 0.25)


def run_default(out: Path, workers: int = 2) -> None:
    """Coverage maps of System A and B (car, clear and glare) into ``out/<system>/``."""
    target = load_target("car")
    xmin, xmax, ymin, ymax, res = DEFAULT_GRID
    for name in DEFAULT_SYSTEMS:
        system = load_system(name)
        for env_name in DEFAULT_ENVIRONMENTS:
            t0 = time.perf_counter()
            scene = Scene(system, target, Conditions.from_config(load_environment(env_name)))
            grid = GridSpec(xmin, xmax, ymin, ymax, res, target.reference_height_m)
            folder = out / name / "coverage" / f"{target.name}_{env_name}"
            summary = write_coverage(scene, grid, folder, workers=workers)
            area = summary["area_m2_by_level"]
            print(f"{folder}: Pd=1 {area['pd=1.0']:.0f} m2, Pd>=0.5 {area['pd>=0.5']:.0f} m2, "
                  f"Pd>0 {area['pd>0']:.0f} m2 ({time.perf_counter() - t0:.2f} s)")
