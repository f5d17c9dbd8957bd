"""The committed road files: OpenDRIVE 1.7 XSD, content as documented, reproducible."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from sensorgap.roads import RoadNetwork, opendrive_xsd_path, xsd_errors

from .builders import ROADS_DIR, document, road_xml

FILES = sorted(ROADS_DIR.glob("*.xodr"))


def _make_roads() -> ModuleType:
    path = ROADS_DIR.parent / "scripts" / "make_roads.py"
    spec = importlib.util.spec_from_file_location("make_roads", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_four_files_are_committed() -> None:
    assert [f.name for f in FILES] == [
        "motorway_3lane.xodr",
        "motorway_r500.xodr",
        "rural_two_lane.xodr",
        "urban_junction.xodr",
    ]


def test_xsd_is_shipped_with_scenariogeneration() -> None:
    path = opendrive_xsd_path()
    assert path.name == "opendrive_17_core.xsd" and path.parent.name == "schemas"


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_file_passes_opendrive_17_xsd(path: Path) -> None:
    assert xsd_errors(path) == []
    head = path.read_text(encoding="utf-8")[:400]
    assert 'revMajor="1" revMinor="7"' in head


def test_xsd_check_is_not_vacuous(tmp_path: Path) -> None:
    # a lane without its required @type and a geometry without @hdg violate the schema
    text = document(road_xml()).replace(' type="driving"', "", 1).replace(' hdg="0"', "")
    bad = tmp_path / "bad.xodr"
    bad.write_text(text, encoding="utf-8")
    errors = xsd_errors(bad)
    assert len(errors) >= 2
    assert any("type" in e for e in errors) and any("hdg" in e for e in errors)


def test_generation_is_deterministic_and_committed_files_are_current() -> None:
    mod = _make_roads()
    for path in FILES:
        first = mod.build(path.name)
        assert first == mod.build(path.name)  # byte-identical on a second run
        assert first == path.read_bytes()  # roads/ is what the script writes
        assert b'date="2024-01-01T00:00:00"' in first


def test_motorway_layout(motorway: RoadNetwork) -> None:
    road = motorway.road(1)
    assert [g.kind for g in road.geometries] == ["line", "spiral", "arc"]
    line, spiral, arc = road.geometries
    assert line.length == 500.0 and spiral.length == 100.0 and arc.length >= 600.0
    assert arc.curvature == pytest.approx(1 / 500, rel=1e-12)
    assert (spiral.curv_start, spiral.curv_end) == (0.0, pytest.approx(1 / 500))
    # the stored start of each geometry equals the end of the previous one (1e-9 m, rad)
    for a, b in zip(road.geometries[:-1], road.geometries[1:], strict=True):
        assert a.end() == pytest.approx((b.x, b.y, b.hdg), abs=1e-9)
    sec = road.sections[0]
    assert [ln.id for ln in sec.right] == [-1, -2] and [ln.id for ln in sec.left] == [1, 2]
    assert all(ln.type == "driving" for ln in sec.left + sec.right)


def test_motorway_3lane_layout() -> None:
    """Three 3.75 m driving lanes per direction; 1000 m line, 100 m clothoid, R = 1000 m
    arc; lane centres of the ego's carriageway at t = -1.875, -5.625, -9.375 m."""
    from sensorgap.roads import read_opendrive

    net = read_opendrive(ROADS_DIR / "motorway_3lane.xodr")
    road = net.road(1)
    assert [g.kind for g in road.geometries] == ["line", "spiral", "arc"]
    line, spiral, arc = road.geometries
    assert (line.length, spiral.length, arc.length) == (1000.0, 100.0, 400.0)
    assert arc.curvature == pytest.approx(1 / 1000, rel=1e-12)
    for a, b in zip(road.geometries[:-1], road.geometries[1:], strict=True):
        assert a.end() == pytest.approx((b.x, b.y, b.hdg), abs=1e-9)
    sec = road.sections[0]
    assert [ln.id for ln in sec.right] == [-1, -2, -3]
    assert [ln.id for ln in sec.left] == [1, 2, 3]
    assert all(ln.type == "driving" for ln in sec.left + sec.right)
    s = np.array([0.0, 1200.0])
    for lane, centre in ((-1, -1.875), (-2, -5.625), (-3, -9.375)):
        np.testing.assert_allclose(net.lane_width(1, lane, s), 3.75)
        inner, outer = net.lane_edges(1, lane, s)
        np.testing.assert_allclose(0.5 * (inner + outer), centre, atol=1e-12)


def test_rural_layout(rural: RoadNetwork) -> None:
    road = rural.road(1)
    assert road.length > 1500.0
    radii = sorted(round(1 / abs(g.curvature)) for g in road.geometries if g.kind == "arc")
    assert radii == [150, 300, 800]
    for a, b in zip(road.geometries[:-1], road.geometries[1:], strict=True):
        assert a.end() == pytest.approx((b.x, b.y, b.hdg), abs=1e-9)
        # curvature is continuous: clothoids connect lines and arcs
        ka = a.evaluate(np.array([a.length]))[3][0]
        kb = b.evaluate(np.array([0.0]))[3][0]
        assert ka == pytest.approx(kb, abs=1e-12)
    np.testing.assert_allclose(rural.lane_width(1, -1, np.array([0.0, 800.0])), 3.5)


def test_urban_layout(urban: RoadNetwork) -> None:
    arms = [urban.road(i) for i in ("1", "2", "3", "4")]
    assert all(a.length >= 80.0 and a.junction == "-1" for a in arms)
    for a in arms:
        sec = a.sections[0]
        assert [(ln.id, ln.type) for ln in sec.right] == [(-1, "driving"), (-2, "sidewalk")]
        assert [(ln.id, ln.type) for ln in sec.left] == [(1, "driving"), (2, "sidewalk")]
        np.testing.assert_allclose(urban.lane_width(a.id, 1, np.array([0.0])), 3.25)
        np.testing.assert_allclose(urban.lane_width(a.id, -2, np.array([0.0])), 2.0)
    junction = urban.junctions["100"]
    assert len(junction.connections) == 12
    assert all((1, -1) in c.lane_links for c in junction.connections)
    # a right turn is a quarter circle of radius 12 m from the arm start to the next arm
    right = urban.road(junction.connections[0].connecting_road)
    assert right.length == pytest.approx(12.0 * math.pi / 2, rel=1e-12)
    assert right.geometries[0].kind == "arc"
