"""Driving within sight (search/speedlimit.py): the ego speed a family may use in an
environment, checked against closed-form answers computed here independently."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sensorgap.config import load_environments
from sensorgap.config.reaction import load_friction, load_reaction
from sensorgap.models import load_system
from sensorgap.models.conditions import Conditions
from sensorgap.scenarios import load_family
from sensorgap.search.evaluate import Evaluator
from sensorgap.search.problem import EGO_SPEED, SearchProblem
from sensorgap.search.speedlimit import FOG_RULE_SPEED_M_S, sight_speed_m_s, speed_limit

ENVS = load_environments()
G = 9.80665


def _closed_form_sight_speed(vis: float, latency: float, jerk: float, a: float) -> float:
    """Positive root of the stopping distance = vis, written out by hand: latency, then a
    brake ramp of t1 = a / jerk (distance v t1 - jerk t1^3 / 6, speed lost a t1 / 2), then
    constant deceleration a: d(v) = v (latency + t1) - jerk t1^3 / 6 + (v - a t1 / 2)^2 / 2a.
    As v^2 + p v + q = 0 (valid while v > a t1 / 2, i.e. the car is still moving after the
    ramp)."""
    t1 = a / jerk
    c = a * t1 / 2.0
    k = jerk * t1**3 / 6.0
    p = 2.0 * a * (latency + t1) - 2.0 * c
    q = c * c - 2.0 * a * k - 2.0 * a * vis
    return (-p + math.sqrt(p * p - 4.0 * q)) / 2.0


@pytest.mark.parametrize(
    "vis,latency,jerk,a",
    [(50.0, 0.3, 12.0, 0.9 * G), (328.8, 0.3, 12.0, 0.2 * G), (120.0, 1.0, 8.0, 0.6 * G)],
)
def test_sight_speed_is_the_closed_form_stopping_answer(
    vis: float, latency: float, jerk: float, a: float
) -> None:
    """Bisection on the outcome's stopping model equals the hand-solved quadratic (1e-5
    m/s: the bisection stops at 1e-6)."""
    got = sight_speed_m_s(vis, latency, jerk, a)
    assert got == pytest.approx(_closed_form_sight_speed(vis, latency, jerk, a), abs=1e-5)


def test_visibility_adds_rain_and_snow_extinction() -> None:
    """Meteorological visibility (Koschmieder 2 %, 550 nm): the preset's visibility when
    dry; with snow, 3.912 / (beta_haze + beta_snow), beta_snow from ITU-R P.1817-1 dry snow
    at 550 nm written out here."""
    assert Conditions.from_config(ENVS["fog_50"]).meteorological_visibility_m() == 50.0
    assert Conditions.from_config(ENVS["clear"]).meteorological_visibility_m() == 23000.0
    snow = ENVS["snow"]
    gamma = (5.42e-5 * 550.0 + 5.4958776) * snow.snow_mm_h**1.38  # dB/km
    beta = gamma * math.log(10) / 10 + 3.912 / (snow.visibility_m / 1000)  # 1/km
    want = 1000 * 3.912 / beta
    assert Conditions.from_config(snow).meteorological_visibility_m() == pytest.approx(
        want, abs=0.06
    )
    assert want < 400  # heavy snow really limits sight


def test_the_fifty_kmh_rule_below_fifty_metres() -> None:
    """StVO 3(1): at 30 m fog the bound is 50 km/h (the sight rule alone would allow
    more), at 50 m the sight rule binds (not 'below 50 m'), in clear weather nothing."""
    react, fr = load_reaction("ads_default"), load_friction()
    fog30 = ENVS["fog_50"].model_copy(update={"visibility_m": 30.0})
    lim = speed_limit(fog30, react, fr)
    assert lim.speed_m_s == FOG_RULE_SPEED_M_S
    assert (
        sight_speed_m_s(
            30.0, react.latency_s, react.jerk_m_s3, min(react.decel_max_m_s2, fr["dry"] * G)
        )
        > FOG_RULE_SPEED_M_S
    )
    lim50 = speed_limit(ENVS["fog_50"], react, fr)
    assert lim50.speed_m_s == pytest.approx(
        _closed_form_sight_speed(
            50.0, react.latency_s, react.jerk_m_s3, min(react.decel_max_m_s2, fr["dry"] * G)
        ),
        abs=1e-5,
    )
    assert "within sight" in lim50.rule
    assert math.isinf(speed_limit(ENVS["clear"], react, fr).speed_m_s)


def test_search_never_drives_above_the_lawful_speed() -> None:
    """Decoded candidates in 50 m fog stay at or below the bound (the whole unit interval
    maps into [low, bound]); in clear weather the family's full range is used; a given
    speed above the bound is an infeasible row whose note names the rule."""
    prob = SearchProblem(
        load_family("cut_in_right"),
        {"clear": ENVS["clear"], "fog_50": ENVS["fog_50"]},
        Evaluator(load_system("system_a"), "lookup"),
    )
    bound = prob.speed_limits["fog_50"].speed_m_s
    assert 15.0 < bound < 36.0
    u = np.random.default_rng(3).random((4000, prob.dim))
    d = prob.decode_batch(u)
    v = np.asarray(d.params[EGO_SPEED], dtype=float)
    fog = d.env_names == "fog_50"
    assert v[fog].max() <= bound and v[fog].max() > bound - 0.1
    assert v[~fog].max() > 35.9
    one = prob.decode(u[np.flatnonzero(fog)[0]])
    assert one.params[EGO_SPEED] == v[np.flatnonzero(fog)[0]]
    cand = prob.candidates(d.take(np.flatnonzero(fog)[:1]))[0]
    cand.params[EGO_SPEED] = 30.0
    res = prob.evaluate(cand)
    assert not res.feasible
    assert "lawful speed in fog_50" in res.note and "within sight" in res.note


def test_search_never_drives_above_the_vehicles_top_speed(tmp_path: Path) -> None:
    """A vehicle whose top speed (``vehicle.max_speed_m_s``) lies inside the family's ego
    speeds: the search's ego speeds stop at it in every environment (an ego asked to drive
    faster would not play as planned in esmini), and a given speed above it is an
    infeasible row naming the top speed. System A's 250 km/h binds nowhere."""
    from sensorgap.config.presets import templates_dir

    text = (templates_dir() / "vehicles" / "system_a.toml").read_text(encoding="utf-8")
    path = tmp_path / "slow.toml"
    path.write_text(text.replace("max_speed_m_s = 69.4", "max_speed_m_s = 20.0"), "utf-8")
    prob = SearchProblem(
        load_family("cut_in_right"),
        {"clear": ENVS["clear"], "fog_50": ENVS["fog_50"]},
        Evaluator(load_system(path), "lookup"),
    )
    assert prob.speed_limits["clear"].speed_m_s == 20.0
    assert "top speed 72 km/h" in prob.speed_limits["clear"].rule
    d = prob.decode_batch(np.random.default_rng(4).random((2000, prob.dim)))
    v = np.asarray(d.params[EGO_SPEED], dtype=float)
    assert v.max() <= 20.0 and v.max() > 19.9
    cand = prob.candidates(d.take(np.arange(1)))[0]
    cand.params[EGO_SPEED] = 30.0
    res = prob.evaluate(cand)
    assert not res.feasible and "top speed 72 km/h" in res.note
    preset = SearchProblem(
        load_family("cut_in_right"), {"clear": ENVS["clear"]}, Evaluator(load_system("system_a"))
    )
    assert math.isinf(preset.speed_limits["clear"].speed_m_s)  # the lawful bound, unchanged


