"""``sensorgap run --vehicle PATH`` (issue #14): the main job for any vehicle file, into
``OUT/<vehicle>/``, with the vehicle recorded by its absolute path; a copy of System A
without its rear radars gets larger near-field blind spots than System A."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from sensorgap.cli import main
from sensorgap.config.presets import templates_dir


def _without_rear_radars(tmp: Path) -> Path:
    text = (templates_dir() / "vehicles" / "system_a.toml").read_text()
    blocks = re.split(r"(?m)^(?=\[\[sensors\]\])", text)
    kept = [b for b in blocks if not re.search(r'(?m)^id = "radar_rear_', b)]
    assert len(kept) == len(blocks) - 2
    path = tmp / "a_no_rear_radar.toml"
    path.write_text("".join(kept))
    return path


@pytest.mark.slow
def test_run_for_a_vehicle_file(tmp_path: Path, capsys) -> None:
    vehicle = _without_rear_radars(tmp_path)
    out = tmp_path / "out"
    assert (
        main(
            [
                "run",
                "--vehicle",
                str(vehicle),
                "--out",
                str(out),
                "--budget",
                "600",
                "--families",
                "cut_in_left,slow_ahead_curve",
                "--environments",
                "clear,fog_50",
            ]
        )
        == 0
    )
    folder = out / "a_no_rear_radar"
    for name in (
        "coverage/car_clear/coverage.png",
        "coverage/car_fog_50/coverage.png",
        "nearfield/nearfield.json",
        "farfield/clear/farfield.png",
        "ranking.json",
        "report.html",
        "run.json",
        "manifest.json",
    ):
        assert (folder / name).is_file(), name
    assert not (folder / "coverage" / "car_snow").exists()  # only what was asked
    run = json.loads((folder / "run.json").read_text())
    assert str(vehicle.resolve()) in json.dumps(run)
    # without the rear radars, more of the rear is unseen: the unseen area of the car-body
    # map grows against System A's map on the same grid
    ours = json.loads((folder / "coverage" / "car_clear" / "summary.json").read_text())
    g = ours["grid"]
    extent = f"{g['xmin']:g},{g['xmax']:g},{g['ymin']:g},{g['ymax']:g}"
    assert (
        main(
            [
                "coverage",
                "--vehicle",
                "system_a",
                "--environment",
                "clear",
                "--target",
                "car",
                "--extent",
                extent,
                "--resolution",
                f"{g['resolution_m']:g}",
                "--heading",
                "0",
                "--out",
                str(tmp_path / "cov_a"),
            ]
        )
        == 0
    )
    ref = json.loads((tmp_path / "cov_a" / "summary.json").read_text())
    assert ours["area_m2_by_level"]["pd=0"] > ref["area_m2_by_level"]["pd=0"] + 100.0
    assert main(["verify", str(folder)]) == 0


def test_run_refuses_unknown_environment_before_writing(tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["run", "--out", str(out), "--environments", "clear,acid_rain"]) == 2
    err = capsys.readouterr().err
    assert "acid_rain" in err and len(err.strip().splitlines()) == 1
    assert not out.exists() or not any(out.rglob("*"))
