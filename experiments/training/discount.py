"""Does a learning task's limit charge cover the discount a learner trains with?

A ``-v1`` task (``termination_cost="episode"``) charges a limit crossing ``T·xᵀQx``: the running
state cost ``c = xᵀQx`` of the state it ended in, held over a whole episode ``T``. A learner that
bootstraps its value at the time limit (PPO, SAC) values holding that state at ``c·Δt/(1 − γ)``,
so the charge is at least that, and ending an episode at a limit never pays in its objective,
exactly when the discount's horizon ``1/(1 − γ)`` decisions is within the episode's
``decisions_per_episode``: ``γ ≤ 1 − 1/decisions`` (AirBearing-v1: 40 decisions of 0.5 s,
γ ≤ 0.975). SB3's default γ 0.99 looks 100 decisions (50 s) ahead there, and a dive into the tilt
stop can be cheaper than surviving. :func:`train <experiments.training.training.train>` warns,
once per setting, when the γ it trains with is past that (:class:`LimitChargeWarning`); it does
not change the charge, so every shipped recipe (each within its episode) trains and scores as
before. The rule is the one ``attitude-envs tune`` draws its discounts by
(:func:`experiments.training.tuning.gamma_choices`).

``termination_cost="hold"`` (the ``-v0`` papers' problems) covers a bootstrapping learner only away
from the end of an episode, and ``"none"`` never: neither is a learning task's charge, and
:func:`uncovered_discount_message` says nothing of them (docs/guide/learning-tasks.md).
"""

from __future__ import annotations

import warnings

import gymnasium as gym

#: relative slack on the horizon comparison (γ = 1 − 1/decisions itself is covered)
_SLACK = 1e-9


class LimitChargeWarning(UserWarning):
    """A learner's discount looks further ahead than the env's limit charge covers."""


def largest_covered_discount(env: gym.Env) -> float | None:
    """The largest γ whose horizon ``1/(1 − γ)`` decisions the env's ``"episode"`` limit charge
    covers, ``1 − 1/decisions_per_episode``; None when the env charges a crossing otherwise
    (``"hold"``, ``"none"``) or has no such keyword."""
    base = env.unwrapped
    if getattr(base, "termination_cost", None) != "episode":
        return None
    return 1.0 - 1.0 / int(base.decisions_per_episode)


def uncovered_discount_message(env: gym.Env, gamma, env_id: str | None = None) -> str | None:
    """One line saying why ``gamma`` is past what the env's ``"episode"`` limit charge covers, or
    None when it is covered (or the env's charge is not ``"episode"``)."""
    base = env.unwrapped
    largest = largest_covered_discount(env)
    try:
        gamma = float(gamma)
    except (TypeError, ValueError):  # not a number: the hyperparameter checks say so, not this
        return None
    if largest is None or not 0.0 <= gamma < 1.0:
        return None
    decisions = int(base.decisions_per_episode)
    horizon = 1.0 / (1.0 - gamma)
    if horizon <= decisions * (1.0 + _SLACK):
        return None
    spec = getattr(env, "spec", None)
    name = env_id or (spec.id if spec is not None else type(base).__name__)
    dt = float(base.control_dt_s)
    return (
        f"gamma {gamma:g} looks {horizon:.4g} decisions ({horizon * dt:.4g} s) ahead on {name}, past its "
        f"{decisions}-decision episode ({decisions * dt:.4g} s) that the limit charge T·xᵀQx "
        f"(termination_cost='episode') covers: in this objective ending an episode at a limit can pay. "
        f"Use gamma <= {largest:.6g} (1 - 1/{decisions}), e.g. --params gamma:{_round_down(largest):g}, "
        "or the shipped recipe's (docs/guide/learning-tasks.md)"
    )


def _round_down(x: float, digits: int = 4) -> float:
    scale = 10**digits
    return int(x * scale) / scale


def warn_if_uncovered(env: gym.Env, gamma, env_id: str | None = None) -> bool:
    """Warn (:class:`LimitChargeWarning`; Python shows one setting's warning once) when ``gamma``
    is past what the env's limit charge covers; returns whether it warned."""
    message = uncovered_discount_message(env, gamma, env_id)
    if message is None:
        return False
    warnings.warn(message, LimitChargeWarning, stacklevel=3)
    return True
