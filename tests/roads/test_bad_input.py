"""Hostile and invalid files: each is one InputError naming the file and the element."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

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
    err = _fails(path, "road[id=3]/planView/geometry[1]@length: must be > 0, got -5")
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
