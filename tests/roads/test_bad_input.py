"""Hostile and invalid files: each is one InputError naming the file and the element."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from sensorgap.errors import InputError
from sensorgap.roads import read_opendrive

from .builders import document, lane_xml, road_xml, section_xml

Write = Callable[..., Path]


def _fails(path: Path, pattern: str, **kw: int) -> InputError:
    with pytest.raises(InputError) as info:
        read_opendrive(path, **kw)
    err = info.value
    line = str(err)
    assert path.name in line and "\n" not in line
    assert err.source == str(path)
    assert pattern in line, line
    return err


VALID = document(road_xml())


def test_valid_minimal_document_reads(write_xodr: Write) -> None:
    net = read_opendrive(write_xodr(VALID))
    assert list(net.roads) == ["1"] and net.road(1).length == 100.0


# -- hostile XML ------------------------------------------------------------------------


def test_external_entity_is_rejected(write_xodr: Write, tmp_path: Path) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text("TOPSECRET", encoding="utf-8")
    text = VALID.replace(
        "<OpenDRIVE>", f'<!DOCTYPE OpenDRIVE [<!ENTITY xxe SYSTEM "file://{secret}">]>\n<OpenDRIVE>'
    ).replace('name="test"', 'name="&xxe;"')
    err = _fails(write_xodr(text, "xxe.xodr"), "DOCTYPE")
    assert "TOPSECRET" not in str(err)


def test_billion_laughs_is_rejected_fast(write_xodr: Write) -> None:
    ents = '<!ENTITY lol0 "lol">' + "".join(
        f'<!ENTITY lol{i} "{f"&lol{i - 1};" * 10}">' for i in range(1, 12)
    )
    text = VALID.replace("<OpenDRIVE>", f"<!DOCTYPE OpenDRIVE [{ents}]>\n<OpenDRIVE>").replace(
        'name="test"', 'name="&lol11;"'
    )
    t0 = time.perf_counter()
    _fails(write_xodr(text, "lol.xodr"), "entity declarations")
    assert time.perf_counter() - t0 < 1.0


def test_entities_in_utf16_are_rejected_after_a_non_expanding_parse(
    write_xodr: Write, tmp_path: Path
) -> None:
    # UTF-16 hides the declaration from the byte pre-scan; the parsed DOCTYPE still shows it
    text = VALID.replace('encoding="utf-8"', 'encoding="utf-16"').replace(
        "<OpenDRIVE>", '<!DOCTYPE OpenDRIVE [<!ENTITY e "x">]>\n<OpenDRIVE>'
    )
    path = tmp_path / "utf16.xodr"
    path.write_bytes(text.encode("utf-16"))
    _fails(path, "DOCTYPE")


def test_external_dtd_is_rejected_but_bare_doctype_is_fine(write_xodr: Write) -> None:
    ext = VALID.replace(
        "<OpenDRIVE>", '<!DOCTYPE OpenDRIVE SYSTEM "http://example.com/x.dtd">\n<OpenDRIVE>'
    )
    _fails(write_xodr(ext, "ext.xodr"), "external DTD")
    bare = VALID.replace("<OpenDRIVE>", "<!DOCTYPE OpenDRIVE>\n<OpenDRIVE>")
    assert list(read_opendrive(write_xodr(bare, "bare.xodr")).roads) == ["1"]


def test_file_over_the_size_limit_is_rejected_before_reading(tmp_path: Path) -> None:
    path = tmp_path / "huge.xodr"
    with open(path, "wb") as fh:  # 100 MB sparse file: a header, then a hole
        fh.write(b'<?xml version="1.0"?>\n<OpenDRIVE>')
        fh.seek(100 * 1024 * 1024)
        fh.write(b"</OpenDRIVE>")
    t0 = time.perf_counter()
    _fails(path, "larger than the limit of 52428800 bytes")
    assert time.perf_counter() - t0 < 0.5


def test_size_limit_is_configurable(write_xodr: Write) -> None:
    path = write_xodr(VALID, "small.xodr")
    _fails(path, "larger than the limit of 200 bytes", max_bytes=200)
    assert read_opendrive(path, max_bytes=len(VALID.encode()))  # exactly at the limit: fine


def test_malformed_xml_names_the_line(write_xodr: Write) -> None:
    text = VALID.replace("</planView>", "</planview>")
    _fails(write_xodr(text, "broken.xodr"), "malformed XML")
    _fails(write_xodr("", "empty.xodr"), "malformed XML")
    _fails(write_xodr("<OpenDRIVE><header/>&undefined;</OpenDRIVE>", "undef.xodr"), "malformed XML")


def test_missing_file_and_folder(tmp_path: Path) -> None:
    _fails(tmp_path / "nope.xodr", "file not found")
    folder = tmp_path / "dir.xodr"
    folder.mkdir()
    _fails(folder, "not a regular file")


# -- invalid OpenDRIVE ------------------------------------------------------------------


def test_wrong_root_and_missing_header(write_xodr: Write) -> None:
    _fails(write_xodr("<Road/>", "root.xodr"), "root element must be <OpenDRIVE>")
    _fails(
        write_xodr(
            VALID.replace('<header revMajor="1" revMinor="7" name="test"/>', ""), "nohdr.xodr"
        ),
        "header: missing",
    )
    _fails(write_xodr(document(), "noroad.xodr"), "must contain at least one <road>")


def test_negative_geometry_length(write_xodr: Write) -> None:
    geo = (
        '<geometry s="0" x="0" y="0" hdg="0" length="50"><line/></geometry>'
        '<geometry s="50" x="50" y="0" hdg="0" length="-5"><line/></geometry>'
    )
    path = write_xodr(document(road_xml(road_id="3", geometry=geo)), "neg.xodr")
    err = _fails(path, "road[id=3]/planView/geometry[1]@length: must be at least 1e-09 m, got -5")
    assert err.field == "road[id=3]/planView/geometry[1]@length"


def test_nan_and_text_numbers(write_xodr: Write) -> None:
    nan = VALID.replace('length="100.0"><line', 'length="NaN"><line')
    _fails(write_xodr(nan, "nan.xodr"), "geometry[0]@length: must be a finite number")
    txt = VALID.replace('x="0"', 'x="east"', 1)
    _fails(write_xodr(txt, "txt.xodr"), "geometry[0]@x: must be a number, got 'east'")
    miss = VALID.replace(' hdg="0"', "", 1)
    _fails(write_xodr(miss, "miss.xodr"), "geometry[0]@hdg: required attribute is missing")


def test_geometry_gap_overlap_and_length_mismatch(write_xodr: Write) -> None:
    two = (
        '<geometry s="0" x="0" y="0" hdg="0" length="50"><line/></geometry>'
        '<geometry s="{s}" x="50" y="0" hdg="0" length="50"><line/></geometry>'
    )
    gap = document(road_xml(geometry=two.format(s=51)))
    _fails(write_xodr(gap, "gap.xodr"), "geometry[1]@s: must be 50")
    _fails(write_xodr(gap, "gap.xodr"), "a gap of 1 m after geometry[0]")
    over = document(road_xml(geometry=two.format(s=49)))
    _fails(write_xodr(over, "over.xodr"), "an overlap of 1 m after geometry[0]")
    short = document(
        road_xml(
            length=100,
            geometry='<geometry s="0" x="0" y="0" hdg="0" length="90"><line/></geometry>',
        )
    )
    _fails(
        write_xodr(short, "short.xodr"),
        "road[id=1]@length: must equal the end of the last planView geometry (90 m)",
    )
    none = document(road_xml(geometry=""))
    _fails(write_xodr(none, "nogeo.xodr"), "planView: must contain at least one <geometry>")
    two_kinds = document(
        road_xml(
            geometry='<geometry s="0" x="0" y="0" hdg="0" '
            'length="100"><line/><arc curvature="0.1"/></geometry>'
        )
    )
    _fails(write_xodr(two_kinds, "kinds.xodr"), "must contain exactly one of line, arc")


def test_road_without_lanes(write_xodr: Write) -> None:
    _fails(write_xodr(document(road_xml(lanes="")), "nolanes.xodr"), "road[id=1]/lanes: missing")
    _fails(
        write_xodr(document(road_xml(lanes="<lanes/>")), "nosec.xodr"),
        "must contain at least one <laneSection>",
    )
    empty = document(road_xml(lanes=f"<lanes>{section_xml(left='', right='')}</lanes>"))
    _fails(write_xodr(empty, "empty_sec.xodr"), "road[id=1]/lanes/laneSection[0]: has no lanes")


def test_missing_lane(write_xodr: Write) -> None:
    gap = document(
        road_xml(lanes=f"<lanes>{section_xml(right=lane_xml(-1) + lane_xml(-3))}</lanes>")
    )
    _fails(write_xodr(gap, "gap_ids.xodr"), "laneSection[0]/right: lane ids must be -1, -2")
    bare_lane = '<lane id="-1" type="driving"/>'
    nowidth = document(road_xml(lanes=f"<lanes>{section_xml(right=bare_lane)}</lanes>"))
    _fails(write_xodr(nowidth, "nowidth.xodr"), "lane[id=-1]: needs at least one <width>")
    neg = document(road_xml(lanes=f"<lanes>{section_xml(right=lane_xml(-1, width=-1.0))}</lanes>"))
    _fails(write_xodr(neg, "negw.xodr"), "lane[id=-1]/width[0]: width must be >= 0")
    # positive at both ends of the 20 m section, -0.5 m in the middle (u = 10)
    dip = '<lane id="-1" type="driving"><width sOffset="0" a="1" b="-0.3" c="0.015" d="0"/></lane>'
    dipped = document(road_xml(length=20.0, lanes=f"<lanes>{section_xml(right=dip)}</lanes>"))
    _fails(write_xodr(dipped, "dip.xodr"), "width[0]: width must be >= 0, got -0.5 m at sOffset 10")
    # a lane link to a lane that the next road does not have
    linked = lane_xml(-1, links='<successor id="-2"/>')
    r1 = road_xml(
        "1",
        link='<successor elementType="road" elementId="2" contactPoint="start"/>',
        lanes=f"<lanes>{section_xml(right=linked)}</lanes>",
    )
    r2 = road_xml(
        "2", geometry='<geometry s="0" x="100" y="0" hdg="0" length="100"><line/></geometry>'
    )
    _fails(
        write_xodr(document(r1, r2), "lanelink.xodr"),
        "road[id=1]/lanes/laneSection[0]/right/lane[id=-1]/link/successor@id: lane -2 does "
        "not exist in road 2 laneSection[0] (lanes: -1, 1)",
    )


def test_references_to_missing_roads_and_junctions(write_xodr: Write) -> None:
    link = road_xml("1", link='<successor elementType="road" elementId="99" contactPoint="start"/>')
    _fails(
        write_xodr(document(link), "r99.xodr"),
        "road[id=1]/link/successor@elementId: road 99 does not exist",
    )
    jlink = road_xml("1", link='<predecessor elementType="junction" elementId="7"/>')
    _fails(write_xodr(document(jlink), "j7.xodr"), "junction 7 does not exist")
    member = road_xml("1", junction="5")
    _fails(
        write_xodr(document(member), "member.xodr"),
        "road[id=1]@junction: junction 5 does not exist",
    )
    no_cp = road_xml("1", link='<successor elementType="road" elementId="1"/>')
    _fails(write_xodr(document(no_cp), "nocp.xodr"), "successor@contactPoint: required")
    dup = document(road_xml("1"), road_xml("1"))
    _fails(write_xodr(dup, "dup.xodr"), "road[id=1]@id: duplicate road id")


def test_junction_connection_errors(write_xodr: Write) -> None:
    arm = road_xml("1", link='<successor elementType="junction" elementId="9"/>')
    conn = road_xml(
        "2", junction="9", link='<predecessor elementType="road" elementId="1" contactPoint="end"/>'
    )

    def junction(body: str) -> str:
        return f'<junction id="9" name="j">{body}</junction>'

    good = (
        '<connection id="0" incomingRoad="1" connectingRoad="2" contactPoint="start">'
        '<laneLink from="-1" to="-1"/></connection>'
    )
    net = read_opendrive(write_xodr(document(arm, conn, junction(good)), "ok.xodr"))
    assert net.junctions["9"].connections[0].incoming_end == "end"
    assert net.lane_graph.has_edge(("1", 0, -1), ("2", 0, -1))
    missing = good.replace('connectingRoad="2"', 'connectingRoad="42"')
    _fails(
        write_xodr(document(arm, conn, junction(missing)), "c42.xodr"),
        "junction[id=9]/connection[id=0]@connectingRoad: road 42 does not exist",
    )
    bad_lane = good.replace('from="-1"', 'from="-4"')
    _fails(
        write_xodr(document(arm, conn, junction(bad_lane)), "c4.xodr"),
        "connection[id=0]/laneLink[0]@from: lane -4 does not exist at the end of road 1",
    )
    bad_to = good.replace('to="-1"', 'to="3"')
    _fails(
        write_xodr(document(arm, conn, junction(bad_to)), "c3.xodr"),
        "laneLink[0]@to: lane 3 does not exist at the start of road 2",
    )
    unlinked = road_xml("1")
    _fails(
        write_xodr(document(unlinked, conn, junction(good)), "unl.xodr"),
        "road 1 is not linked to junction 9",
    )
    outside = road_xml(
        "2", link='<predecessor elementType="road" elementId="1" contactPoint="end"/>'
    )
    _fails(
        write_xodr(document(arm, outside, junction(good)), "outside.xodr"),
        "road 2 must belong to junction 9",
    )


def _with_elevation(profile: str) -> str:
    return document(road_xml().replace("</planView>", f"</planView>{profile}"))


def test_elevation_profile_is_checked_not_modelled(write_xodr: Write) -> None:
    """A hilly but real road reads (8 % grade); a road 10,000 km up, one steeper than 0.5 m/m
    on a piece (grade b + 3 d ds^2, worst at the road end, by hand: ds = 50 m,
    0.02 + 3e-4 * 2500 = 0.77) and pieces out of order are refused in one line."""
    hilly = _with_elevation(
        '<elevationProfile><elevation s="0" a="250" b="0.08" c="0" d="0"/>'
        '<elevation s="50" a="254" b="0.08" c="-0.0008" d="0"/></elevationProfile>'
    )
    flat = read_opendrive(write_xodr(VALID, "flat.xodr"))
    net = read_opendrive(write_xodr(hilly, "hilly.xodr"))
    assert net.road(1).length == flat.road(1).length == 100.0
    high = _with_elevation(
        '<elevationProfile><elevation s="0" a="1e7" b="0" c="0" d="0"/></elevationProfile>'
    )
    _fails(write_xodr(high, "high.xodr"), "the height must stay within +-10000 m")
    steep = _with_elevation(
        '<elevationProfile><elevation s="0" a="0" b="0" c="0" d="0"/>'
        '<elevation s="50" a="0" b="0.02" c="0" d="1e-4"/></elevationProfile>'
    )
    _fails(
        write_xodr(steep, "steep.xodr"),
        "elevation[1]: the grade must stay within +-0.5 m/m, reaches 0.77 m/m at s 100",
    )
    unordered = _with_elevation(
        '<elevationProfile><elevation s="60" a="0" b="0" c="0" d="0"/>'
        '<elevation s="10" a="0" b="0" c="0" d="0"/></elevationProfile>'
    )
    _fails(write_xodr(unordered, "unordered.xodr"), "elevation[1]@s: must not decrease")


def test_elevation_before_its_first_record_is_the_default_not_extrapolated(
    write_xodr: Write,
) -> None:
    """The standard's default elevation (0) holds before the first record, so a record at
    s = 90 is checked on [90, 100] only: by hand, grade 2 c ds reaches 2 * 0.02 * 10 = 0.4
    m/m at the road end (allowed); extrapolated back to s = 0 it would be -3.6 m/m."""
    late = _with_elevation(
        '<elevationProfile><elevation s="90" a="0" b="0" c="0.02" d="0"/></elevationProfile>'
    )
    assert read_opendrive(write_xodr(late, "late.xodr")).road(1).length == 100.0
    steeper = late.replace('c="0.02"', 'c="0.03"')  # 2 * 0.03 * 10 = 0.6 m/m at s 100
    _fails(
        write_xodr(steeper, "steeper.xodr"),
        "elevation[0]: the grade must stay within +-0.5 m/m, reaches 0.6 m/m at s 100",
    )


def _lane_m1(records: str) -> str:
    lane = f'<lane id="-1" type="driving">{records}</lane>'
    return document(road_xml(lanes=f"<lanes>{section_xml(right=lane)}</lanes>"))


def test_first_width_record_must_start_at_the_section_start(write_xodr: Write) -> None:
    """A width record starting at sOffset 70 left the width before it undefined (it was
    extrapolated: 3.75 + 0.05 * (4 - 70) = 0.45 m at 4, -0.25 m at 0); within 1 mm of the
    start it is read, and checked from the section start: by hand a = 0, b = 1 at
    sOffset 0.0005 is -0.0005 m wide at 0."""
    late = _lane_m1('<width sOffset="70" a="3.75" b="0.05" c="0" d="0"/>')
    _fails(
        write_xodr(late, "late.xodr"),
        "lane[id=-1]/width[0]@sOffset: the first width record must start at the lane section "
        "start (sOffset 0), got 70: the width before it is undefined",
    )
    near = _lane_m1('<width sOffset="0.0005" a="3.5" b="0" c="0" d="0"/>')
    np.testing.assert_allclose(
        read_opendrive(write_xodr(near, "near.xodr")).lane_width(1, -1, 0.0), 3.5
    )
    neg = _lane_m1('<width sOffset="0.0005" a="0" b="1" c="0" d="0"/>')
    _fails(write_xodr(neg, "neg.xodr"), "width[0]: width must be >= 0, got -0.0005 m at sOffset 0")
    unordered = _lane_m1(
        '<width sOffset="0" a="3" b="0" c="0" d="0"/><width sOffset="50" a="3" b="0" c="0" d="0"/>'
        '<width sOffset="20" a="3" b="0" c="0" d="0"/>'
    )
    _fails(
        write_xodr(unordered, "unordered.xodr"), "width[2]@sOffset: must not decrease (previous 50)"
    )


def _two_lines(hdg: str) -> str:
    return document(
        road_xml(
            geometry='<geometry s="0" x="0" y="0" hdg="0" length="50"><line/></geometry>'
            f'<geometry s="50" x="50" y="0" hdg="{hdg}" length="50"><line/></geometry>'
        )
    )


def test_heading_jump_between_geometries(write_xodr: Write) -> None:
    """End heading of geometry k against the start heading of k+1, modulo 2 pi, within 1 deg:
    by hand 0.0174 rad = 0.997 deg reads, 0.0176 rad = 1.00841 deg and 90 deg are refused;
    2 pi + 0.01 (0.573 deg) and -0.0174 read."""
    for hdg in ("0.0174", "-0.0174", repr(2 * math.pi + 0.01)):
        assert len(read_opendrive(write_xodr(_two_lines(hdg), "ok.xodr")).road(1).geometries) == 2
    _fails(
        write_xodr(_two_lines("0.0176"), "kink.xodr"),
        "geometry[1]@hdg: must continue geometry[0]'s end heading within 1 deg; at s 50 the "
        "heading jumps by 1.00841 deg",
    )
    _fails(write_xodr(_two_lines(repr(-math.pi / 2)), "corner.xodr"), "jumps by -90 deg")
    # an arc's end heading: 0 + 50 m * 0.01 1/m = 0.5 rad; the next line continues it
    arc = document(
        road_xml(
            geometry='<geometry s="0" x="0" y="0" hdg="0" length="50"><arc curvature="0.01"/>'
            "</geometry>"
            f'<geometry s="50" x="{100 * math.sin(0.5)!r}" y="{100 * (1 - math.cos(0.5))!r}" '
            'hdg="{h}" length="50"><line/></geometry>'
        )
    )
    assert read_opendrive(write_xodr(arc.replace("{h}", "0.5"), "arc.xodr"))
    _fails(write_xodr(arc.replace("{h}", "0"), "arc0.xodr"), "jumps by -28.6479 deg")


def _with_lateral(profile: str) -> str:
    return document(road_xml().replace("</planView>", f"</planView>{profile}"))


def test_superelevation_is_checked_not_modelled(write_xodr: Write) -> None:
    """A 12 % bank (AASHTO's highest rate, 0.12 rad) reads; by hand a = 0.5, b = 0.005 reaches
    1 rad at the road end (s 100) and is refused, and so is 1.5 rad (86 deg). A first record
    at s = 90 (a = 0, b = 0.06: 0.6 rad at s 100) is checked from 90 on: 0 before it (it
    would be -5.4 rad at s 0 extrapolated)."""
    for sup in ('s="0" a="0.12" b="0"', 's="90" a="0" b="0.06"'):
        ok = _with_lateral(f'<lateralProfile><superelevation {sup} c="0" d="0"/></lateralProfile>')
        assert read_opendrive(write_xodr(ok, "ok.xodr")).road(1).length == 100.0
    ramp = _with_lateral(
        '<lateralProfile><superelevation s="0" a="0.5" b="0.005" c="0" d="0"/></lateralProfile>'
    )
    _fails(
        write_xodr(ramp, "ramp.xodr"),
        "road[id=1]/lateralProfile/superelevation[0]: the angle must stay within +-0.7 rad, "
        "reaches 1 rad at s 100",
    )
    _fails(
        write_xodr(ramp.replace('a="0.5" b="0.005"', 'a="1.5" b="0"'), "bank.xodr"),
        "reaches 1.5 rad at s 0",
    )
    nan = ramp.replace('a="0.5"', 'a="nan"')
    _fails(write_xodr(nan, "nan.xodr"), "superelevation[0]@a: must be a finite number")


def test_shape_is_checked_over_the_cross_section(write_xodr: Write) -> None:
    """The road is 3.5 m wide each side (t in [-3.5, 3.5]). A 7 cm crown reads; by hand the
    last record (t = 0, b = 5) reaches 5 * 3.5 = 17.5 m at the left edge, and a single
    record (a = 0, b = -3, c = 0.1) extrapolated to the right edge 10.5 + 1.225 = 11.725 m at
    t -3.5: both refused."""
    crown = _with_lateral(
        '<lateralProfile><shape s="0" t="0" a="0.07" b="-0.02" c="0" d="0"/>'
        '<shape s="0" t="-3.5" a="0" b="0.02" c="0" d="0"/></lateralProfile>'
    )
    assert read_opendrive(write_xodr(crown, "crown.xodr")).road(1).length == 100.0
    steep = crown.replace('t="0" a="0.07" b="-0.02"', 't="0" a="0" b="5"')
    _fails(
        write_xodr(steep, "steep.xodr"),
        "lateralProfile/shape[0]: the height must stay within +-10 m, reaches 17.5 m at t 3.5",
    )
    one = _with_lateral(
        '<lateralProfile><shape s="0" t="0" a="0" b="-3" c="0.1" d="0"/></lateralProfile>'
    )
    _fails(
        write_xodr(one, "one.xodr"),
        "shape[0]: the height must stay within +-10 m, reaches 11.725 m at t -3.5",
    )
    high = _with_lateral(
        '<lateralProfile><shape s="0" t="0" a="1e4" b="0" c="0" d="0"/></lateralProfile>'
    )
    _fails(write_xodr(high, "high.xodr"), "reaches 10000 m at t 0")


def test_lane_height_is_bounded(write_xodr: Write) -> None:
    """A 15 cm curb reads; a lane raised 12 m (or 5 km) is refused on the attribute."""
    w = '<width sOffset="0" a="3.5" b="0" c="0" d="0"/>'
    curb = _lane_m1(w + '<height sOffset="0" inner="0.15" outer="0.15"/>')
    assert read_opendrive(write_xodr(curb, "curb.xodr")).road(1).length == 100.0
    high = _lane_m1(
        w + '<height sOffset="0" inner="0.15" outer="0.15"/>'
        '<height sOffset="10" inner="0.15" outer="-12"/>'
    )
    _fails(
        write_xodr(high, "high.xodr"),
        "lane[id=-1]/height[1]@outer: must be within +-10 m, got -12",
    )
    back = _lane_m1(
        w + '<height sOffset="10" inner="0" outer="0"/><height sOffset="5" inner="0" outer="0"/>'
    )
    _fails(write_xodr(back, "back.xodr"), "height[1]@sOffset: must not decrease (previous 10)")
