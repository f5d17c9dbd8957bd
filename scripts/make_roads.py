#!/usr/bin/env python3
"""Generate the committed OpenDRIVE 1.7 road files in ``roads/`` with scenariogeneration.

    PYTHONPATH=src python scripts/make_roads.py            # (re)write roads/*.xodr
    PYTHONPATH=src python scripts/make_roads.py --check    # exit 1 if roads/ is out of date

Every file is checked against the OpenDRIVE 1.7 XSD (shipped with scenariogeneration) and
read back with ``sensorgap.roads.read_opendrive`` before it is written (atomically). The
output is deterministic: the header date scenariogeneration stamps is replaced by a fixed
value, so two runs give byte-identical files.

Frames: OpenDRIVE inertial frame, x east, y north (m), headings rad CCW from x; right-hand
traffic, so lanes -1, -2, ... carry traffic along +s and lanes 1, 2, ... against it.

``motorway_r500.xodr`` (road 1, Ponn 2019 far-field road):
    Four-lane motorway, two 3.75 m driving lanes per direction. Reference line (the median
    line, t = 0): 500 m straight from (0, 0) heading east, a 100 m clothoid from curvature 0
    to 1/500 1/m, then a 700 m arc of R = 500 m turning LEFT (towards +y); 1300 m in all.
    For the ego driving in +s: lane -1 (t in [-3.75, 0], centre t = -1.875) is the LEFT
    lane (inner, next to the median; inner side of the left-hand curve), lane -2 (t in
    [-7.5, -3.75], centre t = -5.625) the RIGHT lane. The paper's set-up: ego in lane -1
    approaching the curve, target car in lane -2. Lanes 1, 2 are the opposite carriageway.

``motorway_3lane.xodr`` (road 1, three-lane motorway for the cut-in-behind-a-truck family):
    Six-lane motorway, three 3.75 m driving lanes per direction (the lane width of
    motorway_r500; EU motorway lanes are 3.5-3.75 m). Reference line (the median line,
    t = 0): 1000 m straight from (0, 0) heading east, a 100 m clothoid from curvature 0 to
    1/1000 1/m, then a 400 m arc of R = 1000 m turning LEFT; 1500 m in all. For the ego
    driving in +s: lane -1 (centre t = -1.875) is the LEFT lane, lane -2 (centre t =
    -5.625) the MIDDLE lane, lane -3 (centre t = -9.375) the RIGHT lane. Lanes 1, 2, 3 are
    the opposite carriageway.

``rural_two_lane.xodr`` (road 1):
    Two-lane rural road, one 3.5 m driving lane per direction (-1 along +s, 1 against).
    Straights and arcs of R = 150 m (left), 300 m (right) and 800 m (left), each entered and
    left through clothoids (curvature linear to/from 0); 1760 m in all.

``urban_junction.xodr``:
    Four-way junction (id 100) centred on the origin. Arms 1 (east), 2 (north), 3 (west),
    4 (south): 100 m straight roads whose reference lines start 12 m from the centre and
    point away from it; lane -1 (3.25 m, driving) leaves the junction, lane 1 (3.25 m,
    driving) enters it, lanes -2 and 2 are 2 m sidewalks. Connecting roads 101-112 (three
    per arm: right turn, straight, left turn) start on the arm of entry and end on the arm
    of exit (contact point start on both); each carries one driving lane -1 (lane 1 of the
    entry arm -> lane -1 of the exit arm); right turns are quarter circles of R = 12 m and
    also carry the corner sidewalk (lane -2, from sidewalk 2 of the entry arm to sidewalk
    -2 of the exit arm); left turns are quarter circles of R = 12 m, straights 24 m lines.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

from scenariogeneration import xodr

ROOT = Path(__file__).resolve().parents[1]
try:
    from sensorgap.atomic import atomic_write_bytes
    from sensorgap.roads import read_opendrive, xsd_errors
except ModuleNotFoundError:  # run from a checkout without installing: use src/
    sys.path.insert(0, str(ROOT / "src"))
    from sensorgap.atomic import atomic_write_bytes
    from sensorgap.roads import read_opendrive, xsd_errors

#: Replaces the generation time scenariogeneration writes into the header.
FIXED_DATE = "2024-01-01T00:00:00"

MOTORWAY_LANE_WIDTH = 3.75  # m
RURAL_LANE_WIDTH = 3.5  # m
URBAN_LANE_WIDTH = 3.25  # m
SIDEWALK_WIDTH = 2.0  # m
JUNCTION_HALF_SIZE = 12.0  # m, distance of the arm starts from the junction centre
ARM_LENGTH = 100.0  # m
JUNCTION_ID = 100


def _mark(kind: xodr.RoadMarkType) -> xodr.RoadMark:
    return xodr.RoadMark(kind, 0.15)


def _lane(width: float, lane_type: xodr.LaneType = xodr.LaneType.driving,
          mark: xodr.RoadMarkType | None = None) -> xodr.Lane:
    lane = xodr.Lane(lane_type, a=width)
    if mark is not None:
        lane.add_roadmark(_mark(mark))
    return lane


def _center(mark: xodr.RoadMarkType | None) -> xodr.Lane:
    lane = xodr.Lane(xodr.LaneType.none)
    if mark is not None:
        lane.add_roadmark(_mark(mark))
    return lane


def _opendrive(name: str) -> xodr.OpenDrive:
    return xodr.OpenDrive(name, revMajor="1", revMinor="7")


def _divided_motorway(name: str, straight_m: float, radius_m: float, arc_m: float,
                      lanes_per_side: int) -> xodr.OpenDrive:
    """Road 1 ``name``: a straight, a 100 m clothoid into a left-hand arc of ``radius_m``;
    ``lanes_per_side`` 3.75 m lanes each way, broken marks between lanes, solid outside."""
    curv = 1.0 / radius_m
    pv = xodr.PlanView(0.0, 0.0, 0.0)
    pv.add_geometry(xodr.Line(straight_m))
    pv.add_geometry(xodr.Spiral(0.0, curv, length=100.0))
    pv.add_geometry(xodr.Arc(curv, length=arc_m))
    sec = xodr.LaneSection(0, _center(xodr.RoadMarkType.solid_solid))
    solid, broken = xodr.RoadMarkType.solid, xodr.RoadMarkType.broken
    for mark in (broken,) * (lanes_per_side - 1) + (solid,):  # inner lane first: -1 / 1
        sec.add_right_lane(_lane(MOTORWAY_LANE_WIDTH, mark=mark))
        sec.add_left_lane(_lane(MOTORWAY_LANE_WIDTH, mark=mark))
    lanes = xodr.Lanes()
    lanes.add_lanesection(sec)
    odr = _opendrive(name)
    odr.add_road(xodr.Road(1, pv, lanes, name=name))
    odr.adjust_roads_and_lanes()
    return odr


def motorway() -> xodr.OpenDrive:
    """Ponn 2019 far-field road: 500 m straight, 100 m clothoid, 700 m arc of R = 500 m."""
    return _divided_motorway("motorway_r500", 500.0, 500.0, 700.0, 2)


def motorway_3lane() -> xodr.OpenDrive:
    """Three lanes per direction: 1000 m straight, 100 m clothoid, 400 m arc of R = 1000 m."""
    return _divided_motorway("motorway_3lane", 1000.0, 1000.0, 400.0, 3)


def rural() -> xodr.OpenDrive:
    """Two-lane rural road: straights and clothoid-arc-clothoid curves, R 150/300/800 m."""
    pv = xodr.PlanView(0.0, 0.0, 0.0)
    # (radius m, sign: +1 left / -1 right, clothoid length m, arc length m, straight after m)
    curves = ((150.0, 1, 60.0, 150.0, 150.0), (300.0, -1, 70.0, 250.0, 150.0),
              (800.0, 1, 50.0, 300.0, 200.0))
    pv.add_geometry(xodr.Line(200.0))
    for radius, sign, cloth, arc, straight in curves:
        k = sign / radius
        pv.add_geometry(xodr.Spiral(0.0, k, length=cloth))
        pv.add_geometry(xodr.Arc(k, length=arc))
        pv.add_geometry(xodr.Spiral(k, 0.0, length=cloth))
        pv.add_geometry(xodr.Line(straight))
    sec = xodr.LaneSection(0, _center(xodr.RoadMarkType.broken))
    sec.add_right_lane(_lane(RURAL_LANE_WIDTH, mark=xodr.RoadMarkType.solid))
    sec.add_left_lane(_lane(RURAL_LANE_WIDTH, mark=xodr.RoadMarkType.solid))
    lanes = xodr.Lanes()
    lanes.add_lanesection(sec)
    odr = _opendrive("rural_two_lane")
    odr.add_road(xodr.Road(1, pv, lanes, name="rural_two_lane"))
    odr.adjust_roads_and_lanes()
    return odr


#: Arm id -> start point (m) and outward heading (rad).
ARMS: dict[int, tuple[float, float, float]] = {
    1: (JUNCTION_HALF_SIZE, 0.0, 0.0),
    2: (0.0, JUNCTION_HALF_SIZE, math.pi / 2),
    3: (-JUNCTION_HALF_SIZE, 0.0, math.pi),
    4: (0.0, -JUNCTION_HALF_SIZE, -math.pi / 2),
}


def _arm_towards(heading: float) -> int:
    """The arm whose outward heading is ``heading`` (rad)."""
    for rid, (_, _, h) in ARMS.items():
        if abs(math.remainder(h - heading, 2.0 * math.pi)) < 1e-9:
            return rid
    raise ValueError(f"no arm with heading {heading}")


def urban_junction() -> xodr.OpenDrive:
    """Four-way urban junction, one lane per direction plus sidewalks on every arm."""
    odr = _opendrive("urban_junction")
    for rid, (x, y, h) in ARMS.items():
        pv = xodr.PlanView(x, y, h)
        pv.add_geometry(xodr.Line(ARM_LENGTH))
        pv.adjust_geometries()
        sec = xodr.LaneSection(0, _center(xodr.RoadMarkType.solid))
        sec.add_right_lane(_lane(URBAN_LANE_WIDTH, mark=xodr.RoadMarkType.solid))
        sec.add_right_lane(_lane(SIDEWALK_WIDTH, xodr.LaneType.sidewalk))
        sec.add_left_lane(_lane(URBAN_LANE_WIDTH, mark=xodr.RoadMarkType.solid))
        sec.add_left_lane(_lane(SIDEWALK_WIDTH, xodr.LaneType.sidewalk))
        lanes = xodr.Lanes()
        lanes.add_lanesection(sec)
        road = xodr.Road(rid, pv, lanes, name=f"arm_{rid}")
        road.add_predecessor(xodr.ElementType.junction, JUNCTION_ID)
        odr.add_road(road)

    junction = xodr.Junction("crossing", JUNCTION_ID)
    cid = JUNCTION_ID + 1
    d = JUNCTION_HALF_SIZE
    for rid, (x, y, h) in ARMS.items():
        entry = math.remainder(h + math.pi, 2.0 * math.pi)  # heading into the junction
        for turn, dh in (("right", -math.pi / 2), ("straight", 0.0), ("left", math.pi / 2)):
            exit_arm = _arm_towards(entry + dh)
            pv = xodr.PlanView(x, y, entry)
            if turn == "straight":
                pv.add_geometry(xodr.Line(2.0 * d))
            else:
                pv.add_geometry(xodr.Arc(math.copysign(1.0 / d, dh), angle=math.pi / 2))
            pv.adjust_geometries()
            sec = xodr.LaneSection(0, _center(None))
            drive = _lane(URBAN_LANE_WIDTH)
            drive.add_link("predecessor", 1)
            drive.add_link("successor", -1)
            sec.add_right_lane(drive)
            conn = xodr.Connection(rid, cid, xodr.ContactPoint.start)
            conn.add_lanelink(1, -1)
            if turn == "right":
                walk = _lane(SIDEWALK_WIDTH, xodr.LaneType.sidewalk)
                walk.add_link("predecessor", 2)
                walk.add_link("successor", -2)
                sec.add_right_lane(walk)
                conn.add_lanelink(2, -2)
            lanes = xodr.Lanes()
            lanes.add_lanesection(sec)
            road = xodr.Road(cid, pv, lanes, road_type=JUNCTION_ID,
                             name=f"{turn}_{rid}_to_{exit_arm}")
            road.add_predecessor(xodr.ElementType.road, rid, xodr.ContactPoint.start)
            road.add_successor(xodr.ElementType.road, exit_arm, xodr.ContactPoint.start)
            odr.add_road(road)
            junction.add_connection(conn)
            cid += 1
    odr.add_junction(junction)
    return odr


#: Output file name -> builder.
BUILDERS: dict[str, Callable[[], xodr.OpenDrive]] = {
    "motorway_3lane.xodr": motorway_3lane,
    "motorway_r500.xodr": motorway,
    "rural_two_lane.xodr": rural,
    "urban_junction.xodr": urban_junction,
}


def render(odr: xodr.OpenDrive) -> bytes:
    """The file content: indented UTF-8 XML with the header date fixed to ``FIXED_DATE``."""
    root = odr.get_element()
    header = root.find("header")
    if header is None:  # pragma: no cover - scenariogeneration always writes one
        raise RuntimeError("scenariogeneration wrote no <header>")
    header.set("date", FIXED_DATE)
    ET.indent(root, space="  ")
    text = ET.tostring(root, encoding="unicode")
    return ('<?xml version="1.0" encoding="utf-8"?>\n' + text + "\n").encode("utf-8")


def build(name: str) -> bytes:
    """Generate, render and check one file (XSD 1.7 and sensorgap's reader)."""
    data = render(BUILDERS[name]())
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / name
        path.write_bytes(data)
        errors = xsd_errors(path)
        if errors:
            raise RuntimeError(f"{name} violates the OpenDRIVE 1.7 XSD: " + "; ".join(errors))
        read_opendrive(path)
    return data


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` compare) every road file; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--out", type=Path, default=ROOT / "roads", help="output folder")
    ap.add_argument("--check", action="store_true",
                    help="do not write; exit 1 if a file is missing or differs")
    args = ap.parse_args(argv)
    stale = []
    for name in BUILDERS:
        data = build(name)
        target = args.out / name
        if args.check:
            if not target.is_file() or target.read_bytes() != data:
                stale.append(name)
            continue
        atomic_write_bytes(target, data)
        print(f"wrote {target} ({len(data)} bytes)")
    if stale:
        print(f"out of date in {args.out}: {', '.join(stale)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
