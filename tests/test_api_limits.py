"""The facade (``sensorgap.api``, docs/api.md) refuses bad input as the command line does:
one ``InputError`` naming the parameter, before any work (hostile round twelve)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import sensorgap
from sensorgap.coverage import limits
from sensorgap.coverage.occluders import MAX_OCCLUDER_M, Occluder
from sensorgap.errors import InputError

HUGE = 10**400  # beyond a float: float(HUGE) is an OverflowError
HUGER = 10**5000  # beyond Python's int -> str limit: repr(HUGER) is a ValueError

TRUCK = (15.0, -3.5, 0.0, 12.0, 2.5, 3.5, "truck")


@pytest.mark.parametrize(
    ("index", "value", "field"),
    [
        (0, math.nan, "x"),  # silently blanked the whole map (Pd 0 everywhere)
        (1, math.inf, "y"),
        (0, MAX_OCCLUDER_M + 1.0, "x"),
        (2, math.nan, "heading"),
        (2, 7.0, "heading"),  # rad: more than a full turn
        (3, -12.0, "length"),  # a negative length was accepted
        (3, 0.0, "length"),
        (4, 11.0, "width"),
        (5, math.nan, "height"),
        (5, True, "height"),
        (0, "15", "x"),
        (6, "", "label"),
        (6, None, "label"),
    ],
)
def test_occluder_refuses_a_box_no_road_user_could_be(index: int, value: Any, field: str) -> None:
    args: list[Any] = list(TRUCK)
    args[index] = value
    with pytest.raises(InputError, match=f"^Occluder: {field}: ") as exc:
        Occluder(*args)
    assert exc.value.field == field


def test_occluder_takes_numpy_numbers_as_floats() -> None:
    occ = Occluder(np.float32(15.0), np.int64(-3), 0, 12, 2.5, 3.5)
    assert type(occ.x) is float and type(occ.y) is float and type(occ.length) is float


def test_a_nan_occluder_never_reaches_a_map() -> None:
    with pytest.raises(InputError, match="^Occluder: x: must be a finite number"):
        sensorgap.coverage_grid(
            "system_a",
            extent=(0, 10, 0, 10),
            resolution=1.0,
            heading_deg=0.0,
            occluders=[sensorgap.Occluder(math.nan, 0, 0, 12, 2.5, 3.5, "truck")],
        )


@pytest.mark.parametrize(
    ("kwargs", "line"),
    [
        # peaked at 4.9 GB, then numpy's "Unable to allocate 284. PiB"
        (
            {"extent": (-1e5, 1e5, -1e5, 1e5), "resolution": 0.001},
            r"^resolution: grid of 40,000,000,000,000,000 cells is too large "
            r"\(at most 4,000,000 with heading_deg\)",
        ),
        (
            {"extent": (-1e5, 1e5, -1e5, 1e5), "resolution": 0.01, "heading_deg": None},
            r"^resolution: grid of 400,000,000,000,000 cells is too large \(at most 30,000,000\)",
        ),
        (
            {"extent": (0, 2000, 0, 2000), "resolution": 1.0, "heading_deg": None},
            r"^resolution: 4,000,000 cells x 23 sensors is too large",
        ),
        ({"extent": (0, 2e5, 0, 10)}, r"^extent: coordinates must be within \+-100000 m"),
        ({"extent": (10, 0, 0, 10)}, r"^extent: must be \(xmin, xmax, ymin, ymax\) with"),
        ({"extent": (0, 1, 2)}, r"^extent: must be 4 finite real numbers"),
        ({"extent": (0, math.nan, 0, 1)}, r"^extent: must be 4 finite real numbers"),
        ({"extent": None}, r"^extent: must be 4 finite real numbers"),
        ({"resolution": "1"}, r"^resolution: must be a finite number > 0, got '1'"),
        ({"resolution": 0.0001}, r"^resolution: must be at least 0\.001 m"),
        ({"resolution": 100.0, "extent": (0, 10, 0, 10)}, r"^resolution: 100 m cells do not fit"),
        ({"workers": 0}, r"^workers: must be 1\.\.64, got 0"),
        ({"workers": True}, r"^workers: must be 1\.\.64, got True"),
        ({"heading_deg": 1e308}, r"^heading_deg: must be an angle within \+-360 degrees"),
        ({"heading_deg": math.nan}, r"^heading_deg: must be an angle within \+-360 degrees"),
        (
            {"heading_deg": None, "occluders": [Occluder(*TRUCK)]},
            r"^occluders: occluders hide parts of target bodies: add heading_deg",
        ),
        (
            {"occluders": [Occluder(0, 0, 0, 12, 2.5, 3.5, "truck")]},
            r"^occluders: \[0\] \(truck at x 0, y 0 m\) overlaps the ego body \(System A",
        ),
        (
            {"occluders": [Occluder(*TRUCK)] * (limits.MAX_OCCLUDERS + 1)},
            r"^occluders: 101 occluders; at most 100 allowed$",
        ),
        ({"occluders": [TRUCK]}, r"^occluders: \[0\]: must be an Occluder"),
        (
            {
                "extent": (-100, 100, -75, 75),
                "resolution": 0.1,
                "occluders": [Occluder(*TRUCK)] * 50,
            },
            r"^resolution: a map of target bodies of 3,000,000 cells x 23 sensors with 50 "
            r"occluders is too much work",
        ),
    ],
)
def test_coverage_grid_applies_the_coverage_limits(kwargs: dict[str, Any], line: str) -> None:
    kw: dict[str, Any] = {"extent": (0, 10, 0, 10), "resolution": 1.0, "heading_deg": 0.0}
    with pytest.raises(InputError, match=line):
        sensorgap.coverage_grid("system_a", "clear", "car", **{**kw, **kwargs})


def test_coverage_grid_covers_whole_cells_only() -> None:
    """As ``sensorgap coverage``: an extent that is not a multiple of the resolution is
    clipped to the last whole cell."""
    g = sensorgap.coverage_grid(
        "system_a", extent=(0, 10.5, 0, 10), resolution=1.0, heading_deg=None
    )
    assert g.fused.shape == (10, 10)


@pytest.mark.parametrize(
    ("points", "line"),
    [
        # accepted: 3.1 GB and 27 s (a broadcast view: no memory of its own here)
        (np.broadcast_to(np.zeros(3), (10**7, 3)), r"^points: 10000000 points; at most 500000"),
        ([[0.0] * 3] * 500_001, r"^points: 500001 points; at most 500000"),
        (None, r"^points: must be an \(N, 3\) array of finite real numbers"),
        ([1.0, 2.0, 3.0], r"^points: must have shape \(N, 3\) or \(N, 2\)"),
        ([["a", 1, 2]], r"^points: must be an \(N, 3\) array of finite real numbers"),
        ([[1.0, 2.0, math.nan]], r"^points: coordinates must be finite numbers within \+-1e7 m"),
        ([[2e7, 0.0, 1.0]], r"^points: coordinates must be finite numbers within \+-1e7 m"),
        ([[10.0, 0.0, -1.0]], r"^points: z: must be within 0\.\.50 m"),
        ([[30, 0, -5]], r"^points: z: must be within 0\.\.50 m"),  # was Pd [1.]
        ([["a", "b", "c"]], r"^points: must be an \(N, 3\) array of finite real numbers"),
        # was numpy's ComplexWarning on stderr, then the real parts evaluated
        (
            np.array([[30 + 1j, 0, 0.75]]),
            r"^points: must be an \(N, 3\) array of finite real numbers, got compl",
        ),
        (
            [[30 + 1j, 0, 0.75]],
            r"^points: must be an \(N, 3\) array of finite real numbers, got complex",
        ),
        # round thirteen's rerun: a boolean array was read as 1 m coordinates
        (
            np.ones((1, 3), bool),
            r"^points: must be an \(N, 3\) array of finite real numbers, got booleans",
        ),
        (
            [[30.0, True, 0.75]],
            r"^points: must be an \(N, 3\) array of finite real numbers, got booleans",
        ),
    ],
)
def test_evaluate_points_applies_the_probe_limits(points: Any, line: str) -> None:
    with pytest.raises(InputError, match=line):
        sensorgap.evaluate_points("system_a", points)


def test_evaluate_points_limits_points_times_sensors(monkeypatch: pytest.MonkeyPatch) -> None:
    from sensorgap.coverage import pointsio

    monkeypatch.setattr(pointsio, "MAX_POINT_SENSOR_VALUES", 23 * 10)
    with pytest.raises(InputError, match=r"^points: 11 points x 23 sensors is too many"):
        sensorgap.evaluate_points("system_a", np.full((11, 3), 1.0))


@pytest.mark.parametrize(
    ("kwargs", "line"),
    [
        ({"budget": "10"}, r"^budget: must be an integer, got '10'$"),  # TypeError: '<='
        ({"budget": True}, r"^budget: must be an integer, got True$"),
        ({"seed": 1.5}, r"^seed: must be an integer, got 1\.5$"),
        ({"top": "3"}, r"^top: must be an integer, got '3'$"),
        # read as its letters: "unknown family 's'"
        ({"families": "slow_ahead_curve"}, r"^families: must be 'all' or a list of names, got the"),
        ({"environments": "clear"}, r"^environments: must be 'all' or a list of names, got the"),
        ({"families": [3]}, r"^families: \[0\]: must be a name"),
        ({"families": None}, r"^families: must be 'all' or a list of names, got None"),
        # hostile round 38: == "all" on a numpy array was a raw "truth value is ambiguous"
        (
            {"families": np.array(["slow_ahead_curve", "cut_in_left"])},
            r"^families: must be 'all' or a list of names, got array",
        ),
        (
            {"environments": np.array(["clear", "fog_50"])},
            r"^environments: must be 'all' or a list of names, got array",
        ),
        ({"workers": "2"}, r"^workers: must be an integer, got '2'$"),
        ({"detection": 3}, r"^detection: must be a str, got 3$"),
        ({"detection": " 3/5"}, r"^detection: expected 'cumulative' or M/N in ASCII digits"),
        ({"environments_file": ""}, r"^environments_file: must be a path"),
        # hostile round thirteen: a TypeError deep inside, after run.json, search.sqlite
        # and inputs/ were written
        ({"budget": 20.5}, r"^budget: must be an integer, got 20\.5$"),
        ({"environments": None}, r"^environments: must be 'all' or a list of names, got None"),
        ({"bogus": 1}, r"^bogus: unknown option; allowed: detection, "),  # a raw TypeError
        # truthy strings were taken as True
        ({"sun_search": "no"}, r"^sun_search: must be a bool, got 'no'$"),
        ({"resume": "yes"}, r"^resume: must be a bool, got 'yes'$"),
        ({"lock": False}, r"^lock: unknown option; allowed: .*$"),
        ({"progress": 1}, r"^progress: must be a bool, got 1$"),
        ({"min_distance": "x"}, r"^min_distance: must be a finite number >= 0, got 'x'$"),
        ({"min_distance": math.nan}, r"^min_distance: must be a finite number >= 0, got nan$"),
        ({"min_distance": -0.1}, r"^min_distance: must be a finite number >= 0, got -0\.1$"),
        # hostile round fourteen (F10): integers beyond a float were a raw OverflowError
        ({"min_distance": HUGE}, r"^min_distance: must be a finite number >= 0, got an integer "),
        ({"budget": HUGER}, r"^budget: must be within 1\.\.1000000, got an integer of 5001 digits"),
        # hostile round fifteen (F5): a raw TypeError (re.match on an int)
        ({"executor": "dask", "scheduler": 5}, r"^scheduler: must be a str or None, got 5$"),
        ({"strategy": None}, r"^strategy: must be a str, got None$"),
        # hostile round 42, F2: it named the command line's option, "pd: ..."
        ({"mode": "Exact"}, r"^mode: must be lookup or exact, got 'Exact'$"),
        ({"mode": 1}, r"^mode: must be a str, got 1$"),
        ({"executor": ["local"]}, r"^executor: must be a str, got "),
    ],
)
def test_find_scenarios_checks_types_before_any_work(
    tmp_path: Path, kwargs: dict[str, Any], line: str
) -> None:
    kw: dict[str, Any] = {"families": ["slow_ahead_curve"], "environments": ["clear"], "budget": 10}
    with pytest.raises(InputError, match=line):
        sensorgap.find_scenarios("system_b", tmp_path / "run", **{**kw, **kwargs})
    assert not (tmp_path / "run").exists()


def test_find_scenarios_takes_numpy_integers_and_booleans(tmp_path: Path) -> None:
    """Hostile round 41 (a remark): a 0-d integer array was refused for ``budget`` while
    one of floats passed for a number, and ``resume=np.bool_(False)`` was refused while
    ``workers=np.int64(1)`` passed. Both are their values; the run is the same."""
    kw: dict[str, Any] = {"families": ["slow_ahead_curve"], "environments": ["clear"]}
    plain = sensorgap.find_scenarios(
        "system_b", tmp_path / "a", budget=10, seed=1, resume=False, sun_search=True, **kw
    )
    numpy = sensorgap.find_scenarios(
        "system_b",
        tmp_path / "b",
        budget=np.array(10),
        seed=np.array(1, dtype=np.int8),
        resume=np.bool_(False),
        sun_search=np.bool_(True),
        # hostile round 42, F1: these reached the store's JSON, "int64 is not JSON
        # serializable", a store left behind
        seeds=np.int64(1),
        workers=np.array(2, dtype=np.uint8),
        **kw,
    )
    assert numpy.ranking == plain.ranking
    for bad in (np.array(True), np.array(10.0)):
        with pytest.raises(InputError, match=r"^budget: must be an integer, got "):
            sensorgap.find_scenarios("system_b", tmp_path / "c", budget=bad, **kw)


@pytest.mark.parametrize("where", ["f", "f/run", "f/a/run"])
def test_an_output_folder_that_is_a_file_is_refused(tmp_path: Path, where: str) -> None:
    """Hostile round thirteen: ``out`` naming a file (or a path below one) was a raw
    FileExistsError (find_scenarios) or NotADirectoryError (export_catalog)."""
    (tmp_path / "f").write_text("x")
    out = tmp_path / where
    line = rf"^out: {tmp_path / 'f'} is a file, not a folder$"
    kw: dict[str, Any] = {"families": ["slow_ahead_curve"], "environments": ["clear"], "budget": 10}
    with pytest.raises(InputError, match=line):
        sensorgap.find_scenarios("system_b", out, **kw)
    with pytest.raises(InputError, match=line):
        sensorgap.export_catalog(tmp_path / "run", out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]
    assert (tmp_path / "f").read_text() == "x"


@pytest.mark.parametrize(
    ("call", "line"),
    [
        (lambda: sensorgap.write_report(None), r"^run: must be a path"),  # TypeError
        (lambda: sensorgap.write_report(""), r"^run: must be a path"),
        (lambda: sensorgap.export_catalog(None), r"^run: must be a path"),
        (lambda: sensorgap.export_catalog("r", top="3"), r"^top: must be an integer, got '3'"),
        (lambda: sensorgap.export_catalog("r", style=None), r"^style: must be 'maneuver' or"),
        (lambda: sensorgap.find_scenarios("system_b", None), r"^out: must be a path"),
        (lambda: sensorgap.load_vehicle(None), r"^vehicle: must be a vehicle preset name"),
        (lambda: sensorgap.scene("system_a", None), r"^environment: must be an environment"),
        (lambda: sensorgap.scene("system_a", "clear", 3), r"^target: must be a target class"),
        (
            lambda: sensorgap.scene("system_a", ego_heading_deg=math.nan),
            r"^ego_heading_deg: must be an angle within \+-360 degrees",
        ),
        (
            lambda: sensorgap.scene("system_a", ego_heading_deg="5"),
            r"^ego_heading_deg: must be an angle within \+-360 degrees",
        ),
        (
            lambda: sensorgap.scene("system_a", environments_file=""),
            r"^environments_file: must be a path",
        ),
    ],
)
def test_facade_names_the_bad_parameter(call: Any, line: str) -> None:
    with pytest.raises(InputError, match=line):
        call()


LONG = "a" * 300  # one path component beyond NAME_MAX (255 bytes)


@pytest.mark.parametrize(
    "call",
    [
        lambda out: sensorgap.load_vehicle(LONG),
        lambda out: sensorgap.evaluate_points(LONG, np.array([[30.0, 0.0, 0.75]])),
        lambda out: sensorgap.scene("system_b", environments_file=LONG + ".toml"),
        lambda out: sensorgap.find_scenarios(
            LONG, out, families=["slow_ahead_curve"], environments=["clear"], budget=50
        ),
        lambda out: sensorgap.export_catalog(LONG),
        lambda out: sensorgap.write_report(LONG),
    ],
)
def test_a_file_that_cannot_be_opened_is_an_input_error(tmp_path: Path, call: Any) -> None:
    """Hostile round fifteen (F4): a path the system refuses (a name too long) raised a
    raw OSError; now one InputError naming the file and the system's reason."""
    with pytest.raises(
        InputError,
        # (write_report names the run's manifest.json, which it reads first)
        match=r"aaaa(\.toml|/manifest\.json)? \(3[01][0-9] characters\): cannot read or "
        r"write it \(File name",
    ) as exc:
        call(tmp_path / "run")
    assert "\n" not in str(exc.value)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    ("call", "line"),
    [
        # hostile round fourteen (F10): each was a raw OverflowError
        (
            lambda: sensorgap.evaluate_points("system_b", [[HUGE, 0, 0.75]]),
            r"^points: must be an \(N, 3\) array of finite real numbers, got an integer beyond",
        ),
        (
            lambda: sensorgap.coverage_grid("system_b", extent=(-HUGE, 30, -10, 10)),
            r"^extent: must be 4 finite real numbers \(xmin, xmax, ymin, ymax\), m, got \(-1000",
        ),
        (
            lambda: sensorgap.coverage_grid("system_b", extent=(-HUGER, 30, -10, 10)),
            r"^extent: must be 4 finite real numbers .* got a tuple holding an integer too long",
        ),
        (
            lambda: sensorgap.coverage_grid("system_b", resolution=HUGE),
            r"^resolution: must be a finite number > 0, got an integer of 401 digits$",
        ),
        (
            lambda: sensorgap.coverage_grid("system_b", heading_deg=-HUGER),
            r"^heading_deg: must be an angle within \+-360 degrees, got a negative integer of 5001",
        ),
        (
            lambda: sensorgap.coverage_grid("system_b", workers=HUGER),
            r"^workers: must be 1\.\.64, got an integer of 5001 digits$",
        ),
        (
            lambda: sensorgap.scene("system_b", ego_heading_deg=HUGE),
            r"^ego_heading_deg: must be an angle within \+-360 degrees, got an integer of 401 ",
        ),
        (
            lambda: sensorgap.scene("system_b", HUGER),
            r"^environment: must be an environment preset name \(a str\), got an integer of 5001",
        ),
        (
            lambda: Occluder(HUGE, 0, 0, 12.0, 2.5, 3.5, "truck"),
            r"^Occluder: x: must be a finite number within -1000\.\.1000 m .*, got an integer of",
        ),
        (
            lambda: Occluder(0, 20, 0, 12.0, -HUGE, 3.5, "truck"),
            r"^Occluder: width: must be a finite number .*, got a negative integer of 401 digits$",
        ),
    ],
)
def test_integers_beyond_a_float_are_refused_by_name(call: Any, line: str) -> None:
    with pytest.raises(InputError, match=line):
        call()


