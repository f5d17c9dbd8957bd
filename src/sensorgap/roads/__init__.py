"""Roads layer: hardened OpenDRIVE reader, road geometry, lane graph, coordinate transforms.

Frames: OpenDRIVE inertial frame (x east, y north, m; headings rad CCW from x); road frame
(s along the reference line, t to its left, m). Left lanes have positive ids and t, right
lanes negative. See ``docs/roads.md``.
"""

from sensorgap.roads.geometry import Arc, Geometry, Line, ParamPoly3, Poly3, Spiral
from sensorgap.roads.model import (
    Connection,
    CubicPiece,
    Junction,
    Lane,
    LaneSection,
    Road,
    RoadLink,
)
from sensorgap.roads.network import LaneKey, RoadNetwork
from sensorgap.roads.opendrive import read_opendrive
from sensorgap.roads.schema import opendrive_xsd_path, xsd_errors
from sensorgap.roads.xmlsafe import DEFAULT_MAX_BYTES, parse_xml_file

__all__ = [
    "DEFAULT_MAX_BYTES",
    "Arc",
    "Connection",
    "CubicPiece",
    "Geometry",
    "Junction",
    "Lane",
    "LaneKey",
    "LaneSection",
    "Line",
    "ParamPoly3",
    "Poly3",
    "Road",
    "RoadLink",
    "RoadNetwork",
    "Spiral",
    "opendrive_xsd_path",
    "parse_xml_file",
    "read_opendrive",
    "xsd_errors",
]
