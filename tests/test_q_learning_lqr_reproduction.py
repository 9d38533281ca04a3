"""``train.py reproduce q-learning-lqr --quick``: Heravi & Novinzadeh 2017's numbers within their tolerances."""

from __future__ import annotations

import json

from experiments import cli


def test_reproduce_q_learning_lqr_quick(tmp_path, capsys):
    assert cli.main(["reproduce", "q-learning-lqr", "--out", str(tmp_path), "--quick"]) == 0
    doc = json.loads((tmp_path / "q-learning-lqr.json").read_text())
    assert (tmp_path / "q-learning-lqr.md").exists()
    assert (tmp_path / "q-learning-lqr-convergence.png").stat().st_size > 10_000
    assert (tmp_path / "q-learning-lqr-trajectories.png").stat().st_size > 10_000
    rows = doc["rows"]
    checked = [r for r in rows if r["paper"] is not None and r["tolerance"] is not None]
    assert len(checked) >= 7
    for r in checked:
        assert abs(r["ours"] - r["paper"]) <= r["tolerance"] * abs(r["paper"]), r

    def ours(metric: str, controller_prefix: str) -> float:
        return next(r["ours"] for r in rows if r["metric"] == metric and r["controller"].startswith(controller_prefix))

    # the learned gains follow the Riccati recursion from P = 0 at every iteration
    assert ours("max rel. difference from Riccati recursion (all iterations)", "Q-learning VI") <= 1e-5
    assert ours("env samples used", "Q-learning VI") == 90
    assert ours("final rel. gain error vs DARE", "Q-learning LSPI") <= 1e-8
    assert "peak wheel-4 torque" in capsys.readouterr().out
