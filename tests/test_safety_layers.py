"""The safety layers of the constrained slews: the constraint penalty in the reward, the
Lagrange multiplier's dual ascent, the CBF shield (training wrapper and playing twin), the
Zoo ``env_wrapper``/``callback`` keys that put them in a training run, and the constraint
outcome of an episode (campaign rows, J*'s replay, the leaderboard columns)."""

from __future__ import annotations

import math
import pickle

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs  # noqa: F401
from attitude_envs.constraints import episode_summary
from attitude_envs.envs.constrained_slew import ConstrainedSlewEnv
from attitude_envs.evaluation.success import FINAL_ERROR_DEG, metric_of
from attitude_envs.info import policy_view
from attitude_envs.wrappers import ConstraintPenalty
from experiments.report.statistics import constraint_stats, cvar

SEED_THROUGH_A_CONE = 7  # a 1-cone episode whose eigenaxis path crosses the Sun cone


def play(env, policy, seed):
    """(J, infos) of one episode of ``policy`` (the reset's info first)."""
    obs, info = env.reset(seed=seed)
    policy.reset(seed)
    infos, total, done = [info], 0.0, False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        total += info["cost"]
        infos.append(info)
        done = terminated or truncated
    return total, infos


class FakeModel:
    """What a Stable-Baselines3 callback reads of its model."""

    num_timesteps = 0

    def __init__(self, venv, logger=None):
        self.venv = venv
        self.logger = logger

    def get_env(self):
        return self.venv


class Constant:
    """A policy that always asks for the same action."""

    name = "constant"

    def __init__(self, action):
        self.a = np.asarray(action, dtype=np.float32)

    def reset(self, seed=None):
        pass

    def act(self, obs, info):
        return self.a


# --------------------------------------------------------------------------- the penalty
def test_penalty_takes_penalty_times_cost_off_the_reward_and_leaves_j():
    plain = ConstrainedSlewEnv(body_rate_limit_rad_s=0.01)
    shaped = ConstraintPenalty(ConstrainedSlewEnv(body_rate_limit_rad_s=0.01), penalty=3.5)
    plain.reset(seed=1)
    shaped.reset(seed=1)
    a = np.array([1.0, -1.0, 0.5], dtype=np.float32)
    charged = 0
    for _ in range(20):
        _, r0, *_, i0 = plain.step(a)
        _, r1, *_, i1 = shaped.step(a)
        assert i1["cost"] == i0["cost"]
        assert r1 == pytest.approx(r0 - 3.5 * i0["constraint_cost"], rel=0, abs=1e-12)
        assert i1["constraint_penalty"] == 3.5 * i0["constraint_cost"]
        charged += i0["constraint_cost"] > 0
    assert charged > 0  # the rate limit of 0.01 rad/s is crossed within 20 full-torque steps
    shaped.set_penalty(0.0)
    assert shaped.penalty == 0.0


@pytest.mark.parametrize("bad", [-1.0, math.inf, math.nan, "x"])
def test_penalty_refuses_a_bad_value_by_name(bad):
    with pytest.raises(ValueError, match="penalty"):
        ConstraintPenalty(ConstrainedSlewEnv(), penalty=bad)
    w = ConstraintPenalty(ConstrainedSlewEnv(), penalty=1.0)
    with pytest.raises(ValueError, match="penalty"):
        w.set_penalty(bad)


def test_penalty_on_an_env_without_a_cost_says_so():
    env = ConstraintPenalty(gym.make("attitude_envs/ReactionWheel-v0"))
    env.reset(seed=0)
    with pytest.raises(KeyError, match="constraint_cost"):
        env.step(env.action_space.sample())


# --------------------------------------------------------------------------- the Lagrange multiplier
def _lagrangian_venv(n_envs=2, penalty=0.0):
    from stable_baselines3.common.env_util import make_vec_env

    return make_vec_env(
        "attitude_envs/ConstrainedSlew-v0",
        n_envs=n_envs,
        env_kwargs={"body_rate_limit_rad_s": 0.01, "episode_duration_s": 2.0},
        wrapper_class=lambda e: ConstraintPenalty(e, penalty=penalty),
    )


