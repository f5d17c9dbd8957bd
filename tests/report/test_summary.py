"""The report's summary page: what it says is what the run's files say (ranking rows,
summary.json, lookup_vs_exact), in km/h, m and s; and the words for directions, positions
and weather."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from lxml import html as lhtml

from sensorgap.cli import main
from sensorgap.config import load_environments
from sensorgap.config.environment import SunConfig
from sensorgap.export.spec import ScenarioSpec, read_run
from sensorgap.models import Conditions, load_system
from sensorgap.report.summary import (
    KMH,
    MAX_WEAKNESSES,
    _low_words,
    blind_areas,
    blind_extents,
    direction_words,
    explain_spec,
    fmt_p,
    mirrored_pairs,
    pd_without,
    spot_words,
    summary_section,
    sun_azimuth_deg,
    weather_words,
    where_words,
)
from sensorgap.search.evaluate import DetectionRule, Evaluator


def _doc(path: Path) -> lhtml.HtmlElement:
    return lhtml.fromstring(path.read_bytes())


def _ranking(folder: Path) -> dict:
    return json.loads((folder / "ranking.json").read_text())


def test_summary_comes_first_and_says_what_was_searched(job: Path) -> None:
    doc = _doc(job / "report.html")
    body = [e.tag for e in doc.find("body")]
    assert body[:2] == ["h1", "p"] and body[2:4] == ["section", "nav"]
    assert doc.find("body").findall("section")[0].get("id") == "summary"
    text = doc.get_element_by_id("summary").text_content()
    settings = _ranking(job)["settings"]
    assert "Vehicle: System A (system_a.toml), 23 sensors" in text
    fams, envs = settings["families"], settings["environments"]
    assert f"{len(fams)} scenario families ({', '.join(fams)})" in text
    assert f"{len(envs)} environments ({', '.join(envs)})" in text
    assert "budget 2,100 candidates" in text and f"seed {settings['seed']}" in text
    assert f"Found: {len(_ranking(job)['ranking'])} sensor-critical scenario" in text


def test_weaknesses_are_true_to_the_ranking(job: Path) -> None:
    doc = _doc(job / "report.html")
    rows = {r["rank"]: r for r in _ranking(job)["ranking"]}
    items = doc.get_element_by_id("weaknesses").findall(".//li")
    # the first-ranked scenario of each (family, dominant effect), in rank order
    first: dict[tuple[str, str], int] = {}
    for rank in sorted(rows):
        first.setdefault((rows[rank]["family"], rows[rank]["dominant_effect"]), rank)
    want = sorted(first.values())[:MAX_WEAKNESSES]
    got = [int(re.search(r"\(rank (\d+)\)\.$", li.text_content().strip())[1]) for li in items]
    assert got == want and items
    for li, rank in zip(items, got, strict=True):
        row, text = rows[rank], " ".join(li.text_content().split())
        assert li.find("b") is not None  # the lead (what and where) in bold
        assert f"ego at {row['p_ego_speed_m_s'] * KMH:.0f} km/h" in text
        if row.get("p_target_speed_m_s") is not None:
            assert f"{row['target']} at {row['p_target_speed_m_s'] * KMH:.0f} km/h" in text
        assert (
            f"P(collision) {fmt_p(row['collision_probability'])}, impact at "
            f"{row['impact_speed_kmh']:.0f} km/h"
        ) in text
        assert f"At {row['named_step_t_s']:.2f} s" in text
        if row.get("t_confirm_median_s") is not None:
            assert f"confirms it at {row['t_confirm_median_s']:.2f} s (median)" in text
            if row["detection_margin_s"] < 0:
                assert f"{-row['detection_margin_s']:.2f} s too late" in text
        # every sensor the search itemised, with its Pd without the cause
        for sid, better in pd_without(row["reason"]).items():
            assert sid in text, sid
            assert f"{better:.2f}" in text
        # where the target is at that step, in metres ahead/behind (the reason's x)
        x = float(re.search(r"at x=(-?[\d.]+) y=", row["reason"])[1])
        m = re.search(rf"the {row['target']} is (\d+) m (ahead|behind)", text)
        assert m and abs(int(m[1]) - abs(x)) <= 1 and (m[2] == "ahead") == (x > 0)
        assert "m/s" not in text.replace("m/s2", "")  # speeds in km/h
        more = len(row["environments"].split(", ")) - 1
        assert (f"critical for the same reason in {more} more condition" in text) == (more > 0)


def test_explanation_is_the_rankings(job: Path) -> None:
    """The summary's per-sensor causes are recomputed exactly as the search did: same
    text as the row's reason."""
    run = read_run(job)
    system = load_system(run.vehicle_ref)
    ev = Evaluator(system, mode="exact", rule=DetectionRule.parse(run.settings["detection"]))
    for row in run.rows:
        spec = ScenarioSpec.from_row(row, system)
        why = explain_spec(spec, ev)
        assert why.reason == row["reason"]
        assert why.dominant == row["dominant_effect"]


