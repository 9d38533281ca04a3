"""Analytic controllers acting through an estimator: ``lqr+mekf``, ``slosh-lqr+kf``, ...

:class:`Estimated` wraps any policy (``reset(seed)``, ``act(obs, info)``) and an estimator
of :mod:`attitude_envs.estimation.estimators` built from the same env (its nominal model
and nominal sensor specs only). Every step the estimator takes the env's raw sensor
readings (``info["sensors"]``) and the policy sees the observation rebuilt from the
estimate and an ``info`` whose ``measured`` entry is the estimate (the env's own ``info``
is left as it is). A row is named by appending the estimator's name to the policy's:
``lqr+mekf``, ``slosh-lqr+kf``.

The factories (``cls(env, **params)``, the registry's calling convention) build the rows
of each plant's LQR baseline:

================  ==============================  ==========================================
factory           envs                            pair
================  ==============================  ==========================================
``lqr_mekf``      ReactionWheel-v0, AirBearing-v0 :class:`~baselines.lqr.LQRPolicy` + MEKF
``amnftsmc_mekf`` Magnetorquer-v0                 AMNFTSMC (sliding mode) + MEKF (gyro, star
                                                  tracker, magnetometer)
``slosh_lqr_kf``  FuelSlosh-v0                    :class:`~baselines.slosh.SloshLQRPolicy` + KF
``linear_lqr_kf`` LinearSystem-v0                 :class:`~baselines.linear_lqr.LinearLQRPolicy`
                                                  + KF
================  ==============================  ==========================================

Each takes the controller's keyword arguments plus ``estimator_params`` (a dict for the
estimator's constructor).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attitude_envs.estimation.estimators import estimator_for


class Estimated:
    """``policy`` acting on ``estimator``'s estimate. ``name``: default
    ``f"{policy.name}+{estimator.name}"``. The first ``act`` after ``reset`` starts the
    estimator on that observation; later ones update it."""

    def __init__(self, policy, estimator, name: str | None = None) -> None:
        self.policy = policy
        self.estimator = estimator
        self.name = name or f"{getattr(policy, 'name', type(policy).__name__)}+{estimator.name}"
        self._started = False
        self.last_info: dict[str, Any] | None = None  # the policy's view at the last step

    def reset(self, seed: int | None = None) -> None:
        self.policy.reset(seed)
        self._started = False
        self.last_info = None

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        if self._started:
            obs_e, info_e = self.estimator.update(obs, info)
        else:
            obs_e, info_e = self.estimator.reset(obs, info)
            self._started = True
        self.last_info = info_e
        return self.policy.act(obs_e, info_e)


def _estimated(env, policy, estimator_params: dict | None, name: str | None) -> Estimated:
    return Estimated(policy, estimator_for(env, None, **(estimator_params or {})), name)


def lqr_mekf(env, estimator_params: dict | None = None, name: str | None = None, **params) -> Estimated:
    """``lqr+mekf``: the gyrostat LQR (:class:`~baselines.lqr.LQRPolicy`, ``params``) on the MEKF."""
    from baselines.lqr import LQRPolicy

    return _estimated(env, LQRPolicy(env, name="lqr", **params), estimator_params, name)


def amnftsmc_mekf(env, estimator_params: dict | None = None, name: str | None = None, **params) -> Estimated:
    """``amnftsmc+mekf``: Sadigh et al.'s adaptive sliding mode (Magnetorquer-v0) on the MEKF."""
    from baselines.sliding_mode import AMNFTSMCPolicy

    return _estimated(env, AMNFTSMCPolicy(env, **params), estimator_params, name)


def slosh_lqr_kf(env, estimator_params: dict | None = None, name: str | None = None, **params) -> Estimated:
    """``slosh-lqr+kf``: the fuel-slosh LQR (:class:`~baselines.slosh.SloshLQRPolicy`) on the KF."""
    from baselines.slosh import SloshLQRPolicy

    policy = SloshLQRPolicy(env, **params)
    policy.name = "slosh-lqr"
    return _estimated(env, policy, estimator_params, name)


def linear_lqr_kf(env, estimator_params: dict | None = None, name: str | None = None, **params) -> Estimated:
    """``linear-lqr+kf``: LinearSystem-v0's LQR (:class:`~baselines.linear_lqr.LinearLQRPolicy`) on the KF."""
    from baselines.linear_lqr import LinearLQRPolicy

    return _estimated(env, LinearLQRPolicy(env, name="linear-lqr", **params), estimator_params, name)
