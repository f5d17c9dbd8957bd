"""Coverage on a regular grid at one height, computed in tiles (bounded memory) and
optionally on several threads (numpy releases the GIL in its array loops).

Per tile, each sensor is evaluated only on the sub-grid inside the bounding box of what it
can reach at that height (``horizontal_reach_bbox``); sensors that reach no cell of the
grid are never prepared nor evaluated. The generic per-cell loops (field of view, range,
ROC and fusion) are compiled (``fastkernel``); the sensor physics stays numpy.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sensorgap.coverage.fastkernel import (
    accumulate_log_miss,
    mount_constants,
    roc_constants,
    subgrid_geometry,
)
from sensorgap.coverage.scene import Scene
from sensorgap.models.fusion import FusionAccumulator
from sensorgap.models.geometry import horizontal_reach_bbox
from sensorgap.models.numerics import SNR_NOT_IN_VIEW_DB, clip_snr_db
from sensorgap.models.roc import detection_probability, snr_db_for_zero_detection

F64 = NDArray[np.float64]

#: Default number of cells per tile: ~4e5 cells keeps every temporary array of a tile in
#: the low megabytes while amortising the per-sensor Python overhead.
DEFAULT_TILE_CELLS = 400_000


@dataclass(frozen=True)
class GridSpec:
    """A regular grid of cell centres at one height (vehicle frame).

    Cells are ``resolution`` wide; centres at ``xmin + (i + 0.5) * resolution``, so the
    grid covers [xmin, xmin + nx * resolution) exactly when the extent is a multiple of it.
    """

    xmin: float
    xmax: float
    ymin: float
    ymax: float
    resolution: float
    height: float

    def __post_init__(self) -> None:
        vals = (self.xmin, self.xmax, self.ymin, self.ymax, self.resolution, self.height)
        if not all(math.isfinite(v) for v in vals):
            raise ValueError("grid extent, resolution and height must be finite")
        if self.resolution <= 0.0:
            raise ValueError(f"resolution must be > 0 m, got {self.resolution}")
        if self.xmax <= self.xmin or self.ymax <= self.ymin:
            raise ValueError("extent must satisfy xmin < xmax and ymin < ymax")

    @property
    def nx(self) -> int:
        """Number of columns (x)."""
        return max(1, round((self.xmax - self.xmin) / self.resolution))

    @property
    def ny(self) -> int:
        """Number of rows (y)."""
        return max(1, round((self.ymax - self.ymin) / self.resolution))

    @property
    def cells(self) -> int:
        """Number of cells."""
        return self.nx * self.ny

    def lookup_origin(self) -> tuple[float, float, float]:
        """What the compiled lookups take to place a point in the grid: the first cell
        centre's x and y (m) and cells per metre."""
        return (
            self.xmin + 0.5 * self.resolution,
            self.ymin + 0.5 * self.resolution,
            1.0 / self.resolution,
        )

    def xs(self) -> F64:
        """Cell-centre x coordinates, m."""
        return np.asarray(
            self.xmin + (np.arange(self.nx) + 0.5) * self.resolution, dtype=np.float64
        )

    def ys(self) -> F64:
        """Cell-centre y coordinates, m."""
        return np.asarray(
            self.ymin + (np.arange(self.ny) + 0.5) * self.resolution, dtype=np.float64
        )


@dataclass
class GridCoverage:
    """Fused (and optionally per-sensor) detection on a grid; arrays are (ny, nx)."""

    grid: GridSpec
    fused: F64
    evaluated: list[str]
    pd: dict[str, F64] = field(default_factory=dict)
    snr_db: dict[str, F64] = field(default_factory=dict)


def _index_range(values: F64, lo: float, hi: float) -> tuple[int, int]:
    """Slice [i0, i1) of sorted ``values`` within [lo, hi]."""
    return int(np.searchsorted(values, lo, "left")), int(np.searchsorted(values, hi, "right"))


#: Default bound on the fused-Pd error of saturation culling (see ``evaluate_grid``).
DEFAULT_SATURATION_EPS = 1e-10