def test_test_these_first_links_the_files(job: Path) -> None:
    doc = _doc(job / "report.html")
    sec = doc.get_element_by_id("test-first")
    rows = sec.findall(".//tbody/tr")
    weak = doc.get_element_by_id("weaknesses").findall(".//li")
    assert len(rows) == len(weak)
    ranking = {r["rank"]: r for r in _ranking(job)["ranking"]}
    for tr in rows:
        cells = tr.findall("td")
        row = ranking[int(cells[0].text_content())]
        assert cells[1].text_content() == row["scenario_id"]
        hrefs = [a.get("href") for a in tr.findall(".//a")]
        assert hrefs[0] == f"scenarios/{row['scenario_id']}.xosc"
        for h in hrefs:
            assert (job / h).is_file(), h
    md = (job / "report.md").read_text()
    assert "### Test these first" in md and f"](scenarios/{ranking[1]['scenario_id']}" in md


def test_confidence_states_what_was_and_was_not_measured(job: Path) -> None:
    doc = _doc(job / "report.html")
    text = " ".join(doc.get_element_by_id("confidence").text_content().split())
    summary = json.loads((job / "summary.json").read_text())
    never = [f for f, d in summary["per_family"].items() if not d["sensor_critical_by_lookup"]]
    for f in never:
        assert f in text
    if not never:
        assert "Every searched family produced sensor-critical scenarios" in text
    lve = _ranking(job)["lookup_vs_exact"]
    assert f"of {lve['reevaluated']:,} proposals re-evaluated exactly" in text
    assert f"{lve['sensor_critical_exact']} exactly" in text
    assert f"at most {fmt_p(lve['max_abs_diff_collision_probability'])}" in text
    assert f"top-10 overlap {lve['top10_overlap']} of 10" in text
    # the default job runs its budget as three independent searches: how many of them
    # found each of the top 10 on their own, as summary.json and the ranking rows say
    stab = summary["stability"]
    assert stab["seeds"] == 3 and sum(stab["budget_per_seed"]) == summary["candidates"]
    rows = _ranking(job)["ranking"]
    assert stab["found_by"] == [r["found_by_seeds"] for r in rows[:10]]
    assert all(0 <= f <= 3 for f in stab["found_by"])
    assert "Stability over seeds: the budget ran as 3 independent searches" in text
    n_all = sum(1 for f in stab["found_by"] if f == 3)
    if n_all:
        assert "same kind of weakness" in text and f": {n_all} by all 3" in text
    near = stab["found_near_by"]
    assert len(near) == len(stab["found_by"]) and all(0 <= n <= 3 for n in near)
    assert f"near-duplicate distance {stab['near_distance']:g}" in text
    first = doc.get_element_by_id("test-first").text_content()
    assert "found by searches" in first and f"{rows[0]['found_by_seeds']} of 3" in first
    # the top 10 under the model's uncertain values (search/robustness.py): the line says
    # how many survive every variant, the table (its own section, so that the summary
    # prints on one page) has one row per checked finding with its exact P(collision)
    m = re.search(
        r"Uncertain model values \(\d+ variants, .*?\): (\d+) of the top (\d+) stay", text
    )
    assert m, text
    ok, n = int(m.group(1)), int(m.group(2))
    assert n == min(10, len(rows)) and 0 <= ok <= n
    assert not doc.get_element_by_id("confidence").findall(".//table")  # summary: 1 page
    table = doc.get_element_by_id("robustness").findall(".//table")[-1]
    body = [[c.text_content().strip() for c in tr.findall("td")] for tr in table.iter("tr")]
    body = [b for b in body if b]
    assert [b[0] for b in body] == [str(r["rank"]) for r in rows[:n]]
    assert [b[3] for b in body] == [fmt_p(r["collision_probability"]) for r in rows[:n]]
    assert sum(b[6] == "yes" for b in body) == ok


