"""Sensitivity of the paper's Table IV to the calibrated parameters (issue #16).

Seven global values of the presets were tuned so that the far field reproduces Ponn et al.
2019, Table IV (docs/models.md, "Calibrated values"). Each is set here to the two ends of
its plausible range, one at a time, everything else as shipped, and the four far-field
profiles (System A / B, normal / glare from the front right) are recomputed: the table gives
the largest change of any Table IV cell and which cell. The near field (blind-spot areas,
Fig. 5) is a field-of-view property that none of these values enters; ``nearfield_change``
checks that on a coarse grid instead of assuming it.

A parameter is changed only on the devices (or ROC curves) whose source note marks it
``calibrated``; the camera's noise bandwidth follows its exposure (``B_n = 1 / t_int``, as
its source note says).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from sensorgap.config.vehicle import DeviceConfig, RocConfig, VehicleConfig
from sensorgap.models import System
from sensorgap.models.system import build_system


@dataclass(frozen=True)
class Knob:
    """One calibrated parameter: where it lives, its shipped value and plausible range.

    Attributes:
        label: name for tables. field: the device field, or ``roc.floor_db`` (the
        vehicle's default ROC: radar and ultrasonic) / ``roc.half_width_db`` (devices with
        their own smoothstep ROC: camera and lidar). device_type: devices of this type
        (device fields). low, high: the plausible range, in ``unit``. shipped: the
        calibrated value. coupled: other fields set from the value (name -> function).
        estimate: an uncalibrated estimate of the built-in model (the glare constants),
        varied on every device of ``device_type`` whatever its source note says.
    """

    label: str
    field: str
    device_type: str | None
    shipped: float
    low: float
    high: float
    unit: str
    coupled: tuple[tuple[str, Callable[[float], float]], ...] = ()
    estimate: bool = False


#: The calibrated values and their plausible ranges (docs/models.md, source notes).
KNOBS: tuple[Knob, ...] = (
    Knob("radar noise bandwidth", "noise_bandwidth_hz", "radar", 600e3, 200e3, 1e6, "Hz"),
    Knob("lidar receiver aperture", "receiver_diameter_m", "lidar", 0.010, 0.010, 0.025, "m"),
    Knob("lidar optics loss", "system_loss_db", "lidar", 3.5, 2.0, 5.0, "dB"),
    Knob(
        "camera exposure",
        "integration_time_s",
        "camera",
        2e-4,
        1e-5,
        1e-2,
        "s",
        (("noise_bandwidth_hz", lambda t: 1.0 / t),),
    ),
    Knob("camera/lidar ROC half width", "roc.half_width_db", None, 12.0, 3.0, 15.0, "dB"),
    Knob("radar/ultrasonic detection floor", "roc.floor_db", None, 7.5, 0.0, 10.0, "dB"),
    Knob(
        "System B radar antenna gains", "tx_gain_dbi+rx_gain_dbi", "radar", 22.0, 20.0, 30.0, "dBi"
    ),
)


#: The camera's veiling-glare estimates (docs/models.md "Direct sun") and their plausible
#: ranges: not calibrated, so not in the paper's sensitivity table (its glare columns use
#: the paper's glare), but a finding should survive them (the report's confidence section).
GLARE_ESTIMATES: tuple[Knob, ...] = (
    Knob("veiling glare constant", "veiling_glare_k", "camera", 10.0, 3.0, 30.0, "", estimate=True),
    Knob(
        "veil contrast noise", "veil_contrast_noise", "camera", 0.25, 0.05, 0.5, "", estimate=True
    ),
    Knob("veil summation", "veil_summation_px", "camera", 2500.0, 100.0, 1e4, "px", estimate=True),
)


def _calibrated(dev: DeviceConfig, field: str) -> bool:
    return dev.sources.get(field, "").strip().lower().startswith("calibrated")


def vary(cfg: VehicleConfig, knob: Knob, value: float) -> tuple[VehicleConfig, int]:
    """``cfg`` with ``knob`` set to ``value`` where the presets calibrated it; returns the
    new config and how many places changed (0: this vehicle does not use the knob)."""
    if knob.field == "roc.floor_db":
        # the vehicle's default ROC, used by every device without its own [roc]
        if cfg.roc.kind != "paper" or all(d.roc is not None for d in cfg.devices.values()):
            return cfg, 0
        roc = RocConfig.model_validate({**cfg.roc.model_dump(), "floor_db": value})
        return cfg.model_copy(update={"roc": roc}), 1
    devices: dict[str, DeviceConfig] = {}
    changed = 0
    for name, dev in cfg.devices.items():
        data: dict[str, Any] = dev.model_dump()
        if knob.field == "roc.half_width_db":
            if (
                dev.roc is not None
                and dev.roc.kind == "smoothstep"
                and dev.type in ("camera", "lidar")
            ):
                data["roc"] = {**dev.roc.model_dump(), "half_width_db": value}
                changed += 1
        elif dev.type == knob.device_type:
            fields = knob.field.split("+")
            if knob.estimate or all(_calibrated(dev, f) for f in fields):
                for f in fields:
                    data[f] = float(value)
                    if knob.estimate and not str(dev.sources.get(f, "")).strip():
                        data["sources"] = {
                            **data.get("sources", {}),
                            f: f"estimate: varied over its plausible range ({knob.label})",
                        }
                for f, fn in knob.coupled:
                    data[f] = float(fn(value))
                changed += 1
        devices[name] = DeviceConfig.model_validate(data) if data != dev.model_dump() else dev
    if not changed:
        return cfg, 0
    return cfg.model_copy(update={"devices": devices}), changed


def varied_system(system: System, knob: Knob, value: float) -> System | None:
    """The system rebuilt with ``knob`` at ``value`` (None: the knob is not used)."""
    cfg, changed = vary(system.config, knob, value)
    return None if not changed else build_system(cfg, system.source)


def with_camera_fields(system: System, fields: dict[str, float]) -> System:
    """The system rebuilt with ``fields`` (name -> value) set on every camera device (e.g.
    the paper's whole-image glare, ``analysis.paper.WHOLE_IMAGE_GLARE``)."""
    cfg = system.config
    values = {k: float(v) for k, v in fields.items()}
    devices = {
        name: (
            DeviceConfig.model_validate({**dev.model_dump(), **values})
            if dev.type == "camera"
            else dev
        )
        for name, dev in cfg.devices.items()
    }
    return build_system(cfg.model_copy(update={"devices": devices}), system.source)
