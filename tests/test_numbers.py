"""Plain decimal numbers on the command line and in CSV files (held-out review round four:
Python's float() and int() accept '1_000')."""

from __future__ import annotations

import math

import pytest

from sensorgap.config.common import parse_decimal, parse_integer


@pytest.mark.parametrize(
    ("text", "want"),
    [
        ("1", 1.0),
        ("-1.5e3", -1500.0),
        (".5", 0.5),
        ("5.", 5.0),
        (" 2 ", 2.0),
        ("+3E-2", 0.03),
        ("1e400", math.inf),
        ("-inf", -math.inf),
        # 1,000 characters (MAX_NUMBER_CHARS, a probe CSV field's limit): a 400-character
        # cap of its own refused a 503-character 10 m (hostile round eighteen, F13)
        ("10." + "0" * 997, 10.0),
    ],
)
def test_plain_decimals(text: str, want: float) -> None:
    assert parse_decimal(text) == want


def test_nan_is_read_for_the_options_own_check() -> None:
    assert math.isnan(parse_decimal("NaN"))


@pytest.mark.parametrize(
    "text", ["1_000", "0x10", "1e", "", "e5", "1 0", "nan1", "\uff11", "1" * 1001]
)
def test_not_plain_decimals(text: str) -> None:
    with pytest.raises(ValueError, match="not a plain decimal number"):
        parse_decimal(text)


def test_integers() -> None:
    assert parse_integer(" -12 ") == -12
    for bad in ("1_000", "1.0", "1e3", "", "+"):
        with pytest.raises(ValueError, match="not a plain integer"):
            parse_integer(bad)


@pytest.mark.parametrize("text", ["-0", "-0.0", " -0.000e5 ", "+0", "0"])
def test_a_typed_negative_zero_is_zero(text: str) -> None:
    """Hostile round 42, F3: ``coverage --height -0`` wrote ``"height_m": -0.0`` where 0
    wrote 0.0 (and ``--extent``, ``farfield --ego-s``, ``corridor --start`` alike): other
    files for the same input. Every number typed on the command line is read by
    ``parse_decimal``, which gives +0."""
    import math

    from sensorgap.config.common import parse_decimal

    value = parse_decimal(text)
    assert value == 0.0 and math.copysign(1.0, value) == 1.0
