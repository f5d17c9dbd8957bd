"""Figures drawn once per process for the same inputs (``coverage.figurememo``): the same
inputs write the same bytes without drawing again; any change of a drawn value draws."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.figure import Figure

from sensorgap.config import load_environment, load_target
from sensorgap.coverage import GridSpec, Scene, figurememo
from sensorgap.coverage.occluders import Occluder
from sensorgap.coverage.plot import save_figure
from sensorgap.models import Conditions, load_system


def _figure(values: np.ndarray) -> Figure:
    fig = Figure(figsize=(2.0, 1.5))
    fig.add_subplot().plot(values)
    return fig


def test_same_inputs_write_the_same_bytes_drawn_once(tmp_path: Path) -> None:
    figurememo.clear_memo()
    drawn: list[int] = []

    def draw(values: np.ndarray) -> Figure:
        drawn.append(1)
        return _figure(values)

    a = np.array([0.0, 1.0, 0.5])
    figurememo.save_drawn(("t", a), lambda: draw(a), tmp_path / "1.png", dpi=50)
    figurememo.save_drawn(("t", a.copy()), lambda: draw(a), tmp_path / "2.png", dpi=50)
    assert len(drawn) == 1
    save_figure(_figure(a), tmp_path / "direct.png", dpi=50)
    first = (tmp_path / "1.png").read_bytes()
    assert first[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "2.png").read_bytes() == first == (tmp_path / "direct.png").read_bytes()
    # one value one ulp away, another dpi, another kind: drawn again
    b = a.copy()
    b[2] = np.nextafter(b[2], 1.0)
    figurememo.save_drawn(("t", b), lambda: draw(b), tmp_path / "3.png", dpi=50)
    figurememo.save_drawn(("t", a), lambda: draw(a), tmp_path / "4.png", dpi=51)
    figurememo.save_drawn(("u", a), lambda: draw(a), tmp_path / "5.png", dpi=50)
    assert len(drawn) == 4
    assert not list(tmp_path.glob(".*"))  # no temporary file left


def test_the_digest_tells_apart_what_a_drawing_could_read() -> None:
    d = figurememo.digest
    assert d(0.0) != d(-0.0) and d(1) != d(1.0) != d("1") and d(True) != d(1)
    x = np.arange(6.0)
    assert d(x.reshape(2, 3)) != d(x.reshape(3, 2)) != d(x.astype(np.float32))
    y = x.reshape(3, 2).T  # a view, not contiguous: the values count, not the layout
    assert d(y) == d(np.ascontiguousarray(y)) != d(x.reshape(2, 3))
    assert d((1, 2)) != d([1, 2]) and d(((1,), 2)) != d((1, (2,)))
    assert d({"a": 1}) != d({"a": 2})
    # something it cannot describe: no digest, so no memo
    assert d(object()) is None and d(np.array([object()])) is None


def test_every_input_of_the_callers_has_a_digest() -> None:
    """The vehicles, scenes, grids and occluders the writers pass have digests (else
    they would draw every time), and a cache inside ``Conditions`` is not one of them."""
    system = load_system("system_a")
    env = load_environment("glare_front_right")
    cond = Conditions.from_config(env, 0.0)
    grid = GridSpec(-20.0, 40.0, -15.0, 15.0, 1.0, 0.75)
    occ = (Occluder(10.0, 3.5, 0.0, 4.5, 1.8, 1.5, "car"),)
    key: tuple[Any, ...] = (figurememo.drawn_system(system), cond, grid, occ, env)
    before = figurememo.digest(*key)
    assert before is not None
    cond._cache["a band"] = 0.5  # type: ignore[index]  # what the models fill in
    assert figurememo.digest(*key) == before
    moved = Occluder(10.0, 3.5, 0.0, 4.5, 1.8, 1.6, "car")
    assert figurememo.digest(figurememo.drawn_system(system), cond, grid, (moved,), env) != before
    other = load_system("system_b")
    assert figurememo.digest(figurememo.drawn_system(other)) != figurememo.digest(key[0])


def test_at_most_figure_memo_figures_are_kept(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    figurememo.clear_memo()
    monkeypatch.setattr(figurememo, "FIGURE_MEMO", 2)
    for i in range(4):
        a = np.array([float(i), 1.0])
        figurememo.save_drawn(("t", a), lambda a=a: _figure(a), tmp_path / f"{i}.png", dpi=30)
    assert len(figurememo._pngs) == 2
    figurememo.clear_memo()
    assert not figurememo._pngs


def test_a_coverage_map_written_twice_is_drawn_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from sensorgap.coverage import outputs
    from sensorgap.coverage.plot import coverage_figure

    figurememo.clear_memo()
    calls: list[str] = []

    def spy(*args: Any, **kw: Any) -> Figure:
        calls.append(args[2])
        return coverage_figure(*args, **kw)

    monkeypatch.setattr(outputs, "coverage_figure", spy)
    scene = Scene(
        load_system("system_b"),
        load_target("car"),
        Conditions.from_config(load_environment("glare_front_right")),
    )
    grid = GridSpec(-20.0, 40.0, -15.0, 15.0, 1.0, 0.75)
    outputs.write_coverage(scene, grid, tmp_path / "a")
    outputs.write_coverage(scene, grid, tmp_path / "b")
    assert len(calls) == 1
    png = (tmp_path / "a" / "coverage.png").read_bytes()
    assert (tmp_path / "b" / "coverage.png").read_bytes() == png
    figurememo.clear_memo()
    outputs.write_coverage(scene, grid, tmp_path / "c")
    assert len(calls) == 2 and (tmp_path / "c" / "coverage.png").read_bytes() == png


def test_a_reports_scenario_figures_have_digests(tmp_path: Path) -> None:
    """The scenario figure's inputs (the lookup map, the exact trace, the spec's target,
    environment and reaction model) have a digest: a report written again draws none of
    its scenario figures, and writes the same bytes."""
    from sensorgap.cli import main
    from sensorgap.report import figures

    out = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    argv += ["--environments", "snow", "--budget", "30", "--seeds", "1", "--out", str(out)]
    assert main([*argv, "--workers", "1"]) == 0
    figurememo.clear_memo()
    assert main(["report", "--run", str(out)]) == 0
    pngs = sorted((out / "report").glob("scenario_*.png"))
    first = [p.read_bytes() for p in pngs]
    drawn: list[int] = []
    draw = figures.draw_scenario_figure

    def spy(*args: Any) -> Figure:
        drawn.append(1)
        return draw(*args)

    figures.draw_scenario_figure = spy  # type: ignore[assignment]
    try:
        assert main(["report", "--run", str(out)]) == 0
    finally:
        figures.draw_scenario_figure = draw  # type: ignore[assignment]
    assert pngs and drawn == [] and [p.read_bytes() for p in pngs] == first
