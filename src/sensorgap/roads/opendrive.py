"""OpenDRIVE reader: ``read_opendrive(path) -> RoadNetwork`` with full validation.

Reads the 2-D road layout of OpenDRIVE 1.4-1.7 files: planView geometries (line, arc,
spiral, poly3, paramPoly3), laneOffset, lane sections with lane widths and lane links, road
links and junctions (default, direct, virtual) with their connections and lane links.
Elevation, superelevation, the lateral shape and lane heights are checked but not
modelled: the analysis assumes a flat road, and a profile beyond any real road (height
``MAX_ELEVATION_M``, grade ``MAX_GRADE``, bank ``MAX_SUPERELEVATION_RAD``, shape
``MAX_SHAPE_HEIGHT_M``, lane height ``MAX_LANE_HEIGHT_M``) is refused, since the scenarios
exported on the road would be played on it. Road marks, objects and signals are ignored.

Every problem is one ``InputError`` naming the file and the element, e.g.
``roads/x.xodr: road[id=3]/planView/geometry[2]@length: must be > 0, got -5 (line 12)``.
Element indices count from 0 among siblings of the same name.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal, NoReturn, TypeVar, cast

import numpy as np
from lxml import etree

from sensorgap.config.common import parse_decimal, parse_integer
from sensorgap.errors import InputError
from sensorgap.roads.geometry import Arc, Geometry, Line, ParamPoly3, Poly3, Spiral
from sensorgap.roads.model import (
    Connection,
    ContactPoint,
    CubicPiece,
    Junction,
    Lane,
    LaneSection,
    Road,
    RoadLink,
    eval_pieces,
)
from sensorgap.roads.network import RoadNetwork
from sensorgap.roads.xmlsafe import DEFAULT_MAX_BYTES, parse_xml_file

#: Largest accepted gap/overlap between consecutive geometries, and between the sum of the
#: geometry lengths and the road length, m.
S_TOLERANCE = 1e-3
#: Largest distance between the end of a planView geometry and the start of the next, m.
XY_TOLERANCE = 0.1
#: Largest heading jump between the end of a planView geometry and the start of the next,
#: rad (1 degree; an estimate: writers round headings to about 1e-9 rad and the shipped roads
#: join exactly, while a kink of a degree or more is a corner no vehicle follows).
HDG_TOLERANCE = math.radians(1.0)
#: Largest relative difference between a paramPoly3's arc length and its ``length``.
ARC_LENGTH_TOLERANCE = 0.01
#: Samples along a poly3/paramPoly3 for its curvature and arc length.
_CUBIC_SAMPLES = 257
#: Most negative lane width tolerated (rounding in writers), m.
WIDTH_TOLERANCE = 1e-6

_GEOMETRY_KINDS = ("line", "arc", "spiral", "poly3", "paramPoly3")

# Input limits (docs/limits.md), checked while reading, before any road is sampled:
#: largest magnitude of any number in the file (coordinates, coefficients).
MAX_ABS_VALUE = 1.0e8
#: longest road (and planView geometry), m.
MAX_ROAD_LENGTH_M = 100_000.0
#: Shortest road or plan-view geometry, m (an estimate: a nanometre, far below any
#: converter's sliver; a spiral of 5e-324 m overflowed its curvature rate to inf and its
#: heading to NaN, with numpy warnings on stderr: hostile round 44).
MIN_LENGTH_M = 1.0e-9
#: most roads, planView geometries, lane sections and lanes in one file.
MAX_ROADS = 10_000
MAX_GEOMETRIES = 50_000
MAX_LANE_SECTIONS = 50_000
MAX_LANES_PER_SIDE = 50
#: largest curvature of arcs and spirals, 1/m (radius >= 0.1 m).
MAX_CURVATURE = 10.0
#: widest lane and largest lane offset anywhere along its record, m.
MAX_LANE_WIDTH_M = 100.0
MAX_LANE_OFFSET_M = 1000.0
#: Elevation profile bounds: height above the datum, m (the highest road, about 5.8 km, with
#: margin), and grade, m/m (steeper than any public street, about 0.35 at most; an estimate).
MAX_ELEVATION_M = 10_000.0
MAX_GRADE = 0.5
#: Largest superelevation (bank angle), rad (about 40 degrees; an estimate: AASHTO's highest
#: superelevation rate is 12 %, about 0.12 rad, and steep-banked race ovals reach about 33
#: degrees, 0.58 rad).
MAX_SUPERELEVATION_RAD = 0.7
#: Largest height of the lateral shape and of a lane (``<height>``) above or below the road
#: surface, m (an estimate: crowns, curbs and sidewalks are tens of centimetres).
MAX_SHAPE_HEIGHT_M = 10.0
MAX_LANE_HEIGHT_M = 10.0


def _local(el: etree._Element) -> str:
    """Tag name without namespace; '' for comments and processing instructions."""
    tag = el.tag
    return tag.rpartition("}")[2] if isinstance(tag, str) else ""


_Cubic = TypeVar("_Cubic", Poly3, ParamPoly3)


def _cubic_extent(g: Poly3 | ParamPoly3) -> tuple[float, float | None]:
    """Largest |curvature| (1/m; inf at a cusp) of a poly3 or paramPoly3 over its length,
    sampled at ``_CUBIC_SAMPLES`` points, and (paramPoly3 only) its arc length, m, by
    Simpson's rule (a poly3 is parametrised by its arc length already)."""
    with np.errstate(all="ignore"):
        if isinstance(g, Poly3):
            u_end = float(g.u_at(np.array([g.length]))[0])
            u = np.linspace(0.0, u_end, _CUBIC_SAMPLES)
            dv = g.b + u * (2.0 * g.c + 3.0 * g.d * u)
            ddv = 2.0 * g.c + 6.0 * g.d * u
            k = np.abs(ddv) / (1.0 + dv * dv) ** 1.5
            return float(np.max(k)), None
        p_end = g.length if g.p_range == "arcLength" else 1.0
        p = np.linspace(0.0, p_end, _CUBIC_SAMPLES)
        du = g.b_u + p * (2.0 * g.c_u + 3.0 * g.d_u * p)
        dv = g.b_v + p * (2.0 * g.c_v + 3.0 * g.d_v * p)
        ddu = 2.0 * g.c_u + 6.0 * g.d_u * p
        ddv = 2.0 * g.c_v + 6.0 * g.d_v * p
        q = du * du + dv * dv
        speed = np.sqrt(q)
        h = p_end / (_CUBIC_SAMPLES - 1)
        arc = (
            h / 3.0 * (speed[0] + speed[-1] + 4.0 * speed[1:-1:2].sum() + 2.0 * speed[2:-1:2].sum())
        )
        k = np.where(
            q > 0.0, np.abs(du * ddv - dv * ddu) / np.where(q > 0.0, q, 1.0) ** 1.5, np.inf
        )
        kmax = float(np.max(k))
        return kmax, float(arc)


