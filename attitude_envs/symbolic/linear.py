"""LinearSystem-v0 as a :class:`~attitude_envs.symbolic.problem.DiscreteProblem`:
``x⁺ = A x + B u``, ``u`` = the fault layer's output for ``action_scale · clip(a, −1, 1)``,
step cost ``xᵀQx + uᵀRu`` on the state the step starts from (no terminal cost), as
:mod:`attitude_envs.plants.linear_kernels` computes it.

Flight conditions (:mod:`attitude_envs.conditions`; LinearSystem's table,
:mod:`attitude_envs.presets.flight_linear`): the oracle knows the episode's draws and acts
through the env's chain (:func:`attitude_envs.symbolic.actuators.through_chain`), the state
``[x, queued commands]``:

* **gain error of B** (exact): ``u`` is the faulted command times this episode's drawn
  ``actuator_gain`` (each column of ``B`` times its gain), and the cost's ``uᵀRu`` is on
  that ``u``, as the env's;
* **delay** (exact): a queue of the last ``d`` commanded inputs after ``x`` (zeros at the
  start); the plant receives the oldest, so the first ``d`` periods deliver zero;
* **actuator dynamics**: the table has none (``actuators`` on is the gain alone, exact);
* **sensors**: no part (the oracle acts on the true state); the state noise of the flight
  table is the sensors' (process noise must stay 0: refused).

J* is the env's replay of the solution (:mod:`experiments.optimum`)."""

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
    chain = actuators.ChainSpec.from_env(env, m)
    if chain.is_identity:
        chain = None  # the lab's graph, bit-identical
    n_extra = 0 if chain is None else chain.n_state
    x = casadi.SX.sym("x", n + n_extra)
    a = casadi.SX.sym("a", m)
    k = casadi.SX.sym("k")
    commanded = env.action_scale * actuators.clip(a, -1.0, 1.0)
    if chain is None:
        u = actuators.delivered(commanded, k * model.dt_s, env.fault_layer.realized, env.fault_layer.limits)
        x_next = casadi.mtimes(casadi.DM(model.A), x) + casadi.mtimes(casadi.DM(model.B), u)
    else:
        extra = [x[n + i] for i in range(n_extra)]
        out, new_extra = actuators.through_chain(
            chain, commanded, k * model.dt_s, env.fault_layer.realized, env.fault_layer.limits, extra
        )
        u = casadi.vertcat(*out)
        x_plant = x[:n]
        x_next = casadi.vertcat(
            casadi.mtimes(casadi.DM(model.A), x_plant) + casadi.mtimes(casadi.DM(model.B), u), *new_extra
        )
    plant_x = x[:n] if n_extra else x  # the cost's state: the plant's, not the queue
    cost = casadi.bilin(casadi.DM(env.cost.Q), plant_x, plant_x) + casadi.bilin(casadi.DM(env.cost.R), u, u)
    step = casadi.Function("step", [x, a, k], [x_next, cost], ["x", "a", "k"], ["x_next", "cost"])
    notes = ["divergence_threshold termination not modelled (no constraint)"]
    if chain is not None:
        notes += chain.notes()
    x0 = env.state if chain is None else np.concatenate([env.state, np.zeros(n_extra)])
    return DiscreteProblem(
        env_id=env.env_name,
        n_x=n + n_extra,
        n_u=m,
        n_steps=env.episode_steps,
        step=step,
        x0=x0,
        a_lb=-np.ones(m),
        a_ub=np.ones(m),
        g=None,
        notes="; ".join(notes),
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