def test_confidence_of_a_single_search_says_stability_was_not_measured(search_only: Path) -> None:
    """One search (``--seeds 1``, the search command's default): said plainly, no number
    invented, and how to measure it."""
    text = " ".join(
        _doc(search_only / "report.html").get_element_by_id("confidence").text_content().split()
    )
    assert "Stability over seeds: not measured in this run (one search, seed 1)" in text
    assert "rerun with --seeds 3" in text
    rows = _ranking(search_only)["ranking"]
    assert rows and all(r["found_by_seeds"] is None for r in rows)


def test_summary_without_a_search(tmp_path: Path) -> None:
    (tmp_path / "run.json").write_text(json.dumps({"vehicle": "system_b"}))
    assert main(["report", "--run", str(tmp_path)]) == 0
    doc = _doc(tmp_path / "report.html")
    sec = doc.get_element_by_id("summary")
    assert "No search in this run" in sec.text_content()
    assert "Vehicle: System B" in sec.text_content() and not sec.findall(".//section")


def test_direction_words() -> None:
    assert direction_words(0.0) == "straight ahead"
    assert direction_words(360.0) == "straight ahead"
    assert direction_words(-20.0) == "20° to the right of straight ahead"
    assert direction_words(30.0) == "30° to the left of straight ahead"
    assert direction_words(90.0) == "to the left"
    assert direction_words(-90.0) == "to the right"
    assert direction_words(150.0) == "30° to the left of straight behind"
    assert direction_words(-179.0) == "straight behind"


@pytest.mark.parametrize("heading_deg", [0.0, 37.0, 90.0, 200.0, -45.0])
@pytest.mark.parametrize("azimuth_deg", [0.0, 100.0, 274.0])
def test_sun_direction_is_the_models(heading_deg: float, azimuth_deg: float) -> None:
    """The sun direction named in the summary is the one the sensor models use
    (``Conditions.sun_directions``) for a world-frame (compass) sun and an ego heading."""
    env = load_environments()["clear"].model_copy(
        update={"sun": SunConfig(azimuth_deg=azimuth_deg, elevation_deg=12.0, frame="world")}
    )
    h = math.radians(heading_deg)
    d = Conditions.sun_directions(env, np.array([h]))
    assert d is not None
    want = math.degrees(math.atan2(d[0, 1], d[0, 0]))
    got = sun_azimuth_deg(env, h)
    assert got is not None
    assert (got - want + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-9)


