"""The official ASAM Quality Checker for OpenSCENARIO (``asam-qc-openscenarioxml``, a test
dependency; issue #15: "ASAM-QC clean") on every exported file: both styles, OpenSCENARIO
1.0 to 1.3, every family kind, and the small search run's catalogs. No issue at any level
(error, warning, information) is allowed.

The checker (1.0.0) runs in process through its own entry point (``run_checks``, as its
``qc_openscenario -c CONFIG`` does after reading the configuration). What it checks per
version: its rules carry the version they are defined from (the rule UID
``asam.net:xosc:<version>:<rule>``) and it skips a rule for older files. The basic and
schema rules (``xml.valid_xml_document``, ``root_tag_is_openscenario``,
``fileheader_is_present``, ``version_is_defined``, ``valid_schema`` against the schema of
the file's version) are defined from 1.0.0: they run for every version. The twelve
reference, parameter and data-type rules (``reference_control.*``,
``parameters.valid_parameter_declaration_in_catalogs``, ``data_type.*``) are defined from
1.2.0: the checker itself skips them for 1.0 and 1.1 files (asserted below, so a checker
that starts running them is noticed).
"""

from __future__ import annotations

import logging
from pathlib import Path

import pytest
from lxml import etree
from qc_baselib import Configuration, Result, StatusType
from qc_openscenario import constants
from qc_openscenario.main import run_checks

from tests.export.conftest import STYLES, VERSIONS

#: Rules defined from this version on (the checker's definition setting).
LATER_RULES_FROM = (1, 2)


def qc_report(path: Path) -> dict[str, tuple[StatusType, list[str]]]:
    """Run the ASAM QC OpenSCENARIO checker bundle on one file: checker id -> (status,
    issues as ``level rule_uid: description``)."""
    config = Configuration()
    config.set_config_param("InputFile", str(path))
    config.register_checker_bundle(constants.BUNDLE_NAME)
    result = Result()
    result.register_checker_bundle(
        name=constants.BUNDLE_NAME,
        description="sensorgap test",
        version=constants.BUNDLE_VERSION,
        summary="",
    )
    result.set_result_version(version=constants.BUNDLE_VERSION)
    quiet = logging.getLogger().level
    logging.getLogger().setLevel(logging.WARNING)  # the checker logs every step at INFO
    try:
        run_checks(config, result)
    finally:
        logging.getLogger().setLevel(quiet)
    return {
        c.checker_id: (
            c.status,
            [f"{i.level.name} {i.rule_uid}: {i.description}" for i in c.issues],
        )
        for c in result.get_checker_results(constants.BUNDLE_NAME)
    }


def _assert_clean(path: Path, version: str) -> None:
    report = qc_report(path)
    issues = [f"{cid}: {msg}" for cid, (_, found) in report.items() for msg in found]
    assert issues == [], f"{path.name}: {issues}"
    skipped = {cid for cid, (status, _) in report.items() if status != StatusType.COMPLETED}
    basic = {cid for cid in report if "_xml_" in cid}
    assert len(basic) == 5 and len(report) == 17, sorted(report)
    if tuple(int(v) for v in version.split(".")) >= LATER_RULES_FROM:
        assert skipped == set(), f"{path.name}: {sorted(skipped)}"
    else:  # the checker's own rule versions: only the basic and schema rules apply
        assert skipped == set(report) - basic, f"{path.name}: {sorted(skipped)}"
        assert all(report[c][0] == StatusType.SKIPPED for c in skipped)


@pytest.mark.parametrize("style", STYLES)
@pytest.mark.parametrize("version", VERSIONS)
def test_asam_qc_finds_no_issue_in_any_family_kind(
    family_catalogs: dict[tuple[str, str], Path], version: str, style: str
) -> None:
    files = sorted((family_catalogs[(style, version)] / "scenarios").glob("*.xosc"))
    assert len(files) >= 10
    for f in files:
        _assert_clean(f, version)


def test_asam_qc_finds_no_issue_in_the_search_catalogs(
    catalog: Path, maneuver_catalog: Path
) -> None:
    for folder in (catalog, maneuver_catalog):
        files = sorted((folder / "scenarios").glob("*.xosc"))
        assert files
        for f in files:
            _assert_clean(f, "1.2")


def test_asam_qc_reports_a_broken_reference(maneuver_catalog: Path, tmp_path: Path) -> None:
    """The harness can fail: an action for an entity that does not exist is an error."""
    src = sorted((maneuver_catalog / "scenarios").glob("*.xosc"))[0]
    tree = etree.parse(str(src))
    tree.find(".//Init/Actions/Private").set("entityRef", "Nobody")
    tree.find(".//RoadNetwork/LogicFile").set(
        "filepath",
        str((src.parent / tree.find(".//RoadNetwork/LogicFile").get("filepath")).resolve()),
    )
    broken = tmp_path / "broken.xosc"
    tree.write(str(broken))
    report = qc_report(broken)
    found = [m for _, msgs in report.values() for m in msgs]
    assert any("resolvable_entity_references" in m and m.startswith("ERROR") for m in found), found
