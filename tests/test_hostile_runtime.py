"""Issue #18: the numba cache folder when the package is read-only, the search store
under damage and changed inputs, and verify against a tampered folder (unit level; the
CLI lines are in the bad-input corpus)."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sqlite3
import stat
import sys
from pathlib import Path
from typing import Any

import pytest

from sensorgap.cli import main
from sensorgap.coverage.figurememo import clear_memo
from sensorgap.errors import InputError
from sensorgap.filesio import verify_manifest, write_manifest
from sensorgap.runtime import numba_cache_dir
from sensorgap.search.store import Store


def _pkg(tmp_path: Path) -> Path:
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True, exist_ok=True)
    (pkg / "sub" / "__init__.py").write_text("")
    return pkg


def test_numba_cache_default_when_package_writable(tmp_path: Path) -> None:
    env: dict[str, str] = {}
    assert numba_cache_dir(_pkg(tmp_path), env) is None
    assert "NUMBA_CACHE_DIR" not in env


def test_numba_cache_moves_to_xdg_when_package_read_only(tmp_path: Path) -> None:
    env = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}
    chosen = numba_cache_dir(_pkg(tmp_path), env, writable=lambda p: False)
    assert chosen == str(tmp_path / "xdg" / "sensorgap" / "numba")
    assert env["NUMBA_CACHE_DIR"] == chosen and Path(chosen).is_dir()


def test_numba_cache_without_home_uses_a_private_temp_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp))
    env: dict[str, str] = {}
    chosen = numba_cache_dir(_pkg(tmp_path), env, writable=lambda p: False)
    assert chosen is not None and Path(chosen).parent == tmp
    mode = os.stat(chosen).st_mode
    assert not mode & (stat.S_IWGRP | stat.S_IWOTH)
    # a folder someone else could write is not used: a fresh one instead
    os.chmod(chosen, 0o777)
    env2: dict[str, str] = {}
    other = numba_cache_dir(_pkg(tmp_path), env2, writable=lambda p: False)
    assert other is not None and other != chosen and Path(other).is_dir()


def test_matplotlib_config_moves_to_a_private_folder_when_home_is_read_only(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Held-out review round four: with HOME unwritable matplotlib printed a multi-line
    warning on every command; now MPLCONFIGDIR points at a private folder (0700) first.
    A writable default or an explicit setting is left alone."""
    from sensorgap.runtime import matplotlib_config_dir

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp))
    env = {"HOME": str(tmp_path / "home")}
    assert matplotlib_config_dir(env, writable=lambda p: True) is None
    assert "MPLCONFIGDIR" not in env
    chosen = matplotlib_config_dir(env, writable=lambda p: False)
    assert chosen is not None and env["MPLCONFIGDIR"] == chosen and Path(chosen).parent == tmp
    assert not os.stat(chosen).st_mode & (stat.S_IWGRP | stat.S_IWOTH)
    assert matplotlib_config_dir(env, writable=lambda p: False) is None  # already set


def test_matplotlib_dir_when_home_or_the_setting_is_a_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Hostile round six: HOME naming a file (os.access said the file was writable) or an
    MPLCONFIGDIR naming a file made matplotlib warn; both now get a private folder."""
    from sensorgap.runtime import matplotlib_config_dir

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp))
    a_file = tmp_path / "file"
    a_file.write_text("x")
    env = {"HOME": str(a_file)}
    chosen = matplotlib_config_dir(env)
    assert chosen is not None and Path(chosen).is_dir() and env["MPLCONFIGDIR"] == chosen
    env = {"MPLCONFIGDIR": str(a_file)}
    assert matplotlib_config_dir(env) is not None and Path(env["MPLCONFIGDIR"]).is_dir()
    env = {"MPLCONFIGDIR": str(tmp_path)}  # usable: left alone
    assert matplotlib_config_dir(env) is None and env["MPLCONFIGDIR"] == str(tmp_path)


def test_matplotlib_dir_when_home_may_not_be_searched(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Hostile round thirteen: a HOME inside another user's 0700 folder (``Path.exists``
    raises PermissionError there on Python 3.11) left matplotlib's default, which warned
    twice on every command; now the next candidate, a private folder, is chosen. (Tests
    run as root, where the permission does not bite: ``exists`` raises as it would.)"""
    from sensorgap.runtime import matplotlib_config_dir

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp))
    locked = tmp_path / "locked"
    real_exists = Path.exists

    def exists(self: Path) -> bool:
        if str(self).startswith(str(locked)):
            raise PermissionError(13, "Permission denied", str(self))
        return real_exists(self)

    monkeypatch.setattr(Path, "exists", exists)
    env = {"HOME": str(locked / "home")}
    chosen = matplotlib_config_dir(env, writable=lambda p: True)
    assert chosen is not None and env["MPLCONFIGDIR"] == chosen and Path(chosen).parent == tmp
    env = {"MPLCONFIGDIR": str(locked / "mpl")}
    assert matplotlib_config_dir(env, writable=lambda p: True) is not None
    assert Path(env["MPLCONFIGDIR"]).parent == tmp


def test_numba_cache_respects_an_explicit_setting(tmp_path: Path) -> None:
    env = {"NUMBA_CACHE_DIR": "/somewhere"}
    assert numba_cache_dir(_pkg(tmp_path), env, writable=lambda p: False) is None
    assert env["NUMBA_CACHE_DIR"] == "/somewhere"


SETTINGS = {"seed": 0}


def _store_with_row(path: Path, inputs: dict[str, str]) -> None:
    store = Store(path, SETTINGS, inputs)
    store.db.execute(
        "INSERT INTO candidates VALUES ('f', 0, 'id', 'clear', NULL, NULL, '{}', '{}', 0.0, 1, '')"
    )
    store.db.commit()
    store.close()


def test_store_refuses_changed_inputs_once_results_are_stored(tmp_path: Path) -> None:
    db = tmp_path / "search.sqlite"
    _store_with_row(db, {"vehicle": "a", "family f": "b"})
    Store(db, SETTINGS, {"vehicle": "a", "family f": "b"}).close()  # unchanged: fine
    with pytest.raises(InputError, match=r"changed since they were stored: vehicle\)"):
        Store(db, SETTINGS, {"vehicle": "X", "family f": "b"})
    with pytest.raises(InputError, match="different settings"):
        Store(db, {"seed": 1}, {"vehicle": "a", "family f": "b"})


@pytest.mark.parametrize("damage", ["garbage", "truncated", "schema", "json"])
def test_store_damage_is_one_input_error(tmp_path: Path, damage: str) -> None:
    db = tmp_path / "search.sqlite"
    _store_with_row(db, {})
    if damage == "garbage":
        db.write_bytes(b"this is not a database at all" * 100)
    elif damage == "truncated":
        db.write_bytes(db.read_bytes()[:1000])
    elif damage == "schema":
        con = sqlite3.connect(db)
        con.executescript("DROP TABLE candidates; CREATE TABLE candidates (a TEXT);")
        con.close()
    else:
        con = sqlite3.connect(db)
        con.execute("UPDATE candidates SET params = '{broken'")
        con.commit()
        con.close()
    with pytest.raises(InputError) as info:
        store = Store(db, SETTINGS, {})
        try:  # a store that opens (a bad row is found when read) is closed here
            store.get("f", 0, "id")
        finally:
            store.close()
    assert str(db) in info.value.line() and "\n" not in info.value.line()


def test_store_in_unwritable_place_is_one_input_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def refuse(*_: object, **__: object) -> None:
        raise sqlite3.OperationalError("unable to open database file")

    monkeypatch.setattr(sqlite3, "connect", refuse)
    with pytest.raises(InputError, match="cannot open"):
        Store(tmp_path / "search.sqlite", SETTINGS, {})


def _folder(tmp_path: Path) -> Path:
    run = tmp_path / "run"
    (run / "sub").mkdir(parents=True)
    (run / "a.txt").write_text("a")
    (run / "sub" / "b.txt").write_text("b")
    write_manifest(run)
    assert verify_manifest(run) == []
    return run


def test_verify_reports_links_temporaries_and_journals(tmp_path: Path) -> None:
    run = _folder(tmp_path)
    (run / "out").symlink_to("/etc")
    (run / "loop").symlink_to(run / "loop")
    (run / ".x.tmp.xosc").write_text("half")
    (run / "search.sqlite-journal").write_text("j")
    problems = verify_manifest(run)
    assert "out is a symbolic link (not allowed in a run folder)" in problems
    assert "loop is a symbolic link (not allowed in a run folder)" in problems
    assert any(p.startswith(".x.tmp.xosc is a left-over temporary") for p in problems)
    assert any(p.startswith("search.sqlite-journal is a left-over") for p in problems)


def test_write_manifest_removes_leftover_temporaries_but_keeps_journals(tmp_path: Path) -> None:
    run = _folder(tmp_path)
    (run / ".a.txt.abc12345.tmp.txt").write_text("half-written")
    (run / "s.sqlite-journal").write_text("j")
    # a journal is never removed; since round 11 (F6) it is not certified either: verify
    # would reject the new manifest
    with pytest.raises(InputError, match="s.sqlite-journal, named like a left-over"):
        write_manifest(run)
    assert (run / "s.sqlite-journal").exists()
    (run / "s.sqlite-journal").unlink()
    write_manifest(run)
    assert not (run / ".a.txt.abc12345.tmp.txt").exists()


def test_verify_refuses_a_listed_temporary_file(tmp_path: Path) -> None:
    """A remark of round 29: a manifest edited to list a file named like a temporary one
    (``.x.tmp``) passed ``verify``, while every command writing the folder refused it as
    "verify would reject": verify now rejects it too."""
    import json

    run = _folder(tmp_path)
    write_manifest(run)
    (run / ".x.tmp").write_text("kept by hand")
    manifest = json.loads((run / "manifest.json").read_text())
    manifest["files"][".x.tmp"] = {
        "bytes": 12,
        "sha256": hashlib.sha256(b"kept by hand").hexdigest(),
    }
    (run / "manifest.json").write_text(json.dumps(manifest))
    problems = verify_manifest(run)
    assert len(problems) == 1 and problems[0].startswith(".x.tmp is named like a temporary")


