"""Report figures: a ranked scenario over the coverage map with the target's body,
occluders and the sun at the named step; Pd, P(confirmed) and TTC over time."""

from __future__ import annotations

import math
from pathlib import Path

from sensorgap.runtime import pristine_matplotlib

pristine_matplotlib()  # Agg and matplotlib's defaults, whatever the user's rc files say
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

from sensorgap.coverage.figurememo import drawn_system, save_drawn  # noqa: E402
from sensorgap.coverage.plot import (  # noqa: E402
    PD_CMAP,
    PD_NORM,
    draw_map_window,
    draw_vehicle,
    plain_text,
    save_figure,
)
from sensorgap.export.spec import ScenarioSpec  # noqa: E402
from sensorgap.report.summary import direction_words, sun_azimuth_deg  # noqa: E402
from sensorgap.search.evaluate import Evaluator, Trace  # noqa: E402
from sensorgap.search.outcome import first_confirmation  # noqa: E402
from sensorgap.search.ranking import named_step  # noqa: E402

#: A scene longer than this many times its width is drawn with the map over the whole
#: width above the curves (else side by side).
WIDE_SCENE = 2.5


#: Margins of a scenario figure (inches): left of the axes (tick labels and the y label),
#: below them (tick labels, x label and the legends under the axes).
_LEFT, _BOTTOM = 0.8, 1.05


def _fixed_axes(
    size: tuple[float, float],
    map_box: tuple[float, float, float, float],
    time_box: tuple[float, float, float, float],
) -> tuple[plt.Figure, plt.Axes, plt.Axes]:
    """A figure of ``size`` (w, h, inches) with the map and the time axes at fixed places
    (left, bottom, width, height, inches): a fixed layout, not matplotlib's constrained
    one, which measures every text of the figure in an extra draw at each save (a report
    of 8 scenario figures: 8.9 s -> 7.2 s, 2-core machine, 2026-11-27). The margins fit
    the widest tick labels and three legend rows (tests/report/test_report.py checks that
    nothing leaves the figure or overlaps)."""
    w, h = size
    fig = plt.figure(figsize=size)
    ax, bx = (fig.add_axes((b[0] / w, b[1] / h, b[2] / w, b[3] / h)) for b in (map_box, time_box))
    return fig, ax, bx


def scenario_trace(spec: ScenarioSpec, evaluator: Evaluator) -> Trace:
    """The scenario evaluated exactly (the report's curves)."""
    return evaluator.trace(spec.scenario, spec.environment, spec.family.duration_s)


def _box(
    ax: plt.Axes, x: float, y: float, psi: float, length: float, width: float, **kw: object
) -> None:
    """A box (centre x, y in m; heading psi in rad) in the ego frame."""
    c, sn = math.cos(psi), math.sin(psi)
    corners = [
        (x + c * u - sn * v, y + sn * u + c * v)
        for u, v in (
            (length / 2, width / 2),
            (-length / 2, width / 2),
            (-length / 2, -width / 2),
            (length / 2, -width / 2),
        )
    ]
    ax.add_patch(Polygon(corners, closed=True, **kw))


def scenario_figure(spec: ScenarioSpec, evaluator: Evaluator, tr: Trace, path: Path) -> Path:
    """Write ``draw_scenario_figure`` as PNG to ``path`` (drawn once per process for the
    same inputs: ``coverage.figurememo``)."""
    maps = evaluator.maps(spec.environment, spec.target)
    key = (
        "scenario_figure",
        maps.total,
        maps.grid,
        tr,
        drawn_system(spec.system),
        spec.target,
        spec.environment,
        spec.environment_name,
        spec.rank,
        spec.family.name,
        evaluator.reaction,
        WIDE_SCENE,
    )
    return save_drawn(key, lambda: draw_scenario_figure(spec, evaluator, tr), path, dpi=100)


