"""Q-learning LQR on the nonlinear ReactionWheel-v0 (heravi-2017 preset): learned gain vs the
DARE gain of the env's exact ZOH discretization, and the paper's maneuver vs the LQR baseline."""

from __future__ import annotations

import numpy as np

from agents import QLearningLQR
from agents.qlqr.truth import relative_error
from attitude_envs import presets
from attitude_envs.envs.reaction_wheel import ReactionWheelEnv
from attitude_envs.evaluation import rollout
from baselines.lqr import LQRPolicy
from experiments.reproduction import Row

STATE_STD = np.array([1.0, 1.0, 1.0, 0.05, 0.05, 0.05])


def learn_on_reaction_wheel(env, amplitude: float = 1e-3, seed: int = 0, samples: int = 90):
    """Value iteration from one batch of one-step samples near the target (states scaled by
    ``amplitude``, probe ``amplitude`` N·m), learning in body-torque coordinates through the
    wheel geometry's minimum-norm allocation (hardware knowledge, not the dynamics)."""
    allocation = -np.linalg.pinv(presets.get("ReactionWheel-v0", "heravi-2017").params()["wheel_axes"])
    agent = QLearningLQR(
        env,
        method="value_iteration",
        seed=seed,
        state_std=amplitude * STATE_STD,
        exploration_std=amplitude,
        input_map=allocation,
        name="q-learning-vi",
    )
    return agent.learn(samples_per_iteration=samples)


def nonlinear_rows(episode_duration_s: float = 400.0) -> list:
    """Rows: gain error vs the ZOH-DARE gain, and J of the paper's maneuver, learned vs LQR."""
    env = ReactionWheelEnv(preset="heravi-2017", episode_duration_s=episode_duration_s)
    lqr = LQRPolicy(env, "zoh")
    agent = learn_on_reaction_wheel(env)
    j_lqr = rollout(env, lqr, seed=0)
    j_q = rollout(env, agent, seed=0)
    case = f"ReactionWheel-v0 heravi-2017 (RK4 gyrostat), paper x0, {episode_duration_s:g} s"
    return [
        Row(
            "ReactionWheel-v0 heravi-2017; ref: ZOH-DARE gain",
            "Q-learning VI (90 samples near target)",
            "rel. body-torque gain error vs LQR (ZOH) [ref 0]",
            None,
            relative_error(agent.gain, lqr.gain),
            None,
        ),
        Row(case, "Q-learning VI vs LQR (ZOH)", "episode cost J", j_lqr["J"], j_q["J"], 0.01),
        Row(case, "Q-learning VI", "final error angle [deg]", None, j_q["final_error_deg"], None),
        Row(case, "LQR (ZOH)", "final error angle [deg]", None, j_lqr["final_error_deg"], None),
    ]