@pytest.mark.parametrize(
    ("points", "got"),
    [
        # hostile round fourteen (F11): each was evaluated as coordinates
        ([["30", "0", "0.75"]], r"text \(str\)"),
        ([[b"30", b"0", b"0.75"]], "bytes"),
        (np.array([["30", "0", "0.75"]]), r"text \(str\)"),
        (np.array([[b"30", b"0", b"0.75"]]), "bytes"),
        (np.array([[1, 2, 3]], dtype="datetime64[s]"), r"dates \(datetime64\)"),
        (np.array([[1, 2, 3]], dtype="timedelta64[s]"), r"durations \(timedelta64\)"),
        ([[np.timedelta64(30, "s"), 0, 0.5]], r"durations \(timedelta64\)"),
        ([[np.True_, 0, 0.5]], "booleans"),  # numpy casts np.True_ to 1.0 beside numbers
        (np.array([[True, 30, 0.5]], dtype=object), "booleans"),
        (np.array([[np.True_, 30, 0.5]], dtype=object), "booleans"),
        ([[None, 0, 0.5]], "None"),
        ([[30.0, 0.0, 0.5], [1.0, 2.0]], "rows of unequal lengths"),
        # a remark of round 29: the masked values were evaluated as whatever they held
        (
            np.ma.masked_array([[30.0, 0, 0.5], [1e9, 0, 0.5]], mask=[[0, 0, 0], [1, 0, 0]]),
            r"a masked array with masked values \(give the values to use\)",
        ),
    ],
)
def test_evaluate_points_refuses_what_is_not_a_real_number(points: Any, got: str) -> None:
    line = rf"^points: must be an \(N, 3\) array of finite real numbers, got {got}$"
    with pytest.raises(InputError, match=line):
        sensorgap.evaluate_points("system_b", points)


