"""Calibrated parameters varied one at a time (``analysis.sensitivity``): only where the
presets calibrated them, with the couplings their source notes state; at the shipped value
nothing changes."""

from __future__ import annotations

import pytest

from sensorgap.analysis.paper import FarFieldSetup, run_farfield
from sensorgap.analysis.sensitivity import KNOBS, Knob, varied_system, vary
from sensorgap.config.presets import resolve_road
from sensorgap.models import load_system
from sensorgap.roads import read_opendrive


def _knob(label: str) -> Knob:
    return next(k for k in KNOBS if k.label == label)


def test_vary_touches_only_calibrated_devices() -> None:
    a, b = load_system("system_a"), load_system("system_b")
    # B's radar gains are calibrated, A's are estimates: the knob leaves A alone
    assert vary(a.config, _knob("System B radar antenna gains"), 30.0)[1] == 0
    cfg, n = vary(b.config, _knob("System B radar antenna gains"), 30.0)
    assert n >= 1
    radars = [
        d
        for d in cfg.devices.values()
        if d.type == "radar" and d.sources.get("tx_gain_dbi", "").startswith("calibrated")
    ]
    assert radars and all(
        d.params()["tx_gain_dbi"] == 30.0 == d.params()["rx_gain_dbi"] for d in radars
    )
    # camera exposure carries its noise bandwidth along: B_n = 1 / t_int
    cfg, n = vary(a.config, _knob("camera exposure"), 1e-3)
    cams = [
        d
        for d in cfg.devices.values()
        if d.type == "camera" and d.sources.get("integration_time_s", "").startswith("calibrated")
    ]
    assert n == len(cams) >= 1
    for d in cams:
        assert d.params()["integration_time_s"] == 1e-3
        assert d.params()["noise_bandwidth_hz"] == pytest.approx(1e3, rel=1e-12)
    # the vehicle's ROC floor (radar, ultrasonic); the camera/lidar smoothstep half width
    cfg, _ = vary(a.config, _knob("radar/ultrasonic detection floor"), 0.0)
    assert cfg.roc.floor_db == 0.0 and a.config.roc.floor_db == 7.5
    # ... used only by devices without their own [roc]: when every device has one, the
    # knob does not apply (hostile round seventeen: it was counted as two variants that
    # changed nothing)
    own = a.config.model_copy(
        update={
            "devices": {
                n: d.model_copy(update={"roc": d.roc or a.config.roc})
                for n, d in a.config.devices.items()
            }
        }
    )
    assert vary(own, _knob("radar/ultrasonic detection floor"), 0.0)[1] == 0
    cfg, n = vary(a.config, _knob("camera/lidar ROC half width"), 6.0)
    assert n >= 1 and all(
        d.roc is None or d.roc.half_width_db == 6.0
        for d in cfg.devices.values()
        if d.type in ("camera", "lidar")
    )


@pytest.mark.parametrize("label", [k.label for k in KNOBS])
def test_shipped_value_changes_nothing(label: str) -> None:
    # Each knob at its shipped value rebuilds the same far field (System A and B, clear):
    # the knob table and the presets agree.
    setup = FarFieldSetup()
    net = read_opendrive(resolve_road(setup.road))
    knob = _knob(label)
    for name in ("system_a", "system_b"):
        system = load_system(name)
        varied = varied_system(system, knob, knob.shipped)
        if varied is None:
            continue
        base = run_farfield(system, "clear", setup, net)[1].levels_m
        again = run_farfield(varied, "clear", setup, net)[1].levels_m
        assert again == pytest.approx(base, abs=1e-9)
