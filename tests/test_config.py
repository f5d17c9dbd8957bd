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


def _only_sensors(tmp_path: Path, device_prefix: str, reaction: str) -> Path:
    """System A's file with only the mounts whose device starts with ``device_prefix`` and
    ``reaction = <reaction>``."""
    head, *mounts = PRESET_A.read_text().split("[[sensors]]\n")
    keep = [m for m in mounts if f'device = "{device_prefix}' in m]
    assert keep and len(keep) < len(mounts)
    head = head.replace('reaction = "fusion_any"', f'reaction = "{reaction}"')
    assert f'reaction = "{reaction}"' in head
    p = tmp_path / f"{device_prefix}_{reaction}.toml"
    p.write_text(head + "".join("[[sensors]]\n" + m for m in keep))
    return p


def test_vehicle_without_a_sensor_that_can_confirm_is_refused(tmp_path: Path) -> None:
    """A vehicle none of whose sensors its reaction model confirms with could never brake:
    refused at load, naming the file and ``reaction`` (System A's radars under ads_default,
    camera/lidar only); a moving-only type (camera_confirmed's radar) counts as a way to
    confirm; a run folder's recorded copy (``check_reaction=False``) is not checked here."""
    radar_ads = _only_sensors(tmp_path, "radar", "ads_default")
    with pytest.raises(InputError) as info:
        load_system(radar_ads)
    assert info.value.line() == (
        f"{radar_ads}: reaction: reaction model ads_default confirms with camera/lidar, and "
        "this vehicle has no such sensor (it has radar): it could never brake for a detection"
    )
    assert load_system(radar_ads, check_reaction=False).config.reaction == "ads_default"
    radar_b = _only_sensors(tmp_path, "radar", "camera_confirmed")  # radar: moving targets
    assert {s.type_name for s in load_system(radar_b).sensors} == {"radar"}
    assert load_system(_only_sensors(tmp_path, "radar", "fusion_any")).sensors
    us_b = _only_sensors(tmp_path, "ultrasonic", "camera_confirmed")
    want = (
        "reaction: reaction model camera_confirmed confirms with camera/lidar (and radar for "
        "targets moving at >= 5 m/s), and this vehicle has no such sensor (it has ultrasonic)"
    )
    with pytest.raises(InputError, match=re.escape(want)):
        load_system(us_b)


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
    # the ROC shift's range (an estimate, docs/limits.md): -100 gave a radar Pd of 1.0 at
    # -7.6 dB SNR
    ("roc_shift_db = -10.5", r"environments\.wet\.roc_shift_db: .*greater than or equal to -10"),
    ("roc_shift_db = 30.5", r"environments\.wet\.roc_shift_db: .*less than or equal to 30"),
    # a misspelt sources key was accepted (a vehicle's and a reaction model's are refused)
    (
        'sources = { visibilty_m = "typo" }',
        r"environments\.wet\.sources\.visibilty_m: source for an unknown parameter; "
        r"allowed: azimuth_deg, .*, visibility_m, visible, water_vapour_g_m3$",
    ),
]


def test_environment_sources_name_its_fields_and_its_suns(tmp_path: Path) -> None:
    p = tmp_path / "env.toml"
    p.write_text(
        "[environments.wet]\nvisibility_m = 900.0\n[environments.wet.sources]\n"
        'visibility_m = "a"\nsun = "b"\ndirect_irradiance_w_m2 = "c"\n'
    )
    known = {"visibility_m", "sun", "direct_irradiance_w_m2"}
    assert set(load_environments(p)["wet"].sources) == known


def test_target_sources_name_its_fields(tmp_path: Path) -> None:
    # a misspelt key of a target's sources was accepted (a vehicle's, an environment's
    # are refused): now one line naming the file, the key and the fields allowed
    text = (templates_dir() / "targets.toml").read_text(encoding="utf-8")
    p = tmp_path / "targets.toml"
    p.write_text(text)
    assert "rcs_m2" in load_targets(p)["car"].sources
    p.write_text(
        text.replace("[targets.car.sources]\n", '[targets.car.sources]\nrcs_m3 = "typo"\n')
    )
    with pytest.raises(InputError) as exc:
        load_targets(p)
    assert exc.value.line() == (
        f"{p}: targets.car.sources.rcs_m3: source for an unknown parameter; allowed: "
        "camera_cross_section_m2, camera_reflectance, description, height_m, length_m, "
        "lidar_reflectance, max_speed_m_s, name, rcs_m2, reference_height_m, width_m"
    )


@pytest.mark.parametrize("shift", [-10.0, 0.0, 30.0])
def test_roc_shift_range_bounds_are_accepted(tmp_path: Path, shift: float) -> None:
    p = tmp_path / "env.toml"
    p.write_text(f"[environments.wet]\nroc_shift_db = {shift}\n")
    assert load_environments(p)["wet"].roc_shift_db == shift
    assert all(-10.0 <= e.roc_shift_db <= 30.0 for e in load_environments().values())


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


def test_a_family_description_is_one_line(tmp_path: Path) -> None:
    """Hostile round 42, F4: a description with line breaks (a TOML multi-line string)
    reached report.md raw, and a line of it such as ``# Injected heading`` became a heading
    of the report. A description is one line: its line breaks and runs of white space are
    single spaces."""
    from sensorgap.config.presets import templates_dir
    from sensorgap.scenarios import load_family

    text = (templates_dir() / "scenarios" / "slow_ahead_curve.toml").read_text(encoding="utf-8")
    edited = re.sub(
        r"^description = .*$",
        'description = """Slow car\\n# Injected heading\\n| a |\\tb |"""',
        text,
        count=1,
        flags=re.M,
    )
    assert edited != text
    path = tmp_path / "sac.toml"
    path.write_text(edited, encoding="utf-8")
    assert load_family(str(path)).description == "Slow car # Injected heading | a | b |"