FOG49 = """
[environments.fog49]
description = "fog, 49 m visibility"
visibility_m = 49.0
irradiance_w_m2 = 53.0
roc_shift_db = 3.0
[environments.fog49.sources]
visibility_m = "estimate: test"
irradiance_w_m2 = "estimate: test"
roc_shift_db = "estimate: test"
"""


def test_infeasibility_notes_count_by_kind() -> None:
    """Notes of one cause count together (the candidate's own numbers left out, the lawful
    speed rule kept whole), the most frequent first, at most ``MAX_INFEASIBLE_KINDS``
    kinds and ``other``."""
    from sensorgap.search.possible import (
        MAX_INFEASIBLE_KINDS,
        infeasible_kind,
        infeasible_reasons,
        no_feasible_note,
    )

    rule = "fog49: StVO 3(1): visibility 49 m, below 50 m at most 50 km/h"
    assert infeasible_kind(f"ego speed 54 km/h above the lawful speed in {rule}") == (
        f"ego speed above the lawful speed in {rule}"
    )
    assert infeasible_kind("starts critical: TTC 3.25 s at t = 0 (at least 4 s)") == (
        "starts critical: TTC # s at t = # (at least # s)"
    )
    assert infeasible_kind("ego leaves road r_1 (s from -3.1 to 90.0 m, road is 0..500 m)") == (
        "ego leaves road r_1 (s from # to # m, road is #..# m)"
    )
    notes = [f"ego speed {v} km/h above the lawful speed in {rule}" for v in (54, 60, 70)]
    notes += ["starts critical: TTC 1.00 s at t = 0 (at least 4 s)"] * 2
    notes += [f"kind {chr(97 + i)}" for i in range(MAX_INFEASIBLE_KINDS + 2)]
    reasons = infeasible_reasons(notes)
    assert list(reasons.items())[:2] == [
        (f"ego speed above the lawful speed in {rule}", 3),
        ("starts critical: TTC # s at t = # (at least # s)", 2),
    ]
    assert len(reasons) == MAX_INFEASIBLE_KINDS + 1 and reasons["other"] == 4
    assert infeasible_reasons([]) == {}
    assert no_feasible_note(3, {"x": 3}).startswith(
        "no feasible candidate: every one of the 3 candidates was infeasible (3 x); nothing "
        "could be ranked, which says nothing about the sensors"
    )


