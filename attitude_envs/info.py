"""The ``info`` contract of every env: what is truth, and what a flight computer has.

Every env's ``reset`` and ``step`` return an ``info`` dict with

===============  =============================================================================
key              content
===============  =============================================================================
``"truth"``      Ground truth for metrics and evaluation only: ``state`` (the true physical
                 state), ``applied`` (actuator outputs actually delivered), ``faults`` (every
                 fault of the episode, with its draws and whether it is active),
                 ``error_angle_deg``, ``disturbance_torque_nm``, ``true_inertia_kg_m2``,
                 ``sensor_bias`` and env-specific entries. Controllers must not read it.
``"measured"``   What a flight computer has: the state in the same structure as
                 ``truth["state"]``, built from the sensor layer (or an estimator wrapper).
                 With sensors off it equals the truth.
``"cost"``       The step's cost (positive; the reward is its negative).
``"time_s"``     Simulated time at the end of the step, s.
``"commanded"``  The physical command the policy's action asked for (before faults).
``"sensors"``    Raw sensor readings, only when sensors are modelled.
===============  =============================================================================

The evaluator (:mod:`attitude_envs.evaluation`) hands policies :func:`policy_view` of the
info, which has no ``"truth"``; so an analytic baseline sees exactly what an RL agent
could see.
"""

from __future__ import annotations

from typing import Any

TRUTH = "truth"
MEASURED = "measured"


def policy_view(info: dict[str, Any]) -> dict[str, Any]:
    """``info`` without the ground truth (a shallow copy): what a controller may read.
    Works for a single env's info and for a vector env's dict of arrays (drops ``_truth``)."""
    return {k: v for k, v in info.items() if k not in (TRUTH, "_" + TRUTH)}


def fault_onsets_s(info: dict[str, Any]) -> list[float]:
    """The onsets of the episode's faults as realized (drawn onsets included), s, in the order
    of ``info["truth"]["faults"]`` (actuator faults, then sensor faults; empty without faults).
    Any info of the episode gives them, the reset's included."""
    return [float(f["onset_s"]) for f in info[TRUTH]["faults"]]
