"""JSON Schema of the config files, including every registered sensor type's parameters."""

from __future__ import annotations

from typing import Any

from sensorgap.config.environment import EnvironmentConfig
from sensorgap.config.target import TargetConfig
from sensorgap.config.vehicle import DeviceConfig, VehicleConfig
from sensorgap.models import registry


def _named_file(model_schema: dict[str, Any], key: str, title: str) -> dict[str, Any]:
    defs = model_schema.pop("$defs", {})
    entry = dict(model_schema)
    entry["properties"] = {k: v for k, v in entry.get("properties", {}).items() if k != "name"}
    entry["required"] = [r for r in entry.get("required", []) if r != "name"]
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "type": "object",
        "additionalProperties": False,
        "required": [key],
        "properties": {key: {"type": "object", "additionalProperties": entry}},
        "$defs": defs,
    }


def vehicle_schema() -> dict[str, Any]:
    """JSON Schema of a vehicle file; ``devices`` entries are one of the sensor types."""
    schema = VehicleConfig.model_json_schema()
    defs = schema.setdefault("$defs", {})
    base = DeviceConfig.model_json_schema()
    variants = []
    for name in registry.names():
        cls = registry.get(name)
        assert cls is not None
        params = cls.Params.model_json_schema()
        props = {
            "type": {"const": name},
            "sources": {
                "type": "object",
                "additionalProperties": {"type": "string"},
                "description": "source of every parameter (data sheet, paper, "
                "standard or 'estimate: ...')",
            },
            "roc": base["properties"]["roc"],
            **params.get("properties", {}),
        }
        defs.update(params.get("$defs", {}))
        defs.update(base.get("$defs", {}))
        variants.append(
            {
                "title": f"{name} device",
                "type": "object",
                "additionalProperties": False,
                "required": ["type", "sources", *params.get("required", [])],
                "properties": props,
            }
        )
    defs["DeviceConfig"] = {"oneOf": variants, "description": DeviceConfig.__doc__}
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema


def file_schemas() -> dict[str, Any]:
    """Schemas of the vehicle, environments and targets files, by kind."""
    return {
        "vehicle": vehicle_schema(),
        "environments": _named_file(
            EnvironmentConfig.model_json_schema(), "environments", "sensorgap environments file"
        ),
        "targets": _named_file(
            TargetConfig.model_json_schema(), "targets", "sensorgap targets file"
        ),
    }
