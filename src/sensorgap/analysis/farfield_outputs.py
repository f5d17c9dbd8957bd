"""Far-field products: ``farfield.csv``, ``levels.csv``, ``farfield.png`` (Figs. 6-7 style),
``summary.json``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.analysis.farfield import LEVELS, FarField
from sensorgap.coverage.figurememo import drawn_system, save_drawn
from sensorgap.coverage.grid import GridCoverage, GridSpec, evaluate_grid
from sensorgap.coverage.outputs import scene_provenance
from sensorgap.coverage.plot import draw_map, draw_vehicle, plain_text
from sensorgap.coverage.scene import Scene
from sensorgap.filesio import write_csv, write_json
from sensorgap.models.system import System

MAX_PLOT_CELLS = 1_500_000
#: Background cells when the map shows target bodies (each cell a body: ~1 s per 1e5).
MAX_BODY_PLOT_CELLS = 80_000


def farfield_figure_grid(ff: FarField, height: float, max_cells: int = MAX_PLOT_CELLS) -> GridSpec:
    """A grid around the path (vehicle frame) fine enough to show it, at most
    ``max_cells`` cells."""
    x0 = min(-10.0, float(ff.vehicle[:, 0].min()) - 10.0)
    x1 = float(ff.vehicle[:, 0].max()) + 10.0
    y0 = min(-15.0, float(ff.vehicle[:, 1].min()) - 10.0)
    y1 = max(15.0, float(ff.vehicle[:, 1].max()) + 10.0)
    res = max(0.25, math.sqrt((x1 - x0) * (y1 - y0) / max_cells))
    res = math.ceil(res * 4.0) / 4.0
    return GridSpec(x0, x1, y0, y1, res, height)


def write_farfield(
    scene: Scene,
    ff: FarField,
    out_dir: Path,
    title: str,
    extra: dict[str, Any] | None = None,
    bodies: bool = False,
) -> dict[str, Any]:
    """Write the far-field files into ``out_dir``; returns the summary. ``bodies``: the
    profile is of target bodies (``farfield(..., bodies=True)``); the map behind the path
    then shows bodies heading as the ego (a coarser grid), else points at the target's
    reference height."""
    from sensorgap.coverage.body import body_grid

    out_dir.mkdir(parents=True, exist_ok=True)
    cols = ["s", "x_world", "y_world", "x_vehicle", "y_vehicle", "pd"]
    data = [ff.s, ff.world[:, 0], ff.world[:, 1], ff.vehicle[:, 0], ff.vehicle[:, 1], ff.pd]
    for sid, pd in ff.per_sensor.items():
        cols.append(f"{sid}.pd")
        data.append(pd)
    write_csv(out_dir / "farfield.csv", cols, data)
    write_csv(
        out_dir / "levels.csv",
        ["level", "metres"],
        [np.array([k for k, _ in LEVELS]), np.array([ff.levels_m[k] for k, _ in LEVELS])],
    )
    grid = farfield_figure_grid(
        ff, scene.target.reference_height_m, MAX_BODY_PLOT_CELLS if bodies else MAX_PLOT_CELLS
    )
    cov = body_grid(scene, grid, 0.0) if bodies else evaluate_grid(scene, grid, workers=2)
    kind = "car bodies heading as the ego" if bodies else "points"
    save_drawn(
        (
            "farfield_figure",
            cov.fused,
            cov.grid,
            drawn_system(scene.system),
            ff.vehicle,
            ff.s,
            ff.pd,
            ff.ds,
            title,
            kind,
        ),
        lambda: _farfield_figure(scene.system, cov, ff, title, kind),
        out_dir / "farfield.png",
    )
    summary = {
        **scene_provenance(scene),
        **(extra or {}),
        "path_length_m": float(ff.ds.sum()),
        "step_m": float(ff.ds[0]),
        "levels_m": ff.levels_m,
        "figure_grid_resolution_m": grid.resolution,
        "files": ["farfield.csv", "levels.csv", "farfield.png", "summary.json"],
    }
    write_json(out_dir / "summary.json", summary)
    return summary


def _farfield_figure(system: System, cov: GridCoverage, ff: FarField, title: str, kind: str) -> Any:
    """The far-field figure: the Pd map behind the target path (``kind`` of target on
    ``cov``'s grid) with the path, and the fused Pd along it against the distance from the
    ego's front bumper (m)."""
    import matplotlib.pyplot as plt  # after coverage.plot's pristine_matplotlib

    fig, (ax, ax2) = plt.subplots(
        2, 1, figsize=(11.0, 7.5), layout="constrained", height_ratios=(3.0, 1.6)
    )
    g = cov.grid
    im = draw_map(ax, cov.fused, (g.xmin, g.xmax, g.ymin, g.ymax))
    draw_vehicle(ax, system, fov=False)
    ax.plot(
        ff.vehicle[:, 0],
        ff.vehicle[:, 1],
        color="magenta",
        linewidth=2.0,
        label="target path (Pd along it below and in farfield.csv)",
    )
    ax.set_xlim(g.xmin, g.xmax)
    ax.set_ylim(g.ymin, g.ymax)
    ax.set_xlabel("x (vehicle frame) [m]")
    ax.set_ylabel("y (vehicle frame) [m]")
    ax.set_title(f"{plain_text(title)}\nmap: {kind}, {g.resolution:g} m cells", fontsize=10)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.9)
    fig.colorbar(im, ax=ax, label="detection probability $p_d$", shrink=0.8)
    ax2.plot(ff.s, ff.pd, color="black", linewidth=1.5, label="fused Pd")
    for level in (0.5, 0.8):
        ax2.axhline(level, color="grey", linewidth=0.6, linestyle=":")
    ax2.set_xlim(0.0, float(ff.s[-1] + 0.5 * ff.ds[-1]))
    ax2.set_ylim(-0.02, 1.02)
    ax2.set_xlabel("distance along the target path from the ego's front bumper [m]")
    ax2.set_ylabel("Pd")
    ax2.grid(True, linewidth=0.3)
    ax2.legend(loc="upper right", fontsize=8)
    return fig
