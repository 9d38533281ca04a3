"""Transition data ``(x_k, u_k, r_k, x_{k+1})`` collected by stepping a Gymnasium env.

The learner sees only what a flight computer has (:mod:`attitude_envs.info`): the error
state it measures (the float64 measured state ``info["measured"]`` when the env provides
one, else the observation), the input it commanded (``info["commanded"]``: the physical
input of the clipped action) and the positive step cost (``info["cost"]``). Nothing is read
from the env's model or its ground truth ``info["truth"]``; with sensors and faults off the
measured state and the commanded input equal the truth.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from attitude_envs import quaternion
from attitude_envs.info import MEASURED


@dataclass
class Transitions:
    """N transitions: measured states ``X`` (N×n), commanded inputs ``U`` (N×m, physical units),
    step costs ``r`` (N,), next states ``Xn`` (N×n)."""

    X: np.ndarray
    U: np.ndarray
    r: np.ndarray
    Xn: np.ndarray

    def __len__(self) -> int:
        return len(self.r)


class EnvAdapter:
    """How the agent drives one env: setting a start state, reading the float64 error
    state, mapping a physical input to the normalized action.

    ``state_to_options(x) -> dict`` builds ``reset(options=...)`` that starts the env at
    error state ``x`` (one-step "reset" sampling); defaults exist for LinearSystem-v0
    (``{"state": x}``) and ReactionWheel-v0 (attitude ``[x₀..₂, √(1−|x₀..₂|²)]`` about an
    identity target, rate ``x₃..₅``, wheels at rest). Other envs are sampled along
    trajectories from their own ``reset()``. ``action_scale`` is the physical input of a
    unit action (per actuator); by default LinearSystem-v0's ``action_scale`` or
    ReactionWheel-v0's wheel torque rating.

    ``input_map`` (actuators × m) makes the learner's input ``v`` a combination of
    actuators: command ``M v``; the commanded ``v`` is read back as ``M⁺·commanded``. With four
    wheels on three axes, ``M = −A⁺`` (the wheel geometry's minimum-norm allocation) makes
    ``v`` the body torque, removing the wheel null space that no data can determine.
    """

    def __init__(
        self,
        env,
        state_to_options: Callable[[np.ndarray], dict] | None = None,
        action_scale=None,
        input_map=None,
    ):
        self.env = env
        base = env.unwrapped
        name = type(base).__name__
        self.n = int(np.prod(env.observation_space.shape))
        n_act = int(np.prod(env.action_space.shape))
        if input_map is None:
            self.input_map = None
            self.m = n_act
        else:
            M = np.asarray(input_map, dtype=float)
            if (
                M.ndim != 2
                or M.shape[0] != n_act
                or not np.all(np.isfinite(M))
                or np.linalg.matrix_rank(M) < M.shape[1]
            ):
                raise ValueError(f"input_map must be a finite full-column-rank {n_act} x m matrix, got shape {M.shape}")
            self.input_map = M
            self._map_pinv = np.linalg.pinv(M)
            self.m = M.shape[1]
        self.kind = {"LinearSystemEnv": "linear", "ReactionWheelEnv": "reaction_wheel"}.get(name, "generic")
        if self.kind == "reaction_wheel" and self.n != 6:
            raise ValueError(
                "QLearningLQR on ReactionWheel-v0 needs the 6-state error observation "
                f"(no wheel momentum weight, observe_wheel_speeds=False), got {self.n} states"
            )
        if state_to_options is None:
            if self.kind == "linear":
                state_to_options = _linear_options
            elif self.kind == "reaction_wheel":
                state_to_options = _reaction_wheel_options
        self.state_to_options = state_to_options
        if action_scale is None:
            if self.kind == "linear":
                action_scale = base.action_scale
            elif self.kind == "reaction_wheel":
                action_scale = base.model.params.max_wheel_torque_nm  # actuator rating, not dynamics
            else:
                action_scale = 1.0
        scale = np.broadcast_to(np.asarray(action_scale, dtype=float), (n_act,)).copy()
        if np.any(~np.isfinite(scale)) or np.any(scale <= 0):
            raise ValueError(f"action_scale must be finite and > 0, got {scale.tolist()}")
        self.action_scale = scale

    @property
    def can_set_state(self) -> bool:
        return self.state_to_options is not None

    def state(self, obs: np.ndarray, info: dict) -> np.ndarray:
        """The float64 measured error state at the observation time of ``obs`` / ``info``:
        LinearSystem-v0's ``info["measured"]`` array, the error quaternion and rate from
        ReactionWheel-v0's measured state, else ``obs``."""
        if self.kind == "linear":
            return np.asarray(info[MEASURED], dtype=float)
        if self.kind == "reaction_wheel":
            s = info[MEASURED]
            qe = quaternion.error(np.asarray(s["attitude"]), np.asarray(s["target_attitude"]))
            return np.concatenate([qe[:3], s["rate_rad_s"]])
        return np.asarray(obs, dtype=float).reshape(self.n)

    def action(self, u: np.ndarray) -> np.ndarray:
        """Normalized action(s) for the learner's input ``u`` (last axis; clipped to [-1, 1])."""
        if self.input_map is not None:
            u = u @ self.input_map.T
        return np.clip(u / self.action_scale, -1.0, 1.0).astype(np.float32)

    def commanded(self, info: dict) -> np.ndarray:
        """The learner's input commanded for the step, from ``info["commanded"]``."""
        a = np.asarray(info["commanded"], dtype=float)
        return a if self.input_map is None else self._map_pinv @ a


def _linear_options(x: np.ndarray) -> dict:
    return {"state": x}


def _reaction_wheel_options(x: np.ndarray) -> dict:
    v = np.asarray(x[:3], dtype=float)
    s2 = float(v @ v)
    if s2 >= 1.0:
        raise ValueError(f"the attitude part of the sampled state must have norm < 1, got {np.sqrt(s2):.3g}")
    return {
        "attitude": np.concatenate([v, [np.sqrt(1.0 - s2)]]),
        "target_attitude": np.array([0.0, 0.0, 0.0, 1.0]),
        "rate_rad_s": np.asarray(x[3:6], dtype=float),
    }


def collect(
    adapter: EnvAdapter,
    n_samples: int,
    gain: np.ndarray,
    exploration_std: np.ndarray,
    state_std: np.ndarray,
    rng: np.random.Generator,
    env_seed: int | None,
    mode: str,
) -> Transitions:
    """``n_samples`` transitions under the behaviour ``u = −gain·x + η``, ``η ~ N(0, diag(σ²))``
    from ``rng`` (physical input units).

    ``mode="reset"``: each transition starts from a fresh state ``x ~ N(0, diag(state_std²))``
    set through ``reset(options=...)`` (i.i.d. one-step samples, the paper's points p_j ∈ Ω,
    Heravi & Novinzadeh 2017, eq. 29). ``mode="trajectory"``: consecutive steps along episodes from the env's
    own ``reset()``, restarted when an episode ends.
    """
    env = adapter.env
    n, m = adapter.n, adapter.m
    X = np.empty((n_samples, n))
    U = np.empty((n_samples, m))
    r = np.empty(n_samples)
    Xn = np.empty((n_samples, n))
    first = True
    x = None
    for k in range(n_samples):
        if mode == "reset":
            x_req = state_std * rng.standard_normal(n)
            obs, info = env.reset(seed=env_seed if first else None, options=adapter.state_to_options(x_req))
            x = adapter.state(obs, info)
        elif x is None:
            obs, info = env.reset(seed=env_seed if first else None)
            x = adapter.state(obs, info)
        first = False
        u_cmd = -gain @ x + exploration_std * rng.standard_normal(m)
        obs, _, terminated, truncated, info = env.step(adapter.action(u_cmd))
        x_next = adapter.state(obs, info)
        X[k], U[k], r[k], Xn[k] = x, adapter.commanded(info), float(info["cost"]), x_next
        x = None if (terminated or truncated) else x_next
    return Transitions(X, U, r, Xn)
