"""``simulate --ego-reaction`` (issue #15 item 3): the braking as speed actions, the
prediction from the outcome kernel, and esmini runs of both styles (skipped without
esmini)."""

from __future__ import annotations

import csv
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from sensorgap.cli import main
from sensorgap.export.brake import brake_steps
from sensorgap.export.reaction import (
    MAX_IMPACT_DIFF_KMH,
    QUANTILES,
    confirmation_steps,
    planned_batch,
    predict,
    run_reaction,
)
from sensorgap.export.spec import ScenarioSpec, read_run
from sensorgap.models import load_system
from sensorgap.search.evaluate import Evaluator
from sensorgap.search.outcome import braked_speed, lost_distance
from tests.export.conftest import ESMINI, needs_esmini


@pytest.mark.parametrize(("v0", "decel"), [(25.0, 8.8), (3.0, 8.8), (20.0, 1.96)])
def test_brake_steps_follow_the_jerk_ramp(v0: float, decel: float) -> None:
    """Integrating the speed actions (linear at their rates) gives the model's speed at
    every step end and its braking distance (within 1 cm)."""
    jerk, dt, t_b = 12.0, 0.05, 2.0
    steps = brake_steps(t_b, v0, jerk, decel, dt, factor=1.0)
    assert steps[0].start_s == t_b and steps[-1].speed_m_s == 0.0
    assert all(b.start_s > a.start_s for a, b in zip(steps, steps[1:], strict=False))
    h = 1e-4  # integrate the piecewise-linear speed finely
    t, v, x = t_b, v0, 0.0
    i = 0
    while v > 0.0:
        while i + 1 < len(steps) and t >= steps[i + 1].start_s - 1e-12:
            i += 1
        st = steps[i]
        v_new = max(v - st.rate_m_s2 * h, st.speed_m_s)
        x += 0.5 * (v + v_new) * h
        v, t = v_new, t + h
        if abs((t - t_b) / dt - round((t - t_b) / dt)) < 1e-6 and t - t_b < 5.0:
            tau = round((t - t_b) / dt) * dt
            assert v == pytest.approx(braked_speed(tau, v0, jerk, decel), abs=1e-3)
    big = 60.0
    assert x == pytest.approx(v0 * big - lost_distance(big, v0, jerk, decel), abs=0.01)
    # the lane-speed factor scales speeds and rates
    scaled = brake_steps(t_b, v0, jerk, decel, dt, factor=1.01)
    assert [s.rate_m_s2 for s in scaled] == pytest.approx([1.01 * s.rate_m_s2 for s in steps])


def test_prediction_is_the_kernels(maneuver_catalog: Path) -> None:
    """Confirmation at step M - 1 is perfect perception: the kernel's collision_perfect
    and its impact speed; confirmation at or after the open-loop collision collides
    there at the open-loop speed; the median step is the ranking's t_confirm_median_s."""
    run = read_run(maneuver_catalog)
    system = load_system(run.vehicle_ref)
    ev = Evaluator(system, "exact")
    checked = 0
    for row in run.rows:
        spec = ScenarioSpec.from_row(row, system)
        bt = planned_batch(spec, ev)
        enc = bt.encounter
        assert enc is not None
        kc = int(enc.collide_step[0])
        out = bt.outcome_row(0)
        if kc < 0 or not math.isfinite(out["t_confirm_median_s"]):
            continue
        m = ev.reaction.confirm_m
        perfect = predict(bt, ev, m - 1)
        assert (perfect.collision_s is not None) == (out["collision_perfect"] == 1.0)
        if perfect.impact_kmh is not None:
            assert perfect.impact_kmh == pytest.approx(out["impact_speed_perfect_kmh"])
        late = predict(bt, ev, kc)
        assert late.collision_s == pytest.approx(kc * enc.dt)
        steps = confirmation_steps(bt, ev)
        assert steps["median"] is not None
        assert steps["median"] * enc.dt == pytest.approx(row["t_confirm_median_s"])
        assert steps["p90"] is None or steps["p90"] >= steps["median"]
        checked += 1
    assert checked >= 1


