"""The :class:`DiscreteProblem` dataclass (kept apart from the package's ``__init__`` so a
builder module can import it without importing the builder registry), and the IPOPT settings
every solver of the suite (J*, the MPCs) shares: :data:`SOLVED` and :data:`QUIET`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

try:
    import casadi
except ImportError as exc:  # the optional extra
    raise ImportError("the symbolic models need CasADi: pip install 'attitude-envs[optimal]'") from exc


#: IPOPT's return statuses that mean a (locally) optimal point was found
SOLVED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
#: CasADi ``nlpsol`` options that silence IPOPT
QUIET = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": 0}


@dataclass(frozen=True)
class DiscreteProblem:
    """The env's own discrete optimal-control problem for one episode (an oracle: it knows the
    episode's realized faults, start state, target and disturbance).

    ``step`` is the CasADi function ``(x_k (n_x), a_k (n_u), k (1, the step index as a
    float)) -> (x_{k+1} (n_x), cost_k (1))``: exactly the env's step (action clipping,
    scaling and allocation, the known fault effect at ``t = k·dt``, the integrator's
    sub-steps, the cost quadrature). The episode's objective is ``Σ_k cost_k`` over
    ``n_steps`` steps from ``x0``; ``g(x) <= 0`` (when given) must hold at every state.
    With ``params`` (per-step inputs that depend on time only, precomputed from the env, e.g.
    Magnetorquer-v0's orbit, field and reference), ``step`` takes ``p_k = params[k]`` in place
    of ``k``; :meth:`step_inputs` gives that third argument for any steps either way.
    """

    env_id: str
    #: symbolic state size (what the env integrates, e.g. [q, ω, Ω] for the gyrostat)
    n_x: int
    #: normalized action size (= env.action_space.shape[0])
    n_u: int
    #: control steps in the episode (horizon / control period)
    n_steps: int
    #: (x_k, a_k, k) -> (x_{k+1}, cost_k)
    step: casadi.Function
    #: the start state after ``env.reset(seed=, options=)``
    x0: np.ndarray
    #: action bounds (normally -1 and 1)
    a_lb: np.ndarray
    a_ub: np.ndarray
    #: optional path constraint g(x) <= 0 imposed on every state x_1 … x_N (None: none)
    g: casadi.Function | None = None
    #: what was simplified (e.g. "wheel-speed limit as a state constraint")
    notes: str = ""
    #: optional per-step parameters (n_steps, n_p): ``step`` then takes (x_k, a_k, params[k])
    params: np.ndarray | None = None

    def step_inputs(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """The third argument of :attr:`step` for steps ``start … stop − 1`` as columns:
        ``(1, m)`` step indices, or ``(n_p, m)`` rows of :attr:`params` when given (pass it to
        ``step.map(m)``)."""
        stop = self.n_steps if stop is None else stop
        if self.params is None:
            return np.arange(start, stop, dtype=float)[None, :]
        return np.asarray(self.params[start:stop], dtype=float).T

    def rollout(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States ``(n_steps + 1, n_x)`` and step costs ``(n_steps,)`` of ``actions``
        ``(n_steps, n_u)`` through :attr:`step` from :attr:`x0` (numeric)."""
        actions = np.asarray(actions, dtype=float).reshape(self.n_steps, self.n_u)
        states = np.empty((self.n_steps + 1, self.n_x))
        costs = np.empty(self.n_steps)
        states[0] = self.x0
        inputs = self.step_inputs()
        for k in range(self.n_steps):
            x_next, c = self.step(states[k], actions[k], inputs[:, k])
            states[k + 1] = np.asarray(x_next).ravel()
            costs[k] = float(c)
        return states, costs
