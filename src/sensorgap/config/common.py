"""Shared pydantic building blocks: strict, finite numbers and a base model."""

from __future__ import annotations

import numbers
import re
from typing import Annotated, TypeGuard

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

#: A finite float (NaN and +-inf rejected on load).
Finite = Annotated[float, Field(allow_inf_nan=False)]
#: A finite float >= 0.
NonNeg = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
#: A finite float > 0.
Positive = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]

#: Longest user-given name (vehicle, environment, target), characters (docs/limits.md).
MAX_NAME_CHARS = 64
#: What a name may hold: printable ASCII and the Latin letters of Latin-1 and Latin
#: Extended-A (U+00C0..U+017F: é, ü, ß, ł, ...), all drawn by the figures' font (DejaVu
#: Sans), so a name never prints a missing-glyph warning; no control characters, no
#: leading or trailing space.
NAME_CHARS = "printable ASCII or Latin letters (U+00C0..U+017F), no leading/trailing space"


def name_problem(text: str) -> str | None:
    """Why ``text`` is not a valid name (length, characters), or None."""
    ok = all(" " <= c <= "~" or "\u00c0" <= c <= "\u017f" for c in text)
    if not ok or text != text.strip() or not 1 <= len(text) <= MAX_NAME_CHARS:
        return f"a name is 1-{MAX_NAME_CHARS} characters: {NAME_CHARS}"
    return None


def _name_chars(v: str) -> str:
    why = name_problem(v)
    if why:
        raise ValueError(why)
    return v


#: A user-given name: 1-64 characters from ``NAME_CHARS``.
Name = Annotated[str, Field(min_length=1, max_length=MAX_NAME_CHARS), AfterValidator(_name_chars)]

#: Characters a preset name (environment, target class) may not hold: ``@`` starts the
#: sun suffix of an environment label (``clear@sun66/4``), ``,`` separates the names of
#: ``--environments`` / ``--families``, ``/`` and ``\`` would make a folder in the names of
#: coverage maps (``car_<environment>.npz``).
RESERVED_PRESET_CHARS = "@,/\\"


def _preset_chars(v: str) -> str:
    bad = sorted({c for c in v if c in RESERVED_PRESET_CHARS})
    if bad:
        raise ValueError(
            f"a preset name may not hold {' '.join(repr(c) for c in bad)} "
            "(@ starts a sun suffix, ',' separates names, '/' and '\\' make folders)"
        )
    return v


#: The name of a preset (an environment, a target class): a ``Name`` without the
#: ``RESERVED_PRESET_CHARS``.
PresetName = Annotated[Name, AfterValidator(_preset_chars)]


def is_number(value: object) -> TypeGuard[numbers.Real]:
    """A real number given to the library (an int, a float, a numpy scalar), not a boolean
    (``True`` is an int to Python)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_integer(value: object) -> TypeGuard[numbers.Integral]:
    """An integer given to the library (an int or a numpy integer), not a boolean."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


class Strict(BaseModel):
    """Base for config models: unknown keys are errors, numbers must be finite, and no type
    coercion (a quoted "3" is not a number; integers are accepted where floats are)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)


#: A plain decimal number as written in CSV files and on the command line: optional sign,
#: digits with an optional point, optional exponent; no '_' digit separators (Python's
#: ``float('1_000')`` accepts them), no inner spaces. 'nan' and 'inf' are read as such, so
#: that the option's own check names the allowed range.
_DECIMAL = re.compile(
    r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
    r"|[+-]?(?:nan|inf|infinity)",
    re.IGNORECASE,
)
_INTEGER = re.compile(r"[+-]?[0-9]+")


def parse_decimal(text: str) -> float:
    """A plain decimal number (``_DECIMAL``; surrounding spaces allowed) as a float;
    anything else -> ``ValueError``. Values beyond the float range are ``inf``; callers
    check finiteness and range."""
    t = text.strip()
    if len(t) > 400 or not _DECIMAL.fullmatch(t):
        raise ValueError(f"not a plain decimal number: {text[:80]!r}")
    return float(t)


def parse_integer(text: str) -> int:
    """A plain integer (optional sign and digits; no '_' separators) -> ``ValueError``."""
    t = text.strip()
    if len(t) > 400 or not _INTEGER.fullmatch(t):
        raise ValueError(f"not a plain integer: {text[:80]!r}")
    return int(t)
