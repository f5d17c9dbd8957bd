"""Property and fuzz tests (hypothesis): config loading and the OpenDRIVE reader let only
the documented error type (``InputError``) escape, whatever the bytes; valid configs give
finite outputs. Derandomized so CI runs the same examples every time."""

from __future__ import annotations

import contextlib
import math
import tomllib
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sensorgap.config import load_environments
from sensorgap.config.load import load_vehicle
from sensorgap.coverage import Scene, evaluate_points
from sensorgap.errors import InputError
from sensorgap.models import Conditions, build_system
from sensorgap.roads import read_opendrive

REPO = Path(__file__).resolve().parents[1]
VEHICLE = (REPO / "templates" / "vehicles" / "system_b.toml").read_text()
ENVS = (REPO / "templates" / "environments.toml").read_text()
ROAD = (REPO / "roads" / "rural_two_lane.xodr").read_bytes()
FUZZ = settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

_scalar = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**12), 10**12),
    st.text(max_size=8),
    st.booleans(),
    st.just([]),
    st.just({}),
)


def _mutate_toml(text: str, data: st.DataObject) -> str:
    """Replace the value of one random `key = value` line with a random scalar."""
    lines = text.splitlines()
    idx = [
        i
        for i, ln in enumerate(lines)
        if "=" in ln and not ln.lstrip().startswith("#") and not ln.lstrip().startswith("[")
    ]
    i = data.draw(st.sampled_from(idx))
    key = lines[i].split("=", 1)[0]
    value = data.draw(_scalar)
    if isinstance(value, float) and not math.isfinite(value):
        lit = "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    elif isinstance(value, bool):
        lit = "true" if value else "false"
    elif isinstance(value, str):
        lit = '"' + value.replace("\\", "").replace('"', "").replace("\n", "") + '"'
    elif isinstance(value, list):
        lit = "[]"
    elif isinstance(value, dict):
        lit = "{}"
    else:
        lit = repr(value)
    lines[i] = f"{key}= {lit}"
    return "\n".join(lines) + "\n"


@FUZZ
@given(data=st.data())
def test_vehicle_loading_only_raises_input_error(tmp_path_factory, data) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path_factory.mktemp("v") / "v.toml"
    path.write_text(_mutate_toml(VEHICLE, data))
    try:
        cfg, p = load_vehicle(path)
        system = build_system(cfg, p)
    except InputError as exc:
        assert exc.line() and "\n" not in exc.line()
        return
    # a mutation that is still valid: the model gives finite, bounded outputs
    env = load_environments()["clear"]
    from sensorgap.config import load_target

    sc = Scene(system, load_target("car"), Conditions.from_config(env))
    pts = np.column_stack([np.linspace(-50, 200, 40), np.linspace(-5, 5, 40), np.full(40, 0.75)])
    cov = evaluate_points(sc, pts)
    assert np.all(np.isfinite(cov.snr_db)) and np.all((cov.fused >= 0) & (cov.fused <= 1))


@FUZZ
@given(data=st.data())
def test_environment_loading_only_raises_input_error(tmp_path_factory, data) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path_factory.mktemp("e") / "e.toml"
    path.write_text(_mutate_toml(ENVS, data))
    try:
        envs = load_environments(path)
    except InputError as exc:
        assert exc.line() and "\n" not in exc.line()
        return
    for env in envs.values():
        c = Conditions.from_config(env)
        from sensorgap.models.conditions import Band

        for band in (Band("optical", wavelength_m=905e-9), Band("radio", frequency_hz=77e9)):
            g = c.attenuation_db_km(band)
            assert math.isfinite(g) and g >= 0.0


@FUZZ
@given(st.binary(max_size=2000))
def test_random_bytes_as_toml(tmp_path_factory, blob: bytes) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path_factory.mktemp("b") / "v.toml"
    path.write_bytes(blob)
    with contextlib.suppress(InputError):
        load_vehicle(path)


@FUZZ
@given(
    st.lists(
        st.tuples(st.integers(0, len(ROAD) - 1), st.binary(min_size=0, max_size=8)),
        min_size=1,
        max_size=6,
    )
)
def test_mutated_opendrive_only_raises_input_error(tmp_path_factory, edits) -> None:  # type: ignore[no-untyped-def]
    data = bytearray(ROAD)
    for pos, chunk in edits:
        data[pos : pos + len(chunk)] = chunk
    path = tmp_path_factory.mktemp("r") / "road.xodr"
    path.write_bytes(bytes(data))
    try:
        net = read_opendrive(path)
    except InputError as exc:
        assert exc.line() and "\n" not in exc.line()
        return
    for rid in list(net.roads)[:3]:
        s = np.linspace(0.0, net.road(rid).length, 20)
        x, y, h = net.reference_line(rid, s)
        assert np.all(np.isfinite(x)) and np.all(np.isfinite(y)) and np.all(np.isfinite(h))


@FUZZ
@given(st.text(max_size=400))
def test_random_text_as_opendrive(tmp_path_factory, text: str) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path_factory.mktemp("t") / "road.xodr"
    path.write_text("<?xml version='1.0'?><OpenDRIVE>" + text)
    with contextlib.suppress(InputError):
        read_opendrive(path)


def test_mutation_helper_produces_toml() -> None:
    assert tomllib.loads(VEHICLE)["vehicle"]["name"] == "System B"
