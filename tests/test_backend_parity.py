"""The backend-parity decision rule (benchmarks/backend_parity.py) and the throughput benchmark's smoke run."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/ is a folder of the checkout, not a package
from benchmarks.backend_parity import markdown, parity, seed_means  # noqa: E402


def _rows(agent, seed_js):
    return [{"agent": agent, "train_seed": s, "J": j} for s, js in seed_js.items() for j in js]


def test_sbx_is_chosen_only_within_sb3s_seed_spread_or_better():
    rows = [{"agent": "lqr", "train_seed": "", "J": 100.0}] * 2
    rows += _rows("ppo-sb3", {0: [100.0, 110.0], 1: [120.0, 120.0], 2: [130.0, 130.0]})  # seed means 105, 120, 130
    rows += _rows("ppo-sbx", {0: [128.0], 1: [129.0], 2: [130.0]})  # mean 129 <= 130: within the spread
    rows += _rows("sac-sb3", {0: [200.0], 1: [210.0], 2: [220.0]})
    rows += _rows("sac-sbx", {0: [230.0], 1: [221.0], 2: [240.0]})  # mean 230.3 > 220: worse than every SB3 seed
    assert seed_means(rows, "ppo-sb3") == {0: 105.0, 1: 120.0, 2: 130.0}
    result = parity(rows)
    assert result["lqr_J_mean"] == 100.0
    assert result["algorithms"]["ppo"]["sbx_within_sb3_spread_or_better"] is True
    assert result["algorithms"]["sac"]["sbx_within_sb3_spread_or_better"] is False
    assert result["algorithms"]["ppo"]["sb3"]["J_range"] == [105.0, 130.0]
    text = markdown(result)
    assert "| ppo | sb3 | 0: 105.0, 1: 120.0, 2: 130.0 | 118.3 | [105.0, 130.0] | 1.183 |" in text
    assert "* sac: SBX worse than SB3's worst seed" in text


def test_an_unfinished_parity_run_decides_nothing():
    rows = [{"agent": "lqr", "train_seed": "", "J": 1.0}] + _rows("ppo-sb3", {0: [1.0]})
    assert parity(rows)["algorithms"]["ppo"]["sbx_within_sb3_spread_or_better"] is False
    assert "| ppo | sbx | (not run) |" in markdown(parity(rows))


def test_throughput_benchmark_smoke(tmp_path):
    pytest.importorskip("stable_baselines3")
    from benchmarks import training_throughput

    rows = training_throughput.evaluation("attitude_envs/LinearSystem-v0", {"episode_steps": 50}, 3, 1)
    assert [r["stack"] for r in rows] == ["sb3 one by one", "sb3 batched"] and rows[0]["ratio_to_today"] == 1.0
    assert all(r["episodes_per_s"] > 0 for r in rows)


def test_benchmark_models_leave_no_folders_in_the_temp_dir(tmp_path, monkeypatch):
    """The throughput benchmarks call SB3's ``learn()`` directly: their models get a logger
    without a folder, or each call would leave an empty ``$TMPDIR/SB3-<time>`` behind."""
    pytest.importorskip("stable_baselines3")
    import tempfile

    from benchmarks import training_throughput

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    model = training_throughput._model("ppo", "attitude_envs/LinearSystem-v0", {"episode_steps": 50}, "sb3", True)
    model.learn(training_throughput.rollout_steps(model))
    assert model.num_timesteps > 0 and list(scratch.glob("SB3-*")) == []
