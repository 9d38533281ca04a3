"""A campaign file is checked completely at load (one line naming the key and what it accepts),
agent notes reach the report, and campaigns ask each env for its success metric and fault onsets."""

import copy
import inspect
import math

import numpy as np
import pytest

from attitude_envs.evaluation.metrics import episode_metrics
from experiments.campaign import load_campaign, run_campaign, training_jobs
from experiments.campaign.spec import METRIC_RANGES
from experiments.report.leaderboards import leaderboards
from experiments.report.markdown import leaderboard_markdown
from experiments.report.writing import write_campaign_report

RW = "attitude_envs/ReactionWheel-v0"
BASE = {
    "name": "spec",
    "seeds": [0],
    "optimum": {"solve": False},
    "envs": [{"name": "rw", "id": RW, "kwargs": {"episode_duration_s": 2.0}}],
    "agents": [
        {"name": "zero", "policy": "zero"},
        {"name": "ppo", "policy": "sb3", "train": {"algo": "ppo", "timesteps": 128, "seeds": [0]}},
    ],
}


def _with(path: str, value):
    """BASE with the entry at ``path`` (dots; list indices as numbers) set to ``value``."""
    data = copy.deepcopy(BASE)
    *parents, last = path.split(".")
    node = data
    for p in parents:
        node = node[int(p)] if isinstance(node, list) else node.setdefault(p, {})
    node[last] = value
    return data


def _error(data) -> str:
    with pytest.raises(ValueError) as exc:
        load_campaign(data)
    message = str(exc.value)
    assert "\n" not in message
    return message


def test_negative_seeds_name_seeds_and_the_syntax():
    message = _error(_with("seeds", -3))
    assert message.startswith("seeds must be a count N (seeds 0..N-1), a range A-B, or a comma list")
    assert "a count must be >= 1, got -3" in message


def test_a_negative_training_budget_fails_at_load_naming_the_key_and_range():
    message = _error(_with("agents.1.train.timesteps", -10))
    assert message.startswith("agents[1].train.timesteps must be an integer in [1, inf)")
    assert message.endswith("got -10")


def test_a_note_must_be_one_line_of_text():
    assert _error(_with("agents.0.note", 5)) == (
        "agents[0].note must be one line of text (shown beside the agent in the report), got 5"
    )
    assert "agents[0].note" in _error(_with("agents.0.note", "two\nlines"))
    assert "agents[0].note" in _error(_with("agents.0.note", "  "))


@pytest.mark.parametrize(
    ("path", "value", "expected"),
    [
        ("agents.1.train.seeds", "4-2", "agents[1].train.seeds must be a count N"),
        ("agents.1.train.seeds", [0, 0], "agents[1].train.seeds must be a count N"),
        ("agents.1.train.eval_freq", 0, "agents[1].train.eval_freq must be an integer in [1, inf)"),
        ("agents.1.train.checkpoint_freq", 2.5, "agents[1].train.checkpoint_freq must be an integer in [1, inf)"),
        ("agents.1.train.eval_episodes", 0, "agents[1].train.eval_episodes must be an integer in [1, inf)"),
        ("agents.1.train.timesteps", "1e5", "agents[1].train.timesteps must be an integer in [1, inf)"),
        ("agents.1.train.timestep", 5, "agents[1].train has unknown keys ['timestep']"),
        ("agents.1.train.overrides", [1], "agents[1].train.overrides must be a mapping"),
        ("agents.1.train.hyperparams_file", "none.yml", "agents[1].train on env 'rw': YAML file 'none.yml'"),
        ("success_error_deg", 0, "success_error_deg must be a number in (0, 180]"),
        ("success_error_deg", 181, "success_error_deg must be a number in (0, 180]"),
        ("success_state_fraction", 1.5, "success_state_fraction must be a number in (0, 1]"),
        ("metrics.settling_band_deg", -1.0, "metrics.settling_band_deg must be a number in (0, inf)"),
        ("metrics.settling_band", 1.0, "metrics.settling_band must be a number in (0, 1)"),
        ("metrics.steady_state_fraction", True, "metrics.steady_state_fraction must be a number in (0, 1]"),
        ("metrics.settle_band_deg", 1.0, "metrics has unknown keys ['settle_band_deg']"),
        ("video", "yes", "video must be true or false"),
        ("agents.0.optional", "no", "agents[0].optional must be true or false"),
        ("agents.0.envs", "rw", "agents[0].envs must be a list of env names"),
        ("agents.0.deterministic", True, "agents[0] has unknown keys ['deterministic']"),
        ("envs.0.kwarg", {}, "envs[0] has unknown keys ['kwarg']"),
    ],
)
def test_every_key_is_checked_at_load(path, value, expected):
    assert _error(_with(path, value)).startswith(expected)


