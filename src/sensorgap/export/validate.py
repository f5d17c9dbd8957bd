"""Validity of exported files: the official XSDs (as shipped by scenariogeneration) and
semantic checks of our own (entities referenced exist, lanes exist, paths stay on the road).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import scenariogeneration
from lxml import etree

from sensorgap.export.params import ExpressionError, evaluate
from sensorgap.roads import RoadNetwork
from sensorgap.scenarios.kinds import FOOTWAY_M as CROSSING_FOOTWAY_M

#: XSD file per OpenSCENARIO version, in scenariogeneration's ``schemas`` folder.
OSC_XSD = {
    "1.0": "OpenSCENARIO_1_0.xsd",
    "1.1": "OpenSCENARIO_1_1.xsd",
    "1.2": "OpenSCENARIO_1_2.xsd",
    "1.3": "OpenSCENARIO_1_3_1.xsd",
}
ODR_XSD = "opendrive_17_core.xsd"


def schemas_dir() -> Path:
    """The official schemas shipped with scenariogeneration."""
    return Path(scenariogeneration.__file__).resolve().parent.parent / "schemas"


@functools.cache
def _schema(name: str) -> etree.XMLSchema:
    """The schema, compiled by libxml2 (lxml): ~100x faster than a pure-Python validator
    on 2,000-vertex trajectories."""
    return etree.XMLSchema(etree.parse(str(schemas_dir() / name)))


def xsd_errors(path: Path, version: str | None = None) -> list[str]:
    """XSD violations of an .xosc (its own version) or .xodr file (first 5, one line each)."""
    try:
        doc = etree.parse(str(path))
    except (OSError, etree.XMLSyntaxError) as exc:
        return [f"not well-formed XML: {exc}"]
    if path.suffix == ".xodr":
        schema = _schema(ODR_XSD)
    else:
        if version is None:
            header = doc.find("FileHeader")
            version = f"1.{header.get('revMinor')}" if header is not None else "1.2"
        schema = _schema(OSC_XSD[version])
    if schema.validate(doc):
        return []
    return [f"line {e.line}: {e.message}" for e in list(schema.error_log)[:5]]


#: How far beside the outermost lane a vulnerable road user's path may run (a footway or
#: verge where a crossing starts and ends): the crossing family's own bound, plus 0.5 m.
FOOTWAY_M = CROSSING_FOOTWAY_M + 0.5


def semantic_errors(
    xosc_path: Path,
    net: RoadNetwork,
    lanes: dict[str, list[int]],
    tolerance_m: float = 0.5,
    tolerance_by_path: dict[str, float] | None = None,
) -> list[str]:
    """Our own checks of a scenario file: every entity referenced by an action exists; the
    declared lanes exist on the road; every trajectory vertex lies on the road (within
    ``tolerance_m`` of its lanes, or the trajectory's own tolerance in
    ``tolerance_by_path``, e.g. ``FOOTWAY_M`` for a crossing pedestrian)."""
    tree = etree.parse(str(xosc_path))
    errors = parameter_errors(tree)
    names = {e.get("name") for e in tree.iter("ScenarioObject")}
    for tag in ("PrivateAction", "Private", "Actors"):
        for el in tree.iter(tag):
            ref = el.get("entityRef")
            if ref is not None and ref not in names:
                errors.append(f"{tag} references unknown entity {ref!r}")
    for el in tree.iter("EntityRef"):
        if el.get("entityRef") not in names:
            errors.append(f"EntityRef references unknown entity {el.get('entityRef')!r}")
    for road_id, ids in lanes.items():
        for lane in ids:
            if not net.lane_exists(road_id, lane):
                errors.append(f"lane {lane} does not exist on road {road_id}")
    values = declared_parameters(tree)
    for traj in tree.iter("Trajectory"):
        pts = [(float(p.get("x")), float(p.get("y"))) for p in traj.iter("WorldPosition")]
        for rp in traj.iter("RoadPosition"):  # the maneuver style's crossings
            try:
                s = float(evaluate(str(rp.get("s")), values))
                t = float(evaluate(str(rp.get("t")), values))
                xr, yr, hr = net.reference_line(str(rp.get("roadId")), s)
            except (ExpressionError, ValueError, KeyError):
                continue  # reported by parameter_errors / the lane check
            pts.append((xr - t * float(np.sin(hr)), yr + t * float(np.cos(hr))))
        if not pts:
            continue
        xy = np.array(pts)
        off = _off_road_m(net, xy)
        if off > (tolerance_by_path or {}).get(str(traj.get("name")), tolerance_m):
            errors.append(f"trajectory {traj.get('name')} leaves the road by {off:.2f} m")
    return errors


def declared_parameters(tree: etree._ElementTree) -> dict[str, str]:
    """The file's global ParameterDeclarations: name -> value (as written)."""
    decl = tree.find("ParameterDeclarations")
    return {
        str(p.get("name")): str(p.get("value"))
        for p in ([] if decl is None else decl.iter("ParameterDeclaration"))
    }


def parameter_errors(tree: etree._ElementTree) -> list[str]:
    """Every ``$name`` reference and ``${...}`` expression in an attribute resolves with
    the declared parameters (one line per attribute that does not)."""
    values = declared_parameters(tree)
    errors = []
    for el in tree.iter():
        if el.tag == "ParameterDeclaration" or not isinstance(el.tag, str):
            continue
        for key, value in el.attrib.items():
            if "$" in value:
                try:
                    evaluate(value, values)
                except ExpressionError as exc:
                    errors.append(f"{el.tag}@{key}: {exc}")
    return errors


def _off_road_m(net: RoadNetwork, xy: np.ndarray) -> float:
    """Largest distance (m) of world points outside every road's drivable cross-section."""
    return float(np.max(net.off_road_m(xy[:, 0], xy[:, 1]))) if len(xy) else 0.0
