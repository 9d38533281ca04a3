"""Gymnasium wrappers of the suite's envs (:mod:`attitude_envs.wrappers.safety`: Safety-Gymnasium's
6-tuple ``step``). The MEKF observation wrapper lives with the estimators
(:class:`attitude_envs.estimation.wrapper.EstimatedAttitude`)."""

from attitude_envs.wrappers.safety import SafetyGymnasiumWrapper

__all__ = ["SafetyGymnasiumWrapper"]
