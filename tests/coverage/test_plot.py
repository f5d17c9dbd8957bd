"""Coverage figures (issue #14 item 6): a colour bar as high as the map, the fields of view
named in a legend that covers nothing, the sun's direction in words and as an arrow, a
near-field close-up; the A-vs-B difference figure."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.figure import Figure

from sensorgap.config import load_environment, load_target
from sensorgap.coverage import GridSpec, Scene
from sensorgap.coverage.grid import GridCoverage
from sensorgap.coverage.plot import comparison_figure, coverage_figure, sun_words
from sensorgap.models import Conditions, load_system


def _drawn(fig: Figure) -> None:
    fig.canvas.draw()


def _legend_texts(fig: Figure) -> list[str]:
    return [t.get_text() for lg in fig.legends for t in lg.get_texts()]


@pytest.fixture(scope="module")
def cov() -> GridCoverage:
    g = GridSpec(-40.0, 120.0, -30.0, 30.0, 1.0, 0.75)
    xs, ys = np.meshgrid(g.xs(), g.ys())
    return GridCoverage(g, np.clip(1.0 - np.hypot(xs, ys) / 100.0, 0.0, 1.0), [])


def test_sun_words() -> None:
    assert sun_words(-20.0, 8.0) == "sun front (20° right of straight ahead), 8° above the horizon"
    assert sun_words(-45.0, 10.0).startswith("sun front-right (45° right")
    assert sun_words(180.0, 60.0) == "sun rear (straight behind), 60° above the horizon"
    assert sun_words(100.0, 5.0).startswith("sun left (100° left of straight ahead)")


def test_coverage_figure_colour_bar_legend_sun_closeup(cov: GridCoverage) -> None:
    system = load_system("system_a")
    cond = Conditions.from_config(load_environment("glare_front_right"))
    fig = coverage_figure(cov, system, "glare", conditions=cond)
    _drawn(fig)
    ax, zx = fig.axes[0], fig.axes[1]
    # the colour bar is an inset of the map exactly as high as the drawn map
    cbar = [c for c in ax.child_axes]
    assert len(cbar) == 1
    h_map = ax.get_window_extent().height
    assert abs(cbar[0].get_window_extent().height - h_map) < 1.0
    texts = _legend_texts(fig)
    for kind in ("camera", "radar", "lidar", "ultrasonic"):
        assert f"{kind} field of view (to its range)" in texts
    # glare_front_right: sun 20 deg right of straight ahead, 8 deg high (vehicle frame)
    assert any(t.startswith("sun front (20° right of straight ahead), 8° above") for t in texts)
    # the legend lies outside every plot: it covers no marker or map
    lg = fig.legends[0].get_window_extent()
    for a in (ax, zx):
        assert not lg.overlaps(a.get_window_extent())
    # the close-up shows the vehicle's near field
    x0, x1 = zx.get_xlim()
    body = system.config.vehicle
    assert x0 < body.x_rear_m and x1 > body.x_front_m and x1 - x0 < 30.0


def test_no_sun_no_arrow(cov: GridCoverage) -> None:
    cond = Conditions.from_config(load_environment("fog_50"))
    assert cond.sun_direction is None
    fig = coverage_figure(cov, load_system("system_a"), "fog", conditions=cond)
    assert not any(t.startswith("sun ") for t in _legend_texts(fig))


def test_comparison_figure(cov: GridCoverage) -> None:
    sa, sb = load_system("system_a"), load_system("system_b")
    pd_b = np.clip(cov.fused - 0.3, 0.0, 1.0)
    fig = comparison_figure(cov.fused, pd_b, cov.grid, sa, sb, "car_clear")
    _drawn(fig)
    mains = fig.axes[0::2]
    assert len(mains) == 3
    # the difference panel: a diverging scale from -1 to 1 with its colour bar
    im = mains[2].get_images()[0]
    assert im.get_cmap().name == "RdBu" and im.norm.vmin == -1.0 and im.norm.vmax == 1.0
    assert np.allclose(im.get_array(), cov.fused - pd_b)
    for a in mains:
        assert len(a.child_axes) == 1
        assert abs(a.child_axes[0].get_window_extent().height - a.get_window_extent().height) < 1.0
    texts = _legend_texts(fig)
    assert "System A: sensor positions (difference map)" in texts
    assert "System B: sensor positions (difference map)" in texts
    # both vehicles' sensors are marked on the difference map
    marks = [ln for ln in mains[2].get_lines() if len(ln.get_xdata()) > 1]
    assert sorted(len(ln.get_xdata()) for ln in marks) == sorted([len(sa.sensors), len(sb.sensors)])


def test_coverage_of_a_scene_draws_its_sun(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from sensorgap.coverage import figurememo, outputs

    seen: list[list[str]] = []

    def spy(*args: Any, **kw: Any) -> Figure:
        fig = coverage_figure(*args, **kw)
        seen.append(_legend_texts(fig))
        return fig

    monkeypatch.setattr(outputs, "coverage_figure", spy)
    figurememo.clear_memo()  # drawn here, not written again from an earlier test's figure
    scene = Scene(
        load_system("system_b"),
        load_target("car"),
        Conditions.from_config(load_environment("glare_front_right")),
    )
    grid = GridSpec(-20.0, 40.0, -15.0, 15.0, 1.0, 0.75)
    outputs.write_coverage(scene, grid, tmp_path / "cov")
    assert (tmp_path / "cov" / "coverage.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(seen) == 1 and any(t.startswith("sun front (20° right") for t in seen[0])