def _reaction_rows(catalog: Path, tmp_path: Path) -> list[dict[str, str]]:
    work = tmp_path / catalog.name
    shutil.copytree(catalog, work)
    assert (
        main(["simulate", "--catalog", str(work), "--esmini", str(ESMINI), "--ego-reaction"]) == 0
    )
    return list(
        csv.DictReader(
            (work / "simulation.csv").read_text(encoding="utf-8").splitlines(keepends=True)
        )
    )


#: How closely esmini's entities follow the plan (simulate's 'within 0.5 m of the plan').
PLAN_TOL_M = 0.5


def _predicted_clearance(cat: Path, row: dict[str, str], q: str, t_s: float) -> float:
    """The reaction model's gap (m) between the braking ego's front and the target at
    time ``t_s`` for the row's confirmation quantile ``q`` (positive: short of contact)."""
    from sensorgap.export.reaction import clearance_m
    from sensorgap.export.spec import specs_of_run

    run = read_run(cat)
    ev = run.evaluator("exact")
    spec = next(s for s in specs_of_run(run) if s.scenario_id == row["scenario_id"])
    bt = planned_batch(spec, ev)
    k = confirmation_steps(bt, ev)[q]
    assert k is not None
    return clearance_m(bt, ev, predict(bt, ev, k), t_s)