def draw_scenario_figure(spec: ScenarioSpec, evaluator: Evaluator, tr: Trace) -> plt.Figure:
    """Left: the target's path in the ego frame over the fused Pd map of a car body in the
    scenario's weather (the search's lookup map: no sun, no occluders), the vehicle and its
    sensors' fields of view; at the step the reason names, the target's body coloured by
    its exact Pd of the confirming sensors, the occluders of the scene, and the sun's
    direction seen from the vehicle. Right: over time, that Pd, P(confirmed by then), the
    path TTC, and the threat onset, t_safe and median confirmation."""
    maps = evaluator.maps(spec.environment, spec.target)
    g = maps.grid
    pd_map = -np.expm1(maps.total.astype(np.float64))
    pad = 15.0
    x0, x1 = min(float(tr.x.min()), -10.0) - pad, max(float(tr.x.max()), 10.0) + pad
    y0, y1 = min(float(tr.y.min()), -6.0) - pad / 2, max(float(tr.y.max()), 6.0) + pad / 2
    x0, x1 = max(x0, g.xmin), min(x1, g.xmax)
    y0, y1 = max(y0, g.ymin), min(y1, g.ymax)
    wide = (x1 - x0) > WIDE_SCENE * (y1 - y0)
    if wide:
        # a long, thin scene (far ahead): at least a quarter of its length across, the map
        # over the whole width above the curves (side by side it was a thin strip)
        need = (x1 - x0) / 4.0
        if y1 - y0 < need:
            c = 0.5 * (y0 + y1)
            y0, y1 = max(c - 0.5 * need, g.ymin), min(c + 0.5 * need, g.ymax)
        map_h = max(1.8, 10.4 * (y1 - y0) / (x1 - x0))
        fig, ax, bx = _fixed_axes(
            (12.0, map_h + 4.4), (_LEFT, 4.1, 10.1, map_h), (_LEFT, _BOTTOM, 10.5, 2.35)
        )
    else:
        fig, ax, bx = _fixed_axes(
            (12.0, 5.4), (_LEFT, _BOTTOM, 5.5, 4.0), (7.75, _BOTTOM, 3.55, 4.0)
        )
    # only the cells in view (the whole map would be resampled by the renderer)
    im = draw_map_window(ax, pd_map, g, (x0, x1, y0, y1))
    draw_vehicle(ax, spec.system)
    k = named_step(tr)
    pdc = tr.pd if tr.pd_confirm is None else tr.pd_confirm
    ax.plot(tr.x, tr.y, color="white", linewidth=2.2, zorder=6)
    ax.plot(tr.x, tr.y, color="crimson", linewidth=1.2, zorder=7, label="target path")
    ax.plot(tr.x[0], tr.y[0], "o", color="crimson", zorder=8, label="start")
    if tr.occluders is not None:
        for m, box in enumerate(tr.occluders[k]):
            _box(
                ax,
                float(box[0]),
                float(box[1]),
                math.atan2(float(box[3]), float(box[2])),
                2.0 * float(box[4]),
                2.0 * float(box[5]),
                facecolor="0.45",
                edgecolor="black",
                linewidth=0.8,
                zorder=8,
                label="occluders at that step" if m == 0 else None,
            )
    psi = 0.0 if tr.psi is None else float(tr.psi[k])
    _box(
        ax,
        float(tr.x[k]),
        float(tr.y[k]),
        psi,
        spec.target.length_m,
        spec.target.width_m,
        facecolor=plt.get_cmap(PD_CMAP)(PD_NORM(float(pdc[k]))),
        edgecolor="black",
        linewidth=1.4,
        zorder=9,
        label=f"target at t = {tr.t[k]:.2f} s (Pd {pdc[k]:.2f})",
    )
    az = sun_azimuth_deg(spec.environment, float(tr.heading[k]))
    if az is not None:
        span = 0.12 * (x1 - x0)
        a = math.radians(az)
        ax.annotate(
            "",
            xy=(
                x0 + 0.14 * (x1 - x0) + span * math.cos(a) * 0.15,
                y1 - 0.2 * (y1 - y0) + span * math.sin(a) * 0.15,
            ),
            xytext=(
                x0 + 0.14 * (x1 - x0) + span * math.cos(a),
                y1 - 0.2 * (y1 - y0) + span * math.sin(a),
            ),
            arrowprops={"arrowstyle": "->", "color": "orange", "lw": 2.0},
            zorder=10,
        )
        ax.text(
            x0 + 0.02 * (x1 - x0),
            y0 + 0.05 * (y1 - y0),
            f"sun: {direction_words(az)}, {spec.environment.sun.elevation_deg:.0f}° high"
            if spec.environment.sun is not None
            else "",
            fontsize=7,
            color="darkorange",
            zorder=10,
        )
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_xlabel("x (ego vehicle frame) [m]")
    ax.set_ylabel("y (ego vehicle frame) [m]")
    fig.legend(
        *ax.get_legend_handles_labels(),
        loc="lower left",
        bbox_to_anchor=(0.0, 0.0),
        ncol=2,
        fontsize=7,
        frameon=False,
    )
    # the colour bar as tall as the map itself (an inset beside it)
    fig.colorbar(im, cax=ax.inset_axes((1.015, 0.0, 0.018, 1.0)), label="$p_d$")
    ax.set_title(
        plain_text(
            f"rank {spec.rank}: {spec.family.name}, {spec.environment_name}; "
            f"map: Pd of a {spec.target.name} body there, no sun, "
            "no occluders"
        ),
        fontsize=9,
    )
    r = evaluator.reaction
    f = first_confirmation(pdc[None, :], np.array([len(pdc)]), r.confirm_m, r.confirm_n)[0]
    bx.plot(tr.t, pdc, color="tab:blue", label="$p_d$ of the confirming sensors")
    bx.plot(
        tr.t,
        np.cumsum(f[: len(pdc)]),
        color="tab:green",
        label=f"P(confirmed {r.confirm_m} of {r.confirm_n}) by then",
    )
    bx.set_ylim(-0.02, 1.02)
    bx.set_xlabel("time [s]")
    bx.set_ylabel("probability")
    cx = bx.twinx()
    cx.plot(
        tr.t,
        np.minimum(tr.ttc, 10.0),
        color="tab:red",
        linewidth=1.0,
        label="path TTC [s] (cut at 10 s)",
    )
    cx.set_ylabel("time to collision on the path [s]")
    cx.set_ylim(0.0, 10.5)
    for key, colour, text in (
        ("t_threat_s", "0.4", "threat onset"),
        ("t_safe_s", "black", "t_safe"),
        ("t_confirm_median_s", "tab:green", "median confirmation"),
    ):
        v = tr.extra.get(key)
        if v is not None and math.isfinite(float(v)):
            bx.axvline(float(v), color=colour, linestyle=":", linewidth=1.0, label=text)
    lines = bx.get_lines() + cx.get_lines()
    fig.legend(
        lines,
        [str(ln.get_label()) for ln in lines],
        loc="lower right",
        bbox_to_anchor=(1.0, 0.0),
        ncol=2,
        fontsize=7,
        frameon=False,
    )
    bx.set_title("detection and confirmation over time (exact)", fontsize=9)
    return fig