def test_evaluate_points_takes_every_kind_of_real_number() -> None:
    from fractions import Fraction

    plain = sensorgap.evaluate_points("system_b", [[30.0, 0.0, 0.75], [30.0, -8.0, 0.75]])
    for points in (
        [[30, 0, Fraction(3, 4)], [np.float32(30), np.int64(-8), 0.75]],
        np.array([[30, 0, 0.75], [30, -8, 0.75]], dtype=object),
        [np.array([30.0, 0.0, 0.75]), (30, -8, 0.75)],
        np.array([[30, 0], [30, -8]], dtype=np.int16),  # (N, 2): z = 0
    ):
        cov = sensorgap.evaluate_points("system_b", points)
        assert cov.fused.shape == (2,)
        if len(np.asarray(points)[0]) == 3:
            np.testing.assert_array_equal(cov.fused, plain.fused)


@pytest.mark.parametrize("resolution", [np.array(2.0), np.array(2, dtype=np.int8)])
def test_a_zero_dimensional_array_is_its_number(resolution: Any) -> None:
    """Hostile round 40 (a remark): ``coverage_grid(resolution=np.array(0.5))`` was
    refused while ``Fraction(1, 2)`` passed; a 0-d array of integers or floats is its
    number (one of booleans, text or NaN is still refused)."""
    kw: dict[str, Any] = {"extent": (0, 10, 0, 10), "heading_deg": None}
    grid = sensorgap.coverage_grid("system_a", resolution=resolution, **kw)
    plain = sensorgap.coverage_grid("system_a", resolution=2.0, **kw)
    np.testing.assert_array_equal(grid.fused, plain.fused)
    for bad in (np.array(True), np.array("2"), np.array(np.nan), np.array([2.0])):
        with pytest.raises(InputError, match=r"^resolution: must be a finite number > 0"):
            sensorgap.coverage_grid("system_a", resolution=bad, **kw)
    # hostile round 42: "workers: must be 1..64, got array(1)"
    threads = sensorgap.coverage_grid("system_a", resolution=2.0, workers=np.array(1), **kw)
    np.testing.assert_array_equal(threads.fused, plain.fused)


