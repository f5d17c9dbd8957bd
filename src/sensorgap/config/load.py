"""Load and validate TOML config files; every failure becomes one ``InputError`` line."""

from __future__ import annotations

import os
import pickle
import re
import threading
import tomllib
from collections import OrderedDict
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from sensorgap.config.environment import EnvironmentConfig, SunConfig
from sensorgap.config.presets import preset_file, templates_dir, vehicle_presets
from sensorgap.config.target import TargetConfig
from sensorgap.config.vehicle import VehicleConfig
from sensorgap.errors import MAX_QUOTED_CHARS, InputError, cut_quoted

M = TypeVar("M", bound=BaseModel)

MAX_CONFIG_BYTES = 5_000_000
#: Deepest nesting of tables and arrays accepted in a TOML file (docs/limits.md).
MAX_TOML_DEPTH = 16


def toml_depth(data: Any) -> int:
    """Nesting depth of parsed TOML (a scalar is 0, ``{"a": 1}`` is 1); level by level,
    iterative (stops at the first level deeper than ``MAX_TOML_DEPTH``)."""
    deepest, level = 0, [data]
    while True:
        level = [node for node in level if isinstance(node, dict | list)]
        if not level:
            return deepest
        deepest += 1
        if deepest > MAX_TOML_DEPTH:
            return deepest
        level = [c for node in level for c in (node.values() if isinstance(node, dict) else node)]


#: Data of the texts ``read_toml`` parsed last (pickled; up to ``_PARSED_MAX_TEXTS`` texts
#: of at most ``_PARSED_MAX_CHARS`` characters): a text parses to the same data every time,
#: and a process reads the same files many times (each ``load_environment`` reads the whole
#: environments.toml). The file is still read and checked on every call.
_PARSED: OrderedDict[str, bytes] = OrderedDict()
_PARSED_LOCK = threading.Lock()
_PARSED_MAX_TEXTS = 64
_PARSED_MAX_CHARS = 65_536


#: TOML's integers: "Arbitrary 64-bit signed integers (from -2^63 to 2^63-1) should be
#: accepted and handled losslessly. If an integer cannot be represented losslessly, an
#: error must be thrown" (TOML 1.0.0, "Integer"). Python's ``tomllib`` reads any size; a
#: 400-digit integer then overflowed a float field's conversion (hostile round 22).
TOML_INT_MIN, TOML_INT_MAX = -(2**63), 2**63 - 1
_INT_RANGE = (
    "an integer beyond 64 bits; TOML integers are -9223372036854775808 .. 9223372036854775807 "
    "(write a large number as a float, e.g. 1e30)"
)


