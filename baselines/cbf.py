"""Baselines of ConstrainedSlew-v0 (:mod:`attitude_envs.envs.constrained_slew`): a rate-limited
eigenaxis slew, and the same slew through a control barrier function (CBF) safety filter.

:class:`EigenaxisSlewPolicy` turns about the eigenaxis of the attitude error at a commanded rate
``ω_c = −min(ω_max, k_θ θ) e`` (θ the error angle, ``e`` the unit eigenaxis, ``ω_max`` a
fraction of the body-rate limit) and tracks it with ``T = I_eff k_ω (ω_c − ω) + ω × H``
(``H = Iω + J_s A Ω``, the gyroscopic term cancelled). It knows nothing of the cones.

:class:`CBFSafetyFilterPolicy` passes that command each step through the quadratic program

    minimize ‖T − T_nom‖² + ρ δ²  over the body torque T (N·m) and a slack δ ≥ 0
    subject to  the linearized barrier conditions of each keep-out cone (relative degree two:
                ``ḧ + (γ₁ + γ₂) ḣ + γ₁γ₂ h ≥ −δ`` with ``h = cos α' − b · s_B``, α' the
                half-angle plus ``buffer_deg``), of the body-rate limit per axis and of the
                wheel-speed limit per wheel (relative degree one: ``ḣ + γ h ≥ −δ``), and the
                torque limit of the env's minimum-norm allocation, ``|A⁺T|_∞ ≤ u_max``,

solved by Clarabel (an interior-point conic solver; ``pip install clarabel==0.11.1``). The
slack keeps the program feasible when the barrier conditions conflict (ρ large: a last
resort). The conditions are the continuous-time ones on the state at the start of the step,
held over the step (zero-order hold): the buffer and moderate γ absorb the hold. The
cones come from the observation (each slot's direction in body axes, ``cos α`` and mask) and the
boresights from the env's constants; the state from ``info["measured"]``.

Known limit of a CBF filter on a nominal command that ignores the cones: when the eigenaxis
path runs straight through a cone's centre the filtered slew can stall on the cone's boundary
(a deadlock, not a violation).

The same filter shields any policy (a *shield* in the sense of Alshiekh et al., 2018: it sits
between the agent and the env and changes only commands that would break a barrier condition
or the wheels' torque limit; ``filtered_steps`` counts both):
:class:`Shielded` filters a policy's body-torque action at evaluation, :class:`CBFShield` is the
Gymnasium wrapper that filters a learner's actions while it trains (the Zoo's ``env_wrapper:
baselines.cbf.CBFShield``). Both call :meth:`CBFSafetyFilterPolicy.filter_action`, so a
shielded agent plays exactly as it was trained; a run trained behind :class:`CBFShield` is
evaluated behind :class:`Shielded` by the ``sb3`` policy without being told
(:meth:`CBFShield.wrap_policy`).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs import quaternion, validation
from attitude_envs.envs.constrained_slew import CONE_FEATURES, CONE_KINDS, MAX_CONES
from attitude_envs.quaternion import cross
from baselines.measured import MeasuredState
from baselines.played_action import PlayedActionWrapper
from baselines.residual import Residual, ResidualWrapper

__all__ = ["CBFSafetyFilterPolicy", "CBFShield", "EigenaxisResidual", "EigenaxisSlewPolicy", "Shielded", "WithResidual"]


class EigenaxisSlewPolicy:
    """Rate-limited eigenaxis slew on the env's nominal model (body torque demand).

    ``rate_fraction`` of the env's body-rate limit is the cruise rate (1.0 with no limit
    given: ``rate_limit_rad_s`` overrides); ``attitude_gain`` (1/s) the error angle's decay
    rate near the target; ``rate_gain`` (1/s) the rate loop's bandwidth.
    """

    name = "eigenaxis-slew"

    def __init__(
        self,
        env,
        rate_limit_rad_s: float | None = None,
        rate_fraction: float = 0.9,
        attitude_gain: float = 0.4,
        rate_gain: float = 1.2,
    ) -> None:
        base = env.unwrapped
        params = base.model.params
        if rate_limit_rad_s is None:
            limit = getattr(base, "body_rate_limit", None)
            if limit is None:
                raise ValueError("rate_limit_rad_s is needed for an env without a body_rate_limit constraint")
            rate_limit_rad_s = limit.limit_rad_s
        self.max_rate_rad_s = validation.positive("rate_limit_rad_s", rate_limit_rad_s) * validation.in_range(
            "rate_fraction", rate_fraction, 0.0, 1.0, open_low=True
        )
        self.attitude_gain = validation.positive("attitude_gain", attitude_gain)
        self.rate_gain = validation.positive("rate_gain", rate_gain)
        self.inertia = np.asarray(params.inertia_kg_m2, dtype=float)
        self.inertia_eff_inv = np.asarray(params.inertia_eff_inv, dtype=float)
        self.inertia_eff = np.linalg.inv(self.inertia_eff_inv)
        self.wheel_axes = np.asarray(params.wheel_axes, dtype=float)
        self.wheel_inertia = float(params.wheel_inertia_kg_m2)
        self.max_torque_nm = float(params.max_wheel_torque_nm)
        self.allocation = -np.linalg.pinv(self.wheel_axes)  # motor torques u = allocation @ T (N×3)
        self.action_frame = getattr(base, "action_frame", "wheel")

    def reset(self, seed: int | None = None) -> None:
        pass

    def momentum(self, state: MeasuredState) -> np.ndarray:
        """Total angular momentum in body axes, ``H = Iω + J_s A Ω`` (N·m·s)."""
        return self.inertia @ state.rate_rad_s + self.wheel_inertia * (self.wheel_axes @ state.wheel_speed_rad_s)

    def body_torque_nm(self, state: MeasuredState) -> np.ndarray:
        """The slew's body torque demand (N·m), before any limit."""
        qe = quaternion.error(state.attitude, state.target_attitude)
        s = float(np.linalg.norm(qe[:3]))
        w = state.rate_rad_s
        if s > 1e-12:
            theta = 2.0 * math.atan2(s, qe[3])
            w_cmd = -min(self.max_rate_rad_s, self.attitude_gain * theta) * qe[:3] / s
        else:
            w_cmd = np.zeros(3)
        return self.inertia_eff @ (self.rate_gain * (w_cmd - w)) + cross(w, self.momentum(state))

    def action(self, body_torque_nm: np.ndarray) -> np.ndarray:
        """The env's action for a body torque: scaled down as a whole (its direction kept)
        until every wheel of the minimum-norm allocation is within its limit."""
        u = self.allocation @ body_torque_nm
        peak = float(np.max(np.abs(u)))
        if peak > self.max_torque_nm:
            body_torque_nm = body_torque_nm * (self.max_torque_nm / peak)
            u = u * (self.max_torque_nm / peak)
        out = body_torque_nm if self.action_frame == "body" else u
        return np.clip(out / self.max_torque_nm, -1.0, 1.0).astype(np.float32)

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return self.action(self.body_torque_nm(MeasuredState.from_info(info)))