def evaluate_grid(
    scene: Scene,
    grid: GridSpec,
    per_sensor: bool = False,
    workers: int = 1,
    tile_cells: int = DEFAULT_TILE_CELLS,
    saturation_eps: float = DEFAULT_SATURATION_EPS,
) -> GridCoverage:
    """Fused Pd (eq. 11) on ``grid``; with ``per_sensor`` also each sensor's Pd and SNR (dB).

    Saturation culling (fused-only mode): once a cell's fused miss probability
    ``prod(1 - p_i)`` is <= ``saturation_eps``, the remaining sensors are not evaluated
    there; they could raise its fused Pd by at most that much, so the result is within
    ``saturation_eps`` of the full evaluation (0 disables the cull; cells with Pd = 1 are
    always skipped, exactly).

    Memory: O(tile_cells) temporaries per worker plus the outputs (8 bytes per cell for the
    fused map, 16 per cell and sensor with ``per_sensor``).
    """
    xs, ys = grid.xs(), grid.ys()
    nx, ny = grid.nx, grid.ny
    fused = np.empty((ny, nx))
    boxes = []
    for s in scene.sensors:
        bb = horizontal_reach_bbox(s.mount, grid.height)
        if bb is None or bb[1] < xs[0] or bb[0] > xs[-1] or bb[3] < ys[0] or bb[2] > ys[-1]:
            scene.skip(s, f"cannot reach the grid at height {grid.height:g} m")
            continue
        boxes.append((s, *_index_range(xs, bb[0], bb[1]), *_index_range(ys, bb[2], bb[3])))
    for s, *_ in boxes:
        scene.prepared(s)  # prepare once, before threads start
    pd_out = {s.id: np.zeros((ny, nx)) for s, *_ in boxes} if per_sensor else {}
    snr_out = {s.id: np.full((ny, nx), SNR_NOT_IN_VIEW_DB) for s, *_ in boxes} if per_sensor else {}
    n_tiles = max(1, math.ceil(grid.cells / tile_cells))
    if workers > 1:
        n_tiles = math.ceil(n_tiles / workers) * workers  # balanced across workers
    rows_per_tile = max(1, math.ceil(ny / n_tiles))
    tiles = [(r0, min(ny, r0 + rows_per_tile)) for r0 in range(0, ny, rows_per_tile)]
    if not per_sensor:
        # Fused-only: sensors whose ROC reaches exactly 1 first, then far-reaching, wide
        # ones; cells detected with certainty (Pd = 1 is absorbing in eq. 11) are skipped by
        # later sensors (exact).
        boxes.sort(
            key=lambda b: (
                snr_db_for_zero_detection(b[0].roc) is None or b[0].roc.kind == "paper",
                -(b[0].mount.max_range ** 2) * min(b[0].mount.hfov, 6.3),
            )
        )

    if not (0.0 <= saturation_eps < 1.0):
        raise ValueError(f"saturation_eps must be in [0, 1), got {saturation_eps}")
    log_eps = math.log(saturation_eps) if saturation_eps > 0.0 else -math.inf
    consts = {s.id: mount_constants(s.mount) for s, *_ in boxes}
    shift = scene.roc_shift_db
    rocs = {s.id: roc_constants(s.roc, shift) for s, *_ in boxes}

    def run_tile(rows: tuple[int, int]) -> None:
        r0, r1 = rows
        acc = FusionAccumulator((r1 - r0, nx))
        flat_log = acc.log_miss.reshape(-1)
        flat_cert = acc.certain.reshape(-1)
        for s, ix0, ix1, iy0, iy1 in boxes:
            a, b = max(iy0, r0), min(iy1, r1)
            if a >= b or ix0 >= ix1:
                continue
            m = s.mount
            prepared = scene.prepared(s)
            if per_sensor:
                skip = np.zeros((b - a, ix1 - ix0), dtype=bool)
            else:  # saturated cells: later sensors change them by <= saturation_eps
                skip = acc.certain[a - r0 : b - r0, ix0:ix1]
                if log_eps > -math.inf:
                    skip = skip | (acc.log_miss[a - r0 : b - r0, ix0:ix1] <= log_eps)
            flat, r, az, el = subgrid_geometry(
                xs[ix0:ix1] - m.x,
                ys[a:b] - m.y,
                grid.height - m.z,
                consts[s.id],
                skip,
                prepared.uses_angles,
            )
            if flat.size == 0:
                continue
            if not prepared.uses_angles:
                az = el = np.zeros_like(r)
            snr = clip_snr_db(prepared.snr_db(r, az, el))
            iy, ix = np.divmod(flat, ix1 - ix0)
            tflat = (iy + (a - r0)) * nx + (ix + ix0)
            compiled = rocs[s.id]
            if per_sensor or compiled is None:
                pd = detection_probability(snr, s.roc, shift)
                acc.add(pd, tflat)
                if per_sensor:
                    pd_out[s.id][iy + a, ix + ix0] = pd
                    snr_out[s.id][iy + a, ix + ix0] = snr
            else:
                accumulate_log_miss(snr, tflat, compiled[0], compiled[1], flat_log, flat_cert)
        fused[r0:r1] = acc.result()

    if workers > 1 and len(tiles) > 1:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(run_tile, tiles))
    else:
        for t in tiles:
            run_tile(t)
    return GridCoverage(
        grid=grid, fused=fused, evaluated=[s.id for s, *_ in boxes], pd=pd_out, snr_db=snr_out
    )
