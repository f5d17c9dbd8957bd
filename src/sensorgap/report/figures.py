"""Report figures: a ranked scenario over the coverage map, Pd(t) and P_undet(t)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sensorgap.coverage.plot import PD_CMAP, PD_NORM, draw_vehicle, save_figure  # noqa: E402
from sensorgap.export.spec import ScenarioSpec  # noqa: E402
from sensorgap.search.evaluate import Evaluator, Trace  # noqa: E402
from sensorgap.search.metrics import critical_index  # noqa: E402

plt.rcParams["svg.hashsalt"] = "sensorgap"


def scenario_trace(spec: ScenarioSpec, evaluator: Evaluator) -> Trace:
    """The scenario evaluated exactly (the report's curves)."""
    return evaluator.trace(spec.scenario, spec.environment, spec.family.duration_s)


def scenario_figure(spec: ScenarioSpec, evaluator: Evaluator, tr: Trace, path: Path) -> Path:
    """Left: the target's path in the ego frame over the fused Pd map of the scenario's
    weather (no sun; the lookup map of the search), vehicle and sensor fields of view, the
    critical step marked. Right: Pd(t) and P_undet(t) (log scale), TTC on a second axis."""
    maps = evaluator.maps(spec.environment, spec.target)
    g = maps.grid
    pd_map = -np.expm1(maps.total.astype(np.float64))
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12.0, 4.4),
                                 gridspec_kw={"width_ratios": [1.6, 1.0]})
    fig.subplots_adjust(left=0.06, right=0.93, bottom=0.12, top=0.92, wspace=0.35)
    pad = 15.0
    x0, x1 = min(float(tr.x.min()), -10.0) - pad, max(float(tr.x.max()), 10.0) + pad
    y0, y1 = min(float(tr.y.min()), -6.0) - pad / 2, max(float(tr.y.max()), 6.0) + pad / 2
    x0, x1 = max(x0, g.xmin), min(x1, g.xmax)
    y0, y1 = max(y0, g.ymin), min(y1, g.ymax)
    # only the cells in view (the whole map would be resampled by the renderer)
    i0 = max(int(np.floor((x0 - g.xmin) / g.resolution)), 0)
    i1 = min(int(np.ceil((x1 - g.xmin) / g.resolution)), pd_map.shape[1])
    j0 = max(int(np.floor((y0 - g.ymin) / g.resolution)), 0)
    j1 = min(int(np.ceil((y1 - g.ymin) / g.resolution)), pd_map.shape[0])
    im = ax.imshow(pd_map[j0:j1, i0:i1], origin="lower",
                   extent=(g.xmin + i0 * g.resolution, g.xmin + i1 * g.resolution,
                           g.ymin + j0 * g.resolution, g.ymin + j1 * g.resolution),
                   cmap=PD_CMAP, norm=PD_NORM, interpolation="nearest", aspect="equal")
    draw_vehicle(ax, spec.system)
    k = critical_index(tr)
    ax.plot(tr.x, tr.y, color="white", linewidth=2.2, zorder=6)
    ax.plot(tr.x, tr.y, color="crimson", linewidth=1.2, zorder=7, label="target (ego frame)")
    ax.plot(tr.x[0], tr.y[0], "o", color="crimson", zorder=8, label="start")
    ax.plot(tr.x[k], tr.y[k], "X", color="yellow", markeredgecolor="black", markersize=10,
            zorder=9, label=f"critical step t={tr.t[k]:.2f} s")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_xlabel("x (ego vehicle frame) [m]")
    ax.set_ylabel("y (ego vehicle frame) [m]")
    ax.legend(loc="upper right", fontsize=7)
    fig.colorbar(im, ax=ax, label="detection probability $p_d$ (no sun)", shrink=0.85)
    ax.set_title(f"rank {spec.rank}: {spec.family.name}, {spec.environment_name}",
                 fontsize=9)
    bx.plot(tr.t, tr.pd, color="tab:blue", label="fused $p_d$ per step")
    bx.set_ylim(-0.02, 1.02)
    bx.set_xlabel("time [s]")
    bx.set_ylabel("$p_d$")
    cx = bx.twinx()
    # log10 on a linear axis: P_undet spans hundreds of decades (a log axis would need
    # hundreds of ticks)
    lpu = np.maximum(tr.log_undetected / np.log(10.0), -300.0)
    cx.plot(tr.t, lpu, color="tab:red", label="log10 P(still undetected)")
    cx.set_ylabel("log10 P(still undetected)")
    cx.set_ylim(min(float(lpu.min()) * 1.05 - 0.5, -1.0), 0.5)
    bx.axvline(float(tr.t[k]), color="gray", linestyle=":", linewidth=1.0)
    lines = bx.get_lines()[:1] + cx.get_lines()[:1]
    bx.legend(lines, [str(ln.get_label()) for ln in lines], loc="center right", fontsize=7)
    bx.set_title("detection over time (exact evaluation)", fontsize=9)
    return save_figure(fig, path, dpi=100)
