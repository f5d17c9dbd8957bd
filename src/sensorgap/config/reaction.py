"""Reaction models of the vehicle under test (``templates/reactions.toml``) and the road
friction per weather: the inputs of the collision outcome (``search.outcome``).

File layout (the shipped presets or a file of the same layout)::

    [reactions.<name>]
    confirm_m = 3                     # M of ...
    confirm_n = 5                     # ... the last N sensor cycles (20 Hz)
    latency_s = 0.3                   # confirmation (or threat onset) to brake onset, s
    jerk_m_s3 = 12.0                  # brake ramp, m/s3
    decel_max_m_s2 = 9.0              # system limit before friction, m/s2
    confirm_with = ["camera", "lidar"]
    threat_margin_m = 0.5             # m
    threat_horizon_s = 6.0            # s
    threat_prediction_s = 1.0         # s (optional, default 0)
    [reactions.<name>.sources]        # one non-empty source per parameter (and for
    confirm_m = "..."                 # moving_min_speed_m_s whenever confirm_moving_with
                                      # is set, even at its default)

    [friction]                        # peak tyre-road friction per road condition
    dry = 0.9
    wet = 0.6
    snow = 0.2
    [friction.sources]
    dry = "..."

The table's key is the model's name (a ``Name``); a ``name`` key may only repeat it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal, get_args

from pydantic import Field, ValidationError

from sensorgap.config.common import Name, Strict, name_problem
from sensorgap.config.environment import EnvironmentConfig
from sensorgap.config.load import (
    no_stray_source,
    read_toml,
    require_source,
    short,
    validation_to_input_error,
)
from sensorgap.config.presets import templates_dir
from sensorgap.errors import InputError

SensorType = Literal["camera", "lidar", "radar", "ultrasonic"]
RoadCondition = Literal["dry", "wet", "snow"]
#: The sensor types a reaction model may name (``confirm_with``, ``confirm_moving_with``).
SENSOR_TYPES: tuple[str, ...] = get_args(SensorType)
#: The reaction model ``load_reaction(None)`` gives.
DEFAULT_REACTION = "ads_default"
#: The road conditions of ``[friction]``, in this order.
ROAD_CONDITIONS: tuple[RoadCondition, ...] = ("dry", "wet", "snow")
#: Model fields that are not parameters (no source needed).
_NOT_PARAMETERS = frozenset({"name", "description", "sources"})


class ReactionConfig(Strict):
    """How the vehicle under test reacts to a target (see ``search.outcome``).

    Attributes:
        confirm_m, confirm_n: M-of-N confirmation over sensor cycles (20 Hz): confirmed at
            the first cycle with at least M detections among the last N.
        latency_s: confirmation (or threat onset, if later) to brake onset, s.
        jerk_m_s3: brake ramp, m/s3. decel_max_m_s2: system limit before friction, m/s2
            (the outcome uses ``min(decel_max_m_s2, mu g)``).
        confirm_with: sensor types whose detections can confirm a target for braking.
        confirm_moving_with: sensor types whose detections confirm a target only while it
            moves over the ground at ``moving_min_speed_m_s`` or more (a radar that brakes
            for a moving vehicle ahead but suppresses stationary returns).
        moving_min_speed_m_s: the target's ground speed from which ``confirm_moving_with``
            confirms, m/s.
        threat_margin_m, threat_horizon_s: a target is a threat once its box, widened by
            the margin (m) on each side of the ego's path, overlaps the ego's boxes along
            its planned path over the horizon (s).
        threat_prediction_s: the target's lateral offset from the ego's path is predicted
            this far ahead (s) at its current lateral rate in that test (0, the default of
            a file that leaves it out: the target is judged where it is).
        sources: one non-empty source per parameter (standard, paper, data sheet or
            ``estimate: why``); ``load_reaction`` checks it.
        name: the key of its ``[reactions.<name>]`` table, a ``Name`` (a ``name`` key in
            the table may only repeat it).
    """

    name: Name
    description: str = ""
    confirm_m: int = Field(ge=1, le=12, description="M of the M-of-N confirmation, cycles")
    confirm_n: int = Field(ge=1, le=12, description="N of the M-of-N confirmation, cycles")
    latency_s: float = Field(
        ge=0.0,
        le=10.0,
        description="Confirmation (or threat onset) to brake onset, s",
    )
    jerk_m_s3: float = Field(ge=0.1, le=1000.0, description="Brake ramp, m/s3")
    decel_max_m_s2: float = Field(
        gt=0.0, le=20.0, description="Deceleration limit before friction, m/s2"
    )
    confirm_with: tuple[SensorType, ...] = Field(
        min_length=1, description="Sensor types whose detections confirm a target"
    )
    confirm_moving_with: tuple[SensorType, ...] = Field(
        (), description="Sensor types that confirm a target only while it moves"
    )
    moving_min_speed_m_s: float = Field(
        5.0,
        ge=0.0,
        le=100.0,
        description="Target ground speed from which confirm_moving_with confirms, m/s",
    )
    threat_margin_m: float = Field(
        ge=0.0, le=10.0, description="Lateral widening of the threat test, m"
    )
    threat_horizon_s: float = Field(
        gt=0.0, le=30.0, description="Planned path ahead in the threat test, s"
    )
    threat_prediction_s: float = Field(
        0.0,
        ge=0.0,
        le=5.0,
        description="Lateral prediction in the threat test, s",
    )
    sources: dict[str, str] = Field(default_factory=dict)

    def label(self) -> str:
        """Short text for settings and reports."""
        moving = (
            f" (and {'/'.join(self.confirm_moving_with)} for targets moving at "
            f">= {self.moving_min_speed_m_s:g} m/s)"
            if self.confirm_moving_with
            else ""
        )
        return (
            f"{self.name}: {self.confirm_m}/{self.confirm_n} confirmation by "
            f"{'/'.join(self.confirm_with)}{moving}, latency {self.latency_s:g} s, "
            f"{self.decel_max_m_s2:g} m/s2 (jerk {self.jerk_m_s3:g} m/s3)"
        )


def reactions_path() -> Path:
    """The shipped reaction presets file (``templates/reactions.toml``)."""
    return templates_dir() / "reactions.toml"


#: The top-level tables of a reaction file.
REACTION_FILE_TABLES = ("reactions", "friction")


def _tables(path: Path) -> dict[str, Any]:
    doc = read_toml(path)
    unknown = sorted(set(doc) - set(REACTION_FILE_TABLES))
    if unknown:  # a misspelt [friction] was ignored: the shipped friction silently applied
        raise InputError(
            path,
            unknown[0],
            f"unknown table or key; a reaction file holds {', '.join(REACTION_FILE_TABLES)}",
        )
    data = doc.get("reactions")
    if not isinstance(data, dict) or not data:
        raise InputError(path, "reactions", "expected a non-empty table [reactions.<name>]")
    return data


def reaction_presets() -> list[str]:
    """Names of the shipped reaction models, in file order."""
    return list(_tables(reactions_path()))


def load_reaction(
    name_or_path: str | Path | None = None, presets: Path | None = None
) -> ReactionConfig:
    """A reaction model: None gives ``DEFAULT_REACTION``; a preset name of
    ``templates/reactions.toml``; or a path to a TOML file of the same layout (its first
    ``[reactions.<name>]`` table). ``presets``: the file a name is looked up in instead of
    the shipped presets (a run folder's recorded copy). Any problem (unknown name, bad
    value, M > N, a parameter without a source) is an ``InputError`` naming the file and
    the field."""
    text = DEFAULT_REACTION if name_or_path is None else str(name_or_path)
    if isinstance(name_or_path, Path) or text.endswith(".toml") or "/" in text:
        path, name = Path(text), None
    else:
        path, name = presets or reactions_path(), text
    data = _tables(path)
    if name is None:
        name = next(iter(data))
    if name not in data:
        raise InputError(
            path,
            "reactions",
            f"unknown reaction model {name!r}; presets: "
            f"{', '.join(data)} (or give a path to a .toml file)",
        )
    raw = data[name]
    why = name_problem(name)  # the table's key is the model's name (run.json, reports)
    if why:
        raise InputError(path, f"reactions.{short(name)}", f"the table's key is its name: {why}")
    if not isinstance(raw, dict):
        raise InputError(path, f"reactions.{name}", "must be a table")
    raw = dict(raw)
    if "name" in raw and raw["name"] != name:  # a name of its own would rename the model
        raise InputError(
            path,
            f"reactions.{name}.name",
            f"a reaction model is named by its table's key ({name!r}): leave name out or "
            f"repeat the key, got {short(raw['name'])}",
        )
    for key in ("confirm_with", "confirm_moving_with"):
        if isinstance(raw.get(key), list):
            allowed = get_args(SensorType)
            for i, v in enumerate(raw[key]):  # one line per file, not pydantic's two
                if v not in allowed:
                    raise InputError(
                        path,
                        f"reactions.{name}.{key}[{i}]",
                        f"unknown sensor type {str(v)[:80]!r}; allowed: {', '.join(allowed)}",
                    )
            raw[key] = tuple(raw[key])
    try:
        cfg = ReactionConfig.model_validate({"name": name, **raw})
    except ValidationError as exc:
        raise validation_to_input_error(path, exc, prefix=f"reactions.{name}") from None
    if cfg.confirm_m > cfg.confirm_n:
        raise InputError(
            path,
            f"reactions.{name}.confirm_m",
            f"must be <= confirm_n ({cfg.confirm_n}), got {cfg.confirm_m}",
        )
    if len(set(cfg.confirm_with)) != len(cfg.confirm_with):
        raise InputError(path, f"reactions.{name}.confirm_with", "lists a sensor type twice")
    both = sorted(set(cfg.confirm_with) & set(cfg.confirm_moving_with))
    if len(set(cfg.confirm_moving_with)) != len(cfg.confirm_moving_with) or both:
        raise InputError(
            path,
            f"reactions.{name}.confirm_moving_with",
            "lists a sensor type twice or one of confirm_with" + (f" ({both[0]})" if both else ""),
        )
    for key in ReactionConfig.model_fields:
        if key in _NOT_PARAMETERS or (
            key not in cfg.model_fields_set
            and ReactionConfig.model_fields[key].default is not None
            and not ReactionConfig.model_fields[key].is_required()
        ):
            continue  # an optional parameter left at its default needs no source
        require_source(path, f"reactions.{name}.sources.{key}", cfg.sources.get(key))
    if cfg.confirm_moving_with and not str(cfg.sources.get("moving_min_speed_m_s", "")).strip():
        # the speed decides when those sensors confirm: an operative parameter, even at its
        # default
        raise InputError(
            path,
            f"reactions.{name}.sources.moving_min_speed_m_s",
            "missing source: with confirm_moving_with set, moving_min_speed_m_s (default "
            f"{ReactionConfig.model_fields['moving_min_speed_m_s'].default:g} m/s) decides when "
            "they confirm; name the data sheet, paper or standard, or write 'estimate: <why>'",
        )
    unknown = sorted(set(cfg.sources) - set(ReactionConfig.model_fields))
    if unknown:
        raise InputError(
            path, f"reactions.{name}.sources.{unknown[0]}", "source for an unknown parameter"
        )
    return cfg


def unconfirmable(reaction: ReactionConfig, sensor_types: set[str]) -> str | None:
    """Why a vehicle with sensors of ``sensor_types`` could never brake for a detection
    under ``reaction`` (none of its sensors is of a type in ``confirm_with`` or
    ``confirm_moving_with``), or None when some sensor can confirm."""
    if sensor_types & {*reaction.confirm_with, *reaction.confirm_moving_with}:
        return None
    moving = (
        f" (and {'/'.join(reaction.confirm_moving_with)} for targets moving at >= "
        f"{reaction.moving_min_speed_m_s:g} m/s)"
        if reaction.confirm_moving_with
        else ""
    )
    return (
        f"reaction model {reaction.name} confirms with {'/'.join(reaction.confirm_with)}"
        f"{moving}, and this vehicle has no such sensor (it has "
        f"{', '.join(sorted(sensor_types)) or 'none'}): it could never brake for a detection"
    )


def friction_source(reaction: str | None) -> Path:
    """The file whose ``[friction]`` table goes with a vehicle's ``reaction`` setting: a
    reaction file (a path) that has its own ``[friction]`` table, else the shipped
    ``reactions.toml``."""
    text = "" if reaction is None else str(reaction)
    if text.endswith(".toml") or "/" in text:
        path = Path(text)
        if "friction" in read_toml(path):
            return path
    return reactions_path()


def load_friction(path: Path | None = None) -> dict[str, float]:
    """Peak tyre-road friction coefficient per road condition (``dry``, ``wet``, ``snow``)
    from the ``[friction]`` table of ``reactions.toml`` (or ``path``); each value in (0, 2]
    with a non-empty ``[friction.sources]`` entry, else ``InputError``."""
    path = path or reactions_path()
    data = read_toml(path).get("friction")
    if not isinstance(data, dict):
        raise InputError(path, "friction", "expected a table [friction] with dry, wet, snow")
    sources = data.get("sources", {})
    if not isinstance(sources, dict):
        raise InputError(path, "friction.sources", "must be a table")
    unknown = sorted(set(data) - {*ROAD_CONDITIONS, "sources"})
    if unknown:
        raise InputError(
            path,
            f"friction.{unknown[0]}",
            f"unknown road condition; allowed: {', '.join(ROAD_CONDITIONS)}",
        )
    no_stray_source(path, "friction", sources, ROAD_CONDITIONS)
    out: dict[str, float] = {}
    for cond in ROAD_CONDITIONS:
        v = data.get(cond)
        if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 < float(v) <= 2.0:
            raise InputError(
                path,
                f"friction.{cond}",
                f"must be a number in (0, 2] (peak friction coefficient), got {v!r}",
            )
        require_source(path, f"friction.sources.{cond}", sources.get(cond))
        out[cond] = float(v)
    return out


def road_condition(env: EnvironmentConfig) -> RoadCondition:
    """The road surface an environment implies: ``snow`` when it snows (``snow_mm_h > 0``),
    else ``wet`` when it rains (``rain_mm_h > 0``), else ``dry``."""
    if env.snow_mm_h > 0.0:
        return "snow"
    if env.rain_mm_h > 0.0:
        return "wet"
    return "dry"
