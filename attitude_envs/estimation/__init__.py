"""filterpy estimators: attitude/gyro-bias MEKF, its observation wrapper, the per-plant
estimators that feed analytic controllers (:mod:`attitude_envs.estimation.estimators`),
actuator FDI."""

from attitude_envs.estimation.estimators import (
    ESTIMATORS,
    GyrostatMEKF,
    LinearKF,
    MagnetorquerMEKF,
    SampleGate,
    SloshKF,
    estimator_for,
)
from attitude_envs.estimation.mekf import AttitudeMEKF
from attitude_envs.estimation.wrapper import EstimatedAttitude

__all__ = [
    "ESTIMATORS",
    "AttitudeMEKF",
    "EstimatedAttitude",
    "GyrostatMEKF",
    "LinearKF",
    "MagnetorquerMEKF",
    "SampleGate",
    "SloshKF",
    "estimator_for",
]
