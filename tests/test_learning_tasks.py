"""The learning tasks (``-v1`` ids): the ``-v0`` plants with a decision period, an episode
and a limit charge that a learner can learn on, on the same episodes and the same J.

* a ``-v1`` env plays the ``-v0`` episode of the same seed (same start) and integrates the
  same running cost: a held action gives the same J at the ``-v1`` decision period as at
  the ``-v0`` one;
* ``termination_cost="episode"`` charges ``T·xᵀQx`` for a limit crossing, which is at least
  what holding that state costs a learner that bootstraps at the time limit,
  ``xᵀQx·Δt/(1 − γ)``, for every shipped recipe's γ (its horizon is within the episode);
* a dive into a limit never pays in the learner's discounted objective against the
  analytic controller of the plant, even with the survivor charged the bootstrapped value
  of holding its last state.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs  # noqa: F401  (registers the ids)
from attitude_envs.info import TRUTH, policy_view
from attitude_envs.registration import LEARNING_TASKS, base_version, task_defaults
from experiments.policies import build_policy
from experiments.training.hyperparams import hyperparams_path, read_yaml

V1 = sorted(LEARNING_TASKS)

# v1 id → (kwargs that make a limit reachable, a constant action that crosses it, an analytic policy)
DIVES = {
    "attitude_envs/AirBearing-v1": ({}, [1.0, 1.0, 0.0], "lqr"),
    "attitude_envs/FuelSlosh-v1": ({}, [1.0, 1.0], "slosh-lqr"),
    "attitude_envs/ReactionWheel-v1": ({"max_rate_rad_s": 0.02}, [1.0, 1.0, 1.0, 1.0], "lqr"),
    # no analytic controller of the suite survives a rate limit this tight at 10 s decisions, and
    # against free drift a dive at once costs less (7.35 against 7.58 at γ 0.96): the charge's
    # guarantee is the first inequality of the test (no worse than holding the state reached)
    "attitude_envs/Magnetorquer-v1": ({"max_rate_rad_s": 0.004}, [1.0, 1.0, 1.0, 1.0], None),
}


def _episode_length(env) -> float:
    return env.unwrapped.episode_length_s


def _decision_period(env) -> float:
    return float(env.unwrapped.control_dt_s)


def _start_state(info) -> np.ndarray:
    state = info[TRUTH]["state"]
    if isinstance(state, dict):
        state = np.concatenate([np.ravel(np.asarray(v, dtype=float)) for v in state.values()])
    return np.ravel(np.asarray(state, dtype=float))


def test_every_plant_has_a_learning_task_registered_with_its_batched_env():
    assert {base_version(i) for i in V1} == set(attitude_envs.ENV_IDS)
    for env_id in V1:
        spec = gym.spec(env_id)
        assert spec.vector_entry_point == gym.spec(base_version(env_id)).vector_entry_point is not None
        assert spec.kwargs == task_defaults(env_id)


@pytest.mark.parametrize("env_id", [i for i in V1 if "LinearSystem" not in i])
def test_a_v1_env_plays_the_v0_episode_of_its_seed(env_id):
    """Same seed, same start: the task keywords change how often the agent decides and what
    a crossing costs, not the episode (the campaign checks this for every agent too)."""
    defaults = task_defaults(env_id)
    episode = {k: v for k, v in defaults.items() if k not in ("control_dt_s", "termination_cost", "observe_field")}
    if "integrator_dt_s" in episode:  # a v0 period the v1 sub-step divides
        episode["control_dt_s"] = episode["integrator_dt_s"]
    v0 = gym.make(base_version(env_id), **episode)
    v1 = gym.make(env_id)
    for seed in (0, 7):
        _, i0 = v0.reset(seed=seed)
        _, i1 = v1.reset(seed=seed)
        np.testing.assert_array_equal(_start_state(i0), _start_state(i1))
    assert _episode_length(v0) == _episode_length(v1)


@pytest.mark.parametrize(
    ("env_id", "level"), [("attitude_envs/AirBearing-v1", 0.05), ("attitude_envs/FuelSlosh-v1", 0.0)]
)
def test_j_is_the_same_quantity_at_the_v1_decision_period(env_id, level):
    """A constant action held for the whole (short) episode: the integrated cost is the same
    at the v1 decision period as at the v0 one (the same sub-steps, the same quadrature)."""
    defaults = task_defaults(env_id)
    fine = dict(defaults, control_dt_s=gym.make(base_version(env_id)).unwrapped.control_dt_s, episode_duration_s=2.0)
    coarse = dict(defaults, episode_duration_s=2.0)
    totals = []
    for kwargs in (fine, coarse):
        env = gym.make(env_id, **kwargs)
        env.reset(seed=1)
        a = np.full(env.action_space.shape, level, dtype=np.float32)
        total, done = 0.0, False
        while not done:
            _, _, te, tr, info = env.step(a)
            total += info["cost"]
            done = te or tr
        assert not te
        totals.append(total)
    assert totals[1] == pytest.approx(totals[0], rel=1e-9)


def _recipes(env_id: str) -> list[tuple[str, float]]:
    """(algo, γ) of every shipped hyperparameter entry for ``env_id``."""
    out = []
    for algo in ("ppo", "sac"):
        table = read_yaml(hyperparams_path(algo))
        if env_id in table:
            out.append((algo, float(table[env_id].get("gamma", 0.99))))
    return out


@pytest.mark.parametrize("env_id", V1)
def test_every_shipped_recipe_sees_no_further_than_its_episode(env_id):
    """The ``"episode"`` charge covers a bootstrapping learner whose horizon Δt/(1 − γ) is
    within the episode: each shipped recipe's is."""
    env = gym.make(env_id)
    T, dt = _episode_length(env), _decision_period(env)
    if env.unwrapped.env_name == "LinearSystem-v0":
        T, dt = float(env.unwrapped.episode_steps), float(env.unwrapped.control_dt_s / env.unwrapped.model.dt_s)
    assert _recipes(env_id), f"no shipped recipe for {env_id}"
    for algo, gamma in _recipes(env_id):
        assert dt / (1.0 - gamma) <= T, f"{algo} on {env_id}: horizon {dt / (1 - gamma):g} > episode {T:g}"


