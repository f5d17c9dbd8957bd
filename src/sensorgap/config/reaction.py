"""Reaction models of the vehicle under test (``templates/reactions.toml``) and the road
friction per weather: the inputs of the collision outcome (``search.outcome``)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError

from sensorgap.config.common import Positive, Strict
from sensorgap.config.environment import EnvironmentConfig
from sensorgap.config.load import read_toml, validation_to_input_error
from sensorgap.config.presets import templates_dir
from sensorgap.errors import InputError

SensorType = Literal["camera", "lidar", "radar", "ultrasonic"]
RoadCondition = Literal["dry", "wet", "snow"]
#: The reaction model a vehicle file that names none gets.
DEFAULT_REACTION = "fusion_any"


class ReactionConfig(Strict):
    """How the vehicle under test reacts to a target (see ``search.outcome``).

    Attributes:
        confirm_m, confirm_n: M-of-N confirmation over sensor cycles (20 Hz).
        latency_s: confirmation (or threat onset, if later) to brake onset, s.
        jerk_m_s3: brake ramp, m/s3. decel_max_m_s2: system limit before friction, m/s2.
        confirm_with: sensor types whose detections confirm a target for braking.
        threat_margin_m, threat_horizon_s: a target is a threat once its box, widened by
            the margin (m), overlaps the ego's planned path over the horizon (s).
    """

    name: str
    description: str = ""
    confirm_m: int = Field(ge=1, le=20)
    confirm_n: int = Field(ge=1, le=12)
    latency_s: float = Field(ge=0.0, le=10.0, allow_inf_nan=False)
    jerk_m_s3: Positive
    decel_max_m_s2: float = Field(gt=0.0, le=20.0, allow_inf_nan=False)
    confirm_with: tuple[SensorType, ...] = Field(min_length=1)
    threat_margin_m: float = Field(ge=0.0, le=10.0, allow_inf_nan=False)
    threat_horizon_s: float = Field(gt=0.0, le=30.0, allow_inf_nan=False)
    sources: dict[str, str] = Field(default_factory=dict)

    def label(self) -> str:
        """Short text for settings and reports."""
        return (f"{self.name}: {self.confirm_m}/{self.confirm_n} confirmation by "
                f"{'/'.join(self.confirm_with)}, latency {self.latency_s:g} s, "
                f"{self.decel_max_m_s2:g} m/s2 (jerk {self.jerk_m_s3:g} m/s3)")


def _file() -> Path:
    return templates_dir() / "reactions.toml"


def load_reaction(name_or_path: str | Path | None = None) -> ReactionConfig:
    """A reaction preset of ``templates/reactions.toml`` by name (None: the default), or
    the first ``[reactions.<name>]`` of a TOML file; InputError naming the field."""
    text = DEFAULT_REACTION if name_or_path is None else str(name_or_path)
    if text.endswith(".toml") or "/" in text:
        path, name = Path(text), None
    else:
        path, name = _file(), text
    data = read_toml(path).get("reactions")
    if not isinstance(data, dict) or not data:
        raise InputError(path, "reactions", "no [reactions.<name>] table")
    if name is None:
        name = next(iter(data))
    if name not in data:
        raise InputError(path, "reactions", f"unknown reaction model {name!r}; presets: "
                         f"{', '.join(data)}")
    raw = data[name]
    if not isinstance(raw, dict):
        raise InputError(path, f"reactions.{name}", "must be a table")
    raw = dict(raw)
    if isinstance(raw.get("confirm_with"), list):
        raw["confirm_with"] = tuple(raw["confirm_with"])
    try:
        cfg = ReactionConfig.model_validate({"name": name, **raw})
    except ValidationError as exc:
        raise validation_to_input_error(path, exc, prefix=f"reactions.{name}") from None
    if cfg.confirm_m > cfg.confirm_n:
        raise InputError(path, f"reactions.{name}.confirm_m",
                         f"must be <= confirm_n ({cfg.confirm_n}), got {cfg.confirm_m}")
    for key in raw:
        if key in ("sources", "description"):
            continue
        if not str(cfg.sources.get(key, "")).strip():
            raise InputError(path, f"reactions.{name}.sources.{key}",
                             "missing source: name the standard, paper or data sheet, or "
                             "write 'estimate: <why>'")
    return cfg


def load_friction() -> dict[str, float]:
    """Peak tyre-road friction per road condition (``[friction]`` of reactions.toml)."""
    path = _file()
    data = read_toml(path).get("friction", {})
    out = {}
    for cond in ("dry", "wet", "snow"):
        v = data.get(cond)
        if not isinstance(v, int | float) or not 0.0 < float(v) <= 2.0:
            raise InputError(path, f"friction.{cond}", "must be a number in (0, 2]")
        out[cond] = float(v)
    return out


def road_condition(env: EnvironmentConfig) -> RoadCondition:
    """The road surface an environment implies: snow when it snows, wet when it rains,
    else dry."""
    if env.snow_mm_h > 0.0:
        return "snow"
    if env.rain_mm_h > 0.0:
        return "wet"
    return "dry"