def test_metric_ranges_cover_episode_metrics_options():
    assert set(METRIC_RANGES) == set(inspect.signature(episode_metrics).parameters) - {"trace"}


def test_seeds_take_the_one_syntax_for_episodes_and_training(tmp_path):
    campaign = load_campaign({**_with("agents.1.train.seeds", "1-3"), "seeds": "0,5"})
    assert campaign.seeds == [0, 5] and campaign.agents[1].train["seeds"] == [1, 2, 3]
    assert [j["seed"] for j in training_jobs(campaign, tmp_path)] == [1, 2, 3]
    assert load_campaign(_with("seeds", 3)).seeds == [0, 1, 2]


def test_validation_episodes_reach_the_training_job(tmp_path):
    """``train.eval_episodes``: the validation episodes (seeds 10000+) that choose the best snapshot."""
    assert {j["eval_episodes"] for j in training_jobs(load_campaign(BASE), tmp_path)} == {5}
    campaign = load_campaign(_with("agents.1.train.eval_episodes", 20))
    assert {j["eval_episodes"] for j in training_jobs(campaign, tmp_path)} == {20}


def test_a_note_is_not_part_of_the_campaign_definition():
    noted = load_campaign(_with("agents.0.note", "free drift | no control"))
    plain = load_campaign(BASE)
    assert noted.agents[0].note == "free drift | no control" and "note" not in noted.agents[0].spec
    assert noted.fingerprint == plain.fingerprint and noted.agent_notes == {"zero": "free drift | no control"}
    quick = load_campaign("quick")
    assert quick.agent_notes == {"ppo-brief": "a 6,000-step smoke run, not a trained agent"}


def test_the_note_is_shown_beside_the_agent_in_the_report(tmp_path):
    config = _with("agents.0.note", "free drift: no control")
    config["agents"] = [config["agents"][0], {"name": "lqr", "policy": "lqr"}]
    result = run_campaign(config, tmp_path, workers=1)
    report = write_campaign_report(result, video=False).read_text()
    board = report.split("## Leaderboards")[1]
    assert "| zero (free drift: no control) | 1 (< 5 episodes) |" in board and "| lqr | 1 (< 5 episodes) |" in board
    escaped = leaderboard_markdown(leaderboards(result.rows), {"lqr": "a | b"})
    assert "| lqr (a \\| b) |" in escaped


def test_recovery_is_measured_from_the_realized_onset_of_a_drawn_fault(tmp_path):
    drawn = [{"kind": "outage", "target": "actuator", "index": "random", "onset_s": {"uniform": [1.0, 5.0]}}]
    config = {
        "name": "drawn",
        "seeds": [0],
        "optimum": {"solve": False},
        "envs": [{"name": "rw", "id": RW, "kwargs": {"preset": "pyramid-4wheel"}, "faults": {"drawn": drawn}}],
        "agents": [{"name": "quaternion-lqr", "policy": "quaternion-lqr"}],
    }
    (row,) = run_campaign(config, tmp_path, workers=1).rows
    assert row["success"] and math.isfinite(row["recovery_time_s"]) and row["recovery_time_s"] > 0.0
    assert np.isfinite(row["final_error_deg"]) and row["final_error_deg"] <= 2.0
