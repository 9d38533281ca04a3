"""Navabi & Davoodi reproduction: the paper setup's numbers (the sanity targets of an
independent prototype of the paper's set-up), the
paper's qualitative claims where our reconstruction supports them, and the output files.

The full-plant (env) half of the reproduction takes ≈ 1–2 min and is not run here:
``python train.py reproduce fuel-slosh --out DIR``.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from experiments.reproductions import fuel_slosh
from experiments.reproductions.fuel_slosh_runs import metrics


@pytest.fixture(scope="module")
def runs():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fuel_slosh.run_paper_setup()


def _at(tr, t_s: float, row: int) -> float:
    return float(tr.x[row, np.searchsorted(tr.t, t_s)])


def test_pd_matches_the_reconstructed_reference_trajectory(runs):
    """An independent prototype's set-up: PD on the linear reduced model."""
    pd = runs["pd"]
    np.testing.assert_allclose([_at(pd, t, 0) for t in (250, 500, 1000)], [-31.1, -28.1, 7.7], atol=0.1)
    np.testing.assert_allclose(
        [math.degrees(_at(pd, t, 1)) for t in (250, 500, 1000)], [0.414, -0.458, 0.104], atol=2e-3
    )
    m = metrics(pd)
    assert m["min v_z (m/s)"] == pytest.approx(-44.3, abs=0.1)
    assert m["settling psi1 (s)"] == pytest.approx(1435, abs=2)


def test_other_controllers_match_the_reconstructed_reference_numbers(runs):
    lqr, lyap, fuzzy = (metrics(runs[n]) for n in ("lqr-paper", "lyapunov", "fuzzy"))
    assert lqr["settling v_z (s)"] == pytest.approx(8, abs=1)
    assert lqr["settling psi1 (s)"] == pytest.approx(383, abs=2)
    assert lqr["peak abs u1 (m/s^2)"] == pytest.approx(106, abs=1)
    assert math.degrees(_at(runs["lqr-paper"], 1000, 1)) == pytest.approx(0.66, abs=0.01)
    assert lyap["settling v_z (s)"] == pytest.approx(556, abs=2)
    assert lyap["settling theta (s)"] == pytest.approx(270, abs=2)
    assert lyap["min v_z (m/s)"] == pytest.approx(-24.6, abs=0.1)
    # fuzzy: our scikit-fuzzy build vs an independent prototype (both with the same defaults; the
    # prototype's inference details are not given): v_z 1312 s there
    assert fuzzy["settling theta (s)"] == pytest.approx(999, abs=5)
    assert fuzzy["settling psi1 (s)"] == pytest.approx(833, abs=5)
    assert fuzzy["settling v_z (s)"] == pytest.approx(1312, abs=50)


def test_paper_claims_on_paper_setup(runs):
    cl = fuel_slosh.claims({n: metrics(t) for n, t in runs.items()})
    holds = {k for k, v in cl.items() if v}
    assert holds == {
        "PD and fuzzy: slosh settles (0.5 deg) between 700 and 1500 s",
        "LQR (paper weights) faster than PD in v_z and psi",
        "LQR (paper weights) uses larger inputs than PD",
        "LQR (feasible weights) faster than PD in v_z, theta and psi",
        "Lyapunov faster than fuzzy in v_z, theta and psi",
        "PD and fuzzy slower than LQR (paper) and Lyapunov (v_z and psi settling)",
    }
    # what our reconstruction does NOT support (reported in the notes): PD leaves
    # v_z ≈ 7.7 m/s at 1000 s, and the paper-weight LQR leaves θ ≈ 0.6° at 1500 s
    assert not cl["LQR (paper weights) faster than PD in theta"]


def test_lyapunov_rate_nonpositive_and_lqr_minimizes_cost(runs):
    assert np.max(runs["lyapunov"].extra["Vdot"]) <= 0.0  # paper Fig. 20
    costs = {n: tr.cost for n, tr in runs.items()}
    assert min(costs, key=costs.get) == "lqr-paper"  # the LQR is optimal for this very cost


def test_reproduce_quick_writes_schema_and_plots(runs, tmp_path, monkeypatch):
    monkeypatch.setattr(fuel_slosh, "run_paper_setup", lambda: runs)
    rows = fuel_slosh.reproduce(tmp_path, quick=True)
    doc = json.loads((tmp_path / "fuel-slosh.json").read_text())
    assert doc["paper"] == "fuel-slosh" and doc["source"].startswith("Navabi, M. and Davoodi, A.")
    assert len(doc["rows"]) == len(rows) == 5 * 11 + 1
    assert {r["controller"] for r in doc["rows"]} == {"pd", "lqr-paper", "lqr-feasible", "fuzzy", "lyapunov"}
    assert all(r["paper"] is None for r in doc["rows"])  # the paper prints no numbers
    assert "HOLDS: Lyapunov faster than fuzzy" in doc["notes"]
    for name in ("fuel-slosh.md", "fuel-slosh-paper-setup.png", "fuel-slosh-lyapunov-V.png"):
        assert (tmp_path / name).stat().st_size > 1000