def test_where_and_weather_words() -> None:
    assert where_words(86.9, 0.0) == "87 m ahead"
    assert where_words(190.5, 37.6) == "190 m ahead and 38 m to the left"
    assert where_words(-3.2, -2.0) == "3 m behind and 2 m to the right"
    assert where_words(0.2, 0.3) == "beside the vehicle"
    envs = load_environments()
    assert weather_words(envs["fog_50"]) == "fog with 50 m visibility"
    assert weather_words(envs["rain_25"]) == "rain 25 mm/h"
    assert weather_words(envs["snow"]) == "snowfall 5 mm/h"
    assert weather_words(envs["clear"]) == "clear air"
    assert sun_azimuth_deg(envs["glare_front_right"], None) == -20.0
    assert sun_azimuth_deg(envs["rain_5"], 0.0) is None


def test_pd_without_reads_the_rankings_reason() -> None:
    reason = (
        "weather: at t=2.85 s the target is at x=86.9 y=0.0 m (ego frame), Pd of the "
        "confirming sensors 0.00; P(collision) 1; missing: cam_windshield (weather: "
        "Pd 0.00, 0.87 in clear air), radar_front_center (occlusion: Pd 0.00, 0.92 "
        "without the occluders), cam_main (glare: Pd 0.10, 0.93 without the sun), "
        "cam_narrow (glare: Pd 0.00, 0.94 without the sun, sun 7.9 deg from its line of sight)"
    )
    assert pd_without(reason) == {
        "cam_windshield": 0.87,
        "radar_front_center": 0.92,
        "cam_main": 0.93,
        "cam_narrow": 0.94,
    }


def test_pd_without_reads_a_long_reason_in_one_pass() -> None:
    """A 200,000-character reason without spaces (a hand-edited ranking.json) is read in
    one pass: the sensor id is tried only where an id may start, at most 64 characters
    deep (before, every position of the run was tried and the rest of the run rescanned:
    5 such rows kept `report --run` busy for minutes; now a few milliseconds each,
    benchmark by hand: ``timeit pd_without("x" * 200_000)``)."""
    item = "cam_main (glare: Pd 0.10, 0.93 without the sun)"
    assert pd_without("x" * 200_000) == {}
    assert pd_without("x" * 200_000 + " (glare: Pd 0.10, 0.93 without the sun)") == {}
    assert pd_without("x" * 200_000 + " " + item) == {"cam_main": 0.93}
    assert pd_without("missing: " + ", ".join([item] * 4_000)) == {"cam_main": 0.93}
    assert pd_without("x" * 200_000 + "-" + item) == {}  # no id of 200,009 characters
    assert pd_without("a" * 64 + " (range: Pd 0.00, 0.50 in clear air)") == {"a" * 64: 0.5}


def test_glare_words_give_the_suns_angle_from_each_line_of_sight() -> None:
    """The report says how far from each blinded camera's line of sight the sun stands
    (rounded to a degree), and nothing when an angle is missing."""
    env = load_environments()["glare_front_right"]
    types = {"cam_a": "camera", "cam_b": "camera"}
    two = _low_words(
        "glare", ["cam_a", "cam_b"], 0.0, [0.9, 0.9], "", env, types, {"cam_a": 7.94, "cam_b": 12.5}
    )
    assert two == (
        "the cameras cam_a and cam_b are blinded by the sun 8° and 12° from their lines of "
        "sight (Pd 0.00; 0.90 without the sun)"
    )
    one = _low_words("glare", ["cam_a"], 0.1, [0.9], "", env, types, {"cam_a": 3.2})
    assert "blinded by the sun 3° from its line of sight (Pd 0.10" in one
    none = _low_words("glare", ["cam_a", "cam_b"], 0.0, [0.9, 0.9], "", env, types, {"cam_a": 3.2})
    assert "line" not in none and "blinded by the sun (Pd 0.00" in none
    same = _low_words(
        "glare", ["a", "b", "c"], 0.0, [0.9] * 3, "", env, types, {"a": 3.2, "b": 3.4, "c": 2.6}
    )
    assert "blinded by the sun 3° from their lines of sight" in same
    three = _low_words(
        "glare", ["a", "b", "c"], 0.0, [0.9] * 3, "", env, types, {"a": 3.2, "b": 5.0, "c": 9.0}
    )
    assert "blinded by the sun 3°, 5° and 9° from their lines of sight" in three


