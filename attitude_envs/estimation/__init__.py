"""filterpy estimators: attitude/gyro-bias MEKF, its observation wrapper, actuator FDI."""

from attitude_envs.estimation.mekf import AttitudeMEKF
from attitude_envs.estimation.wrapper import EstimatedAttitude

__all__ = ["AttitudeMEKF", "EstimatedAttitude"]
