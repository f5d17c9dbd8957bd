"""Configuration: typed, validated vehicle, environment and target files (TOML).

Degrees in files, radians inside: the ``*_rad`` properties convert.
"""

from sensorgap.config.environment import EnvironmentConfig, SunConfig
from sensorgap.config.load import (
    load_environment,
    load_environments,
    load_target,
    load_targets,
    load_vehicle,
)
from sensorgap.config.presets import templates_dir, vehicle_presets
from sensorgap.config.target import TargetConfig
from sensorgap.config.vehicle import DeviceConfig, MountConfig, RocConfig, VehicleConfig

__all__ = [
    "DeviceConfig",
    "EnvironmentConfig",
    "MountConfig",
    "RocConfig",
    "SunConfig",
    "TargetConfig",
    "VehicleConfig",
    "load_environment",
    "load_environments",
    "load_target",
    "load_targets",
    "load_vehicle",
    "templates_dir",
    "vehicle_presets",
]