@pytest.mark.parametrize(
    ("entry", "pattern"),
    [
        ("../../etc/passwd", "normalised relative path"),
        ("/etc/passwd", "not an absolute path"),
        ("sub/../a.txt", "normalised relative path"),
        ("", "non-empty relative path"),
    ],
)
def test_verify_refuses_entries_outside_the_folder(
    tmp_path: Path, entry: str, pattern: str
) -> None:
    import json

    run = _folder(tmp_path)
    m = json.loads((run / "manifest.json").read_text())
    m["files"][entry] = {"bytes": 4, "sha256": "0" * 64}
    (run / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(InputError, match=pattern):
        verify_manifest(run)


@pytest.mark.parametrize(
    "text",
    [
        '{"files": []}',
        "[]",
        "{broken",
        '{"files": {"a.txt": 3}}',
        '{"files": {"a.txt": {"bytes": true, "sha256": "x"}}}',
    ],
)
def test_verify_malformed_manifest(tmp_path: Path, text: str) -> None:
    run = _folder(tmp_path)
    (run / "manifest.json").write_text(text)
    with pytest.raises(InputError, match="manifest.json"):
        verify_manifest(run)


def test_relative_road_is_relative_to_the_family_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import shutil

    from sensorgap.config.presets import resolve_road, templates_dir
    from sensorgap.scenarios import load_family

    fam_dir = tmp_path / "families"
    (fam_dir / "roads").mkdir(parents=True)
    shutil.copy(resolve_road("motorway_r500"), fam_dir / "roads" / "m.xodr")
    text = (templates_dir() / "scenarios" / "cut_in_left.toml").read_text()
    (fam_dir / "f.toml").write_text(text.replace('road = "motorway_r500"', 'road = "roads/m.xodr"'))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    fam = load_family(str(fam_dir / "f.toml"))
    assert fam.settings["road"] == str((fam_dir / "roads" / "m.xodr").resolve())


def test_run_records_the_vehicle_file_absolute(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from sensorgap.search.settings import vehicle_ref as _vehicle_ref

    (tmp_path / "v.toml").write_text("")
    monkeypatch.chdir(tmp_path)
    assert _vehicle_ref("v.toml") == str(tmp_path.resolve() / "v.toml")
    assert _vehicle_ref("system_a") == "system_a"


def test_relative_reaction_is_relative_to_the_vehicle_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from sensorgap.config import load_vehicle, templates_dir
    from sensorgap.config.reaction import load_reaction, reactions_path

    vdir = tmp_path / "car"
    (vdir / "r").mkdir(parents=True)
    text = (templates_dir() / "vehicles" / "system_a.toml").read_text()
    (vdir / "v.toml").write_text(
        text.replace('reaction = "fusion_any"', 'reaction = "r/mine.toml"')
    )
    # a reaction file whose first model is a distinctive one (latency 0.9 s)
    presets = reactions_path().read_text()
    (vdir / "r" / "mine.toml").write_text(
        presets.replace("[reactions.ads_default", "[reactions.x_ads_default").replace(
            "latency_s = 0.3\n", "latency_s = 0.9\n", 1
        )
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    cfg, _ = load_vehicle("../car/v.toml")
    assert cfg.reaction == str((vdir / "r" / "mine.toml").resolve())
    r = load_reaction(cfg.reaction)
    assert r.name.startswith("x_") and r.latency_s == 0.9


def test_names_outside_the_font_are_refused_and_latin_names_draw_without_warnings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import warnings

    from sensorgap.cli import main
    from sensorgap.config import templates_dir

    text = (templates_dir() / "vehicles" / "system_a.toml").read_text()
    (tmp_path / "v.toml").write_text(
        text.replace('name = "System A"', 'name = "Škoda Élan ß-ł $x^{$ (Ä)"')
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert (
            main(
                [
                    "coverage",
                    "--vehicle",
                    str(tmp_path / "v.toml"),
                    "--environment",
                    "clear",
                    "--target",
                    "car",
                    "--resolution",
                    "1",
                    "--extent",
                    "0,10,0,10",
                    "--out",
                    str(tmp_path / "out"),
                ]
            )
            == 0
        )
    assert not [w for w in caught if "Glyph" in str(w.message)], [str(w.message) for w in caught]
    assert capsys.readouterr().err == ""
    (tmp_path / "w.toml").write_text(text.replace('name = "System A"', 'name = "車 A"'))
    assert (
        main(["nearfield", "--vehicle", str(tmp_path / "w.toml"), "--out", str(tmp_path / "nf")])
        == 2
    )
    assert "vehicle.name" in capsys.readouterr().err
    assert not (tmp_path / "nf").exists()


def test_target_reference_height_must_be_on_the_body() -> None:
    from sensorgap.config import TargetConfig

    base = {
        "name": "box",
        "rcs_m2": 1.0,
        "camera_cross_section_m2": 1.0,
        "length_m": 1.0,
        "width_m": 1.0,
        "height_m": 1.5,
        "lidar_reflectance": 0.5,
        "camera_reflectance": 0.5,
    }
    assert TargetConfig.model_validate({**base, "reference_height_m": 1.5})
    with pytest.raises(ValueError, match="must not exceed height_m"):
        TargetConfig.model_validate({**base, "reference_height_m": 1.6})


def test_absolute_reaction_path_is_taken_as_it_is(tmp_path: Path) -> None:
    from sensorgap.config import load_vehicle, templates_dir
    from sensorgap.config.reaction import reactions_path

    text = (templates_dir() / "vehicles" / "system_a.toml").read_text()
    absolute = str(reactions_path().resolve())
    (tmp_path / "v.toml").write_text(
        text.replace('reaction = "fusion_any"', f'reaction = "{absolute}"')
    )
    cfg, _ = load_vehicle(tmp_path / "v.toml")
    assert cfg.reaction == absolute


def test_unit_bounds_by_suffix() -> None:
    from sensorgap.config.parameters import bound_error, bound_of

    # the first suffix that matches wins: a speed is not a speed difference
    assert bound_error("target_speed_m_s", -1.0)
    assert bound_error("speed_delta_m_s", -50.0) is None
    assert bound_error("speed_delta_m_s", 101.0)
    assert bound_error("conflict_offset_s", -1.5) is None
    assert bound_error("lc_start_s", 61.0)
    assert bound_error("decel_m_s2", -1.0)  # its own bound: braking is >= 0
    assert bound_error("accel_m_s2", -1.0) is None  # by unit: +-10 m/s2
    assert bound_error("merge_duration_s", 0.0) and bound_error("parked_gap_m", 0.0)
    assert bound_of("shape") is None


def test_loads_json_refuses_a_key_named_twice() -> None:
    from sensorgap.filesio import loads_json

    assert loads_json('{"a": {"b": 1}, "c": [{"b": 2}]}') == {"a": {"b": 1}, "c": [{"b": 2}]}
    with pytest.raises(ValueError, match="key 'b' appears twice"):
        loads_json('{"a": {"b": 1, "b": 2}}')


def test_lane_change_duration_bounds() -> None:
    from sensorgap.config.parameters import PARAMETER_BOUNDS, bound_error

    b = PARAMETER_BOUNDS["lc_duration_s"]
    assert (b.low, b.high, b.unit) == (1.0, 10.0, "s") and "Olsen" in b.source
    assert bound_error("lc_duration_s", 1.0) is None
    assert bound_error("lc_duration_s", 10.0) is None
    for bad in (0.999, -1.0, 10.01, float("nan"), float("inf")):
        assert bound_error("lc_duration_s", bad)
    assert bound_error("gap0_m", -5.0) is None  # a parameter without a bound


def _esmini_log(path: Path, rows: list[str]) -> Path:
    head = (
        "Index [-] , TimeStamp [sec] , #1 Entity_Name [-] , #1 Entity_ID [-] , "
        "#1 Current_Speed [m/s] , #1 World_Position_X [m] , #1 World_Position_Y [m] , "
        "#1 World_Position_Z [m] , #1 World_Heading_Angle [rad] ,"
    )
    path.write_text("\n".join([head, *rows]) + "\n")
    return path


def test_esmini_log_with_a_short_row_is_a_bad_log(tmp_path: Path) -> None:
    from sensorgap.export.simulate import parse_esmini_csv

    good = "0, 0.00, Ego, 0, 10.0, 1.0, 2.0, 0.0, 0.1,"
    sim = parse_esmini_csv(_esmini_log(tmp_path / "ok.csv", [good, good.replace("0.00", "0.05")]))
    t, x, y, h, v = sim.states["Ego"]
    assert t.tolist() == [0.0, 0.05] and x.tolist() == [1.0, 1.0] and v[0] == 10.0
    with pytest.raises(ValueError, match=r"line 3: 4 fields, no column 9 \(#1 World_Heading"):
        parse_esmini_csv(_esmini_log(tmp_path / "short.csv", [good, "1, 0.05, Ego, 0"]))
    with pytest.raises(ValueError, match="no data rows"):
        parse_esmini_csv(_esmini_log(tmp_path / "empty.csv", []))


@pytest.mark.parametrize(
    ("field", "value", "column"),
    [
        (5, "nan", "#1 World_Position_X"),
        (6, "inf", "#1 World_Position_Y"),
        (1, "nan", "TimeStamp"),
        (4, "1e308", "#1 Current_Speed"),
        (5, "-1000001", "#1 World_Position_X"),
        (8, "-inf", "#1 World_Heading_Angle"),
    ],
)
def test_esmini_log_with_a_non_finite_or_huge_number_is_a_bad_log(
    tmp_path: Path, field: int, value: str, column: str
) -> None:
    """Hostile round thirteen: nan or inf in esmini's CSV log was an internal error
    ("trajectory x is not finite"), 1e308 a numpy overflow warning and then one; every
    number read must now be finite and within +-MAX_ESMINI_LOG_VALUE (a bad log)."""
    from sensorgap.export.simulate import MAX_ESMINI_LOG_VALUE, parse_esmini_csv

    assert MAX_ESMINI_LOG_VALUE == 1e6
    good = "0, 0.00, Ego, 0, 10.0, 1.0, 2.0, 0.0, 0.1,"
    bad = good.split(",")
    bad[field] = f" {value}"
    log = _esmini_log(tmp_path / "bad.csv", [good, ",".join(bad)])
    with pytest.raises(ValueError, match=rf"line 3: {column} \S* is {value}; every number"):
        parse_esmini_csv(log)
    edge = good.replace(" 1.0,", " -1000000,")  # the bound itself is accepted
    assert parse_esmini_csv(_esmini_log(tmp_path / "ok.csv", [edge])).states["Ego"][1][0] == -1e6


def test_esmini_log_with_a_bad_box_number_is_a_bad_log(tmp_path: Path) -> None:
    """The box and velocity columns are optional (an older esmini), but a bad number in
    them is a bad log, never a silently missing box check."""
    from sensorgap.export.simulate import parse_esmini_csv

    head = (
        "Index [-] , TimeStamp [sec] , #1 Entity_Name [-] , #1 Current_Speed [m/s] , "
        "#1 World_Position_X [m] , #1 World_Position_Y [m] , #1 World_Heading_Angle [rad] , "
        "#1 bb_x [m] , #1 bb_y [m] , #1 bb_length [m] , #1 bb_width [m] , "
        "#1 Vel_X [m/s] , #1 Vel_Y [m/s] ,"
    )
    good = "0, 0.0, Ego, 10, 1, 2, 0.1, 1.4, 0, 4.5, 1.8, 10, 0,"
    (tmp_path / "ok.csv").write_text(f"{head}\n{good}\n")
    sim = parse_esmini_csv(tmp_path / "ok.csv")
    assert sim.boxes["Ego"][2].tolist() == [4.5] and sim.velocity["Ego"][0].tolist() == [10.0]
    for i, col in ((9, "bb_length"), (11, "Vel_X")):
        fields = good.split(",")
        fields[i] = " nan"
        (tmp_path / "bad.csv").write_text(f"{head}\n{','.join(fields)}\n")
        with pytest.raises(ValueError, match=rf"line 2: #1 {col} .* is nan"):
            parse_esmini_csv(tmp_path / "bad.csv")


def test_a_relative_esmini_path_is_made_absolute(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Hostile round thirteen: ``--esmini ./esmini`` passed the check but esmini runs in a
    temporary folder, so every scenario failed ("No such file or directory") and a
    certified all-error simulation.csv was written; the path is now resolved where it was
    checked."""
    from sensorgap.export.simulate import find_esmini

    exe = tmp_path / "esmini"
    exe.write_text("#!/bin/sh\n")
    exe.chmod(0o755)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("SENSORGAP_ESMINI", raising=False)
    for given in ("./esmini", "esmini"):
        assert find_esmini(given) == exe
    monkeypatch.setenv("SENSORGAP_ESMINI", "esmini")
    assert find_esmini(None) == exe


def test_a_flooding_or_hanging_esmini_stays_bounded(tmp_path: Path) -> None:
    """Hostile round seven: esmini's output was captured whole (700 MB of stdout peaked at
    4.6 GB RSS), and a timeout killed only a wrapper script, not what it started. Now
    only the tails of its output are read, and the whole session is killed."""
    import resource
    import time

    from sensorgap.export import simulate

    def script(name: str, body: str) -> Path:
        path = tmp_path / name
        path.write_text(f"#!/bin/sh\n{body}\n")
        path.chmod(0o755)
        return path

    work = tmp_path / "work"
    work.mkdir()
    xosc = tmp_path / "s.xosc"
    xosc.write_text("<OpenSCENARIO/>")
    flood = script("flood.sh", "yes 'flood line' | head -c 200000000\necho 'last words' >&2")
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    res = simulate.run_esmini(flood, xosc, work, 60.0, 0.05)
    # (it was called "crashed: esmini exit code 0"; it ended normally without its log)
    assert res == "bad log: esmini ended with exit code 0 without writing log.csv: last words"
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 100_000  # KiB
    marker = tmp_path / "still_running"
    wrapper = script("wrap.sh", f"(sleep 1.5; touch {marker}) &\nsleep 30")
    t0 = time.perf_counter()
    assert simulate.run_esmini(wrapper, xosc, work, 0.5, 0.05) == (
        "timeout: esmini did not finish within 0.5 s (killed)"
    )
    assert time.perf_counter() - t0 < 5.0
    time.sleep(max(0.0, t0 + 2.0 - time.perf_counter()))
    assert not marker.exists()  # the wrapper's children were killed with it
    # hostile round 37: a wrapper that ends at once, leaving a child behind in its session
    left = tmp_path / "left_running"
    quick = script("quick.sh", f"(sleep 0.5; touch {left}) &\nexit 3")
    t0 = time.perf_counter()
    assert simulate.run_esmini(quick, xosc, work, 60.0, 0.05) == "crashed: esmini exit code 3: "
    time.sleep(max(0.0, t0 + 1.2 - time.perf_counter()))
    assert not left.exists()  # what it left running was killed when it ended


def test_an_esmini_script_with_windows_line_ends_is_named_for_its_interpreter(
    tmp_path: Path,
) -> None:
    """A wrapper script saved with Windows line ends asks for ``/bin/sh\\r``, and the
    system says "No such file or directory" naming the script, which exists (remark of
    session 25). The reason names its #! line and the carriage return."""
    from sensorgap.export import simulate

    crlf = tmp_path / "esmini"
    crlf.write_bytes(b"#!/bin/sh\r\necho hi\r\n")
    crlf.chmod(0o755)
    work = tmp_path / "work"
    work.mkdir()
    xosc = tmp_path / "s.xosc"
    xosc.write_text("<OpenSCENARIO/>")
    res = simulate.run_esmini(crlf, xosc, work, 60.0, 0.05)
    assert isinstance(res, str)
    assert res == (
        f"error: cannot run esmini: {crlf}: the interpreter of its #! line (/bin/sh\\r) was "
        "not found (the line ends in a carriage return: saved with Windows line ends)"
    ), res
    gone = tmp_path / "gone"
    gone.write_bytes(b"#!/no/such/shell\necho hi\n")
    gone.chmod(0o755)
    res = simulate.run_esmini(gone, xosc, work, 60.0, 0.05)
    assert res == (
        f"error: cannot run esmini: {gone}: the interpreter of its #! line (/no/such/shell) "
        "was not found"
    ), res


def test_an_oversized_esmini_log_is_a_bad_log(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from sensorgap.export import simulate

    monkeypatch.setattr(simulate, "MAX_ESMINI_LOG_BYTES", 100)
    log = _esmini_log(tmp_path / "big.csv", ["0, 0.00, Ego, 0, 10.0, 1.0, 2.0, 0.0, 0.1,"] * 5)
    with pytest.raises(ValueError, match=r"big\.csv: \d+ bytes; at most 100 read"):
        simulate.parse_esmini_csv(log)


def test_sigterm_unwinds_and_leaves_no_temporary_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import signal
    import time

    from matplotlib.figure import Figure

    from sensorgap.cli import main

    def killed_while_saving(self: Figure, fname: Any, **kwargs: object) -> None:
        fname.write(b"half a png")  # the figure is drawn into memory, then written
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the handler runs before this returns
        raise AssertionError("SIGTERM was not delivered")

    monkeypatch.setattr(Figure, "savefig", killed_while_saving)
    clear_memo()  # drawn (and killed) here, not written from an earlier test's figure
    previous = signal.getsignal(signal.SIGTERM)
    out = tmp_path / "out"
    assert (
        main(
            [
                "coverage",
                "--vehicle",
                "system_a",
                "--environment",
                "clear",
                "--target",
                "car",
                "--resolution",
                "1",
                "--extent",
                "0,10,0,10",
                "--out",
                str(out),
            ]
        )
        == 143
    )
    assert capsys.readouterr().err.strip() == "sensorgap: interrupted"
    # nothing half-written: not its temporary file, nor the folder it had created
    # (hostile round eight: the empty --out stayed; a report's first figures stayed,
    # unlisted, and verify failed until the report was rerun)
    assert not out.exists()
    assert signal.getsignal(signal.SIGTERM) == previous  # restored after the command


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP"])
def test_sighup_stops_a_command_as_sigterm_does(
    name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round twelve: SIGHUP (the terminal closed) killed a command half-way with
    exit 129, leaving its temporary files, a half-written export or report, and a fresh
    nested --out. Now it unwinds as SIGTERM does: one line, exit 128 + the signal's
    number, nothing left (the fresh --out and the parents it made removed)."""
    import signal
    import time

    from matplotlib.figure import Figure

    sig = getattr(signal, name)

    def killed_while_saving(self: Figure, fname: Any, **kwargs: object) -> None:
        fname.write(b"half a png")
        os.kill(os.getpid(), sig)
        time.sleep(5)
        raise AssertionError(f"{name} was not delivered")

    monkeypatch.setattr(Figure, "savefig", killed_while_saving)
    clear_memo()
    before = signal.getsignal(sig)
    out = tmp_path / "a" / "b" / "out"
    argv = ["coverage", "--vehicle", "system_a", "--environment", "clear", "--target", "car"]
    argv += ["--resolution", "1", "--extent", "0,10,0,10", "--out", str(out)]
    assert main(argv) == 128 + sig
    assert capsys.readouterr().err.strip() == "sensorgap: interrupted"
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(sig) == before


def test_standard_error_that_cannot_be_written_keeps_the_exit_code(tmp_path: Path) -> None:
    """Hostile round twelve: ``2>/dev/full`` turned a bad input (one line, exit 2) into an
    internal error (exit 1): printing the line failed. Now the line is lost, the exit code
    is the command's."""
    import subprocess
    import sys

    argv = [sys.executable, "-m", "sensorgap", "verify", str(tmp_path / "missing")]
    with open("/dev/full", "w") as full:
        done = subprocess.run(argv, stderr=full, stdout=subprocess.DEVNULL, check=False)
    assert done.returncode == 2


@pytest.mark.parametrize(
    ("variable", "why"),
    [
        ("NUMBA_NUM_THREADS=0", "numba refuses it"),  # was an internal error
        ("NUMBA_OPT=99", "numba cannot parse it"),  # was numba's RuntimeWarning on stderr
    ],
)
def test_a_numba_variable_numba_cannot_take_is_one_line(variable: str, why: str) -> None:
    """Hostile round twelve: numba reads its ``NUMBA_*`` variables on import; one it
    cannot take is now refused before the command starts, naming the variable."""
    import subprocess
    import sys

    name, value = variable.split("=")
    env = {**os.environ, name: value}
    done = subprocess.run(
        [sys.executable, "-m", "sensorgap", "schema", "vehicle"],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr == (
        f"sensorgap: error: environment variable {name}: '{value}': {why}"
        + (" (Number of threads specified must be > 0.)" if name == "NUMBA_NUM_THREADS" else "")
        + "; unset it or correct it\n"
    )


def test_a_sigterm_after_the_command_is_done_keeps_its_exit_code(tmp_path: Path) -> None:
    """Hostile round eleven (F13): a SIGTERM in the interpreter's shutdown, after the
    command had written its complete output, ended the process with 143 and no line. The
    command's own process (``main()`` with ``sys.argv``) now ignores SIGTERM and Ctrl-C
    once the command is done: the exit code is the command's, nothing on stderr. A caller
    of ``main(argv)`` gets its own handler back (test above)."""
    import signal
    import subprocess
    import sys

    child = (
        "import os, signal, sys, time\n"
        "from sensorgap.cli import main\n"
        "code = main()\n"
        "os.kill(os.getpid(), signal.SIGTERM)\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(0.2)\n"
        "sys.exit(code)\n"
    )
    out = tmp_path / "schema.json"
    with out.open("wb") as stdout:
        done = subprocess.run(
            [sys.executable, "-c", child, "schema", "vehicle"],
            stdout=stdout,
            stderr=subprocess.PIPE,
            check=False,
        )
    assert (done.returncode, done.stderr) == (0, b"")
    assert out.read_bytes().startswith(b"{") and out.stat().st_size > 1000
    bad = subprocess.run(
        [sys.executable, "-c", child, "schema", "nothing"],
        capture_output=True,
        check=False,
    )
    assert bad.returncode == 2 and bad.stderr.count(b"\n") == 1, bad.stderr
    assert signal.getsignal(signal.SIGTERM) is not signal.SIG_IGN  # this process untouched


def test_environment_name_with_dollars_is_drawn_as_written_in_the_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the scenario figure's colour-bar label mixes math ($p_d$) with the environment name:
    # a name 'a$x^{$' was parsed as math there (internal error)
    from sensorgap.cli import main
    from sensorgap.config import templates_dir

    text = (templates_dir() / "environments.toml").read_text()
    name = "a$x^{$ Ä"
    text = text.replace("[environments.snow", f'[environments."{name}"')
    (tmp_path / "e.toml").write_text(text)
    run = tmp_path / "run"
    assert (
        main(
            [
                "search",
                "--vehicle",
                "system_b",
                "--families",
                "stopped_rural_curve",
                "--environments-file",
                str(tmp_path / "e.toml"),
                "--environments",
                name,
                "--budget",
                "12",
                "--top",
                "1",
                "--strategy",
                "lhs",
                "--out",
                str(run),
            ]
        )
        == 0
    )
    assert main(["report", "--run", str(run)]) == 0, capsys.readouterr().err
    assert (run / "report" / "scenario_001.png").is_file()
    assert name in (run / "report.md").read_text()


def test_a_users_tmp_files_survive_a_write_into_their_folder(tmp_path: Path) -> None:
    """Held-out review round four: writing into an existing folder removed every `*.tmp`
    below it. Only sensorgap's own temporaries (``.NAME.<8 random>.tmp.EXT``, left by an
    interrupted command) are removed; a user's files stay. Since round 11 (F6) a user's
    temporary-looking file is refused up front (verify would reject the new manifest)."""
    from sensorgap.filesio import is_own_temporary

    out = tmp_path / "proj"
    (out / "deep").mkdir(parents=True)
    mine = [out / "deep" / "report.tmp", out / ".notes.tmp.txt"]
    for p in mine:
        p.write_text("user data")
    ours = out / ".nearfield.png.abcd1234.tmp.png"
    ours.write_text("half")
    assert is_own_temporary(ours.name) and not any(is_own_temporary(p.name) for p in mine)
    argv = ["nearfield", "--vehicle", "system_a", "--resolution", "1", "--out", str(out)]
    assert main(argv) == 2
    assert all(p.read_text() == "user data" for p in mine) and ours.exists()
    for p in mine:
        p.rename(p.with_name(p.name.replace(".tmp", "")))
    assert main(argv) == 0
    assert not ours.exists() and main(["verify", str(out)]) == 0


@pytest.mark.parametrize(
    "argv",
    [
        ["nearfield", "--vehicle", "system_a", "--out", ""],
        ["search", "--vehicle", "system_a", "--budget", "10", "--out", " "],
    ],
)
def test_an_empty_out_is_refused(
    argv: list[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert (
        capsys.readouterr()
        .err.strip()
        .endswith("(an empty path would write into the working directory)")
    )
    assert list(tmp_path.iterdir()) == []


def test_refuse_if_changed_unit(tmp_path: Path) -> None:
    """A manifest is rewritten only over what the command writes itself: a listed file
    changed is refused (naming it); the command's own outputs (a file, a folder, a
    folder's direct children), files added or lost since and a folder without a manifest
    pass, a lost file staying listed."""
    from sensorgap.filesio import refuse_if_changed

    refuse_if_changed(tmp_path / "nothing", ("x",))  # no manifest: nothing certified yet
    run = _folder(tmp_path)
    refuse_if_changed(run, ())
    (run / "new.txt").write_text("n")  # added since: e.g. another command's outputs
    refuse_if_changed(run, ())
    (run / "a.txt").write_text("A")
    (run / "sub" / "b.txt").write_text("B")
    with pytest.raises(InputError, match=r"a\.txt was changed .*and 1 more"):
        refuse_if_changed(run, ())
    with pytest.raises(InputError, match=r"sub/b\.txt was changed"):
        refuse_if_changed(run, ("a.txt",))
    refuse_if_changed(run, ("a.txt", "sub/*"))
    refuse_if_changed(run, ("a.txt", "sub/"))
    (run / "sub" / "b.txt").unlink()
    (run / "sub" / "deeper").mkdir()
    (run / "sub" / "deeper" / "b.txt").write_text("b")
    refuse_if_changed(run, ("a.txt", "sub/*"))  # sub/b.txt is a direct child: ours
    # a file lost is not refused (the command degrades) but stays listed by the manifest
    # written with the same rewrites, so verify keeps reporting it
    (run / "a.txt").write_text("a")
    (run / "sub" / "b.txt").write_text("b")
    write_manifest(run)
    (run / "sub" / "b.txt").unlink()
    refuse_if_changed(run, ())
    write_manifest(run, ())
    assert verify_manifest(run) == ["sub/b.txt is missing"]
    write_manifest(run, ("sub/",))  # a file the command writes itself: not kept
    assert verify_manifest(run) == []
    (run / "a.txt").unlink()  # the run's own record, at the top: refused
    with pytest.raises(InputError, match=r"a\.txt is missing"):
        refuse_if_changed(run, ())


def _small_search(run: Path, budget: str, *extra: str) -> int:
    """A small search of System B (slow_ahead_curve in snow, seed 1, top 2) into ``run``."""
    return main(
        [
            "search",
            "--vehicle",
            "system_b",
            "--families",
            "slow_ahead_curve",
            "--environments",
            "snow",
            "--budget",
            budget,
            "--seed",
            "1",
            "--top",
            "2",
            "--out",
            str(run),
            *extra,
        ]
    )


def test_report_and_export_do_not_certify_a_tampered_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Held-out review round four: `report --run` (and an export in place) rewrote the
    manifest over a ranking.csv edited by hand, after which `verify` said OK. Now they
    refuse (exit 2, one line naming the file) and leave the folder as it was; an intact
    run is reported, exported and re-reported as before, and verifies. A part lost from a
    sub-folder lets the report degrade and stays listed (verify names it); the run's own
    record lost from the top of the folder is refused."""
    run = tmp_path / "run"
    assert _small_search(run, "30", "--strategy", "lhs") == 0
    assert main(["report", "--run", str(run)]) == 0
    assert main(["export", "--run", str(run)]) == 0
    assert main(["report", "--run", str(run)]) == 0
    assert main(["verify", str(run)]) == 0
    capsys.readouterr()
    original = (run / "ranking.csv").read_bytes()
    (run / "ranking.csv").write_text((run / "ranking.csv").read_text() + "forged,row\n")
    before = {p: p.read_bytes() for p in run.rglob("*") if p.is_file()}
    for argv in (["report", "--run", str(run)], ["export", "--run", str(run)]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        # the manifest, or the store's record of the ranking files (round eighteen, F5)
        assert len(err) == 1 and "ranking.csv" in err[0], err
        assert "ranking.csv was changed" in err[0] or "is not the file the search" in err[0]
    assert {p: p.read_bytes() for p in run.rglob("*") if p.is_file()} == before
    assert main(["verify", str(run)]) != 0
    # a lost part (in a sub-folder) is not refused: the report degrades, and verify still
    # names the loss; a lost record at the top (ranking.json) is refused
    (run / "ranking.csv").write_bytes(original)
    assert main(["verify", str(run)]) == 0
    lost = sorted((run / "scenarios").glob("*.xosc"))[0]
    lost.unlink()
    assert main(["report", "--run", str(run)]) == 0
    capsys.readouterr()
    assert main(["verify", str(run)]) != 0
    assert f"scenarios/{lost.name} is missing" in capsys.readouterr().err
    (run / "ranking.json").unlink()
    assert main(["report", "--run", str(run)]) == 2
    assert "ranking.json is missing" in capsys.readouterr().err


def test_a_reaction_files_friction_is_used(tmp_path: Path) -> None:
    """Held-out review round four: a vehicle's own reaction file with its own [friction]
    table was evaluated with the shipped friction. Now the evaluator, the run record and
    the run folder's evaluator use that table (dry road 0.3 instead of 0.9: the
    deceleration limit is 2.9 m/s2)."""
    from sensorgap.config import templates_dir
    from sensorgap.config.reaction import friction_source, load_friction, reactions_path
    from sensorgap.models import load_system
    from sensorgap.search.evaluate import Evaluator
    from sensorgap.search.runfolder import read_run

    shipped = load_friction()
    vdir = tmp_path / "car"
    vdir.mkdir()
    presets = reactions_path().read_text()
    assert "dry = 0.9" in presets
    (vdir / "mine.toml").write_text(presets.replace("dry = 0.9", "dry = 0.3", 1))
    text = (templates_dir() / "vehicles" / "system_a.toml").read_text()
    (vdir / "v.toml").write_text(text.replace('reaction = "fusion_any"', 'reaction = "mine.toml"'))
    system = load_system(str(vdir / "v.toml"))
    assert friction_source(system.config.reaction) == (vdir / "mine.toml").resolve()
    ev = Evaluator(system)
    assert ev.friction["dry"] == 0.3 and ev.friction["wet"] == shipped["wet"]
    run = tmp_path / "run"
    assert (
        main(
            [
                "search",
                "--vehicle",
                str(vdir / "v.toml"),
                "--families",
                "slow_ahead_curve",
                "--environments",
                "clear",
                "--budget",
                "8",
                "--strategy",
                "lhs",
                "--out",
                str(run),
            ]
        )
        == 0
    )
    assert read_run(run).evaluator().friction["dry"] == 0.3
    # a reaction file without a [friction] table: the shipped one
    (vdir / "bare.toml").write_text(presets.split("\n[friction]\n")[0])
    assert friction_source(str(vdir / "bare.toml")) == reactions_path()


def test_a_resumed_search_that_changes_the_ranking_removes_the_stale_export(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round five: a resumed search whose ranking changed left the previous
    export and report in the folder, and the new manifest certified them although they no
    longer matched ranking.json. Now they are removed (one line says so) and the folder
    verifies; a resume that leaves the ranking as it was keeps them."""
    run = tmp_path / "run"

    def search(budget: str, *extra: str) -> int:
        return _small_search(run, budget, *extra)

    assert search("40") == 0
    assert main(["export", "--run", str(run)]) == 0
    assert main(["report", "--run", str(run)]) == 0
    kept = sorted(p.relative_to(run).as_posix() for p in run.rglob("*") if p.is_file())
    assert "catalog.json" in kept and "report.html" in kept
    capsys.readouterr()
    assert search("40", "--resume") == 0  # same budget: the same ranking
    assert "removed" not in capsys.readouterr().out
    assert (run / "catalog.json").is_file() and (run / "report.html").is_file()
    ranking = (run / "ranking.json").read_bytes()
    assert search("400", "--resume") == 0
    out = capsys.readouterr().out
    assert (run / "ranking.json").read_bytes() != ranking
    assert "changed the ranking: removed" in out
    for gone in ("catalog.json", "report.html", "report.md", "scenarios", "roads", "report"):
        assert not (run / gone).exists(), gone
    assert main(["verify", str(run)]) == 0


def _as_unprivileged(argv: list[str]) -> tuple[list[str], dict[str, str]]:
    """The sensorgap command line run without the right to override file permissions, with
    no HOME: root keeps its identity (so it can still read a checkout in a private folder)
    but loses CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH (setpriv); others run as
    themselves."""
    import shutil
    import sys

    cmd = [sys.executable, "-m", "sensorgap", *argv]
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": os.pathsep.join(sys.path)}
    if os.geteuid() == 0:
        setpriv = shutil.which("setpriv")
        if setpriv is None:
            pytest.skip("running as root without setpriv: permissions cannot be enforced")
        drop = ["--bounding-set=-dac_override,-dac_read_search", "--inh-caps=-all"]
        cmd = [setpriv, *drop, *cmd]
    return cmd, env


def test_read_only_places_as_a_real_user_are_one_line(tmp_path: Path) -> None:
    """Issue #18 on a real file system, not a patched sqlite: for a process that may not
    write the output folder (mode 0555), search and coverage into it are one line, exit 2,
    and nothing is written there. (As root, first checked: the folder really refuses the
    process's writes.)"""
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        _read_only_cases(ro)
    finally:
        ro.chmod(0o755)


def _read_only_cases(ro: Path) -> None:
    import subprocess

    cases = {
        "search.sqlite: cannot open": ["search", "--vehicle", "system_a", "--budget", "40"],
        # the output file, not its hidden temporary (".coverage.npz.56l1knkx.tmp.npz")
        f"{ro}/coverage.npz: cannot write or read: Permission denied": [
            "coverage",
            "--vehicle",
            "system_a",
            "--environment",
            "clear",
            "--target",
            "car",
            "--resolution",
            "2",
            "--extent=-10,10,-10,10",
        ],
    }
    import sys

    probe, env = _as_unprivileged([])
    probe = [*probe[: probe.index("-m")], "-c", f"open({str(ro / 'x')!r}, 'w')"]
    refused = subprocess.run(probe, env=env, capture_output=True, text=True, timeout=60)
    if refused.stderr.startswith("setpriv:"):  # a container without CAP_SETPCAP
        pytest.skip(f"setpriv cannot drop capabilities here: {refused.stderr.strip()}")
    assert refused.returncode != 0 and "Permission denied" in refused.stderr, sys.executable
    for expected, argv in cases.items():
        cmd, env = _as_unprivileged([*argv, "--out", str(ro)])
        done = subprocess.run(cmd, env=env, cwd="/", capture_output=True, text=True, timeout=300)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1, done.stderr
        assert lines[0].startswith("sensorgap: error: ") and expected in lines[0], lines[0]
        assert list(ro.iterdir()) == []


def test_cached_kernels_are_dropped_when_an_inlined_helpers_module_changes(
    tmp_path: Path,
) -> None:
    """numba checks a cached kernel against its own file only: a change to a helper it
    inlines from another kernel module must drop the cache (``runtime.drop_stale_kernels``);
    a change to a module without kernels must not."""
    from sensorgap.runtime import SOURCES_STAMP, drop_stale_kernels

    pkg = tmp_path / "pkg"
    (pkg / "sub" / "__pycache__").mkdir(parents=True)
    (pkg / "kernel.py").write_text("import numba\n@numba.njit(cache=True)\ndef k(x): return h(x)\n")
    (pkg / "sub" / "helper.py").write_text(
        "import numba\n@numba.njit(inline='always')\ndef h(x): return x\n"
    )
    (pkg / "cli.py").write_text("print('no kernels here')\n")

    def cached() -> list[Path]:
        (pkg / "sub" / "__pycache__" / "kernel.k-3.py311.nbi").write_bytes(b"i")
        (pkg / "sub" / "__pycache__" / "kernel.k-3.py311.1.nbc").write_bytes(b"c")
        return sorted((pkg / "sub" / "__pycache__").glob("*.nb?"))

    cached()
    assert drop_stale_kernels(pkg, pkg)  # no record yet: provenance unknown, dropped
    assert (pkg / "__pycache__" / SOURCES_STAMP).is_file()
    assert len(cached()) == 2 and not drop_stale_kernels(pkg, pkg)  # same sources: kept
    (pkg / "cli.py").write_text("print('still no kernels')\n")
    assert not drop_stale_kernels(pkg, pkg) and len(cached()) == 2
    (pkg / "sub" / "helper.py").write_text(
        "import numba\n@numba.njit(inline='always')\ndef h(x): return -x\n"
    )
    assert drop_stale_kernels(pkg, pkg)
    assert not list((pkg / "sub" / "__pycache__").glob("*.nb?"))
    # a cache folder of its own (package read-only): the record lives in that folder
    own = tmp_path / "cache"
    assert not drop_stale_kernels(pkg, own) and (own / SOURCES_STAMP).is_file()


# -- hostile round ten (streams, environment, messages) ---------------------------------


def test_a_read_only_store_is_not_called_damaged(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``search --resume`` on a store the user may not write (another user's run folder)
    was "not a readable sensorgap search database (attempt to write a readonly database);
    delete it": advice that loses a valid run. It says it cannot be written."""
    db = tmp_path / "search.sqlite"
    _store_with_row(db, {"vehicle": "a"})
    connect = sqlite3.connect

    def read_only(path: Path, *args: object, **kwargs: object) -> sqlite3.Connection:
        return connect(f"file:{path}?mode=ro", *args, uri=True, **kwargs)  # type: ignore[misc]

    monkeypatch.setattr(sqlite3, "connect", read_only)
    with pytest.raises(InputError) as info:
        Store(db, SETTINGS, {"vehicle": "a"})
    line = info.value.line()
    assert line.startswith(f"{db}: cannot be written (attempt to write a readonly database)")
    assert "stored results are kept" in line and "delete" not in line


def test_verify_says_a_folder_it_cannot_list_cannot_be_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A sub-folder the user may not read (``chmod 000 run/scenarios``) hid its files from
    the walk: verify said ``scenarios/X.xosc is missing``. (Root reads any folder: the
    refusal is the system's, patched in.)"""
    run = _folder(tmp_path)
    (run / "empty").mkdir()
    write_manifest(run)
    scandir = os.scandir

    def refuse(path: object = ".") -> object:
        if Path(str(path)).name in ("sub", "empty"):
            raise PermissionError(13, "Permission denied", str(path))
        return scandir(path)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "scandir", refuse)
    assert verify_manifest(run) == [
        "sub/b.txt cannot be read: its folder sub cannot be listed (Permission denied)",
        "empty cannot be listed (Permission denied): what it holds cannot be checked",
    ]
    assert main(["verify", str(run)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"sensorgap: error: {run / 'manifest.json'}: files: sub/b.txt cannot be read: its "
        "folder sub cannot be listed (Permission denied) (and 1 more)"
    ]
    with pytest.raises(PermissionError):  # a manifest never leaves out what it cannot see
        write_manifest(run)


@pytest.mark.parametrize("umask", [0o077, 0o022, 0o002])
def test_output_files_follow_the_umask(tmp_path: Path, umask: int) -> None:
    """Every output file was chmod'ed to 0644 whatever the umask (``umask 077`` left the
    folder 0700 and its files readable by all): a file gets what ``open(..., "w")``
    would give, 0666 without the umask's bits."""
    from sensorgap.atomic import atomic_write_bytes

    old = os.umask(umask)
    try:
        atomic_write_bytes(tmp_path / "a.bin", b"x")
        assert (
            main(
                [
                    "nearfield",
                    "--vehicle",
                    "system_a",
                    "--resolution",
                    "1",
                    "--out",
                    str(tmp_path / "nf"),
                ]
            )
            == 0
        )
    finally:
        os.umask(old)
    files = [tmp_path / "a.bin", *(tmp_path / "nf").iterdir()]
    assert len(files) == 4
    for f in files:
        assert stat.S_IMODE(f.stat().st_mode) == 0o666 & ~umask, f


def test_a_failed_write_names_the_output_file(tmp_path: Path) -> None:
    """A write that fails names no file (ENOSPC, EFBIG: "output: cannot write or read: No
    space left on device"): the error of ``atomic_path`` names the file being written."""
    import errno

    from sensorgap.atomic import atomic_path
    from sensorgap.cli import _os_error_line

    target = tmp_path / "map.npz"
    with pytest.raises(OSError) as info, atomic_path(target):
        raise OSError(errno.ENOSPC, "No space left on device")
    assert info.value.filename == str(target)
    assert list(tmp_path.iterdir()) == []
    # a copy into the temporary file (shutil: filename the source, filename2 the copy)
    with pytest.raises(OSError) as info, atomic_path(target) as tmp:
        raise OSError(errno.ENOSPC, "No space left on device", "/src.xodr", None, str(tmp))
    assert (info.value.filename, info.value.filename2) == ("/src.xodr", str(target))
    assert _os_error_line(info.value, None) == (
        f"sensorgap: error: {target}: cannot write or read: No space left on device "
        "(no partial file was left)"
    )


def test_source_date_epoch_accepts_ascii_seconds_up_to_the_year_9999(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from sensorgap.provenance import MAX_SOURCE_DATE_EPOCH, utc_now

    for text, when in (
        ("0", "1970-01-01T00:00:00Z"),
        ("0001700000000", "2023-11-14T22:13:20Z"),
        (str(MAX_SOURCE_DATE_EPOCH), "9999-12-31T23:59:59Z"),
    ):
        monkeypatch.setenv("SOURCE_DATE_EPOCH", text)
        assert utc_now() == when
    for text in ("", " 1", "+1", "-1", "1.5", "²", "１７００000000", "9" * 5000):
        monkeypatch.setenv("SOURCE_DATE_EPOCH", text)
        with pytest.raises(InputError, match="^SOURCE_DATE_EPOCH: must be whole seconds"):
            utc_now()


def test_every_quoted_or_named_value_in_an_error_line_is_cut() -> None:
    """One place (``errors.clip``, applied by ``InputError.line``) keeps a 100 kB value out
    of an error line, whatever message quoted it; short values and apostrophes inside
    words are left alone."""
    from sensorgap.errors import clip

    long = "a" * 100_000
    line = InputError(f"/x/{long}.toml", "", f"got {long!r} and {'b' * 300 + ' c'!r}").line()
    assert len(line) < 500 and "(100008 characters)" in line and line.count("...") == 3
    assert line.endswith(
        "'bbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbb... (302 characters)"
    )
    text = "the table's key 'clear' (or be left out), got 'fog_50'; the vehicle's file"
    assert clip(text) == text
    assert clip(f"it's {long!r}") == f"it's {repr(long)[:60]}... (100000 characters)"


def test_error_lines_escape_control_and_bidi_characters_and_count_the_users_characters() -> None:
    """Hostile round 11 (F8): an ESC, another C0/C1 control or a bidirectional or format
    character (U+200E/F, U+202A-202E, U+2066-2069) in a file name, a folder or a TOML key
    named without quotes reached the error line raw (``verify $'x\\e[2Jy'`` cleared the
    screen). Every unprintable character is now escaped as repr does, in ``errors.clip``,
    and a cut value's length counts the user's characters, not their escapes (40,000 times
    U+202E was '(240002 characters)')."""
    from sensorgap.errors import clip

    bad = "\x1b\x07\x00\x7f\x9b\u200e\u200f\u202a\u202e\u2066\u2069\ufeff\udcff"
    line = InputError(f"/t/{bad}.toml", f"devices.{bad}.type", f"got {bad!r}").line()
    assert line.isprintable() and line.isascii()
    escaped = r"\x1b\x07\x00\x7f\x9b\u200e\u200f\u202a\u202e\u2066\u2069\ufeff\udcff"
    assert line == f"/t/{escaped}.toml: devices.{escaped}.type: got '{escaped}'"
    assert clip("x\x1b[2Jy z: folder does not exist") == r"x\x1b[2Jy z: folder does not exist"
    assert clip(clip(line)) == line  # escaping twice changes nothing
    rlo = "\u202e" * 40_000
    assert clip(f"got {rlo!r}").endswith("\\u202e... (40000 characters)")
    assert clip(f"got {'5' * 100_000!r}").endswith("... (100000 characters)")
    named = clip("/x/" + "\x1b" * 1000 + " rest")
    assert named.endswith(r"\x1b (1003 characters) rest") and len(named) < 300


def test_a_manifest_over_its_documented_size_is_refused_unread(tmp_path: Path) -> None:
    """docs/limits.md names the manifest's own limit (``filesio.MAX_MANIFEST_BYTES``,
    100 MB; hostile round twelve found the docs saying 20 MB for it): one byte more is
    refused in one line without being read (a sparse file: nothing is allocated)."""
    from sensorgap.filesio import MAX_MANIFEST_BYTES

    (tmp_path / "a.txt").write_text("a")
    write_manifest(tmp_path)
    os.truncate(tmp_path / "manifest.json", MAX_MANIFEST_BYTES + 1)
    with pytest.raises(InputError, match=r"manifest\.json: larger than 100 MB; not a sensorgap"):
        verify_manifest(tmp_path)
    assert main(["verify", str(tmp_path)]) == 2


# -- round fourteen: a umask without the owner's write, memory limits -------------------


def test_a_kernel_whose_cache_numba_cannot_place_compiles_without_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """numba raises "no locator available" when no cache folder can be used for a kernel's
    file (a cache folder a ``umask 277`` run left read-only to its owner): every compiling
    command was an internal error. ``jit.njit`` compiles such a kernel without the cache;
    any other numba error still surfaces."""
    import numba

    from sensorgap import jit

    real = numba.njit
    seen: list[bool] = []

    def fake(*args: object, cache: bool = False, **kw: object) -> object:
        seen.append(cache)
        if cache:
            raise RuntimeError("cannot cache function 'k': no locator available for file 'x'")
        return real(*args, **kw)

    monkeypatch.setattr(numba, "njit", fake)

    @jit.njit(nogil=True)
    def k(x: float) -> float:
        return 2.0 * x

    assert k(1.5) == 3.0 and seen == [True, False]

    def broken(*args: object, **kw: object) -> object:
        raise RuntimeError("some other numba failure")

    monkeypatch.setattr(numba, "njit", broken)
    with pytest.raises(RuntimeError, match="some other"):
        jit.njit()(lambda x: x)


def test_a_umask_without_the_owners_write_turns_the_kernel_cache_off(tmp_path: Path) -> None:
    """Under ``umask 277`` numba's cache folders and files would be read-only to their
    owner (hostile round fourteen: the first command failed, and every later one with any
    umask): the kernels compile in memory and nothing is written to the cache folder."""
    import subprocess
    import sys

    cache = tmp_path / "cache"
    cache.mkdir()
    (tmp_path / "kmod.py").write_text(
        "from sensorgap.jit import njit\n\n@njit(nogil=True)\ndef k(x):\n    return x + 1.0\n"
    )
    code = (
        "import kmod, sensorgap.jit as j; print(j.current_umask(), j.cache_usable(), kmod.k(1.0))"
    )
    env = {
        **os.environ,
        "NUMBA_CACHE_DIR": str(cache),
        "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path]),
    }
    for umask, usable in ((0o277, "False"), (0o022, "True")):
        done = subprocess.run(
            [sys.executable, "-c", code], env=env, umask=umask, capture_output=True, text=True
        )
        assert done.returncode == 0, done.stderr
        assert done.stdout.split() == [str(umask), usable, "2.0"], done.stdout
        cached = sorted(p.name for p in cache.rglob("*") if p.is_file())
        assert bool(cached) == (usable == "True"), cached  # nothing cached under 277


def test_out_of_memory_is_one_line(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A command that runs out of memory (``ulimit -v`` below its peak: numpy's
    ``MemoryError``, or the loader failing to map a compiled module) says so in one line,
    exit 2, and leaves no new folder (was: "internal error ... this is a bug")."""
    import sensorgap.analysis.nearfield as nf

    out = tmp_path / "nf"
    for exc in (
        MemoryError("Unable to allocate 84 MiB for an array with shape (2000, 5500)"),
        ImportError("x.so: failed to map segment from shared object"),
    ):

        def fail(*args: object, exc: BaseException = exc, **kw: object) -> object:
            raise exc

        monkeypatch.setattr(nf, "write_nearfield", fail)
        argv = ["nearfield", "--vehicle", "system_a", "--out", str(out)]
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("sensorgap: error: out of memory ("), err
        assert not out.exists()


def test_figures_ignore_the_users_matplotlib_configuration(tmp_path: Path) -> None:
    """A ``matplotlibrc`` in the working directory (LaTeX text without LaTeX, a font that
    does not exist, 2000 dpi, an unknown backend) and ``MPLBACKEND=nosuchbackend``: the
    command works, prints nothing on stderr, and its figure is byte-identical to the one
    made without them (``runtime.pristine_matplotlib``; hostile round fourteen: internal
    errors, and an rc ``savefig.dpi`` changed every figure)."""
    import subprocess
    import sys

    # a small coverage map: its figure has a colour bar, text, lines and an image
    cov = ["coverage", "--vehicle", "system_a", "--environment", "clear", "--target", "car"]
    cov += ["--resolution", "1", "--extent", "-10,30,-10,10", "--out"]
    ref = tmp_path / "ref"
    assert main([*cov, str(ref)]) == 0
    work = tmp_path / "work"
    work.mkdir()
    (work / "matplotlibrc").write_text(
        "figure.dpi: 2000\nsavefig.dpi: 2000\nfont.family: NoSuchFont\ntext.usetex: True\n"
        "backend: nosuchbackend\naxes.formatter.use_locale: True\n"
    )
    env = {**os.environ, "MPLBACKEND": "nosuchbackend", "PYTHONPATH": os.pathsep.join(sys.path)}
    done = subprocess.run(
        [sys.executable, "-m", "sensorgap", *cov, "cov"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert (work / "cov" / "coverage.png").read_bytes() == (ref / "coverage.png").read_bytes()


@pytest.mark.parametrize(
    ("body", "said"),
    [
        ("def register():\n    raise RuntimeError('boom')\n", "RuntimeError: boom"),
        ("import sys\ndef register():\n    sys.exit(0)\n", "SystemExit: 0"),
        ("def register(:\n", "SyntaxError"),
    ],
)
def test_a_broken_plugin_is_one_line_before_any_work(
    body: str,
    said: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A ``sensorgap.plugins`` entry point that raises, calls ``sys.exit(0)`` or does not
    parse: one line naming it, exit 2, and no --out folder (hostile round fourteen: the
    search made its folder, store and inputs first, then loaded the plugins at its first
    family kind; ``sys.exit(0)`` ended it with exit 0 and nothing written)."""
    from importlib.metadata import EntryPoint

    import sensorgap.plugins as plugins

    module = f"brokenplug_{abs(hash(body))}"  # a name of its own: not cached by an earlier case
    (tmp_path / f"{module}.py").write_text(body)
    monkeypatch.syspath_prepend(str(tmp_path))
    ep = EntryPoint("x", f"{module}:register", plugins.GROUP)
    monkeypatch.setattr(
        plugins, "entry_points", lambda group: [ep] if group == plugins.GROUP else []
    )
    monkeypatch.setattr(plugins, "_loaded", False)
    out = tmp_path / "s"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    assert main([*argv, "--environments", "clear", "--budget", "20", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"sensorgap: error: plugin x: {module}:register")
    assert said in err[0] and not out.exists()


@pytest.mark.parametrize(
    ("value", "said"),
    [
        ("nosuchmodule_xyz:Thermal", "failed to load: ModuleNotFoundError"),
        ("sensorgap.models.radar:RADAR_NOPE", "failed to load: AttributeError"),
        ("math:pi", "must name a SensorModel subclass, got float"),
        ("clashplug:Radar2", "sensor type 'radar' is already registered"),
    ],
)
def test_a_broken_sensor_plugin_is_one_line(
    value: str,
    said: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A ``sensorgap.sensors`` entry point that cannot be imported, names no
    ``SensorModel`` subclass or takes a built-in type's name, loaded for a vehicle with a
    sensor type no built-in model has: one line naming the plugin, exit 2 (were internal
    errors)."""
    from importlib.metadata import EntryPoint

    import sensorgap.models.registry as reg
    from sensorgap.config.presets import templates_dir

    (tmp_path / "clashplug.py").write_text(
        "from sensorgap.models.radar import Radar\n\n"
        "class Radar2(Radar):\n    type_name = 'radar'\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    ep = EntryPoint("thermal", value, reg.ENTRY_POINT_GROUP)
    monkeypatch.setattr(reg, "entry_points", lambda group: [ep])
    monkeypatch.setattr(reg, "_entry_points_loaded", False)
    text = (templates_dir() / "vehicles" / "system_b.toml").read_text()
    assert 'type = "radar"' in text
    vehicle = tmp_path / "v.toml"
    vehicle.write_text(text.replace('type = "radar"', 'type = "thermal"'))
    out = tmp_path / "nf"
    assert main(["nearfield", "--vehicle", str(vehicle), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("sensorgap: error: sensor plugin thermal: ")
    assert said in err[0] and not out.exists()


def test_a_new_search_that_fails_before_storing_leaves_nothing(tmp_path: Path) -> None:
    """A search into a new --out whose store was made but which failed before storing a
    result (here the file-size limit stops the copy of its 46 kB vehicle file into
    ``inputs/``; a full disk at ``run.json`` in hostile round fourteen) leaves no folder,
    store or inputs: before, ``inputs/``, ``run.json`` and an empty ``search.sqlite``
    stayed, and the next search there was told to use --resume."""
    import resource
    import subprocess
    import sys

    from sensorgap.config.presets import templates_dir

    text = (templates_dir() / "vehicles" / "system_b.toml").read_text()
    pad = "".join(
        f"# padding line {i:05d} ..................................\n" for i in range(600)
    )
    vehicle = tmp_path / "v.toml"
    vehicle.write_text(text + pad)
    assert 40_000 < vehicle.stat().st_size < 60_000  # the store (20,480 bytes) fits, it not

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (40_000, 40_000))

    out = tmp_path / "a" / "b" / "run"
    argv = ["search", "--vehicle", str(vehicle), "--families", "slow_ahead_curve"]
    argv += ["--environments", "clear", "--budget", "20", "--out", str(out)]
    done = subprocess.run(
        [sys.executable, "-m", "sensorgap", *argv],
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
        preexec_fn=limit,
        capture_output=True,
        text=True,
        timeout=300,
    )
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert "inputs/vehicle/v.toml: cannot write or read: File too large" in lines[0]
    assert not (tmp_path / "a").exists()


def test_a_near_field_and_a_map_added_to_a_run_keep_it_verifying(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``nearfield --out RUN/nearfield`` and ``coverage --out RUN/coverage/<name>`` add the
    report's inputs to a search run and certify RUN again (``filesio.certified_parent``):
    ``verify RUN`` passes at once (before, it named their files as unlisted until the next
    report), and the report then reads them. Another folder inside RUN is refused."""
    run = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    assert main([*argv, "--environments", "clear", "--budget", "20", "--out", str(run)]) == 0
    nf = ["nearfield", "--vehicle", "system_b", "--resolution", "0.5"]
    assert main([*nf, "--out", str(run / "nearfield")]) == 0
    assert main(["verify", str(run)]) == 0
    cov = ["coverage", "--vehicle", "system_b", "--environment", "clear", "--target", "car"]
    assert main([*cov, "--resolution", "2", "--out", str(run / "coverage" / "car_clear")]) == 0
    assert main(["verify", str(run)]) == 0
    listed = json.loads((run / "manifest.json").read_text())["files"]
    assert "nearfield/nearfield.json" in listed and "coverage/car_clear/coverage.npz" in listed
    capsys.readouterr()
    assert main([*nf, "--out", str(run / "elsewhere")]) == 2
    assert "lies inside" in capsys.readouterr().err
    assert main(["report", "--run", str(run)]) == 0 and main(["verify", str(run)]) == 0
    md = (run / "report.md").read_text()
    assert "Near-field blind spots" in md and "not run" not in md.split("Near-field")[1][:300]


def test_a_restore_folder_is_usable_whatever_the_umask(tmp_path: Path) -> None:
    """The folder keeping a run's files while a command rewrites them is 0700 whatever
    the umask: under ``umask 777`` it was made 000, so (as its owner, not root) its links
    could not be made nor the folder removed, and it stayed in the run (hostile round
    fourteen, F16)."""
    from sensorgap.atomic import _back_up, _drop

    (tmp_path / "a.txt").write_text("a")
    old = os.umask(0o777)
    try:
        keep, saved = _back_up(tmp_path, {"a.txt"}, ())
    finally:
        os.umask(old)
    assert keep is not None and stat.S_IMODE(keep.stat().st_mode) == 0o700
    assert saved["a.txt"].read_text() == "a"
    _drop(keep)
    assert not keep.exists()


THREAD_LINE = (
    "sensorgap: error: cannot start a thread ({}): the process limit (ulimit -u, a "
    "container's pids limit) is reached; raise it or use fewer --workers"
)


def test_a_thread_that_cannot_start_is_one_line_and_a_search_leaves_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Under a process limit (``ulimit -u`` for a non-root user) a thread or process that
    cannot start was an internal error (exit 1; a search left run.json, inputs/ and an
    empty store, which refused the next search). Now one line, exit 2, and a search that
    stored nothing leaves nothing (hostile round fourteen, F15)."""
    import sensorgap.search.run as search_run

    def no_thread(*_: object, **__: object) -> None:
        raise RuntimeError("can't start new thread")

    monkeypatch.setattr(search_run, "search_loop", no_thread)
    out = tmp_path / "s"
    args = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    args += ["--environments", "clear", "--budget", "10", "--strategy", "lhs"]
    assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(THREAD_LINE.format("can't start new thread")) and err.count("\n") == 1
    assert not out.exists()
    # a fork refused by the limit (EAGAIN, no file named) says the same, not "cannot write"
    import sensorgap.coverage.grid as grid

    def no_fork(*_: object, **__: object) -> None:
        raise BlockingIOError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(grid, "ThreadPoolExecutor", no_fork)
    cov = ["coverage", "--vehicle", "system_b", "--environment", "clear", "--target", "car"]
    cov += ["--resolution", "0.5", "--extent", "-20,60,-20,20", "--workers", "2"]
    assert main([*cov, "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(THREAD_LINE.format("[Errno 11] Resource temporarily unavailable"))
    assert err.count("\n") == 1 and not (tmp_path / "c").exists()


def test_the_command_line_keeps_openblas_to_one_thread() -> None:
    """OpenBLAS started a thread per core at numpy's import and, under a process limit,
    printed a line per thread from C and raised SIGINT ("interrupted", exit 130). The
    command line sets ``OPENBLAS_NUM_THREADS=1`` before numpy is imported (sensorgap's
    linear algebra is 3x3), unless the user set it."""
    import subprocess
    import sys

    code = (
        "import sys, os; import sensorgap.cli; "
        "print(os.environ.get('OPENBLAS_NUM_THREADS'), 'numpy' in sys.modules)"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.split() == ["1", "True"]
    env["OPENBLAS_NUM_THREADS"] = "3"  # the user's choice is kept
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.split() == ["3", "True"]
    probe = "import sensorgap, os; print(os.environ.get('OPENBLAS_NUM_THREADS'))"
    env.pop("OPENBLAS_NUM_THREADS")
    done = subprocess.run(
        [sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.split() == ["None"]  # a library user's process is left alone


# -- hostile round eighteen: stop signals at the start and in a search's last writes -----


@pytest.mark.parametrize(("name", "code"), [("SIGINT", 130), ("SIGTERM", 143), ("SIGHUP", 129)])
def test_a_stop_signal_while_the_command_line_is_imported_is_one_line(name: str, code: int) -> None:
    """Round eighteen, F8: Ctrl-C while the console script imported ``sensorgap.cli``
    printed a KeyboardInterrupt traceback; SIGTERM there ended the process with 143 and no
    line. The signal arrives here exactly while that import runs (an import hook sends
    it): one line, exit 128 + signal number."""
    import subprocess
    import sys

    script = (
        "import builtins, os, signal, sys, time\n"
        "import sensorgap.entry as entry\n"
        "real = builtins.__import__\n"
        "def hook(name, *a, **k):\n"
        "    if name == 'sensorgap.cli':\n"
        f"        os.kill(os.getpid(), signal.{name}); time.sleep(2)\n"
        "    return real(name, *a, **k)\n"
        "builtins.__import__ = hook\n"
        "sys.argv = ['sensorgap', '--version']\n"
        "sys.exit(entry.main())\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=False
    )
    assert proc.returncode == code, proc.stderr
    assert proc.stderr == "sensorgap: interrupted\n", proc.stderr


def test_a_program_importing_the_package_keeps_its_signal_handlers() -> None:
    """The early stop handlers (``earlystop``) are the command's only: ``import
    sensorgap`` in a program of its own leaves SIGINT, SIGTERM and SIGHUP as they were;
    ``python -m sensorgap`` (the command) gets them from the package's first line."""
    import subprocess
    import sys

    show = "import signal; print([signal.getsignal(s) for s in (2, 15, 1)])"
    lib = subprocess.run(
        [sys.executable, "-c", f"import sensorgap; {show}"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    assert "stop_before_work" not in lib.stdout, lib.stdout
    assert "default_int_handler" in lib.stdout and lib.stdout.count("SIG_DFL") == 2

    from sensorgap import earlystop

    assert not earlystop.is_the_command_line()  # pytest's process


@pytest.mark.parametrize(
    ("argv", "module"),
    [
        (["python", "-m", "sensorgap", "run"], "sensorgap"),
        (["python", "-u", "-m", "sensorgap"], "sensorgap"),
        (["python", "-I", "-X", "dev", "-m", "sensorgap"], "sensorgap"),
        (["python", "-Xdev", "-W", "error", "-msensorgap"], "sensorgap"),
        (["python", "-OO", "-um", "sensorgap"], "sensorgap"),
        (["python", "--check-hash-based-pycs", "always", "-m", "sensorgap"], "sensorgap"),
        (["python", "-c", "import sensorgap", "-m", "sensorgap"], None),
        (["python", "prog.py", "-m", "sensorgap"], None),
        (["python", "-m", "pytest", "-m", "sensorgap"], "pytest"),
        (["python", "-"], None),
        (["python", "-m"], None),
    ],
)
def test_the_command_is_recognised_after_interpreter_options(
    monkeypatch: pytest.MonkeyPatch, argv: list[str], module: str | None
) -> None:
    """Hostile round twenty, F1: ``python -u -m sensorgap`` (any interpreter option before
    ``-m``) was not taken for the command, so a stop signal while the package was imported
    gave a traceback (SIGINT) or no line (SIGTERM). The module ``-m`` runs is read after
    the interpreter's options, their values skipped."""
    from sensorgap import earlystop

    assert earlystop.module_run(argv) == module
    monkeypatch.setattr(sys, "orig_argv", argv)
    assert earlystop.is_the_command_line() == (module == "sensorgap")


@pytest.mark.parametrize("when", ["starting", "working"])
def test_the_jobs_second_process_ends_quietly_on_ctrl_c(
    capfd: pytest.CaptureFixture[str], when: str
) -> None:
    """Hostile round twenty, F4: Ctrl-C in a terminal reaches the whole process group, and
    the job's second process (``jobs._run_job``) printed "Process SpawnProcess-1:" and a
    KeyboardInterrupt traceback before the command's line. It now ends as on SIGTERM,
    silently: while it starts (SIGINT blocked from its spawn until its initializer) and
    while it works."""
    import multiprocessing
    import signal
    import time
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    from sensorgap import jobs

    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=ctx, initializer=jobs._quiet_on_ctrl_c) as pool:
        if when == "working":
            assert pool.submit(abs, -1).result(timeout=60) == 1  # started, initialised
        job = jobs._spawn_blocking_ctrl_c(pool, time.sleep, 60)
        (pid,) = list(pool._processes)
        os.kill(pid, signal.SIGINT)
        with pytest.raises(BrokenProcessPool):
            job.result(timeout=60)
    err = capfd.readouterr().err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err


@pytest.mark.parametrize("sig", ["SIGINT", "SIGHUP"])
def test_a_dask_search_stopped_through_its_process_group_says_one_line(
    tmp_path: Path, sig: str
) -> None:
    """Hostile round twenty, F3: Ctrl-C (or a closed terminal's SIGHUP) reaches the whole
    process group, the local Dask cluster's workers and multiprocessing's resource
    tracker too: they died, were restarted, and 8-80 lines of warnings and tracebacks
    came before the command's line. They are now spared the group's signals
    (``runtime.children_spared_stop_signals``, ``search.daskworker``), the command closes
    them, and Dask's log of the abandoned work is not printed: one line, and no worker
    left behind."""
    import signal
    import subprocess
    import time

    out = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "cut_in_left"]
    argv += ["--environments", "clear", "--budget", "3000", "--executor", "dask"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "sensorgap", *argv, "--workers", "2", "--out", str(out)],
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 120
        while not (out / "search.sqlite").exists():  # the cluster is up, batches run
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(0.5)
        os.killpg(proc.pid, getattr(signal, sig))
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 128 + getattr(signal, sig), err
    assert err == "sensorgap: interrupted\n", err
    with pytest.raises(ProcessLookupError):  # the group is empty: no worker left
        for _ in range(100):
            os.killpg(proc.pid, 0)
            time.sleep(0.1)


def test_a_dask_worker_leaves_the_group_and_drops_its_pending_stop_signals() -> None:
    """``daskworker.dask_setup`` in a process started with the stop signals blocked and a
    Ctrl-C pending (the group's, sent while it started): the process is then a group of
    its own, the signal dropped (it was the command's), the signals unblocked."""
    import subprocess

    script = (
        "import os, signal\n"
        "from sensorgap.runtime import children_spared_stop_signals\n"
        "from sensorgap.search.daskworker import dask_setup\n"
        "with children_spared_stop_signals():\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    assert signal.SIGINT in signal.sigpending()\n"
        "    dask_setup(None)\n"
        "    assert os.getpgid(0) == os.getpid()\n"
        "    assert not signal.sigpending()\n"
        "    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])\n"
        "print('ok')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script],
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0 and done.stdout == "ok\n", done.stderr


def test_a_stop_signal_inside_a_weakref_callback_or_finalizer_is_sent_again() -> None:
    """Hostile round twenty-one, F2: a Ctrl-C that arrived while the interpreter ran a
    ``WeakKeyDictionary`` callback was raised there, printed as "Exception ignored in"
    with a traceback, and lost: the command ran to its end, exit 0. The frames where an
    exception is swallowed (weak-reference callbacks, ``__del__``, numba's compiler) are
    recognised, and the signal is sent again 0.1 s later instead."""
    import weakref

    from sensorgap import cli

    seen: dict[str, bool] = {}  # where the handler would run -> recognised there

    def trace(frame: Any, event: str, arg: Any) -> None:
        if event == "call" and frame.f_code.co_name == "remove":
            seen["remove"] = cli._in_compiler_callback(frame)

    class Key:
        def __del__(self) -> None:
            seen["__del__"] = cli._in_compiler_callback(sys._getframe())

    table: weakref.WeakKeyDictionary[Key, int] = weakref.WeakKeyDictionary()
    key = Key()
    table[key] = 1
    sys.setprofile(trace)
    try:
        del key  # its finalizer, then the dictionary's callback
    finally:
        sys.setprofile(None)
    assert seen == {"__del__": True, "remove": True}, seen
    assert not table
    assert not cli._in_compiler_callback(sys._getframe())


def test_a_stop_in_the_last_writes_of_a_search_is_delivered_after_them() -> None:
    """Round eighteen, F7: Ctrl-C after a resumed search rewrote its ranking files and
    before its manifest left a folder failing verify. ``DeferredStop`` holds the signal
    from ``begin()`` to the end of the block, then delivers it to the handler in place
    before: nothing is raised inside, KeyboardInterrupt right after; the handlers are
    put back."""
    import signal

    from sensorgap.runtime import DeferredStop

    before = signal.getsignal(signal.SIGINT)
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with DeferredStop() as stop:
            stop.begin()
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # the handler would have run by now
                reached.append(1)
            assert signal.getsignal(signal.SIGINT) is not before
        for _ in range(1000):  # delivered at the end of the block
            pass
    assert len(reached) == 1000
    assert signal.getsignal(signal.SIGINT) is before


@pytest.mark.parametrize("record", ["{}", '{"ranking.json": null}', None])
def test_a_partial_record_of_the_ranking_files_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], record: str | None
) -> None:
    """Round nineteen, F2: the store's record of the ranking files was checked only for
    the names it held: emptied (or a null digest), it let an edited ranking.json through.
    A search records all four, so a partial record is refused, naming the store; so is a
    store without the record (round twenty, F2: it passed as an older search's)."""
    from sensorgap.search.run import run_search

    run = tmp_path / "run"
    run_search("system_b", ["stopped_rural_curve"], ["snow"], 30, 1, 2, run, strategy="lhs")
    con = sqlite3.connect(run / "search.sqlite")
    if record is None:
        con.execute("DELETE FROM meta WHERE key = 'ranking_files'")
    else:
        con.execute("UPDATE meta SET value = ? WHERE key = 'ranking_files'", (record,))
    con.commit()
    con.close()
    capsys.readouterr()
    code = main(["report", "--run", str(run)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    if record is None:
        assert "search.sqlite: meta.ranking_files: missing: a search records it" in err[0]
    else:
        assert "search.sqlite: meta.ranking_files: the record of the ranking files lacks" in err[0]


def test_a_second_stop_signal_does_not_stop_the_put_back() -> None:
    """Round nineteen, F6: ``timeout`` (and a terminal) signal the process group too, so a
    job got SIGTERM twice; the second, raised inside the put-back of the folder, left its
    restore folder and a folder failing verify. Once one stop signal was taken, the next
    ones are ignored (the command is stopping already)."""
    import signal

    from sensorgap import cli

    cli._RECEIVED.clear()
    try:
        with pytest.raises(KeyboardInterrupt):
            cli._terminate(signal.SIGTERM, None)
        assert cli._terminate(signal.SIGTERM, None) is None
        assert cli._terminate(signal.SIGINT, None) is None
    finally:
        cli._RECEIVED.clear()


def test_run_files_the_report_and_compare_read_are_checked(tmp_path: Path) -> None:
    """Hostile round 24: farfield/table_iv.csv with a column missing, a short row or a
    path as environment; a far field's levels_m as a list or NaN; an anchor's
    probability NaN, -7 or text: each one line naming the file (were internal errors, a
    figure embedded from outside the run, "nan" printed)."""
    import json as _json
    import re

    from sensorgap.report.anchors import anchors_section
    from sensorgap.report.build import read_table_iv
    from sensorgap.report.compare import _farfield_levels

    tab = tmp_path / "table_iv.csv"
    good = "environment,level,metres\nclear,pd=1.0,78.2\n"
    tab.write_text(good)
    assert read_table_iv(tab)[0]["metres"] == "78.2"
    for text, said in (
        ("a,b\n1,2\n", "row 2: no environment"),
        ("environment,level,metres\nclear,pd=1.0\n", "row 2: no metres"),
        ("environment,level,metres\n/etc,pd=1.0,1\n", "row 2.environment: a name, not a path"),
        ("environment,level,metres\n..,pd=1.0,1\n", "row 2.environment: a name, not a path"),
        ("environment,level,metres\nclear,pd=1.0,nan\n", "row 2.metres: expected a length"),
    ):
        tab.write_text(text)
        with pytest.raises(InputError, match=re.escape(said)):
            read_table_iv(tab)
    ff = tmp_path / "ff"
    ff.mkdir()
    (ff / "summary.json").write_text(_json.dumps({"levels_m": {"pd=1.0": 12.5}}))
    assert _farfield_levels(ff) == {"pd=1.0": 12.5}
    for body, said in (
        ("[1]", "levels_m: expected a JSON object"),
        ('{"levels_m": [1]}', "levels_m: expected a JSON object"),
        ('{"levels_m": {"pd=1.0": NaN}}', "levels_m.pd=1.0: expected a length >= 0"),
    ):
        (ff / "summary.json").write_text(body)
        with pytest.raises(InputError, match=re.escape(said)):
            _farfield_levels(ff)
    (tmp_path / "anchors").mkdir()
    row = {
        "vut_kmh": 20.0,
        "pedestrian_kmh": 5.0,
        "class": "not critical",
        "collision_probability": 0.25,
        "impact_speed_kmh": 10.0,
        "t_confirm_median_s": 1.0,
        "t_safe_s": 2.0,
        "command": "sensorgap evaluate ...",
    }
    for value, ok in ((0.25, True), (float("nan"), False), (-7, False), ("1e99999", False)):
        (tmp_path / "anchors" / "anchors.json").write_text(
            _json.dumps({"anchors": [{**row, "collision_probability": value}]})
        )
        if ok:
            anchors_section(tmp_path)
        else:
            with pytest.raises(InputError, match="collision_probability: expected a number"):
                anchors_section(tmp_path)


def test_esmini_log_read_a_line_at_a_time_with_clear_lines(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Hostile round 29: the CSV log was kept whole as text (~110 bytes of memory per byte
    of log, 2.5 GB for 20 MB); it is read a line at a time now, a line longer than
    MAX_ESMINI_LOG_LINE is a bad log, a field that is no number says so (it was Python's
    own text), and a header without entity columns too ("max() arg is an empty
    sequence")."""
    from sensorgap.export import simulate

    good = "0, 0.00, Ego, 0, 10.0, 1.0, 2.0, 0.0, 0.1,"
    sim = simulate.parse_esmini_csv(_esmini_log(tmp_path / "ok.csv", [good] * 3))
    assert sim.states["Ego"][0].tolist() == [0.0, 0.0, 0.0]
    monkeypatch.setattr(simulate, "MAX_ESMINI_LOG_LINE", 300)  # the header has ~200
    long = good + " " * 300
    with pytest.raises(ValueError, match=r"long\.csv: line 3: longer than 300 characters$"):
        simulate.parse_esmini_csv(_esmini_log(tmp_path / "long.csv", [good, long]))
    with pytest.raises(ValueError, match=r"line 2: #1 World_Position_X \S* is 'x1'; not a number"):
        simulate.parse_esmini_csv(_esmini_log(tmp_path / "nan.csv", [good.replace("1.0", "x1")]))
    # float() reads these too (remark of session 26): no CSV reader takes them for numbers
    for i, odd in enumerate(["1_0", "\u0661.0", " 1_0 "]):
        log = _esmini_log(tmp_path / f"odd{i}.csv", [good.replace("1.0", odd)])
        with pytest.raises(ValueError, match=r"World_Position_X \S* is '.*'; not a number"):
            simulate.parse_esmini_csv(log)
    (tmp_path / "none.csv").write_text("Index, TimeStamp\n0, 0.0\n")
    with pytest.raises(ValueError, match=r"no entity columns \(#1 \.\.\.\)"):
        simulate.parse_esmini_csv(tmp_path / "none.csv")


def test_library_round_29_refusals(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Hostile round 29, the Python API: ``find_scenarios`` into a certified run (the CLI
    refuses it; the API wrote there and the run no longer verified), its internal
    ``stop`` option (an AttributeError after the whole search), a NUL in ``out`` (a raw
    ValueError), a long double beyond a float (numpy's overflow warning printed first) and
    ``evaluate_candidate``'s arguments (a NaN sun left a half-written trace.csv, azimuth
    400 was accepted, a str ``out`` was an AttributeError): each one InputError naming the
    parameter, nothing written."""
    import math
    import warnings

    import numpy as np

    import sensorgap
    from sensorgap.search.whatif import evaluate_candidate

    monkeypatch.chdir(tmp_path)
    run = tmp_path / "run"
    run.mkdir()
    (run / "a.txt").write_text("x")
    write_manifest(run)
    kw: dict[str, Any] = {"families": ["cut_out_reveal"], "environments": ["fog_50"]}
    with pytest.raises(InputError, match=r"^out: .*run/sub lies inside .*give another out "):
        sensorgap.find_scenarios("system_b", run / "sub", budget=10, **kw)
    with pytest.raises(InputError, match=r"^stop: unknown option"):
        sensorgap.find_scenarios("system_b", tmp_path / "o", budget=10, stop=5, **kw)
    with pytest.raises(InputError, match=r"^out: must not hold a NUL character"):
        sensorgap.find_scenarios("system_b", "o\x00x", budget=10, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        big = np.array([[np.longdouble("1e4000"), 0.0, 0.75]], dtype=np.longdouble)
        with pytest.raises(InputError, match=r"^points: coordinates must be finite"):
            sensorgap.evaluate_points("system_b", big)
    args = ("system_b", "slow_ahead_curve", "clear")
    for sun, out, params in (
        ((math.nan, 10.0), "ev", []),
        ((400.0, 10.0), "ev", []),
        ((60.0,), "ev", []),
        (None, 3, []),
        (None, "ev", [1, 2]),
    ):
        with pytest.raises(InputError, match=r"^(sun|out|param): "):
            evaluate_candidate(*args, sun, params, out)  # type: ignore[arg-type]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert verify_manifest(run) == []


def test_an_esmini_log_after_the_planned_end_is_a_bad_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round 29, F4: a log whose steps all lie after the scenario's planned end
    left nothing to compare; the deviation was inf and the command an internal error
    ("refusing to write a non-finite number: inf"). It is a bad log now."""
    run, cat = tmp_path / "run", tmp_path / "cat"
    argv = ["search", "--vehicle", "system_b", "--families", "cut_out_reveal"]
    argv += ["--environments", "fog_50", "--budget", "60", "--top", "1", "--out", str(run)]
    assert main(argv) == 0
    assert main(["export", "--run", str(run), "--out", str(cat), "--top", "1"]) == 0
    fake = tmp_path / "esmini"
    head = "Index, TimeStamp" + "".join(
        f", #{k} Entity_Name, #{k} Entity_ID, #{k} Current_Speed, #{k} World_Position_X, "
        f"#{k} World_Position_Y, #{k} World_Heading_Angle"
        for k in (1, 2)
    )
    rows = "\\n".join(
        f"{i}, 10{i}, Ego, 0, 10, {i}, 0, 0, Target, 1, 5, 50, 0, 0" for i in range(3)
    )
    fake.write_text(
        "#!/bin/sh\nwhile [ $# -gt 0 ]; do case $1 in --csv_logger) log=$2; shift;; "
        "--logfile_path) tl=$2; shift;; esac; shift; done\n"
        f'printf "{head}\\n{rows}\\n" > "$log"\necho log > "$tl"\nexit 0\n'
    )
    fake.chmod(0o755)
    shutil.copytree(cat, tmp_path / "cat2")
    capsys.readouterr()
    assert main(["simulate", "--catalog", str(cat), "--esmini", str(fake)]) == 0
    out = capsys.readouterr().out
    assert "bad log: " in out and "its first step (t = 100 s) is after the planned end" in out
    text = (cat / "simulation.csv").read_text()
    assert "bad log" in text and "inf" not in text
    # round 32: the message named esmini's temporary folder (a new random name each run)
    assert "sensorgap-esmini-" not in text and "log.csv: its first step" in text
    assert main(["simulate", "--catalog", str(tmp_path / "cat2"), "--esmini", str(fake)]) == 0
    assert (tmp_path / "cat2" / "simulation.csv").read_text() == text
    # round 33: the reaction runs' messages named their temporary folder too (a log with a
    # position that is not a number: every run's log is bad)
    bad = tmp_path / "esmini_bad"
    bad.write_text(
        fake.read_text().replace(rows, "0, 0.0, Ego, 0, 10, abc, 0, 0, Target, 1, 5, 50, 0, 0")
    )
    bad.chmod(0o755)
    shutil.copytree(tmp_path / "cat2", tmp_path / "cat3")
    argv = ["simulate", "--catalog", str(tmp_path / "cat3"), "--esmini", str(bad)]
    assert main([*argv, "--ego-reaction"]) == 0
    text = (tmp_path / "cat3" / "simulation.csv").read_text()
    assert "median: log.csv: line 2: " in text and "sensorgap-" not in text


def test_esmini_log_columns_are_found_by_entity_and_name(tmp_path: Path) -> None:
    """The columns are looked up by entity number and name, with or without a unit after
    the name (hostile round 30: a scan of the whole header per column took 282 s for 9,000
    entities); the last of many entities is read from its own columns."""
    from sensorgap.export.simulate import parse_esmini_csv

    n = 300
    cols = ["Index [-]", "TimeStamp[sec]"]
    row = ["0", "0.5"]
    for k in range(1, n + 1):
        cols += [f"#{k} Entity_Name [-]", f"#{k} Current_Speed[m/s]", f"#{k} World_Position_X [m]"]
        cols += [f"#{k} World_Position_Y", f"#{k} World_Heading_Angle [rad]"]
        row += [f"E{k}", f"{k}", f"{2 * k}", f"{3 * k}", "0.1"]
    log = tmp_path / "wide.csv"
    log.write_text(", ".join(cols) + "\n" + ", ".join(row) + "\n")
    sim = parse_esmini_csv(log)
    t, x, y, h, v = sim.states[f"E{n}"]
    assert len(sim.states) == n and t[0] == 0.5 and x[0] == 2 * n and y[0] == 3 * n
    assert v[0] == n and h[0] == 0.1


def test_library_refusals_name_the_parameter_not_the_option(tmp_path: Path) -> None:
    """Hostile round 30, F4: a check the API shares with the command line named its
    option (``--out: NF holds the certified outputs of another command``); the facade
    names the parameter (``out``)."""
    import sensorgap

    nf = tmp_path / "NF"
    nf.mkdir()
    (nf / "nearfield.json").write_text("{}")
    write_manifest(nf)
    kw: dict[str, Any] = {"families": ["cut_out_reveal"], "environments": ["fog_50"]}
    with pytest.raises(InputError) as info:
        sensorgap.find_scenarios("system_b", nf, budget=10, **kw)
    assert info.value.source == "out" and str(info.value).startswith("out: ")
    assert "certified outputs of another command" in str(info.value)
    assert "--" not in str(info.value)  # round 31: "give another --out" in its text
    run = tmp_path / "run"  # a search there already: "add resume=True", not "--resume"
    sensorgap.find_scenarios("system_b", run, budget=10, progress=False, **kw)
    with pytest.raises(InputError, match=r"add resume=True to continue it, or use another out"):
        sensorgap.find_scenarios("system_b", run, budget=10, progress=False, **kw)


def test_evaluate_candidate_checks_its_out_as_the_command_does(tmp_path: Path) -> None:
    """Hostile round 30, F2: the library's ``evaluate_candidate`` wrote into a certified
    run (verify failed), raised raw OS errors for a file as ``out``, and left trace.csv
    alone when evaluation.json could not be written. Now as ``evaluate --out``."""
    from sensorgap.search.whatif import evaluate_candidate

    run = tmp_path / "run"
    run.mkdir()
    (run / "a.txt").write_text("x")
    write_manifest(run)
    (tmp_path / "afile").write_text("x")
    (tmp_path / "e" / "evaluation.json").mkdir(parents=True)
    params = ["ego_s0_m=20", "ego_speed_m_s=25", "lead_gap_m=30", "target_speed_m_s=10"]
    params += ["cut_out_s=2", "lc_duration_s=2", "reveal_s=3"]
    args = ("system_b", "cut_out_reveal", "clear", None, params)
    for out, said in (
        (run / "ev", r"^out: .*ev lies inside .*a certified folder"),
        (tmp_path / "afile", r"^out: .*afile is a file, not a folder$"),
        (tmp_path / "afile" / "sub", r"^out: .*afile is a file, not a folder$"),
        (tmp_path / "e", r"e/evaluation\.json: is a folder"),
    ):
        with pytest.raises(InputError, match=said):
            evaluate_candidate(*args, out)
    assert verify_manifest(run) == [] and not (run / "ev").exists()
    assert [p.name for p in (tmp_path / "e").iterdir()] == ["evaluation.json"]


def test_an_export_builds_the_occluders_of_the_runs_recorded_classes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Hostile round 30, F6: a run searched with templates whose car is 12 m long was
    exported (without them) with the shipped 4.5 m lead car: exit 0, valid files, verify
    OK, and not the scenario that was ranked. The occluder's class now comes from the run's
    recorded targets, also when the templates at export time lack the class."""
    import re
    import shutil

    from sensorgap.config.presets import templates_dir

    big = tmp_path / "big"
    shutil.copytree(templates_dir(), big)
    targets = big / "targets.toml"
    text = targets.read_text(encoding="utf-8")
    i = text.index("[targets.car]")
    j = text.index("[targets.", i + 1)
    car = text[i:j].replace("length_m = 4.5", "length_m = 12.0")
    assert car != text[i:j]
    targets.write_text(text[:i] + car + text[j:], encoding="utf-8")
    monkeypatch.setenv("SENSORGAP_TEMPLATES", str(big))
    run = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "cut_out_reveal"]
    argv += ["--environments", "fog_50", "--budget", "50", "--top", "1", "--out", str(run)]
    assert main(argv) == 0
    nocar = tmp_path / "nocar"
    shutil.copytree(templates_dir(), nocar)
    t = (nocar / "targets.toml").read_text(encoding="utf-8")
    (nocar / "targets.toml").write_text(t.replace("[targets.car", "[targets.carx"))
    for env in (None, str(nocar)):  # the shipped templates, then ones without a car
        if env is None:
            monkeypatch.delenv("SENSORGAP_TEMPLATES")
        else:
            monkeypatch.setenv("SENSORGAP_TEMPLATES", env)
        cat = tmp_path / f"cat{env is None}"
        assert main(["export", "--run", str(run), "--out", str(cat), "--top", "1"]) == 0
        xosc = next((cat / "scenarios").glob("*.xosc")).read_text(encoding="utf-8")
        lengths = sorted(float(v) for v in re.findall(r'<Dimensions[^>]* length="([0-9.]+)"', xosc))
        assert 12.0 in lengths and 4.5 not in lengths, lengths


def test_the_librarys_report_keeps_a_certified_run_verifying(tmp_path: Path) -> None:
    """Hostile round 30, F5 (the report half): ``sensorgap.write_report`` left report.html,
    report.md and report/ unlisted in a certified run, and ``verify`` then failed. It now
    rewrites the manifest as ``report --run`` does."""
    import sensorgap

    run = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    argv += ["--environments", "snow", "--budget", "30", "--out", str(run)]
    assert main(argv) == 0 and (run / "manifest.json").is_file()
    html, md = sensorgap.write_report(run)
    assert html.is_file() and md.is_file()
    assert verify_manifest(run) == []
    assert main(["verify", str(run)]) == 0


def test_the_librarys_search_certifies_its_run_as_the_command_does(tmp_path: Path) -> None:
    """Hostile round 30, F5 (the search half): ``sensorgap.find_scenarios(resume=True)``
    into an exported run rewrote the ranking and the store, but neither removed the export
    of the previous ranking nor rewrote the manifest: ``verify`` failed and ``report --run``
    refused the folder. It now runs the command's step (``steps.certified_search``):
    a new run is certified, a resumed one too, with its stale export removed."""
    import sensorgap

    run = tmp_path / "run"
    kw: dict[str, Any] = {"families": ["slow_ahead_curve"], "environments": ["snow"]}
    sensorgap.find_scenarios("system_b", run, budget=10, seed=0, progress=False, **kw)
    assert verify_manifest(run) == []  # a new run is certified, as `search` certifies it
    sensorgap.export_catalog(run, top=1)
    assert (run / "catalog.json").is_file() and verify_manifest(run) == []
    before = (run / "ranking.json").read_bytes()
    sensorgap.find_scenarios("system_b", run, budget=40, seed=0, resume=True, progress=False, **kw)
    assert (run / "ranking.json").read_bytes() != before  # the ranking changed
    assert not (run / "catalog.json").exists() and not (run / "scenarios").exists()
    assert verify_manifest(run) == []
    assert main(["verify", str(run)]) == 0


def test_an_occluder_class_missing_from_a_runs_recorded_targets_is_refused(
    tmp_path: Path,
) -> None:
    """Hostile round 31, F1: a family whose occluder class was missing from a run's recorded
    targets file was given the class of that name from the current templates (shipped, or
    SENSORGAP_TEMPLATES at export time): one run folder exported two catalogs. A class the
    family names (target or occluder) missing from the recorded copy is refused naming it."""
    from sensorgap.config.load import templates_dir
    from sensorgap.scenarios import load_family

    drop, role = "car", "occluder"  # (a missing target class: the corpus's cases)
    lines = (templates_dir() / "targets.toml").read_text(encoding="utf-8").splitlines()
    kept, skipping = [], False
    for line in lines:  # the class's table and its sub-tables left out
        if line.startswith("["):
            skipping = line.startswith((f"[targets.{drop}]", f"[targets.{drop}."))
        if not skipping:
            kept.append(line)
    recorded = tmp_path / "targets.toml"
    recorded.write_text("\n".join(kept) + "\n", encoding="utf-8")
    assert f"[targets.{drop}]" not in recorded.read_text(encoding="utf-8")
    family = load_family("pedestrian_behind_parked_cars")  # shipped: pedestrian behind cars
    assert family.settings["target"] == "pedestrian" and family.settings["occluder"] == "car"
    with pytest.raises(InputError) as err:
        load_family("pedestrian_behind_parked_cars", targets=recorded)
    assert err.value.source == str(recorded) and err.value.field == "targets"
    assert f"no target class {drop!r} (the {role} of family" in err.value.message


def test_the_librarys_export_runs_the_commands_step(tmp_path: Path) -> None:
    """Hostile round 31, F2: ``sensorgap.export_catalog`` skipped the command's step: an
    export in place that changed the scenario files kept the report of the previous one
    (certified by ``verify``), and a symbolic link the command refuses was removed. It now
    runs the command's step (``steps.certified_export``)."""
    import sensorgap

    run = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    argv += ["--environments", "snow", "--budget", "30", "--out", str(run)]
    assert main(argv) == 0 and main(["export", "--run", str(run), "--top", "1"]) == 0
    assert main(["report", "--run", str(run)]) == 0 and (run / "report.md").is_file()
    index = sensorgap.export_catalog(run, osc_version="1.0", top=1)  # other scenario files
    assert len(index["scenarios"]) == 1
    assert not (run / "report.md").exists() and not (run / "report.html").exists()
    assert verify_manifest(run) == [] and main(["verify", str(run)]) == 0
    link = run / "scenarios" / "x.xosc"
    link.symlink_to("/etc/hostname")
    with pytest.raises(InputError, match=r"^run: .*scenarios/x\.xosc, a symbolic link"):
        sensorgap.export_catalog(run)
    assert link.is_symlink()  # left for its owner to move, as the command leaves it


def test_json_nesting_is_bounded_the_same_on_every_python() -> None:
    """The readers' "nested too deeply" line must not depend on the interpreter: Python
    3.11's ``json`` gave up near 1,000 levels, 3.13's parses far deeper (and the corpus's
    deep cases then met other checks). ``filesio.loads_json`` refuses more than
    ``MAX_JSON_DEPTH`` levels itself; brackets inside strings do not count."""
    from sensorgap.filesio import MAX_JSON_DEPTH, json_too_deep, loads_json

    n = MAX_JSON_DEPTH
    assert loads_json("[" * n + "]" * n) is not None
    for text in ("[" * (n + 1) + "]" * (n + 1), '{"a":' * (n + 1) + "1" + "}" * (n + 1)):
        assert json_too_deep(text)
        with pytest.raises(RecursionError, match="nested more than 64 levels"):
            loads_json(text)
    inside = '["' + "[{" * 500 + '\\"' + '"]'  # brackets and an escaped quote in a string
    assert not json_too_deep(inside) and loads_json(inside) == ["[{" * 500 + '"']


def test_an_export_under_warnings_as_errors_is_clean(tmp_path: Path) -> None:
    """Hostile round 32, F1: on Python 3.12+ scenariogeneration's writing of a scenario
    warns (an XML element's truth value tested): ``PYTHONWARNINGS=default`` printed it and
    ``=error`` made every export an internal error. The export ignores that one warning
    while it writes (``export.xosc.write_scenario_xml``)."""
    import warnings

    run = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    argv += ["--environments", "fog_50", "--budget", "30", "--top", "1", "--out", str(run)]
    assert main(argv) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # as PYTHONWARNINGS=error
        assert main(["export", "--run", str(run), "--out", str(tmp_path / "c")]) == 0
    assert list((tmp_path / "c" / "scenarios").glob("*.xosc"))


def test_a_manifest_verify_could_not_read_is_never_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Hostile round 32, F3: 27,000 files under long paths made export write a 107.7 MB
    manifest, which verify and report then refused (at most 100 MB). write_manifest now
    refuses one over the limit before writing (the limit lowered here to 300 bytes)."""
    import sensorgap.filesio as filesio

    run = _folder(tmp_path)
    before = (run / "manifest.json").read_bytes()
    for i in range(5):
        (run / f"{'long_name_' * 8}{i}.txt").write_text("x")
    monkeypatch.setattr(filesio, "MAX_MANIFEST_BYTES", 300)
    with pytest.raises(InputError, match=r"manifest\.json: not written: it would be \d+ bytes"):
        write_manifest(run)
    assert (run / "manifest.json").read_bytes() == before


def test_a_crowded_run_is_refused_naming_the_option_given(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round 32, F4 and F3: an export in place of a run of more than 100,000 files
    named --out, which the user had not given; report --run listed them all (45 s). Both
    refuse before any work, naming --run (the limit lowered here to 40 entries)."""
    import sensorgap.filesio as filesio

    run = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    argv += ["--environments", "fog_50", "--budget", "20", "--top", "1", "--out", str(run)]
    assert main(argv) == 0
    (run / "many").mkdir()
    for i in range(40):
        (run / "many" / f"{i}.txt").write_text("x")
    monkeypatch.setattr(filesio, "MAX_OUT_ENTRIES", 40)
    for args in (["export", "--run", str(run)], ["report", "--run", str(run)]):
        capsys.readouterr()
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.startswith("sensorgap: error: --run: ") and "move the files that" in err
    assert not (run / "catalog.json").exists() and not (run / "report.html").exists()


def test_a_resumed_search_over_a_damaged_run_json_rewrites_it(tmp_path: Path) -> None:
    """Hostile round 32, F5: a run.json nested 200,001 levels was read back by plain
    json.loads to keep its fields, and the resumed search stopped with an internal
    RecursionError. A damaged run.json is read as empty (it is one of the files a search
    rewrites) and the folder verifies afterwards."""
    run = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    argv += ["--environments", "fog_50", "--top", "1", "--out", str(run)]
    assert main([*argv, "--budget", "20"]) == 0
    n = 200_000
    (run / "run.json").write_text('{"x":' + "[" * n + "]" * n + "}")
    assert main([*argv, "--budget", "30", "--resume"]) == 0
    assert "x" not in json.loads((run / "run.json").read_text())
    assert verify_manifest(run) == []


def test_a_run_whose_manifest_verify_could_not_read_is_refused_before_any_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A remark of round 33: a folder whose manifest would pass 100 MB (27,000 files under
    3,900-character paths) was refused only after 85 s of work, when the manifest was
    written. Its least size (paths plus a fixed part per file, ``manifest_lower_bound``) is
    now checked with the other folder limits, before any work (the limit lowered here)."""
    import sensorgap.filesio as filesio

    run = tmp_path / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    argv += ["--environments", "fog_50", "--budget", "20", "--top", "1", "--out", str(run)]
    assert main(argv) == 0
    files, least = filesio.manifest_lower_bound(run)
    assert 0 < least <= len((run / "manifest.json").read_bytes())  # a bound, never above
    monkeypatch.setattr(filesio, "MAX_MANIFEST_BYTES", least - 1)
    capsys.readouterr()
    assert main(["export", "--run", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("sensorgap: error: --run: ") and f"at least {least} bytes" in err
    assert not (run / "catalog.json").exists()