def _run_rollout(cb, venv, steps):
    """Feed ``cb`` ``steps`` vector steps of full-torque actions as SB3's collect_rollouts does."""
    cb.on_rollout_start()
    venv.reset()
    for _ in range(steps):
        _, _, dones, infos = venv.step(np.ones((venv.num_envs, 3), dtype=np.float32))
        cb.update_locals({"infos": infos, "dones": dones})
        cb.on_step()
    cb.on_rollout_end()


def test_dual_ascent_raises_the_penalty_while_episodes_violate_and_projects_at_zero():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.logger import Logger

    from experiments.training.lagrangian import LagrangeMultiplier

    venv = _lagrangian_venv()

    cb = LagrangeMultiplier(budget=0.0, lr=0.25, max_penalty=50.0)
    cb.init_callback(FakeModel(venv, Logger(folder=None, output_formats=[])))
    cb.on_training_start({}, {})
    _run_rollout(cb, venv, 8)  # 2 s episodes of 4 steps at full torque: the 0.01 rad/s limit is crossed
    lam = cb.penalty
    assert lam > 0.0
    assert venv.get_attr("penalty") == [lam, lam]  # every sub-env holds the same λ
    cb.budget = 1e6  # a budget above every episode's cost lowers λ, which stops at 0
    _run_rollout(cb, venv, 8)
    assert cb.penalty == 0.0


def test_dual_ascent_step_is_exact():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.logger import Logger

    from experiments.training.lagrangian import LagrangeMultiplier

    venv = _lagrangian_venv(n_envs=1, penalty=2.0)

    cb = LagrangeMultiplier(budget=0.5, lr=0.1)
    cb.init_callback(FakeModel(venv, Logger(folder=None, output_formats=[])))
    cb.on_training_start({}, {})
    cb.on_rollout_start()
    fake = [
        ({"violations": 1}, False),
        ({"violations": 2}, True),
        ({"violations": 0}, False),
        ({"violations": 1}, True),
    ]
    for info, done in fake:  # two episodes ended, with 2 and 1 violating steps: mean 1.5
        cb.update_locals({"infos": [info], "dones": np.array([done])})
        cb.on_step()
    cb.on_rollout_end()
    assert cb.penalty == pytest.approx(2.0 + 0.1 * (1.5 - 0.5), rel=0, abs=1e-15)
    cb.on_rollout_start()
    cb.update_locals({"infos": [{"cost": 1.0}], "dones": np.array([True])})
    with pytest.raises(KeyError, match="violations"):
        cb.on_step()


def test_the_multiplier_needs_the_penalty_wrapper():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_util import make_vec_env

    from experiments.training.lagrangian import LagrangeMultiplier

    venv = make_vec_env("attitude_envs/ConstrainedSlew-v0", n_envs=1)
    cb = LagrangeMultiplier()
    cb.init_callback(FakeModel(venv))
    with pytest.raises(ValueError, match="ConstraintPenalty"):
        cb.on_training_start({}, {})


@pytest.mark.parametrize("kwargs", [{"budget": -1.0}, {"lr": 0.0}, {"max_penalty": -2.0}, {"episode_cost_key": ""}])
def test_the_multiplier_refuses_bad_settings_by_name(kwargs):
    pytest.importorskip("stable_baselines3")
    from experiments.training.lagrangian import LagrangeMultiplier

    with pytest.raises(ValueError, match=next(iter(kwargs))):
        LagrangeMultiplier(**kwargs)


# --------------------------------------------------------------------------- the CBF shield
def test_the_shield_keeps_a_policy_out_of_the_cone_it_would_cross():
    pytest.importorskip("clarabel")
    from baselines.cbf import EigenaxisSlewPolicy, Shielded

    env = ConstrainedSlewEnv()
    _, bare = play(env, EigenaxisSlewPolicy(env), SEED_THROUGH_A_CONE)
    shielded = Shielded(EigenaxisSlewPolicy(env), env)
    _, infos = play(env, shielded, SEED_THROUGH_A_CONE)
    assert bare[-1]["violations"] > 0
    assert infos[-1]["violations"] == 0
    assert shielded.filter.filtered_steps > 0
    assert infos[-1]["truth"]["error_angle_deg"] < 2.0


