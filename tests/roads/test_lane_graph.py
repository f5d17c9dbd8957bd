"""Lane graph: neighbours and successors on the committed files and on files written by
scenariogeneration here."""

from __future__ import annotations

import math
from pathlib import Path

import networkx as nx
import numpy as np
from scenariogeneration import xodr

from sensorgap.roads import RoadNetwork, read_opendrive


def _kind(g: nx.DiGraph, kind: str) -> nx.DiGraph:
    return nx.DiGraph([(u, v) for u, v, d in g.edges(data=True) if d["kind"] == kind])


def _succ(g: nx.DiGraph, node: tuple[str, int, int]) -> set[tuple[str, int, int]]:
    return {v for v, d in g.succ[node].items() if d["kind"] == "successor"}


def _side(g: nx.DiGraph, node: tuple[str, int, int], kind: str) -> set[tuple[str, int, int]]:
    return {v for v, d in g.succ[node].items() if d["kind"] == kind}


def test_every_successor_edge_has_its_predecessor_mirror(urban: RoadNetwork) -> None:
    g = urban.lane_graph
    succ = [(u, v) for u, v, d in g.edges(data=True) if d["kind"] == "successor"]
    pred = [(u, v) for u, v, d in g.edges(data=True) if d["kind"] == "predecessor"]
    assert len(succ) == len(pred) > 0
    assert {(v, u) for u, v in succ} == set(pred)


def test_motorway_neighbours(motorway: RoadNetwork) -> None:
    g = motorway.lane_graph
    assert set(g.nodes) == {("1", 0, i) for i in (-2, -1, 1, 2)}
    # ego lane -1 travels +s: left of it is the opposite carriageway (lane 1), right lane -2
    assert _side(g, ("1", 0, -1), "left") == {("1", 0, 1)}
    assert _side(g, ("1", 0, -1), "right") == {("1", 0, -2)}
    assert _side(g, ("1", 0, -2), "left") == {("1", 0, -1)}
    assert _side(g, ("1", 0, -2), "right") == set()
    assert g.edges[("1", 0, -2), ("1", 0, -1)]["same_direction"] is True
    assert g.edges[("1", 0, -1), ("1", 0, 1)]["same_direction"] is False
    # lane 2 travels -s: its left is lane 1, its right nothing
    assert _side(g, ("1", 0, 2), "left") == {("1", 0, 1)}
    assert g.nodes["1", 0, -1]["travel"] == 1 and g.nodes["1", 0, 2]["travel"] == -1
    assert not any(d["kind"] == "successor" for _, _, d in g.edges(data=True))


def test_urban_junction_successors(urban: RoadNetwork) -> None:
    g = urban.lane_graph
    assert g.number_of_nodes() == 4 * 4 + 12 + 4  # arm lanes, connecting lanes, corner walks
    exits = {"1": {"4", "2", "3"}, "2": {"1", "3", "4"}, "3": {"4", "1", "2"}, "4": {"2", "3", "1"}}
    for arm, others in exits.items():
        entry = (arm, 0, 1)  # lane 1 of every arm travels towards the junction
        conns = _succ(g, entry)
        assert len(conns) == 3
        assert all(urban.road(c[0]).junction == "100" and c[2] == -1 for c in conns)
        reached = set().union(*(_succ(g, c) for c in conns))
        assert reached == {(o, 0, -1) for o in others}
        assert _succ(g, (arm, 0, -1)) == set()  # lane -1 leaves the network
    # right turn from the west arm (3) to the south arm (4) carries the corner sidewalk
    walk = _succ(g, ("3", 0, 2))
    assert len(walk) == 1
    (corner,) = walk
    assert g.nodes[corner]["type"] == "sidewalk"
    assert _succ(g, corner) == {("4", 0, -2)}
    assert _side(g, (corner[0], 0, -1), "right") == {corner}
    # the driving paths: from the west arm, straight on ends on the east arm
    succ = _kind(g, "successor")
    assert nx.has_path(succ, ("3", 0, 1), ("1", 0, -1))
    assert not nx.has_path(succ, ("3", 0, 1), ("3", 0, -1))  # no U-turn connection


