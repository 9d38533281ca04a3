"""Safety-Gymnasium's step signature for the suite's constrained envs.

Safety-Gymnasium (and OmniSafe, which trains on it) step an env as
``obs, reward, cost, terminated, truncated, info = env.step(action)``: Gymnasium's 5-tuple
with the step's constraint cost after the reward. :class:`SafetyGymnasiumWrapper` gives an env
that reports its cost in ``info`` (ConstrainedSlew-v0's ``info["constraint_cost"]``: 1.0 on a
step that violates a constraint, Safety-Gymnasium's indicator convention) that signature.
``reset`` is Gymnasium's, unchanged.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym


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
        if self.cost_key not in info:
            raise KeyError(
                f"SafetyGymnasiumWrapper: the env's info has no {self.cost_key!r} "
                f"(keys: {sorted(info)}); wrap an env with a constraint cost (ConstrainedSlew-v0) or pass cost_key"
            )
        return obs, reward, float(info[self.cost_key]), terminated, truncated, info