def _kids(el: etree._Element, name: str) -> list[etree._Element]:
    return [c for c in el if _local(c) == name]


def _kid(el: etree._Element, name: str) -> etree._Element | None:
    kids = _kids(el, name)
    return kids[0] if kids else None


class _Reader:
    """Parses one document; ``source`` names the file in every error."""

    def __init__(self, source: str) -> None:
        self.source = source

    # -- primitives --------------------------------------------------------------------
    def fail(self, where: str, message: str, el: etree._Element | None = None) -> NoReturn:
        line = f" (line {el.sourceline})" if el is not None and el.sourceline else ""
        raise InputError(self.source, where, message + line)

    def text(self, el: etree._Element, attr: str, where: str, default: str | None = None) -> str:
        raw = el.get(attr)
        if raw is None or not raw.strip():
            if default is not None:
                return default
            self.fail(f"{where}@{attr}", "required attribute is missing", el)
        return raw.strip()

    def num(self, el: etree._Element, attr: str, where: str, default: float | None = None) -> float:
        raw = el.get(attr)
        if raw is None:
            if default is not None:
                return default
            self.fail(f"{where}@{attr}", "required attribute is missing", el)
        try:
            # the xsd:double syntax (no '_' separators, no other scripts' digits: float()
            # read width="3_5" as 35 and "３.5" as 3.5, which the export's XSD check refused)
            value = parse_decimal(raw)
        except ValueError:
            self.fail(f"{where}@{attr}", f"must be a number, got {raw[:80]!r}", el)
        if not math.isfinite(value):
            self.fail(f"{where}@{attr}", f"must be a finite number, got {raw!r}", el)
        if abs(value) > MAX_ABS_VALUE:
            self.fail(f"{where}@{attr}", f"must be within +-{MAX_ABS_VALUE:g}, got {raw!r}", el)
        return value

    def some(self, el: etree._Element, name: str, where: str) -> list[etree._Element]:
        """The ``<name>`` children of ``el`` (at ``where``): at least one."""
        kids = _kids(el, name)
        if not kids:
            self.fail(where, f"must contain at least one <{name}>", el)
        return kids

    def length(self, el: etree._Element, where: str) -> float:
        """The ``length`` attribute of a road or a plan-view geometry: > 0 and at most
        ``MAX_ROAD_LENGTH_M``, m."""
        value = self.num(el, "length", where)
        if value < MIN_LENGTH_M:  # (a subnormal spiral's curvature rate overflowed: NaN)
            self.fail(
                f"{where}@length", f"must be at least {MIN_LENGTH_M:g} m, got {float(value)!r}", el
            )
        if value > MAX_ROAD_LENGTH_M:
            self.fail(
                f"{where}@length",
                f"must be at most {MAX_ROAD_LENGTH_M:g} m, got {float(value)!r}",
                el,
            )
        return value

    def count(self, n: int, limit: int, where: str, what: str, el: etree._Element) -> None:
        """At most ``limit`` elements of a kind (docs/limits.md)."""
        if n > limit:
            self.fail(where, f"{n} {what}; at most {limit} allowed", el)

    def integer(self, el: etree._Element, attr: str, where: str) -> int:
        raw = self.text(el, attr, where)
        try:
            return parse_integer(raw)  # ASCII digits (int() also took "１")
        except ValueError:
            self.fail(f"{where}@{attr}", f"must be an integer, got {raw[:80]!r}", el)

    def choice(
        self,
        el: etree._Element,
        attr: str,
        where: str,
        allowed: tuple[str, ...],
        default: str | None = None,
    ) -> str:
        value = self.text(el, attr, where, default)
        if value not in allowed:
            self.fail(f"{where}@{attr}", f"must be one of {', '.join(allowed)}, got {value!r}", el)
        return value

    def cubic(self, el: etree._Element, where: str, s_attr: str) -> CubicPiece:
        return CubicPiece(
            self.num(el, s_attr, where), *(self.num(el, k, where) for k in ("a", "b", "c", "d"))
        )

    # -- document ----------------------------------------------------------------------
    def network(self, root: etree._Element) -> RoadNetwork:
        if _local(root) != "OpenDRIVE":
            self.fail(_local(root) or "root", "root element must be <OpenDRIVE>", root)
        header = _kid(root, "header")
        if header is None:
            self.fail("header", "missing: an OpenDRIVE file starts with <header>", root)
        major = header.get("revMajor")
        if major is not None and major.strip() != "1":
            self.fail("header@revMajor", f"must be 1 (OpenDRIVE 1.x), got {major!r}", header)
        road_els = self.some(root, "road", "OpenDRIVE")
        self.count(len(road_els), MAX_ROADS, "OpenDRIVE", "roads", root)
        self.count(
            sum(len(_kids(pv, "geometry")) for r in road_els for pv in _kids(r, "planView")),
            MAX_GEOMETRIES,
            "OpenDRIVE",
            "planView geometries",
            root,
        )
        self.count(
            sum(len(_kids(ls, "laneSection")) for r in road_els for ls in _kids(r, "lanes")),
            MAX_LANE_SECTIONS,
            "OpenDRIVE",
            "lane sections",
            root,
        )
        roads: dict[str, Road] = {}
        lines: dict[str, int] = {}
        for i, rel in enumerate(road_els):
            road = self.road(rel, i)
            if road.id in roads:
                self.fail(
                    f"road[id={road.id}]@id",
                    f"duplicate road id (first on line {lines[road.id]})",
                    rel,
                )
            roads[road.id] = road
            lines[road.id] = rel.sourceline or 0
        junctions: dict[str, Junction] = {}
        jels: dict[str, etree._Element] = {}
        for i, jel in enumerate(_kids(root, "junction")):
            junction = self.junction(jel, i)
            if junction.id in junctions:
                self.fail(f"junction[id={junction.id}]@id", "duplicate junction id", jel)
            junctions[junction.id] = junction
            jels[junction.id] = jel
        self.check_road_refs(roads, junctions, road_els)
        junctions = {jid: self.check_junction(j, roads, jels[jid]) for jid, j in junctions.items()}
        return RoadNetwork(roads, junctions, source=self.source)

    # -- roads -------------------------------------------------------------------------
    def road(self, el: etree._Element, index: int) -> Road:
        rid = el.get("id", "").strip()
        where = f"road[id={rid}]" if rid else f"road[{index}]"
        if not rid:
            self.fail(f"{where}@id", "required attribute is missing", el)
        length = self.length(el, where)
        junction = el.get("junction", "-1").strip() or "-1"
        rule = cast(
            Literal["RHT", "LHT"], self.choice(el, "rule", where, ("RHT", "LHT"), default="RHT")
        )
        pred = succ = None
        link = _kid(el, "link")
        if link is not None:
            pred = self.road_link(link, "predecessor", where)
            succ = self.road_link(link, "successor", where)
        geoms = self.plan_view(el, where, length)
        self.elevation(el, where, length)
        offsets, sections = self.lanes(el, where, length)
        road = Road(
            rid, length, junction, geoms, offsets, sections, pred, succ, rule, el.get("name", "")
        )
        self.lateral_profile(el, where, road)
        return road

    def road_link(self, link: etree._Element, kind: str, where: str) -> RoadLink | None:
        els = _kids(link, kind)
        if not els:
            return None
        w = f"{where}/link/{kind}"
        if len(els) > 1:
            self.fail(w, f"at most one <{kind}> per road", els[1])
        e = els[0]
        etype = self.choice(e, "elementType", w, ("road", "junction"))
        eid = self.text(e, "elementId", w)
        cp: ContactPoint | None = None
        if etype == "road":
            cp = cast(ContactPoint, self.choice(e, "contactPoint", w, ("start", "end")))
        return RoadLink(cast(Literal["road", "junction"], etype), eid, cp)

    def plan_view(self, el: etree._Element, where: str, length: float) -> tuple[Geometry, ...]:
        pv = _kid(el, "planView")
        if pv is None:
            self.fail(f"{where}/planView", "missing: every road needs a planView", el)
        if len(_kids(el, "planView")) > 1:  # the second one was ignored silently
            self.fail(
                f"{where}/planView", "at most one planView per road", _kids(el, "planView")[1]
            )
        gels = self.some(pv, "geometry", f"{where}/planView")
        geoms: list[Geometry] = []
        for i, g in enumerate(gels):
            w = f"{where}/planView/geometry[{i}]"
            s, x, y, hdg = (self.num(g, k, w) for k in ("s", "x", "y", "hdg"))
            glen = self.length(g, w)
            expected = geoms[-1].s + geoms[-1].length if geoms else 0.0
            if abs(s - expected) > S_TOLERANCE:
                what = "a gap" if s > expected else "an overlap"
                after = f"after geometry[{i - 1}]" if geoms else "at the road start"
                self.fail(
                    f"{w}@s",
                    f"must be {expected:.6g} (geometries are contiguous in s); "
                    f"got {s:.6g}, {what} of {abs(s - expected):.6g} m {after}",
                    g,
                )
            kids = [c for c in g if _local(c)]
            if len(kids) != 1 or _local(kids[0]) not in _GEOMETRY_KINDS:
                found = ", ".join(_local(c) for c in kids) or "nothing"
                self.fail(
                    w, f"must contain exactly one of {', '.join(_GEOMETRY_KINDS)}; found {found}", g
                )
            if geoms:
                # contiguous in x, y too: a geometry starting kilometres from where the
                # previous one ends made every path jump there (at any speed)
                ex, ey, eh = geoms[-1].end()
                gap = math.hypot(x - ex, y - ey)
                if not gap <= XY_TOLERANCE:
                    self.fail(
                        f"{w}@x/y",
                        f"must start where geometry[{i - 1}] ends ({ex:.6g}, {ey:.6g}), within "
                        f"{XY_TOLERANCE:g} m; got ({x:.6g}, {y:.6g}), {gap:.6g} m away",
                        g,
                    )
                # and in heading: a kink made every path turn on the spot (modulo 2 pi)
                jump = math.remainder(hdg - eh, 2.0 * math.pi)
                if not abs(jump) <= HDG_TOLERANCE:
                    self.fail(
                        f"{w}@hdg",
                        f"must continue geometry[{i - 1}]'s end heading within "
                        f"{math.degrees(HDG_TOLERANCE):g} deg; at s {s:.6g} the heading jumps "
                        f"by {math.degrees(jump):.6g} deg",
                        g,
                    )
            geoms.append(self.geometry(kids[0], f"{w}/{_local(kids[0])}", s, x, y, hdg, glen))
        total = geoms[-1].s + geoms[-1].length
        if abs(total - length) > S_TOLERANCE:
            self.fail(
                f"{where}@length",
                f"must equal the end of the last planView geometry "
                f"({total:.6g} m), got {length:.6g}",
                el,
            )
        return tuple(geoms)

    def geometry(
        self, k: etree._Element, w: str, s: float, x: float, y: float, hdg: float, length: float
    ) -> Geometry:
        kind = _local(k)
        if kind == "line":
            return Line(s, x, y, hdg, length)
        if kind == "arc":
            return Arc(s, x, y, hdg, length, self.curvature(k, "curvature", w))
        if kind == "spiral":
            return Spiral(
                s,
                x,
                y,
                hdg,
                length,
                self.curvature(k, "curvStart", w),
                self.curvature(k, "curvEnd", w),
            )
        if kind == "poly3":
            a, b, c, d = (self.num(k, n, w) for n in ("a", "b", "c", "d"))
            return self.cubic_curve(Poly3(s, x, y, hdg, length, a, b, c, d), w, k)
        au, bu, cu, du, av, bv, cv, dv = (
            self.num(k, n, w) for n in ("aU", "bU", "cU", "dU", "aV", "bV", "cV", "dV")
        )
        p_range = cast(
            Literal["arcLength", "normalized"],
            self.choice(k, "pRange", w, ("arcLength", "normalized"), "normalized"),
        )
        return self.cubic_curve(
            ParamPoly3(
                s,
                x,
                y,
                hdg,
                length,
                a_u=au,
                b_u=bu,
                c_u=cu,
                d_u=du,
                a_v=av,
                b_v=bv,
                c_v=cv,
                d_v=dv,
                p_range=p_range,
            ),
            w,
            k,
        )

    def cubic_curve(self, g: _Cubic, w: str, k: etree._Element) -> _Cubic:
        """A poly3 or paramPoly3 whose curvature stays within ``MAX_CURVATURE`` (as an arc's
        and a spiral's) and, for a paramPoly3, whose arc length is its ``length`` (within
        ``ARC_LENGTH_TOLERANCE``): s runs along the curve, so a curve 1e8 m long declared
        200 m moved every road user 5e5 times faster than its speed, and a curve that is a
        point moved none."""
        kmax, arc = _cubic_extent(g)
        if arc is not None and not abs(arc - g.length) <= ARC_LENGTH_TOLERANCE * g.length:
            self.fail(
                f"{w}",
                f"the curve is {arc:.6g} m long; its geometry's length is {g.length:.6g} m "
                f"(they must agree within {ARC_LENGTH_TOLERANCE:.0%}: s runs along the curve)",
                k,
            )
        if not kmax <= MAX_CURVATURE:
            self.fail(
                w,
                f"curvature reaches {kmax:.3g} 1/m; at most {MAX_CURVATURE:g} 1/m (radius >= "
                f"{1.0 / MAX_CURVATURE:g} m), as for an arc or a spiral",
                k,
            )
        return g

    def curvature(self, k: etree._Element, attr: str, w: str) -> float:
        value = self.num(k, attr, w)
        if abs(value) > MAX_CURVATURE:
            self.fail(
                f"{w}@{attr}",
                f"must be within +-{MAX_CURVATURE:g} 1/m (radius >= "
                f"{1.0 / MAX_CURVATURE:g} m), got {float(value)!r}",
                k,
            )
        return value

    def bounded_cubic(
        self,
        piece: CubicPiece,
        end: float,
        limit: float,
        where: str,
        what: str,
        el: etree._Element,
        unit: str = "m",
        start: float | None = None,
        along: str = "s",
    ) -> None:
        """``InputError`` if the cubic record exceeds ``limit`` in magnitude on its span
        [``start`` (default: the record's own start), ``end``] (in ``along``, m)."""
        neg = CubicPiece(piece.s, -piece.a, -piece.b, -piece.c, -piece.d)
        lo_at, lo = _cubic_min(piece, end, start)
        hi_at, hi = _cubic_min(neg, end, start)
        at, worst = (lo_at, lo) if abs(lo) >= abs(hi) else (hi_at, -hi)
        if not (math.isfinite(worst) and abs(worst) <= limit):
            self.fail(
                where,
                f"{what} must stay within +-{limit:g} {unit}, reaches {worst:.6g} {unit} at "
                f"{along} {at:.6g}",
                el,
            )

    def spans(
        self, els: list[etree._Element], where: str, length: float
    ) -> list[tuple[CubicPiece, float, str, etree._Element]]:
        """Cubic records along a road (``laneOffset``, ``elevation``, ``superelevation``,
        ``shape``; ``where``: their path, the i-th is ``where[i]``) in order within its
        ``length`` (m): (piece, end of its span in s, its path, its element), each span
        ending where the next record starts. Before the first record the OpenDRIVE default
        (0) holds: nothing is extrapolated backwards."""
        pieces: list[tuple[CubicPiece, str, etree._Element]] = []
        for i, e in enumerate(els):
            w = f"{where}[{i}]"
            piece = self.cubic(e, w, "s")
            if not -S_TOLERANCE <= piece.s <= length + S_TOLERANCE:
                self.fail(f"{w}@s", f"must be within [0, {length:g}] m, got {piece.s:g}", e)
            if pieces and piece.s < pieces[-1][0].s:
                self.fail(f"{w}@s", f"must not decrease (previous {pieces[-1][0].s:g})", e)
            pieces.append((piece, w, e))
        return [
            (piece, pieces[i + 1][0].s if i + 1 < len(pieces) else max(length, piece.s), w, e)
            for i, (piece, w, e) in enumerate(pieces)
        ]

    def elevation(self, el: etree._Element, where: str, length: float) -> None:
        """Checks the elevation profile (not modelled: a flat road is assumed): pieces in
        order within the road, height within ``MAX_ELEVATION_M`` (m), grade within
        ``MAX_GRADE`` (m/m); 0 before the first piece (the standard's default)."""
        els = [e for prof in _kids(el, "elevationProfile") for e in _kids(prof, "elevation")]
        for piece, end, w, e in self.spans(els, f"{where}/elevationProfile/elevation", length):
            self.bounded_cubic(piece, end, MAX_ELEVATION_M, w, "the height", e)
            grade = CubicPiece(piece.s, piece.b, 2.0 * piece.c, 3.0 * piece.d, 0.0)
            self.bounded_cubic(grade, end, MAX_GRADE, w, "the grade", e, unit="m/m")

    def lateral_profile(self, el: etree._Element, where: str, road: Road) -> None:
        """Checks the lateral profile (not modelled: a flat road is assumed): superelevation
        pieces in order within the road and within ``MAX_SUPERELEVATION_RAD`` (rad; 0 before
        the first); shape pieces in order of s, each height cubic in t within
        ``MAX_SHAPE_HEIGHT_M`` (m) from its t to the next t at the same s (sorted by t), the
        first from the road's right edge, the last to its left edge (at that s)."""
        profs = _kids(el, "lateralProfile")
        w = f"{where}/lateralProfile"
        sup = [e for prof in profs for e in _kids(prof, "superelevation")]
        for piece, end, ws, e in self.spans(sup, f"{w}/superelevation", road.length):
            self.bounded_cubic(piece, end, MAX_SUPERELEVATION_RAD, ws, "the angle", e, "rad")
        shapes = [e for prof in profs for e in _kids(prof, "shape")]
        stations: dict[float, list[tuple[float, CubicPiece, str, etree._Element]]] = {}
        for piece, _, ws, e in self.spans(shapes, f"{w}/shape", road.length):
            stations.setdefault(piece.s, []).append((self.num(e, "t", ws), piece, ws, e))
        s_at = np.clip(np.array(list(stations), dtype=np.float64), 0.0, road.length)
        lefts, rights = road.extents(s_at)
        for recs, left, right in zip(stations.values(), lefts, rights, strict=True):
            recs.sort(key=lambda r: r[0])
            for k, (t, piece, ws, e) in enumerate(recs):
                start = min(t, float(right)) if k == 0 else t
                end = recs[k + 1][0] if k + 1 < len(recs) else max(t, float(left))
                height = CubicPiece(t, piece.a, piece.b, piece.c, piece.d)
                self.bounded_cubic(
                    height, end, MAX_SHAPE_HEIGHT_M, ws, "the height", e, "m", start, "t"
                )

    # -- lanes -------------------------------------------------------------------------
    def lanes(
        self, el: etree._Element, where: str, length: float
    ) -> tuple[tuple[CubicPiece, ...], tuple[LaneSection, ...]]:
        lel = _kid(el, "lanes")
        if lel is None:
            self.fail(
                f"{where}/lanes",
                "missing: every road needs <lanes> with at least one <laneSection>",
                el,
            )
        spans = self.spans(_kids(lel, "laneOffset"), f"{where}/lanes/laneOffset", length)
        for piece, end, w, _ in spans:
            self.bounded_cubic(piece, end, MAX_LANE_OFFSET_M, w, "the lane offset", el)
        offsets = [piece for piece, _, _, _ in spans]
        if offsets and offsets[0].s > 0.0:
            # no offset before the first record: the standard defines none there (its own
            # example starts at s = 25 with a = 0); extrapolating the first one backwards
            # put a path 13 km off the road
            offsets.insert(0, CubicPiece(0.0, 0.0))
        sels = self.some(lel, "laneSection", f"{where}/lanes")
        starts: list[float] = []
        for i, sec in enumerate(sels):
            w = f"{where}/lanes/laneSection[{i}]"
            s = self.num(sec, "s", w)
            if i == 0 and abs(s) > S_TOLERANCE:
                self.fail(f"{w}@s", f"the first laneSection must start at s=0, got {s:g}", sec)
            if i > 0 and s <= starts[-1]:
                self.fail(
                    f"{w}@s",
                    f"must be greater than the previous laneSection's s "
                    f"({starts[-1]:g}), got {s:g}",
                    sec,
                )
            if s >= length:
                self.fail(f"{w}@s", f"must be < the road length {length:g}, got {s:g}", sec)
            starts.append(max(s, 0.0) if i == 0 else s)
        ends = starts[1:] + [length]
        sections = tuple(
            self.section(sec, f"{where}/lanes/laneSection[{i}]", starts[i], ends[i])
            for i, sec in enumerate(sels)
        )
        return tuple(offsets), sections

    def section(self, el: etree._Element, w: str, s: float, s_end: float) -> LaneSection:
        center_el = _kid(el, "center")
        if center_el is None:
            self.fail(f"{w}/center", "missing: a laneSection needs a <center> lane", el)
        centers = [self.lane(c, f"{w}/center", 0.0) for c in _kids(center_el, "lane")]
        if len(centers) != 1 or centers[0].id != 0:
            self.fail(f"{w}/center", "must hold exactly one <lane> with id 0", center_el)
        sides: dict[str, tuple[Lane, ...]] = {}
        for side, sign in (("left", 1), ("right", -1)):
            sel = _kid(el, side)
            if sel is not None:
                self.count(len(_kids(sel, "lane")), MAX_LANES_PER_SIDE, f"{w}/{side}", "lanes", sel)
            lanes = (
                []
                if sel is None
                else [self.lane(ln, f"{w}/{side}", s_end - s) for ln in _kids(sel, "lane")]
            )
            ids = sorted((ln.id for ln in lanes), key=abs)
            want = [sign * k for k in range(1, len(lanes) + 1)]
            if ids != want:
                self.fail(
                    f"{w}/{side}",
                    f"lane ids must be {', '.join(map(str, want))} "
                    f"(each once), got {', '.join(str(ln.id) for ln in lanes)}",
                    sel,
                )
            sides[side] = tuple(sorted(lanes, key=lambda ln: abs(ln.id)))
        if not sides["left"] and not sides["right"]:
            self.fail(w, "has no lanes: a laneSection needs at least one left or right lane", el)
        return LaneSection(s, s_end, sides["left"], centers[0], sides["right"])

    def lane(self, el: etree._Element, w_side: str, sec_len: float) -> Lane:
        raw = el.get("id")
        lid = self.integer(el, "id", f"{w_side}/lane")
        w = f"{w_side}/lane[id={raw.strip() if raw else ''}]"
        ltype = self.text(el, "type", w)
        direction = self.choice(
            el, "direction", w, ("standard", "reversed", "both"), default="standard"
        )
        preds: list[int] = []
        succs: list[int] = []
        link = _kid(el, "link")
        if link is not None:
            preds = [
                self.integer(p, "id", f"{w}/link/predecessor") for p in _kids(link, "predecessor")
            ]
            succs = [self.integer(p, "id", f"{w}/link/successor") for p in _kids(link, "successor")]
        for hel, wh in self.lane_records(el, "height", w):
            for attr in ("inner", "outer"):
                value = self.num(hel, attr, wh)
                if abs(value) > MAX_LANE_HEIGHT_M:
                    self.fail(
                        f"{wh}@{attr}",
                        f"must be within +-{MAX_LANE_HEIGHT_M:g} m, got {float(value)!r}",
                        hel,
                    )
        if lid == 0:
            return Lane(0, ltype, (), tuple(preds), tuple(succs), direction)
        if _kid(el, "border") is not None:
            self.fail(
                f"{w}/border",
                "lane <border> records are not supported; describe the lane with <width> records",
                _kid(el, "border"),
            )
        widths = [self.cubic(e, ww, "sOffset") for e, ww in self.lane_records(el, "width", w)]
        if not widths:
            self.fail(w, "needs at least one <width> record", el)
        if widths[0].s > S_TOLERANCE:
            # the width is defined from each record on; before the first it is undefined
            # (extrapolating it backwards made a lane -8.55 m wide)
            self.fail(
                f"{w}/width[0]@sOffset",
                f"the first width record must start at the lane section start (sOffset 0), "
                f"got {widths[0].s:g}: the width before it is undefined",
                _kids(el, "width")[0],
            )
        for i, piece in enumerate(widths):
            end = widths[i + 1].s if i + 1 < len(widths) else max(sec_len, piece.s)
            start = 0.0 if i == 0 else None  # the first record covers [0, its sOffset) too
            at, wmin = _cubic_min(piece, end, start)
            if wmin < -WIDTH_TOLERANCE:
                self.fail(
                    f"{w}/width[{i}]",
                    f"width must be >= 0, got {wmin:.6g} m at sOffset {at:.6g}",
                    el,
                )
            self.bounded_cubic(
                piece, end, MAX_LANE_WIDTH_M, f"{w}/width[{i}]", "the width", el, start=start
            )
        return Lane(lid, ltype, tuple(widths), tuple(preds), tuple(succs), direction)

    def lane_records(
        self, el: etree._Element, name: str, w: str
    ) -> list[tuple[etree._Element, str]]:
        """The ``<name>`` records of a lane (``width``, ``height``) with their paths, their
        ``sOffset`` (m from the section start) >= 0 and not decreasing."""
        out: list[tuple[etree._Element, str]] = []
        previous = 0.0
        for i, rel in enumerate(_kids(el, name)):
            wr = f"{w}/{name}[{i}]"
            s = self.num(rel, "sOffset", wr)
            if s < 0.0:
                self.fail(f"{wr}@sOffset", f"must be >= 0, got {s:g}", rel)
            if s < previous:
                self.fail(f"{wr}@sOffset", f"must not decrease (previous {previous:g})", rel)
            previous = s
            out.append((rel, wr))
        return out

    # -- junctions ---------------------------------------------------------------------
    def junction(self, el: etree._Element, index: int) -> Junction:
        jid = el.get("id", "").strip()
        where = f"junction[id={jid}]" if jid else f"junction[{index}]"
        if not jid:
            self.fail(f"{where}@id", "required attribute is missing", el)
        jtype = self.choice(el, "type", where, ("default", "direct", "virtual"), "default")
        conns: list[Connection] = []
        for i, c in enumerate(_kids(el, "connection")):
            cid = c.get("id", "").strip()
            w = f"{where}/connection[id={cid}]" if cid else f"{where}/connection[{i}]"
            cid = self.text(c, "id", w)
            inc = self.text(c, "incomingRoad", w)
            attr = "linkedRoad" if jtype == "direct" else "connectingRoad"
            conn_road = self.text(c, attr, w)
            cp = cast(ContactPoint, self.choice(c, "contactPoint", w, ("start", "end")))
            links = tuple(
                (
                    self.integer(ll, "from", f"{w}/laneLink[{k}]"),
                    self.integer(ll, "to", f"{w}/laneLink[{k}]"),
                )
                for k, ll in enumerate(_kids(c, "laneLink"))
            )
            conns.append(Connection(cid, inc, conn_road, cp, links))
        return Junction(jid, el.get("name", ""), jtype, tuple(conns))

    # -- cross references --------------------------------------------------------------
    def check_road_refs(
        self, roads: dict[str, Road], junctions: dict[str, Junction], els: list[etree._Element]
    ) -> None:
        by_id = {r.id: el for r, el in zip(roads.values(), els, strict=False)}
        for road in roads.values():
            el = by_id[road.id]
            where = f"road[id={road.id}]"
            if road.junction != "-1" and road.junction not in junctions:
                self.fail(f"{where}@junction", f"junction {road.junction} does not exist", el)
            for kind, link in (("predecessor", road.predecessor), ("successor", road.successor)):
                if link is None:
                    continue
                pool: dict[str, Road] | dict[str, Junction] = (
                    roads if link.element_type == "road" else junctions
                )
                if link.element_id not in pool:
                    self.fail(
                        f"{where}/link/{kind}@elementId",
                        f"{link.element_type} {link.element_id} does not exist",
                        el,
                    )
            self.check_lane_links(road, roads, el)

    def check_lane_links(self, road: Road, roads: dict[str, Road], el: etree._Element) -> None:
        for i, sec in enumerate(road.sections):
            for lane in sec.left + sec.right:
                w = (
                    f"road[id={road.id}]/lanes/laneSection[{i}]/"
                    f"{'left' if lane.id > 0 else 'right'}/lane[id={lane.id}]/link"
                )
                for kind, ids in (
                    ("predecessor", lane.predecessors),
                    ("successor", lane.successors),
                ):
                    target = self.lane_link_target(road, i, kind, roads)
                    if target is None:
                        continue
                    troad, tsec = target
                    for lid in ids:
                        if troad.sections[tsec].lane(lid) is None or lid == 0:
                            self.fail(
                                f"{w}/{kind}@id",
                                f"lane {lid} does not exist in road "
                                f"{troad.id} laneSection[{tsec}] (lanes: "
                                f"{_ids(troad.sections[tsec])})",
                                el,
                            )

    @staticmethod
    def lane_link_target(
        road: Road, i: int, kind: str, roads: dict[str, Road]
    ) -> tuple[Road, int] | None:
        """The (road, section index) a lane link of section ``i`` points into, if any."""
        step = 1 if kind == "successor" else -1
        if 0 <= i + step < len(road.sections):
            return road, i + step
        link = road.successor if kind == "successor" else road.predecessor
        if link is None or link.element_type != "road" or link.element_id not in roads:
            return None
        other = roads[link.element_id]
        return other, (0 if link.contact_point == "start" else len(other.sections) - 1)

    def check_junction(self, j: Junction, roads: dict[str, Road], el: etree._Element) -> Junction:
        out: list[Connection] = []
        for c in j.connections:
            w = f"junction[id={j.id}]/connection[id={c.id}]"
            attr = "linkedRoad" if j.type == "direct" else "connectingRoad"
            for name, rid in (("incomingRoad", c.incoming_road), (attr, c.connecting_road)):
                if rid not in roads:
                    self.fail(f"{w}@{name}", f"road {rid} does not exist", el)
            inc, con = roads[c.incoming_road], roads[c.connecting_road]
            if j.type != "direct" and con.junction != j.id:
                self.fail(
                    f"{w}@{attr}",
                    f"road {con.id} must belong to junction {j.id} "
                    f"(its @junction is {con.junction})",
                    el,
                )
            sides: tuple[tuple[ContactPoint, RoadLink | None], ...] = (
                ("end", inc.successor),
                ("start", inc.predecessor),
            )
            ends = [
                e
                for e, link in sides
                if link is not None and link.element_type == "junction" and link.element_id == j.id
            ]
            if not ends:
                self.fail(
                    f"{w}@incomingRoad",
                    f"road {inc.id} is not linked to junction "
                    f"{j.id} (neither its predecessor nor its successor)",
                    el,
                )
            end = ends[0] if len(ends) == 1 else _nearer_end(inc, con, c.contact_point)
            isec = 0 if end == "start" else len(inc.sections) - 1
            csec = 0 if c.contact_point == "start" else len(con.sections) - 1
            for k, (a, b) in enumerate(c.lane_links):
                lw = f"{w}/laneLink[{k}]"
                if a == 0 or inc.sections[isec].lane(a) is None:
                    self.fail(
                        f"{lw}@from",
                        f"lane {a} does not exist at the {end} of road "
                        f"{inc.id} (lanes: {_ids(inc.sections[isec])})",
                        el,
                    )
                if b == 0 or con.sections[csec].lane(b) is None:
                    self.fail(
                        f"{lw}@to",
                        f"lane {b} does not exist at the {c.contact_point} of "
                        f"road {con.id} (lanes: {_ids(con.sections[csec])})",
                        el,
                    )
            out.append(
                Connection(
                    c.id, c.incoming_road, c.connecting_road, c.contact_point, c.lane_links, end
                )
            )
        return Junction(j.id, j.name, j.type, tuple(out))


