"""Config loading: presets validate; bad input becomes one InputError line naming the file,
the field and what is allowed."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from sensorgap.config import (
    load_environments,
    load_targets,
    load_vehicle,
    templates_dir,
    vehicle_presets,
)
from sensorgap.errors import InputError
from sensorgap.models import load_system

PRESET_A = templates_dir() / "vehicles" / "system_a.toml"


def test_presets_load_and_reproduce_table_iii() -> None:
    assert {"system_a", "system_b"} <= set(vehicle_presets())
    a, _ = load_vehicle("system_a")
    b, _ = load_vehicle("system_b")
    count = lambda cfg, t: sum(cfg.devices[s.device].type == t for s in cfg.sensors)  # noqa: E731
    assert [count(a, t) for t in ("camera", "radar", "ultrasonic", "lidar")] == [5, 5, 12, 1]
    assert [count(b, t) for t in ("camera", "radar", "ultrasonic", "lidar")] == [8, 1, 12, 0]
    # Table III HFOV / range pairs
    pairs_a = sorted((s.hfov_deg, s.max_range_m) for s in a.sensors)
    for want in [(50, 120), (137, 60), (30, 250), (150, 100), (70, 5.5), (145, 150)]:
        assert want in pairs_a
    pairs_b = sorted((s.hfov_deg, s.max_range_m) for s in b.sensors)
    for want in [
        (35, 250),
        (45, 150),
        (120, 60),
        (90, 80),
        (75, 100),
        (135, 50),
        (35, 160),
        (90, 8),
    ]:
        assert want in pairs_b


def test_every_parameter_has_a_source() -> None:
    for name in ("system_a", "system_b"):
        cfg, _ = load_vehicle(name)
        for dev in cfg.devices.values():
            assert set(dev.params()) <= set(dev.sources)
        assert all(s.source for s in cfg.sensors)
    for t in load_targets().values():
        assert t.sources
    assert len(load_environments()) >= 7


def test_environments_include_required_presets() -> None:
    envs = load_environments()
    assert envs["glare_front_right"].sun is not None
    assert envs["rain_5"].rain_mm_h == 5.0 and envs["rain_25"].rain_mm_h == 25.0
    assert envs["fog_200"].visibility_m == 200.0 and envs["fog_50"].visibility_m == 50.0
    assert envs["snow"].snow_mm_h > 0.0


def mutate(tmp_path: Path, old: str, new: str, count: int = 1) -> Path:
    text = PRESET_A.read_text()
    assert old in text, old
    p = tmp_path / "vehicle.toml"
    p.write_text(text.replace(old, new, count))
    return p


BAD = [
    ("hfov_deg = 50.0", "hfov_deg = 400.0", r"sensors\[0\]\.hfov_deg: .*less than or equal to 360"),
    ("hfov_deg = 50.0", "hfov_deg = nan", r"sensors\[0\]\.hfov_deg"),
    ("max_range_m = 120.0", "max_range_m = inf", r"sensors\[0\]\.max_range_m"),
    (
        "max_range_m = 120.0",
        "max_range_m = -5.0",
        r"sensors\[0\]\.max_range_m: .*greater than or equal to 0\.01",
    ),
    (
        "max_range_m = 120.0",
        "max_range_m = 1e308",
        r"sensors\[0\]\.max_range_m: .*less than or equal to 10000",
    ),
    (
        "min_range_m = 0.5\nmax_range_m = 120.0",
        "min_range_m = 200.0\nmax_range_m = 120.0",
        r"sensors\[0\]: min_range_m \(200.0\) must be below max_range_m",
    ),
    (
        'type = "lidar"',
        'type = "sonar"',
        r"devices\.lidar_scanning\.type: unknown sensor type "
        r"'sonar'; allowed: camera, lidar, radar, ultrasonic",
    ),
    (
        "tx_power_dbm = 12.0",
        "tx_power_dbm = -99.0",
        r"devices\.radar_77_lrr\.tx_power_dbm: .*greater than or equal to -30",
    ),
    (
        'peak_power_w = "',
        'peak_power_w_x = "',
        r"devices\.lidar_scanning\.sources\.peak_power_w_x|"
        r"devices\.lidar_scanning\.sources\.peak_power_w: missing source",
    ),
    ('id = "us_front_2"', 'id = "us_front_1"', r"duplicate sensor id 'us_front_1'"),
    ('device = "lidar_scanning"', 'device = "nope"', r"unknown device 'nope'"),
    ("wheelbase_m = 3.0", "wheelbase_m = 3.0\nwheelbase_x = 1", r"vehicle\.wheelbase_x: Extra"),
    ("[roc]", "[roc\n", r"TOML syntax error"),
]


@pytest.mark.parametrize(("old", "new", "pattern"), BAD)
def test_bad_vehicle_files(tmp_path: Path, old: str, new: str, pattern: str) -> None:
    p = mutate(tmp_path, old, new)
    with pytest.raises(InputError) as info:
        load_system(p)
    line = info.value.line()
    assert "\n" not in line
    assert line.startswith(str(p)), line
    assert re.search(pattern, line), line


def test_sensor_mounts_must_sit_on_the_body(tmp_path: Path) -> None:
    """A mount up to 0.5 m outside the body box is accepted (mirrors, roof pods); farther
    out is refused in one line naming the sensor and the distance (by hand: System A's body
    spans x -1.13..4.04 m, |y| <= 0.975 m, z <= 1.47 m)."""
    body = load_system(PRESET_A).config.vehicle
    assert body.outside_by(2.2, 1.05, 1.02) == pytest.approx(0.075, abs=1e-12)  # mirror
    assert body.outside_by(0.0, 0.0, 0.5) == 0.0
    assert body.outside_by(4.04 + 0.3, 0.975 + 0.4, 1.0) == pytest.approx(0.5, abs=1e-12)
    ok = mutate(tmp_path, "position_m = [4.02, 0.00, 0.50]", "position_m = [4.53, 0.00, 0.50]")
    assert load_system(ok).config.vehicle.x_front_m == pytest.approx(4.04)  # 0.49 m: kept
    bad = mutate(tmp_path, "position_m = [4.02, 0.00, 0.50]", "position_m = [4.56, 0.00, 0.50]")
    with pytest.raises(InputError) as info:
        load_system(bad)
    line = info.value.line()
    assert "\n" not in line and line.startswith(str(bad)), line
    assert re.search(r"'radar_front_center' at \(4\.56, 0, 0\.5\) m lies 0\.52 m outside", line)


def test_empty_sensor_list(tmp_path: Path) -> None:
    text = PRESET_A.read_text()
    p = tmp_path / "v.toml"
    p.write_text(text[: text.index("[[sensors]]")])
    with pytest.raises(InputError, match=r"sensors: .*(at least 1|Field required)"):
        load_system(p)


def test_missing_file_and_unknown_preset(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="file not found"):
        load_system(tmp_path / "nope.toml")
    with pytest.raises(InputError, match=r"^vehicle: unknown preset 'system_z'; presets: "):
        load_system("system_z")


ENV_BAD = [
    ("rain_mm_h = -1.0", r"environments\.wet\.rain_mm_h: .*greater than or equal to 0"),
    ("rain_mm_h = nan", r"environments\.wet\.rain_mm_h"),
    ("visibility_m = inf", r"environments\.wet\.visibility_m"),
    ("visibility_m = 0.0", r"environments\.wet\.visibility_m: .*greater than or equal to 1"),
    (
        "sun = { azimuth_deg = 0.0, elevation_deg = 95.0 }",
        r"environments\.wet\.sun\.elevation_deg: .*less than or equal to 90",
    ),
    ("fog = 3", r"environments\.wet\.fog: Extra inputs are not permitted"),
    ('roc_shift_db = "3"', r"environments\.wet\.roc_shift_db: Input should be a valid number"),
]


@pytest.mark.parametrize(("line", "pattern"), ENV_BAD)
def test_bad_environment_files(tmp_path: Path, line: str, pattern: str) -> None:
    p = tmp_path / "env.toml"
    p.write_text(f"[environments.wet]\n{line}\n")
    with pytest.raises(InputError) as info:
        load_environments(p)
    assert info.value.line().startswith(str(p))
    assert re.search(pattern, info.value.line()), info.value.line()


def test_environment_file_must_have_table(tmp_path: Path) -> None:
    p = tmp_path / "env.toml"
    p.write_text("rain = 1\n")
    with pytest.raises(InputError, match=r"environments: expected a non-empty table"):
        load_environments(p)