def test_blind_areas_by_direction(tmp_path: Path) -> None:
    """Pd < 0.5 cells counted per 45-degree direction from the body's centre, outside the
    body and within the radius (reduced to the map)."""
    system = load_system("system_a")
    body = system.config.vehicle
    cx = 0.5 * (body.x_rear_m + body.x_front_m)
    res = 0.5
    x = np.arange(-60.0, 80.0, res) + res / 2
    y = np.arange(-50.0, 50.0, res) + res / 2
    pd = np.ones((len(y), len(x)), dtype=np.float32)

    def blind(x0: float, y0: float, n: int = 2) -> None:  # n x n cells from (x0, y0)
        i, j = np.searchsorted(x, x0), np.searchsorted(y, y0)
        pd[j : j + n, i : i + n] = 0.2

    blind(cx - 20.0, 10.0)  # behind-left: 1 m2
    blind(cx + 20.0, -0.25, 4)  # ahead: 4 m2
    blind(cx, -8.0)  # right: 1 m2
    blind(cx, 0.0)  # inside the body: not counted
    blind(cx - 55.0, 0.0)  # beyond 50 m: not counted
    np.savez(
        tmp_path / "coverage.npz",
        pd=pd,
        x=x,
        y=y,
        resolution=np.array([res]),
        height=np.array([0.75]),
    )
    r, areas = blind_areas(tmp_path / "coverage.npz", system)
    assert r == 50.0
    assert areas == {
        "ahead": 4.0,
        "ahead-left": 0.0,
        "left": 0.0,
        "behind-left": 1.0,
        "behind": 0.0,
        "behind-right": 0.0,
        "right": 1.0,
        "ahead-right": 0.0,
    }
    # a map reaching 30 m to the side: the circle shrinks to fit it
    keep = np.abs(y) < 30.0
    np.savez(
        tmp_path / "small.npz",
        pd=pd[keep],
        x=x,
        y=y[keep],
        resolution=np.array([res]),
        height=np.array([0.75]),
    )
    r, areas = blind_areas(tmp_path / "small.npz", system)
    assert r == 30.0 and areas["ahead"] == 4.0 and areas["behind-left"] == 1.0


def test_blind_extents_give_the_distance_from_the_body(tmp_path: Path) -> None:
    system = load_system("system_a")
    body = system.config.vehicle
    res = 0.5
    x = np.arange(-60.0, 80.0, res) + res / 2
    y = np.arange(-50.0, 50.0, res) + res / 2
    pd = np.ones((len(y), len(x)), dtype=np.float32)
    # a blind strip straight behind, from 2 m to 10 m behind the rear bumper, |y| < 0.5
    xx, yy = np.meshgrid(x, y)
    strip = (xx <= body.x_rear_m - 2.0) & (xx >= body.x_rear_m - 10.0) & (np.abs(yy) < 0.5)
    pd[strip] = 0.0
    np.savez(tmp_path / "c.npz", pd=pd, x=x, y=y, resolution=np.array([res]))
    _, ext = blind_extents(tmp_path / "c.npz", system)
    area, d0, d1 = ext["behind"]
    assert area == np.count_nonzero(strip) * res * res
    # cell centres: the nearest and farthest of the strip, straight behind the bumper
    assert d0 == pytest.approx(body.x_rear_m - xx[strip].max())
    assert d1 == pytest.approx(body.x_rear_m - xx[strip].min())
    assert 2.0 <= d0 < 2.5 and 9.5 < d1 <= 10.0
    assert ext["ahead"] == (0.0, 0.0, 0.0)


