"""Shared pydantic building blocks: strict, finite numbers and a base model."""

from __future__ import annotations

import datetime
import math
import numbers
import re
from typing import Annotated, TypeGuard

import numpy as np
from numpy.typing import NDArray
from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from sensorgap.filesio import is_temporary

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
    if is_temporary(v):
        # it names folders (coverage/car_<environment>/, farfield/<environment>/) that
        # verify would take for left-overs: hostile round 36's fog.tmp ran a whole job
        raise ValueError(
            "a preset name may not read like a temporary or journal file (*.tmp, "
            "*-journal, *-wal, *-shm): it names folders of a run"
        )
    return v


#: The name of a preset (an environment, a target class): a ``Name`` without the
#: ``RESERVED_PRESET_CHARS``.
PresetName = Annotated[Name, AfterValidator(_preset_chars)]


def is_number(value: object) -> TypeGuard[numbers.Real]:
    """A real number given to the library (an int, a float, a numpy scalar), not a boolean
    (``True`` is an int to Python) nor a numpy ``timedelta64`` (a duration; numpy files it
    under its integers)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.timedelta64)


def is_integer(value: object) -> TypeGuard[numbers.Integral]:
    """An integer given to the library (an int or a numpy integer), not a boolean nor a
    numpy ``timedelta64``."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool | np.timedelta64)


def as_integer(value: object) -> int | None:
    """An integer parameter of the library as an int when it is an int, a numpy integer
    or a 0-d numpy array of integers, else None (not a boolean, a float, text). Every
    integer the library keeps is a plain int: a numpy one reached the store's JSON
    (hostile round 42: ``seeds=np.int64(2)``, "Object of type int64 is not JSON
    serializable", a store left behind)."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iu":
        value = value[()]
    return int(value) if is_integer(value) else None


def finite_real(value: object) -> float | None:
    """A number parameter of the library as a float when it is a finite real number (an
    int, a float, a numpy integer or floating scalar), else None: not a boolean, text
    (``'30'``), bytes, a duration, NaN or an infinity, nor an int beyond a float's range
    (``10**400`` was a raw ``OverflowError``). The one check of every number the library
    takes (``real_array`` for arrays of them); the caller names the parameter. A 0-d
    numpy array of integers or floats counts as its number (``np.array(0.5)``; hostile
    round 40: refused while a ``Fraction`` passed)."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value[()]
    if not is_number(value):
        return None
    try:
        number = float(value)
    except (OverflowError, TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


def _what(kind: type) -> str:
    """What a value of ``kind`` is, for an error line ("got booleans")."""
    for types, what in (
        ((bool, np.bool_), "booleans"),
        ((str, np.str_), "text (str)"),
        ((bytes, np.bytes_), "bytes"),
        ((datetime.date, np.datetime64), "dates (datetime64)"),
        ((datetime.timedelta, np.timedelta64), "durations (timedelta64)"),
        ((complex, np.complexfloating), "complex numbers"),
        ((list, tuple, np.ndarray), "rows of unequal lengths"),
        ((type(None),), "None"),
    ):
        if issubclass(kind, types):
            return what
    return f"{kind.__name__} values"


#: What an array of each numpy dtype kind holds, when not real numbers.
_KIND_WHAT = {
    "b": "booleans",
    "U": "text (str)",
    "S": "bytes",
    "M": "dates (datetime64)",
    "m": "durations (timedelta64)",
    "c": "complex numbers",
    "V": "records (a structured array)",
}


def real_array(values: object) -> NDArray[np.float64]:
    """An array parameter of real numbers (an ndarray of integers or floats, or nested
    lists of ints, floats and numpy integer or floating scalars) as float64, else
    ``ValueError`` saying what it holds instead ("got booleans", "got text (str)"), for
    the caller's ``InputError`` naming the parameter. Refused, not cast as numpy would:
    booleans (``True`` as 1), text and bytes (``"30"`` as 30), dates and durations (as
    their counts), complex numbers, other objects, and ints beyond a float's range. NaN
    and infinities pass: the caller's range check names them. A masked array with any value
    masked is refused (its masked values would be read as whatever they hold)."""
    if isinstance(values, np.ma.MaskedArray) and np.ma.getmaskarray(values).any():
        raise ValueError("got a masked array with masked values (give the values to use)")
    try:
        if isinstance(values, np.ndarray) or hasattr(values, "__array__"):
            array = np.asarray(values)
        else:  # lists: numpy would turn True, np.True_ and "30" into numbers
            array = np.asarray(values, dtype=object)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"got {type(values).__name__} ({exc})") from None
    if array.dtype.kind in "iuf":
        # a long double beyond a float's range becomes inf, which the caller's range check
        # names (numpy's overflow warning was printed first: hostile round 29)
        with np.errstate(over="ignore"):
            return np.asarray(array, dtype=np.float64)
    if array.dtype.kind != "O":
        raise ValueError(f"got {_KIND_WHAT.get(array.dtype.kind, str(array.dtype))}")
    for kind in {type(v) for v in array.flat}:  # the kinds only: fast over 1e6 elements
        if not (issubclass(kind, numbers.Real) and not issubclass(kind, bool | np.timedelta64)):
            raise ValueError(f"got {_what(kind)}")
    try:
        with np.errstate(over="ignore"):  # as above
            return np.asarray(array.astype(np.float64), dtype=np.float64)
    except OverflowError:
        raise ValueError("got an integer beyond a float's range (1.8e308)") from None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"got values that are not real numbers ({exc})") from None


def shown(value: object, limit: int = 80) -> str:
    """``repr(value)`` for an error line, cut to ``limit`` characters; an int beyond 64
    bits as its number of digits (``repr(10**5000)`` is itself a ``ValueError``)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        digits = math.floor(math.log10(abs(value))) + 1
        return f"{'a negative' if value < 0 else 'an'} integer of {digits} digits"
    try:
        text = repr(value)
    except ValueError:  # a container holding such an int
        return f"a {type(value).__name__} holding an integer too long to print"
    return text if len(text) <= limit else text[: limit - 3] + "..."


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


#: The longest number text read (an option's value, a CSV field, an OpenDRIVE attribute),
#: characters: a probe CSV's field limit (``coverage.pointsio.MAX_FIELD_CHARS``) is this
#: one (a 400-character cap of its own refused a valid 503-character "10.000...0" as "not a
#: number": hostile round eighteen, F13).
MAX_NUMBER_CHARS = 1_000


def parse_decimal(text: str) -> float:
    """A plain decimal number (``_DECIMAL``; surrounding spaces allowed) as a float;
    anything else -> ``ValueError``. Values beyond the float range are ``inf``; callers
    check finiteness and range. ``-0`` is 0 (it was kept: ``--height -0`` wrote
    ``"height_m": -0.0`` where 0 wrote 0.0, other files for the same input; hostile round
    42, F3)."""
    t = text.strip()
    if len(t) > MAX_NUMBER_CHARS or not _DECIMAL.fullmatch(t):
        raise ValueError(f"not a plain decimal number: {text[:80]!r}")
    return float(t) + 0.0


def parse_integer(text: str) -> int:
    """A plain integer (optional sign and digits; no '_' separators) -> ``ValueError``."""
    t = text.strip()
    if len(t) > MAX_NUMBER_CHARS or not _INTEGER.fullmatch(t):
        raise ValueError(f"not a plain integer: {text[:80]!r}")
    return int(t)
