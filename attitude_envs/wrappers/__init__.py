"""Gymnasium wrappers of the suite's envs (:mod:`attitude_envs.wrappers.safety`: Safety-Gymnasium's
6-tuple ``step``, and a constraint penalty in the reward; :mod:`attitude_envs.wrappers.last_action`:
the observation with the previous command). The MEKF observation wrapper lives with the estimators
(:class:`attitude_envs.estimation.wrapper.EstimatedAttitude`)."""

from attitude_envs.wrappers.last_action import LastAction
from attitude_envs.wrappers.safety import ConstraintPenalty, SafetyGymnasiumWrapper

__all__ = ["ConstraintPenalty", "LastAction", "SafetyGymnasiumWrapper"]