class WithResidual(Residual):
    """``policy``'s action as a correction to the eigenaxis slew's (:class:`EigenaxisSlewPolicy`
    on ``env`` with ``nominal``, its keywords): ``clip(a_slew + scale · a, −1, 1)``, body-torque
    demands in units of the wheels' torque limit (residual RL: the learner starts from the
    analytic slew and learns what to change). The name gains ``+eigenaxis``."""

    def __init__(self, policy, env, scale: float = 0.5, **nominal: Any) -> None:
        base = EigenaxisSlewPolicy(env, **nominal)
        if base.action_frame != "body":
            raise ValueError(
                f"the residual acts on body-torque actions: build the env with action_frame='body', got {base.action_frame!r}"
            )
        super().__init__(policy, base, scale, "eigenaxis")


class EigenaxisResidual(ResidualWrapper):
    """A learner's env whose action is a residual on the eigenaxis slew (:class:`WithResidual`'s
    ``scale`` and nominal keywords): each action becomes ``clip(a_slew + scale · a, −1, 1)``, as
    :class:`WithResidual` plays it. The Zoo's ``env_wrapper: baselines.cbf.EigenaxisResidual``;
    listed after :class:`CBFShield` (outside it), the residual's sum is what the shield filters."""

    twin = WithResidual

    def __init__(self, env: gym.Env, scale: float = 0.5, **nominal: Any) -> None:
        super().__init__(env, scale, **nominal)


