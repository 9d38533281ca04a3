"""The termination cost: a step that crosses a limit is charged the terminal error state's
running cost ``xᵀQx`` over the rest of the horizon (``termination_cost="hold"``, the
default), so ending an episode early never pays; the batched envs charge the same bits."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs  # noqa: F401  (registers the ids)
from attitude_envs.info import TRUTH

# id, kwargs, a constant action that crosses a limit, steps allowed to get there
CASES = {
    "slosh": (
        "attitude_envs/FuelSlosh-v0",
        {"episode_duration_s": 100.0, "randomize_initial_state": True},
        [1.0, 1.0],
        20,
    ),
    "air-bearing": ("attitude_envs/AirBearing-v0", {}, [1.0, 1.0, 0.0], 2000),
    "wheel": ("attitude_envs/ReactionWheel-v0", {"max_rate_rad_s": 0.02}, [1.0, 1.0, 1.0, 1.0], 2000),
    "magnetorquer": ("attitude_envs/Magnetorquer-v0", {"max_rate_rad_s": 0.002}, [1.0, 1.0, 1.0, 1.0], 3000),
    "linear": (
        "attitude_envs/LinearSystem-v0",
        {"A": [[1.1, 0.0], [0.0, 0.9]], "B": [[1.0], [0.0]], "divergence_threshold": 5.0, "episode_steps": 100},
        None,
        100,
    ),
}


def _action(env, action):
    return np.ones(env.action_space.shape, np.float32) if action is None else np.asarray(action, np.float32)


def _run(env_id, kwargs, action, max_steps, seed=3):
    """Steps until the episode ends: (infos, terminated)."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=seed)
    a = _action(env, action)
    infos = []
    for _ in range(max_steps):
        _, reward, terminated, truncated, info = env.step(a)
        assert reward == -info["cost"]
        infos.append(info)
        if terminated or truncated:
            return env.unwrapped, infos, terminated
    return env.unwrapped, infos, False


def _terminal_error_state(env, info) -> np.ndarray:
    """The true error state at the terminal step, from the info (independent of the env's
    own termination-cost path)."""
    truth = info[TRUTH]
    if "x" in truth:  # FuelSlosh-v0
        return np.asarray(truth["x"])
    if env.env_name == "LinearSystem-v0":
        return np.asarray(truth["state"])
    if env.env_name == "Magnetorquer-v0":
        return env.error_state()
    s = truth["state"]
    return env.model.error_state(s["attitude"], s["rate_rad_s"], s["wheel_speed_rad_s"], s["target_attitude"])


@pytest.mark.parametrize("mode", ["hold", "episode"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_a_limit_crossing_is_charged_the_terminal_running_cost_over_the_rest(case, mode):
    """``"hold"``: over the rest of the horizon, ``(T − t)·xᵀQx``; ``"episode"`` (the v1 envs):
    over a whole episode, ``T·xᵀQx``."""
    env_id, kwargs, action, max_steps = CASES[case]
    env, held, terminated = _run(env_id, dict(kwargs, termination_cost=mode), action, max_steps)
    assert terminated, f"{case}: the action should cross a limit within {max_steps} steps"
    _, free, terminated_free = _run(env_id, dict(kwargs, termination_cost="none"), action, max_steps)
    assert terminated_free and len(free) == len(held)
    # every step before the crossing is unchanged
    assert [i["cost"] for i in held[:-1]] == [i["cost"] for i in free[:-1]]
    x = _terminal_error_state(env, held[-1])
    if env.env_name == "LinearSystem-v0":
        remaining = env.episode_steps - len(held)  # discrete time: steps
    else:
        remaining = env.episode_duration_s - held[-1]["time_s"]
    assert remaining > 0
    if mode == "episode":
        remaining = env.episode_steps if env.env_name == "LinearSystem-v0" else env.episode_duration_s
    charge = float(x @ env.model.cost.Q @ x) * remaining if env.env_name != "LinearSystem-v0" else None
    if charge is None:
        charge = float(x @ env.cost.Q @ x) * remaining
    assert charge > 0
    assert held[-1]["cost"] == pytest.approx(free[-1]["cost"] + charge, rel=1e-9)


@pytest.mark.parametrize("case", sorted(CASES))
def test_batched_envs_charge_the_single_envs_bits(case):
    env_id, kwargs, action, max_steps = CASES[case]
    n, seed = 3, 3
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(env_id, **kwargs) for _ in range(n)]
    vec.reset(seed=seed)
    for i, s in enumerate(singles):
        s.reset(seed=seed + i)
    a = _action(singles[0], action)
    ended = np.zeros(n, dtype=bool)
    charged = 0
    for _ in range(max_steps):
        _, rewards, term, trunc, infos = vec.step(np.tile(a, (n, 1)))
        for i, s in enumerate(singles):
            if ended[i]:
                continue
            _, r, te, tr, info = s.step(a)
            assert (te, tr) == (term[i], trunc[i])
            assert rewards[i] == r and infos["cost"][i] == info["cost"]
            if te:
                ended[i] = True
                charged += 1
        if ended.all():
            break
    assert charged == n


@pytest.mark.parametrize("case", sorted(CASES))
def test_termination_cost_rejects_unknown_modes_by_name(case):
    env_id, kwargs, _, _ = CASES[case]
    with pytest.raises(ValueError, match=r"termination_cost must be one of \['episode', 'hold', 'none'\], got 'zero'"):
        gym.make(env_id, **kwargs, termination_cost="zero")


def test_ending_the_slosh_episode_early_no_longer_pays():
    """The exploit the learned slosh agents found: full gimbal and moment end the episode
    within two steps. Charged, it costs far more than the paper's LQR over the whole run."""
    from experiments.policies import build_policy

    env_id, kwargs, action, max_steps = CASES["slosh"]
    _, held, _ = _run(env_id, kwargs, action, max_steps)
    crash = sum(i["cost"] for i in held)
    env = gym.make(env_id, **kwargs)
    policy = build_policy({"policy": "slosh-lqr"}, env)
    obs, info = env.reset(seed=3)
    policy.reset(3)
    lqr, done = 0.0, False
    from attitude_envs.info import policy_view

    while not done:
        obs, _, te, tr, info = env.step(policy.act(obs, policy_view(info)))
        lqr += info["cost"]
        done = te or tr
    assert not te
    assert crash > 100 * lqr