def test_a_search_without_a_lawful_encounter_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """At 49 m visibility the 50 km/h rule bounds the ego below every speed of
    slow_ahead_curve: every candidate is infeasible. The search exits 0 (a valid question
    whose answer is "no lawful encounter"), but says so in its printed line, summary.json
    and the report's summary, instead of "0 ranked, best collision probability 0" (which
    read as safe)."""
    import json

    from sensorgap.cli import main

    envs = tmp_path / "envs.toml"
    envs.write_text(FOG49, encoding="utf-8")
    out = tmp_path / "s"
    args = ["search", "--vehicle", "system_b", "--environments-file", str(envs)]
    args += ["--environments", "fog49", "--families", "slow_ahead_curve", "--budget", "40"]
    assert main([*args, "--top", "2", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    kind = (
        "ego speed above the lawful speed in fog49: StVO 3(1): visibility 49 m, below 50 m "
        "at most 50 km/h"
    )
    note = (
        f"no feasible candidate: every one of the 40 candidates was infeasible (40 {kind}); "
        "nothing could be ranked, which says nothing about the sensors"
    )
    assert f"0 ranked (0 sensor-critical); {note}" in printed
    assert "best collision probability" not in printed
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["feasible"] == 0 and summary["infeasible_reasons"] == {kind: 40}
    assert summary["note"].startswith(note)
    assert main(["report", "--run", str(out)]) == 0
    md = (out / "report.md").read_text(encoding="utf-8")
    assert f"Found: N{note[1:]}" in md
    assert "sensor-critical scenarios ranked" not in md
    assert main(["verify", str(out)]) == 0
