"""Coverage products on disk: ``coverage.npz``, a PNG heat map and ``summary.json``;
the per-point CSV of ``sensorgap probe``."""

from __future__ import annotations

import math
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgap.coverage.figurememo import drawn_system, save_drawn
from sensorgap.coverage.grid import GridCoverage, GridSpec, evaluate_grid
from sensorgap.coverage.limits import MAX_EXTENT_M
from sensorgap.coverage.occluders import Occluder, occluder_array
from sensorgap.coverage.plot import coverage_figure, pd_levels_area
from sensorgap.coverage.points import PointCoverage
from sensorgap.coverage.scene import Scene
from sensorgap.errors import InputError
from sensorgap.filesio import csv_bytes, regular_file_size, write_json, write_npz
from sensorgap.models.geometry import heading_rad
from sensorgap.provenance import sha256_of
from sensorgap.version import __version__


def scene_provenance(scene: Scene) -> dict[str, Any]:
    """What an assessor needs to trace a map back to its inputs."""
    return {
        "sensorgap_version": __version__,
        "vehicle": scene.system.name,
        "vehicle_file": scene.system.source.name,
        "vehicle_sha256": sha256_of(scene.system.source),
        "environment": scene.conditions.env.name,
        "target": scene.target.name,
    }


def probe_csv(cov: PointCoverage) -> bytes:
    """CSV: x,y,z, then ``<id>.snr_db`` and ``<id>.pd`` per sensor, then fused ``pd``."""
    cols = ["x", "y", "z"]
    data = [cov.points[:, 0], cov.points[:, 1], cov.points[:, 2]]
    for i, sid in enumerate(cov.sensor_ids):
        cols += [f"{sid}.snr_db", f"{sid}.pd"]
        data += [cov.snr_db[i], cov.pd[i]]
    cols.append("pd")
    data.append(cov.fused)
    return csv_bytes(cols, data)


def compute_coverage(
    scene: Scene,
    grid: GridSpec,
    per_sensor: bool = False,
    workers: int = 1,
    heading_deg: float | None = None,
    occluders: Sequence[Occluder] = (),
) -> GridCoverage:
    """The coverage ``write_coverage`` writes (points, or bodies at ``heading_deg`` with
    ``occluders``), without writing anything: safe on worker threads (no figures)."""
    from sensorgap.coverage.body import body_grid

    if heading_deg is None:
        return evaluate_grid(scene, grid, per_sensor=per_sensor, workers=workers)
    return body_grid(
        scene,
        grid,
        heading_rad(heading_deg),
        per_sensor=per_sensor,
        occluders=occluder_array(occluders) if occluders else None,
    )


def _unreadable(path: Path | str, exc: BaseException) -> InputError:
    """The one line for a coverage map that cannot be read."""
    return InputError(
        path,
        "",
        f"unreadable coverage map (expected the .npz of `sensorgap coverage`: pd, x, y, "
        f"resolution): {exc}",
    )


def read_coverage_npz(
    path: Path,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]:
    """The map of a ``coverage.npz`` (``write_coverage``): fused Pd at the cell centres
    (shape (len(y), len(x))), the centres' x and y (m, vehicle frame) and the cell size
    (m); unreadable or inconsistent -> ``InputError`` naming the file."""
    try:
        regular_file_size(path)  # a named pipe would block the reader
    except OSError as exc:
        raise _unreadable(path, exc) from None
    _check_npz_members(path)
    try:
        with np.load(path) as z:
            pd = np.asarray(z["pd"], np.float64)
            x, y = np.asarray(z["x"], np.float64), np.asarray(z["y"], np.float64)
            res = float(np.asarray(z["resolution"]).ravel()[0])
    except (OSError, KeyError, ValueError, IndexError, EOFError, zipfile.BadZipFile) as exc:
        raise _unreadable(path, exc) from None
    if x.ndim != 1 or y.ndim != 1 or pd.shape != (len(y), len(x)):
        raise InputError(
            path, "pd", f"expected shape (len(y), len(x)) = ({len(y)}, {len(x)}), got {pd.shape}"
        )
    if pd.size == 0:  # the readers take its extent (hostile round 24: an internal error)
        raise InputError(path, "pd", "an empty map (no cell); coverage writes at least one")
    for name, c in (("x", x), ("y", y)):
        if not (np.all(np.isfinite(c)) and np.all(np.diff(c) > 0.0)):
            raise InputError(path, name, "cell centres must be finite and increasing")
    if not (math.isfinite(res) and 0.0 < res <= 2.0 * MAX_EXTENT_M):
        raise InputError(
            path,
            "resolution",
            f"must be a number > 0 and at most {2.0 * MAX_EXTENT_M:g} m (the extent limit), "
            f"got {res!r}",
        )
    for name, c in (("x", x), ("y", y)):  # the cells the map's resolution says
        if c.size > 1 and not np.allclose(np.diff(c), res, rtol=1e-6, atol=1e-9):
            raise InputError(path, name, f"cell centres must be the resolution ({res:g} m) apart")
    if not np.all((pd >= 0.0) & (pd <= 1.0)):  # also false for nan
        raise InputError(path, "pd", "every cell must be a probability within 0..1")
    return pd, x, y, res