def test_spot_words() -> None:
    system = load_system("system_a")
    body = system.config.vehicle
    hw = 0.5 * body.width_m
    xr = body.x_rear_m
    # beside the left door: 1.0-3.0 m ahead of the rear bumper, 1.5-4.0 m left of the body
    words = spot_words([xr + 1.0, hw + 1.5, xr + 3.0, hw + 4.0], [xr + 2.0, hw + 2.7], system)
    assert words == ("left: 1.0 to 3.0 m ahead of the rear bumper, 1.5 to 4.0 m left of the body")
    # a rear corner spot reaching under the bumper line and into the body's width
    words = spot_words(
        [xr - 0.2, -(hw + 0.5), xr + 1.0, -(hw - 0.1)], [xr - 0.1, -(hw + 0.2)], system
    )
    assert words == (
        "behind-right: from 0.20 m behind to 1.0 m ahead of the rear bumper, "
        "up to 0.50 m right of the body"
    )


def test_mirrored_pairs() -> None:
    items = [
        ("3.34 m²", "left: 1.3 to 3.8 m ahead of the rear bumper, 1.7 to 4.8 m left of the body"),
        ("3.34 m²", "right: 1.3 to 3.8 m ahead of the rear bumper, 1.7 to 4.8 m right of the body"),
        (
            "0.20 m²",
            "behind-left: 0.1 to 0.5 m behind the rear bumper, up to 0.3 m left of the body",
        ),
        (
            "0.21 m²",
            "behind-right: 0.1 to 0.5 m behind the rear bumper, up to 0.3 m right of the body",
        ),
    ]
    assert mirrored_pairs(items) == [
        (
            "3.34 m² each",
            "left and right: 1.3 to 3.8 m ahead of the rear bumper, 1.7 to "
            "4.8 m to the side of the body",
        ),
        items[2],
        items[3],
    ]  # different areas: not merged


def _without_rear_radars(tmp_path: Path) -> Path:
    """A copy of System A's vehicle file without its two rear corner radars."""
    from sensorgap.config.presets import templates_dir

    text = (templates_dir() / "vehicles" / "system_a.toml").read_text(encoding="utf-8")
    blocks = text.split("[[sensors]]")
    kept = [b for b in blocks[1:] if 'id = "radar_rear_' not in b]
    assert len(kept) == len(blocks) - 3
    path = tmp_path / "a_norear.toml"
    path.write_text("[[sensors]]".join([blocks[0], *kept]), encoding="utf-8")
    return path


def test_summary_names_the_rear_blind_wedges_without_rear_radars(tmp_path: Path) -> None:
    # issue #14 done-when: a copy of System A without its rear radars shows its new rear
    # blind wedges, by direction and distance, on the summary page; System A does not
    from sensorgap.analysis.nearfield import write_nearfield
    from sensorgap.config import load_environment, load_target
    from sensorgap.coverage import GridSpec, Scene
    from sensorgap.coverage.outputs import write_coverage

    paras = {}
    for name, vehicle in (("norear", _without_rear_radars(tmp_path)), ("a", "system_a")):
        system = load_system(vehicle)
        folder = tmp_path / name
        scene = Scene(system, load_target("car"), Conditions.from_config(load_environment("clear")))
        write_coverage(
            scene,
            GridSpec(-52.0, 56.0, -50.0, 50.0, 0.5, 0.75),
            folder / "coverage" / "car_clear",
            heading_deg=0.0,
        )
        if name == "norear":
            write_nearfield(system, folder / "nearfield", resolution=0.2)
        sec = summary_section(folder, system, {}, None, None, None, 0)
        paras[name] = next(
            b.text for b in sec.blocks if getattr(b, "text", "").startswith("Blind spots")
        )
        _, ext = blind_extents(folder / "coverage" / "car_clear" / "coverage.npz", system)
        paras[name + "_ext"] = ext  # type: ignore[assignment]
    text, ext = paras["norear"], paras["norear_ext"]
    left, right = ext["behind-left"], ext["behind-right"]  # type: ignore[index]
    for area, d0, d1 in (left, right):
        assert area >= 10.0 and d0 < 1.0 and d1 > 20.0
    # symmetric: one phrase for both wedges
    assert left == right
    area, d0, d1 = left
    assert (
        f"{round(area):,} m² each behind-left and behind-right ({d0:.2f} to {d1:.1f} m "
        "from the body)"
    ) in text
    assert all(ext_a[0] < 1.0 for ext_a in paras["a_ext"].values())  # type: ignore[union-attr]
    assert "behind-left (" not in paras["a"]
    # the near field by direction, from nearfield.json's exact holes
    near = json.loads((tmp_path / "norear" / "nearfield" / "nearfield.json").read_text())
    big = [h for h in near["blind_spot_m2"]["holes"] if h["area_m2"] >= 0.01]
    assert len(big) == 4
    for h in big:
        assert f"{h['area_m2']:.2f} m² each " in text
    assert " m² each left and right: " in text
    assert " m² each behind-left and behind-right: " in text