def _linked_roads(tmp_path: Path) -> Path:
    # road 1 -> road 2 (with a lane merge: three lane sections) -> road 3 reversed (end to end)
    r1 = xodr.create_road(xodr.Line(100), 1, left_lanes=1, right_lanes=2)
    r2 = xodr.create_road(
        [xodr.Line(50), xodr.Arc(0.01, length=50)],
        2,
        left_lanes=1,
        right_lanes=[xodr.LaneDef(10, 30, 2, 1, -2)],
    )
    r3 = xodr.create_road(xodr.Spiral(0.0001, 0.02, length=60), 3, left_lanes=1, right_lanes=1)
    r1.add_successor(xodr.ElementType.road, 2, xodr.ContactPoint.start)
    r2.add_predecessor(xodr.ElementType.road, 1, xodr.ContactPoint.end)
    r2.add_successor(xodr.ElementType.road, 3, xodr.ContactPoint.end)
    r3.add_successor(xodr.ElementType.road, 2, xodr.ContactPoint.end)
    odr = xodr.OpenDrive("linked", revMajor="1", revMinor="7")
    for r in (r1, r2, r3):
        odr.add_road(r)
    odr.adjust_roads_and_lanes()
    path = tmp_path / "linked.xodr"
    odr.write_xml(str(path))
    return path


def test_linked_roads_written_by_scenariogeneration(tmp_path: Path) -> None:
    net = read_opendrive(_linked_roads(tmp_path))
    g = net.lane_graph
    assert len(net.road(2).sections) == 3
    # +s traffic: 1/-1 -> 2/-1 through all sections of road 2 -> road 3 lane 1 (reversed road)
    assert _succ(g, ("1", 0, -1)) == {("2", 0, -1)}
    assert _succ(g, ("1", 0, -2)) == {("2", 0, -2)}
    assert _succ(g, ("2", 0, -1)) == {("2", 1, -1)}
    assert _succ(g, ("2", 0, -2)) == {("2", 1, -2)}
    assert _succ(g, ("2", 1, -2)) == set()  # the merging lane ends
    assert _succ(g, ("2", 2, -1)) == {("3", 0, 1)}
    assert g.nodes["3", 0, 1]["travel"] == -1  # against road 3's s: away from the joint
    # the opposite direction: road 3 lane -1 -> road 2 lane 1 -> ... -> road 1 lane 1
    succ = _kind(g, "successor")
    assert nx.shortest_path(succ, ("3", 0, -1), ("1", 0, 1)) == [
        ("3", 0, -1),
        ("2", 2, 1),
        ("2", 1, 1),
        ("2", 0, 1),
        ("1", 0, 1),
    ]
    # geometry stitched by scenariogeneration: road 3 ends where road 2 ends, reversed
    x2, y2, h2 = net.reference_line(2, net.road(2).length)
    x3, y3, h3 = net.reference_line(3, net.road(3).length)
    assert np.hypot(x3 - x2, y3 - y2) < 1e-9
    assert abs(math.remainder(h3 - h2 - math.pi, 2 * math.pi)) < 1e-9
    # merging lane -2 narrows from 3 m to 0 between s = 10 and 30 (polynomial width)
    w = net.lane_width(2, -2, np.array([5.0, 10.0, 20.0, 29.999]))
    np.testing.assert_allclose(w, [3.0, 3.0, 1.5, 0.0], atol=1e-6)


def test_junction_written_by_scenariogeneration(tmp_path: Path) -> None:
    arms = [xodr.create_road([xodr.Line(100)], i, left_lanes=1, right_lanes=1) for i in range(4)]
    jc = xodr.CommonJunctionCreator(1, "cross", startnum=100)
    for i, road in enumerate(arms):
        jc.add_incoming_road_circular_geometry(road, 20, i * np.pi / 2, "successor")
    for i in range(4):
        for j in range(i + 1, 4):
            jc.add_connection(i, j)
    odr = xodr.OpenDrive("cross", revMajor="1", revMinor="7")
    for road in arms:
        odr.add_road(road)
    odr.add_junction_creator(jc)
    odr.adjust_roads_and_lanes()
    path = tmp_path / "cross.xodr"
    odr.write_xml(str(path))
    net = read_opendrive(path)
    assert len(net.junctions["1"].connections) > 0
    succ = _kind(net.lane_graph, "successor")
    for i in range(4):
        # each arm's successor is the junction: lane -1 travels +s into it, lane 1 out of it
        reach = {v for v in nx.descendants(succ, (str(i), 0, -1)) if v[0] in "0123"}
        assert reach == {(str(k), 0, 1) for k in range(4) if k != i}
    # connecting roads join the arm ends continuously (within 1e-6 m)
    for road in net.roads.values():
        if road.junction != "1":
            continue
        assert road.predecessor is not None and road.successor is not None
        for s_end, link in ((0.0, road.predecessor), (road.length, road.successor)):
            other = net.road(link.element_id)
            s_other = 0.0 if link.contact_point == "start" else other.length
            a = net.reference_line(road.id, s_end)
            b = net.reference_line(other.id, s_other)
            assert np.hypot(a[0] - b[0], a[1] - b[1]) < 1e-6
