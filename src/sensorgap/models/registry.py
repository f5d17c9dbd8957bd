"""Sensor types by name; users add their own without editing sensorgap.

Either call ``register`` on a ``SensorModel`` subclass, or publish it from another package
under the entry-point group ``sensorgap.sensors`` (loaded on first lookup), e.g. in that
package's pyproject.toml::

    [project.entry-points."sensorgap.sensors"]
    thermal = "mypkg.thermal:ThermalCamera"
"""

from __future__ import annotations

from importlib.metadata import entry_points

from sensorgap.errors import InputError
from sensorgap.models.base import SensorModel
from sensorgap.registry import Registry

ENTRY_POINT_GROUP = "sensorgap.sensors"

_entry_points_loaded = False


def _load_entry_points() -> None:
    global _entry_points_loaded
    if _entry_points_loaded:
        return
    _entry_points_loaded = True
    for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        where = f"sensor plugin {ep.name}"
        try:
            cls = ep.load()
        except (Exception, SystemExit) as exc:  # noqa: BLE001 - a broken plugin: one line
            raise InputError(
                where, ep.value, f"failed to load: {type(exc).__name__}: {exc}"
            ) from None
        if not (isinstance(cls, type) and issubclass(cls, SensorModel)):
            raise InputError(
                where, ep.value, f"must name a SensorModel subclass, got {type(cls).__name__}"
            )
        try:
            _TYPES.register(cls)
        except ValueError as exc:  # a name taken (by a built-in type or another plugin)
            raise InputError(where, ep.value, str(exc)) from None


_TYPES: Registry[type[SensorModel]] = Registry(
    "sensor type", key=lambda cls: cls.type_name, on_lookup=_load_entry_points
)


def register(cls: type[SensorModel]) -> type[SensorModel]:
    """Register a sensor type under ``cls.type_name`` (usable as a class decorator)."""
    return _TYPES.register(cls)


def unregister(name: str) -> None:
    """Remove a registered sensor type (for tests and plug-in reloads)."""
    _TYPES.unregister(name)


def get(name: str) -> type[SensorModel] | None:
    """The sensor type registered as ``name``, or ``None``."""
    return _TYPES.get(name)


def names() -> list[str]:
    """All registered sensor type names, sorted."""
    return _TYPES.names()
