"""A vehicle's sensor system built from its config: mounts, device models, ROCs."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from pydantic import ValidationError

from sensorgap.config.load import (
    load_vehicle,
    no_stray_source,
    require_source,
    validation_to_input_error,
)
from sensorgap.config.vehicle import MountConfig, RocConfig, VehicleConfig
from sensorgap.errors import InputError
from sensorgap.models import registry
from sensorgap.models.base import SensorModel
from sensorgap.models.geometry import Mount


@dataclass(frozen=True)
class Sensor:
    """One mounted sensor: id, pose/FOV (SI), physical model and ROC."""

    id: str
    type_name: str
    mount: Mount
    model: SensorModel
    roc: RocConfig
    config: MountConfig


@dataclass(frozen=True)
class System:
    """A vehicle with its sensors, ready for coverage evaluation."""

    config: VehicleConfig
    source: Path
    sensors: tuple[Sensor, ...]

    @property
    def name(self) -> str:
        """The vehicle's display name."""
        return self.config.vehicle.name

    def sensor_ids(self) -> list[str]:
        """Sensor ids in file order."""
        return [s.id for s in self.sensors]


def mount_from_config(m: MountConfig) -> Mount:
    """Degrees-in-file mount -> SI ``Mount`` (rad, m)."""
    x, y, z = m.position_m
    return Mount(
        x=x,
        y=y,
        z=z,
        yaw=m.yaw_rad,
        pitch=m.pitch_rad,
        hfov=m.hfov_rad,
        vfov=m.vfov_rad,
        min_range=m.min_range_m,
        max_range=m.max_range_m,
    )


def build_models(cfg: VehicleConfig, source: Path | str) -> dict[str, SensorModel]:
    """Validate every device's parameters against its sensor type; InputError on failure.

    Every parameter must name its source (``sources.<param>``): a data sheet, paper or
    standard, or ``estimate: <why>``.
    """
    models: dict[str, SensorModel] = {}
    for name, dev in cfg.devices.items():
        cls = registry.get(dev.type)
        if cls is None:
            raise InputError(
                source,
                f"devices.{name}.type",
                f"unknown sensor type {dev.type!r}; allowed: {', '.join(registry.names())}",
            )
        params = dev.params()
        try:
            validated = cls.Params.model_validate(params)
        except ValidationError as exc:
            raise validation_to_input_error(source, exc, prefix=f"devices.{name}") from None
        for key in params:
            require_source(source, f"devices.{name}.sources.{key}", dev.sources.get(key))
        no_stray_source(source, f"devices.{name}", dev.sources, params)
        models[name] = cls(validated)
    body = cfg.vehicle
    no_stray_source(source, "vehicle", body.sources, type(body).model_fields)
    return models


def build_system(cfg: VehicleConfig, source: Path | str) -> System:
    """Instantiate the sensors of a validated vehicle config."""
    models = build_models(cfg, source)
    sensors = []
    for m in cfg.sensors:
        dev = cfg.devices[m.device]
        sensors.append(
            Sensor(
                id=m.id,
                type_name=dev.type,
                mount=mount_from_config(m),
                model=models[m.device],
                roc=dev.roc or cfg.roc,
                config=m,
            )
        )
    return System(config=cfg, source=Path(source), sensors=tuple(sensors))


def load_system(name_or_path: str | Path, check_reaction: bool = True) -> System:
    """Load a vehicle preset name or file and build its sensor system
    (``check_reaction``: see ``config.load.load_vehicle``)."""
    cfg, path = load_vehicle(name_or_path, check_reaction=check_reaction)
    return build_system(cfg, path)
