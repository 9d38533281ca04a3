"""PPO-Lagrangian's multiplier: a Stable-Baselines3 callback that sets the constraint penalty of
the training envs by projected dual ascent.

The constrained problem ``max E[Σ r]`` subject to ``E[Σ c] ≤ d`` (``c`` the step's constraint
cost, ``d`` the budget per episode) is solved as the saddle point of the Lagrangian
``E[Σ r] − λ (E[Σ c] − d)`` (Ray, Achiam & Amodei 2019, "Benchmarking Safe Exploration in Deep
RL", their PPO-Lagrangian; Stooke, Achiam & Abbeel 2020 write the same update as the integral
term of a PID). The policy ascends ``r − λ c`` (:class:`attitude_envs.wrappers.ConstraintPenalty`
wraps every training env, and this callback sets its ``penalty`` = λ); after each rollout λ
takes one projected gradient step on the dual,

    λ ← min(max_penalty, max(0, λ + lr · (C̄ − d)))

with ``C̄`` the mean constraint cost of the episodes that ended in the rollout, read at each
episode's end from the env's own count (``info[episode_cost_key]``, ConstrainedSlew-v0's
``violations``: the episode's violating steps, the sum of its per-step costs). One value
function learns ``r − λ c`` here, where Ray et al. keep a second critic for ``c``: with λ
moving the critic lags it, which the small ``lr`` keeps in bounds. λ lives in the envs and the
episode counts in the env's info, so a checkpoint keeps both and a resumed run continues
exactly as an uninterrupted one (an episode that spans two ``learn()`` segments is counted
whole).

Use (the Zoo's hyperparameter keys)::

    env_wrapper:
      - attitude_envs.wrappers.ConstraintPenalty: {penalty: 1.0}
    callback:
      - experiments.training.lagrangian.LagrangeMultiplier: {budget: 0.0, lr: 0.05}
"""

from __future__ import annotations

import math

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from attitude_envs import validation


class LagrangeMultiplier(BaseCallback):
    """Dual ascent on the training envs' constraint penalty λ (see the module).

    ``budget`` (≥ 0): the constraint cost allowed per episode (ConstrainedSlew-v0: violating
    steps); ``lr`` (> 0): the dual step, in λ's units per unit of cost above the budget;
    ``max_penalty`` (> 0): λ's cap; ``episode_cost_key``: the info key of the episode's cost so
    far (read when the episode ends). Logs ``lagrangian/penalty`` and
    ``lagrangian/episode_cost`` after each rollout in which an episode ended."""

    def __init__(
        self,
        budget: float = 0.0,
        lr: float = 0.05,
        max_penalty: float = 100.0,
        episode_cost_key: str = "violations",
        verbose: int = 0,
    ) -> None:
        super().__init__(verbose)
        self.budget = validation.in_range("budget", budget, 0.0, math.inf)
        self.lr = validation.positive("lr", lr)
        self.max_penalty = validation.positive("max_penalty", max_penalty)
        if not isinstance(episode_cost_key, str) or not episode_cost_key:
            raise ValueError(f"episode_cost_key must be a non-empty string (an info key), got {episode_cost_key!r}")
        self.episode_cost_key = episode_cost_key
        self._ended: list[float] = []

    def _on_training_start(self) -> None:
        try:
            penalties = self.training_env.get_attr("penalty")
        except AttributeError as exc:
            raise ValueError(
                "LagrangeMultiplier needs the training envs wrapped in attitude_envs.wrappers.ConstraintPenalty "
                "(the Zoo's env_wrapper key)"
            ) from exc
        if len(set(penalties)) != 1:
            raise ValueError(f"the training envs' penalties differ ({penalties}); they must start equal")
        self._ended = []

    @property
    def penalty(self) -> float:
        """λ, as the training envs hold it."""
        return float(self.training_env.get_attr("penalty", indices=[0])[0])

    def _on_step(self) -> bool:
        for info, done in zip(self.locals["infos"], self.locals["dones"], strict=True):
            if done:
                if self.episode_cost_key not in info:
                    raise KeyError(
                        f"LagrangeMultiplier: the env's info has no {self.episode_cost_key!r} at an episode's end "
                        f"(keys: {sorted(info)}); pass episode_cost_key"
                    )
                self._ended.append(float(info[self.episode_cost_key]))
        return True

    def _on_rollout_end(self) -> None:
        if not self._ended:
            return
        mean_cost = float(np.mean(self._ended))
        self._ended = []
        new = min(self.max_penalty, max(0.0, self.penalty + self.lr * (mean_cost - self.budget)))
        self.training_env.env_method("set_penalty", new)
        self.logger.record("lagrangian/penalty", new)
        self.logger.record("lagrangian/episode_cost", mean_cost)
