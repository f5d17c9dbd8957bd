"""Coverage heat maps: Pd on one fixed colour scale, vehicle outline, sensor fields of view."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Polygon, Wedge  # noqa: E402

from sensorgap.atomic import atomic_path  # noqa: E402
from sensorgap.coverage.grid import GridCoverage  # noqa: E402
from sensorgap.coverage.occluders import Occluder  # noqa: E402
from sensorgap.models.system import System  # noqa: E402

#: One colour scale for Pd in every figure sensorgap draws.
PD_CMAP = "viridis"
PD_NORM = Normalize(vmin=0.0, vmax=1.0)

_TYPE_COLOURS = {"camera": "tab:orange", "radar": "tab:red", "lidar": "tab:cyan",
                 "ultrasonic": "tab:pink"}


def plain_text(text: str) -> str:
    """User-given text (vehicle, family, environment names) for a matplotlib label: every
    ``$`` escaped, so a name like ``A $x^{$`` is drawn as written, not parsed as math."""
    return text.replace("$", r"\$")


def draw_vehicle(ax: plt.Axes, system: System, fov: bool = True) -> None:
    """Vehicle footprint and (optionally) each sensor's horizontal field of view."""
    body = system.config.vehicle
    ax.add_patch(Polygon(body.footprint(), closed=True, facecolor="white",
                         edgecolor="black", linewidth=1.0, zorder=5))
    if not fov:
        return
    for s in system.sensors:
        m = s.mount
        colour = _TYPE_COLOURS.get(s.type_name, "tab:gray")
        if m.hfov >= 2.0 * math.pi:
            theta1, theta2 = 0.0, 360.0
        else:
            theta1 = math.degrees(m.yaw - 0.5 * m.hfov)
            theta2 = math.degrees(m.yaw + 0.5 * m.hfov)
        ax.add_patch(Wedge((m.x, m.y), m.max_range, theta1, theta2, fill=False,
                           edgecolor=colour, linewidth=0.6, alpha=0.8, zorder=4))


def coverage_figure(cov: GridCoverage, system: System, title: str,
                    occluders: Sequence[Occluder] = ()) -> Figure:
    """A heat map of the fused Pd with colour bar, axes in metres, vehicle and FOVs, and
    the footprints of ``occluders`` (grey, labelled)."""
    g = cov.grid
    aspect = (g.ymax - g.ymin) / (g.xmax - g.xmin)
    fig, ax = plt.subplots(figsize=(10.0, max(3.0, min(10.0, 10.0 * aspect + 1.2))),
                           layout="constrained")
    im = ax.imshow(cov.fused, origin="lower", extent=(g.xmin, g.xmax, g.ymin, g.ymax),
                   cmap=PD_CMAP, norm=PD_NORM, interpolation="nearest", aspect="equal")
    draw_vehicle(ax, system)
    for i, occ in enumerate(occluders):
        ax.add_patch(Polygon(occ.corners(), closed=True, facecolor="0.55", edgecolor="white",
                             linewidth=0.8, zorder=5,
                             label="occluder (its shadow: low Pd behind it)" if i == 0
                             else None))
        ax.annotate(plain_text(f"{occ.label} {occ.height:g} m"), (occ.x, occ.y), color="white",
                    fontsize=7, ha="center", va="center", zorder=6)
    if occluders:
        ax.legend(loc="upper left", fontsize=8, framealpha=0.9)
    ax.set_xlim(g.xmin, g.xmax)
    ax.set_ylim(g.ymin, g.ymax)
    ax.set_xlabel("x (vehicle frame) [m]")
    ax.set_ylabel("y (vehicle frame) [m]")
    ax.set_title(plain_text(title), fontsize=10)
    fig.colorbar(im, ax=ax, label="detection probability $p_d$", shrink=0.9)
    return fig


def save_figure(fig: Figure, path: str | Path, dpi: int = 120) -> Path:
    """Save a figure as PNG atomically, without a timestamp in its metadata."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi, metadata={"Software": None})
    plt.close(fig)
    return Path(path)


def pd_levels_area(cov: GridCoverage) -> dict[str, float]:
    """Area (m2) of the grid at the paper's Pd levels (1.0, >= 0.8, >= 0.5, > 0, = 0)."""
    cell = cov.grid.resolution**2
    f = cov.fused
    return {
        "pd=1.0": float(np.count_nonzero(f >= 1.0) * cell),
        "pd>=0.8": float(np.count_nonzero(f >= 0.8) * cell),
        "pd>=0.5": float(np.count_nonzero(f >= 0.5) * cell),
        "pd>0": float(np.count_nonzero(f > 0.0) * cell),
        "pd=0": float(np.count_nonzero(f <= 0.0) * cell),
    }
