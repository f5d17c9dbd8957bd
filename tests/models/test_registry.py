"""A user adds a sensor type without editing sensorgap; sensor order does not matter;
FOV 0 / 360 deg sensors evaluate finitely."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from pydantic import Field

from sensorgap.config import load_target
from sensorgap.config.common import Strict
from sensorgap.config.target import TargetConfig
from sensorgap.coverage import Scene, evaluate_points
from sensorgap.models import (
    Conditions,
    PreparedSensor,
    SensorModel,
    load_system,
    register,
    registry,
)
from sensorgap.models.conditions import Band
from sensorgap.models.geometry import Mount
from tests.conftest import make_scene


class IdealParams(Strict):
    snr_db: float = Field(ge=-100, le=100)


class Ideal(SensorModel):
    """An ideal sensor: constant SNR inside its field of view."""

    type_name = "ideal_test"
    Params = IdealParams
    params: IdealParams

    def band(self) -> Band:
        return Band("radio", frequency_hz=77e9)

    def prepare(self, mount: Mount, target: TargetConfig, conditions: Conditions) -> PreparedSensor:
        value = self.params.snr_db
        return PreparedSensor(snr_db=lambda r, az, el: np.full_like(r, value), uses_angles=False)


@pytest.fixture
def ideal() -> Iterator[None]:
    register(Ideal)
    yield
    registry.unregister("ideal_test")


VEHICLE = """
schema_version = 1
[vehicle]
name = "T"
length_m = 4.5
width_m = 1.8
height_m = 1.5
wheelbase_m = 2.7
rear_overhang_m = 0.9
[devices.d]
type = "ideal_test"
snr_db = 30.0
[devices.d.roc]
kind = "smoothstep"
[devices.d.sources]
snr_db = "estimate: test"
{sensors}
"""

SENSOR = """
[[sensors]]
id = "{id}"
device = "d"
position_m = [1.0, 0.0, 0.5]
yaw_deg = {yaw}
hfov_deg = {hfov}
vfov_deg = {vfov}
max_range_m = 50.0
source = "test"
"""


def write(tmp_path: Path, sensors: list[dict[str, object]]) -> Path:
    body = "".join(SENSOR.format(**s) for s in sensors)
    p = tmp_path / "v.toml"
    p.write_text(VEHICLE.format(sensors=body))
    return p


def test_user_sensor_type_without_core_edits(tmp_path: Path, ideal: None) -> None:
    p = write(
        tmp_path,
        [
            {"id": "all", "yaw": 0, "hfov": 360, "vfov": 180},
            {"id": "none", "yaw": 0, "hfov": 1e-9, "vfov": 1e-9},
        ],
    )
    system = load_system(p)
    scene = Scene(
        system, load_target("car"), Conditions.from_config(make_scene(system).conditions.env)
    )
    pts = np.array([[10.0, 5.0, 0.5], [-20.0, -3.0, 2.0], [30.0, 0.0, 0.5], [1.0, 0.0, 0.5]])
    cov = evaluate_points(scene, pts)
    assert cov.pd[0].tolist() == [1.0, 1.0, 1.0, 0.0]  # r = 0 is never in view
    # a pencil beam (FOV 1e-9 deg; 0 is refused: tests/bad_inputs) sees only its boresight
    assert cov.pd[1].tolist() == [0.0, 0.0, 1.0, 0.0]
    assert np.all(np.isfinite(cov.snr_db))


def test_vehicle_of_user_types_only_loads_but_cannot_brake(tmp_path: Path, ideal: None) -> None:
    """No reaction model can name a user type (``confirm_with`` takes the built-in types):
    a vehicle of user types only loads (its coverage above), and where it would brake (the
    search's ``Evaluator``) it is refused in one line naming the file and ``reaction``."""
    from sensorgap.errors import InputError
    from sensorgap.search.evaluate import Evaluator

    p = write(tmp_path, [{"id": "a", "yaw": 0, "hfov": 90, "vfov": 30}])
    system = load_system(p)
    with pytest.raises(InputError) as info:
        Evaluator(system, "exact")
    assert info.value.line() == (
        f"{p}: reaction: reaction model ads_default confirms with camera/lidar, and this "
        "vehicle has no such sensor (it has ideal_test): it could never brake for a detection"
    )


def test_unknown_type_lists_registered(tmp_path: Path) -> None:
    p = write(tmp_path, [{"id": "a", "yaw": 0, "hfov": 90, "vfov": 30}])
    from sensorgap.errors import InputError

    with pytest.raises(InputError, match="unknown sensor type 'ideal_test'; allowed: camera"):
        load_system(p)


def test_yaw_wrap_in_files(tmp_path: Path, ideal: None) -> None:
    a = load_system(write(tmp_path, [{"id": "a", "yaw": 180, "hfov": 90, "vfov": 30}]))
    b = load_system(write(tmp_path, [{"id": "a", "yaw": -180, "hfov": 90, "vfov": 30}]))
    assert math.isclose(
        a.sensors[0].mount.yaw, b.sensors[0].mount.yaw, abs_tol=1e-15
    ) or math.isclose(abs(a.sensors[0].mount.yaw), math.pi)
    pts = np.array([[-10.0, 0.0, 0.5], [-10.0, 8.0, 0.5], [10.0, 0.0, 0.5]])
    ca = evaluate_points(make_scene(a), pts)
    cb = evaluate_points(make_scene(b), pts)
    np.testing.assert_array_equal(ca.pd, cb.pd)
    assert ca.pd[0].tolist() == [1.0, 1.0, 0.0]


def test_fused_invariant_to_sensor_order(tmp_path: Path) -> None:
    system = load_system("system_a")
    text = system.source.read_text()
    head, *blocks = text.split("[[sensors]]")
    p = tmp_path / "rev.toml"
    p.write_text(
        head
        + "".join(
            "[[sensors]]" + b if b.endswith("\n") else "[[sensors]]" + b + "\n"
            for b in reversed(blocks)
        )
    )
    rev = load_system(p)
    assert [s.id for s in rev.sensors] == [s.id for s in reversed(system.sensors)]
    rng = np.random.default_rng(11)
    pts = np.column_stack(
        [rng.uniform(-60, 200, 2000), rng.uniform(-30, 30, 2000), np.full(2000, 0.75)]
    )
    f1 = evaluate_points(make_scene(system, "pedestrian", "rain_25"), pts).fused
    f2 = evaluate_points(make_scene(rev, "pedestrian", "rain_25"), pts).fused
    np.testing.assert_allclose(f1, f2, rtol=0, atol=1e-15)
