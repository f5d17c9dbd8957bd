"""OpenDRIVE text builders for the roads tests (small valid documents to break on purpose)."""

from __future__ import annotations

from pathlib import Path

ROADS_DIR = Path(__file__).resolve().parents[2] / "roads"

LANE = (
    '<lane id="{id}" type="{type}"><link>{links}</link>'
    '<width sOffset="0" a="{w}" b="0" c="0" d="0"/></lane>'
)


def lane_xml(lane_id: int, width: float = 3.5, lane_type: str = "driving", links: str = "") -> str:
    """One lane with a constant width (m)."""
    return LANE.format(id=lane_id, type=lane_type, links=links, w=width)


def section_xml(s: float = 0.0, left: str | None = None, right: str | None = None) -> str:
    """A lane section; by default one 3.5 m driving lane each side."""
    left = lane_xml(1) if left is None else left
    right = lane_xml(-1) if right is None else right
    parts = [f'<laneSection s="{s}">']
    if left:
        parts.append(f"<left>{left}</left>")
    parts.append('<center><lane id="0" type="none"/></center>')
    if right:
        parts.append(f"<right>{right}</right>")
    parts.append("</laneSection>")
    return "".join(parts)


def road_xml(
    road_id: str = "1",
    length: float = 100.0,
    geometry: str | None = None,
    lanes: str | None = None,
    link: str = "",
    junction: str = "-1",
    attrs: str = "",
) -> str:
    """A road; by default a straight line along +x from the origin with one section."""
    geometry = (
        f'<geometry s="0" x="0" y="0" hdg="0" length="{length}"><line/></geometry>'
        if geometry is None
        else geometry
    )
    lanes = f"<lanes>{section_xml()}</lanes>" if lanes is None else lanes
    return (
        f'<road id="{road_id}" length="{length}" junction="{junction}" {attrs}>'
        f"<link>{link}</link><planView>{geometry}</planView>{lanes}</road>"
    )


def document(*bodies: str) -> str:
    """A full OpenDRIVE 1.7 document around roads/junctions."""
    return (
        '<?xml version="1.0" encoding="utf-8"?>\n<OpenDRIVE>\n'
        '<header revMajor="1" revMinor="7" name="test"/>\n' + "\n".join(bodies) + "\n</OpenDRIVE>\n"
    )
