"""Phenomenological sensor models (Ponn et al. 2019, eq. 1-11).

Importing this package registers the built-in types: camera, lidar, radar, ultrasonic.
"""

from sensorgap.models import camera, lidar, radar, ultrasonic  # noqa: F401  (registration)
from sensorgap.models.base import PreparedSensor, SensorModel
from sensorgap.models.conditions import Band, Conditions
from sensorgap.models.fusion import FusionAccumulator, fuse
from sensorgap.models.geometry import Mount
from sensorgap.models.registry import register
from sensorgap.models.roc import detection_probability
from sensorgap.models.system import Sensor, System, build_system, load_system

__all__ = [
    "Band",
    "Conditions",
    "FusionAccumulator",
    "Mount",
    "PreparedSensor",
    "Sensor",
    "SensorModel",
    "System",
    "build_system",
    "detection_probability",
    "fuse",
    "load_system",
    "register",
]
