"""Residual reinforcement learning on the LQR: the learner's action corrects the LQR's command.

The env receives ``clip(u_LQR(o) + scale · clip(a, −1, 1), −1, 1)``: ``u_LQR(o)`` the
:class:`baselines.lqr.LQRPolicy` command for the observation ``o`` that the learner sees too,
``a`` the learner's action (Johannink et al. 2019, "Residual reinforcement learning for robot
control", ICRA; Silver et al. 2018, "Residual policy learning"). The learner starts from the
analytic controller and learns what to change: here what the LQR's linear, nominal, undelayed
model leaves out (the drawn plant, the actuators' dynamics, the computation delay, the
air-bearing table's offset torque).

:class:`Residual` and :class:`ResidualWrapper` combine any base policy with a learner's action
(the eigenaxis slew's residual, :mod:`baselines.cbf`, is one). :class:`LQRResidual` is the
training-side wrapper on the LQR (the Zoo's ``env_wrapper``), :class:`WithLQR` its playing-side
twin, and :class:`baselines.residual_jax.LQRResidual` the JAX
plants' twin for the fused trainer; the three compute the same command (the JAX twin to rounding:
its matrix products are XLA's). The LQR is the
gyrostat's (ReactionWheel, AirBearing) without a delay: a memoryless linear feedback.
:class:`SloshLQRResidual` does the same on FuelSlosh with Navabi & Davoodi's LQR
(:class:`baselines.slosh.SloshLQRPolicy`, its nonlinear input inversion included), with the JAX
twin :class:`baselines.residual_jax.SloshLQRResidual` (the exact inversion only).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs import validation
from baselines.lqr import LQRPolicy
from baselines.played_action import PlayedActionWrapper
from baselines.slosh import SloshLQRPolicy


def base_lqr(env: gym.Env, **lqr: Any) -> LQRPolicy:
    """The memoryless :class:`~baselines.lqr.LQRPolicy` of ``env`` with keywords ``lqr`` that a
    residual corrects; ``ValueError`` for a delay-compensating one (it remembers its commands)."""
    if lqr.get("delay_steps", 0) not in (0, None):
        raise ValueError(f"a residual corrects the memoryless LQR: delay_steps must be 0, got {lqr['delay_steps']!r}")
    return LQRPolicy(env, **lqr)


def check_scale(scale: Any) -> float:
    """The residual's ``scale``: a number in (0, 2], the largest correction in action units."""
    return validation.in_range("scale", scale, 0.0, 2.0, open_low=True)


class Residual:
    """``policy``'s action as a correction to the ``base`` policy's:
    ``clip(a_base + scale · clip(a, −1, 1), −1, 1)`` (residual RL: the learner starts from the
    analytic controller and learns what to change). The name gains ``+suffix``."""

    def __init__(self, policy, base, scale: float, suffix: str) -> None:
        self.policy = policy
        self.base = base
        self.scale = check_scale(scale)
        self.name = f"{getattr(policy, 'name', type(policy).__name__)}+{suffix}"

    def reset(self, seed: int | None = None) -> None:
        self.policy.reset(seed)
        self.base.reset(seed)

    def combine(self, action: Any, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The env's action for the residual ``action`` given what the policy saw."""
        base = self.base.act(obs, info)
        residual = np.clip(np.asarray(action, dtype=float).reshape(base.shape), -1.0, 1.0)
        return np.clip(base + self.scale * residual, -1.0, 1.0).astype(np.float32)

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return self.combine(self.policy.act(obs, info), obs, info)


class ResidualWrapper(PlayedActionWrapper, gym.utils.RecordConstructorArgs):
    """A learner's env whose action is a residual on a base policy, combined as its playing-side
    :attr:`twin` (a :class:`Residual` built from ``(policy, env, scale, **keywords)``) combines
    it; the base policy is reset with the env."""

    twin: type[Residual]

    def __init__(self, env: gym.Env, scale: float, **keywords: Any) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, scale=scale, **keywords)
        gym.Wrapper.__init__(self, env)
        self.residual = self.twin(None, env, scale, **keywords)

    @classmethod
    def wrap_policy(cls, policy, env: gym.Env, **kwargs: Any) -> Residual:
        """The playing-side twin of this wrapper: ``policy`` as a residual on the base."""
        return cls.twin(policy, env, **kwargs)

    def on_reset(self) -> None:
        self.residual.base.reset()

    def transform(self, action: Any, obs: np.ndarray, info: dict[str, Any]) -> tuple[np.ndarray, dict[str, Any]]:
        return self.residual.combine(action, obs, info), {}


class WithLQR(Residual):
    """``policy``'s action as a correction to the LQR's on ``env`` (keywords ``lqr``):
    ``clip(u_LQR + scale · clip(a, −1, 1), −1, 1)``. The name gains ``+lqr``."""

    def __init__(self, policy, env: gym.Env, scale: float = 0.25, **lqr: Any) -> None:
        super().__init__(policy, base_lqr(env, **lqr), scale, "lqr")


class LQRResidual(ResidualWrapper):
    """A learner's env whose action is a residual on the LQR (:class:`WithLQR`'s ``scale`` and
    LQR keywords). The Zoo's ``env_wrapper: {baselines.residual.LQRResidual: {scale: 0.25}}``."""

    twin = WithLQR
    #: the JAX plants' twin, which the fused trainer applies in its place
    jax_twin = "baselines.residual_jax.LQRResidual"

    def __init__(self, env: gym.Env, scale: float = 0.25, **lqr: Any) -> None:
        super().__init__(env, scale, **lqr)


class WithSloshLQR(Residual):
    """``policy``'s action as a correction to the fuel-slosh LQR's on ``env`` (keywords ``lqr``
    of :class:`~baselines.slosh.SloshLQRPolicy`): ``clip(u_LQR + scale · clip(a, −1, 1), −1, 1)``
    in the env's normalized action (gimbal angle, pitch moment). The name gains ``+slosh-lqr``."""

    def __init__(self, policy: Any, env: gym.Env, scale: float = 0.25, **lqr: Any) -> None:
        super().__init__(policy, SloshLQRPolicy(env, **lqr), scale, "slosh-lqr")


class SloshLQRResidual(ResidualWrapper):
    """A learner's FuelSlosh env whose action is a residual on the fuel-slosh LQR
    (:class:`WithSloshLQR`'s ``scale`` and LQR keywords). The Zoo's
    ``env_wrapper: {baselines.residual.SloshLQRResidual: {scale: 0.1}}``."""

    twin = WithSloshLQR
    #: the JAX plants' twin, which the fused trainer applies in its place
    jax_twin = "baselines.residual_jax.SloshLQRResidual"

    def __init__(self, env: gym.Env, scale: float = 0.25, **lqr: Any) -> None:
        super().__init__(env, scale, **lqr)
