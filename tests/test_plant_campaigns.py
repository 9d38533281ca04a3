"""The plant campaigns (`--config wheel|air-bearing|magnetorquer|slosh|linear|all`): every plant
has one, with the papers' controllers and trained PPO/SAC (+ fault-randomized PPO where faults
apply) on >= 20 seeds, its envs build, and `--config all` runs each into OUT/<name> with an index."""

import json
from pathlib import Path

import pytest
import yaml

import attitude_envs
from attitude_envs.registration import LEARNING_TASKS
from experiments import cli
from experiments.campaign import PLANT_CAMPAIGNS, load_campaign, preset_path, probe_models
from experiments.training.hyperparams import load_hyperparams


def test_every_registered_plant_has_a_campaign():
    ids = {e.id for name in PLANT_CAMPAIGNS for e in load_campaign(name).envs}
    assert ids == set(attitude_envs.ENV_IDS)


#: campaigns that train on the faults they are scored on (the others train PPO on the healthy task)
FAULT_TRAINED = {"wheel": "ppo-mlp-two-wheel", "air-bearing": "ppo-fault-randomized"}


@pytest.mark.parametrize("name", PLANT_CAMPAIGNS)
def test_plant_campaign_has_analytic_and_learned_agents_on_20_seeds(name):
    """The papers' controllers, an MPC, and PPO trained on the plant's learning task (-v1) over
    3 seeds, on >= 20 seeds."""
    campaign = load_campaign(name)
    assert len(campaign.seeds) >= 20
    probe_models(campaign, {})  # every env x scenario x fault builds
    trained = {a.name: a for a in campaign.agents if a.train is not None}
    analytic = [a.name for a in campaign.agents if a.train is None and a.name != "zero"]
    assert "ppo" in trained and analytic
    assert "mpc" in analytic
    for agent in trained.values():
        assert agent.env_id in LEARNING_TASKS and len(agent.train["seeds"]) >= 3
        load_hyperparams(agent.train["algo"], agent.env_id)  # a shipped Zoo entry for the task it trains on
    if name in FAULT_TRAINED:
        assert trained[FAULT_TRAINED[name]].train["env_kwargs"]["faults"]


TINY = """
name: {name}
seeds: 2
optimum: {{solve: false}}
envs:
  - name: e
    id: {id}
    kwargs: {kwargs}
agents:
  - {{name: zero, policy: zero}}
  - {{name: {agent}, policy: {agent}}}
"""


def test_config_all_runs_every_campaign_into_its_directory_with_an_index(tmp_path, monkeypatch, capsys):
    configs = []
    for name, env_id, kwargs, agent in [
        ("tiny-ab", "attitude_envs/AirBearing-v0", "{episode_duration_s: 1.0}", "lqr"),
        ("tiny-fs", "attitude_envs/FuelSlosh-v0", "{episode_duration_s: 2.0}", "slosh-pd"),
    ]:
        path = tmp_path / f"{name}.yml"
        path.write_text(TINY.format(name=name, id=env_id, kwargs=kwargs, agent=agent))
        configs.append(str(path))
    monkeypatch.setattr(cli, "ALL_CAMPAIGNS", tuple(configs))
    out = tmp_path / "all"
    assert cli.main(["benchmark", "--config", "all", "--out", str(out), "--jobs", "1", "--no-video"]) == 0
    for name in ("tiny-ab", "tiny-fs"):
        assert (out / name / "report.md").is_file() and (out / name / "episodes.csv").is_file()
    report = (out / "tiny-ab" / "report.md").read_text()  # each report names its envs by id and kwargs
    assert '| env: e | `attitude_envs/AirBearing-v0` `{"episode_duration_s": 1.0}` |' in report
    index = (out / "index.md").read_text()
    assert "[tiny-ab/report.md](tiny-ab/report.md)" in index and "`attitude_envs/FuelSlosh-v0`" in index
    assert "| tiny-fs | e · default · none | slosh-pd: J " in index  # the best analytic controller per cell
    # the result first: the best-per-cell table opens the page, the run record follows
    assert index.splitlines()[2].startswith("| campaign | env · scenario · fault | best analytic")
    assert index.index("## Run record") < index.index("[tiny-ab/report.md]")
    assert "== campaign" in capsys.readouterr().out
    with pytest.raises(ValueError, match="holds a single campaign's results; --config all needs its own directory"):
        cli._benchmark(cli.build_parser().parse_args(["benchmark", "--config", "all", "--out", str(out / "tiny-ab")]))


def test_config_all_checks_every_campaign_before_running_any(tmp_path, monkeypatch):
    good, bad = tmp_path / "good.yml", tmp_path / "bad.yml"
    good.write_text(
        TINY.format(name="good", id="attitude_envs/AirBearing-v0", kwargs="{episode_duration_s: 1.0}", agent="lqr")
    )
    bad.write_text(
        TINY.format(name="bad", id="attitude_envs/AirBearing-v0", kwargs="{episode_duration_s: 1.0}", agent="lqr")
    )
    (tmp_path / "all" / "bad").mkdir(parents=True)
    (tmp_path / "all" / "bad" / "campaign.json").write_text('{"name": "other", "fingerprint": "x"}')
    monkeypatch.setattr(cli, "ALL_CAMPAIGNS", (str(good), str(bad)))
    with pytest.raises(ValueError, match="holds results of a different campaign definition"):
        cli._benchmark(cli.build_parser().parse_args(["benchmark", "--config", "all", "--out", str(tmp_path / "all")]))
    assert not (tmp_path / "all" / "good").exists()  # nothing ran