def test_the_training_wrapper_plays_exactly_as_the_shielded_policy_and_pickles():
    pytest.importorskip("clarabel")
    from baselines.cbf import CBFShield, EigenaxisSlewPolicy, Shielded

    env = ConstrainedSlewEnv()
    j_policy, infos_policy = play(env, Shielded(EigenaxisSlewPolicy(env), env), SEED_THROUGH_A_CONE)
    wrapped = pickle.loads(pickle.dumps(CBFShield(ConstrainedSlewEnv())))  # checkpoints pickle the env
    nominal = EigenaxisSlewPolicy(env)
    obs, info = wrapped.reset(seed=SEED_THROUGH_A_CONE)
    wrapped = pickle.loads(pickle.dumps(wrapped))  # mid-episode too (a checkpoint between rollouts)
    total, changed, done = 0.0, 0, False
    while not done:
        obs, _, terminated, truncated, info = wrapped.step(nominal.act(obs, policy_view(info)))
        total += info["cost"]
        changed += info["shield_changed"]
        done = terminated or truncated
    assert total == j_policy
    assert info["violations"] == infos_policy[-1]["violations"] == 0
    assert changed > 0


def test_the_filter_passes_a_feasible_command_unchanged():
    pytest.importorskip("clarabel")
    from baselines.cbf import CBFSafetyFilterPolicy
    from baselines.measured import MeasuredState

    env = ConstrainedSlewEnv()
    f = CBFSafetyFilterPolicy(env)
    obs, info = env.reset(seed=0)
    state = MeasuredState.from_info(policy_view(info))
    small = np.array([1e-4, -2e-4, 5e-5])
    assert np.array_equal(f.filtered_torque_nm(obs, state, nominal=small), small)
    assert f.filtered_steps == 0


def test_the_shield_needs_body_torque_actions():
    pytest.importorskip("clarabel")
    from baselines.cbf import CBFShield

    with pytest.raises(ValueError, match="action_frame"):
        CBFShield(ConstrainedSlewEnv(action_frame="wheel"))


# --------------------------------------------------------------------------- the Zoo keys
def test_zoo_objects_forms_and_errors():
    from experiments.training.hyperparams import import_dotted, zoo_objects

    assert zoo_objects("env_wrapper", None) == []
    assert zoo_objects("env_wrapper", "a.B") == [("a.B", {})]
    assert zoo_objects("callback", [{"a.B": {"x": 1}}, "c.D"]) == [("a.B", {"x": 1}), ("c.D", {})]
    for bad in ("NoDot", {"a.B": 3}, {"a.B": {}, "c.D": {}}, 7):
        with pytest.raises(ValueError, match="env_wrapper"):
            zoo_objects("env_wrapper", bad)
    with pytest.raises(ValueError, match="nowhere.Thing"):
        import_dotted("nowhere.Thing")


def test_load_hyperparams_checks_the_keys_form_and_jax_refuses_them(tmp_path):
    from experiments.training.hyperparams import load_hyperparams
    from experiments.training.training import train

    with pytest.raises(ValueError, match="env_wrapper"):
        load_hyperparams("ppo", "attitude_envs/ConstrainedSlew-v0", overrides={"env_wrapper": "NoDot"})
    with pytest.raises(ValueError, match="jax backend"):
        train(
            "ppo",
            "attitude_envs/ConstrainedSlew-v0",
            tmp_path / "run",
            overrides={"env_wrapper": "baselines.cbf.CBFShield", "backend": "jax"},
            total_timesteps=10,
        )


class Zero:
    name = "zero"

    def reset(self, seed=None):
        pass

    def act(self, obs, info):
        return np.zeros(3, dtype=np.float32)