def _oversized_integer(data: Any) -> str | None:
    """The dotted key of the first integer outside TOML's 64-bit range, else None."""
    todo: list[tuple[str, Any]] = [("", data)]
    while todo:
        key, node = todo.pop()
        if isinstance(node, dict):
            todo += [(f"{key}.{k}" if key else str(k), v) for k, v in node.items()]
        elif isinstance(node, list):
            todo += [(f"{key}[{i}]", v) for i, v in enumerate(node)]
        elif isinstance(node, int) and not TOML_INT_MIN <= node <= TOML_INT_MAX:
            return key
    return None


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; missing, unreadable, oversized or malformed -> ``InputError``."""
    if not path.exists():
        raise InputError(path, "", "file not found")
    if not path.is_file():  # a folder, a device (/dev/zero) or a pipe: never read
        raise InputError(path, "", "not a regular file (a folder, device or pipe)")
    try:
        size = path.stat().st_size
        if size > MAX_CONFIG_BYTES:
            raise InputError(path, "", f"file is {size} bytes; at most {MAX_CONFIG_BYTES} allowed")
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(path, "", f"not UTF-8 text ({exc.reason})") from None
    except OSError as exc:
        raise InputError(path, "", f"cannot read: {exc.strerror}") from None
    if text.startswith("\ufeff"):
        raise InputError(
            path, "", "starts with a byte-order mark (U+FEFF); save it as UTF-8 without BOM"
        )
    with _PARSED_LOCK:
        known = _PARSED.get(text)
        if known is not None:
            _PARSED.move_to_end(text)
    if known is not None:
        parsed: dict[str, Any] = pickle.loads(known)  # a copy of its own for the caller
        return parsed
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(path, "", f"TOML syntax error: {exc}") from None
    except ValueError:  # int() of more than sys.get_int_max_str_digits() (4,300) digits
        long = re.search(r"[0-9_]{4300,}", text)
        where = "" if long is None else f"line {text.count(chr(10), 0, long.start()) + 1}"
        raise InputError(path, where, _INT_RANGE) from None
    except RecursionError:
        data = None
    if data is None or toml_depth(data) > MAX_TOML_DEPTH:
        raise InputError(
            path,
            "",
            f"tables and arrays nested too deeply; at most {MAX_TOML_DEPTH} levels allowed",
        )
    wide = _oversized_integer(data)
    if wide is not None:
        raise InputError(path, cut_quoted(wide), _INT_RANGE)
    if len(text) <= _PARSED_MAX_CHARS:
        with _PARSED_LOCK:
            _PARSED[text] = pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL)
            while len(_PARSED) > _PARSED_MAX_TEXTS:
                _PARSED.popitem(last=False)
    return data


def short(value: object) -> str:
    """``repr(value)``, cut to ``MAX_QUOTED_CHARS`` characters (an error stays one short
    line when a file holds a megabyte-long string)."""
    return cut_quoted(repr(value))


def _loc(loc: tuple[int | str, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            part = str(part)
            out += ("." if out else "") + (part if len(part) <= MAX_QUOTED_CHARS else short(part))
    return out


def validation_to_input_error(
    source: Path | str, exc: ValidationError, prefix: str = ""
) -> InputError:
    """Every pydantic error as an ``InputError`` naming the field and what is allowed (the
    first; the others in ``more``, one line each when printed)."""
    found = []
    for err in exc.errors(include_url=False):
        field = _loc(tuple(err.get("loc", ())))
        if prefix:
            field = f"{prefix}.{field}" if field else prefix
        msg = str(err.get("msg", "invalid value"))
        msg = msg.removeprefix("Value error, ")
        if "input" in err and err.get("type") not in ("missing", "model_type", "dict_type"):
            value = err["input"]
            if not isinstance(value, dict | list):
                msg += f" (got {short(value)})"
        found.append(InputError(source, field, msg))
    if not found:
        return InputError(source, prefix, "invalid")
    return InputError(found[0].source, found[0].field, found[0].message, found[1:])


def require_source(source: Path | str, field: str, text: object) -> None:
    """Every parameter names where its value comes from: ``InputError`` at ``field`` of
    the file ``source`` unless ``text`` (the parameter's ``sources`` entry) is non-blank
    text."""
    if not isinstance(text, str) or not text.strip():
        raise InputError(
            source,
            field,
            "missing source: name the data sheet, paper or standard, or write 'estimate: <why>'",
        )


def no_stray_source(
    source: Path | str, where: str, sources: Mapping[str, str], known: Iterable[str]
) -> None:
    """A ``sources`` entry names a parameter of its table (a misspelt parameter name is
    refused), ``InputError`` naming the first stray one and the names allowed (``known``
    but ``sources`` itself): a device's, the vehicle body's, an environment's, a target
    class's (a reaction model's likewise, ``config.reaction``)."""
    allowed = sorted(set(known) - {"sources"})
    stray = sorted(set(sources) - set(allowed))
    if stray:
        raise InputError(
            source,
            f"{where}.sources.{stray[0][:80]}",
            f"source for an unknown parameter; allowed: {', '.join(allowed)}",
        )


def parse_model(model: type[M], data: Any, source: Path | str, prefix: str = "") -> M:
    """Validate ``data`` as ``model``; errors become ``InputError``."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise validation_to_input_error(source, exc, prefix) from None


def resolve_vehicle_path(name_or_path: str | Path) -> Path:
    """A preset name (``system_a``) or a path to a vehicle TOML file."""
    text = str(name_or_path)
    if not text.strip():  # Path("") would be the working directory
        raise InputError(
            "vehicle", "", f"must name a preset ({', '.join(vehicle_presets())}) or a .toml file"
        )
    candidate = Path(text)
    if text.endswith(".toml") or "/" in text or candidate.exists():
        return candidate
    return preset_file(
        templates_dir() / "vehicles", text, "vehicle", ("preset", "presets"), vehicle_presets()
    )


def load_vehicle(
    name_or_path: str | Path, check_reaction: bool = True
) -> tuple[VehicleConfig, Path]:
    """Load and validate a vehicle file; returns the config and the file it came from.

    ``check_reaction``: also load the reaction model ``reaction`` names (a path's file, its
    ``[friction]`` table included) and refuse a vehicle of the built-in sensor types none
    of whose sensors could confirm a target under it (``config.reaction.unconfirmable``);
    False for a run folder's recorded vehicle copy, whose reaction model is recorded
    apart."""
    from sensorgap.config.reaction import (
        SENSOR_TYPES,
        friction_source,
        load_friction,
        load_reaction,
        reaction_presets,
        unconfirmable,
    )

    path = resolve_vehicle_path(name_or_path)
    cfg = parse_model(VehicleConfig, read_toml(path), path)
    reaction = cfg.reaction
    model = None
    if reaction.endswith(".toml") or "/" in reaction:
        # a path: a relative one is relative to the vehicle file's folder (as a family
        # file's road); an absolute one stays as it is
        cfg = cfg.model_copy(update={"reaction": os.path.abspath(path.parent / reaction)})
        if check_reaction:  # checked for every command, as a preset name is
            model = load_reaction(cfg.reaction)  # a missing file: "<its path>: file not found"
            load_friction(friction_source(cfg.reaction))  # its [friction] table, if any
    else:  # a preset name: checked for every command, not only those that use it
        names = reaction_presets()
        if reaction not in names:
            raise InputError(
                path,
                "reaction",
                f"unknown reaction model {reaction[:64]!r}; "
                f"presets: {', '.join(names)} (or a path to a .toml file)",
            )
        model = load_reaction(reaction) if check_reaction else None
    types = {cfg.devices[m.device].type for m in cfg.sensors}
    # a user-registered sensor type (models.registry) is one no reaction model can name:
    # such a vehicle is checked where it would brake (search.evaluate.Evaluator), so that
    # its coverage and near field stay possible
    why = None if model is None or types - set(SENSOR_TYPES) else unconfirmable(model, types)
    if why:
        raise InputError(path, "reaction", why)
    return cfg, path