def test_summary_says_what_no_sensor_sees_beyond_the_enclosed_blind_spots(
    tmp_path: Path,
) -> None:
    # a vehicle looking forward only has no *enclosed* blind spot (the paper's measure);
    # the summary must not read "0.00 m2 seen by no sensor" with everything behind unseen
    from sensorgap.analysis.nearfield import write_nearfield
    from sensorgap.config.presets import templates_dir

    text = (templates_dir() / "vehicles" / "system_a.toml").read_text(encoding="utf-8")
    blocks = text.split("[[sensors]]")
    kept = [b for b in blocks[1:] if 'id = "cam_windshield"' in b or 'id = "lidar' in b]
    path = tmp_path / "front_only.toml"
    path.write_text("[[sensors]]".join([blocks[0], *kept]), encoding="utf-8")
    system = load_system(path)
    write_nearfield(system, tmp_path / "nearfield", resolution=0.2, dphi_deg=0.5)
    near = json.loads((tmp_path / "nearfield" / "nearfield.json").read_text())
    unseen = near["unseen_any_height_m2"]
    assert unseen["exact"] > 50.0 and unseen["open_to_outside"] > 50.0
    sec = summary_section(tmp_path, system, {}, None, None, None, 0)
    para = next(b.text for b in sec.blocks if getattr(b, "text", "").startswith("Blind spots"))
    assert (
        f"near field: {unseen['exact']:.2f} m² within 5 m of the body seen by no sensor at "
        f"any height, {unseen['exact'] - near['blind_spot_m2']['exact']:.2f} m² of it open "
        f"to the outside (no sensor looks there) and "
        f"{near['blind_spot_m2']['exact']:.2f} m² enclosed blind spots"
    ) in para


def test_summary_names_the_blind_spots(job: Path) -> None:
    doc = _doc(job / "report.html")
    text = " ".join(doc.get_element_by_id("summary").text_content().split())
    near = json.loads((job / "nearfield" / "nearfield.json").read_text())
    assert f"near field: {near['blind_spot_m2']['exact']:.2f} m² within 5 m" in text
    _, areas = blind_areas(job / "coverage" / "car_clear" / "coverage.npz", load_system("system_a"))
    assert (
        f"within 50 m of the vehicle a car (heading the same way; clear, "
        f"coverage/car_clear) is detected with Pd < 0.5 over "
        f"{sum(areas.values()):,.0f} m² outside the body"
    ) in text


def test_unreadable_coverage_map_is_one_line_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "run.json").write_text(json.dumps({"vehicle": "system_a"}))
    npz = tmp_path / "coverage" / "car_clear" / "coverage.npz"
    npz.parent.mkdir(parents=True)
    npz.write_bytes(b"PK\x03\x04 not a zip")
    assert main(["report", "--run", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "coverage.npz" in err and len(err.splitlines()) == 1