class CBFSafetyFilterPolicy(EigenaxisSlewPolicy):
    """:class:`EigenaxisSlewPolicy` through a CBF quadratic program (see the module).

    ``cone_gains`` (γ₁, γ₂, 1/s) and ``limit_gain`` (γ, 1/s) set how fast each barrier may
    close; ``buffer_deg`` widens every cone; ``rate_margin`` and ``wheel_margin`` scale the
    rate and wheel-speed limits the filter keeps (below 1: inside them); ``slack_weight`` is ρ.
    ``filtered_steps`` counts the steps whose command the filter changed, ``slack_steps`` those
    that needed the slack.
    """

    name = "cbf-eigenaxis-slew"

    def __init__(
        self,
        env,
        cone_gains: tuple[float, float] = (0.4, 0.4),
        limit_gain: float = 1.0,
        buffer_deg: float = 2.0,
        rate_margin: float = 0.95,
        wheel_margin: float = 0.95,
        slack_weight: float = 1e6,
        **nominal: Any,
    ) -> None:
        super().__init__(env, **nominal)
        import clarabel  # only here: the nominal slew needs no solver
        import scipy.sparse

        self._clarabel, self._sparse = clarabel, scipy.sparse
        base = env.unwrapped
        if self.action_frame != "body":
            raise ValueError(
                f"the CBF filter acts on body-torque actions: build the env with action_frame='body', got {self.action_frame!r}"
            )
        self.boresights = [np.asarray(base.boresights[kind[1]], dtype=float) for kind in CONE_KINDS]
        self.gamma1, self.gamma2 = (validation.positive("cone_gains", g) for g in cone_gains)
        self.limit_gain = validation.positive("limit_gain", limit_gain)
        self.buffer_rad = math.radians(validation.in_range("buffer_deg", buffer_deg, 0.0, 30.0))
        self.rate_limit = base.body_rate_limit.limit_rad_s * validation.in_range("rate_margin", rate_margin, 0.0, 1.0)
        self.wheel_limit = base.wheel_speed_limit.limit_rad_s * validation.in_range(
            "wheel_margin", wheel_margin, 0.0, 1.0
        )
        self.slack_weight = validation.positive("slack_weight", slack_weight)
        self._settings = clarabel.DefaultSettings()
        self._settings.verbose = False
        self.filtered_steps = 0
        self.slack_steps = 0

    def reset(self, seed: int | None = None) -> None:
        self.filtered_steps = 0
        self.slack_steps = 0

    def barrier_rows(self, obs: np.ndarray, state: MeasuredState) -> tuple[np.ndarray, np.ndarray]:
        """``(G, r)``: the barrier conditions as ``G T ≤ r`` (before the slack)."""
        w = state.rate_rad_s
        h_total = self.momentum(state)
        drift = -self.inertia_eff_inv @ cross(w, h_total)  # ω̇ = I_eff⁻¹ T + drift
        rows, rhs = [], []
        cones = np.asarray(obs, dtype=float)[-CONE_FEATURES * MAX_CONES :].reshape(MAX_CONES, CONE_FEATURES)
        g1, g2 = self.gamma1, self.gamma2
        for b, slot in zip(self.boresights, cones, strict=True):
            if slot[4] < 0.5:
                continue
            s_b = slot[:3] / np.linalg.norm(slot[:3])
            cos_keep = math.cos(min(math.acos(min(1.0, slot[3])) + self.buffer_rad, 0.5 * math.pi))
            c = cross(b, s_b)
            h = cos_keep - float(b @ s_b)  # safe: h ≥ 0
            h_dot = -float(w @ c)
            # ḧ = −c·ω̇ − ω·(b × (s_B × ω))
            rest = -float(c @ drift) - float(w @ cross(b, cross(s_b, w)))
            # −c·I_eff⁻¹ T + rest + (γ₁+γ₂) ḣ + γ₁γ₂ h ≥ 0
            rows.append(c @ self.inertia_eff_inv)
            rhs.append(rest + (g1 + g2) * h_dot + g1 * g2 * h)
        k = self.limit_gain
        for axis in range(3):  # L ∓ ω_k ≥ 0: ±ω̇_k ≤ γ (L ∓ ω_k)
            for sign in (1.0, -1.0):
                rows.append(sign * self.inertia_eff_inv[axis])
                rhs.append(k * (self.rate_limit - sign * w[axis]) - sign * drift[axis])
        # J_s Ω̇_i = u_i − J_s a_i·ω̇, u = M T: ±Ω̇_i ≤ γ (L ∓ Ω_i)
        wheel_rate = self.allocation / self.wheel_inertia - self.wheel_axes.T @ self.inertia_eff_inv
        wheel_drift = -self.wheel_axes.T @ drift
        for i, speed in enumerate(state.wheel_speed_rad_s):
            for sign in (1.0, -1.0):
                rows.append(sign * wheel_rate[i])
                rhs.append(k * (self.wheel_limit - sign * speed) - sign * wheel_drift[i])
        return np.array(rows), np.array(rhs)

    def __getstate__(self) -> dict[str, Any]:  # a training env behind CBFShield is pickled with its checkpoint
        state = self.__dict__.copy()
        for key in ("_clarabel", "_sparse", "_settings"):
            state.pop(key)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        import clarabel
        import scipy.sparse

        self.__dict__.update(state)
        self._clarabel, self._sparse = clarabel, scipy.sparse
        self._settings = clarabel.DefaultSettings()
        self._settings.verbose = False

    def filtered_torque_nm(
        self, obs: np.ndarray, state: MeasuredState, nominal: np.ndarray | None = None
    ) -> np.ndarray:
        """The body torque closest to ``nominal`` (N·m; default: the eigenaxis slew's) that keeps
        the barrier conditions (with the slack) and the torque limit."""
        if nominal is None:
            nominal = self.body_torque_nm(state)
        g, r = self.barrier_rows(obs, state)
        n_b = len(r)
        m = self.allocation
        if np.all(g @ nominal <= r) and np.all(np.abs(m @ nominal) <= self.max_torque_nm):
            return nominal  # the nominal command is feasible: it is the program's solution, no solve needed
        # variables [T (3), δ]; constraints A x + s = b, s in the nonnegative cone
        a = np.vstack(
            [
                np.hstack([g, -np.ones((n_b, 1))]),  # G T − δ ≤ r
                np.hstack([m, np.zeros((len(m), 1))]),  # M T ≤ u_max
                np.hstack([-m, np.zeros((len(m), 1))]),  # −M T ≤ u_max
                [[0.0, 0.0, 0.0, -1.0]],  # δ ≥ 0
            ]
        )
        b = np.concatenate([r, np.full(2 * len(m), self.max_torque_nm), [0.0]])
        scale = 1.0 / self.max_torque_nm**2  # a well-scaled objective
        p = self._sparse.csc_matrix(np.diag([2.0 * scale] * 3 + [2.0 * self.slack_weight]))
        q = np.concatenate([-2.0 * scale * nominal, [0.0]])
        solver = self._clarabel.DefaultSolver(
            p, q, self._sparse.csc_matrix(a), b, [self._clarabel.NonnegativeConeT(len(b))], self._settings
        )
        sol = solver.solve()
        if str(sol.status) not in ("Solved", "AlmostSolved", "SolverStatus.Solved", "SolverStatus.AlmostSolved"):
            return np.zeros(3)  # pragma: no cover - the slack keeps the program feasible
        x = np.asarray(sol.x)
        torque = x[:3]
        if np.linalg.norm(torque - nominal) > 1e-6 * max(1.0, float(np.linalg.norm(nominal))):
            self.filtered_steps += 1
        if x[3] > 1e-6:
            self.slack_steps += 1
        return torque

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        state = MeasuredState.from_info(info)
        return self.action(self.filtered_torque_nm(obs, state))

    def filter_action(self, action: np.ndarray, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Any policy's action (a body-torque demand in [-1, 1]³, ``T = a · max_wheel_torque_nm``)
        through the filter: the env's action for the filtered torque. ``obs`` and ``info`` are
        what the policy saw for it."""
        a = np.clip(np.asarray(action, dtype=float).reshape(3), -1.0, 1.0)
        state = MeasuredState.from_info(info)
        return self.action(self.filtered_torque_nm(obs, state, nominal=a * self.max_torque_nm))


class Shielded:
    """``policy`` (``reset(seed)``, ``act(obs, info)``) behind the CBF filter of
    :class:`CBFSafetyFilterPolicy` built on ``env`` with ``filter_params`` (its keywords). The
    policy's action is taken as the nominal body-torque demand and filtered every step; its
    name gains ``+cbf``. ``filter.filtered_steps`` counts the steps it changed."""

    def __init__(self, policy, env, **filter_params: Any) -> None:
        self.policy = policy
        self.filter = CBFSafetyFilterPolicy(env, **filter_params)
        self.name = f"{getattr(policy, 'name', type(policy).__name__)}+cbf"

    def reset(self, seed: int | None = None) -> None:
        self.policy.reset(seed)
        self.filter.reset(seed)

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return self.filter.filter_action(self.policy.act(obs, info), obs, info)


class CBFShield(PlayedActionWrapper, gym.utils.RecordConstructorArgs):
    """A learner's env behind the CBF filter (``filter_params``: :class:`CBFSafetyFilterPolicy`'s
    keywords): each action is filtered as :class:`Shielded` filters it at evaluation.
    ``info["shield_changed"]``: whether the filter changed this step's action. The reward and the
    cost are the env's for the filtered action.
    """

    def __init__(self, env: gym.Env, **filter_params: Any) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, **filter_params)
        gym.Wrapper.__init__(self, env)
        self.filter = CBFSafetyFilterPolicy(env, **filter_params)

    @staticmethod
    def wrap_policy(policy, env, **filter_params: Any) -> Shielded:
        """The evaluation-side twin of this wrapper: ``policy`` behind the same filter."""
        return Shielded(policy, env, **filter_params)

    def on_reset(self) -> None:
        self.filter.reset()

    def transform(self, action: Any, obs: np.ndarray, info: dict[str, Any]) -> tuple[np.ndarray, dict[str, Any]]:
        before = self.filter.filtered_steps
        filtered = self.filter.filter_action(action, obs, info)
        return filtered, {"shield_changed": self.filter.filtered_steps > before}