def farfield_pair_figure(
    curves: list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
    name_a: str,
    name_b: str,
    path: Path,
) -> Path:
    """The far field of two vehicles (the paper's Figs. 6-7 as curves): per environment,
    the fused Pd of each along the target path against the distance from the ego's front
    bumper (m); ``curves``: (environment, s_a, pd_a, s_b, pd_b), distances in m."""
    n = max(1, len(curves))
    ncols = 2 if n > 1 else 1
    nrows = (n + ncols - 1) // ncols
    fig, axes = plt.subplots(
        nrows,
        ncols,
        figsize=(11.0, 1.9 * nrows + 0.9),
        layout="constrained",
        squeeze=False,
        sharex=True,
        sharey=True,
    )
    for k, ax in enumerate(axes.ravel()):
        if k >= len(curves):
            ax.set_visible(False)
            continue
        env, sa, pa, sb, pb = curves[k]
        ax.plot(sa, pa, color="tab:blue", linewidth=1.4, label=f"{name_a} (A)")
        ax.plot(sb, pb, color="tab:red", linewidth=1.2, linestyle="--", label=f"{name_b} (B)")
        for level in (0.5, 0.8):
            ax.axhline(level, color="grey", linewidth=0.5, linestyle=":")
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(plain_text(env), fontsize=9)
        ax.tick_params(labelsize=8)
        if k % ncols == 0:
            ax.set_ylabel("fused $p_d$", fontsize=8)
        if k >= len(curves) - ncols:
            ax.tick_params(labelbottom=True)
            ax.set_xlabel(
                "distance along the target lane from the ego's front bumper [m]", fontsize=8
            )
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(
        handles,
        [plain_text(t) for t in labels],
        loc="outside lower center",
        ncol=2,
        fontsize=8,
        frameon=False,
    )
    return save_figure(fig, path, dpi=90)