def test_a_zero_residual_is_the_eigenaxis_slew_and_the_wrapper_plays_as_the_policy():
    from baselines.cbf import EigenaxisResidual, EigenaxisSlewPolicy, WithResidual

    env = ConstrainedSlewEnv()
    j_slew, _ = play(env, EigenaxisSlewPolicy(env), 3)
    j_residual, _ = play(env, WithResidual(Zero(), env), 3)
    assert j_residual == j_slew
    push = Constant([0.3, -0.2, 0.1])
    j_policy, _ = play(env, WithResidual(push, env, scale=0.25), 3)
    wrapped = EigenaxisResidual(ConstrainedSlewEnv(), scale=0.25)
    obs, info = wrapped.reset(seed=3)
    total, done = 0.0, False
    while not done:
        obs, _, terminated, truncated, info = wrapped.step(push.act(obs, info))
        total += info["cost"]
        done = terminated or truncated
    assert total == j_policy != j_slew
    with pytest.raises(ValueError, match="scale"):
        WithResidual(Zero(), env, scale=0.0)


def test_a_run_trained_behind_the_shield_plays_behind_it(tmp_path):
    pytest.importorskip("clarabel")
    pytest.importorskip("stable_baselines3")
    from baselines.cbf import Shielded, WithResidual
    from experiments.policies import build_policy
    from experiments.training.training import train

    out = tmp_path / "run"
    overrides = {
        "env_wrapper": ["baselines.cbf.CBFShield", {"baselines.cbf.EigenaxisResidual": {"scale": 0.5}}],
        "callback": [],
        "backend": "sb3",
        "n_envs": 2,
        "n_steps": 16,
        "batch_size": 16,
    }
    result = train(
        "ppo",
        "attitude_envs/ConstrainedSlew-v0",
        out,
        overrides=overrides,
        total_timesteps=32,
        eval_freq=32,
        checkpoint_freq=32,
        eval_episodes=1,
    )
    assert result.timesteps == 32
    env = ConstrainedSlewEnv()
    policy = build_policy({"policy": "sb3", "model": str(out)}, env, name="ppo-cbf")
    assert isinstance(policy, Shielded) and isinstance(policy.policy, WithResidual)  # the shield outermost
    assert policy.name == "ppo-cbf"
    _, infos = play(env, policy, SEED_THROUGH_A_CONE)
    assert infos[-1]["violations_by_constraint"]["keep_out_sun_star_tracker"] == 0


# --------------------------------------------------------------------------- the outcome
def test_episode_summary_counts_and_the_least_margin():
    from baselines.cbf import EigenaxisSlewPolicy

    env = ConstrainedSlewEnv()
    _, infos = play(env, EigenaxisSlewPolicy(env), SEED_THROUGH_A_CONE)
    s = episode_summary(infos)
    assert s["violations"] == infos[-1]["violations"] > 0
    assert s["violations_keep_out_sun_star_tracker"] > 0
    assert s["min_margin_deg"] < 0.0  # the path enters the cone
    assert s["min_margin_deg"] == min(m for i in infos for m in i["constraint_margins_deg"].values())
    assert episode_summary([{"cost": 1.0}]) == {}
    assert metric_of(["final_error_deg", *s]) is FINAL_ERROR_DEG


def test_cvar_and_constraint_stats():
    assert cvar([1.0, 2.0, 3.0, 10.0], 0.25) == 10.0
    assert cvar([1.0, 2.0, 3.0, 10.0], 0.5) == 6.5
    assert cvar(list(range(20)), 0.1) == 18.5  # the worst 2 of 20
    assert math.isnan(cvar([math.nan]))
    with pytest.raises(ValueError, match="alpha"):
        cvar([1.0], 0.0)
    rows = [{"violations": 0, "min_margin_deg": 3.0}, {"violations": "4", "min_margin_deg": "-1.5"}]
    assert constraint_stats(rows) == {"violating_rate": 0.5, "violation_steps": 2.0, "min_margin_deg": -1.5}
    assert constraint_stats([{"J": 1.0}]) == {}
    assert math.isnan(constraint_stats([{"violations": ""}])["violating_rate"])


