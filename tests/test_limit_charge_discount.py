"""The limit charge holds for the γ a user picks, or training says it does not.

A ``-v1`` task charges a limit crossing ``T·xᵀQx`` (``termination_cost="episode"``): at least what
holding the state reached is worth to a learner that bootstraps at the time limit,
``xᵀQx·Δt/(1 − γ)``, exactly when the horizon ``1/(1 − γ)`` decisions is within the episode's
decisions. For a longer horizon ``train`` warns once (:class:`LimitChargeWarning`,
:mod:`experiments.training.discount`) and leaves the charge as it is, so the shipped recipes (each
within its episode) train as before. For γ ∈ {0.9, 0.95, 0.99, 0.995} on every ``-v1`` id:

* ``train`` warns exactly where the charge falls short (the table :data:`WARNS`, SB3's default
  0.99 among them), with one warning that names the id and the largest covered γ; the shipped
  recipes never warn;
* where it does not warn, a dive into a limit never pays in the learner's discounted objective
  (the charge is at least the bootstrapped value of holding the terminal state, and the dive's
  discounted return is below the analytic controller's, the survivor charged that value too);
  where it warns, the charge is indeed below that value (the warning is not spurious).
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from test_learning_tasks import DIVES, _Constant, _play

import attitude_envs  # noqa: F401  (registers the ids)
from attitude_envs.registration import LEARNING_TASKS
from experiments.policies import build_policy
from experiments.training import training
from experiments.training.discount import LimitChargeWarning, largest_covered_discount
from experiments.training.hyperparams import hyperparams_path, read_yaml

V1 = sorted(LEARNING_TASKS)
GAMMAS = (0.9, 0.95, 0.99, 0.995)
#: (id, γ) pairs whose horizon exceeds the episode: 1/(1 − γ) decisions > decisions_per_episode
#: (AirBearing-v1 40, Magnetorquer-v1 30, LinearSystem-v1 80; FuelSlosh-v1 400, ReactionWheel-v1 600)
WARNS = {
    ("attitude_envs/AirBearing-v1", 0.99),
    ("attitude_envs/AirBearing-v1", 0.995),
    ("attitude_envs/Magnetorquer-v1", 0.99),
    ("attitude_envs/Magnetorquer-v1", 0.995),
    ("attitude_envs/LinearSystem-v1", 0.99),
    ("attitude_envs/LinearSystem-v1", 0.995),
}


class _Stop(Exception):
    pass


def _warnings_of_train(monkeypatch, tmp_path, env_id: str, algo: str = "ppo", overrides=None) -> list[str]:
    """The LimitChargeWarnings ``train`` gives before it would write its run directory."""

    def stop(*args, **kwargs):
        raise _Stop

    monkeypatch.setattr(training, "RunDir", stop)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(_Stop):
            training.train(algo, env_id, tmp_path / "run", overrides=overrides)
    return [str(w.message) for w in caught if issubclass(w.category, LimitChargeWarning)]


def test_the_table_is_the_horizon_rule():
    for env_id in V1:
        decisions = gym.make(env_id).unwrapped.decisions_per_episode
        for gamma in GAMMAS:
            assert ((env_id, gamma) in WARNS) == (1.0 / (1.0 - gamma) > decisions), (env_id, gamma, decisions)


@pytest.mark.parametrize("gamma", GAMMAS)
@pytest.mark.parametrize("env_id", V1)
def test_training_warns_exactly_where_the_charge_falls_short(env_id, gamma, monkeypatch, tmp_path):
    found = _warnings_of_train(monkeypatch, tmp_path, env_id, overrides={"gamma": gamma})
    if (env_id, gamma) in WARNS:
        assert len(found) == 1, found
        largest = largest_covered_discount(gym.make(env_id))
        assert env_id in found[0] and f"gamma {gamma:g}" in found[0] and f"{largest:.6g}" in found[0], found[0]
    else:
        assert found == []


def _shipped(env_id: str) -> list[str]:
    return [algo for algo in ("ppo", "sac") if env_id in read_yaml(hyperparams_path(algo))]


@pytest.mark.parametrize("env_id", V1)
def test_the_shipped_recipes_train_without_a_warning(env_id, monkeypatch, tmp_path):
    assert _shipped(env_id)
    for algo in _shipped(env_id):
        assert _warnings_of_train(monkeypatch, tmp_path, env_id, algo) == [], algo


def test_a_v0_charge_is_not_judged(monkeypatch, tmp_path):
    """``"hold"`` (the papers' problems) is not a learning task's charge: no warning at any γ."""
    found = _warnings_of_train(monkeypatch, tmp_path, "attitude_envs/AirBearing-v0", overrides={"gamma": 0.999})
    assert found == []


@pytest.mark.parametrize("env_id", sorted(DIVES))
def test_a_dive_never_pays_where_training_does_not_warn(env_id):
    kwargs, action, analytic = DIVES[env_id]
    env = gym.make(env_id, **kwargs)
    base = env.unwrapped
    T, dt = base.episode_length_s, float(base.control_dt_s)
    dive, terminated = _play(env, _Constant(action), seed=3)
    assert terminated
    no_charge, _ = _play(gym.make(env_id, **kwargs, termination_cost="none"), _Constant(action), seed=3)
    charge = dive[-1] - no_charge[-1]
    assert charge > 0
    c_end = charge / T  # the terminal running cost xᵀQx
    survive = None
    if analytic is not None:
        survive, survived_terminated = _play(env, build_policy({"policy": analytic}, env), seed=3)
        assert not survived_terminated
    for gamma in GAMMAS:
        held = c_end * dt / (1.0 - gamma)  # holding the terminal state, to a learner bootstrapping at the limit
        if (env_id, gamma) in WARNS:
            assert charge < held, f"γ {gamma} on {env_id}: the charge covers it, the warning is spurious"
            continue
        assert charge >= held * (1 - 1e-12), f"γ {gamma} on {env_id}: {charge:g} < {held:g}"
        if survive is None:
            continue
        discounts = gamma ** np.arange(max(len(dive), len(survive)))
        g_dive = -float(np.dot(discounts[: len(dive)], dive))
        tail = survive[-1] / (1.0 - gamma)
        g_survive = -float(np.dot(discounts[: len(survive)], survive)) - discounts[len(survive) - 1] * tail
        assert g_dive < g_survive, f"γ {gamma} on {env_id}: a dive pays ({g_dive:g} ≥ {g_survive:g})"
