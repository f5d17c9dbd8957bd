"""``--out`` against certified folders (hostile round fourteen): ``paper``, ``tradeoff``,
``compare`` and ``report --compare`` refuse another command's certified output but accept
their own earlier one; ``evaluate`` and ``probe`` refuse any folder at or inside a
certified one, not a folder below a ``manifest.json`` of another tool. The corpus
(tests/bad_inputs/cases.toml, round 14) has the refusals end to end."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sensorgap.cli import _refuse_unsafe_out, main
from sensorgap.errors import InputError
from sensorgap.filesio import refuse_certified_out, write_manifest

#: Each command's own marker file (what its manifest lists) and the command.
OWN = [
    ("paper", "paper.md"),
    ("tradeoff", "tradeoff.csv"),
    ("compare", "comparison.json"),
    ("report --compare", "comparison.json"),
]


def _certified(folder: Path, *names: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(f"{name}\n")
    write_manifest(folder)
    return folder


@pytest.mark.parametrize(("command", "own"), OWN)
def test_own_earlier_output_is_accepted(tmp_path: Path, command: str, own: str) -> None:
    # a rerun into the command's own folder (its manifest lists its marker) goes on
    _refuse_unsafe_out(_certified(tmp_path / "o", own, "figure.png"), command)


def test_compare_and_report_compare_share_their_folders(tmp_path: Path) -> None:
    # both write the same files (report.compare.write_compare_report)
    folder = _certified(tmp_path / "o", "comparison.json", "report.html")
    _refuse_unsafe_out(folder, "compare")
    _refuse_unsafe_out(folder, "report --compare")


@pytest.mark.parametrize(("command", "own"), OWN)
@pytest.mark.parametrize("other", ["paper.md", "tradeoff.csv", "comparison.json", "summary.json"])
def test_another_commands_output_is_refused(
    tmp_path: Path, command: str, own: str, other: str
) -> None:
    if other == own:
        return
    folder = _certified(tmp_path / "o", other)
    with pytest.raises(
        InputError, match=rf"holds the certified outputs of another command.*no {own}"
    ):
        _refuse_unsafe_out(folder, command)


def test_a_folder_of_ones_own_files_without_a_manifest_is_accepted(tmp_path: Path) -> None:
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "notes.txt").write_text("mine\n")
    for command, _ in OWN:
        _refuse_unsafe_out(tmp_path / "o", command)


def test_tradeoff_rerun_into_its_own_folder(tmp_path: Path) -> None:
    out = tmp_path / "t"
    assert main(["tradeoff", "--quick", "--out", str(out)]) == 0
    assert main(["tradeoff", "--quick", "--out", str(out)]) == 0
    assert main(["verify", str(out)]) == 0


# -- evaluate, probe: at or inside a certified folder ---------------------------------------


@pytest.mark.parametrize("below", ["", "scenarios", "scenarios/x", "a/b/c", "sub/new"])
def test_inside_a_certified_folder_is_refused(tmp_path: Path, below: str) -> None:
    run = _certified(tmp_path / "run", "ranking.json", "scenarios/s.xosc")
    with pytest.raises(InputError, match="certified folder") as exc:
        refuse_certified_out(run / below if below else run, "evaluate")
    assert "\n" not in exc.value.line()


def test_inside_a_nested_certified_folder_names_the_nearest(tmp_path: Path) -> None:
    # sensorgap run's OUT/<vehicle>: both certified, the vehicle folder named
    out = _certified(tmp_path / "OUT", "system_a/ranking.json")
    write_manifest(out / "system_a")
    write_manifest(out)
    with pytest.raises(InputError, match=r"system_a/coverage/x lies inside \S+/OUT/system_a,"):
        refuse_certified_out(out / "system_a" / "coverage" / "x", "probe")


def test_inside_a_certified_folder_through_a_link_is_refused(tmp_path: Path) -> None:
    run = _certified(tmp_path / "run", "ranking.json")
    (tmp_path / "link").symlink_to(run / "sub", target_is_directory=True)
    (run / "sub").mkdir()
    with pytest.raises(InputError, match="certified folder"):
        refuse_certified_out(tmp_path / "link" / "x", "evaluate")


def test_below_another_tools_manifest_is_accepted(tmp_path: Path) -> None:
    # a web app's or a browser extension's manifest.json is not a sensorgap manifest
    (tmp_path / "manifest.json").write_text(json.dumps({"name": "my app", "version": "1"}))
    refuse_certified_out(tmp_path / "results" / "eval", "evaluate")
    refuse_certified_out(tmp_path / "results", "probe")


def test_a_folder_of_ones_own_files_is_accepted(tmp_path: Path) -> None:
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("x\n")
    refuse_certified_out(tmp_path / "mine", "evaluate")
    refuse_certified_out(tmp_path / "mine" / "new", "evaluate")


@pytest.mark.parametrize("command", ["coverage", "nearfield", "farfield", "corridor"])
def test_an_analysis_rerun_into_a_folder_of_ones_own_files(tmp_path: Path, command: str) -> None:
    """An analysis command certifies a folder of the user's files with its own outputs;
    the same command run again there goes on while the user's files are as certified,
    and is refused when one was edited (the new manifest would certify the edit). Another
    command's outputs beside the user's are still refused (hostile round 22: the rerun
    was refused as "another command's outputs")."""
    from sensorgap.cli import _COMMAND_FILES, ANALYSIS_WRITES
    from sensorgap.filesio import refuse_foreign_outputs

    writes = ANALYSIS_WRITES[command]
    mine = _certified(tmp_path / "mine", "notes.txt", "data/raw.csv", *writes)
    refuse_foreign_outputs(mine, writes, command, _COMMAND_FILES)
    (mine / "notes.txt").write_text("edited\n")
    with pytest.raises(InputError, match="notes.txt was changed"):
        refuse_foreign_outputs(mine, writes, command, _COMMAND_FILES)
    for other, files in ANALYSIS_WRITES.items():
        if other == command:
            continue
        folder = _certified(tmp_path / f"with_{other}", "notes.txt", *files, *writes)
        if set(files) <= set(writes):
            continue  # nothing of the other's that this command does not write itself
        with pytest.raises(InputError, match="holds the certified outputs of another command"):
            refuse_foreign_outputs(folder, writes, command, _COMMAND_FILES)
    # a folder without this command's own files is another command's, not its rerun
    partial = _certified(tmp_path / "partial", "notes.txt", writes[0])
    with pytest.raises(InputError, match="holds the certified outputs of another command"):
        refuse_foreign_outputs(partial, writes, command, _COMMAND_FILES)


def test_coverage_runs_again_into_the_folder_of_ones_own_files_it_certified(
    tmp_path: Path,
) -> None:
    """End to end: the same coverage twice into a folder holding the user's notes."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("my notes\n")
    argv = ["coverage", "--vehicle", "system_b", "--environment", "clear", "--target", "car"]
    argv += ["--extent", "-10,10,-10,10", "--resolution", "2", "--out", str(mine)]
    assert main(argv) == 0
    assert main(argv) == 0
    assert main(["verify", str(mine)]) == 0
    assert (mine / "notes.txt").read_text() == "my notes\n"