# --------------------------------------------------------------------------- the campaign
SLEW = {
    "name": "slew-test",
    "seeds": [7],
    "optimum": {"solve": False},
    "envs": [{"name": "slew", "id": "attitude_envs/ConstrainedSlew-v0", "kwargs": {"episode_duration_s": 10.0}}],
    "agents": [
        {"name": "eigenaxis", "policy": "eigenaxis"},
        {
            "name": "ppo",
            "policy": "sb3",
            "train": {
                "algo": "ppo",
                "timesteps": 32,
                "seeds": [0],
                "eval_freq": 32,
                "overrides": {"backend": "sb3", "n_envs": 2, "n_steps": 16, "batch_size": 16},
            },
        },
        {"name": "ppo+cbf", "policy": "sb3", "models_of": "ppo", "params": {"shield": "cbf"}},
    ],
}


def test_models_of_must_name_an_earlier_trained_agent():
    from experiments.campaign import load_campaign

    bad = {**SLEW, "agents": [SLEW["agents"][0], {**SLEW["agents"][2], "models_of": "eigenaxis"}]}
    with pytest.raises(ValueError, match="models_of must name an earlier agent with train"):
        load_campaign(bad)
    with pytest.raises(ValueError, match="models_of"):
        load_campaign({**SLEW, "agents": [*SLEW["agents"][:2], {**SLEW["agents"][2], "train": {"algo": "ppo"}}]})


def test_a_slew_campaign_plays_one_training_twice_and_reports_the_constraints(tmp_path):
    pytest.importorskip("clarabel")
    pytest.importorskip("stable_baselines3")
    from experiments.campaign import run_campaign, training_jobs
    from experiments.campaign.spec import load_campaign
    from experiments.report.writing import write_campaign_report

    assert [j["out_dir"].split("/")[-2] for j in training_jobs(load_campaign(SLEW), tmp_path)] == ["ppo"]
    result = run_campaign(SLEW, tmp_path, workers=1)
    rows = {r["agent"]: r for r in result.rows}
    assert set(rows) == {"eigenaxis", "ppo", "ppo+cbf"}
    for r in rows.values():
        assert {"violations", "min_margin_deg", "violations_body_rate"} <= set(r)
    assert rows["ppo+cbf"]["train_seed"] == rows["ppo"]["train_seed"] == 0
    report = write_campaign_report(result, video=False).read_text()
    assert "violating episodes" in report and "CVaR₀.₁ J/J*" in report
    assert "the models ppo trained" in report
    assert any(p.name.startswith("boresight-slew") for p in (tmp_path / "figures").iterdir())


def test_validation_counts_violating_episodes_and_the_best_snapshot_has_the_fewest():
    from experiments.training.callbacks import EvalLog, evaluate_cost
    from experiments.training.run_dir import RunDir

    class Full:  # a predictor asking for full torque: spins past the body-rate limit
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.ones(3, dtype=np.float32), None

    row = evaluate_cost(Full(), ConstrainedSlewEnv(episode_duration_s=5.0), [0, 1])
    assert row["violating_episodes"] == 2
    assert "violating_episodes" not in evaluate_cost(
        Full(), gym.make("attitude_envs/ReactionWheel-v0", action_frame="body"), [0]
    )
    assert EvalLog.row_text(EvalLog("."), {"timesteps": 1, **row}, header=True).splitlines()[0] == (
        "timesteps,J_mean,J_std,violating_episodes"
    )
    run = {"eval_log": "", "best": None, "last_eval": None}

    class Log:
        def row_text(self, row, header):
            return ""

        def append(self, text):
            pass

    fake = RunDir.__new__(RunDir)
    fake.evaluations = Log()
    assert RunDir.record(fake, run, {"timesteps": 1, "J_mean": 10.0, "J_std": 0.0, "violating_episodes": 1})
    assert RunDir.record(fake, run, {"timesteps": 2, "J_mean": 50.0, "J_std": 0.0, "violating_episodes": 0})
    assert not RunDir.record(fake, run, {"timesteps": 3, "J_mean": 5.0, "J_std": 0.0, "violating_episodes": 1})
    assert run["best"]["timesteps"] == 2