@pytest.mark.parametrize(
    "extent",
    [
        np.array([0.0, 10.0, 0.0, 10.0]),  # hostile round fourteen (F12): was refused
        np.array([0, 10, 0, 10], dtype=np.int32),
        [np.float64(0.0), 10, np.int64(0), 10.0],
    ],
)
def test_coverage_grid_takes_an_extent_as_a_numpy_array(extent: Any) -> None:
    kw: dict[str, Any] = {"resolution": 1.0, "heading_deg": None}
    grid = sensorgap.coverage_grid("system_a", extent=extent, **kw)
    plain = sensorgap.coverage_grid("system_a", extent=(0, 10, 0, 10), **kw)
    np.testing.assert_array_equal(grid.fused, plain.fused)


@pytest.mark.parametrize(
    "extent",
    [
        np.array([[0.0, 10.0], [0.0, 10.0]]),
        np.array([True, True, False, True]),
        np.array(["0", "10", "0", "10"]),
        ["0", "10", "0", "10"],
        b"\x00\x0a\x00\x0a",
        range(10**20),  # len() is an OverflowError
    ],
)
def test_coverage_grid_refuses_an_extent_of_other_things(extent: Any) -> None:
    with pytest.raises(InputError, match=r"^extent: must be 4 finite real numbers \(xmin"):
        sensorgap.coverage_grid("system_a", extent=extent, resolution=1.0)