def _play(env, policy, seed: int, max_steps: int = 10_000) -> tuple[list[float], bool]:
    obs, info = env.reset(seed=seed)
    policy.reset(seed)
    costs, terminated = [], False
    for _ in range(max_steps):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        costs.append(float(info["cost"]))
        if terminated or truncated:
            break
    return costs, bool(terminated)


class _Constant:
    def __init__(self, action) -> None:
        self.action = np.asarray(action, dtype=np.float32)

    def reset(self, seed=None) -> None:
        pass

    def act(self, obs, info):
        return self.action


@pytest.mark.parametrize("env_id", sorted(DIVES))
def test_a_dive_into_a_limit_never_pays_in_the_learners_objective(env_id):
    kwargs, action, analytic = DIVES[env_id]
    env = gym.make(env_id, **kwargs)
    T, dt = _episode_length(env), _decision_period(env)
    dive, terminated = _play(env, _Constant(action), seed=3)
    assert terminated, f"the constant action {action} should cross a limit on {env_id}"
    base = env.unwrapped
    free = gym.make(env_id, **kwargs, termination_cost="none")
    no_charge, _ = _play(free, _Constant(action), seed=3)
    charge = dive[-1] - no_charge[-1]
    # the charge is T·c of the terminal running cost c = xᵀQx, whatever the time of the crossing
    assert charge > 0
    c_end = charge / T
    assert _recipes(env_id)
    for _algo, gamma in _recipes(env_id):
        # at least what holding the terminal state is worth to a learner bootstrapping at the time limit
        assert charge >= c_end * dt / (1.0 - gamma) * (1 - 1e-12)
    if analytic is None:
        return
    survive, survived_terminated = _play(env, build_policy({"policy": analytic}, env), seed=3)
    assert not survived_terminated
    for algo, gamma in _recipes(env_id):
        discounts = gamma ** np.arange(max(len(dive), len(survive)))
        g_dive = -float(np.dot(discounts[: len(dive)], dive))
        # the survivor is charged, at the time limit, the bootstrapped value of holding its last state
        tail = survive[-1] / (1.0 - gamma)  # the last step's cost is c·Δt
        g_survive = -float(np.dot(discounts[: len(survive)], survive)) - discounts[len(survive) - 1] * tail
        assert g_dive < g_survive, f"{algo} (γ {gamma}) on {env_id}: a dive pays ({g_dive:g} ≥ {g_survive:g})"
    assert base.termination_cost == "episode"


@pytest.mark.parametrize("env_id", V1)
def test_a_search_draws_only_discounts_whose_horizon_fits_the_episode(env_id):
    """``attitude-envs tune`` (optuna and the JAX population) draws γ from :func:`gamma_choices`
    of the task: at least three values, every horizon 1/(1 − γ) within the episode's decisions."""
    from experiments.training.tuning import PPO_SPACE, gamma_choices, ppo_space, task_decisions

    decisions = task_decisions(env_id)
    assert decisions == gym.make(env_id).unwrapped.decisions_per_episode
    choices = ppo_space(decisions)["gamma"]
    assert len(choices) >= 3
    assert all(0.0 < g < 1.0 and 1.0 / (1.0 - g) <= decisions * (1 + 1e-9) for g in choices), choices
    assert gamma_choices(10**6) == PPO_SPACE["gamma"]  # a long task keeps the Zoo's list
    assert gamma_choices(40) == [0.8, 0.9, 0.95, 0.975]  # AirBearing-v1: 1/8 … the whole 40 decisions
