"""Coverage heat maps: Pd on one fixed colour scale, vehicle outline, sensor fields of view
(named in a legend below the plot), a colour bar as high as the map, the sun's direction
when the environment has one, a near-field close-up; and the A-vs-B difference map."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sensorgap.runtime import pristine_matplotlib

pristine_matplotlib()  # Agg and matplotlib's defaults, whatever the user's rc files say
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.image import AxesImage  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Polygon, Rectangle, Wedge  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from sensorgap.atomic import atomic_write_bytes  # noqa: E402
from sensorgap.coverage.figurememo import png_bytes  # noqa: E402
from sensorgap.coverage.grid import GridCoverage, GridSpec  # noqa: E402
from sensorgap.coverage.occluders import Occluder  # noqa: E402
from sensorgap.models.conditions import Conditions  # noqa: E402
from sensorgap.models.system import System  # noqa: E402

#: One colour scale for Pd in every figure sensorgap draws.
PD_CMAP = "viridis"
PD_NORM = Normalize(vmin=0.0, vmax=1.0)

#: Near-field close-up beside a map: the vehicle's footprint grown by this, m.
CLOSEUP_MARGIN_M = 8.0

_TYPE_COLOURS = {
    "camera": "tab:orange",
    "radar": "tab:red",
    "lidar": "tab:cyan",
    "ultrasonic": "tab:pink",
}


def sensor_colour(type_name: str) -> str:
    """The colour every figure draws a sensor type in (grey for a plug-in type)."""
    return _TYPE_COLOURS.get(type_name, "tab:gray")


def draw_map(
    ax: plt.Axes,
    data: NDArray[np.float64],
    extent: tuple[float, float, float, float],
    cmap: Any = PD_CMAP,
    norm: Any = PD_NORM,
) -> AxesImage:
    """A map of cells (rows along y, columns along x) drawn cell by cell over ``extent``
    (xmin, xmax, ymin, ymax of the cells' edges, m, vehicle frame) at equal aspect;
    default colours: Pd. Returns the image (for a colour bar)."""
    return ax.imshow(
        data,
        origin="lower",
        extent=extent,
        cmap=cmap,
        norm=norm,
        interpolation="nearest",
        aspect="equal",
    )


def draw_map_window(
    ax: plt.Axes,
    data: NDArray[np.float64],
    g: GridSpec,
    window: tuple[float, float, float, float],
    cmap: Any = PD_CMAP,
    norm: Any = PD_NORM,
) -> AxesImage:
    """``draw_map`` of only the cells of the grid ``g`` that ``window`` (x0, x1, y0, y1,
    m) shows, whole cells (the renderer resamples every cell of an image, also those out
    of view: a close-up drew the whole map, about half the time of a comparison figure)."""
    x0, x1, y0, y1 = window
    r = g.resolution
    i0 = min(max(int(np.floor((x0 - g.xmin) / r)), 0), data.shape[1] - 1)
    i1 = max(min(int(np.ceil((x1 - g.xmin) / r)), data.shape[1]), i0 + 1)
    j0 = min(max(int(np.floor((y0 - g.ymin) / r)), 0), data.shape[0] - 1)
    j1 = max(min(int(np.ceil((y1 - g.ymin) / r)), data.shape[0]), j0 + 1)
    return draw_map(
        ax,
        data[j0:j1, i0:i1],
        (g.xmin + i0 * r, g.xmin + i1 * r, g.ymin + j0 * r, g.ymin + j1 * r),
        cmap,
        norm,
    )


def plain_text(text: str) -> str:
    """User-given text (vehicle, family, environment names) for a matplotlib label: every
    ``$`` escaped, so a name like ``A $x^{$`` is drawn as written, not parsed as math."""
    return text.replace("$", r"\$")


def draw_vehicle(
    ax: plt.Axes, system: System, fov: bool = True, edgecolor: str = "black", linestyle: str = "-"
) -> list[Line2D]:
    """Vehicle footprint and (optionally) each sensor's horizontal field of view (to its
    maximum range); returns one legend handle per sensor type drawn ("radar field of
    view", ...)."""
    body = system.config.vehicle
    ax.add_patch(
        Polygon(
            body.footprint(),
            closed=True,
            facecolor="white",
            edgecolor=edgecolor,
            linewidth=1.0,
            linestyle=linestyle,
            zorder=5,
        )
    )
    if not fov:
        return []
    types: list[str] = []
    for s in system.sensors:
        m = s.mount
        colour = sensor_colour(s.type_name)
        if m.hfov >= 2.0 * math.pi:
            theta1, theta2 = 0.0, 360.0
        else:
            theta1 = math.degrees(m.yaw - 0.5 * m.hfov)
            theta2 = math.degrees(m.yaw + 0.5 * m.hfov)
        ax.add_patch(
            Wedge(
                (m.x, m.y),
                m.max_range,
                theta1,
                theta2,
                fill=False,
                edgecolor=colour,
                linewidth=0.6,
                alpha=0.8,
                zorder=4,
            )
        )
        if s.type_name not in types:
            types.append(s.type_name)
    return [
        Line2D(
            [],
            [],
            color=sensor_colour(t),
            linewidth=1.0,
            label=f"{t} field of view (to its range)",
        )
        for t in types
    ]


def colorbar_beside(fig: Figure, ax: plt.Axes, mappable: Any, label: str) -> Any:
    """A colour bar right of ``ax``, exactly as high as the drawn plot (an inset axes in
    the plot's own coordinates, so it follows the equal-aspect box)."""
    cax = ax.inset_axes((1.015, 0.0, 0.022, 1.0))
    return fig.colorbar(mappable, cax=cax, label=label)


#: Directions seen from the vehicle, 45 deg each, counter-clockwise from straight ahead.
_SUN_SECTORS = (
    "front",
    "front-left",
    "left",
    "rear-left",
    "rear",
    "rear-right",
    "right",
    "front-right",
)


def sun_words(azimuth_deg: float, elevation_deg: float) -> str:
    """Where the sun stands seen from the vehicle, in words: "sun front-right (40° right
    of straight ahead), 10° above the horizon" (vehicle-frame azimuth in deg,
    counter-clockwise from straight ahead; elevation in deg)."""
    a = (azimuth_deg + 180.0) % 360.0 - 180.0
    sector = _SUN_SECTORS[int(math.floor((a % 360.0 + 22.5) / 45.0)) % 8]
    side = "left" if a > 0 else "right"
    exact = (
        "straight ahead"
        if abs(a) < 0.5
        else "straight behind"
        if abs(a) > 179.5
        else f"{abs(a):.0f}° {side} of straight ahead"
    )
    return f"sun {sector} ({exact}), {elevation_deg:.0f}° above the horizon"


def draw_sun(
    ax: plt.Axes, conditions: Conditions | None, centre: tuple[float, float] = (0.0, 0.0)
) -> Line2D | None:
    """An arrow from the sun's vehicle-frame azimuth towards the vehicle (its light), when
    the conditions have a sun that reaches the sensors; returns its legend handle with the
    direction in words (None without a sun)."""
    if conditions is None or conditions.sun_direction is None:
        return None
    dx, dy, dz = conditions.sun_direction
    az = math.degrees(math.atan2(dy, dx))
    el = math.degrees(math.asin(max(-1.0, min(1.0, dz))))
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    cx, cy = centre
    # the longest ray from the centre in the sun's direction that stays inside the plot
    c, s = math.cos(math.radians(az)), math.sin(math.radians(az))
    reach = min(
        (x1 - cx) / c if c > 1e-9 else (x0 - cx) / c if c < -1e-9 else math.inf,
        (y1 - cy) / s if s > 1e-9 else (y0 - cy) / s if s < -1e-9 else math.inf,
    )
    tail, head = 0.9 * reach, 0.45 * reach
    ax.annotate(
        "",
        xy=(cx + head * c, cy + head * s),
        xytext=(cx + tail * c, cy + tail * s),
        arrowprops={"arrowstyle": "-|>", "color": "orange", "lw": 2.2, "mutation_scale": 14},
        zorder=8,
    )
    ax.plot(
        [cx + tail * c],
        [cy + tail * s],
        marker="o",
        markersize=9,
        color="gold",
        markeredgecolor="darkorange",
        zorder=8,
    )
    return Line2D(
        [],
        [],
        color="orange",
        linewidth=2.2,
        marker="o",
        markersize=6,
        markerfacecolor="gold",
        label=sun_words(az, el) + " (arrow: its light)",
    )


def _closeup_limits(
    system: System, g: GridSpec, margin_m: float
) -> tuple[float, float, float, float] | None:
    """The vehicle's footprint grown by ``margin_m`` (m), when the grid contains it."""
    body = system.config.vehicle
    x0, x1 = body.x_rear_m - margin_m, body.x_front_m + margin_m
    y0, y1 = -0.5 * body.width_m - margin_m, 0.5 * body.width_m + margin_m
    if x0 < g.xmin or x1 > g.xmax or y0 < g.ymin or y1 > g.ymax:
        return None
    return x0, x1, y0, y1


def _axes_labels(ax: plt.Axes, y: bool = True) -> None:
    ax.set_xlabel("x (vehicle frame) [m]")
    if y:
        ax.set_ylabel("y (vehicle frame) [m]")


def coverage_figure(
    cov: GridCoverage,
    system: System,
    title: str,
    occluders: Sequence[Occluder] = (),
    conditions: Conditions | None = None,
    closeup_m: float = CLOSEUP_MARGIN_M,
) -> Figure:
    """A heat map of the fused Pd: axes in metres, a colour bar as high as the map, the
    vehicle and its sensors' fields of view (named in the legend), the footprints of
    ``occluders`` (grey, labelled), the sun's direction when ``conditions`` have one, and
    at the right a near-field close-up (the vehicle's footprint grown by ``closeup_m`` m,
    when the map contains it). The legend sits below the plots, never over the map."""
    g = cov.grid
    close = _closeup_limits(system, g, closeup_m)
    aspect = (g.ymax - g.ymin) / (g.xmax - g.xmin)
    if close is not None:
        fig, (ax, zx) = plt.subplots(
            1,
            2,
            figsize=(12.0, max(3.4, min(10.0, 7.8 * aspect + 1.7))),
            layout="constrained",
            width_ratios=(3.4, 1.0),
        )
    else:
        fig, ax = plt.subplots(
            figsize=(10.0, max(3.0, min(10.0, 10.0 * aspect + 1.8))), layout="constrained"
        )
        zx = None
    extent = (g.xmin, g.xmax, g.ymin, g.ymax)
    im = draw_map(ax, cov.fused, extent)
    handles: list[Any] = draw_vehicle(ax, system)
    for i, occ in enumerate(occluders):
        patch = Polygon(
            occ.corners(),
            closed=True,
            facecolor="0.55",
            edgecolor="white",
            linewidth=0.8,
            zorder=5,
            label="occluder (its shadow: low Pd behind it)" if i == 0 else None,
        )
        ax.add_patch(patch)
        if i == 0:
            handles.append(patch)
        ax.annotate(
            plain_text(f"{occ.label} {occ.height:g} m"),
            (occ.x, occ.y),
            color="white",
            fontsize=7,
            ha="center",
            va="center",
            zorder=6,
        )
    ax.set_xlim(g.xmin, g.xmax)
    ax.set_ylim(g.ymin, g.ymax)
    _axes_labels(ax)
    ax.set_title(plain_text(title), fontsize=10)
    sun = draw_sun(ax, conditions)
    if sun is not None:
        handles.append(sun)
    colorbar_beside(fig, ax, im, "detection probability $p_d$")
    if zx is not None and close is not None:
        _closeup(zx, ax, cov.fused, g, system, close)
        handles.append(
            Line2D(
                [],
                [],
                color="white",
                marker="o",
                linestyle="none",
                markeredgecolor="black",
                markersize=5,
                label="sensor position (close-up)",
            )
        )
    fig.legend(
        handles=handles,
        loc="outside lower center",
        ncol=min(4, len(handles)) or 1,
        fontsize=7,
        frameon=False,
    )
    return fig


def _closeup(
    zx: plt.Axes,
    ax: plt.Axes,
    pd: NDArray[np.float64],
    g: GridSpec,
    system: System,
    lim: tuple[float, float, float, float],
    cmap: Any = PD_CMAP,
    norm: Any = PD_NORM,
) -> None:
    """The near field of ``pd`` on ``zx`` (limits ``lim``), its frame marked on ``ax``."""
    x0, x1, y0, y1 = lim
    draw_map_window(zx, pd, g, lim, cmap, norm)
    draw_vehicle(zx, system, fov=False)
    for s in system.sensors:
        zx.plot(
            [s.mount.x],
            [s.mount.y],
            marker="o",
            markersize=3.5,
            color="white",
            markeredgecolor="black",
            markeredgewidth=0.6,
            zorder=7,
        )
    zx.set_xlim(x0, x1)
    zx.set_ylim(y0, y1)
    zx.set_title(f"near field (close-up, {g.resolution:g} m cells)", fontsize=8)
    zx.set_xlabel("x [m]", fontsize=8)
    zx.set_ylabel("y [m]", fontsize=8)
    zx.tick_params(labelsize=7)
    ax.add_patch(
        Rectangle(
            (x0, y0),
            x1 - x0,
            y1 - y0,
            fill=False,
            edgecolor="white",
            linewidth=0.9,
            linestyle="--",
            zorder=7,
        )
    )


#: Diverging colour scale of a difference of two Pd maps (+1: only A detects, blue).
DIFF_CMAP = "RdBu"
DIFF_NORM = Normalize(vmin=-1.0, vmax=1.0)
#: Sensor markers of the two vehicles on a difference map.
_MARKERS = (("^", "black", "white"), ("v", "white", "black"))


def comparison_figure(
    pd_a: NDArray[np.float64],
    pd_b: NDArray[np.float64],
    g: GridSpec,
    system_a: System,
    system_b: System,
    title: str,
    conditions: Conditions | None = None,
    closeup_m: float = CLOSEUP_MARGIN_M,
) -> Figure:
    """Two vehicles' fused Pd maps on one grid and environment, one above the other, and
    their difference Pd_A - Pd_B below on a diverging scale (blue: A detects where B does
    not, red: the reverse), each with a colour bar as high as the map and a near-field
    close-up; the difference map marks both vehicles' sensor positions (A: up triangles,
    B: down triangles) and outlines (B dashed)."""
    close = _closeup_limits(system_a, g, closeup_m)
    close_b = _closeup_limits(system_b, g, closeup_m)
    if close is not None and close_b is not None:
        close = (
            min(close[0], close_b[0]),
            max(close[1], close_b[1]),
            min(close[2], close_b[2]),
            max(close[3], close_b[3]),
        )
    aspect = (g.ymax - g.ymin) / (g.xmax - g.xmin)
    row_h = max(2.0, min(6.0, 7.8 * aspect)) + 0.5
    ncols = 2 if close is not None else 1
    fig, axes = plt.subplots(
        3,
        ncols,
        figsize=(12.0, 3 * row_h + 1.6),
        layout="constrained",
        squeeze=False,
        width_ratios=(3.4, 1.0) if ncols == 2 else None,
    )
    extent = (g.xmin, g.xmax, g.ymin, g.ymax)
    diff = pd_a - pd_b
    rows = (
        (pd_a, system_a, PD_CMAP, PD_NORM, f"{system_a.name} (A)", "detection probability $p_d$"),
        (pd_b, system_b, PD_CMAP, PD_NORM, f"{system_b.name} (B)", "detection probability $p_d$"),
        (
            diff,
            None,
            DIFF_CMAP,
            DIFF_NORM,
            f"difference A - B: blue where {system_a.name} detects and {system_b.name} "
            "does not, red the reverse",
            "$p_d$(A) - $p_d$(B)",
        ),
    )
    handles: list[Any] = []
    sun = None
    for r, (data, system, cmap, norm, head, label) in enumerate(rows):
        ax = axes[r][0]
        im = draw_map(ax, data, extent, cmap, norm)
        if system is not None:
            for h in draw_vehicle(ax, system):
                if h.get_label() not in [x.get_label() for x in handles]:
                    handles.append(h)
        else:
            _both_vehicles(ax, system_a, system_b)
        ax.set_xlim(g.xmin, g.xmax)
        ax.set_ylim(g.ymin, g.ymax)
        _axes_labels(ax)
        ax.set_title(plain_text(head), fontsize=9)
        sun = draw_sun(ax, conditions) or sun
        colorbar_beside(fig, ax, im, label)
        if ncols == 2 and close is not None:
            zx = axes[r][1]
            _closeup(zx, ax, data, g, system_a if system is None else system, close, cmap, norm)
            if system is None:
                _both_vehicles(zx, system_a, system_b, markersize=5.0)
    if sun is not None:
        handles.append(sun)
    for (marker, face, edge), system in zip(_MARKERS, (system_a, system_b), strict=True):
        handles.append(
            Line2D(
                [],
                [],
                marker=marker,
                linestyle="none",
                markerfacecolor=face,
                markeredgecolor=edge,
                markersize=6,
                label=plain_text(f"{system.name}: sensor positions (difference map)"),
            )
        )
    fig.suptitle(plain_text(title), fontsize=10)
    fig.legend(handles=handles, loc="outside lower center", ncol=3, fontsize=7, frameon=False)
    return fig


def _both_vehicles(
    ax: plt.Axes, system_a: System, system_b: System, markersize: float = 4.0
) -> None:
    """Both vehicles' outlines (B dashed) and sensor positions (``_MARKERS``)."""
    for (marker, face, edge), system, style in zip(
        _MARKERS, (system_a, system_b), ("-", "--"), strict=True
    ):
        draw_vehicle(ax, system, fov=False, linestyle=style)
        ax.plot(
            [s.mount.x for s in system.sensors],
            [s.mount.y for s in system.sensors],
            marker=marker,
            linestyle="none",
            markersize=markersize,
            markerfacecolor=face,
            markeredgecolor=edge,
            markeredgewidth=0.6,
            zorder=7,
        )


def save_figure(fig: Figure, path: str | Path, dpi: int = 120) -> Path:
    """Save a figure as PNG atomically, without a timestamp in its metadata; closes it
    (``figurememo.save_drawn``: the same, drawn once per process for the same inputs)."""
    return atomic_write_bytes(path, png_bytes(fig, dpi))


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
