"""The feedback-linearization reproduction: EULERINT vs Table 2, ranking, wheel-speed limit, output files."""

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from baselines.feedback_linearization import outer_loop_gain
from experiments.reproductions import REPRODUCTIONS
from experiments.reproductions.feedback_linearization import (
    MANEUVERS,
    TABLE_2,
    reproduce,
    run_maneuvers,
)


@pytest.fixture(scope="module")
def episodes():
    ev = run_maneuvers()
    return {(r["scenario"], r["controller"]): r for r in ev.rows}


def test_eulerint_matches_table_2(episodes):
    errors = {key: abs(r["eulerint_deg_s"] / TABLE_2[key][3] - 1.0) for key, r in episodes.items()}
    assert len(errors) == 12
    assert sum(e <= 0.05 for e in errors.values()) >= 10, errors
    assert max(errors.values()) <= 0.10, errors
    # maneuver 4 is the known outlier (see the reproduction notes): high for both controllers
    assert all(
        episodes[("maneuver-4", c)]["eulerint_deg_s"] > TABLE_2[("maneuver-4", c)][3]
        for c in ("feedback-linearization", "quaternion-lqr")
    )


def test_flc_beats_lqr_on_eulerint_in_every_maneuver(episodes):
    for case in MANEUVERS:
        assert (
            episodes[(case, "feedback-linearization")]["eulerint_deg_s"]
            < episodes[(case, "quaternion-lqr")]["eulerint_deg_s"]
        )


def test_flc_eulerint_depends_on_the_initial_angle_only(episodes):
    """From rest at identity the FLC maneuver is an eigen-axis rotation with
    α(t) = α0 − 2 asin((1 − φ(t)) sin(α0/2)) (the designed double integrator's closed form), whatever the axis and inertia."""
    K = outer_loop_gain()
    k1, k2 = K[0, 0], K[0, 3]
    t = np.linspace(0.0, 60.0, 6001)
    phi = solve_ivp(
        lambda t, y: [y[1], -k1 * y[0] - k2 * y[1]], (0, 60), [1.0, 0.0], t_eval=t, rtol=1e-11, atol=1e-13
    ).y[0]
    for case in MANEUVERS:
        row = episodes[(case, "feedback-linearization")]
        a0 = np.radians(row["initial_error_deg"])
        alpha = np.degrees(np.abs(a0 - 2 * np.arcsin((1 - phi) * np.sin(a0 / 2))))
        closed_form = float(np.sum(0.5 * (alpha[1:] + alpha[:-1]) * np.diff(t)))
        assert row["eulerint_deg_s"] == pytest.approx(closed_form, rel=2e-3), case


def test_wheel_speed_design_limit_violation_is_reported(episodes):
    flagged = {key for key, r in episodes.items() if r["wheel_speed_violation"]}
    assert flagged == {("maneuver-3", "feedback-linearization")}  # an independent re-simulation: ≈ 5430 rpm
    assert episodes[("maneuver-3", "feedback-linearization")]["peak_wheel_speed_rpm"] > 5400
    # maneuver 1: "approximately 3000 rpm for both methods" (paper §4.4)
    for c in ("feedback-linearization", "quaternion-lqr"):
        assert episodes[("maneuver-1", c)]["peak_wheel_speed_rpm"] == pytest.approx(3000, rel=0.1)


def test_torque_limit_never_reached(episodes):
    assert all(r["saturation_fraction"] == 0.0 and not r["terminated"] for r in episodes.values())


def test_reproduce_command_writes_the_shared_schema(tmp_path):
    assert "feedback-linearization" in REPRODUCTIONS
    rows = reproduce(tmp_path, quick=True)
    doc = json.loads((tmp_path / "feedback-linearization.json").read_text())
    assert set(doc) == {"paper", "source", "rows", "notes"}
    assert doc["paper"] == "feedback-linearization" and "Modares Mechanical Engineering" in doc["source"]
    assert len(doc["rows"]) == len(rows)
    assert set(doc["rows"][0]) == {"case", "controller", "metric", "paper", "ours", "tolerance"}
    metrics = {r["metric"] for r in doc["rows"]}
    assert {"eulerint_deg_s", "power_sum_w", "effort_sum_nm", "energy_sum_nm2"} <= metrics
    for r in doc["rows"]:
        if r["metric"] in ("power_sum_w", "effort_sum_nm", "energy_sum_nm2"):
            assert r["paper"] is not None and r["tolerance"] is None  # solver artefacts: no claim
        if r["metric"] == "eulerint_deg_s":
            assert abs(r["ours"] / r["paper"] - 1) <= r["tolerance"]
    assert "solver" in doc["notes"] and "Maneuver 4" in doc["notes"] and "Wheel-speed limit" in doc["notes"]
    assert (
        "| maneuver-1 | feedback-linearization | eulerint_deg_s | 458.63 |"
        in (tmp_path / "feedback-linearization.md").read_text()
    )
    for name in ("maneuver-1", "maneuver-1-error", "cost", "eulerint"):
        assert (tmp_path / f"feedback-linearization-{name}.png").stat().st_size > 10_000
    assert (tmp_path / "feedback-linearization-episodes.csv").read_text().count("\n") == 3
