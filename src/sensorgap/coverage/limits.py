"""The limits of a coverage map (docs/limits.md, "Commands": ``coverage``), checked before
any work, in one place for the command line (``sensorgap coverage``) and the library
(``sensorgap.coverage_grid``): each check names the option or the parameter (``Names``).

The worst accepted input stays within ~4 GiB (measured: benchmarks/bench_limits.py; a point
grid peaks at ~100 B per cell, a per-sensor map cell at ~31 B).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from sensorgap.config.common import as_integer, finite_real, shown
from sensorgap.config.vehicle import BodyConfig
from sensorgap.coverage.grid import GridSpec
from sensorgap.coverage.occluders import Occluder
from sensorgap.errors import InputError

#: Cells of a grid of points, and of target bodies (a heading given).
MAX_GRID_CELLS = 30_000_000
MAX_BODY_CELLS = 4_000_000
#: Cells x sensors of the per-sensor maps.
MAX_PER_SENSOR_CELLS = 80_000_000
#: Extent coordinates, m, either way, and the finest resolution, m.
MAX_EXTENT_M = 100_000.0
MIN_RESOLUTION_M = 0.001
#: A target's (and the ego's) heading, deg, either way.
MAX_HEADING_DEG = 360.0
#: Most occluders of one map: the time grows with cells x occluders (~0.3 us a pair here:
#: 1,000 occluders over 70,400 cells took 20 s, so over the 4e6 cells allowed with a heading
#: ~19 min; 100 keep it near 2 min).
MAX_OCCLUDERS = 100
#: Most threads of one map.
MAX_WORKERS = 64
#: Work of one map of target bodies (a heading given): cells x sensors x (1 + occluders x
#: ``OCCLUDER_WORK``), body evaluations of one cell by one sensor. Measured on the 2-core
#: machine (2026-11-28, one thread): 0.37 us each for System A's sensors without
#: occluders, 0.017 us more per occluder (20 and 50 trucks over 20,000 cells), so an
#: occluder counts 1/20; about 0.74 us each for long-range sensors that see every cell
#: (System A's radars and lidar copied to 128 sensors, 100 trucks, 80,000 cells: 22.5 s on
#: 2 threads). At the limit that case takes about 75 s on 2 threads. Hostile round 37: the
#: limits one by one (4e6 cells, 128 sensors, 100 occluders) allowed a map of ~20 minutes.
MAX_BODY_WORK = 200_000_000
OCCLUDER_WORK = 0.05


@dataclass(frozen=True)
class Names:
    """How the errors name each input: the command line's options or the library's
    parameters."""

    extent: str
    extent_form: str
    resolution: str
    heading: str
    heading_usage: str
    per_sensor: str
    workers: str
    occluders: str


CLI_NAMES = Names(
    "--extent",
    "XMIN,XMAX,YMIN,YMAX",
    "--resolution",
    "--heading",
    "--heading DEG",
    "--per-sensor",
    "--workers",
    "--occluder",
)
API_NAMES = Names(
    "extent",
    "(xmin, xmax, ymin, ymax)",
    "resolution",
    "heading_deg",
    "heading_deg (degrees)",
    "resolution",  # the library's maps are always per sensor
    "workers",
    "occluders",
)


def check_workers(workers: object, names: Names) -> int:
    """Threads of a map: an integer within 1..``MAX_WORKERS``."""
    number = as_integer(workers)  # (a 0-d integer array too: hostile round 42)
    if number is None or not 1 <= number <= MAX_WORKERS:
        raise InputError(names.workers, "", f"must be 1..{MAX_WORKERS}, got {shown(workers)}")
    return number


def check_heading(heading_deg: object, name: str) -> float:
    """A finite angle within +-``MAX_HEADING_DEG`` deg (as an occluder's heading): a
    finite real number (``config.common.finite_real``)."""
    angle = finite_real(heading_deg)
    if angle is None or abs(angle) > MAX_HEADING_DEG:
        raise InputError(
            name,
            "",
            f"must be an angle within +-{MAX_HEADING_DEG:g} degrees, got {shown(heading_deg)}",
        )
    return angle


def check_resolution(resolution: object, name: str) -> float:
    """A cell size: a finite real number > 0, m (``config.common.finite_real``)."""
    size = finite_real(resolution)
    if size is None or size <= 0.0:
        raise InputError(name, "", f"must be a finite number > 0, got {shown(resolution)}")
    return size


def grid_cells(
    extent: Sequence[float],
    resolution: float,
    bodies: bool,
    names: Names,
    shown: str | None = None,
) -> tuple[int, int]:
    """Columns and rows of whole cells of ``resolution`` (m) in ``extent`` (xmin, xmax,
    ymin, ymax, m; every value a finite number), checked against the limits: coordinates
    within +-``MAX_EXTENT_M``, a resolution of at least ``MIN_RESOLUTION_M`` that fits the
    extent, at most ``MAX_GRID_CELLS`` cells (``MAX_BODY_CELLS`` of target ``bodies``).
    ``shown``: the extent as the user wrote it (for the error line)."""
    xmin, xmax, ymin, ymax = extent
    shown = repr(extent) if shown is None else repr(shown)
    if not (xmin < xmax and ymin < ymax):
        raise InputError(
            names.extent,
            "",
            f"must be {names.extent_form} with xmin < xmax and ymin < ymax, got {shown}",
        )
    if max(abs(xmin), abs(xmax), abs(ymin), abs(ymax)) > MAX_EXTENT_M:
        raise InputError(
            names.extent, "", f"coordinates must be within +-{MAX_EXTENT_M:g} m, got {shown}"
        )
    if resolution < MIN_RESOLUTION_M:
        raise InputError(
            names.resolution, "", f"must be at least {MIN_RESOLUTION_M:g} m, got {resolution!r}"
        )
    # whole cells only: the grid never reaches beyond the extent
    nx = math.floor((xmax - xmin) / resolution + 1e-9)
    ny = math.floor((ymax - ymin) / resolution + 1e-9)
    if nx < 1 or ny < 1:
        raise InputError(
            names.resolution,
            "",
            f"{resolution:g} m cells do not fit the extent "
            f"{xmax - xmin:g} x {ymax - ymin:g} m; give a resolution at most "
            f"{min(xmax - xmin, ymax - ymin):g} m",
        )
    cells = nx * ny
    limit = MAX_BODY_CELLS if bodies else MAX_GRID_CELLS
    if cells > limit:
        raise InputError(
            names.resolution,
            "",
            f"grid of {cells:,} cells is too large (at "
            f"most {int(limit):,}{f' with {names.heading}' if bodies else ''}"
            "); coarsen the resolution or shrink the extent",
        )
    return nx, ny


def check_per_sensor(cells: int, sensors: int, names: Names) -> None:
    """The per-sensor maps: at most ``MAX_PER_SENSOR_CELLS`` cells x sensors."""
    if cells * sensors > MAX_PER_SENSOR_CELLS:
        raise InputError(
            names.per_sensor,
            "",
            f"{cells:,} cells x {sensors:,} "
            f"sensors is too large (at most {int(MAX_PER_SENSOR_CELLS):,} map "
            "cells); coarsen the resolution or shrink the extent",
        )


def check_body_work(cells: int, sensors: int, occluders: int, names: Names) -> None:
    """A map of target bodies: at most ``MAX_BODY_WORK`` cell-sensor evaluations, an
    occluder adding ``OCCLUDER_WORK`` of one to each (checked before any work)."""
    work = cells * sensors * (1.0 + occluders * OCCLUDER_WORK)
    if work > MAX_BODY_WORK:
        raise InputError(
            names.resolution,
            "",
            f"a map of target bodies of {cells:,} cells x {sensors:,} sensors with "
            f"{occluders:,} occluders is too much work ({work:.3g} cell-sensor evaluations, "
            f"an occluder counting {OCCLUDER_WORK:g} of one; at most {MAX_BODY_WORK:.3g}: "
            "a minute or two); coarsen the resolution, shrink the extent or use fewer "
            "occluders",
        )


def check_occluder_count(count: int, names: Names) -> None:
    """At most ``MAX_OCCLUDERS`` occluders of one map."""
    if count > MAX_OCCLUDERS:
        raise InputError(names.occluders, "", f"{count} occluders; at most {MAX_OCCLUDERS} allowed")


def check_occluders(
    occluders: Sequence[Occluder],
    heading_deg: float | None,
    body: BodyConfig,
    names: Names,
    shown: Sequence[str] | None = None,
) -> None:
    """Occluders of a map (each a valid ``Occluder``): at most ``MAX_OCCLUDERS``, only
    with a heading (they hide parts of target bodies, not points), none overlapping the
    ego ``body`` (a box standing on the ego would hide the sensors mounted in it and make
    every map meaningless). ``shown``: each as the user wrote it (for the error line)."""
    check_occluder_count(len(occluders), names)
    if occluders and heading_deg is None:
        raise InputError(
            names.occluders,
            "",
            f"occluders hide parts of target bodies: add {names.heading_usage}",
        )
    footprint = body.footprint()
    for i, occ in enumerate(occluders):
        if occ.overlaps(footprint):
            what = (
                repr(shown[i])
                if shown is not None
                else f"[{i}] ({occ.label} at x {occ.x:g}, y {occ.y:g} m)"
            )
            raise InputError(
                names.occluders,
                "",
                f"{what} overlaps the ego body ({body.name}: x {body.x_rear_m:g}.."
                f"{body.x_front_m:g} m, y within +-{0.5 * body.width_m:g} m, the rear axle "
                "at the origin); place the occluder outside it",
            )


def grid_spec(
    extent: Sequence[float], resolution: float, nx: int, ny: int, height: float
) -> GridSpec:
    """The grid of ``nx`` x ``ny`` whole cells from the extent's lower corner."""
    xmin, _, ymin, _ = extent
    return GridSpec(xmin, xmin + nx * resolution, ymin, ymin + ny * resolution, resolution, height)


__all__ = [
    "API_NAMES",
    "CLI_NAMES",
    "MAX_BODY_CELLS",
    "MAX_BODY_WORK",
    "MAX_EXTENT_M",
    "MAX_GRID_CELLS",
    "MAX_HEADING_DEG",
    "MAX_OCCLUDERS",
    "MAX_PER_SENSOR_CELLS",
    "MAX_WORKERS",
    "MIN_RESOLUTION_M",
    "Names",
    "OCCLUDER_WORK",
    "check_body_work",
    "check_heading",
    "check_occluder_count",
    "check_occluders",
    "check_per_sensor",
    "check_resolution",
    "check_workers",
    "grid_cells",
    "grid_spec",
]
