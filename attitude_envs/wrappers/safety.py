"""Safety-Gymnasium's step signature for the suite's constrained envs.

Safety-Gymnasium (and OmniSafe, which trains on it) step an env as
``obs, reward, cost, terminated, truncated, info = env.step(action)``: Gymnasium's 5-tuple
with the step's constraint cost after the reward. :class:`SafetyGymnasiumWrapper` gives an env
that reports its cost in ``info`` (ConstrainedSlew-v0's ``info["constraint_cost"]``: 1.0 on a
step that violates a constraint, Safety-Gymnasium's indicator convention) that signature.
``reset`` is Gymnasium's, unchanged.

:class:`ConstraintPenalty` folds that cost into the reward instead, ``r − penalty · cost``: the
shaped reward of a learner trained with a fixed violation penalty, and, with ``penalty`` set
between rollouts by a dual-ascent update, the Lagrangian reward of PPO-Lagrangian.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from attitude_envs import validation


def step_cost(info: dict[str, Any], cost_key: str, who: str) -> float:
    """``info[cost_key]`` as a float; a ``KeyError`` naming ``who`` and the info's keys when the
    env reports no such cost."""
    if cost_key not in info:
        raise KeyError(
            f"{who}: the env's info has no {cost_key!r} (keys: {sorted(info)}); "
            "wrap an env with a constraint cost (ConstrainedSlew-v0) or pass cost_key"
        )
    return float(info[cost_key])


class SafetyGymnasiumWrapper(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """``step`` returns ``(obs, reward, cost, terminated, truncated, info)`` with
    ``cost = float(info[cost_key])`` (default ``"constraint_cost"``); ``info`` is passed on
    unchanged (the cost stays in it too). The reward is the env's: ConstrainedSlew-v0's
    ``−J`` step cost, which has no constraint term.

    The 6-tuple is not Gymnasium's step API: do not stack Gymnasium wrappers that read the
    step's result (``TimeLimit``, ``RecordEpisodeStatistics``) on top of this one; put them
    underneath it.
    """

    def __init__(self, env: gym.Env, cost_key: str = "constraint_cost") -> None:
        if not isinstance(cost_key, str) or not cost_key:
            raise ValueError(f"cost_key must be a non-empty string (an info key), got {cost_key!r}")
        gym.utils.RecordConstructorArgs.__init__(self, cost_key=cost_key)
        gym.Wrapper.__init__(self, env)
        self.cost_key = cost_key

    def step(self, action: Any) -> tuple[Any, float, float, bool, bool, dict[str, Any]]:  # type: ignore[override]
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, step_cost(info, self.cost_key, "SafetyGymnasiumWrapper"), terminated, truncated, info


class ConstraintPenalty(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """The reward less ``penalty`` times the step's constraint cost: ``r − penalty · info[cost_key]``
    (default ``"constraint_cost"``: ConstrainedSlew-v0's 1.0 per violating step, so ``penalty``
    is in the reward's units per violating step). ``info`` gains ``"constraint_penalty"``, the
    amount taken off. ``info["cost"]`` and the score J are untouched: the penalty changes what a
    learner is trained on, not what it is scored on.

    ``penalty`` (≥ 0, finite) is an attribute a trainer may set between steps (a
    Lagrange multiplier: :class:`experiments.training.lagrangian.LagrangeMultiplier` sets it
    on every sub-env of a vector env through :meth:`set_penalty`).
    """

    def __init__(self, env: gym.Env, penalty: float = 0.0, cost_key: str = "constraint_cost") -> None:
        if not isinstance(cost_key, str) or not cost_key:
            raise ValueError(f"cost_key must be a non-empty string (an info key), got {cost_key!r}")
        gym.utils.RecordConstructorArgs.__init__(self, penalty=penalty, cost_key=cost_key)
        gym.Wrapper.__init__(self, env)
        self.cost_key = cost_key
        self.penalty = penalty

    @property
    def penalty(self) -> float:
        """The reward taken off per unit of constraint cost (≥ 0)."""
        return self._penalty

    @penalty.setter
    def penalty(self, value: float) -> None:
        self._penalty = validation.nonnegative("penalty", value)

    def set_penalty(self, value: float) -> None:
        """Set :attr:`penalty` (a vector env's ``env_method("set_penalty", value)`` reaches it
        through any wrappers stacked on this one)."""
        self.penalty = value

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        charge = self._penalty * step_cost(info, self.cost_key, "ConstraintPenalty")
        info["constraint_penalty"] = charge
        return obs, float(reward) - charge, terminated, truncated, info