#: Most cells of a coverage map read back (``read_coverage_npz``), as ``coverage`` writes
#: at most (``coverage.limits.MAX_GRID_CELLS``): checked from the .npy headers before any array is
#: read, so a map whose header claims 1e10 cells, or a zip bomb, is refused unread.
MAX_MAP_CELLS = 30_000_000


def _check_npz_members(path: Path) -> None:
    """``InputError`` unless ``pd``, ``x``, ``y`` of the .npz at ``path`` are real numeric
    arrays of at most ``MAX_MAP_CELLS`` values and ``resolution`` one real number (read
    from their headers, nothing allocated: hostile round 24 found a complex, a datetime and
    a 6e8-value resolution, a warning, an internal error and 5 GB)."""
    try:
        with zipfile.ZipFile(path) as zf:
            for name, most in (
                ("pd", MAX_MAP_CELLS),
                ("x", MAX_MAP_CELLS),
                ("y", MAX_MAP_CELLS),
                ("resolution", 1),
            ):
                try:
                    info = zf.getinfo(f"{name}.npy")
                except KeyError:
                    continue  # reported as a missing array by np.load below
                with zf.open(info) as fp:
                    version = np.lib.format.read_magic(fp)
                    if version == (1, 0):
                        shape, _, dtype = np.lib.format.read_array_header_1_0(fp)
                    else:
                        shape, _, dtype = np.lib.format.read_array_header_2_0(fp)
                cells = math.prod(shape)
                if dtype.kind not in "fiu" or cells > most:
                    what = "one real number" if most == 1 else f"at most {most:.0e} real values"
                    raise InputError(path, name, f"expected {what}, got {dtype} of shape {shape}")
                if info.file_size > 16 * most + 4096:
                    raise InputError(path, name, f"{info.file_size} bytes uncompressed")
    except InputError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise _unreadable(path, exc) from None


def write_coverage(
    scene: Scene,
    grid: GridSpec,
    out_dir: Path,
    per_sensor: bool = False,
    workers: int = 1,
    heading_deg: float | None = None,
    occluders: Sequence[Occluder] = (),
    cov: GridCoverage | None = None,
) -> dict[str, Any]:
    """Evaluate ``grid`` and write coverage.npz, coverage.png and summary.json to
    ``out_dir``; returns the summary. ``heading_deg``: evaluate target bodies centred at
    the cells at this heading relative to the ego (``coverage.body``) instead of points;
    ``occluders`` (bodies only): boxes hiding parts of them (``coverage.occluders``);
    ``cov``: that coverage already computed (``compute_coverage``)."""
    if occluders and heading_deg is None:
        raise ValueError("occluders need target bodies (a heading)")
    if cov is None:
        cov = compute_coverage(scene, grid, per_sensor, workers, heading_deg, occluders)
    arrays = {
        "x": grid.xs(),
        "y": grid.ys(),
        "pd": cov.fused,
        "height": np.array(grid.height),
        "resolution": np.array(grid.resolution),
    }
    for sid, pd in cov.pd.items():
        arrays[f"pd.{sid}"] = pd
        if sid in cov.snr_db:
            arrays[f"snr_db.{sid}"] = cov.snr_db[sid]
    out_dir.mkdir(parents=True, exist_ok=True)
    write_npz(out_dir / "coverage.npz", arrays)
    model = (
        f"height {grid.height:g} m"
        if heading_deg is None
        else f"bodies at heading {heading_deg:g} deg"
    )
    title = (
        f"{scene.system.name}: {scene.target.name}, {scene.conditions.env.name}, "
        f"{model}, {grid.resolution:g} m grid"
    )
    if occluders:
        title += f", {len(occluders)} occluder{'s' if len(occluders) > 1 else ''}"
    save_drawn(
        (
            "coverage_figure",
            cov.fused,
            cov.grid,
            drawn_system(scene.system),
            title,
            tuple(occluders),
            scene.conditions,
        ),
        lambda: coverage_figure(cov, scene.system, title, occluders, scene.conditions),
        out_dir / "coverage.png",
    )
    summary = {
        **scene_provenance(scene),
        "grid": {
            "xmin": grid.xmin,
            "xmax": grid.xmax,
            "ymin": grid.ymin,
            "ymax": grid.ymax,
            "resolution_m": grid.resolution,
            "height_m": grid.height,
            "nx": grid.nx,
            "ny": grid.ny,
        },
        "target_model": (
            "point at the grid height"
            if heading_deg is None
            else f"body (coverage.body) at heading {heading_deg:g} deg"
        ),
        "occluders": [
            {
                "label": o.label,
                "x_m": o.x,
                "y_m": o.y,
                "heading_deg": math.degrees(o.heading),
                "length_m": o.length,
                "width_m": o.width,
                "height_m": o.height,
            }
            for o in occluders
        ],
        "area_m2_by_level": pd_levels_area(cov),
        "sensors_evaluated": cov.evaluated,
        "skipped": list(scene.log["skipped"]),
        "effects": list(scene.log["effects"]),
        "files": ["coverage.npz", "coverage.png", "summary.json"],
    }
    write_json(out_dir / "summary.json", summary)
    return summary