def environments_path() -> Path:
    """The shipped environment presets file."""
    return templates_dir() / "environments.toml"


def _named_tables(model: type[M], path: Path, key: str) -> dict[str, M]:
    data = read_toml(path)
    tables = data.get(key)
    if not isinstance(tables, dict) or not tables:
        raise InputError(path, key, f"expected a non-empty table [{key}.<name>]")
    unknown = sorted(set(data) - {key})
    if unknown:
        raise InputError(path, unknown[0], f"unknown top-level key; only [{key}.*] allowed")
    out: dict[str, M] = {}
    for name, body in tables.items():
        label = f"{key}.{name if len(name) <= MAX_QUOTED_CHARS else short(name)}"
        if not isinstance(body, dict):
            raise InputError(path, label, "expected a table")
        if "name" in body and body["name"] != name:
            # the table's key names it; a different `name` renamed it silently (two
            # environments could share a name)
            raise InputError(
                path,
                f"{label}.name",
                f"must repeat the table's key {short(name)} (or be left out), "
                f"got {short(body['name'])}",
            )
        out[name] = parse_model(model, {**body, "name": name}, path, prefix=label)
    return out


def load_environments(path: Path | None = None) -> dict[str, EnvironmentConfig]:
    """All environments of a file (default: the shipped presets), by name; a ``sources``
    key must name a field of its environment or of its ``sun`` table (a misspelt one is
    refused, as a vehicle file's)."""
    path = path or environments_path()
    envs = _named_tables(EnvironmentConfig, path, "environments")
    known = {*EnvironmentConfig.model_fields, *SunConfig.model_fields}
    for name, env in envs.items():
        label = f"environments.{name if len(name) <= MAX_QUOTED_CHARS else short(name)}"
        no_stray_source(path, label, env.sources, known)
    return envs


def load_environment(name: str, path: Path | None = None) -> EnvironmentConfig:
    """One environment preset by name; unknown names list what is allowed."""
    envs = load_environments(path)
    if name not in envs:
        raise InputError(
            "environment", "", f"unknown environment {name!r}; presets: {', '.join(envs)}"
        )
    return envs[name]


def load_targets(path: Path | None = None) -> dict[str, TargetConfig]:
    """All target classes (default: the shipped ``targets.toml``), by name; a ``sources``
    key must name a field of its target class (a misspelt one is refused, as a vehicle
    file's and an environment's: it was accepted silently)."""
    path = path or templates_dir() / "targets.toml"
    targets = _named_tables(TargetConfig, path, "targets")
    for name, target in targets.items():
        label = f"targets.{name if len(name) <= MAX_QUOTED_CHARS else short(name)}"
        no_stray_source(path, label, target.sources, TargetConfig.model_fields)
    return targets


def load_target(name: str, path: Path | None = None) -> TargetConfig:
    """One target class by name."""
    targets = load_targets(path)
    if name not in targets:
        raise InputError("target", "", f"unknown target {name!r}; allowed: {', '.join(targets)}")
    return targets[name]


def require_shipped(
    vehicles: Iterable[str] = (),
    environments: Iterable[str] = (),
    targets: Iterable[str] = (),
    families: Iterable[str] = (),
) -> None:
    """Refuse, before any work, a templates folder lacking a shipped preset that a command
    uses by its fixed name (``paper``: System A and B, ``tradeoff``: rain_25, two
    families...): one ``InputError`` naming ``SENSORGAP_TEMPLATES`` when it is set, and
    every missing preset (hostile round 28: ``tradeoff`` refused after 15 s of measuring,
    naming ``--environment``, an option it does not have)."""
    tdir = templates_dir()
    missing = [
        f"vehicles/{n}.toml" for n in vehicles if not (tdir / "vehicles" / f"{n}.toml").is_file()
    ]
    missing += [
        f"scenarios/{n}.toml" for n in families if not (tdir / "scenarios" / f"{n}.toml").is_file()
    ]
    wanted_envs, wanted_targets = list(dict.fromkeys(environments)), list(dict.fromkeys(targets))
    if wanted_envs:
        envs = load_environments()
        missing += [f"environment {n!r} (environments.toml)" for n in wanted_envs if n not in envs]
    if wanted_targets:
        known = load_targets()
        missing += [f"target {n!r} (targets.toml)" for n in wanted_targets if n not in known]
    if not missing:
        return
    env = os.environ.get("SENSORGAP_TEMPLATES")
    if env:
        raise InputError(
            "SENSORGAP_TEMPLATES",
            "",
            f"{env} lacks {', '.join(missing)} (shipped presets this command needs); name a "
            "folder holding the shipped templates, or do not set it",
        )
    raise InputError(tdir, "", f"lacks {', '.join(missing)} (a broken installation)")