@needs_esmini
def test_esmini_reaction_runs_agree_with_the_prediction(
    catalog: Path, maneuver_catalog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Both styles of the small run, every reaction run (median and 90th-percentile
    confirmation): esmini collides exactly when the prediction does, within one step of
    the predicted time. Replay: impact speeds within 2 km/h. Maneuver: within 2 km/h, or,
    where esmini's contact falls one step earlier or later, within 2 km/h plus the speed
    the braking ego changes in one step (3.6 A dt: 1.6 km/h at 8.8 m/s2; measured: one
    such run, 2.4 km/h, docs/export.md)."""
    runs = 0
    for cat in (catalog, maneuver_catalog):
        rows = _reaction_rows(cat, tmp_path)
        for r in rows:
            for q in QUANTILES:
                if r[f"react_{q}_agrees"] == "":
                    continue
                runs += 1
                assert r[f"react_{q}_within_plan"] == "yes", (
                    q,
                    r["style"],
                    r["reaction_decel_m_s2"],
                    *(
                        r[f"react_{q}_{c}"]
                        for c in (
                            "collision_predicted_s",
                            "collision_esmini_s",
                            "impact_predicted_kmh",
                            "impact_esmini_kmh",
                        )
                    ),
                )
                pred, sim = (r[f"react_{q}_collision_{w}_s"] for w in ("predicted", "esmini"))
                if pred == "" and sim != "":
                    # a near miss in the plan that esmini's ego, following the plan to
                    # within 0.5 m (the export's check), turns into a touch: allowed
                    # only within that tolerance (measured: one run, 0.14 m short at
                    # the scenario's last step, contact at 10.0 s)
                    assert _predicted_clearance(cat, r, q, float(sim)) <= PLAN_TOL_M, (q, r)
                    continue
                assert (pred == "") == (sim == ""), (q, r)
                if pred == "":
                    continue
                dt = abs(float(pred) - float(sim))
                assert dt <= 0.05 + 1e-9, (q, r)
                dv = abs(
                    float(r[f"react_{q}_impact_predicted_kmh"])
                    - float(r[f"react_{q}_impact_esmini_kmh"])
                )
                if r["style"] == "replay" or dt < 1e-9:
                    assert dv <= MAX_IMPACT_DIFF_KMH, (q, r)
                    assert r[f"react_{q}_agrees"] == "yes", (q, r)
                else:
                    assert (
                        dv <= MAX_IMPACT_DIFF_KMH + 3.6 * float(r["reaction_decel_m_s2"]) * 0.05
                    ), (q, r)
        assert "ego reaction" in capsys.readouterr().out
    assert runs >= 4


@needs_esmini
def test_esmini_reaction_avoids_when_predicted(encounter_run: Path, tmp_path: Path) -> None:
    """Confirmation steps from perfect perception to the open-loop collision (every
    0.5 s) on the encounter run's maneuver catalog: the predicted collisions and the
    predicted avoidances both occur and >= 95 % of the runs agree with esmini."""
    from sensorgap.export import export_catalog

    cat = tmp_path / "encounters"
    export_catalog(encounter_run, cat, coverage=False)
    index = json.loads((cat / "catalog.json").read_text())
    run = read_run(cat)
    system = load_system(run.vehicle_ref)
    ev = Evaluator(system, "exact")
    by_id = {r["scenario_id"]: r for r in run.rows}
    results = []
    for entry in index["scenarios"]:
        spec = ScenarioSpec.from_row(by_id[entry["scenario_id"]], system)
        bt = planned_batch(spec, ev)
        enc = bt.encounter
        assert enc is not None
        kc, kt = int(enc.collide_step[0]), int(enc.threat_step[0])
        if kc < 0 or kt < 0:
            continue
        for k in range(ev.reaction.confirm_m - 1, kc + 1, 10):
            results.append(
                run_reaction(
                    spec, ev, bt, k, ESMINI, "maneuver", "1.2", cat / entry["road"], 60.0, 0.05
                )
            )
    assert all(not r.error for r in results)
    predicted = [r.prediction.collision_s is not None for r in results]
    assert any(predicted) and not all(predicted)
    agree = np.mean([r.agrees for r in results])
    assert agree >= 0.95, agree


def test_within_plan_by_hand() -> None:
    """|v_p^2 - v_e^2| <= 2 a d with d = 0.5 m, on a stub encounter braking at 5.884 m/s2
    (5.884 m2/s2): 12.88 vs 9.91 km/h: 12.80 - 7.58 = 5.22 (within); 20 vs 9.91: 30.86 -
    7.58 = 23.3 (not); a predicted 7.19 km/h impact that esmini avoids: 3.99 (within); 12
    km/h vs none: 11.1 (not); none vs none: 0; the edge 2 a d exactly, then just beyond."""
    from types import SimpleNamespace

    from sensorgap.export.reaction import Prediction, within_plan

    def case(a: float, vp: float | None, ve: float | None) -> bool:
        bt = SimpleNamespace(decel_m_s2=np.array([a]))
        pred = Prediction(0, 0.0, 0.3, None if vp is None else 5.0, vp)
        return within_plan(
            bt,
            None,
            pred,
            None if ve is None else 5.0,  # type: ignore[arg-type]
            ve,
        )

    assert case(5.884, 12.88, 9.91)
    assert not case(5.884, 20.0, 9.91)
    assert case(5.884, 7.19, None)
    assert not case(5.884, 12.0, None)
    assert case(5.884, None, None)
    a, ve = 8.826, 3.0
    vp = (ve * ve + 2.0 * a * 0.5) ** 0.5
    assert case(a, vp * 3.6, ve * 3.6)
    assert not case(a, vp * 3.6 * 1.001, ve * 3.6)


def test_a_contact_in_esminis_step_past_the_end_counts_only_against_a_predicted_one() -> None:
    """System C's rank 3 (cut_out_reveal, rain_25, 90th-percentile confirmation): contact
    predicted at 9.95 s of a 10 s run, esmini's at 10.05 s (its last step, past the end) at
    18.2 vs 20.1 km/h: compared (it had been dropped, a disagreement). Without a predicted
    contact, esmini's contact past the end is not compared; within the run it always is."""
    from sensorgap.export.reaction import Prediction, compared_contact

    hit = Prediction(98, 4.9, 5.2, 9.95, 20.08)
    miss = Prediction(98, 4.9, 5.2, None, None)
    assert compared_contact(10.05, 10.0, hit) == 10.05
    assert compared_contact(10.05, 10.0, miss) is None
    assert compared_contact(10.0, 10.0, miss) == 10.0
    assert compared_contact(None, 10.0, hit) is None