def test_backend_option_replaces_every_trained_agents_backend():
    data = yaml.safe_load(preset_path("wheel").read_text())
    plain, forced = load_campaign(data), load_campaign(data, backend="sb3")
    for agent in plain.agents:  # the -v1 entries' backend (SBX, the parity run's choice), but the flight PPO's
        if agent.train is not None:
            backend = agent.train.get("backend") or load_hyperparams(agent.train["algo"], agent.env_id)["backend"]
            assert backend == ("jax" if agent.name == "ppo-flight" else "sbx")
    assert all(a.train.get("backend") == "sb3" for a in forced.agents if a.train is not None)
    assert plain.fingerprint != forced.fingerprint  # a different campaign: results never mix
    assert json.dumps(data) == json.dumps(yaml.safe_load(Path(preset_path("wheel")).read_text()))  # input untouched


SHORT = {
    "attitude_envs/ReactionWheel-v0": {"episode_duration_s": 3.0},
    "attitude_envs/AirBearing-v0": {"episode_duration_s": 0.5},
    "attitude_envs/Magnetorquer-v0": {"episode_duration_s": 5.0, "control_dt_s": 1.0, "integrator_dt_s": 0.1},
    "attitude_envs/FuelSlosh-v0": {"episode_duration_s": 2.0},
    "attitude_envs/LinearSystem-v0": {"episode_steps": 30},
}


@pytest.mark.parametrize("env_id", sorted(SHORT))
def test_state_trace_of_every_env_sums_to_the_rollouts_J_and_plots(env_id, tmp_path):
    import gymnasium as gym

    from attitude_envs.evaluation import record_state_trace, rollout
    from baselines.base import ZeroPolicy
    from experiments.plots import plot_state_histories

    env = gym.make(env_id, **SHORT[env_id])
    trace = record_state_trace(env, ZeroPolicy(env), seed=3)
    k = len(trace.cost)
    assert k > 0 and trace.time_s.shape == (k + 1,) and trace.applied.shape[0] == k
    assert all(v.shape[0] == k + 1 for v in trace.state.values())
    assert (trace.error_angle_deg is not None) == ("attitude" in trace.state)
    assert trace.cost.sum() == pytest.approx(rollout(env, ZeroPolicy(env), seed=3)["J"], rel=1e-12)
    path = plot_state_histories({"zero": trace, "zero again": trace}, tmp_path / "h.png", title=env_id)
    assert path.stat().st_size > 10_000


def test_histories_show_the_best_analytic_and_the_best_learned_agent():
    from experiments.report.leaderboards import history_agents

    board = [{"agent": a} for a in ("lqr", "zero", "ppo", "pid", "sac")]
    assert history_agents(board, {"ppo", "sac"}) == ["lqr", "ppo"]
    assert history_agents(board, set()) == ["lqr", "ppo"]  # one kind only: the best two controllers
    assert history_agents([{"agent": "zero"}, {"agent": "sac"}], {"sac"}) == ["sac"]


def _affinity(_job):
    import os
    import time

    time.sleep(0.2)  # long enough that both workers take jobs
    return sorted(os.sched_getaffinity(0))


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_getaffinity"), reason="no CPU affinity on this platform")
def test_pinned_campaign_workers_each_run_on_their_own_cpu():
    import os

    from experiments.campaign import LocalExecutor

    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        pytest.skip("one CPU")
    seen = {tuple(a) for a in LocalExecutor(2, pin=True).map_unordered(_affinity, [{}] * 6)}
    assert seen <= {(cpus[0],), (cpus[1],)} and len(seen) == 2
    assert sorted(os.sched_getaffinity(0)) == cpus  # the parent keeps all of them
    unpinned = {tuple(a) for a in LocalExecutor(2).map_unordered(_affinity, [{}] * 4)}
    assert unpinned == {tuple(cpus)}  # only campaigns that train with SBX pin their workers


def test_only_campaigns_that_train_with_sbx_pin_their_workers():
    from experiments.campaign import trains_with_sbx

    data = yaml.safe_load(preset_path("linear").read_text())
    assert trains_with_sbx(load_campaign(data))  # the LinearSystem-v1 entry's backend (sbx)
    assert not trains_with_sbx(load_campaign(data, backend="sb3"))
    for agent in data["agents"]:
        if "train" in agent:
            agent["train"]["overrides"] = {"backend": "sb3"}  # the entry's backend, overridden
    assert not trains_with_sbx(load_campaign(data))
    trained = [agent for agent in data["agents"] if "train" in agent]
    trained[-1]["train"]["overrides"] = {"backend": "sbx"}
    assert trains_with_sbx(load_campaign(data))
