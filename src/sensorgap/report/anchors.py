"""The report's section on the anchor cases (``search.anchors``): Euro NCAP's obstructed
near-side pedestrian crossing evaluated exactly for the vehicle, from the run folder's
``anchors/anchors.json``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sensorgap.errors import InputError
from sensorgap.filesio import loads_json
from sensorgap.report.document import NOT_RUN, Para, Section, Table

TITLE = "Anchor cases: Euro NCAP obstructed near-side crossing"


#: The numbers of an anchor row the table prints, with their allowed range: a
#: probability, speeds (km/h) and times (s); None (JSON null) prints blank. NaN, inf, text
#: or -7 were printed as they were (hostile round 24).
_RANGES = {
    "vut_kmh": (0.0, 360.0),
    "pedestrian_kmh": (0.0, 360.0),
    "collision_probability": (0.0, 1.0),
    "impact_speed_kmh": (0.0, 720.0),
    "t_confirm_median_s": (0.0, 3600.0),
    "t_safe_s": (0.0, 3600.0),
}


def _num(r: dict[str, Any], key: str, fmt: str) -> str:
    v = r[key]
    if v is None:
        return ""
    lo, hi = _RANGES[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not lo <= v <= hi:
        raise ValueError(f"{key}: expected a number within {lo:g}..{hi:g}, got {str(v)[:40]!r}")
    return format(float(v), fmt)


def anchors_section(folder: Path) -> Section:
    """The anchor table (one row per test speed: class, P(collision), impact speed,
    confirmation and t_safe) with how each row is reproduced; one line when the run has
    none."""
    path = Path(folder) / "anchors" / "anchors.json"
    if not path.is_file():
        return Section("anchors", TITLE, [Para(NOT_RUN)])
    try:
        rows = loads_json(path.read_text(encoding="utf-8"))["anchors"]
        table = [
            [
                _num(r, "vut_kmh", ".0f"),
                _num(r, "pedestrian_kmh", ".0f"),
                str(r["class"]),
                _num(r, "collision_probability", ".2g"),
                _num(r, "impact_speed_kmh", ".1f"),
                _num(r, "t_confirm_median_s", ".2f"),
                _num(r, "t_safe_s", ".2f"),
                str(r.get("dominant_effect", "")),
            ]
            for r in rows
        ]
        command = str(rows[0]["command"]) if rows else ""
    except (ValueError, KeyError, TypeError, IndexError) as exc:
        raise InputError(path, "", f"malformed anchors file: {exc}") from None
    return Section(
        "anchors",
        TITLE,
        [
            Para(
                "The public test points of the pedestrian-behind-parked-cars family, evaluated "
                "exactly for this vehicle and its reaction model (not searched): the vehicle "
                "at 10-60 km/h, an adult pedestrian walking out at 5 km/h from between cars "
                "parked at the kerb on the right, the 50 % impact point without braking "
                "(Euro NCAP AEB VRU test protocol geometry; impact 4.5 s after the start and a "
                "1 m gap between the parked cars are estimates; docs/search.md)."
            ),
            Table(
                [
                    "vehicle km/h",
                    "pedestrian km/h",
                    "class",
                    "P(collision)",
                    "impact km/h",
                    "confirmed at s (median)",
                    "t_safe s",
                    "limiting effect",
                ],
                table,
                "Anchor cases (anchors/anchors.csv)",
            ),
            Para(
                "Each row is reproduced by `sensorgap evaluate` with its parameters "
                "(anchors/anchors.json holds the command of every row), e.g. " + command
            ),
        ],
    )