def _cubic_min(piece: CubicPiece, end: float, start: float | None = None) -> tuple[float, float]:
    """Smallest value of a cubic record over [start, end] (``start`` defaults to piece.s; an
    earlier one extrapolates the record backwards) and where (exact: end points and the real
    roots of the derivative)."""
    if piece.b == piece.c == piece.d == 0.0:
        return piece.s, piece.a
    lo = 0.0 if start is None else min(start - piece.s, 0.0)
    hi = max(end - piece.s, 0.0)
    cands = [lo, hi]
    if piece.c != 0.0 or piece.d != 0.0:
        roots = np.roots([3.0 * piece.d, 2.0 * piece.c, piece.b])
        cands += [float(r.real) for r in roots if abs(r.imag) < 1e-12 and lo < r.real < hi]
    u = np.array(cands)
    vals = eval_pieces((CubicPiece(0.0, piece.a, piece.b, piece.c, piece.d),), u)[0]
    k = int(np.argmin(vals))
    return piece.s + float(u[k]), float(vals[k])


def _ids(sec: LaneSection) -> str:
    return ", ".join(str(i) for i in sec.lane_ids)


def _road_end_xy(road: Road, end: ContactPoint) -> tuple[float, float]:
    if end == "start":
        g = road.geometries[0]
        return g.x, g.y
    x, y, _ = road.geometries[-1].end()
    return x, y


def _nearer_end(inc: Road, con: Road, contact: ContactPoint) -> ContactPoint:
    """Which end of ``inc`` lies nearer the connecting road's contact point (for an incoming
    road linked to the same junction at both ends)."""
    cx, cy = _road_end_xy(con, contact)
    d = {e: math.hypot(x - cx, y - cy) for e in ("start", "end") for x, y in [_road_end_xy(inc, e)]}
    return "start" if d["start"] <= d["end"] else "end"


def read_opendrive(path: str | Path, max_bytes: int = DEFAULT_MAX_BYTES) -> RoadNetwork:
    """Read and validate an OpenDRIVE file.

    Args:
        path: the ``.xodr`` file.
        max_bytes: largest accepted file size, bytes (default 50 MB), checked before parsing.

    Returns:
        The road network (roads, junctions, lane graph, coordinate transforms).

    Raises:
        InputError: unreadable, oversized, hostile or malformed XML; invalid or inconsistent
            OpenDRIVE content. The message names the file and the element.
    """
    root = parse_xml_file(path, max_bytes)
    return _Reader(str(path)).network(root)
