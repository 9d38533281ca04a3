"""LinearSystem-v0 as a :class:`~attitude_envs.symbolic.problem.DiscreteProblem`:
``x⁺ = A x + B u``, ``u`` = the fault layer's output for ``action_scale · clip(a, −1, 1)``,
step cost ``xᵀQx + uᵀRu`` on the state the step starts from (no terminal cost), as
:mod:`attitude_envs.plants.linear_kernels` computes it."""

from __future__ import annotations

import casadi
import numpy as np

from attitude_envs.symbolic import actuators
from attitude_envs.symbolic.problem import DiscreteProblem


def build_linear_system(env) -> DiscreteProblem:
    """The problem of the episode ``env`` (an unwrapped LinearSystem-v0, just reset) starts."""
    if env.process_noise_std > 0:
        raise ValueError(
            f"process_noise_std must be 0 for a symbolic model (deterministic plant), got {env.process_noise_std}"
        )
    model = env.model
    n, m = model.n, model.m
    x = casadi.SX.sym("x", n)
    a = casadi.SX.sym("a", m)
    k = casadi.SX.sym("k")
    commanded = env.action_scale * actuators.clip(a, -1.0, 1.0)
    u = actuators.delivered(commanded, k * model.dt_s, env.fault_layer.realized, env.fault_layer.limits)
    x_next = casadi.mtimes(casadi.DM(model.A), x) + casadi.mtimes(casadi.DM(model.B), u)
    cost = casadi.bilin(casadi.DM(env.cost.Q), x, x) + casadi.bilin(casadi.DM(env.cost.R), u, u)
    step = casadi.Function("step", [x, a, k], [x_next, cost], ["x", "a", "k"], ["x_next", "cost"])
    return DiscreteProblem(
        env_id=env.env_name,
        n_x=n,
        n_u=m,
        n_steps=env.episode_steps,
        step=step,
        x0=env.state,
        a_lb=-np.ones(m),
        a_ub=np.ones(m),
        g=None,
        notes="divergence_threshold termination not modelled (no constraint)",
    )
