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


def model_step_function(A, B, Q, R, N=None) -> casadi.Function:
    """``(x (n), u (m)) -> (x_next (n), cost (1))`` of the NOMINAL discrete linear model
    ``x⁺ = A x + B u`` with step cost ``xᵀQx + 2xᵀNu + uᵀRu`` (``N=None``: no cross term) on
    the state the step starts from, for a model-based controller. ``u`` is the physical input
    (the env's ``action_scale · a``), not clipped and without faults; with the env's matrices
    (``env.model``, ``env.cost``) and ``N=None`` it is the env's fault-free step to round-off.
    ``A``, ``B``, ``Q``, ``R``, ``N`` may also be a k-step (decision-period) model with its
    exactly discretized cost (cross term ``N``)."""
    A, B = np.asarray(A, float), np.asarray(B, float)
    n, m = B.shape
    if A.shape != (n, n):
        raise ValueError(f"A must be {n}x{n} (the rows of B), got shape {A.shape}")
    Q, R = np.asarray(Q, float), np.asarray(R, float)
    if Q.shape != (n, n) or R.shape != (m, m):
        raise ValueError(f"Q must be {n}x{n} and R {m}x{m}, got shapes {Q.shape} and {R.shape}")
    x = casadi.SX.sym("x", n)
    u = casadi.SX.sym("u", m)
    x_next = casadi.mtimes(casadi.DM(A), x) + casadi.mtimes(casadi.DM(B), u)
    cost = casadi.bilin(casadi.DM(Q), x, x) + casadi.bilin(casadi.DM(R), u, u)
    if N is not None:
        N = np.asarray(N, float)
        if N.shape != (n, m):
            raise ValueError(f"N must be {n}x{m}, got shape {N.shape}")
        if np.any(N):
            cost = cost + 2.0 * casadi.bilin(casadi.DM(N), x, u)
    return casadi.Function("linear_model_step", [x, u], [x_next, cost], ["x", "u"], ["x_next", "cost"])
